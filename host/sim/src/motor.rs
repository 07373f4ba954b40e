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
//!
//! **Load.** A load torque at the wheel (rolling resistance, friction: [`Motor::with_load`])
//! takes `ω_nl / T_stall` off the speed per N·m, which is the same as a larger dead zone of
//! `(12 V − V0) / T_stall` per N·m (6.6 V per N·m with the DFRobot's 1.77 N·m stall torque).
//!
//! **Current and battery.** Each motor draws `(V − ke·ω) / Ra` while driven (`Ra` = 12 V /
//! 7 A stall current, `ke` from the 0.35 A no-load current at 12 V), the battery that
//! current times the PWM duty plus the electronics' own; the [`Battery`]'s voltage falls
//! with the charge drawn and, through its internal resistance, with the current.

use ratf_core::config::MotorConfig;

/// The motor's rated voltage, V: DFRobot FIT0186's 12 V rating.
const RATED_V: f64 = 12.0;
/// Stall torque at the rated voltage, N·m: 18 kg·cm (DFRobot FIT0186).
const STALL_TORQUE_NM: f64 = 1.77;
/// Stall current at the rated voltage, A (DFRobot FIT0186).
const STALL_CURRENT_A: f64 = 7.0;
/// No-load current at the rated voltage, A (DFRobot FIT0186).
const NO_LOAD_CURRENT_A: f64 = 0.35;
/// What the Raspberry Pi, the lidar, the Mega and the IMU draw from the battery, A: about
/// 8 W through the regulators. An assumption: a Pi 4 under load takes 5–6 W, the X4 about
/// 1.75 W (0.35 A at 5 V), the Mega and the shield's logic well under 1 W.
pub const ELECTRONICS_CURRENT_A: f64 = 0.7;

/// The steady-state wheel speed of `model` for a constant voltage, rad/s.
pub fn steady_speed_rad_s(model: &MotorConfig, voltage_v: f64) -> f64 {
    let effective = (voltage_v.abs() - model.dead_zone_v).max(0.0);
    model.gain_rad_s_per_v * effective * voltage_v.signum()
}

/// The voltage that balances a load torque of `torque_nm` at the wheel for `model`, V.
pub fn load_voltage_v(model: &MotorConfig, torque_nm: f64) -> f64 {
    torque_nm.max(0.0) * (RATED_V - model.dead_zone_v) / STALL_TORQUE_NM
}

/// One motor's state: its wheel speed.
#[derive(Clone, Debug, PartialEq)]
pub struct Motor {
    model: MotorConfig,
    /// The load torque as the voltage that balances it, V (see [`load_voltage_v`]).
    load_v: f64,
    /// Back-EMF constant, V per rad/s of the wheel.
    ke_v_per_rad_s: f64,
    speed_rad_s: f64,
    current_a: f64,
}

impl Motor {
    /// A motor at rest, with no load.
    pub fn new(model: &MotorConfig) -> Self {
        let armature_ohm = RATED_V / STALL_CURRENT_A;
        let no_load_rad_s = steady_speed_rad_s(model, RATED_V).max(f64::EPSILON);
        Self {
            model: model.clone(),
            load_v: 0.0,
            ke_v_per_rad_s: (RATED_V - NO_LOAD_CURRENT_A * armature_ohm) / no_load_rad_s,
            speed_rad_s: 0.0,
            current_a: 0.0,
        }
    }

    /// This motor turning a wheel that `torque_nm` of load torque holds back (≥ 0, N·m).
    pub fn with_load(mut self, torque_nm: f64) -> Self {
        self.load_v = load_voltage_v(&self.model, torque_nm);
        self
    }

    /// Wheel speed, rad/s.
    pub fn speed_rad_s(&self) -> f64 {
        self.speed_rad_s
    }

    /// The current the motor drew over the last step while driven, A (≥ 0; 0 when coasting
    /// or when its back-EMF pushes back).
    pub fn current_a(&self) -> f64 {
        self.current_a
    }

    /// Advance by `dt_s` seconds with `voltage_v` across the motor.
    pub fn step(&mut self, voltage_v: f64, dt_s: f64) {
        let target = if self.load_v > 0.0 {
            let effective = (voltage_v.abs() - self.model.dead_zone_v - self.load_v).max(0.0);
            self.model.gain_rad_s_per_v * effective * voltage_v.signum()
        } else {
            steady_speed_rad_s(&self.model, voltage_v)
        };
        let armature_ohm = RATED_V / STALL_CURRENT_A;
        let driven = (voltage_v - self.ke_v_per_rad_s * self.speed_rad_s) * voltage_v.signum();
        self.current_a = (driven / armature_ohm).max(0.0);
        let blend = 1.0 - (-dt_s / self.model.time_constant_s).exp();
        self.speed_rad_s += (target - self.speed_rad_s) * blend;
    }
}

/// The robot's battery over a round: an open-circuit voltage that falls with the charge
/// drawn, less the drop across its internal resistance (cells and wiring).
#[derive(Clone, Debug, PartialEq)]
pub struct Battery {
    start_v: f64,
    resistance_ohm: f64,
    drop_v_per_ah: f64,
    drawn_ah: f64,
    current_a: f64,
}

impl Battery {
    /// A battery at `start_v` (open circuit), with `resistance_ohm` internal resistance
    /// and an open-circuit voltage that falls by `drop_v_per_ah` per ampere-hour drawn.
    pub fn new(start_v: f64, resistance_ohm: f64, drop_v_per_ah: f64) -> Self {
        Self {
            start_v,
            resistance_ohm,
            drop_v_per_ah,
            drawn_ah: 0.0,
            current_a: 0.0,
        }
    }

    /// True when the voltage never moves (no resistance, no drop with charge).
    pub fn is_stiff(&self) -> bool {
        self.resistance_ohm == 0.0 && self.drop_v_per_ah == 0.0
    }

    /// The terminal voltage now, V (with the current of the last step).
    pub fn voltage_v(&self) -> f64 {
        if self.is_stiff() {
            return self.start_v;
        }
        self.start_v - self.drop_v_per_ah * self.drawn_ah - self.resistance_ohm * self.current_a
    }

    /// Charge drawn so far, A·h.
    pub fn drawn_ah(&self) -> f64 {
        self.drawn_ah
    }

    /// Draw `current_a` (≥ 0) for `dt_s` seconds.
    pub fn draw(&mut self, current_a: f64, dt_s: f64) {
        self.current_a = current_a.max(0.0);
        self.drawn_ah += self.current_a * dt_s / 3600.0;
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
    fn a_load_torque_slows_the_wheel_as_the_stall_slope_says() {
        let m = model();
        let (mut free, mut loaded) = (Motor::new(&m), Motor::new(&m).with_load(0.1));
        for _ in 0..2000 {
            free.step(6.0, 0.001);
            loaded.step(6.0, 0.001);
        }
        // 0.1 N·m at 14.6 rad/s per N·m (the motor's no-load speed over its stall torque).
        let slope = steady_speed_rad_s(&m, 12.0) / STALL_TORQUE_NM;
        let lost = free.speed_rad_s() - loaded.speed_rad_s();
        assert!((lost - 0.1 * slope).abs() < 1e-6, "{lost} rad/s");
        // And the loaded motor draws more current at its lower speed: the datasheet's line
        // from 0.35 A at no load to 7 A at 1.77 N·m.
        let more_a = loaded.current_a() - free.current_a();
        let expected_a = 0.1 * (STALL_CURRENT_A - NO_LOAD_CURRENT_A) / STALL_TORQUE_NM;
        assert!((more_a - expected_a).abs() < 1e-6, "{more_a} A");
        assert_eq!(Motor::new(&m).with_load(0.0), Motor::new(&m));
    }

    #[test]
    fn a_free_motor_draws_its_no_load_current_and_stalls_at_seven_amperes() {
        let m = model();
        let mut motor = Motor::new(&m);
        motor.step(12.0, 0.001);
        assert!((motor.current_a() - STALL_CURRENT_A).abs() < 1e-9);
        for _ in 0..3000 {
            motor.step(12.0, 0.001);
        }
        assert!(
            (motor.current_a() - NO_LOAD_CURRENT_A).abs() < 0.01,
            "{motor:?}"
        );
        // Coasting (no voltage) draws nothing.
        motor.step(0.0, 0.001);
        assert_eq!(motor.current_a(), 0.0);
    }

    #[test]
    fn a_battery_sags_with_current_and_falls_with_charge() {
        let mut battery = Battery::new(12.0, 0.03, 0.4);
        battery.draw(10.0, 0.0);
        assert!((battery.voltage_v() - 11.7).abs() < 1e-12);
        // 3 A for 2 minutes: 0.1 A·h, 40 mV off the open-circuit voltage, 90 mV sag.
        for _ in 0..120 {
            battery.draw(3.0, 1.0);
        }
        assert!((battery.drawn_ah() - 0.1).abs() < 1e-12);
        assert!((battery.voltage_v() - (12.0 - 0.04 - 0.09)).abs() < 1e-9);
        let mut stiff = Battery::new(11.1, 0.0, 0.0);
        stiff.draw(10.0, 100.0);
        assert_eq!(stiff.voltage_v(), 11.1);
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
