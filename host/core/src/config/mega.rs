//! `[mega]`: the Mega firmware's numbers, convertible into the protocol's `McuConfig`.

use ratf_protocol::mcu::McuConfig;
use ratf_protocol::pi::{DeadZone, PiConfig, PiGains};
use serde::{Deserialize, Serialize};

use super::check::Checker;
use super::limits;

/// The firmware's control-loop numbers. Defaults = [`McuConfig::default`] (the original's
/// timing and limits, original-system.md §2.2, and the PI gains of
/// [`ratf_protocol::pi::PiGains`]). Ticks per revolution and battery voltage come from
/// `robot.ticks_per_wheel_rev` and `motor.battery_voltage_v`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MegaConfig {
    /// Control period, µs. 20 000 (50 Hz): original §2.2.
    pub control_period_us: u32,
    /// Watchdog timeout after the last wheel command, µs. 100 000: original §2.2.
    pub watchdog_timeout_us: u32,
    /// Largest PWM magnitude. 255: the motor shield library's 8-bit range.
    pub pwm_max: i16,
    /// Largest PWM change per tick. 100: original §2.2.
    pub pwm_slew_per_tick: i16,
    /// PI proportional gain Kc, V/(rad/s). 1/2.19: the original's IMC rule (§2.2) applied
    /// to the measured motor gain (see `ratf_protocol::pi::PiGains`; the original used 1/4.5).
    pub kc_v_per_rad_s: f64,
    /// PI integral gain Ki = Kc/Ti, V/rad. Ti = 0.1 s, the motor's time constant: 4.566.
    pub ki_v_per_rad: f64,
    /// Feed-forward Kf, V/(rad/s). 0: with the correct Kc the PI alone suffices (the
    /// original's 0.456 made up for its halved Kc).
    pub kf_v_per_rad_s: f64,
    /// Hammerstein dead zone V0, V. 0: disabled, as the original ships (§2.5).
    pub dead_zone_v0_v: f64,
    /// Hammerstein compensated range Vd, V. 0: disabled (§2.5).
    pub dead_zone_vd_v: f64,
    /// Close each telemetry batch with a checksum frame. true: the ratf extension.
    pub send_checksums: bool,
    /// Delay from the firmware's control tick to its first telemetry byte, µs. 2080:
    /// measured on the release ELF in simavr, idle and driving alike (`hil-tests`,
    /// `target/hil-report.json`, `telemetry_latency_*_us`). The simulator's Mega waits this
    /// long before sending, and the host subtracts it to time the odometry.
    pub telemetry_latency_us: u32,
}

impl Default for MegaConfig {
    fn default() -> Self {
        let d = McuConfig::default();
        let g = d.pi.gains;
        Self {
            control_period_us: d.control_period_us,
            watchdog_timeout_us: d.watchdog_timeout_us,
            pwm_max: d.pwm_max,
            pwm_slew_per_tick: d.pwm_slew_per_tick,
            kc_v_per_rad_s: f64::from(g.kc_v_per_rad_s),
            ki_v_per_rad: f64::from(g.ki_v_per_rad),
            kf_v_per_rad_s: f64::from(g.kf_v_per_rad_s),
            dead_zone_v0_v: f64::from(d.pi.dead_zone.v0_v),
            dead_zone_vd_v: f64::from(d.pi.dead_zone.vd_v),
            send_checksums: d.send_checksums,
            telemetry_latency_us: 2_080,
        }
    }
}

impl MegaConfig {
    /// The protocol's configuration (f32 on the Mega). The host sends its controller
    /// settings (gains, feed-forward, dead zone, battery voltage as the voltage limit, ticks
    /// per revolution) to the real Mega at start-up and after every reset.
    pub fn to_mcu_config(&self, ticks_per_wheel_rev: f64, battery_voltage_v: f64) -> McuConfig {
        McuConfig {
            control_period_us: self.control_period_us,
            watchdog_timeout_us: self.watchdog_timeout_us,
            ticks_per_wheel_rev: ticks_per_wheel_rev as f32,
            battery_voltage_v: battery_voltage_v as f32,
            // The whole battery: the PI saturates where the actuator does (§10.5).
            voltage_limit_v: battery_voltage_v as f32,
            pwm_max: self.pwm_max,
            pwm_slew_per_tick: self.pwm_slew_per_tick,
            pi: PiConfig {
                gains: PiGains {
                    kc_v_per_rad_s: self.kc_v_per_rad_s as f32,
                    ki_v_per_rad: self.ki_v_per_rad as f32,
                    kf_v_per_rad_s: self.kf_v_per_rad_s as f32,
                },
                dead_zone: DeadZone {
                    v0_v: self.dead_zone_v0_v as f32,
                    vd_v: self.dead_zone_vd_v as f32,
                },
            },
            send_checksums: self.send_checksums,
        }
    }

    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        c.within_int(
            "control_period_us",
            self.control_period_us,
            1_000,
            100_000,
            "µs",
            "the firmware closes control windows on its 1 ms time base (20 ms on the board); \
             slower than 10 Hz the wheel PI cannot follow the motor's 0.1 s time constant",
        );
        // Only once in range, so a wild value gets one issue.
        let in_range = (1_000..=100_000).contains(&self.control_period_us);
        c.require(
            "control_period_us",
            self.control_period_us,
            !in_range || self.control_period_us.is_multiple_of(1_000),
            || {
                "must be a whole number of milliseconds: the firmware's time base ticks every \
                1 ms (firmware-mega/README.md)"
                    .to_owned()
            },
        );
        let host_period_us = i128::from(limits::HOST_REFERENCE_PERIOD_US);
        c.within_int(
            "watchdog_timeout_us",
            self.watchdog_timeout_us,
            2 * host_period_us,
            1_000_000,
            "µs",
            "at least two of the host's 50 Hz reference batches, or the Mega stops the \
             wheels between them; at most 1 s, in which a runaway robot crosses half the floor",
        );
        c.within_int(
            "pwm_max",
            self.pwm_max,
            1,
            255,
            "",
            "the motor shield library's 8-bit PWM range",
        );
        c.within_int(
            "pwm_slew_per_tick",
            self.pwm_slew_per_tick,
            1,
            510,
            "per tick",
            "510 is a full reversal from -255 to +255 in one tick, i.e. no limit",
        );
        c.within(
            "kc_v_per_rad_s",
            self.kc_v_per_rad_s,
            0.0,
            100.0,
            "V/(rad/s)",
            "one encoder count per 20 ms tick is 0.11 rad/s; a gain above 12.6 V / 0.11 rad/s \
             turns one count of jitter into the full battery voltage",
        );
        c.within(
            "ki_v_per_rad",
            self.ki_v_per_rad,
            0.0,
            5_000.0,
            "V/rad",
            "the largest Kc over an integral time of one 20 ms tick",
        );
        c.within(
            "kf_v_per_rad_s",
            self.kf_v_per_rad_s,
            0.0,
            12.6,
            "V/(rad/s)",
            "beyond it a reference of 1 rad/s alone asks for more than a full 3S battery",
        );
        c.within_int(
            "telemetry_latency_us",
            self.telemetry_latency_us,
            0,
            100_000,
            "µs",
            "the firmware sends a tick's batch within that tick: 2080 µs measured; the link \
             check below bounds it by mega.control_period_us",
        );
        const DEAD_ZONE: &str =
            "a voltage the motor shield can give: its bridges take at most 13.5 V";
        c.within(
            "dead_zone_v0_v",
            self.dead_zone_v0_v,
            0.0,
            limits::MOTOR_SUPPLY_MAX_V,
            "V",
            DEAD_ZONE,
        );
        c.within(
            "dead_zone_vd_v",
            self.dead_zone_vd_v,
            0.0,
            limits::MOTOR_SUPPLY_MAX_V,
            "V",
            DEAD_ZONE,
        );
    }
}
