//! The gyro's yaw angle as a function of time: the integral of the raw z rate (bias not
//! removed), so that the rotation over any odometry step can be read off.

use std::collections::VecDeque;

/// Samples kept: 1.28 s at 200 Hz, more than any odometry step needs.
const CAPACITY: usize = 256;

/// Running integral of the gyro's z rate (trapezoidal between samples).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GyroIntegrator {
    /// (sample time µs, ∫ rate dt since the first sample rad, rate rad/s).
    samples: VecDeque<(u64, f64, f64)>,
}

impl GyroIntegrator {
    /// An empty integrator.
    pub fn new() -> Self {
        Self {
            samples: VecDeque::with_capacity(CAPACITY),
        }
    }

    /// Add a rate sample, rad/s, at `time_us`; samples not after the newest are ignored
    /// (returns false), as are non-finite rates.
    pub fn push(&mut self, time_us: u64, rate_rad_s: f64) -> bool {
        if !rate_rad_s.is_finite() {
            return false;
        }
        let angle = match self.samples.back() {
            Some(&(t, a, r)) if time_us > t => {
                a + 0.5 * (r + rate_rad_s) * (time_us - t) as f64 * 1e-6
            }
            Some(_) => return false,
            None => 0.0,
        };
        if self.samples.len() == CAPACITY {
            self.samples.pop_front();
        }
        self.samples.push_back((time_us, angle, rate_rad_s));
        true
    }

    /// Forget every sample (after a gap or a reset).
    pub fn clear(&mut self) {
        self.samples.clear();
    }

    /// The rotation from `from_us` to `to_us`, rad, raw. `None` unless the samples cover
    /// `from_us` and reach within `max_gap_us` of `to_us` (the last rate is held beyond).
    pub fn angle_between(&self, from_us: u64, to_us: u64, max_gap_us: u64) -> Option<f64> {
        let &(first, ..) = self.samples.front()?;
        let &(last, ..) = self.samples.back()?;
        if from_us < first || to_us.saturating_sub(last) > max_gap_us || to_us < from_us {
            return None;
        }
        Some(self.angle_at(to_us) - self.angle_at(from_us))
    }

    fn angle_at(&self, time_us: u64) -> f64 {
        let after = self.samples.partition_point(|s| s.0 < time_us);
        if after == self.samples.len() {
            let (t, a, r) = self.samples[after - 1];
            return a + r * (time_us - t) as f64 * 1e-6;
        }
        let (t1, a1, r1) = self.samples[after];
        if after == 0 || t1 == time_us {
            return a1;
        }
        let (t0, a0, r0) = self.samples[after - 1];
        // Rate linear between the samples: integrate it exactly.
        let span = (t1 - t0) as f64 * 1e-6;
        let dt = (time_us - t0) as f64 * 1e-6;
        let rate_at = r0 + (r1 - r0) * dt / span;
        a0 + 0.5 * (r0 + rate_at) * dt
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrates_a_ramp_exactly_and_needs_coverage() {
        let mut g = GyroIntegrator::new();
        assert_eq!(g.angle_between(0, 10, 5000), None);
        // rate = t (s): angle from 0.01 s to 0.03 s = (0.03² − 0.01²)/2.
        for k in 0..=10u64 {
            assert!(g.push(k * 5000, k as f64 * 0.005));
        }
        assert!(!g.push(50_000, 1.0), "not after the newest");
        let a = g.angle_between(10_000, 30_000, 5000).unwrap();
        assert!(
            (a - (0.03f64.powi(2) - 0.01f64.powi(2)) / 2.0).abs() < 1e-12,
            "{a}"
        );
        let mid = g.angle_between(12_500, 17_500, 5000).unwrap();
        assert!((mid - (0.0175f64.powi(2) - 0.0125f64.powi(2)) / 2.0).abs() < 1e-12);
        assert!(g.angle_between(40_000, 54_000, 5000).is_some());
        assert_eq!(
            g.angle_between(40_000, 56_000, 5000),
            None,
            "gyro too stale"
        );
        g.clear();
        assert_eq!(g.angle_between(0, 1, 5000), None);
    }
}
