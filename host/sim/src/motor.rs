//! A wheel's DC motor and gearbox as a first-order system with a dead zone.
//!
//! Steady state: `ω = K · (|V| − V0) · sign(V)` for `|V| > V0`, else 0, where `ω` is the wheel
//! (gearbox output) speed in rad/s, `K` the gain and `V0` the dead zone. Dynamics: first order
//! with time constant `τ`, integrated exactly over each step (`ω += (ω_ss − ω)(1 − e^{−dt/τ})`).
//!
//! The parameters and their sources are in [`MotorConfig`]. Note that the gain, 2.19 (rad/s)/V
//! from the motor's 251 rpm at 12 V, is also the inverse of the original firmware's
//! feed-forward (0.456 V per rad/s), so the feed-forward alone drives a wheel close to its
//! reference.

use ratf_core::config::MotorConfig;

/// The steady-state wheel speed of `model` for a constant voltage, rad/s.
pub fn steady_speed_rad_s(model: &MotorConfig, voltage_v: f64) -> f64 {
    let effective = (voltage_v.abs() - model.dead_zone_v).max(0.0);
    model.gain_rad_s_per_v * effective * voltage_v.signum()
}

/// One motor's state: its wheel speed.
#[derive(Clone, Debug, PartialEq)]
pub struct Motor {
    model: MotorConfig,
    speed_rad_s: f64,
}

impl Motor {
    /// A motor at rest.
    pub fn new(model: &MotorConfig) -> Self {
        Self {
            model: model.clone(),
            speed_rad_s: 0.0,
        }
    }

    /// Wheel speed, rad/s.
    pub fn speed_rad_s(&self) -> f64 {
        self.speed_rad_s
    }

    /// Advance by `dt_s` seconds with `voltage_v` across the motor.
    pub fn step(&mut self, voltage_v: f64, dt_s: f64) {
        let target = steady_speed_rad_s(&self.model, voltage_v);
        let blend = 1.0 - (-dt_s / self.model.time_constant_s).exp();
        self.speed_rad_s += (target - self.speed_rad_s) * blend;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> MotorConfig {
        MotorConfig::default()
    }

    #[test]
    fn no_load_speed_at_12_v_is_close_to_the_rated_251_rpm() {
        let rpm = steady_speed_rad_s(&model(), 12.0) * 60.0 / std::f64::consts::TAU;
        // 251 rpm is the rating; the dead zone takes a couple of rpm off it.
        assert!((rpm - 251.0).abs() < 6.0, "{rpm} rpm");
    }

    #[test]
    fn dead_zone_and_symmetry() {
        let m = model();
        assert_eq!(steady_speed_rad_s(&m, 0.9 * m.dead_zone_v), 0.0);
        assert_eq!(steady_speed_rad_s(&m, -0.9 * m.dead_zone_v), 0.0);
        assert_eq!(steady_speed_rad_s(&m, -3.0), -steady_speed_rad_s(&m, 3.0));
    }

    #[test]
    fn reaches_63_percent_after_one_time_constant() {
        let m = model();
        let mut motor = Motor::new(&m);
        let steps = (m.time_constant_s / 0.001).round() as usize;
        for _ in 0..steps {
            motor.step(6.0, 0.001);
        }
        let ratio = motor.speed_rad_s() / steady_speed_rad_s(&m, 6.0);
        assert!((ratio - 0.632).abs() < 0.001, "{ratio}");
    }

    #[test]
    fn step_size_does_not_change_the_result() {
        let m = model();
        let (mut fine, mut coarse) = (Motor::new(&m), Motor::new(&m));
        for _ in 0..1000 {
            fine.step(5.0, 0.0001);
        }
        coarse.step(5.0, 0.1);
        assert!((fine.speed_rad_s() - coarse.speed_rad_s()).abs() < 1e-9);
    }
}
