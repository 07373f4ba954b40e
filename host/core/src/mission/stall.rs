//! A carry that stopped getting on along its route.
//!
//! A carry can meet what its routes do not know: a part left standing proud of its slot,
//! one pushed out of it, a robot whose estimate runs ahead of it after a slip. The body and
//! its part stop there, the wheels spin on, and the estimate, pulled back by every scan, goes
//! nowhere. Before this watch the robot pushed until `drive_timeout_s` ran out, 25 s,
//! pushing the part it met out of its slot meanwhile. The watch tells it within
//! [`MissionConfig::stall_s`](super::MissionConfig::stall_s): the way along the route (and
//! the heading's turning, which a turn on the spot makes instead) has not grown by
//! [`PROGRESS_M`] for that long. The mission then treats the carry as one run out of time:
//! it marks where it stalled (`Navigator::blocked_here`) and gives the carry up.
//!
//! Near the drop the jam watch (`mission::jam`) has the say: a part caught on a divider's tip
//! is gripped again centred, not given up.

use crate::field::geometry::wrap_angle;

use super::progress::Progress;

/// What counts as getting on, m: more than the estimate's wobble against an obstacle (the
/// wheels run it on a few centimetres between scans, and the best of those runs is kept).
pub(super) const PROGRESS_M: f64 = 0.02;

/// How far a turn on the spot counts as getting on, m per radian: the body's half width,
/// how far its corners move.
const TURN_LEVER_M: f64 = 0.15;

/// Watches a carry's way along its route for a stall.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct StallWatch {
    along: Progress,
    /// The heading at the last tick, rad, and the turning since the watch began, rad.
    last_yaw_rad: Option<f64>,
    turned_rad: f64,
}

impl StallWatch {
    /// How long, s, the robot at `now_us`, `along_m` along its route with heading
    /// `yaw_rad`, has not got on by [`PROGRESS_M`].
    pub(super) fn stalled_s(&mut self, now_us: u64, along_m: f64, yaw_rad: f64) -> f64 {
        if let Some(last) = self.last_yaw_rad {
            self.turned_rad += wrap_angle(yaw_rad - last).abs();
        }
        self.last_yaw_rad = Some(yaw_rad);
        self.along
            .stalled_s(now_us, along_m + TURN_LEVER_M * self.turned_rad, PROGRESS_M)
    }

    /// Start watching afresh (a new leg).
    pub(super) fn reset(&mut self) {
        *self = Self::default();
    }

    /// Every time `held_us` later: the mission stood held that long (its clock stopped).
    pub(super) fn later(&mut self, held_us: u64) {
        self.along.later(held_us);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000;
    const TICK: u64 = 20_000;

    #[test]
    fn a_robot_that_stops_getting_on_is_stalled_for_as_long_as_it_stands() {
        let mut watch = StallWatch::default();
        let mut last = 0.0;
        for k in 0..100 {
            // 0.3 m/s for a second, then against something: the wheels run the estimate
            // 3 cm on between scans and the scans pull it back.
            let along = if k < 50 {
                0.3 * (k * TICK) as f64 * 1e-6
            } else {
                0.15 + 0.03 * ((k % 7) as f64 / 7.0)
            };
            last = watch.stalled_s(k * TICK, along, 0.0);
        }
        assert!((last - 1.0).abs() < 0.05, "{last}");
    }

    #[test]
    fn a_turn_on_the_spot_gets_on() {
        let mut watch = StallWatch::default();
        for k in 0..100 {
            // π in 2 s.
            let yaw = -std::f64::consts::PI + std::f64::consts::PI * k as f64 / 100.0 * 2.0;
            assert!(watch.stalled_s(k * TICK, 0.0, yaw) < 0.3, "at tick {k}");
        }
    }

    #[test]
    fn a_hold_stops_its_clock_and_a_reset_forgets() {
        let mut watch = StallWatch::default();
        watch.stalled_s(0, 0.5, 0.0);
        watch.later(5 * S);
        assert!((watch.stalled_s(6 * S, 0.5, 0.0) - 1.0).abs() < 1e-9);
        watch.reset();
        assert_eq!(watch.stalled_s(7 * S, 0.5, 0.0), 0.0);
    }
}
