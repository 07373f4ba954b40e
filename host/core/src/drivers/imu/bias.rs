//! Gyro bias estimated at start-up while the robot is still (replacing the original's
//! hard-coded biases, original-system.md §3.3, §10.12).
//!
//! The bias is the per-axis mean of N gyro readings. The estimate is refused when the
//! readings show the robot was moving:
//!
//! - the per-axis standard deviation exceeds [`BiasConfig::max_std_rad_s`] (the rate
//!   changed during the window), or
//! - the per-axis mean exceeds [`BiasConfig::max_bias_rad_s`] (a steady rotation, which
//!   the spread alone cannot see).
//!
//! Take the samples after the gyro has started: the product specification gives a 35 ms
//! gyro start-up time after waking, so drop the first ~50 ms of samples after
//! [`super::Mpu9255::new`].

/// Bias estimation limits. Defaults and where they come from:
///
/// - `min_samples` 200: one second at the default 200 Hz; the mean's noise is then
///   σ/√200 ≈ 0.07 σ;
/// - `max_std_rad_s` 0.01 rad/s (0.57 °/s): the MPU-9250's rate noise density is
///   0.01 °/s/√Hz (product specification §3.1), about 0.08 °/s rms through the 41 Hz
///   filter, so still readings stay far below this, while a push or a vibrating motor does
///   not;
/// - `max_bias_rad_s` 0.1 rad/s (5.7 °/s): just above the datasheet's ±5 °/s initial
///   zero-rate tolerance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BiasConfig {
    /// Fewest samples accepted.
    pub min_samples: usize,
    /// Largest per-axis standard deviation of a still robot, rad/s.
    pub max_std_rad_s: f64,
    /// Largest believable per-axis bias, rad/s.
    pub max_bias_rad_s: f64,
}

impl Default for BiasConfig {
    fn default() -> Self {
        Self {
            min_samples: 200,
            max_std_rad_s: 0.01,
            max_bias_rad_s: 0.1,
        }
    }
}

/// Why no bias was estimated.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum BiasError {
    /// Not enough samples.
    #[error("gyro bias needs at least {need} samples, got {got}")]
    TooFewSamples {
        /// Samples given.
        got: usize,
        /// Samples required.
        need: usize,
    },
    /// The spread of one axis shows motion.
    #[error(
        "gyro axis {axis} moved during bias estimation: std {std_rad_s:.4} rad/s > {limit_rad_s} rad/s"
    )]
    Moving {
        /// Axis index (0 x, 1 y, 2 z).
        axis: usize,
        /// Standard deviation measured, rad/s.
        std_rad_s: f64,
        /// The limit, rad/s.
        limit_rad_s: f64,
    },
    /// One axis reads a steady rate larger than any plausible bias.
    #[error(
        "gyro axis {axis} reads a steady {mean_rad_s:.4} rad/s, more than a bias can be ({limit_rad_s} rad/s): is the robot turning?"
    )]
    Rotating {
        /// Axis index (0 x, 1 y, 2 z).
        axis: usize,
        /// Mean measured, rad/s.
        mean_rad_s: f64,
        /// The limit, rad/s.
        limit_rad_s: f64,
    },
    /// A sample is NaN or infinite.
    #[error("gyro sample {index} is not finite")]
    NotFinite {
        /// Index of the sample.
        index: usize,
    },
}

/// The per-axis gyro bias, rad/s, from `samples_rad_s` taken while still (see the module
/// doc).
pub fn estimate_gyro_bias(
    samples_rad_s: &[[f64; 3]],
    config: &BiasConfig,
) -> Result<[f64; 3], BiasError> {
    let n = samples_rad_s.len();
    if n < config.min_samples.max(2) {
        return Err(BiasError::TooFewSamples {
            got: n,
            need: config.min_samples.max(2),
        });
    }
    if let Some(index) = samples_rad_s
        .iter()
        .position(|s| s.iter().any(|v| !v.is_finite()))
    {
        return Err(BiasError::NotFinite { index });
    }
    let mut mean = [0.0; 3];
    for (axis, m) in mean.iter_mut().enumerate() {
        *m = samples_rad_s.iter().map(|s| s[axis]).sum::<f64>() / n as f64;
    }
    for axis in 0..3 {
        let variance = samples_rad_s
            .iter()
            .map(|s| (s[axis] - mean[axis]).powi(2))
            .sum::<f64>()
            / (n - 1) as f64;
        let std_rad_s = variance.sqrt();
        if std_rad_s > config.max_std_rad_s {
            return Err(BiasError::Moving {
                axis,
                std_rad_s,
                limit_rad_s: config.max_std_rad_s,
            });
        }
        if mean[axis].abs() > config.max_bias_rad_s {
            return Err(BiasError::Rotating {
                axis,
                mean_rad_s: mean[axis],
                limit_rad_s: config.max_bias_rad_s,
            });
        }
    }
    Ok(mean)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_of_still_samples() {
        let samples: Vec<[f64; 3]> = (0..300)
            .map(|k| {
                let wiggle = if k % 2 == 0 { 0.001 } else { -0.001 };
                [0.01 + wiggle, -0.02 - wiggle, 0.03]
            })
            .collect();
        let bias = estimate_gyro_bias(&samples, &BiasConfig::default()).unwrap();
        for (got, want) in bias.iter().zip([0.01, -0.02, 0.03]) {
            assert!((got - want).abs() < 1e-12);
        }
    }

    #[test]
    fn refusals() {
        let config = BiasConfig::default();
        assert_eq!(
            estimate_gyro_bias(&[[0.0; 3]; 10], &config),
            Err(BiasError::TooFewSamples { got: 10, need: 200 })
        );
        let mut samples = vec![[0.0; 3]; 200];
        samples[50][1] = f64::NAN;
        assert_eq!(
            estimate_gyro_bias(&samples, &config),
            Err(BiasError::NotFinite { index: 50 })
        );
        // A push: the z rate ramps up halfway through.
        let pushed: Vec<[f64; 3]> = (0..200)
            .map(|k| [0.0, 0.0, if k < 100 { 0.0 } else { 0.05 }])
            .collect();
        assert!(matches!(
            estimate_gyro_bias(&pushed, &config),
            Err(BiasError::Moving { axis: 2, .. })
        ));
        // A steady turn at 0.5 rad/s.
        let turning = vec![[0.0, 0.0, 0.5]; 200];
        let err = estimate_gyro_bias(&turning, &config).unwrap_err();
        assert!(matches!(err, BiasError::Rotating { axis: 2, .. }));
        assert!(err.to_string().contains("0.5000 rad/s"), "{err}");
    }
}
