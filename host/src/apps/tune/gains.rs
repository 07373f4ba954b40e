//! `ratf tune gains`: the Mega's wheel PI from the identified motor model (`[motor]`, plus
//! the delay `ratf tune motors` reports), by IMC tuning
//! ([`ratf_core::identification::pi_tuning`]), with the predicted 10 rad/s step; writes the
//! `[mega]` keys.

use ratf_core::config::Config;
use ratf_core::identification::motor_model::MotorModel;
use ratf_core::identification::pi_tuning::{
    self, StepResponse, TunedGains, TuningGoal, predict_step, with_gains,
};
use ratf_core::identification::set_config_key;
use std::f64::consts::TAU;

/// The step `ratf tune gains` predicts, rad/s (issue 16's target).
pub const STEP_RAD_S: f64 = 10.0;

/// The model `config` holds (`[motor]`) with `delay_s`.
pub fn model_of(config: &Config, delay_s: f64) -> MotorModel {
    MotorModel {
        gain_rad_s_per_v: config.motor.gain_rad_s_per_v,
        time_constant_s: config.motor.time_constant_s,
        dead_zone_v: config.motor.dead_zone_v,
        delay_s,
    }
}

/// The gains for `model` in `config`'s Mega (control period, ticks per revolution).
pub fn tune(config: &Config, model: &MotorModel, goal: &TuningGoal) -> TunedGains {
    pi_tuning::tune(
        model,
        goal,
        f64::from(config.mega.control_period_us) * 1e-6,
        TAU / config.robot.ticks_per_wheel_rev,
    )
}

/// The predicted step of `reference_rad_s` over 1 s with `gains` on `config`'s Mega.
pub fn predict(
    config: &Config,
    model: &MotorModel,
    gains: &TunedGains,
    reference_rad_s: f64,
) -> StepResponse {
    predict_step(
        model,
        with_gains(config.mcu_config(), gains),
        reference_rad_s,
        1.0,
    )
}

/// Set the `[mega]` keys of `gains` in `file`.
pub fn write_into(gains: &TunedGains, file: &mut toml::Table) {
    for (key, value) in [
        ("kc_v_per_rad_s", gains.kc_v_per_rad_s),
        ("ki_v_per_rad", gains.ki_v_per_rad),
        ("kf_v_per_rad_s", gains.kf_v_per_rad_s),
        ("dead_zone_v0_v", gains.dead_zone_v0_v),
        ("dead_zone_vd_v", gains.dead_zone_vd_v),
    ] {
        set_config_key(file, "mega", key, toml::Value::Float(round6(value)));
    }
}

/// Set the `[motor]` keys of `model` in `file` (the delay has no key: the simulator's motors
/// have none).
pub fn write_model_into(model: &MotorModel, file: &mut toml::Table) {
    for (key, value) in [
        ("gain_rad_s_per_v", model.gain_rad_s_per_v),
        ("time_constant_s", model.time_constant_s),
        ("dead_zone_v", model.dead_zone_v),
    ] {
        set_config_key(file, "motor", key, toml::Value::Float(round6(value)));
    }
}

fn round6(value: f64) -> f64 {
    (value * 1e6).round() / 1e6
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_robot_gets_gains_that_meet_the_step_target_and_a_valid_config() {
        let config = Config::default();
        let model = model_of(&config, 0.0);
        let gains = tune(&config, &model, &TuningGoal::default());
        let step = predict(&config, &model, &gains, STEP_RAD_S);
        assert!(step.settling_s.is_some_and(|s| s <= 0.3), "{step:?}");
        assert!(step.overshoot_pct <= 5.0, "{step:?}");
        let mut file = toml::Table::new();
        write_into(&gains, &mut file);
        let written = Config::from_toml_str(&toml::to_string(&file).unwrap()).unwrap();
        assert!((written.mega.kc_v_per_rad_s - gains.kc_v_per_rad_s).abs() < 1e-6);
        assert!((written.mega.dead_zone_v0_v - 0.22).abs() < 1e-6);
    }

    #[test]
    fn gains_tuned_on_the_simulator_s_identified_motors_meet_the_step_target_on_each_wheel() {
        use crate::apps::tune::motors::{StepPlan, fit_all, mean_model, run_in_sim};
        let mut config = Config::default();
        config.sim.world = ratf_core::config::WorldProfile::Realistic;
        config.sim.seed = 11;
        let fits = fit_all(&run_in_sim(&config, &StepPlan::default()).wheels).unwrap();
        let gains = tune(&config, &mean_model(&fits), &TuningGoal::default());
        for fit in &fits {
            let step = predict(&config, &fit.model, &gains, STEP_RAD_S);
            assert!(step.settling_s.is_some_and(|s| s <= 0.3), "{step:?}");
            assert!(step.overshoot_pct <= 5.0, "{step:?}");
        }
    }
}
