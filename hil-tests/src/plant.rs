//! A DC motor with gearbox and encoder: the plant that closes the firmware's speed loop.
//!
//! First-order model with a dead zone, `τ·dω/dt = K·(|V| − V0)·sign(V) − ω` (0 inside the
//! dead zone), ω in wheel (gearbox output) rad/s, with the competition robot's defaults, the
//! same numbers as the host simulator's `[motor]` config (`host/src/config/motor.rs`, where
//! their sources are argued; this crate may not depend on the host): K = 2.19 (rad/s)/V from
//! the DFRobot motor's 251 rpm at 12 V, confirmed by the recorded PWM steps (2.17); τ = 0.1 s
//! from the original's motor model and the recorded step responses; V0 = 0.22 V from the
//! recorded steps. (The original firmware's tuning assumed K = 4.5, about twice the real gain;
//! its feed-forward 0.456 V/(rad/s) = 1/2.19 matches the real one.)
//!
//! It is integrated exactly over each step for a voltage held constant during the step
//! (zero-order hold), so the step size only sets how finely edges are placed in time.
//! Position is tracked in encoder edges, 2803.2 per wheel revolution (16 × 4 × 43.8, §2.2).

use std::f64::consts::TAU;

/// Steady-state gain above the dead zone, wheel (rad/s)/V (see the module doc).
pub const MOTOR_GAIN_RAD_S_PER_V: f64 = 2.19;
/// Time constant, s (see the module doc).
pub const MOTOR_TAU_S: f64 = 0.1;
/// Dead zone, V (see the module doc).
pub const MOTOR_DEAD_ZONE_V: f64 = 0.22;
/// Encoder edges per wheel revolution (original-system.md §2.2).
pub const EDGES_PER_WHEEL_REV: f64 = 2803.2;

/// One wheel's motor and encoder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WheelPlant {
    speed_rad_s: f64,
    position_edges: f64,
    emitted_edges: i64,
}

impl Default for WheelPlant {
    fn default() -> Self {
        Self::new()
    }
}

impl WheelPlant {
    /// A wheel at rest at position 0.
    pub fn new() -> Self {
        Self {
            speed_rad_s: 0.0,
            position_edges: 0.0,
            emitted_edges: 0,
        }
    }

    /// Wheel speed, rad/s.
    pub fn speed_rad_s(&self) -> f64 {
        self.speed_rad_s
    }

    /// Wheel position, edges (fractional).
    pub fn position_edges(&self) -> f64 {
        self.position_edges
    }

    /// Advance by `dt_s` seconds with `voltage_v` on the terminals. Returns the encoder
    /// edges that became due during the step: positive forward, negative backward.
    pub fn step(&mut self, dt_s: f64, voltage_v: f64) -> i64 {
        let effective_v = (voltage_v.abs() - MOTOR_DEAD_ZONE_V).max(0.0) * voltage_v.signum();
        let target_rad_s = MOTOR_GAIN_RAD_S_PER_V * effective_v;
        let decay = (-dt_s / MOTOR_TAU_S).exp();
        let travelled_rad =
            target_rad_s * dt_s + (self.speed_rad_s - target_rad_s) * MOTOR_TAU_S * (1.0 - decay);
        self.speed_rad_s = target_rad_s + (self.speed_rad_s - target_rad_s) * decay;
        self.position_edges += travelled_rad * EDGES_PER_WHEEL_REV / TAU;
        let due = self.position_edges.floor() as i64;
        let edges = due - self.emitted_edges;
        self.emitted_edges = due;
        edges
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_response_reaches_63_percent_after_tau() {
        let mut plant = WheelPlant::new();
        for _ in 0..10_000 {
            plant.step(1e-5, 2.0);
        }
        let steady = MOTOR_GAIN_RAD_S_PER_V * (2.0 - MOTOR_DEAD_ZONE_V);
        let expected = steady * (1.0 - (-1.0f64).exp());
        assert!((plant.speed_rad_s() - expected).abs() < 1e-9);
    }

    #[test]
    fn edges_match_travelled_angle_in_steady_state() {
        let mut plant = WheelPlant::new();
        // Settle at K·(2 V − V0) ≈ 3.9 rad/s, then count edges over 1 s.
        for _ in 0..200 {
            plant.step(0.01, 2.0);
        }
        let mut edges = 0;
        for _ in 0..100_000 {
            edges += plant.step(1e-5, 2.0);
        }
        let steady = MOTOR_GAIN_RAD_S_PER_V * (2.0 - MOTOR_DEAD_ZONE_V);
        let expected = steady * EDGES_PER_WHEEL_REV / TAU;
        assert!(
            (edges as f64 - expected).abs() <= 1.0,
            "{edges} vs {expected}"
        );
    }

    #[test]
    fn inside_the_dead_zone_the_wheel_does_not_turn() {
        let mut plant = WheelPlant::new();
        let edges: i64 = (0..10_000)
            .map(|_| plant.step(1e-4, 0.9 * MOTOR_DEAD_ZONE_V))
            .sum();
        assert_eq!(edges, 0);
    }

    #[test]
    fn reverse_voltage_gives_negative_edges() {
        let mut plant = WheelPlant::new();
        let edges: i64 = (0..10_000).map(|_| plant.step(1e-5, -3.0)).sum();
        assert!(edges < -50, "{edges}");
        assert!(plant.speed_rad_s() < 0.0);
    }

    #[test]
    fn step_size_does_not_change_the_trajectory() {
        let mut coarse = WheelPlant::new();
        let mut fine = WheelPlant::new();
        coarse.step(0.05, 5.0);
        for _ in 0..5_000 {
            fine.step(1e-5, 5.0);
        }
        assert!((coarse.speed_rad_s() - fine.speed_rad_s()).abs() < 1e-9);
        assert!((coarse.position_edges() - fine.position_edges()).abs() < 1e-6);
    }
}
