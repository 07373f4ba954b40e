//! A short history of filter states, one per odometry step, with the input that produced
//! each, so that a late scan can be applied at its acquisition time and the later inputs
//! re-applied, and so that scan points can be de-skewed with the poses of their own times.

use std::collections::VecDeque;

use super::ekf::{EkfState, StepInput};
use crate::field::geometry::{Pose2, wrap_angle};

/// One odometry step: the state at its end and the input that led to it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// End of the step (the odometry batch's receive time), µs.
    pub time_us: u64,
    /// The input applied from the previous step; `None` for the first entry after a reset.
    pub input: Option<StepInput>,
    /// The state after the step.
    pub state: EkfState,
}

/// Bounded, time-ordered ring of [`Step`]s.
#[derive(Clone, Debug, PartialEq)]
pub struct History {
    steps: VecDeque<Step>,
    capacity: usize,
}

impl History {
    /// A history holding only `state` at `time_us`; keeps at most `capacity` (≥ 2) steps.
    pub fn new(state: EkfState, time_us: u64, capacity: usize) -> Self {
        let capacity = capacity.max(2);
        let mut steps = VecDeque::with_capacity(capacity);
        steps.push_back(Step {
            time_us,
            input: None,
            state,
        });
        Self { steps, capacity }
    }

    /// The newest step.
    pub fn latest(&self) -> &Step {
        // Never empty: created with one step, and `push` evicts only beyond capacity ≥ 2.
        &self.steps[self.steps.len() - 1]
    }

    /// The oldest step kept.
    pub fn oldest(&self) -> &Step {
        &self.steps[0]
    }

    /// Append a step (its time must not precede the newest; the caller checks).
    pub fn push(&mut self, step: Step) {
        if self.steps.len() == self.capacity {
            self.steps.pop_front();
        }
        self.steps.push_back(step);
    }

    /// Number of steps kept.
    pub fn len(&self) -> usize {
        self.steps.len()
    }

    /// Always false (a history holds at least one step); for clippy's `len` convention.
    pub fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }

    /// The step at `index` (0 = oldest).
    pub fn get(&self, index: usize) -> Option<&Step> {
        self.steps.get(index)
    }

    /// Index of the step whose time is nearest to `time_us`.
    pub fn nearest(&self, time_us: f64) -> usize {
        let after = self.steps.partition_point(|s| (s.time_us as f64) < time_us);
        if after == 0 {
            return 0;
        }
        if after == self.steps.len() {
            return after - 1;
        }
        let before_gap = time_us - self.steps[after - 1].time_us as f64;
        let after_gap = self.steps[after].time_us as f64 - time_us;
        if before_gap <= after_gap {
            after - 1
        } else {
            after
        }
    }

    /// The pose at `time_us`: linear between the two steps around it (yaw along the short
    /// way), held at the ends.
    pub fn pose_at(&self, time_us: f64) -> Pose2 {
        let after = self.steps.partition_point(|s| (s.time_us as f64) < time_us);
        if after == 0 {
            return self.steps[0].state.pose();
        }
        if after == self.steps.len() {
            return self.latest().state.pose();
        }
        let (a, b) = (&self.steps[after - 1], &self.steps[after]);
        let span = (b.time_us - a.time_us) as f64;
        let f = if span > 0.0 {
            ((time_us - a.time_us as f64) / span).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let (pa, pb) = (a.state.pose(), b.state.pose());
        Pose2::new(
            pa.x + (pb.x - pa.x) * f,
            pa.y + (pb.y - pa.y) * f,
            wrap_angle(pa.yaw_rad + wrap_angle(pb.yaw_rad - pa.yaw_rad) * f),
        )
    }

    /// Replace the state at `index` and recompute every later state by re-applying its
    /// stored input with `predict`.
    pub fn rewrite_from(
        &mut self,
        index: usize,
        state: EkfState,
        mut predict: impl FnMut(&EkfState, &StepInput) -> EkfState,
    ) {
        let Some(step) = self.steps.get_mut(index) else {
            return;
        };
        step.state = state;
        let mut previous = state;
        for step in self.steps.iter_mut().skip(index + 1) {
            if let Some(input) = &step.input {
                step.state = predict(&previous, input);
            }
            previous = step.state;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::LocalisationConfig;
    use crate::odometry::BodyIncrement;

    fn state(x: f64, yaw: f64) -> EkfState {
        EkfState::new(
            Pose2::new(x, 0.0, yaw),
            0.0,
            1e-4,
            &LocalisationConfig::default(),
        )
    }

    #[test]
    fn bounded_nearest_and_interpolated() {
        let mut h = History::new(state(0.0, 3.1), 1000, 3);
        h.push(Step {
            time_us: 2000,
            input: None,
            state: state(1.0, -3.1),
        });
        h.push(Step {
            time_us: 3000,
            input: None,
            state: state(2.0, -3.1),
        });
        assert_eq!(h.nearest(1400.0), 0);
        assert_eq!(h.nearest(1600.0), 1);
        let mid = h.pose_at(1500.0);
        assert!((mid.x - 0.5).abs() < 1e-12);
        // Yaw goes the short way across ±π.
        assert!(
            wrap_angle(mid.yaw_rad - std::f64::consts::PI).abs() < 1e-9,
            "{mid:?}"
        );
        assert_eq!(h.pose_at(9999.0).x, 2.0);
        h.push(Step {
            time_us: 4000,
            input: None,
            state: state(3.0, 0.0),
        });
        assert_eq!(h.len(), 3);
        assert_eq!(h.oldest().time_us, 2000);
        assert_eq!(h.pose_at(0.0).x, 1.0);
    }

    #[test]
    fn rewrite_reapplies_later_inputs() {
        let config = LocalisationConfig::default();
        let input = StepInput {
            dt_s: 0.02,
            increment: BodyIncrement {
                dx_m: 0.01,
                dy_m: 0.0,
                dtheta_rad: 0.0,
            },
            gyro_dtheta_rad: None,
            unmeasured_translation_std_m: None,
        };
        let predict = |s: &EkfState, i: &StepInput| s.predict(i, &config, 1.75e-4).0;
        let mut h = History::new(state(0.0, 0.0), 0, 8);
        for k in 1..=3 {
            let next = predict(&h.latest().state, &input);
            h.push(Step {
                time_us: k * 20_000,
                input: Some(input),
                state: next,
            });
        }
        h.rewrite_from(1, state(5.0, 0.0), predict);
        assert!((h.latest().state.mean[0] - 5.02).abs() < 1e-12);
    }
}
