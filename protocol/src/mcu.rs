//! The Mega's whole behaviour as a pure state machine (original-system.md §2.4–2.7, fixed
//! per §10.1, §10.4, §10.5).
//!
//! The firmware runs this on the chip and the host simulator runs the very same code, so
//! every simulation exercises the wheel-level logic that drives the real robot. Nothing here
//! touches hardware or reads a clock: the caller passes the time (`now_us`, a wrapping `u32`
//! of microseconds) and the sampled inputs, and applies the returned outputs.
//!
//! The caller's loop:
//!
//! 1. at boot, send the bytes of [`Mcu::boot`] (the reset frame `r00000000`);
//! 2. pass every received byte chunk to [`Mcu::receive`], then apply [`Mcu::solenoid_on`]
//!    (the solenoid follows `L` at once, as in the original);
//! 3. every control period ([`McuConfig::control_period_us`]), call [`Mcu::control_tick`]
//!    with the encoder deltas since the previous tick and the switch level, write the
//!    returned PWMs to the motors and send the returned telemetry batch. (The firmware calls
//!    its two halves, [`Mcu::begin_tick`] and [`Mcu::finish_tick`], so the telemetry leaves
//!    before the controllers run.)
//!
//! Behaviour:
//!
//! - `G`..`J` set a wheel's speed reference and enable its PI controller; `K` disables that
//!   wheel's PI and sets its PWM directly; `L` sets the solenoid.
//! - Stop on the switch (`U`, ours: [`Command::StopOnSwitch`]): while armed, the tick that
//!   first reads the switch pressed sets every wheel under speed control to a reference of 0
//!   (the PI brakes it), and every `G`..`J` after it counts as 0 for
//!   [`SWITCH_STOP_HOLD_US`], or until `U` 0. A reset disarms it.
//! - Watchdog: if no `G` or `K` arrived for more than [`McuConfig::watchdog_timeout_us`],
//!   the next tick stops every motor at once (PWM 0, controllers disabled) and releases the
//!   solenoid [`SOLENOID_HOLD_AFTER_STOP_US`] later, so a carried part stays on the magnet
//!   while the robot coasts to rest. Unlike the original, **telemetry keeps flowing** while timed out, so a host
//!   that only speaks after hearing `g` can never deadlock (§10.1). The Mega boots timed out:
//!   motors stay off until the host speaks. A new `G` or `K` resumes control.
//! - Speeds are computed with the *measured* period, which is also reported on `k` (§10.4).
//! - The PI's anti-windup limit is the battery voltage, the real actuator limit (§10.5), or
//!   the lower voltage limit the host set.
//! - `M`..`T` set the controller settings ([`crate::settings`]): each valid value replaces
//!   the compiled default at once (the PIs keep their integrals); an invalid one is refused,
//!   counted as a bad message and flagged in `y`. A reset brings the defaults back, so the
//!   host resends them after every `r`.
//! - Telemetry batch, every tick: `g h i j k s q x y`, then the checksum frame `z` when
//!   checksums are on.

use crate::channels::{FRAME_LEN, Frame};
use crate::integrity::{
    BatchReceiver, BatchWriter, HOST_CHECKSUM_CHANNEL, LinkStats, MCU_CHECKSUM_CHANNEL,
};
use crate::messages::{Command, Faults, QuadratureErrors, Telemetry, WHEEL_COUNT, Wheel};
use crate::pi::{PiConfig, PiController};
use crate::settings::{SETTING_COUNT, Setting, SettingsAck, fingerprint};
use core::f32::consts::TAU;

/// Frames in one telemetry batch, checksum excluded: `g h i j k s q x y`.
pub const TELEMETRY_FRAMES: usize = 9;
/// Largest telemetry batch on the wire, bytes (with its checksum frame).
pub const TELEMETRY_BATCH_MAX_LEN: usize = (TELEMETRY_FRAMES + 1) * FRAME_LEN;
/// Largest host batch the Mega buffers, frames (the host sends `G H I J L U`, and the eight
/// settings `M`..`T` in a batch of their own).
pub const RX_BATCH_CAPACITY: usize = 8;

/// The Mega's configuration. Defaults are the competition robot's; each says its source.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct McuConfig {
    /// Control period, µs. 20 000 (50 Hz): the original firmware's `robotconfig.h`
    /// (original-system.md §2.2). The firmware's timer makes this a board constant.
    pub control_period_us: u32,
    /// Watchdog timeout after the last `G` or `K`, µs. 100 000: original §2.2.
    pub watchdog_timeout_us: u32,
    /// Encoder ticks per wheel revolution. 2803.2 = 16 counts × 4 (quadrature) × 43.8
    /// (gearbox), original §2.2 (the paper's 2796.8 uses 43.7).
    pub ticks_per_wheel_rev: f32,
    /// Voltage that PWM `pwm_max` delivers, V: the battery voltage. 11.1 V, the 3S LiPo's
    /// nominal voltage, original §2.2. Also bounds the PI's limit ([`Self::voltage_limit_v`]).
    pub battery_voltage_v: f32,
    /// The PI's anti-windup and saturation limit, V; the battery voltage applies when it is
    /// lower. 11.1 V: the battery's, so by default the whole actuator range (§10.5).
    pub voltage_limit_v: f32,
    /// Largest PWM magnitude. 255: the Adafruit Motor Shield V2 library's 8-bit speed.
    pub pwm_max: i16,
    /// Largest PWM change per tick (slew limit). 100: original §2.2. Not applied to a
    /// watchdog stop, which is immediate.
    pub pwm_slew_per_tick: i16,
    /// Wheel speed controller, the same for all four wheels.
    pub pi: PiConfig,
    /// Close each telemetry batch with a checksum frame ([`crate::integrity`]). On by
    /// default; off makes the Mega speak exactly the original protocol.
    pub send_checksums: bool,
}

/// How long the stop on the switch holds the wheels at zero, µs, unless `U` 0 frees them
/// sooner. 100 000, as the watchdog's timeout: the host reads the switch in the batch of the
/// tick that stopped them and stops the wheels itself within about 45 ms (a batch on the
/// wire, its 20 ms tick, a command); a press too short for the host to see (one batch, lost
/// on the line, or two batches within one host tick) then costs the robot a pause, not the
/// leg, since the host's references apply again after it.
pub const SWITCH_STOP_HOLD_US: u32 = 100_000;

/// How long the solenoid stays on after a watchdog stop, µs (if it was on). The stop sets
/// PWM 0 and the wheels coast down with the motors' ~0.1 s time constant: released with the
/// stop, a carried part flew off at full speed (issue 17: a USB cable pulled out mid-carry,
/// the part then beyond where the robot looks for it); 300 ms later the robot moves at about
/// 5 % of its speed. A `G` or `K` within the hold keeps the solenoid as `L` last set it.
pub const SOLENOID_HOLD_AFTER_STOP_US: u32 = 300_000;

impl Default for McuConfig {
    fn default() -> Self {
        Self {
            control_period_us: 20_000,
            watchdog_timeout_us: 100_000,
            ticks_per_wheel_rev: 2803.2,
            battery_voltage_v: 11.1,
            voltage_limit_v: 11.1,
            pwm_max: 255,
            pwm_slew_per_tick: 100,
            pi: PiConfig::default(),
            send_checksums: true,
        }
    }
}

impl McuConfig {
    /// The value of `setting`, in its unit.
    pub fn setting(&self, setting: Setting) -> f32 {
        let pi = &self.pi;
        match setting {
            Setting::Kc => pi.gains.kc_v_per_rad_s,
            Setting::Ki => pi.gains.ki_v_per_rad,
            Setting::Kf => pi.gains.kf_v_per_rad_s,
            Setting::DeadZoneV0 => pi.dead_zone.v0_v,
            Setting::DeadZoneVd => pi.dead_zone.vd_v,
            Setting::BatteryVoltage => self.battery_voltage_v,
            Setting::VoltageLimit => self.voltage_limit_v,
            Setting::TicksPerWheelRev => self.ticks_per_wheel_rev,
        }
    }

    /// Every setting's value, in [`Setting`] order (what [`fingerprint`] covers).
    pub fn setting_values(&self) -> [f32; SETTING_COUNT] {
        Setting::ALL.map(|setting| self.setting(setting))
    }

    /// The commands that give a Mega this configuration's settings, in sending order.
    pub fn setting_commands(&self) -> [Command; SETTING_COUNT] {
        Setting::ALL.map(|setting| Command::Setting {
            setting,
            value: self.setting(setting),
        })
    }

    /// Set `setting` to `value` (unchecked: see [`Setting::validate`]).
    fn set(&mut self, setting: Setting, value: f32) {
        let pi = &mut self.pi;
        match setting {
            Setting::Kc => pi.gains.kc_v_per_rad_s = value,
            Setting::Ki => pi.gains.ki_v_per_rad = value,
            Setting::Kf => pi.gains.kf_v_per_rad_s = value,
            Setting::DeadZoneV0 => pi.dead_zone.v0_v = value,
            Setting::DeadZoneVd => pi.dead_zone.vd_v = value,
            Setting::BatteryVoltage => self.battery_voltage_v = value,
            Setting::VoltageLimit => self.voltage_limit_v = value,
            Setting::TicksPerWheelRev => self.ticks_per_wheel_rev = value,
        }
    }
}

/// What the firmware samples for one control tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TickInputs {
    /// Encoder counts since the previous tick, per wheel (motor index order).
    pub encoder_deltas: [i16; WHEEL_COUNT],
    /// The box switch is pressed (pin 53 reads 0).
    pub switch_pressed: bool,
    /// Invalid quadrature transitions since boot, per wheel, wrapping (from the encoder ISR).
    pub quadrature_errors: [u8; WHEEL_COUNT],
    /// Failed I2C transfers to the motor shield since boot, wrapping.
    pub i2c_faults: u8,
    /// Serial bytes lost since boot (receive buffer overruns plus telemetry bytes that did
    /// not fit the transmit buffer), wrapping.
    pub serial_bytes_dropped: u8,
}

/// What the firmware applies after a control tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Actuation {
    /// Signed PWM per motor, within ±`pwm_max`; negative = backward.
    pub pwm: [i16; WHEEL_COUNT],
    /// Electromagnet level.
    pub solenoid_on: bool,
}

/// Bytes to transmit, at most [`TELEMETRY_BATCH_MAX_LEN`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TxBatch {
    bytes: [u8; TELEMETRY_BATCH_MAX_LEN],
    len: usize,
}

impl TxBatch {
    /// The bytes to send, in order.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..self.len]
    }

    fn write(writer: &mut BatchWriter, frames: &[Frame]) -> Self {
        let mut batch = Self {
            bytes: [0; TELEMETRY_BATCH_MAX_LEN],
            len: 0,
        };
        // Every batch the Mega writes has at most TELEMETRY_FRAMES frames, which fit.
        batch.len = writer.write_batch(frames, &mut batch.bytes).unwrap_or(0);
        batch
    }
}

/// The result of a control tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickOutput {
    /// Motor PWMs and solenoid level to apply now.
    pub actuation: Actuation,
    /// The telemetry batch to send now.
    pub telemetry: TxBatch,
}

/// How a wheel is driven.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Drive {
    /// Stopped: PWM 0 (at boot and after a watchdog stop).
    Off,
    /// PI speed control towards a reference, wheel rad/s.
    Speed(f32),
    /// Open-loop PWM (from `K`).
    Pwm(i16),
}

/// What [`Mcu::begin_tick`] measured, for [`Mcu::finish_tick`].
#[derive(Clone, Copy, Debug)]
struct PendingTick {
    dt_s: f32,
    measured_rad_s: [f32; WHEEL_COUNT],
}

#[derive(Clone, Copy, Debug)]
struct WheelState {
    drive: Drive,
    controller: PiController,
    pwm: i16,
    total_ticks: i32,
}

/// The Mega's behaviour: see the module documentation.
#[derive(Clone, Debug)]
pub struct Mcu {
    config: McuConfig,
    receiver: BatchReceiver<RX_BATCH_CAPACITY>,
    writer: BatchWriter,
    wheels: [WheelState; WHEEL_COUNT],
    solenoid_requested: bool,
    last_feed_us: Option<u32>,
    timed_out: bool,
    /// When the watchdog stopped the motors, while the solenoid's hold after it runs.
    stopped_at_us: Option<u32>,
    last_tick_us: Option<u32>,
    pending: Option<PendingTick>,
    bad_messages: u8,
    settings_ack: SettingsAck,
    /// `U` armed the stop on the switch.
    stop_on_switch: bool,
    /// The last tick read the switch pressed with the stop armed.
    armed_and_pressed: bool,
    /// When the switch closed with the stop armed, while its hold lasts
    /// ([`SWITCH_STOP_HOLD_US`]).
    switch_stop_at_us: Option<u32>,
}

impl Mcu {
    /// The state at power-up: motors off, timed out until the host speaks.
    pub fn new(config: McuConfig) -> Self {
        let wheel = WheelState {
            drive: Drive::Off,
            controller: PiController::new(config.pi),
            pwm: 0,
            total_ticks: 0,
        };
        Self {
            config,
            receiver: BatchReceiver::new(HOST_CHECKSUM_CHANNEL),
            writer: BatchWriter::new(MCU_CHECKSUM_CHANNEL, config.send_checksums),
            wheels: [wheel; WHEEL_COUNT],
            solenoid_requested: false,
            last_feed_us: None,
            timed_out: true,
            stopped_at_us: None,
            last_tick_us: None,
            pending: None,
            bad_messages: 0,
            stop_on_switch: false,
            armed_and_pressed: false,
            switch_stop_at_us: None,
            settings_ack: SettingsAck {
                applied: 0,
                refused: 0,
                fingerprint: fingerprint(&config.setting_values()),
            },
        }
    }

    /// The acknowledgement of the settings in force, as sent on `y`.
    pub fn settings_ack(&self) -> SettingsAck {
        self.settings_ack
    }

    /// The configuration in force.
    pub fn config(&self) -> &McuConfig {
        &self.config
    }

    /// The boot batch: the reset frame `r00000000` (with its checksum frame).
    pub fn boot(&mut self) -> TxBatch {
        TxBatch::write(&mut self.writer, &[Telemetry::Reset.to_frame()])
    }

    /// Consume received bytes (any chunking) at time `now_us`.
    pub fn receive(&mut self, bytes: &[u8], now_us: u32) {
        let mut commands: [Option<Frame>; RX_BATCH_CAPACITY] = [None; RX_BATCH_CAPACITY];
        // Frames arrive through a callback; collect them per 9-byte chunk and apply them in
        // order once the receiver's borrow ends. A 9-byte chunk can complete at most one
        // checksum frame (releasing at most RX_BATCH_CAPACITY frames), or in compatible mode
        // at most five short frames, so nothing is dropped here.
        for chunk in bytes.chunks(FRAME_LEN) {
            let mut n = 0;
            self.receiver.feed(chunk, |frame| {
                if n < commands.len() {
                    commands[n] = Some(frame);
                    n += 1;
                }
            });
            for frame in commands[..n].iter().flatten() {
                self.apply(*frame, now_us);
            }
        }
    }

    fn apply(&mut self, frame: Frame, now_us: u32) {
        match Command::from_frame(frame) {
            Ok(Command::WheelSpeed { wheel, speed_rad_s }) => {
                let held = self.holds_switch_stop(now_us);
                let state = &mut self.wheels[wheel.index()];
                if !matches!(state.drive, Drive::Speed(_)) {
                    state.controller.reset();
                }
                state.drive = Drive::Speed(if held { 0.0 } else { speed_rad_s });
                // As in the original, G (wheel 0) feeds the watchdog: the host sends G..J
                // together, G first.
                if wheel == Wheel::BackRight {
                    self.feed_watchdog(now_us);
                }
            }
            Ok(Command::MotorPwm { wheel, pwm }) => {
                let state = &mut self.wheels[wheel.index()];
                state.controller.reset();
                state.drive = Drive::Pwm(pwm.clamp(-self.config.pwm_max, self.config.pwm_max));
                self.feed_watchdog(now_us);
            }
            Ok(Command::Solenoid { on }) => self.solenoid_requested = on,
            Ok(Command::StopOnSwitch { armed }) => {
                self.stop_on_switch = armed;
                if !armed {
                    self.switch_stop_at_us = None;
                }
            }
            Ok(Command::Setting { setting, value }) => self.apply_setting(setting, value),
            Err(_) => {
                self.bad_messages = self.bad_messages.wrapping_add(1);
                if let Some(setting) = Setting::from_channel(frame.channel()) {
                    self.settings_ack.refused |= setting.bit();
                }
            }
        }
    }

    fn apply_setting(&mut self, setting: Setting, value: f32) {
        if setting
            .validate(value, self.config.battery_voltage_v)
            .is_err()
        {
            self.bad_messages = self.bad_messages.wrapping_add(1);
            self.settings_ack.refused |= setting.bit();
            return;
        }
        self.config.set(setting, value);
        for wheel in &mut self.wheels {
            wheel.controller.set_config(self.config.pi);
        }
        self.settings_ack.applied |= setting.bit();
        self.settings_ack.refused &= !setting.bit();
        self.settings_ack.fingerprint = fingerprint(&self.config.setting_values());
    }

    fn feed_watchdog(&mut self, now_us: u32) {
        self.last_feed_us = Some(now_us);
        self.timed_out = false;
        self.stopped_at_us = None;
    }

    /// The solenoid level to apply now: as last commanded by `L`, and released while the
    /// watchdog has the motors stopped, from [`SOLENOID_HOLD_AFTER_STOP_US`] after the stop.
    pub fn solenoid_on(&self) -> bool {
        self.solenoid_requested && (!self.timed_out || self.stopped_at_us.is_some())
    }

    /// True from the tick at which the switch stopped the wheels (`U`,
    /// [`Command::StopOnSwitch`]) until `U` 0 or the first tick after its hold
    /// ([`SWITCH_STOP_HOLD_US`]).
    pub fn stopped_on_switch(&self) -> bool {
        self.switch_stop_at_us.is_some()
    }

    /// True while the switch's stop holds the wheels at `now_us`.
    fn holds_switch_stop(&self, now_us: u32) -> bool {
        self.switch_stop_at_us
            .is_some_and(|at| now_us.wrapping_sub(at) < SWITCH_STOP_HOLD_US)
    }

    /// True while the watchdog has the motors stopped (also at boot, before the host speaks).
    pub fn timed_out(&self) -> bool {
        self.timed_out
    }

    /// Receive-side link counters.
    pub fn link_stats(&self) -> LinkStats {
        self.receiver.stats()
    }

    /// One control tick at `now_us`: [`Mcu::begin_tick`] then [`Mcu::finish_tick`].
    pub fn control_tick(&mut self, now_us: u32, inputs: &TickInputs) -> TickOutput {
        let telemetry = self.begin_tick(now_us, inputs);
        let actuation = self.finish_tick(now_us);
        TickOutput {
            actuation,
            telemetry,
        }
    }

    /// First half of a control tick: account for the inputs and return the telemetry batch,
    /// so the caller can start sending it before the controllers run. The telemetry does not
    /// depend on the control computation, so the time from the tick to its first byte is the
    /// same whatever the motors are doing.
    pub fn begin_tick(&mut self, now_us: u32, inputs: &TickInputs) -> TxBatch {
        let period_us = match self.last_tick_us {
            Some(last) if now_us != last => now_us.wrapping_sub(last),
            _ => self.config.control_period_us,
        };
        self.last_tick_us = Some(now_us);
        if !self.holds_switch_stop(now_us) {
            self.switch_stop_at_us = None;
        }
        let armed_and_pressed = self.stop_on_switch && inputs.switch_pressed;
        if armed_and_pressed && !self.armed_and_pressed {
            self.switch_stop_at_us = Some(now_us);
            for wheel in &mut self.wheels {
                if let Drive::Speed(_) = wheel.drive {
                    wheel.drive = Drive::Speed(0.0);
                }
            }
        }
        self.armed_and_pressed = armed_and_pressed;
        let dt_s = period_us as f32 * 1.0e-6;
        let rad_per_tick = TAU / self.config.ticks_per_wheel_rev;
        let mut measured_rad_s = [0.0; WHEEL_COUNT];
        for (k, wheel) in self.wheels.iter_mut().enumerate() {
            let delta = inputs.encoder_deltas[k];
            wheel.total_ticks = wheel.total_ticks.wrapping_add(i32::from(delta));
            measured_rad_s[k] = f32::from(delta) * rad_per_tick / dt_s;
        }
        self.pending = Some(PendingTick {
            dt_s,
            measured_rad_s,
        });

        let faults = Faults {
            i2c: inputs.i2c_faults,
            rx_batches_discarded: self.receiver.stats().batches_discarded() as u8,
            rx_bad_messages: self.bad_messages,
            serial_bytes_dropped: inputs.serial_bytes_dropped,
        };
        let mut frames = [Telemetry::Reset.to_frame(); TELEMETRY_FRAMES];
        for (k, wheel) in self.wheels.iter().enumerate() {
            frames[k] = Telemetry::Ticks {
                wheel: Wheel::ALL[k],
                total: wheel.total_ticks,
            }
            .to_frame();
        }
        frames[4] = Telemetry::LoopPeriod { period_us }.to_frame();
        frames[5] = Telemetry::Switch {
            pressed: inputs.switch_pressed,
        }
        .to_frame();
        frames[6] =
            Telemetry::QuadratureErrors(QuadratureErrors(inputs.quadrature_errors)).to_frame();
        frames[7] = Telemetry::Faults(faults).to_frame();
        frames[8] = Telemetry::SettingsAck(self.settings_ack).to_frame();
        TxBatch::write(&mut self.writer, &frames)
    }

    /// Second half of a control tick at `now_us`: the watchdog and the speed controllers,
    /// using what [`Mcu::begin_tick`] measured (a wheel standing still over the nominal period
    /// if it was not called). Returns the PWMs and solenoid level to apply now.
    pub fn finish_tick(&mut self, now_us: u32) -> Actuation {
        let PendingTick {
            dt_s,
            measured_rad_s,
        } = self.pending.take().unwrap_or(PendingTick {
            dt_s: self.config.control_period_us as f32 * 1.0e-6,
            measured_rad_s: [0.0; WHEEL_COUNT],
        });
        let expired = match self.last_feed_us {
            None => true,
            Some(fed) => now_us.wrapping_sub(fed) > self.config.watchdog_timeout_us,
        };
        if expired && !self.timed_out {
            self.stopped_at_us = Some(now_us);
        }
        if let Some(stopped) = self.stopped_at_us
            && now_us.wrapping_sub(stopped) >= SOLENOID_HOLD_AFTER_STOP_US
        {
            self.solenoid_requested = false;
            self.stopped_at_us = None;
        }
        if expired {
            self.timed_out = true;
            for wheel in &mut self.wheels {
                wheel.drive = Drive::Off;
                wheel.controller.reset();
            }
        }

        let volts_to_pwm = f32::from(self.config.pwm_max) / self.config.battery_voltage_v;
        let limit_v = self
            .config
            .voltage_limit_v
            .min(self.config.battery_voltage_v);
        let mut actuation = Actuation {
            pwm: [0; WHEEL_COUNT],
            solenoid_on: self.solenoid_on(),
        };
        for (k, wheel) in self.wheels.iter_mut().enumerate() {
            let target = match wheel.drive {
                Drive::Off => None,
                Drive::Pwm(pwm) => Some(pwm),
                Drive::Speed(reference) => {
                    let volts = wheel
                        .controller
                        .step(reference, measured_rad_s[k], dt_s, limit_v);
                    Some(round_to_pwm(volts * volts_to_pwm, self.config.pwm_max))
                }
            };
            wheel.pwm = match target {
                None => 0,
                Some(target) => {
                    let slew = self.config.pwm_slew_per_tick;
                    let step = target.saturating_sub(wheel.pwm).clamp(-slew, slew);
                    wheel.pwm.saturating_add(step)
                }
            };
            actuation.pwm[k] = wheel.pwm;
        }
        actuation
    }
}

/// `value` rounded half away from zero and clamped to ±`max` (`f32::round` is not in
/// `core`).
fn round_to_pwm(value: f32, max: i16) -> i16 {
    let max_f = f32::from(max);
    let clamped = value.clamp(-max_f, max_f);
    let rounded = if clamped >= 0.0 {
        clamped + 0.5
    } else {
        clamped - 0.5
    };
    rounded as i16
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::channels::Decoder;
    use crate::integrity::BatchWriter;
    use std::vec::Vec;

    const PERIOD: u32 = 20_000;

    fn host() -> BatchWriter {
        BatchWriter::new(HOST_CHECKSUM_CHANNEL, true)
    }

    fn send(mcu: &mut Mcu, writer: &mut BatchWriter, commands: &[Command], now_us: u32) {
        let frames: Vec<Frame> = commands.iter().map(Command::to_frame).collect();
        let mut buf = [0u8; 128];
        let n = writer.write_batch(&frames, &mut buf).unwrap();
        mcu.receive(&buf[..n], now_us);
    }

    fn speeds(speed_rad_s: f32) -> Vec<Command> {
        Wheel::ALL
            .iter()
            .map(|&wheel| Command::WheelSpeed { wheel, speed_rad_s })
            .collect()
    }

    fn decode(bytes: &[u8]) -> Vec<Frame> {
        let mut frames = Vec::new();
        Decoder::new().feed(bytes, |f| frames.push(f));
        frames
    }

    #[test]
    fn boot_sends_the_reset_frame() {
        let mut mcu = Mcu::new(McuConfig {
            send_checksums: false,
            ..McuConfig::default()
        });
        assert_eq!(mcu.boot().as_bytes(), b"r00000000");
        let mut mcu = Mcu::new(McuConfig::default());
        let boot = mcu.boot();
        assert_eq!(&boot.as_bytes()[..9], b"r00000000");
        assert_eq!(boot.as_bytes()[9], b'z');
    }

    #[test]
    fn telemetry_batch_contents_and_order() {
        let mut mcu = Mcu::new(McuConfig::default());
        mcu.boot();
        let inputs = TickInputs {
            encoder_deltas: [5, -3, 0, 1200],
            switch_pressed: true,
            quadrature_errors: [1, 0, 0, 2],
            i2c_faults: 3,
            serial_bytes_dropped: 9,
        };
        mcu.control_tick(0, &inputs);
        let out = mcu.control_tick(20_016, &inputs);
        let frames = decode(out.telemetry.as_bytes());
        let letters: Vec<u8> = frames.iter().map(|f| f.channel()).collect();
        assert_eq!(letters, b"ghijksqxyz");
        let messages: Vec<Telemetry> = frames[..9]
            .iter()
            .map(|f| Telemetry::from_frame(*f).unwrap())
            .collect();
        assert_eq!(
            messages[..6],
            [
                Telemetry::Ticks {
                    wheel: Wheel::BackRight,
                    total: 10
                },
                Telemetry::Ticks {
                    wheel: Wheel::BackLeft,
                    total: -6
                },
                Telemetry::Ticks {
                    wheel: Wheel::FrontRight,
                    total: 0
                },
                Telemetry::Ticks {
                    wheel: Wheel::FrontLeft,
                    total: 2400
                },
                Telemetry::LoopPeriod { period_us: 20_016 },
                Telemetry::Switch { pressed: true },
            ]
        );
        assert_eq!(
            messages[6],
            Telemetry::QuadratureErrors(QuadratureErrors([1, 0, 0, 2]))
        );
        assert_eq!(
            messages[7],
            Telemetry::Faults(Faults {
                i2c: 3,
                rx_batches_discarded: 0,
                rx_bad_messages: 0,
                serial_bytes_dropped: 9,
            })
        );
    }

    #[test]
    fn the_two_halves_of_a_tick_equal_a_whole_tick() {
        let script = |mcu: &mut Mcu, split: bool| {
            let mut host = host();
            let mut outputs = Vec::new();
            for i in 0..10u32 {
                send(mcu, &mut host, &speeds(3.0 + i as f32), i * PERIOD);
                let inputs = TickInputs {
                    encoder_deltas: [i as i16 * 7; 4],
                    ..TickInputs::default()
                };
                let out = if split {
                    let telemetry = mcu.begin_tick(i * PERIOD, &inputs);
                    TickOutput {
                        actuation: mcu.finish_tick(i * PERIOD),
                        telemetry,
                    }
                } else {
                    mcu.control_tick(i * PERIOD, &inputs)
                };
                outputs.push(out);
            }
            outputs
        };
        let whole = script(&mut Mcu::new(McuConfig::default()), false);
        let halves = script(&mut Mcu::new(McuConfig::default()), true);
        assert_eq!(whole, halves);
    }

    /// Asks every wheel for 10 rad/s while it turns at 5 (45 ticks a period), `U` armed
    /// (until `disarm_at`) or not, the switch closing at the fifth tick; the PWMs of wheel 0,
    /// tick by tick.
    fn approach_onto_the_switch(armed: bool, disarm_at: Option<u32>) -> Vec<i16> {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut host = host();
        (0..12u32)
            .map(|i| {
                let now = i * PERIOD;
                let mut batch = speeds(10.0);
                let armed_now = armed && disarm_at.is_none_or(|at| i < at);
                batch.push(Command::StopOnSwitch { armed: armed_now });
                send(&mut mcu, &mut host, &batch, now);
                let inputs = TickInputs {
                    encoder_deltas: [45; 4],
                    switch_pressed: i >= 5,
                    ..TickInputs::default()
                };
                mcu.control_tick(now, &inputs).actuation.pwm[0]
            })
            .collect()
    }

    #[test]
    fn armed_the_mega_brakes_from_the_tick_that_reads_the_switch_for_the_hold() {
        let pwm = approach_onto_the_switch(true, None);
        assert!(pwm[4] > 0, "driving before the switch: {pwm:?}");
        // From the tick that reads it (5, at 100 ms) for the 100 ms hold, the references are
        // 0 whatever the host still sends: the PI brakes the turning wheel.
        for (i, &p) in pwm.iter().enumerate().take(10).skip(5) {
            assert!(p < pwm[4], "tick {i} did not brake: {pwm:?}");
        }
        assert!(pwm[9] <= 0, "still driving at the hold's end: {pwm:?}");
        // A host that did not see the press gets its wheels back after the hold.
        assert!(pwm[11] > 0, "{pwm:?}");
    }

    #[test]
    fn disarmed_or_never_armed_the_switch_leaves_the_wheels_to_the_host() {
        let never = approach_onto_the_switch(false, None);
        assert!(never.iter().skip(1).all(|&p| p > 0), "{never:?}");
        // Disarmed at tick 6, within the hold, the host's 10 rad/s drives the wheels again.
        let freed = approach_onto_the_switch(true, Some(6));
        assert!(
            freed[5] < freed[4] && freed[8] > 0 && freed[9] > 0,
            "{freed:?}"
        );
    }

    #[test]
    fn motors_stay_off_until_the_host_speaks() {
        let mut mcu = Mcu::new(McuConfig::default());
        assert!(mcu.timed_out());
        let out = mcu.control_tick(0, &TickInputs::default());
        assert_eq!(out.actuation.pwm, [0; 4]);
        assert!(!out.telemetry.as_bytes().is_empty());
    }

    #[test]
    fn watchdog_stops_motors_after_100_ms_and_telemetry_keeps_flowing() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut host = host();
        send(&mut mcu, &mut host, &speeds(10.0), 0);
        send(&mut mcu, &mut host, &[Command::Solenoid { on: true }], 0);
        assert!(mcu.solenoid_on());
        let mut t = 0;
        let mut stopped_at = None;
        while t <= 500_000 {
            let out = mcu.control_tick(t, &TickInputs::default());
            assert!(
                !out.telemetry.as_bytes().is_empty(),
                "telemetry stopped at {t}"
            );
            if stopped_at.is_none() && out.actuation.pwm == [0; 4] && t > 0 {
                stopped_at = Some(t);
            }
            // The solenoid holds for 300 ms after the stop at 120 ms.
            assert_eq!(out.actuation.solenoid_on, t < 420_000, "at {t} µs");
            if t <= 100_000 {
                assert!(
                    out.actuation.pwm.iter().all(|&p| p > 0),
                    "stopped early at {t}"
                );
            }
            t += PERIOD;
        }
        // Last G at 0: the first tick more than 100 ms later is at 120 ms.
        assert_eq!(stopped_at, Some(120_000));
        assert!(mcu.timed_out());
        // A new G resumes control.
        send(&mut mcu, &mut host, &speeds(10.0), t);
        let out = mcu.control_tick(t, &TickInputs::default());
        assert!(out.actuation.pwm.iter().all(|&p| p > 0));
        // The solenoid was released by the trip and needs a new L.
        assert!(!mcu.solenoid_on());
    }

    #[test]
    fn a_g_within_the_solenoids_hold_after_a_stop_keeps_the_part() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut host = host();
        send(&mut mcu, &mut host, &speeds(10.0), 0);
        send(&mut mcu, &mut host, &[Command::Solenoid { on: true }], 0);
        let mut t = 0;
        while t <= 200_000 {
            mcu.control_tick(t, &TickInputs::default());
            t += PERIOD;
        }
        // Stopped at 120 ms, the solenoid still on; the host speaks again at 210 ms.
        assert!(mcu.timed_out() && mcu.solenoid_on());
        send(&mut mcu, &mut host, &speeds(10.0), 210_000);
        let out = mcu.control_tick(220_000, &TickInputs::default());
        assert!(!mcu.timed_out());
        assert!(out.actuation.solenoid_on && out.actuation.pwm.iter().all(|&p| p > 0));
        // Silent again: stopped at 340 ms, the solenoid still held when a G comes at 600 ms.
        send(&mut mcu, &mut host, &speeds(10.0), 600_000);
        assert!(
            mcu.control_tick(600_000, &TickInputs::default())
                .actuation
                .solenoid_on
        );
    }

    #[test]
    fn only_g_and_k_feed_the_watchdog() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut host = host();
        send(&mut mcu, &mut host, &speeds(5.0), 0);
        let mut t = 0;
        while t <= 200_000 {
            // H, I, J and L keep arriving, but not G.
            send(&mut mcu, &mut host, &speeds(5.0)[1..], t);
            send(&mut mcu, &mut host, &[Command::Solenoid { on: true }], t);
            mcu.control_tick(t, &TickInputs::default());
            t += PERIOD;
        }
        assert!(mcu.timed_out());
        send(
            &mut mcu,
            &mut host,
            &[Command::MotorPwm {
                wheel: Wheel::FrontLeft,
                pwm: 50,
            }],
            t,
        );
        assert!(!mcu.timed_out());
    }

    #[test]
    fn k_overrides_one_wheel_with_slew_limit() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut host = host();
        send(&mut mcu, &mut host, &speeds(0.0), 0);
        send(
            &mut mcu,
            &mut host,
            &[Command::MotorPwm {
                wheel: Wheel::FrontRight,
                pwm: -250,
            }],
            0,
        );
        let pwm: Vec<i16> = (0..4)
            .map(|i| {
                mcu.control_tick(i * PERIOD, &TickInputs::default())
                    .actuation
                    .pwm[2]
            })
            .collect();
        assert_eq!(pwm, [-100, -200, -250, -250]);
        // Out-of-range PWM is clamped to the shield's 255.
        send(
            &mut mcu,
            &mut host,
            &[Command::MotorPwm {
                wheel: Wheel::BackLeft,
                pwm: 1000,
            }],
            4 * PERIOD,
        );
        let mut last = 0;
        for i in 4..8 {
            last = mcu
                .control_tick(i * PERIOD, &TickInputs::default())
                .actuation
                .pwm[1];
        }
        assert_eq!(last, 255);
        // A G on that wheel returns it to closed loop.
        send(&mut mcu, &mut host, &speeds(0.0), 8 * PERIOD);
        let mut out = mcu.control_tick(8 * PERIOD, &TickInputs::default());
        for i in 9..12 {
            out = mcu.control_tick(i * PERIOD, &TickInputs::default());
        }
        assert_eq!(out.actuation.pwm, [0; 4]);
    }

    #[test]
    fn closed_loop_uses_the_measured_period() {
        // 10 rad/s over 20 ms is 89.2 ticks at 2803.2 ticks/rev. If the period were 25 ms,
        // the same ticks would be 8 rad/s and the controller would push harder.
        let ticks = (10.0f32 * 0.02 * 2803.2 / TAU) as i16;
        let pwm_after = |period: u32| {
            let mut mcu = Mcu::new(McuConfig::default());
            let mut host = host();
            send(&mut mcu, &mut host, &speeds(10.0), 0);
            mcu.control_tick(0, &TickInputs::default());
            let inputs = TickInputs {
                encoder_deltas: [ticks; 4],
                ..TickInputs::default()
            };
            mcu.control_tick(period, &inputs).actuation.pwm[0]
        };
        assert!(pwm_after(25_000) > pwm_after(20_000));
    }

    #[test]
    fn corrupted_host_batches_are_not_applied_in_strict_mode() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut host = host();
        send(&mut mcu, &mut host, &speeds(0.0), 0); // switches the Mega to strict mode
        let frames: Vec<Frame> = [Command::MotorPwm {
            wheel: Wheel::BackRight,
            pwm: 80,
        }]
        .iter()
        .map(Command::to_frame)
        .collect();
        let mut buf = [0u8; 32];
        let n = host.write_batch(&frames, &mut buf).unwrap();
        buf[5] = b'9'; // K0000 0050 -> K0000 9050: a different PWM
        mcu.receive(&buf[..n], 0);
        assert_eq!(mcu.link_stats().batches_corrupt, 1);
        let out = mcu.control_tick(0, &TickInputs::default());
        assert_eq!(out.actuation.pwm, [0; 4]);
    }

    #[test]
    fn an_original_host_without_checksums_is_obeyed() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut bytes = Vec::new();
        for cmd in speeds(0.0).into_iter().chain([
            Command::MotorPwm {
                wheel: Wheel::FrontLeft,
                pwm: -60,
            },
            Command::Solenoid { on: true },
        ]) {
            bytes.extend_from_slice(&cmd.to_frame().encode());
        }
        mcu.receive(&bytes, 0);
        assert!(mcu.solenoid_on());
        let out = mcu.control_tick(0, &TickInputs::default());
        assert_eq!(out.actuation.pwm, [0, 0, 0, -60]);
    }

    #[test]
    fn malformed_commands_are_counted_and_ignored() {
        let mut mcu = Mcu::new(McuConfig {
            send_checksums: false,
            ..McuConfig::default()
        });
        let mut bytes = Vec::new();
        bytes.extend_from_slice(&Frame::new(b'G', f32::NAN.to_bits()).unwrap().encode());
        bytes.extend_from_slice(&Frame::new(b'L', 7).unwrap().encode());
        mcu.receive(&bytes, 0);
        assert!(mcu.timed_out());
        let out = mcu.control_tick(0, &TickInputs::default());
        let frames = decode(out.telemetry.as_bytes());
        let faults = Telemetry::from_frame(frames[7]).unwrap();
        assert_eq!(
            faults,
            Telemetry::Faults(Faults {
                rx_bad_messages: 2,
                ..Faults::default()
            })
        );
    }

    #[test]
    fn cumulative_ticks_wrap_like_the_original_uint32() {
        let mut mcu = Mcu::new(McuConfig::default());
        let inputs = TickInputs {
            encoder_deltas: [i16::MAX; 4],
            ..TickInputs::default()
        };
        let mut t = 0u32;
        for _ in 0..70_000 {
            mcu.control_tick(t, &inputs);
            t = t.wrapping_add(PERIOD);
        }
        let out = mcu.control_tick(t, &inputs);
        let frames = decode(out.telemetry.as_bytes());
        let expected = (i32::from(i16::MAX)).wrapping_mul(70_001);
        assert_eq!(
            Telemetry::from_frame(frames[0]).unwrap(),
            Telemetry::Ticks {
                wheel: Wheel::BackRight,
                total: expected
            }
        );
    }

    fn ack_of(out: &TickOutput) -> SettingsAck {
        let frames = decode(out.telemetry.as_bytes());
        match Telemetry::from_frame(frames[8]) {
            Ok(Telemetry::SettingsAck(ack)) => ack,
            other => panic!("frame 8 is not y: {other:?}"),
        }
    }

    #[test]
    fn settings_from_the_host_replace_the_defaults_and_are_acknowledged() {
        let first_pwm = |mcu: &mut Mcu, host: &mut BatchWriter| {
            send(mcu, host, &speeds(10.0), 0);
            mcu.control_tick(0, &TickInputs::default()).actuation.pwm[0]
        };
        let mut defaults = Mcu::new(McuConfig::default());
        let out = defaults.control_tick(0, &TickInputs::default());
        let ack = ack_of(&out);
        assert_eq!((ack.applied, ack.refused), (0, 0));
        assert!(!ack.confirms(&McuConfig::default().setting_values()));
        let default_pwm = first_pwm(&mut defaults, &mut host());

        let mut wanted = McuConfig::default();
        wanted.pi.gains.kc_v_per_rad_s *= 2.0;
        wanted.pi.gains.ki_v_per_rad *= 2.0;
        wanted.voltage_limit_v = 6.0;
        wanted.ticks_per_wheel_rev = 1400.0;
        let mut mcu = Mcu::new(McuConfig::default());
        let mut host = host();
        send(&mut mcu, &mut host, &wanted.setting_commands(), 0);
        assert_eq!(*mcu.config(), wanted);
        let ack = ack_of(&mcu.control_tick(0, &TickInputs::default()));
        assert!(ack.confirms(&wanted.setting_values()), "{ack:?}");
        // Twice the gains: twice the first drive (10 rad/s of error, integral 0.2 rad).
        let doubled = first_pwm(&mut mcu, &mut host);
        assert_eq!(doubled, (2 * default_pwm).min(100));
        // The 6 V limit holds the output at 6/11.1 of full PWM.
        let mut pwm = 0;
        for i in 1..20 {
            send(&mut mcu, &mut host, &speeds(10.0), i * PERIOD);
            pwm = mcu
                .control_tick(i * PERIOD, &TickInputs::default())
                .actuation
                .pwm[0];
        }
        assert_eq!(pwm, round_to_pwm(6.0 * 255.0 / 11.1, 255));
    }

    #[test]
    fn invalid_settings_are_refused_reported_and_never_applied() {
        let mut mcu = Mcu::new(McuConfig::default());
        let mut host = host();
        let frames = [
            Frame::new(b'M', f32::NAN.to_bits()).unwrap(),
            Command::Setting {
                setting: Setting::Ki,
                value: -1.0,
            }
            .to_frame(),
            Command::Setting {
                setting: Setting::VoltageLimit,
                value: 12.0,
            }
            .to_frame(),
            Command::Setting {
                setting: Setting::Kf,
                value: 0.25,
            }
            .to_frame(),
        ];
        let mut buf = [0u8; 64];
        let n = host.write_batch(&frames, &mut buf).unwrap();
        mcu.receive(&buf[..n], 0);
        let mut expected = McuConfig::default();
        expected.pi.gains.kf_v_per_rad_s = 0.25;
        assert_eq!(*mcu.config(), expected);
        let out = mcu.control_tick(0, &TickInputs::default());
        let ack = ack_of(&out);
        assert_eq!(ack.applied, Setting::Kf.bit());
        let refused = Setting::Kc.bit() | Setting::Ki.bit() | Setting::VoltageLimit.bit();
        assert_eq!(ack.refused, refused);
        let faults = Telemetry::from_frame(decode(out.telemetry.as_bytes())[7]).unwrap();
        assert!(matches!(faults, Telemetry::Faults(f) if f.rx_bad_messages == 3));
        // A valid value clears the refusal; a lower battery then bounds the limit.
        send(
            &mut mcu,
            &mut host,
            &[Command::Setting {
                setting: Setting::VoltageLimit,
                value: 11.0,
            }],
            0,
        );
        assert_eq!(
            mcu.settings_ack().refused,
            Setting::Kc.bit() | Setting::Ki.bit()
        );
        send(
            &mut mcu,
            &mut host,
            &[
                Command::Setting {
                    setting: Setting::BatteryVoltage,
                    value: 7.4,
                },
                Command::WheelSpeed {
                    wheel: Wheel::BackRight,
                    speed_rad_s: 30.0,
                },
            ],
            0,
        );
        let mut volts = 0.0;
        for i in 1..10 {
            send(&mut mcu, &mut host, &speeds(30.0)[..1], i * PERIOD);
            let pwm = mcu
                .control_tick(i * PERIOD, &TickInputs::default())
                .actuation
                .pwm[0];
            volts = f32::from(pwm) * 7.4 / 255.0;
        }
        assert!((volts - 7.4).abs() < 0.03, "{volts} V");
    }
}
