//! `ratf tune motors`: open-loop PWM steps per wheel pattern (v, vn, w, as the original's
//! `auto_tunning_motion.sh`), the speeds the Mega reports, and a [`MotorModel`] fitted per
//! wheel.
//!
//! In the simulator the steps go through the simulated Mega (the very `protocol::mcu` code,
//! `K` frames over the simulated serial line, its telemetry parsed by the host's
//! [`MegaLink`]) to the simulated motors, whose drawn truth is printed beside the fit.

use ratf_core::config::Config;
use ratf_core::drivers::mega_link::{MegaEvent, MegaLink, MegaLinkConfig};
use ratf_core::identification::motor_fit::{self, MotorFit, MotorFitError};
use ratf_core::identification::motor_model::{MotorModel, Sample};
use ratf_core::kinematics::{BodyTwist, Mecanum};
use ratf_sim::truth::WorldTruth;
use ratf_sim::world::{Scenario, World};
use serde::Serialize;
use std::collections::VecDeque;
use std::f64::consts::TAU;

/// The largest PWM magnitude the identification may apply: about 35 % of a full battery,
/// ~4 V, ~0.25 m/s of rim, so a robot on the floor stays within a metre per step.
pub const PWM_LIMIT: i16 = 90;
/// The longest step, s.
pub const STEP_LIMIT_S: f64 = 3.0;

/// The identification drive: each level, in each pattern, forward then backward, with rests.
#[derive(Clone, Debug, PartialEq)]
pub struct StepPlan {
    /// PWM magnitudes (at least two, to separate gain from dead zone), each ≤ [`PWM_LIMIT`].
    pub levels: Vec<i16>,
    /// How long each step holds, s.
    pub step_s: f64,
    /// How long the wheels rest between steps, s.
    pub rest_s: f64,
}

impl Default for StepPlan {
    /// The levels of the original's logs (PWM 30, 45, 60: 1.3–2.8 V at 11.1 V), steps of
    /// 1 s (ten time constants) and rests of 0.6 s.
    fn default() -> Self {
        Self {
            levels: vec![30, 45, 60],
            step_s: 1.0,
            rest_s: 0.6,
        }
    }
}

/// Why a plan is refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A level out of the safety limit.
    #[error("--levels: PWM {0} is outside 1..={PWM_LIMIT} (the identification's safety limit)")]
    Level(i16),
    /// Fewer than two distinct levels.
    #[error("--levels: give at least two different PWM levels (e.g. 30,45,60)")]
    TooFewLevels,
    /// A duration out of range.
    #[error("--step-s and --rest-s: each within 0.2..={STEP_LIMIT_S} s (got {0} s)")]
    Duration(f64),
}

impl StepPlan {
    /// Check the plan against the safety limits.
    pub fn check(&self) -> Result<(), PlanError> {
        if let Some(&bad) = self.levels.iter().find(|l| !(1..=PWM_LIMIT).contains(*l)) {
            return Err(PlanError::Level(bad));
        }
        let mut distinct = self.levels.clone();
        distinct.sort_unstable();
        distinct.dedup();
        if distinct.len() < 2 {
            return Err(PlanError::TooFewLevels);
        }
        for d in [self.step_s, self.rest_s] {
            if !(0.2..=STEP_LIMIT_S).contains(&d) {
                return Err(PlanError::Duration(d));
            }
        }
        Ok(())
    }

    /// The PWM per motor at `t_s` after the start; `None` once the plan is over.
    pub fn pwm_at(&self, patterns: &[[i8; 4]; 3], t_s: f64) -> Option<[i16; 4]> {
        let step = self.step_s + self.rest_s;
        let index = (t_s / step).floor();
        let phase = t_s - index * step;
        let index = index as usize;
        // Per level: 3 patterns × (forward, backward).
        let level = *self.levels.get(index / 6)?;
        let pattern = patterns[(index / 2) % 3];
        let sign = if index.is_multiple_of(2) { 1 } else { -1 };
        if phase >= self.step_s {
            return Some([0; 4]);
        }
        Some(pattern.map(|s| i16::from(s) * sign * level))
    }

    /// The plan's length, s.
    pub fn duration_s(&self) -> f64 {
        self.levels.len() as f64 * 6.0 * (self.step_s + self.rest_s)
    }
}

/// The wheel sign patterns that drive the robot forward (v), left (vn) and turn it (w), from
/// the robot's kinematics (the original scripts' `v`, `vn`, `w`).
pub fn patterns(config: &Config) -> [[i8; 4]; 3] {
    let mecanum = Mecanum::new(&config.robot);
    [
        BodyTwist::new(0.1, 0.0, 0.0),
        BodyTwist::new(0.0, 0.1, 0.0),
        BodyTwist::new(0.0, 0.0, 0.5),
    ]
    .map(|twist| mecanum.inverse(twist).map(|w| w.signum() as i8))
}

/// One wheel's identification.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WheelReport {
    /// Motor index.
    pub wheel: usize,
    /// Gain, wheel (rad/s) per V.
    pub gain_rad_s_per_v: f64,
    /// Time constant, s.
    pub time_constant_s: f64,
    /// Dead zone, V.
    pub dead_zone_v: f64,
    /// Delay, s.
    pub delay_s: f64,
    /// RMS error over the steps and spin-downs, rad/s.
    pub rmse_rad_s: f64,
    /// R² over the same samples.
    pub r2: f64,
}

impl WheelReport {
    /// The report of `fit` for motor `wheel`.
    pub fn new(wheel: usize, fit: &MotorFit) -> Self {
        Self {
            wheel,
            gain_rad_s_per_v: fit.model.gain_rad_s_per_v,
            time_constant_s: fit.model.time_constant_s,
            dead_zone_v: fit.model.dead_zone_v,
            delay_s: fit.model.delay_s,
            rmse_rad_s: fit.quality.rmse_rad_s,
            r2: fit.quality.r2,
        }
    }
}

/// Fit every wheel's samples.
pub fn fit_all(wheels: &[Vec<Sample>]) -> Result<Vec<MotorFit>, (usize, MotorFitError)> {
    wheels
        .iter()
        .enumerate()
        .map(|(k, samples)| motor_fit::fit(samples).map_err(|e| (k, e)))
        .collect()
}

/// The wheels' mean model (what the Mega's one set of gains is tuned for).
pub fn mean_model(fits: &[MotorFit]) -> MotorModel {
    let n = fits.len().max(1) as f64;
    let mean = |f: &dyn Fn(&MotorModel) -> f64| fits.iter().map(|x| f(&x.model)).sum::<f64>() / n;
    MotorModel {
        gain_rad_s_per_v: mean(&|m| m.gain_rad_s_per_v),
        time_constant_s: mean(&|m| m.time_constant_s),
        dead_zone_v: mean(&|m| m.dead_zone_v),
        delay_s: mean(&|m| m.delay_s),
    }
}

/// A simulated identification: the samples and the simulated motors' truth.
#[derive(Clone, Debug, PartialEq)]
pub struct SimSteps {
    /// Per wheel, one sample per telemetry batch.
    pub wheels: Vec<Vec<Sample>>,
    /// The simulated motors' true models (delay 0: the simulated Mega applies PWM at its
    /// tick; the dead zone with the wheel's load torque).
    pub truth: [MotorModel; 4],
    /// The battery's true voltage (what a team measures with a multimeter first), V.
    pub battery_v: f64,
}

/// Run `plan` on the simulated Mega and motors of `config`'s world (`[sim] seed`, `world`).
/// The voltage of each sample is its PWM at the world's true battery voltage.
pub fn run_in_sim(config: &Config, plan: &StepPlan) -> SimSteps {
    let scenario = Scenario::new(config);
    let mut world = World::new(config, &scenario);
    let truth_draw = world.truth().clone();
    let battery_v = truth_draw.battery_voltage_v;
    let period_us = u64::from(config.mega.control_period_us);
    let pwm_max = f64::from(config.mega.pwm_max);
    let rad_per_tick = TAU / config.robot.ticks_per_wheel_rev;
    let mut link = MegaLink::new(MegaLinkConfig {
        send_checksums: config.mega.send_checksums,
        baud: config.link.mega_baud,
        telemetry_latency_us: config.mega.telemetry_latency_us,
    });
    let patterns = patterns(config);
    let mut wheels = vec![Vec::new(); 4];
    let mut applied: VecDeque<[i16; 4]> = VecDeque::new();
    let mut next_host_us = 0u64;
    // A second of rest first, then the plan, then a last rest.
    let start_us = 1_000_000u64;
    let end_us = start_us + (plan.duration_s() * 1e6) as u64 + 1_000_000;
    while world.now_us() < end_us {
        let now_us = world.now_us();
        if now_us >= next_host_us {
            let t_s = now_us.saturating_sub(start_us) as f64 * 1e-6;
            let pwm = if now_us < start_us {
                [0; 4]
            } else {
                plan.pwm_at(&patterns, t_s).unwrap_or([0; 4])
            };
            world.send_to_mega(&link.encode_pwm(pwm, false));
            next_host_us += period_us;
        }
        world.step();
        if world.now_us().is_multiple_of(period_us) {
            // The Mega ticked in this step: the PWM it applied acts over the next period.
            applied.push_back(world.actuation().pwm);
        }
        let bytes = world.receive_from_mega();
        link.feed(&bytes, world.now_us(), |event| {
            let MegaEvent::Telemetry(t) = event else {
                return;
            };
            let Some(pwm) = applied.pop_front() else {
                return;
            };
            let Some(deltas) = t.deltas_ticks else {
                return;
            };
            let period_s = f64::from(t.period_us) * 1e-6;
            for (k, wheel) in wheels.iter_mut().enumerate() {
                wheel.push(Sample {
                    period_s,
                    voltage_v: f64::from(pwm[k]) / pwm_max * battery_v,
                    speed_rad_s: f64::from(deltas[k]) * rad_per_tick / period_s,
                });
            }
        });
    }
    SimSteps {
        wheels,
        truth: true_models(config, &truth_draw),
        battery_v,
    }
}

/// The simulated motors' true models in the world `truth` drawn for `config` (delay 0: the
/// simulated Mega applies PWM at its tick; the floor's load torque acts as more dead zone,
/// `ratf_sim::motor::load_voltage_v`).
pub fn true_models(config: &Config, truth: &WorldTruth) -> [MotorModel; 4] {
    std::array::from_fn(|k| MotorModel {
        gain_rad_s_per_v: config.motor.gain_rad_s_per_v * truth.motor_gain_scale[k],
        time_constant_s: config.motor.time_constant_s,
        dead_zone_v: config.motor.dead_zone_v
            + ratf_sim::motor::load_voltage_v(&config.motor, truth.wheel_load_torque_nm[k]),
        delay_s: 0.0,
    })
}

/// Test support: every wheel's fit of `wheels` within 5 % of `truth` in gain, time constant
/// and dead zone, with R² above 0.99 (issue 16's target for the simulator).
#[cfg(test)]
pub(crate) fn assert_recovers_within_5_percent(wheels: &[Vec<Sample>], truth: &[MotorModel]) {
    let fits = fit_all(wheels).unwrap();
    assert_eq!(fits.len(), truth.len());
    for (k, (fit, truth)) in fits.iter().zip(truth).enumerate() {
        let m = fit.model;
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(
            rel(m.gain_rad_s_per_v, truth.gain_rad_s_per_v) < 0.05,
            "{k}: {m:?}"
        );
        assert!(
            rel(m.time_constant_s, truth.time_constant_s) < 0.05,
            "{k}: {m:?}"
        );
        assert!(rel(m.dead_zone_v, truth.dead_zone_v) < 0.05, "{k}: {m:?}");
        assert!(fit.quality.r2 > 0.99, "{k}: {:?}", fit.quality);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_core::config::WorldProfile;

    #[test]
    fn the_plan_runs_each_level_in_each_pattern_both_ways() {
        let plan = StepPlan::default();
        plan.check().unwrap();
        let p = patterns(&Config::default());
        assert_eq!(p[0], [1, -1, 1, -1]);
        assert_eq!(plan.pwm_at(&p, 0.5), Some([30, -30, 30, -30]));
        assert_eq!(plan.pwm_at(&p, 1.2), Some([0; 4]));
        assert_eq!(plan.pwm_at(&p, 2.0), Some([-30, 30, -30, 30]));
        assert_eq!(plan.pwm_at(&p, plan.duration_s() + 0.1), None);
        assert!(
            StepPlan {
                levels: vec![30, 200],
                ..StepPlan::default()
            }
            .check()
            .is_err()
        );
    }

    #[test]
    fn identification_recovers_the_simulated_motors_within_5_percent() {
        let mut config = Config::default();
        config.sim.world = WorldProfile::Realistic;
        config.sim.seed = 7;
        let run = run_in_sim(&config, &StepPlan::default());
        assert_recovers_within_5_percent(&run.wheels, &run.truth);
    }
}
