//! A wheel motor's first-order model with dead zone and delay, and its response to a
//! sampled voltage sequence (what `ratf tune motors` fits, `motor_fit`).
//!
//! Model (the simulator's, `ratf_sim::motor`, plus a pure delay):
//! `τ·ω̇ = K·D(V(t − d)) − ω`, with `D(V) = sign(V)·max(|V| − V0, 0)`: gain `K` (wheel rad/s
//! per V), time constant `τ`, dead zone `V0`, delay `d`. The voltage is what the Mega applies
//! (PWM / `pwm_max` × battery voltage), so the fit is compensated for the battery.
//!
//! Sampling (the firmware's, original-system.md §2.4): sample `k` covers one control period
//! ending at `t_k`; its speed is the encoder count over that period, i.e. the *mean* speed
//! over it; its voltage is what the firmware applied at `t_k`, after measuring, so it acts
//! from `t_k + d` until the next sample's voltage takes over. The response is integrated
//! exactly between breakpoints (first order, piecewise-constant input), so the time step
//! does not bias the fitted time constant.

use serde::Serialize;

/// One control period of one wheel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// The period's length, s (the firmware's measured period).
    pub period_s: f64,
    /// Voltage applied at the period's end, V (signed).
    pub voltage_v: f64,
    /// Mean wheel speed over the period, rad/s (encoder ticks / period).
    pub speed_rad_s: f64,
}

/// The model's parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MotorModel {
    /// Steady-state gain above the dead zone, wheel (rad/s) per V.
    pub gain_rad_s_per_v: f64,
    /// Time constant, s.
    pub time_constant_s: f64,
    /// Dead zone: the voltage below which the wheel does not turn, V.
    pub dead_zone_v: f64,
    /// Pure delay from the firmware's tick to the motor's response, s.
    pub delay_s: f64,
}

impl MotorModel {
    /// The steady-state speed for a constant `voltage_v`, rad/s.
    pub fn steady_speed_rad_s(&self, voltage_v: f64) -> f64 {
        self.gain_rad_s_per_v * dead_zone(voltage_v, self.dead_zone_v)
    }

    /// The mean speed the model predicts over each sample's period, rad/s (starting at rest).
    pub fn simulate(&self, samples: &[Sample]) -> Vec<f64> {
        let inputs: Vec<f64> = samples
            .iter()
            .map(|s| self.steady_speed_rad_s(s.voltage_v))
            .collect();
        filtered(samples, &inputs, self.time_constant_s, self.delay_s)
    }
}

/// `D(V) = sign(V)·max(|V| − V0, 0)`, V.
pub fn dead_zone(voltage_v: f64, dead_zone_v: f64) -> f64 {
    (voltage_v.abs() - dead_zone_v).max(0.0) * voltage_v.signum()
}

/// The mean over each sample's period of `x`, where `τ·ẋ = u − x` from rest and `u` is
/// `inputs[j]` from `t_j + delay` to `t_{j+1} + delay` (0 before `t_0 + delay`).
pub fn filtered(
    samples: &[Sample],
    inputs: &[f64],
    time_constant_s: f64,
    delay_s: f64,
) -> Vec<f64> {
    let tau = time_constant_s.max(1e-6);
    let delay = delay_s.max(0.0);
    let mut ends = Vec::with_capacity(samples.len());
    let mut t_end = 0.0;
    for s in samples {
        t_end += s.period_s.max(0.0);
        ends.push(t_end);
    }
    let breakpoint = |j: usize| ends.get(j).map_or(f64::INFINITY, |e| e + delay);
    let (mut t, mut x) = (0.0, 0.0);
    // Index of the next input to take effect; inputs[next - 1] is in force.
    let mut next = 0usize;
    let mut means = Vec::with_capacity(samples.len());
    for (k, &end) in ends.iter().enumerate() {
        let mut integral = 0.0;
        while t < end {
            while breakpoint(next) <= t {
                next += 1;
            }
            let u = if next == 0 {
                0.0
            } else {
                inputs.get(next - 1).copied().unwrap_or(0.0)
            };
            let segment_end = end.min(breakpoint(next));
            let h = segment_end - t;
            let decay = (-h / tau).exp();
            integral += u * h + (x - u) * tau * (1.0 - decay);
            x = u + (x - u) * decay;
            t = segment_end;
        }
        let period = samples[k].period_s;
        means.push(if period > 0.0 { integral / period } else { x });
    }
    means
}

/// How well predictions match measurements over the samples `mask` keeps.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FitQuality {
    /// Root-mean-square error, rad/s.
    pub rmse_rad_s: f64,
    /// Coefficient of determination (1 − SSE/SST).
    pub r2: f64,
    /// Samples compared.
    pub samples: usize,
}

/// RMSE and R² of `predicted` against the measured speeds, over the samples `mask` keeps.
pub fn quality(samples: &[Sample], predicted: &[f64], mask: &[bool]) -> FitQuality {
    let kept: Vec<(f64, f64)> = samples
        .iter()
        .zip(predicted)
        .zip(mask)
        .filter(|(_, keep)| **keep)
        .map(|((s, p), _)| (s.speed_rad_s, *p))
        .collect();
    let n = kept.len().max(1) as f64;
    let mean = kept.iter().map(|(m, _)| m).sum::<f64>() / n;
    let sse: f64 = kept.iter().map(|(m, p)| (m - p).powi(2)).sum();
    let sst: f64 = kept.iter().map(|(m, _)| (m - mean).powi(2)).sum();
    FitQuality {
        rmse_rad_s: (sse / n).sqrt(),
        r2: if sst > 0.0 { 1.0 - sse / sst } else { 0.0 },
        samples: kept.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steps(levels: &[(f64, usize)]) -> Vec<Sample> {
        levels
            .iter()
            .flat_map(|&(v, n)| {
                std::iter::repeat_n(
                    Sample {
                        period_s: 0.02,
                        voltage_v: v,
                        speed_rad_s: 0.0,
                    },
                    n,
                )
            })
            .collect()
    }

    #[test]
    fn a_long_step_settles_at_the_gain_above_the_dead_zone() {
        let model = MotorModel {
            gain_rad_s_per_v: 2.0,
            time_constant_s: 0.1,
            dead_zone_v: 0.5,
            delay_s: 0.03,
        };
        let speeds = model.simulate(&steps(&[(3.0, 200), (-2.0, 200)]));
        assert!((speeds[199] - 5.0).abs() < 1e-6, "{}", speeds[199]);
        assert!((speeds[399] + 3.0).abs() < 1e-6, "{}", speeds[399]);
    }

    #[test]
    fn the_delay_holds_the_response_back() {
        let model = MotorModel {
            gain_rad_s_per_v: 1.0,
            time_constant_s: 0.1,
            dead_zone_v: 0.0,
            delay_s: 0.05,
        };
        // The voltage set at the end of period 0 acts from 0.02 + 0.05 s: periods 1 and 2
        // (to 0.06 s) see nothing, period 3 (0.06–0.08 s) half of one.
        let speeds = model.simulate(&steps(&[(1.0, 10)]));
        assert_eq!(&speeds[..3], &[0.0, 0.0, 0.0]);
        assert!(speeds[3] > 0.0);
    }

    #[test]
    fn the_mean_over_a_period_matches_a_fine_integration() {
        let samples = steps(&[(2.0, 5), (0.0, 5)]);
        let inputs: Vec<f64> = samples.iter().map(|s| s.voltage_v).collect();
        let exact = filtered(&samples, &inputs, 0.07, 0.013);
        // Euler at 1 µs.
        let (mut x, mut t) = (0.0, 0.0);
        for (k, mean) in exact.iter().enumerate() {
            let (start, end) = (k as f64 * 0.02, (k + 1) as f64 * 0.02);
            let mut sum = 0.0;
            let h = 1e-6;
            while t < end - h / 2.0 {
                let applied = ((t - 0.013) / 0.02).floor() - 1.0;
                let u = if applied >= 0.0 {
                    inputs.get(applied as usize).copied().unwrap_or(0.0)
                } else {
                    0.0
                };
                x += h * (u - x) / 0.07;
                sum += x * h;
                t += h;
            }
            let fine = sum / (end - start);
            assert!((fine - mean).abs() < 1e-3, "period {k}: {fine} vs {mean}");
        }
    }

    #[test]
    fn perfect_predictions_have_r2_one() {
        let mut samples = steps(&[(1.0, 5), (3.0, 5)]);
        for (k, s) in samples.iter_mut().enumerate() {
            s.speed_rad_s = k as f64;
        }
        let predicted: Vec<f64> = (0..10).map(f64::from).collect();
        let q = quality(&samples, &predicted, &[true; 10]);
        assert_eq!(q.rmse_rad_s, 0.0);
        assert_eq!(q.r2, 1.0);
    }
}
