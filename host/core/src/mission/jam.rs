//! A carried part jammed short of its drop.
//!
//! The magnet pulls a part's plate flat against its face but leaves it where it met the
//! face across it: a part gripped where it lay knocked out of its slot, or caught again by
//! the face before the switch had been open long enough to count it lost, rides up to the
//! switch's lateral reach off centre. A slot's dividers leave 20 mm on each side of a
//! centred part; off centre and with the pose's few millimetres, its corner meets a
//! divider's tip, and the robot pushed there until the drive timed out (20 s, then the
//! action given up with the part still on the magnet). The robot cannot see where the part
//! sits on its face, but it can see that it stopped getting closer to its drop: then it backs
//! off the tip ([`JAMMED_BACK_OUT_M`]), lets the part go, and grips it again the way it grips
//! a part that fell off (`mission::search`), whose centring strafes find the plate's edges
//! with the switch before the magnet takes it up, so the part rides centred into the slot.

use super::progress::Progress;

/// Distance from the drop pose within which the robot is watched for a jam, m: a slot's
/// dividers are 7 cm long, so the carried part meets their tips with the robot about 7 cm
/// short of its drop pose (6.7 and 7.4 cm in the two runs of the fault bench that jammed).
pub(super) const WATCH_RADIUS_M: f64 = 0.15;

/// Distance from the drop pose within which a stall is no jam, m: the part is in its slot
/// ([`super::LET_GO_SHORT_OF_DROP_M`]) and pressed against its back. Judged on the distance
/// when the stall has lasted, not the closest: a robot pushing a divider spins its wheels,
/// and the estimate runs on with them a few centimetres before the lidar pulls it back.
pub(super) const IN_SLOT_M: f64 = super::LET_GO_SHORT_OF_DROP_M;

/// What counts as getting closer, m: more than the estimate's jitter standing still (a
/// robot pushing a divider wobbles by a few millimetres as the lidar corrects its wheels).
pub(super) const PROGRESS_M: f64 = 0.003;

/// How long the robot may get no closer before it counts as jammed, s. A free robot docking
/// at the drop closes at 5 cm/s or more; 1 s is 5 cm of its slowest approach.
pub(super) const STALL_S: f64 = 1.0;

/// Jams per action the robot backs off and grips its part again for; after them it pushes on
/// until the drive times out, as before.
pub(super) const MAX_RESEATS: u32 = 2;

/// Reverse from a jam before letting the part go, m: 3 cm takes its corner off the tip;
/// the whole `back_out_m` from there, short of the drop pose, can put the body's back onto
/// the dividers behind it (machine B's, over outgoing slot 3), and so can these 3 cm where the
/// jam came farther out: the mission reverses less where the walls behind leave less.
pub(super) const JAMMED_BACK_OUT_M: f64 = 0.03;

/// Watches a carry's distance to its drop pose for a stall within [`WATCH_RADIUS_M`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct JamWatch {
    /// Getting closer is the progress watched: the distance's negative.
    closer: Progress,
}

impl JamWatch {
    /// Whether the robot, `distance_m` from its drop pose at `now_us`, has come no closer
    /// than [`PROGRESS_M`] for [`STALL_S`] within [`WATCH_RADIUS_M`] and stands at least
    /// [`IN_SLOT_M`] short.
    pub(super) fn jammed(&mut self, now_us: u64, distance_m: f64) -> bool {
        if distance_m > WATCH_RADIUS_M {
            self.closer.reset();
            return false;
        }
        self.closer.stalled_s(now_us, -distance_m, PROGRESS_M) >= STALL_S && distance_m >= IN_SLOT_M
    }

    /// Start watching afresh (a new carry).
    pub(super) fn reset(&mut self) {
        self.closer.reset();
    }

    /// Every time `held_us` later: the mission stood held that long (its clock stopped).
    pub(super) fn later(&mut self, held_us: u64) {
        self.closer.later(held_us);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000;

    #[test]
    fn a_robot_that_stops_getting_closer_within_the_radius_is_jammed_after_the_stall_time() {
        let mut watch = JamWatch::default();
        assert!(!watch.jammed(0, 0.10));
        assert!(!watch.jammed(S / 2, 0.099));
        assert!(!watch.jammed(S - 1, 0.101));
        assert!(watch.jammed(S, 0.098));
    }

    #[test]
    fn getting_closer_keeps_it_free() {
        let mut watch = JamWatch::default();
        for k in 0..100 {
            // 5 cm/s, the slowest docking approach, ticking at 50 Hz.
            let t = k * S / 50;
            assert!(!watch.jammed(t, 0.14 - 0.05 * k as f64 / 50.0));
        }
    }

    #[test]
    fn a_robot_stalled_with_its_part_in_the_slot_is_not_jammed() {
        let mut watch = JamWatch::default();
        assert!(!watch.jammed(0, 0.02));
        assert!(!watch.jammed(5 * S, 0.02));
    }

    #[test]
    fn a_stall_whose_estimate_ran_on_with_the_wheels_is_judged_where_it_stands() {
        let mut watch = JamWatch::default();
        assert!(!watch.jammed(0, 0.07));
        // Wheels spinning against a divider: the estimate runs 4 cm on, then back.
        assert!(!watch.jammed(S / 5, 0.028));
        assert!(!watch.jammed(S / 2, 0.06));
        assert!(watch.jammed(S + S / 5, 0.065));
    }

    #[test]
    fn outside_the_radius_it_is_never_jammed_and_forgets() {
        let mut watch = JamWatch::default();
        assert!(!watch.jammed(0, 0.10));
        assert!(!watch.jammed(2 * S, 0.20));
        assert!(!watch.jammed(2 * S + 1, 0.10));
        assert!(!watch.jammed(3 * S - 1, 0.10));
        assert!(watch.jammed(3 * S + 1, 0.10));
    }

    #[test]
    fn a_hold_stops_its_clock_and_a_reset_forgets() {
        let mut watch = JamWatch::default();
        assert!(!watch.jammed(0, 0.10));
        watch.later(5 * S);
        assert!(!watch.jammed(5 * S + S / 2, 0.10));
        assert!(watch.jammed(6 * S, 0.10));
        watch.reset();
        assert!(!watch.jammed(6 * S, 0.10));
    }
}
