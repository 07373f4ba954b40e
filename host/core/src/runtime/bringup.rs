//! Bring-up through the seam: what the core does once before the round, on the same
//! inputs in the simulator and on the robot. The lidar's start command goes out at the first
//! host tick (`Core`); here, the gyro's bias is measured while the robot stands still
//! waiting for the start, and handed to the pose estimator (drivers/imu/bias.rs).

use crate::drivers::imu::ImuSample;
use crate::drivers::imu::bias::{BiasConfig, BiasError, estimate_gyro_bias};

/// Samples dropped after power-up, µs: the gyro's 35 ms start-up time after waking
/// (MPU-9250 product specification), with a margin.
pub const GYRO_SETTLE_US: u64 = 50_000;

/// Samples measured, at 200 Hz: 0.75 s, so the estimate is in before a server that starts
/// the round one second after power-up (the competition's usual wait is longer); the mean's
/// noise is then σ/√150 ≈ 0.08 σ.
pub const GYRO_BIAS_SAMPLES: usize = 150;

/// Fewest samples accepted when the round starts before [`GYRO_BIAS_SAMPLES`] are in: 0.5 s.
pub const GYRO_BIAS_MIN_SAMPLES: usize = 100;

/// The gyro bias measured at start-up.
#[derive(Clone, Debug, Default)]
pub struct GyroBiasStartup {
    samples: Vec<[f64; 3]>,
    done: bool,
}

/// What the start-up measurement concluded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BiasOutcome {
    /// The z bias and its standard deviation, rad/s.
    Measured {
        /// Mean z rate while still, rad/s.
        bias_rad_s: f64,
        /// Standard deviation of that mean, rad/s.
        std_rad_s: f64,
    },
    /// No estimate: the estimator keeps learning the bias on its own.
    Refused(BiasError),
}

impl GyroBiasStartup {
    /// True once the measurement has concluded.
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// A gyro sample while the robot stands still; `Some` when the measurement concludes.
    pub fn on_sample(&mut self, sample: &ImuSample) -> Option<BiasOutcome> {
        if self.done || sample.time_us < GYRO_SETTLE_US {
            return None;
        }
        self.samples.push(sample.gyro_rad_s);
        (self.samples.len() >= GYRO_BIAS_SAMPLES).then(|| self.conclude())
    }

    /// The robot is about to move: conclude with what was collected (`None` if concluded).
    pub fn finish(&mut self) -> Option<BiasOutcome> {
        (!self.done).then(|| self.conclude())
    }

    fn conclude(&mut self) -> BiasOutcome {
        self.done = true;
        let samples = std::mem::take(&mut self.samples);
        let config = BiasConfig {
            min_samples: GYRO_BIAS_MIN_SAMPLES,
            ..BiasConfig::default()
        };
        match estimate_gyro_bias(&samples, &config) {
            Ok(bias) => {
                let n = samples.len() as f64;
                let mean = bias[2];
                let variance =
                    samples.iter().map(|s| (s[2] - mean).powi(2)).sum::<f64>() / (n - 1.0);
                BiasOutcome::Measured {
                    bias_rad_s: mean,
                    std_rad_s: (variance / n).sqrt(),
                }
            }
            Err(e) => BiasOutcome::Refused(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(time_us: u64, z_rad_s: f64) -> ImuSample {
        ImuSample {
            time_us,
            gyro_rad_s: [0.001, -0.002, z_rad_s],
            accel_m_s2: [0.0, 0.0, 9.81],
            temperature_c: 30.0,
            saturated: false,
        }
    }

    #[test]
    fn a_still_gyro_gives_its_bias_after_the_settling_time() {
        let mut startup = GyroBiasStartup::default();
        let mut outcome = None;
        for k in 0..400u64 {
            // Garbage while the gyro starts, then a bias of 0.005 rad/s with ±0.001 noise.
            let z = if k * 5_000 < GYRO_SETTLE_US {
                1.0
            } else {
                0.005 + if k % 2 == 0 { 0.001 } else { -0.001 }
            };
            if let Some(o) = startup.on_sample(&sample(k * 5_000, z)) {
                outcome = Some(o);
                break;
            }
        }
        let Some(BiasOutcome::Measured {
            bias_rad_s,
            std_rad_s,
        }) = outcome
        else {
            panic!("{outcome:?}");
        };
        assert!((bias_rad_s - 0.005).abs() < 1e-5, "{bias_rad_s}");
        assert!(std_rad_s > 0.0 && std_rad_s < 1e-4, "{std_rad_s}");
        assert!(startup.is_done());
        assert_eq!(startup.finish(), None);
    }

    #[test]
    fn a_robot_pushed_during_the_measurement_is_refused_and_too_few_samples_too() {
        let mut startup = GyroBiasStartup::default();
        for k in 10..100u64 {
            startup.on_sample(&sample(k * 5_000, 0.3 * ((k % 7) as f64)));
        }
        assert!(matches!(
            startup.finish(),
            Some(BiasOutcome::Refused(BiasError::TooFewSamples { .. }))
        ));
        let mut pushed = GyroBiasStartup::default();
        let outcome =
            (10..400u64).find_map(|k| pushed.on_sample(&sample(k * 5_000, 0.3 * ((k % 7) as f64))));
        assert!(matches!(
            outcome,
            Some(BiasOutcome::Refused(BiasError::Moving { .. }))
        ));
    }
}
