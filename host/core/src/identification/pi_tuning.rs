//! Wheel PI gains by IMC (lambda) tuning from an identified [`MotorModel`], and the step
//! response they give, predicted with the Mega's own controller ([`ratf_protocol::mcu::Mcu`]:
//! the same discrete PI, rounding to PWM, slew limit and saturation as the firmware) against
//! the model.
//!
//! IMC rule for a first-order plant with dead time (Rivera, Morari & Skogestad 1986; the
//! original firmware's rule, original-system.md §2.2, is its `θ = 0`, `λ = τ` case):
//! `Kc = τ / (K·(λ + θ))`, `Ti = τ`, `Ki = Kc/Ti`, for a chosen closed-loop time constant `λ`.
//! `θ` is the identified delay plus one control period (half for the hold of the PWM over
//! the period, half for the speed being the period's mean). The dead zone is compensated by
//! the Hammerstein block (`V0` = the identified dead zone), so the PI sees a linear plant;
//! its ramp `Vd` spans the voltage the proportional term gives for one encoder count per
//! period, so a count of jitter around zero speed does not throw `±V0` at the motor. The
//! feed-forward is 0 by default: added on top of the IMC PI it overshoots (`pi.rs`).

use super::motor_model::MotorModel;
use ratf_protocol::channels::Frame;
use ratf_protocol::integrity::{BatchWriter, HOST_CHECKSUM_CHANNEL};
use ratf_protocol::mcu::{Mcu, McuConfig, TickInputs};
use ratf_protocol::messages::{Command, WHEEL_COUNT, Wheel};
use ratf_protocol::pi::{DeadZone, PiGains};
use serde::Serialize;
use std::collections::VecDeque;
use std::f64::consts::TAU;

/// The controller settings the tuning gives, in the `[mega]` keys' units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TunedGains {
    /// Kc, V/(rad/s) (`mega.kc_v_per_rad_s`).
    pub kc_v_per_rad_s: f64,
    /// Ki, V/rad (`mega.ki_v_per_rad`).
    pub ki_v_per_rad: f64,
    /// Kf, V/(rad/s) (`mega.kf_v_per_rad_s`).
    pub kf_v_per_rad_s: f64,
    /// Hammerstein V0, V (`mega.dead_zone_v0_v`).
    pub dead_zone_v0_v: f64,
    /// Hammerstein Vd, V (`mega.dead_zone_vd_v`).
    pub dead_zone_vd_v: f64,
}

/// What the tuning is asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TuningGoal {
    /// Closed-loop time constant λ, s.
    pub closed_loop_s: f64,
    /// Feed-forward as a fraction of the inverse gain (0: none; 1: `Kf = 1/K`).
    pub feed_forward: f64,
    /// Compensate the dead zone (Hammerstein block).
    pub dead_zone_compensation: bool,
}

impl Default for TuningGoal {
    /// λ = 0.06 s: a 10 rad/s step settles within ±5 % in about 0.26 s on the competition
    /// robot's model without overshoot (faster λ meets the slew limit and the one-count
    /// speed resolution); no feed-forward; dead zone compensated.
    fn default() -> Self {
        Self {
            closed_loop_s: 0.06,
            feed_forward: 0.0,
            dead_zone_compensation: true,
        }
    }
}

/// IMC gains for `model` at `control_period_s`, with one encoder count per period worth
/// `rad_per_tick / control_period_s` rad/s.
pub fn tune(
    model: &MotorModel,
    goal: &TuningGoal,
    control_period_s: f64,
    rad_per_tick: f64,
) -> TunedGains {
    let theta = model.delay_s + control_period_s;
    let kc = model.time_constant_s / (model.gain_rad_s_per_v * (goal.closed_loop_s + theta));
    let one_count_rad_s = rad_per_tick / control_period_s;
    let (v0, vd) = if goal.dead_zone_compensation && model.dead_zone_v > 0.0 {
        (
            model.dead_zone_v,
            (kc * one_count_rad_s).min(model.dead_zone_v),
        )
    } else {
        (0.0, 0.0)
    };
    TunedGains {
        kc_v_per_rad_s: kc,
        ki_v_per_rad: kc / model.time_constant_s,
        kf_v_per_rad_s: goal.feed_forward / model.gain_rad_s_per_v,
        dead_zone_v0_v: v0,
        dead_zone_vd_v: vd,
    }
}

/// A predicted step response.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StepResponse {
    /// The reference, rad/s.
    pub reference_rad_s: f64,
    /// Measured speed per control period (what the Mega's encoders see), rad/s.
    pub speed_rad_s: Vec<f64>,
    /// PWM per control period.
    pub pwm: Vec<i16>,
    /// Control period, s.
    pub period_s: f64,
    /// Time after which the speed stays within ±5 % of the reference, s (`None`: never).
    pub settling_s: Option<f64>,
    /// Peak above the reference, per cent of it (0 when it never exceeds it).
    pub overshoot_pct: f64,
}

/// The measured response of one wheel with `model` to a `reference_rad_s` step over
/// `duration_s`, driven by the Mega's code with `mcu` (gains, limits, battery voltage).
/// The motor is integrated in 100 sub-steps per period with its delay; the encoder counts
/// whole ticks.
pub fn predict_step(
    model: &MotorModel,
    mcu: McuConfig,
    reference_rad_s: f64,
    duration_s: f64,
) -> StepResponse {
    let period_s = f64::from(mcu.control_period_us) * 1e-6;
    let ticks_per_rad = f64::from(mcu.ticks_per_wheel_rev) / TAU;
    let volts_per_pwm = f64::from(mcu.battery_voltage_v) / f64::from(mcu.pwm_max);
    let mut mega = Mcu::new(mcu);
    let mut writer = BatchWriter::new(HOST_CHECKSUM_CHANNEL, true);
    let frames: Vec<Frame> = Wheel::ALL
        .iter()
        .map(|&wheel| {
            Command::WheelSpeed {
                wheel,
                speed_rad_s: reference_rad_s as f32,
            }
            .to_frame()
        })
        .collect();
    const SUB: usize = 100;
    let h = period_s / SUB as f64;
    let delay_steps = (model.delay_s / h).round() as usize;
    let mut pending: VecDeque<f64> = std::iter::repeat_n(0.0, delay_steps).collect();
    let (mut speed, mut angle, mut counted) = (0.0f64, 0.0f64, 0i64);
    let mut voltage = 0.0;
    let periods = (duration_s / period_s).ceil() as usize;
    let (mut speeds, mut pwms) = (Vec::with_capacity(periods), Vec::with_capacity(periods));
    let mut delta: i16 = 0;
    for k in 0..periods {
        let now_us = (k as u64 * u64::from(mcu.control_period_us)) as u32;
        let mut bytes = [0u8; 128];
        let n = writer.write_batch(&frames, &mut bytes).unwrap_or(0);
        mega.receive(&bytes[..n], now_us);
        let inputs = TickInputs {
            encoder_deltas: [delta; WHEEL_COUNT],
            ..TickInputs::default()
        };
        let out = mega.control_tick(now_us, &inputs);
        let pwm = out.actuation.pwm[0];
        pwms.push(pwm);
        let applied = f64::from(pwm) * volts_per_pwm;
        let blend = 1.0 - (-h / model.time_constant_s.max(1e-6)).exp();
        for _ in 0..SUB {
            pending.push_back(applied);
            voltage = pending.pop_front().unwrap_or(voltage);
            speed += (model.steady_speed_rad_s(voltage) - speed) * blend;
            angle += speed * h;
        }
        let total = (angle * ticks_per_rad).floor() as i64;
        delta = (total - counted).clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16;
        counted = total;
        speeds.push(f64::from(delta) / ticks_per_rad / period_s);
    }
    let band = 0.05 * reference_rad_s.abs();
    let settling_s = match speeds
        .iter()
        .rposition(|w| (w - reference_rad_s).abs() > band)
    {
        Some(last) if last + 1 == speeds.len() => None,
        Some(last) => Some((last + 1) as f64 * period_s),
        None => Some(0.0),
    };
    let peak = speeds
        .iter()
        .map(|w| w * reference_rad_s.signum())
        .fold(0.0, f64::max);
    let overshoot_pct = ((peak / reference_rad_s.abs() - 1.0) * 100.0).max(0.0);
    StepResponse {
        reference_rad_s,
        speed_rad_s: speeds,
        pwm: pwms,
        period_s,
        settling_s,
        overshoot_pct,
    }
}

/// `mcu` with `gains` in force.
pub fn with_gains(mut mcu: McuConfig, gains: &TunedGains) -> McuConfig {
    mcu.pi.gains = PiGains {
        kc_v_per_rad_s: gains.kc_v_per_rad_s as f32,
        ki_v_per_rad: gains.ki_v_per_rad as f32,
        kf_v_per_rad_s: gains.kf_v_per_rad_s as f32,
    };
    mcu.pi.dead_zone = DeadZone {
        v0_v: gains.dead_zone_v0_v as f32,
        vd_v: gains.dead_zone_vd_v as f32,
    };
    mcu
}

#[cfg(test)]
mod tests {
    use super::*;

    fn competition_motor() -> MotorModel {
        MotorModel {
            gain_rad_s_per_v: 2.19,
            time_constant_s: 0.1,
            dead_zone_v: 0.22,
            delay_s: 0.0,
        }
    }

    fn rad_per_tick() -> f64 {
        TAU / 2803.2
    }

    #[test]
    fn imc_with_no_delay_and_lambda_tau_is_the_original_rule() {
        let model = MotorModel {
            delay_s: 0.0,
            ..competition_motor()
        };
        let goal = TuningGoal {
            closed_loop_s: 0.08,
            feed_forward: 0.0,
            dead_zone_compensation: false,
        };
        // θ = one 20 ms period, so λ + θ = τ.
        let g = tune(&model, &goal, 0.02, rad_per_tick());
        assert!((g.kc_v_per_rad_s - 1.0 / 2.19).abs() < 1e-12);
        assert!((g.ki_v_per_rad - 1.0 / 2.19 / 0.1).abs() < 1e-9);
        assert_eq!((g.dead_zone_v0_v, g.dead_zone_vd_v), (0.0, 0.0));
    }

    #[test]
    fn the_default_goal_meets_the_step_target_on_the_competition_motor() {
        let model = competition_motor();
        let gains = tune(&model, &TuningGoal::default(), 0.02, rad_per_tick());
        let step = predict_step(&model, with_gains(McuConfig::default(), &gains), 10.0, 1.0);
        let settled = step.settling_s.unwrap();
        assert!(
            settled <= 0.3,
            "settled after {settled} s: {:?}",
            step.speed_rad_s
        );
        assert!(step.overshoot_pct <= 5.0, "{} %", step.overshoot_pct);
    }

    #[test]
    fn a_step_beyond_the_battery_saturates_and_falls_short() {
        let model = competition_motor();
        let gains = tune(&model, &TuningGoal::default(), 0.02, rad_per_tick());
        let step = predict_step(&model, with_gains(McuConfig::default(), &gains), 40.0, 1.0);
        assert_eq!(step.settling_s, None);
        // Conditional integration stops the integral one step short of the limit, so the
        // PWM stays within one integration step (Ki·e·dt ≈ 2.3 V ≈ 50 PWM) below 255.
        let pwm = *step.pwm.last().unwrap();
        assert!((205..=255).contains(&pwm), "{pwm}");
        // At most the wheel's no-load speed at 11.1 V: 2.19 × (11.1 − 0.22) = 23.8 rad/s.
        let last = *step.speed_rad_s.last().unwrap();
        assert!(last > 20.0 && last < 24.0, "{last}");
    }
}
