//! `[motor]` and `[traction]`: the wheel drive models the simulator uses.

use serde::{Deserialize, Serialize};

use super::check::{Checker, num};
use super::limits;

/// First-order DC motor + gearbox model, per wheel: ω̇ = (K·(V − dead zone) − ω)/τ.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotorConfig {
    /// Steady-state gain, wheel (rad/s) per V. 2.19: DFRobot 251 rpm no-load at 12 V
    /// (paper §III): 251·2π/60/12. The floor data (`/work/shared/data`,
    /// motor-pwm-steps-11.79V.csv, steady states at PWM ±30..±60 on the floor, least-squares
    /// line through all four motors) gives 2.17 (per motor 2.15–2.20), which agrees.
    pub gain_rad_s_per_v: f64,
    /// The gain the original's PI tuning assumed, (rad/s)/V. 4.5: original `robotconfig.h`
    /// (original-system.md §2.2). About twice the real gain; kept for reference and for
    /// reproducing the original's tuning (Kc = 1/4.5), not used by the plant.
    pub design_gain_rad_s_per_v: f64,
    /// Time constant, s. 0.1: original `robotconfig.h` (§2.2); the floor data's median
    /// 63 % rise time after 0 → PWM steps is 0.10–0.12 s (20 ms resolution).
    pub time_constant_s: f64,
    /// Dead zone: voltage below which the wheel does not turn on the floor, V. 0.22: the
    /// zero-speed intercept of the line above (per motor 0.19–0.26 V). An extrapolation: the
    /// smallest step in the data is PWM 30 ≈ 1.39 V. The original's unused estimate is
    /// 0.20 V (`kMotHammV0`, §2.2).
    pub dead_zone_v: f64,
    /// Battery voltage, V. 11.1: 3S LiPo nominal (original §2.2). Full charge is 12.6 V;
    /// the data set was recorded at 11.79 V.
    pub battery_voltage_v: f64,
}

impl Default for MotorConfig {
    fn default() -> Self {
        Self {
            gain_rad_s_per_v: 2.19,
            design_gain_rad_s_per_v: 4.5,
            time_constant_s: 0.1,
            dead_zone_v: 0.22,
            battery_voltage_v: 11.1,
        }
    }
}

impl MotorConfig {
    /// No-load wheel speed at full battery voltage, rad/s (gain × (battery − dead zone)).
    pub fn no_load_speed_rad_s(&self) -> f64 {
        self.gain_rad_s_per_v * (self.battery_voltage_v - self.dead_zone_v)
    }

    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        const GAIN: &str = "a geared wheel motor: 2.19 for the DFRobot 251 rpm at 12 V; 50 \
                            would be 5700 rpm at 12 V, an ungeared motor";
        c.within(
            "gain_rad_s_per_v",
            self.gain_rad_s_per_v,
            0.1,
            50.0,
            "(rad/s)/V",
            GAIN,
        );
        c.within(
            "design_gain_rad_s_per_v",
            self.design_gain_rad_s_per_v,
            0.1,
            50.0,
            "(rad/s)/V",
            GAIN,
        );
        c.within(
            "time_constant_s",
            self.time_constant_s,
            0.001,
            10.0,
            "s",
            "a wheel motor settles in tens to hundreds of ms (0.1 s measured on the floor)",
        );
        c.within(
            "battery_voltage_v",
            self.battery_voltage_v,
            4.5,
            limits::MOTOR_SUPPLY_MAX_V,
            "V",
            "the Motor Shield V2's TB6612 bridges take 4.5–13.5 V; a 3S LiPo is 9.9–12.6 V",
        );
        let battery_v = if (4.5..=limits::MOTOR_SUPPLY_MAX_V).contains(&self.battery_voltage_v) {
            self.battery_voltage_v
        } else {
            limits::MOTOR_SUPPLY_MAX_V
        };
        c.require(
            "dead_zone_v",
            num(self.dead_zone_v),
            self.dead_zone_v.is_finite() && (0.0..battery_v).contains(&self.dead_zone_v),
            || {
                format!(
                    "must be within 0 … {} V, below motor.battery_voltage_v (no PWM would \
                     turn the wheel)",
                    num(battery_v)
                )
            },
        );
    }
}

/// Wheel–floor contact, for the simulator's slip model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TractionConfig {
    /// Friction coefficient between the rollers and the printed paper floor. 0.7:
    /// assumption, the middle of the 0.6–0.8 usually quoted for rubber on paper/card.
    pub friction_coefficient: f64,
    /// Robot mass with battery, kg. 2.0: assumption (not published; a 3D-printed 30 cm
    /// mecanum base with four geared motors, a 3S LiPo, a Pi 4 and a Mega).
    pub robot_mass_kg: f64,
}

impl Default for TractionConfig {
    fn default() -> Self {
        Self {
            friction_coefficient: 0.7,
            robot_mass_kg: 2.0,
        }
    }
}

impl TractionConfig {
    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        c.within(
            "friction_coefficient",
            self.friction_coefficient,
            0.05,
            2.0,
            "",
            "rubber on paper is 0.6–0.8; 2 is beyond rubber on any dry floor",
        );
        c.within(
            "robot_mass_kg",
            self.robot_mass_kg,
            0.3,
            15.0,
            "kg",
            "a 30 × 30 × 30 cm robot with four motors, a battery and two computers",
        );
    }
}
