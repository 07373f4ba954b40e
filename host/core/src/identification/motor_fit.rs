//! Fit a [`MotorModel`] to one wheel's sampled voltage and speed.
//!
//! For a fixed time constant and delay the model is linear in `K` and `K·V0` (for the samples
//! whose voltage is above the dead zone: `K·D(V) = K·V − K·V0·sign(V)`), so those two come
//! from a 2 × 2 least-squares solve (repeated until the set of samples above the dead zone
//! stops changing); the time constant and delay are searched, on a grid and then by a
//! pattern search that halves its steps. The error is measured only on the samples the
//! [`excited`] mask keeps (the steps and their spin-down, not long idle stretches whose
//! zeros every model predicts).

use super::motor_model::{FitQuality, MotorModel, Sample, filtered, quality};

/// Longest delay searched, s (five 20 ms periods: a motor that responds later is broken).
pub const MAX_DELAY_S: f64 = 0.1;
/// Time constants searched, s.
pub const TIME_CONSTANT_RANGE_S: (f64, f64) = (0.005, 2.0);
/// How long after the last nonzero voltage samples still count, s: the spin-down.
pub const SPIN_DOWN_S: f64 = 0.5;

/// A fitted model and how well it fits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorFit {
    /// The model.
    pub model: MotorModel,
    /// Its fit over the excited samples.
    pub quality: FitQuality,
}

/// Why a wheel's data cannot be fitted.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MotorFitError {
    /// Too few samples with a voltage applied.
    #[error(
        "only {excited} samples with a voltage applied (at least {needed} needed): record \
         longer steps"
    )]
    TooFewSamples {
        /// Samples kept.
        excited: usize,
        /// Samples needed.
        needed: usize,
    },
    /// All steps have the same magnitude: gain and dead zone cannot be told apart.
    #[error(
        "every step has the same voltage magnitude: record steps at two or more levels \
         (e.g. PWM 40 and 60) to separate the gain from the dead zone"
    )]
    OneLevel,
    /// The wheel never turned.
    #[error("the wheel never turned: check its encoder and motor wiring (ratf check)")]
    NoMotion,
}

/// Samples to compare: those within [`SPIN_DOWN_S`] after a nonzero voltage.
pub fn excited(samples: &[Sample]) -> Vec<bool> {
    let mut since_drive = f64::INFINITY;
    samples
        .iter()
        .map(|s| {
            // The voltage of sample k acts after its period, so the previous voltages decide.
            let keep = since_drive <= SPIN_DOWN_S;
            since_drive = if s.voltage_v != 0.0 {
                0.0
            } else {
                since_drive + s.period_s
            };
            keep
        })
        .collect()
}

/// Fit the model to `samples` (one wheel, in time order, starting at rest).
pub fn fit(samples: &[Sample]) -> Result<MotorFit, MotorFitError> {
    let mask = excited(samples);
    let kept = mask.iter().filter(|k| **k).count();
    const NEEDED: usize = 20;
    if kept < NEEDED {
        return Err(MotorFitError::TooFewSamples {
            excited: kept,
            needed: NEEDED,
        });
    }
    if samples.iter().all(|s| s.speed_rad_s == 0.0) {
        return Err(MotorFitError::NoMotion);
    }
    let magnitudes: Vec<f64> = samples
        .iter()
        .map(|s| s.voltage_v.abs())
        .filter(|v| *v > 0.0)
        .collect();
    let (low, high) = magnitudes
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    if high - low < 0.05 * high {
        return Err(MotorFitError::OneLevel);
    }

    let cost = |tau: f64, delay: f64| linear_part(samples, &mask, tau, delay);
    // Grid: log-spaced time constants, delays every 10 ms.
    let (tau_lo, tau_hi) = TIME_CONSTANT_RANGE_S;
    let mut best = (f64::INFINITY, 0.1, 0.0);
    for i in 0..24 {
        let tau = tau_lo * (tau_hi / tau_lo).powf(f64::from(i) / 23.0);
        for j in 0..=10 {
            let delay = MAX_DELAY_S * f64::from(j) / 10.0;
            let (sse, _) = cost(tau, delay);
            if sse < best.0 {
                best = (sse, tau, delay);
            }
        }
    }
    // Pattern search in (ln τ, delay).
    let (mut sse, mut tau, mut delay) = best;
    let (mut step_ln, mut step_delay) = (0.25, 0.01);
    while step_ln > 1e-4 || step_delay > 1e-5 {
        let mut improved = false;
        // Diagonals too: a longer delay and a shorter time constant trade off.
        for (dl, dd) in [
            (step_ln, 0.0),
            (-step_ln, 0.0),
            (0.0, step_delay),
            (0.0, -step_delay),
            (step_ln, -step_delay),
            (-step_ln, step_delay),
            (step_ln, step_delay),
            (-step_ln, -step_delay),
        ] {
            let t = (tau.ln() + dl).exp().clamp(tau_lo, tau_hi);
            let d = (delay + dd).clamp(0.0, MAX_DELAY_S);
            let (candidate, _) = cost(t, d);
            if candidate < sse {
                (sse, tau, delay) = (candidate, t, d);
                improved = true;
            }
        }
        if !improved {
            step_ln /= 2.0;
            step_delay /= 2.0;
        }
    }
    let (_, (gain, dead_zone_v)) = cost(tau, delay);
    let model = MotorModel {
        gain_rad_s_per_v: gain,
        time_constant_s: tau,
        dead_zone_v,
        delay_s: delay,
    };
    let quality = quality(samples, &model.simulate(samples), &mask);
    Ok(MotorFit { model, quality })
}

/// For a time constant and delay: the squared error over `mask` and the best (gain, dead
/// zone).
fn linear_part(samples: &[Sample], mask: &[bool], tau: f64, delay: f64) -> (f64, (f64, f64)) {
    let mut dead_zone_v = 0.0;
    let mut result = (f64::INFINITY, (0.0, 0.0));
    for _ in 0..4 {
        let above = |v: f64| v.abs() > dead_zone_v;
        let u1: Vec<f64> = samples
            .iter()
            .map(|s| if above(s.voltage_v) { s.voltage_v } else { 0.0 })
            .collect();
        let u2: Vec<f64> = samples
            .iter()
            .map(|s| {
                if above(s.voltage_v) {
                    -s.voltage_v.signum()
                } else {
                    0.0
                }
            })
            .collect();
        let y1 = filtered(samples, &u1, tau, delay);
        let y2 = filtered(samples, &u2, tau, delay);
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for k in (0..samples.len()).filter(|&k| mask[k]) {
            let w = samples[k].speed_rad_s;
            a11 += y1[k] * y1[k];
            a12 += y1[k] * y2[k];
            a22 += y2[k] * y2[k];
            b1 += y1[k] * w;
            b2 += y2[k] * w;
        }
        let det = a11 * a22 - a12 * a12;
        let (gain, gain_dead_zone) = if det.abs() > 1e-12 * a11 * a22 && det != 0.0 {
            ((b1 * a22 - b2 * a12) / det, (a11 * b2 - a12 * b1) / det)
        } else if a11 > 0.0 {
            (b1 / a11, 0.0)
        } else {
            (0.0, 0.0)
        };
        let new_dead_zone = if gain > 0.0 {
            (gain_dead_zone / gain).max(0.0)
        } else {
            0.0
        };
        let sse: f64 = (0..samples.len())
            .filter(|&k| mask[k])
            .map(|k| (samples[k].speed_rad_s - gain * y1[k] - gain_dead_zone * y2[k]).powi(2))
            .sum();
        result = (sse, (gain, new_dead_zone));
        if (new_dead_zone - dead_zone_v).abs() < 1e-9 {
            break;
        }
        dead_zone_v = new_dead_zone;
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// PWM-like steps at several levels both ways, with rests between.
    fn excitation(levels: &[f64]) -> Vec<Sample> {
        let mut samples = Vec::new();
        let mut push = |v: f64, n: usize| {
            for _ in 0..n {
                samples.push(Sample {
                    period_s: 0.02,
                    voltage_v: v,
                    speed_rad_s: 0.0,
                });
            }
        };
        push(0.0, 10);
        for &v in levels {
            push(v, 40);
            push(0.0, 40);
            push(-v, 40);
            push(0.0, 40);
        }
        samples
    }

    fn measured(model: &MotorModel, mut samples: Vec<Sample>) -> Vec<Sample> {
        let speeds = model.simulate(&samples);
        for (s, w) in samples.iter_mut().zip(speeds) {
            s.speed_rad_s = w;
        }
        samples
    }

    #[test]
    fn recovers_a_known_model_exactly() {
        let truth = MotorModel {
            gain_rad_s_per_v: 2.19,
            time_constant_s: 0.1,
            dead_zone_v: 0.22,
            delay_s: 0.025,
        };
        let fit = fit(&measured(&truth, excitation(&[1.4, 1.9, 2.8]))).unwrap();
        let m = fit.model;
        assert!((m.gain_rad_s_per_v - 2.19).abs() < 1e-3, "{m:?}");
        assert!((m.time_constant_s - 0.1).abs() < 1e-3, "{m:?}");
        assert!((m.dead_zone_v - 0.22).abs() < 1e-3, "{m:?}");
        assert!((m.delay_s - 0.025).abs() < 1e-3, "{m:?}");
        assert!(fit.quality.r2 > 0.9999, "{:?}", fit.quality);
    }

    #[test]
    fn one_level_is_refused() {
        let truth = MotorModel {
            gain_rad_s_per_v: 2.0,
            time_constant_s: 0.1,
            dead_zone_v: 0.2,
            delay_s: 0.0,
        };
        assert_eq!(
            fit(&measured(&truth, excitation(&[2.0]))),
            Err(MotorFitError::OneLevel)
        );
    }

    #[test]
    fn a_still_wheel_is_refused() {
        assert_eq!(fit(&excitation(&[1.0, 2.0])), Err(MotorFitError::NoMotion));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]
        #[test]
        fn recovers_random_models_within_two_percent(
            gain in 1.0f64..6.0,
            tau in 0.03f64..0.4,
            dead_zone in 0.05f64..0.8,
            delay in 0.0f64..0.06,
        ) {
            let truth = MotorModel {
                gain_rad_s_per_v: gain,
                time_constant_s: tau,
                dead_zone_v: dead_zone,
                delay_s: delay,
            };
            let levels = [dead_zone + 1.0, dead_zone + 2.0, dead_zone + 4.0];
            let m = fit(&measured(&truth, excitation(&levels))).unwrap().model;
            prop_assert!((m.gain_rad_s_per_v / gain - 1.0).abs() < 0.02, "{:?}", m);
            prop_assert!((m.time_constant_s / tau - 1.0).abs() < 0.02, "{:?}", m);
            prop_assert!((m.dead_zone_v / dead_zone - 1.0).abs() < 0.02, "{:?}", m);
            prop_assert!((m.delay_s - delay).abs() < 0.002, "{:?}", m);
        }
    }
}
