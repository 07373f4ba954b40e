//! `[navigation]`: speed, acceleration and gain limits of our path follower, docking and the
//! free-space shortcuts (`control`, `planning::shortcuts`).

use serde::{Deserialize, Serialize};

use super::check::Checker;
use super::limits;

/// Limits and gains of the path follower. Defaults derived from the motor and traction
/// models (`[robot]`, `[motor]`, `[traction]`); each doc comment gives the derivation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NavigationConfig {
    /// Top along-track speed, m/s. 0.60: the wheel limit `robot.max_wheel_speed_rad_s`
    /// 24.3 rad/s × 0.03 m radius = 0.73 m/s at the rim with no load; 0.60 (82 %) leaves the
    /// Mega's wheel PI headroom to reject load; corrections beyond the limit are scaled down
    /// with the whole twist (direction kept). Tried with `corner_blend_m` 0.08 and
    /// `dock_speed_m_s` 0.20: on the realistic world's tuning seeds 1–10 and 61–70
    /// (calibrated) 4–5 % faster per round with 7 collisions against 11, but on the held-out
    /// seeds 11–60 only 2–4 % faster with 47 collisions against 29 and 2 actions given up:
    /// rejected. 0.70 alone at `804ca0e` (tuning seeds 61–110, calibrated): realistic 1 % or
    /// less faster, harsh 194 → 289 collisions (README: Worlds): rejected.
    pub max_speed_m_s: f64,
    /// Along-track acceleration limit, m/s². 2.0: friction allows μg = 0.7 × 9.81 =
    /// 6.9 m/s² (`traction.friction_coefficient`), the motor (τ = 0.1 s) reaches 0.6 m/s in
    /// a step at up to 6 m/s²; 2.0 stays a factor 3 below both, so the wheels do not slip
    /// (the odometry stays exact) and the PI follows the ramp without saturating. (3.0 was
    /// tried in the benchmark: a few % faster, but corner overshoot caused collisions.)
    pub max_accel_m_s2: f64,
    /// Deceleration limit, m/s². 2.0: as `max_accel_m_s2` (same friction and motor).
    pub max_decel_m_s2: f64,
    /// Yaw rate limit, rad/s. 3.5: rotation adds k·ω = 0.1725 m × 3.5 = 0.60 m/s to each
    /// rim (k = half the wheelbase sum, `robot`), as much as the top speed; the robot turns
    /// mostly where it moves slowly, and beyond the 0.73 m/s rim limit the body twist is
    /// scaled down as a whole (direction kept). 2.0 was 4 % slower in the benchmark; 4.2 at
    /// `804ca0e` gained nothing in the realistic world and cost 24 collisions in the harsh one
    /// (README: Worlds).
    pub max_yaw_rate_rad_s: f64,
    /// Length over which a corner's change of direction is spread, m. 0.05: tuned in the
    /// simulator. A corner of angle φ at speed v changes the velocity by 2·v·sin(φ/2)
    /// within about this length; keeping that within `max_accel_m_s2` gives the corner
    /// speed v = √(a·ℓ / (2·sin(φ/2))) (0.27 m/s at 90°). 0.08 was 2 % faster in the
    /// benchmark but overshot a corner next to a divider into a collision (the graph's rows
    /// leave 10–20 mm); see `max_speed_m_s` for a later try.
    pub corner_blend_m: f64,
    /// Cross-track correction gain, 1/s: sideways speed per metre off the path. 5.0: tuned
    /// on the realistic world's seeds 61–110 (calibrated), where 3.0 left the ~1 cm a corner
    /// overshoots standing for some 15 cm of the next leg: into the outgoing row that is
    /// where a carried part passes the first divider's tip (22 collisions in 150 rounds
    /// with 3.0, 15 with 5.0 and 14 with 7.0, each with the slot-entry gate of
    /// `control::follower`). The 50 Hz loop with ~40 ms of telemetry and motor lag is stable
    /// up to about 8.
    pub cross_track_gain_per_s: f64,
    /// Heading gain, 1/s. 6.0: tuned in the simulator (the original's `k_w` is 4,
    /// original-system.md §6.3; with the lag compensation 6 is 4 % faster and still does not
    /// overshoot). 9 left no run with a full score at `804ca0e` (README: Worlds).
    pub heading_gain_per_s: f64,
    /// Lag compensation, s: the follower acts on the estimate moved on by its last command
    /// over this time. 0.12: the motor time constant 0.1 s (`motor.time_constant_s`) plus
    /// about one 20 ms control period of telemetry delay; without it the robot overshoots a
    /// 90° corner by about v·τ (2–3 cm at the corner speed).
    pub lag_compensation_s: f64,
    /// Gain of the final position hold near the goal, 1/s. 6.0: tuned in the simulator
    /// (3 is 5 % slower; 10 starts limit cycles around the goal). Within 11 cm of a goal it
    /// binds before the 2 m/s² braking curve, so the last centimetres are an exponential
    /// with a 0.17 s time constant. Doubling it beyond 3 cm of a drop's goal (6 within
    /// 1 cm) was measured at `a210463` (realistic world, calibrated): 0.3 / 0.5 / 0.6 s
    /// faster per round over seeds 61–160 with no collision, but drops stopped 0.5 mm
    /// deeper on average (170 drops, seeds 61–70) and the held-out seeds 11–60 had a part
    /// touch machine A's back wall (round 2, seed 36; none before): not kept. Doubled onto a
    /// part too, the ideal world's magnet pushed a part into its slot's back wall in 6 of
    /// 50 rounds 1.
    pub position_gain_per_s: f64,
    /// Arrival tolerance on the predicted stopping point, m. 0.005: half the 0.01 m goal
    /// target, the rest is margin for the estimate's error and the coasting.
    pub goal_tolerance_m: f64,
    /// Arrival tolerance on heading, degrees. 1.0: half the 2° target.
    pub goal_heading_tolerance_deg: f64,
    /// Length of the straight, slow docking approach into a slot, m. 0.05: assumption; the
    /// robot is square to the face over this length so the switch (±25 mm, ±15°) closes.
    pub dock_length_m: f64,
    /// Speed cap of the docking approach to a part, m/s (a drop's approach has none: it
    /// brakes onto its pose, `control::route::Route::docks_on_switch`). 0.25: the cap only
    /// matters until the braking curve and the position hold take over, which bring the
    /// speed to ~0.05 m/s by the time the switch closes (5 mm before the pick pose), so the
    /// robot coasts ~5 mm, well inside the 15 mm gap to the plate. Tuned on the realistic
    /// world's seeds 61–110 (calibrated), mean s per round 1 / 2 / 3 (collisions in the 150
    /// rounds): 0.15 capping drops too 38.4 / 42.4 / 54.4 (1); with the drop's approach
    /// uncapped, 0.15 37.5 / 41.0 / 52.5 (2), 0.25 37.1 / 40.4 / 51.6 (1), 0.30 37.0 / 40.2 /
    /// 51.4 (5), and 0.25 with `position_gain_per_s` 8 36.7 / 39.8 / 50.7 (25).
    pub dock_speed_m_s: f64,
    /// How far beyond the pick pose the robot creeps straight on when it arrives there and
    /// the switch is still open, m. 0.04: a 90 mm part in a 130 mm slot may stand 20 mm
    /// deeper than its nominal place (competition.md §1.7), and the pose estimate may be a
    /// centimetre off when the lidar's calibration is (real-world-errors.md); the original
    /// creeps with no limit at all (original-system.md §6.4). 0 turns the creep off.
    pub dock_creep_m: f64,
    /// Creep speed, m/s (the docking approach hands over to the creep on the pick pose
    /// without stopping, `control::follower`). 0.035: the switch closes about 5 mm before the magnet meets
    /// the plate (its lever reaches 20 mm beyond the front face, the magnet 15 mm), and the
    /// robot stops some 0.14 s later (up to 40 ms of telemetry, the motors' 0.1 s time
    /// constant): 5 mm / 0.14 s. At 0.05 the magnet pushed a part standing against its
    /// slot's back wall 2 mm into it (the ideal world's seed 51, rounds 1 and 2).
    pub dock_creep_speed_m_s: f64,
    /// No rotation within this path length of the start, m. 0.10: leaving a slot, the
    /// robot's front is then 0.1 m clear of the divider tips (the original used 0.15 m,
    /// §6.3). The planner further restricts turning to where the swept disc is free.
    pub rotate_after_m: f64,
    /// The heading must reach the goal's this path length before the end, m. 0.08: more
    /// than `dock_length_m`, so the robot enters a slot square.
    pub align_before_m: f64,
    /// Replace graph detours by straight lines where the footprint is free. true: over whole
    /// rounds the few corners the rows leave room for pay (`bench rounds --calibrated`,
    /// realistic world, tuning seeds 61–110: 36.5 / 38.5 / 49.4 → 36.0 / 38.1 / 49.1 s per
    /// round, collisions 1 → 0), although `bench navigation`'s single trips gain almost
    /// nothing (3.15 → 3.13 s), which is why it was off before.
    pub shortcuts: bool,
    /// Plan our legs through free space for the whole body with its heading, the part it
    /// carries and its turn (`planning::free_routes`), rather than on the waypoint graph
    /// with shortcuts, which stays the fallback wherever no free route is found (a start
    /// inside what the robot believes is an obstacle).
    pub free_routes: bool,
    /// Extra clearance around the robot's swept footprint for shortcuts, m. 0.02:
    /// assumption, covers the estimate's error and the cross-track error.
    pub shortcut_margin_m: f64,
}

impl Default for NavigationConfig {
    fn default() -> Self {
        Self {
            max_speed_m_s: 0.60,
            max_accel_m_s2: 2.0,
            max_decel_m_s2: 2.0,
            max_yaw_rate_rad_s: 3.5,
            corner_blend_m: 0.05,
            cross_track_gain_per_s: 5.0,
            heading_gain_per_s: 6.0,
            lag_compensation_s: 0.12,
            position_gain_per_s: 6.0,
            goal_tolerance_m: 0.005,
            goal_heading_tolerance_deg: 1.0,
            dock_length_m: 0.05,
            dock_speed_m_s: 0.25,
            dock_creep_m: 0.04,
            dock_creep_speed_m_s: 0.035,
            rotate_after_m: 0.10,
            align_before_m: 0.08,
            shortcuts: true,
            free_routes: true,
            shortcut_margin_m: 0.02,
        }
    }
}

impl NavigationConfig {
    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        self.check_motion(c);
        self.check_gains(c);
        self.check_docking(c);
        self.check_route(c);
    }

    /// Speeds and accelerations.
    fn check_motion(&self, c: &mut Checker<'_>) {
        c.within(
            "max_speed_m_s",
            self.max_speed_m_s,
            0.01,
            5.0,
            "m/s",
            "robot.max_wheel_speed_rad_s bounds it further (see there)",
        );
        const ACCEL: &str = "1.5 g: more than rubber's friction gives on any floor";
        c.within(
            "max_accel_m_s2",
            self.max_accel_m_s2,
            0.01,
            15.0,
            "m/s²",
            ACCEL,
        );
        c.within(
            "max_decel_m_s2",
            self.max_decel_m_s2,
            0.01,
            15.0,
            "m/s²",
            ACCEL,
        );
        c.within(
            "max_yaw_rate_rad_s",
            self.max_yaw_rate_rad_s,
            0.01,
            20.0,
            "rad/s",
            "five times the 4.2 rad/s the default wheels reach turning on the spot",
        );
        c.within(
            "corner_blend_m",
            self.corner_blend_m,
            0.001,
            0.5,
            "m",
            "a corner spread over more than 0.5 m cuts through the graph's 0.15 m rows",
        );
    }

    /// The follower's gains.
    fn check_gains(&self, c: &mut Checker<'_>) {
        const GAIN: &str = "at 50/s the 50 Hz loop corrects the whole error in one 20 ms tick; \
                            a larger gain overshoots every tick";
        c.within(
            "cross_track_gain_per_s",
            self.cross_track_gain_per_s,
            0.01,
            50.0,
            "1/s",
            GAIN,
        );
        c.within(
            "heading_gain_per_s",
            self.heading_gain_per_s,
            0.01,
            50.0,
            "1/s",
            GAIN,
        );
        c.within(
            "position_gain_per_s",
            self.position_gain_per_s,
            0.01,
            50.0,
            "1/s",
            GAIN,
        );
        c.within(
            "lag_compensation_s",
            self.lag_compensation_s,
            0.0,
            1.0,
            "s",
            "ten times the motor's 0.1 s time constant",
        );
    }

    /// Arrival and docking.
    fn check_docking(&self, c: &mut Checker<'_>) {
        c.within(
            "goal_tolerance_m",
            self.goal_tolerance_m,
            0.0005,
            0.025,
            "m",
            "the switch closes within ±25 mm of the plate",
        );
        c.within(
            "goal_heading_tolerance_deg",
            self.goal_heading_tolerance_deg,
            0.001,
            15.0,
            "°",
            "the switch closes within ±15°",
        );
        c.within(
            "dock_length_m",
            self.dock_length_m,
            0.0,
            limits::STRAIGHT_RUN_M,
            "m",
            "the approach starts in front of the slot: where machine A's output faces machine \
             B's input, the robot has 0.26 m before its back reaches the other's dividers",
        );
        let max_speed = if (0.01..=5.0).contains(&self.max_speed_m_s) {
            self.max_speed_m_s
        } else {
            5.0
        };
        c.within(
            "dock_speed_m_s",
            self.dock_speed_m_s,
            0.005,
            max_speed,
            "m/s",
            "at most navigation.max_speed_m_s",
        );
        c.within(
            "dock_creep_m",
            self.dock_creep_m,
            0.0,
            0.15,
            "m",
            "at the pick pose the robot's front is 75 mm from the slot's back wall; twice that \
             passes any part",
        );
        c.within(
            "dock_creep_speed_m_s",
            self.dock_creep_speed_m_s,
            0.005,
            0.3,
            "m/s",
            "the robot must stop within millimetres once the switch closes",
        );
    }

    /// Where the route may turn, and shortcuts.
    fn check_route(&self, c: &mut Checker<'_>) {
        c.within(
            "rotate_after_m",
            self.rotate_after_m,
            0.0,
            limits::FLOOR_DIAGONAL_M,
            "m",
            "no route is longer than the floor's 2.3 m diagonal in a straight line",
        );
        // A dock length out of its own range is reported there, not here again.
        let dock_m = if (0.0..=limits::STRAIGHT_RUN_M).contains(&self.dock_length_m) {
            self.dock_length_m
        } else {
            0.0
        };
        c.within(
            "align_before_m",
            self.align_before_m,
            dock_m,
            limits::FLOOR_DIAGONAL_M,
            "m",
            "at least navigation.dock_length_m, so the robot enters a slot square, and no more \
             than the floor's diagonal",
        );
        c.within(
            "shortcut_margin_m",
            self.shortcut_margin_m,
            0.0,
            0.2,
            "m",
            "the graph's rows leave 10–20 mm: beyond 0.2 m no shortcut is ever free",
        );
    }
}
