//! The best a measure of progress has reached, and since when it has gone no further: the
//! jam watch's distance to the drop (`mission::jam`) and the stall watch's way along a
//! carry's route (`mission::stall`) both ask how long the robot has stopped getting on.
//!
//! Judged on the best, not the latest: a robot pushing against something spins its wheels,
//! and the estimate runs on with them a few centimetres before the lidar pulls it back.
//! That run sets one best; the ones after it reach about as far and set none.

/// The best value of a measure that should keep growing, and when it was reached.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Best {
    value: f64,
    since_us: u64,
}

/// Tracks a measure that should keep growing (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Progress {
    best: Option<Best>,
}

impl Progress {
    /// Note `value` at `now_us`; how long, s, it has gone without growing more than `gain`
    /// past its best (0 when it just did, or at the first value).
    pub(super) fn stalled_s(&mut self, now_us: u64, value: f64, gain: f64) -> f64 {
        match self.best {
            Some(best) if value <= best.value + gain => {
                now_us.saturating_sub(best.since_us) as f64 * 1e-6
            }
            _ => {
                self.best = Some(Best {
                    value,
                    since_us: now_us,
                });
                0.0
            }
        }
    }

    /// Forget the best: the next value starts afresh.
    pub(super) fn reset(&mut self) {
        self.best = None;
    }

    /// The best reached `held_us` later: the mission stood held that long (its clock
    /// stopped).
    pub(super) fn later(&mut self, held_us: u64) {
        if let Some(best) = self.best.as_mut() {
            best.since_us = best.since_us.saturating_add(held_us);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000;

    #[test]
    fn growing_keeps_the_clock_at_zero_and_a_plateau_runs_it() {
        let mut p = Progress::default();
        assert_eq!(p.stalled_s(0, 0.0, 0.01), 0.0);
        assert_eq!(p.stalled_s(S, 0.05, 0.01), 0.0);
        assert_eq!(p.stalled_s(2 * S, 0.055, 0.01), 1.0);
        assert_eq!(p.stalled_s(3 * S, 0.03, 0.01), 2.0);
        assert_eq!(p.stalled_s(4 * S, 0.07, 0.01), 0.0);
    }

    #[test]
    fn a_hold_moves_the_clock_on_and_a_reset_forgets() {
        let mut p = Progress::default();
        p.stalled_s(0, 1.0, 0.01);
        p.later(5 * S);
        assert_eq!(p.stalled_s(6 * S, 1.0, 0.01), 1.0);
        p.reset();
        assert_eq!(p.stalled_s(7 * S, 0.0, 0.01), 0.0);
    }
}
