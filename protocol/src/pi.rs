//! The wheel speed controller (paper §V.B; original-system.md §2.2, §2.5).
//!
//! Per control period, for reference `w_ref` and measured speed `w` (wheel rad/s):
//!
//! 1. `e = w_ref − w`; candidate integral `I* = I + e·dt`; if `w_ref == 0` exactly, `I* = 0`
//!    (the original clears the integral at a zero reference so a stopped wheel does not hum);
//! 2. `u = Kc·e + Ki·I* + Kf·w_ref` (PI plus feed-forward), volts;
//! 3. Hammerstein dead-zone compensation `u' = D(u)` with parameters (V0, Vd): for `u > Vd`,
//!    `u − Vd + V0`; for `u ≤ −Vd`, `u + Vd − V0`; in between `u·V0/Vd` (0 if `Vd = 0`).
//!    With `V0 = Vd = 0` it is the identity, as in the shipped original;
//! 4. anti-windup by conditional integration: if `|u'|` exceeds the actuator limit and `I*`
//!    would push it further out, keep the old integral and recompute `u'`;
//! 5. saturate `u'` to ± the limit.
//!
//! Fixing original-system.md §10.5, the limit is the actuator's *real* limit, passed in on
//! every step (the battery voltage, which is what PWM 255 delivers), not a fixed 12 V, and the
//! anti-windup test is made on the voltage actually sent to the motor (after the dead zone).

/// PI gains and feed-forward.
///
/// Defaults: the original firmware's own tuning rule (IMC with the closed-loop time constant
/// equal to the motor's, τ_cl = τ = 0.1 s, so Kc·K = 1 and Ti = τ; original-system.md §2.2)
/// applied to the motor's *measured* gain K = 2.19 (rad/s)/V (251 rpm at 12 V; the recorded
/// PWM steps in `shared/data` give 2.17). The original applied the rule to K = 4.5, about
/// twice the real gain, which halved its Kc and Ki, and made up with a feed-forward of
/// 0.456 V/(rad/s) = 1/2.19. With the correct K the PI alone places the closed-loop pole at
/// τ, so the feed-forward is 0: added on top it doubles the initial drive and overshoots.
/// Measured on the motor model (K 2.19, τ 0.1 s, dead zone 0.22 V, 20 ms ticks, slew 100):
/// a 10 rad/s step settles within ±5 % in 240 ms with no overshoot, against 580 ms and
/// 16 % overshoot for [`PiGains::ORIGINAL`] (`hil-tests` checks it on the firmware ELF).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiGains {
    /// Proportional gain Kc, V per (rad/s). Default 1/2.19 = 0.4566.
    pub kc_v_per_rad_s: f32,
    /// Integral gain Ki = Kc/Ti, V per rad. Default Ti = 0.1 s: 4.566.
    pub ki_v_per_rad: f32,
    /// Feed-forward Kf, V per (rad/s) of reference. Default 0.
    pub kf_v_per_rad_s: f32,
}

/// Measured motor gain, wheel (rad/s) per V: the default tuning's plant model (see
/// [`PiGains`]).
pub const MOTOR_GAIN_RAD_S_PER_V: f32 = 2.19;
/// Motor time constant, s: the default tuning's plant model (see [`PiGains`]).
pub const MOTOR_TIME_CONSTANT_S: f32 = 0.1;

impl PiGains {
    /// The original firmware's values: Kc = 1/4.5, Ki = Kc/0.1, Kf = 0.456294584
    /// (original-system.md §2.2), for reproducing the original.
    pub const ORIGINAL: PiGains = PiGains {
        kc_v_per_rad_s: 1.0 / 4.5,
        ki_v_per_rad: (1.0 / 4.5) / 0.1,
        kf_v_per_rad_s: 0.456_294_58,
    };
}

impl Default for PiGains {
    fn default() -> Self {
        let kc = 1.0 / MOTOR_GAIN_RAD_S_PER_V;
        Self {
            kc_v_per_rad_s: kc,
            ki_v_per_rad: kc / MOTOR_TIME_CONSTANT_S,
            kf_v_per_rad_s: 0.0,
        }
    }
}

/// Hammerstein dead-zone compensation parameters, volts.
///
/// Default: disabled (`V0 = Vd = 0`), as shipped: the original defines V0 = 0.20 V and
/// Vd = 0.12 V (`kMotHammV0`, `kMotHammVd`) but never uses them; the feed-forward does the
/// dead-zone job (original-system.md §2.5).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeadZone {
    /// V0: the motor's estimated dead zone, V.
    pub v0_v: f32,
    /// Vd: the controller output range mapped onto ±V0, V.
    pub vd_v: f32,
}

impl DeadZone {
    /// The original's (unused) constants, for teams that identify their own dead zone.
    pub const ORIGINAL_UNUSED: DeadZone = DeadZone {
        v0_v: 0.20,
        vd_v: 0.12,
    };

    /// The compensated voltage for controller output `u_v`.
    pub fn apply(&self, u_v: f32) -> f32 {
        let (v0, vd) = (self.v0_v, self.vd_v);
        if u_v > vd {
            u_v - vd + v0
        } else if u_v <= -vd {
            u_v + vd - v0
        } else if vd == 0.0 {
            0.0
        } else {
            u_v * v0 / vd
        }
    }
}

/// Everything that configures one wheel's controller.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PiConfig {
    /// Gains.
    pub gains: PiGains,
    /// Dead-zone compensation.
    pub dead_zone: DeadZone,
}

/// One wheel's PI speed controller state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PiController {
    config: PiConfig,
    integral_rad: f32,
}

impl PiController {
    /// A controller with a zero integral.
    pub const fn new(config: PiConfig) -> Self {
        Self {
            config,
            integral_rad: 0.0,
        }
    }

    /// Use `config` from the next step on, keeping the integral (new gains from the host
    /// take effect without a jump in the integral's state).
    pub fn set_config(&mut self, config: PiConfig) {
        self.config = config;
    }

    /// Clear the integral (when the controller is enabled or disabled).
    pub fn reset(&mut self) {
        self.integral_rad = 0.0;
    }

    /// The integral of the error, rad.
    pub fn integral_rad(&self) -> f32 {
        self.integral_rad
    }

    /// One control step: the motor voltage for reference `reference_rad_s` and measurement
    /// `measured_rad_s` over `dt_s` seconds, within ±`limit_v` (the actuator's real limit).
    pub fn step(
        &mut self,
        reference_rad_s: f32,
        measured_rad_s: f32,
        dt_s: f32,
        limit_v: f32,
    ) -> f32 {
        let PiGains {
            kc_v_per_rad_s: kc,
            ki_v_per_rad: ki,
            kf_v_per_rad_s: kf,
        } = self.config.gains;
        let error = reference_rad_s - measured_rad_s;
        let candidate = if reference_rad_s == 0.0 {
            0.0
        } else {
            self.integral_rad + error * dt_s
        };
        let output = |integral: f32| {
            self.config
                .dead_zone
                .apply(kc * error + ki * integral + kf * reference_rad_s)
        };
        let mut u = output(candidate);
        let winding_up = (u > limit_v && candidate > 0.0) || (u < -limit_v && candidate < 0.0);
        if winding_up {
            u = output(self.integral_rad);
        } else {
            self.integral_rad = candidate;
        }
        u.clamp(-limit_v, limit_v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// First-order motor: dw/dt = (K·u − w)/τ, with the measured K = 2.19 (rad/s)/V and
    /// τ = 0.1 s, integrated finely inside each control period.
    struct Motor {
        w: f32,
        gain: f32,
        tau_s: f32,
    }

    impl Motor {
        fn new() -> Self {
            Self {
                w: 0.0,
                gain: 4.5,
                tau_s: 0.1,
            }
        }
        fn run(&mut self, u: f32, dt_s: f32) {
            let steps = 100;
            let h = dt_s / steps as f32;
            for _ in 0..steps {
                self.w += h * (self.gain * u - self.w) / self.tau_s;
            }
        }
    }

    const DT: f32 = 0.02;
    const BATTERY: f32 = 11.1;

    /// The last time (s) the wheel was outside ±5 % of `reference` over 1 s, and its peak.
    fn settling(gains: PiGains, reference: f32) -> (f32, f32) {
        let mut pi = PiController::new(PiConfig {
            gains,
            ..PiConfig::default()
        });
        let mut motor = Motor::new();
        let (mut settled_at, mut peak) = (0.0, 0.0f32);
        for k in 1..=50 {
            let u = pi.step(reference, motor.w, DT, BATTERY);
            motor.run(u, DT);
            peak = peak.max(motor.w);
            if (motor.w - reference).abs() > 0.05 * reference {
                settled_at = k as f32 * DT;
            }
        }
        (settled_at, peak)
    }

    #[test]
    fn default_step_response_settles_fast_without_overshoot() {
        let (settled_s, peak) = settling(PiGains::default(), 10.0);
        assert!(settled_s <= 0.3, "settled after {settled_s} s");
        assert!(peak < 10.2, "peak {peak}");
    }

    #[test]
    fn the_original_gains_overshoot_on_the_measured_motor() {
        let (settled_s, peak) = settling(PiGains::ORIGINAL, 10.0);
        assert!(peak > 11.0, "peak {peak}");
        assert!(settled_s > 0.3, "settled after {settled_s} s");
    }

    #[test]
    fn anti_windup_recovers_within_one_period_after_saturation_ends() {
        let mut pi = PiController::new(PiConfig::default());
        // Hold the wheel (stalled) with a reference the battery can barely reach: the
        // integral grows for a few periods until the output saturates, then stops.
        for _ in 0..100 {
            let u = pi.step(15.0, 0.0, DT, BATTERY);
            assert!(u <= BATTERY);
        }
        let held = pi.integral_rad();
        assert!(held > 0.0, "the integral never integrated");
        // 15 rad/s of error for 2 s would integrate 30 rad without anti-windup.
        assert!(held < 1.0, "integral {held} wound up");
        // Saturation ends: the reference drops to a reachable value and the wheel runs near
        // it. Within one period the output is back inside the limits.
        let u = pi.step(5.0, 5.0, DT, BATTERY);
        assert!(u.abs() < BATTERY, "still saturated: {u}");
    }

    #[test]
    fn without_anti_windup_the_integral_would_grow() {
        // Sanity check of the test above: the same stall with a huge limit integrates freely.
        let mut pi = PiController::new(PiConfig::default());
        for _ in 0..100 {
            pi.step(15.0, 0.0, DT, 1.0e9);
        }
        assert!(pi.integral_rad() > 29.0);
    }

    #[test]
    fn the_limit_is_the_one_passed_in() {
        let mut pi = PiController::new(PiConfig::default());
        assert_eq!(pi.step(100.0, 0.0, DT, 7.4), 7.4);
        assert_eq!(pi.step(-100.0, 0.0, DT, 7.4), -7.4);
    }

    #[test]
    fn dead_zone_with_zero_parameters_is_the_identity() {
        let dz = DeadZone::default();
        for u in [-12.0, -1.0, -0.1, -0.0, 0.0, 0.05, 0.12, 3.3, 12.0] {
            assert_eq!(dz.apply(u), u);
        }
    }

    #[test]
    fn dead_zone_shifts_outside_and_scales_inside() {
        let dz = DeadZone::ORIGINAL_UNUSED;
        assert!((dz.apply(1.0) - 1.08).abs() < 1e-6);
        assert!((dz.apply(-1.0) + 1.08).abs() < 1e-6);
        assert!((dz.apply(0.06) - 0.10).abs() < 1e-6);
        // Continuous at the edges.
        assert!((dz.apply(0.12) - 0.20).abs() < 1e-6);
        assert!((dz.apply(-0.12) + 0.20).abs() < 1e-6);
    }

    #[test]
    fn a_zero_reference_clears_the_integral() {
        let mut pi = PiController::new(PiConfig::default());
        pi.step(5.0, 0.0, DT, BATTERY);
        assert!(pi.integral_rad() > 0.0);
        assert_eq!(pi.step(0.0, 0.0, DT, BATTERY), 0.0);
        assert_eq!(pi.integral_rad(), 0.0);
    }
}
