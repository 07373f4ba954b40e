//! A route: the polyline a follower drives, with arc lengths, the heading to reach and an
//! optional final docking segment; and how routes to a slot are planned.

use crate::config::{Config, NavigationConfig};
use crate::field::geometry::{Pose2, Rect, Segment, Vec2, wrap_angle};
use crate::field::{Field, PART_DEPTH_M, PART_WIDTH_M, Slot};
use crate::planning::free_routes::{Departure, FreePath, FreeRoutes};
use crate::planning::graph::{PlanError, RoadMap, merge_collinear};
use crate::planning::our_map::our_graph;
use crate::planning::shortcuts::{Footprint, FreeSpace, SAMPLE_STEP_M};

/// Tolerance for merging collinear route points, m (1 mm: far below the follower's error).
pub const MERGE_TOLERANCE_M: f64 = 0.001;

/// A polyline from the start to the goal, with the goal heading.
#[derive(Clone, Debug, PartialEq)]
pub struct Route {
    points: Vec<Vec2>,
    cumulative_m: Vec<f64>,
    start_yaw_rad: f64,
    goal_yaw_rad: f64,
    dock_length_m: f64,
    turn_window_m: Option<(f64, f64)>,
    carries_part_in: bool,
    corner_caps_m_s: Vec<(usize, f64)>,
}

/// Where a position projects onto a route.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projection {
    /// Index of the segment (points `segment` → `segment + 1`).
    pub segment: usize,
    /// Arc length from the start to the projected point, m.
    pub s_m: f64,
    /// The projected point, m.
    pub point: Vec2,
    /// Unit direction of the segment.
    pub tangent: Vec2,
}

impl Route {
    /// A route through `points` (at least two, finite, consecutive ones distinct), starting
    /// with heading `start_yaw_rad` and ending with `goal_yaw_rad`; the last `dock_length_m`
    /// of it is a docking approach. `None` when the points do not make a route.
    pub fn new(
        points: Vec<Vec2>,
        start_yaw_rad: f64,
        goal_yaw_rad: f64,
        dock_length_m: f64,
    ) -> Option<Self> {
        if points.len() < 2
            || points.iter().any(|p| !p.is_finite())
            || points.windows(2).any(|w| w[0].distance(w[1]) < 1e-9)
            || !start_yaw_rad.is_finite()
            || !goal_yaw_rad.is_finite()
        {
            return None;
        }
        let mut cumulative_m = vec![0.0];
        for w in points.windows(2) {
            let last = cumulative_m.last().copied().unwrap_or(0.0);
            cumulative_m.push(last + w[0].distance(w[1]));
        }
        Some(Self {
            points,
            cumulative_m,
            start_yaw_rad,
            goal_yaw_rad,
            dock_length_m: dock_length_m.max(0.0),
            turn_window_m: None,
            carries_part_in: false,
            corner_caps_m_s: Vec::new(),
        })
    }

    /// This route with the robot allowed to turn only between arc lengths `from_m` and
    /// `to_m` (clamped to the route).
    pub fn with_turn_window(mut self, from_m: f64, to_m: f64) -> Self {
        let length = self.length_m();
        let from_m = from_m.clamp(0.0, length);
        self.turn_window_m = Some((from_m, to_m.clamp(from_m, length)));
        self
    }

    /// This route with a part carried into the goal's slot: its last segment takes the
    /// part between the slot's dividers, so the follower goes in only once on the
    /// segment's line (`control::follower`).
    pub fn carrying_part_in(mut self) -> Self {
        self.carries_part_in = true;
        self
    }

    /// This route with the corner at point `index` taken at `speed_m_s` at most (the
    /// planner's cap where an overshoot would touch an obstacle, [`plan_route`]).
    pub fn with_corner_cap(mut self, index: usize, speed_m_s: f64) -> Self {
        self.corner_caps_m_s.retain(|&(i, _)| i != index);
        self.corner_caps_m_s.push((index, speed_m_s));
        self
    }

    /// The planner's speed cap at the corner at point `index`, m/s (infinite without one).
    pub fn corner_cap_m_s(&self, index: usize) -> f64 {
        self.corner_caps_m_s
            .iter()
            .find(|&&(i, _)| i == index)
            .map_or(f64::INFINITY, |&(_, v)| v)
    }

    /// Whether the last segment takes a carried part into a slot ([`Self::carrying_part_in`]).
    pub fn carries_part_in(&self) -> bool {
        self.carries_part_in
    }

    /// Where the robot may turn, as arc lengths (m), if the planner said.
    pub fn turn_window_m(&self) -> Option<(f64, f64)> {
        self.turn_window_m
    }

    /// The point at arc length `s_m` (clamped to the route).
    pub fn point_at(&self, s_m: f64) -> Vec2 {
        let s = s_m.clamp(0.0, self.length_m());
        let i = self.segment_at(s);
        self.points[i] + self.tangent(i) * (s - self.cumulative_m[i])
    }

    /// The unit direction of travel at arc length `s_m` (clamped to the route; at a corner,
    /// the incoming segment's).
    pub fn tangent_at_m(&self, s_m: f64) -> Vec2 {
        self.tangent(self.segment_at(s_m.clamp(0.0, self.length_m())))
    }

    /// The segment arc length `s_m` (on the route) lies on; a corner belongs to the
    /// segment before it.
    fn segment_at(&self, s_m: f64) -> usize {
        self.cumulative_m
            .windows(2)
            .position(|w| s_m <= w[1])
            .unwrap_or(self.points.len() - 2)
    }

    /// The points.
    pub fn points(&self) -> &[Vec2] {
        &self.points
    }

    /// Total length, m.
    pub fn length_m(&self) -> f64 {
        self.cumulative_m.last().copied().unwrap_or(0.0)
    }

    /// Arc length at point `index`, m.
    pub fn s_at_point_m(&self, index: usize) -> f64 {
        self.cumulative_m.get(index).copied().unwrap_or(0.0)
    }

    /// The final pose.
    pub fn goal(&self) -> Pose2 {
        let p = self.points[self.points.len() - 1];
        Pose2::new(p.x, p.y, self.goal_yaw_rad)
    }

    /// The heading at the start, rad.
    pub fn start_yaw_rad(&self) -> f64 {
        self.start_yaw_rad
    }

    /// Length of the final docking approach, m (0 = none).
    pub fn dock_length_m(&self) -> f64 {
        self.dock_length_m
    }

    /// Whether the route ends in a docking approach that closes the box switch on a part to
    /// pick: the last `dock_length_m` at the docking speed, stopping when the switch closes.
    /// A route that carries a part in ([`Self::carries_part_in`]) has no switch to close:
    /// it brakes onto the drop pose as late as the deceleration limit allows.
    pub fn docks_on_switch(&self) -> bool {
        self.dock_length_m > 0.0 && !self.carries_part_in
    }

    /// Unit direction of segment `index`.
    pub fn tangent(&self, index: usize) -> Vec2 {
        let i = index.min(self.points.len() - 2);
        let d = self.points[i + 1] - self.points[i];
        d * (1.0 / d.norm())
    }

    /// Turn angle at interior point `index` (1..len−1), rad in [0, π].
    pub fn turn_angle_rad(&self, index: usize) -> f64 {
        if index == 0 || index + 1 >= self.points.len() {
            return 0.0;
        }
        let a = self.tangent(index - 1);
        let b = self.tangent(index);
        a.cross(b).atan2(a.dot(b)).abs()
    }

    /// Project `p` onto segment `index` (clamped to the segment).
    pub fn project_on(&self, index: usize, p: Vec2) -> Projection {
        let i = index.min(self.points.len() - 2);
        let point = Segment::new(self.points[i], self.points[i + 1]).closest_point(p);
        Projection {
            segment: i,
            s_m: self.cumulative_m[i] + self.points[i].distance(point),
            point,
            tangent: self.tangent(i),
        }
    }

    /// Project `p`, searching forward from segment `hint` only (progress never goes back, so
    /// a U-shaped route is not short-circuited): the next segment is taken when it is at
    /// least as close as the current one.
    pub fn project(&self, hint: usize, p: Vec2) -> Projection {
        let mut best = self.project_on(hint, p);
        while best.segment + 2 < self.points.len() {
            let next = self.project_on(best.segment + 1, p);
            let at_end = best.s_m >= self.cumulative_m[best.segment + 1] - 1e-9;
            if at_end || next.point.distance(p) <= best.point.distance(p) {
                best = next;
            } else {
                break;
            }
        }
        best
    }
}

/// The points from the graph into `slot`: the graph path to the slot's leaf without the
/// leaf itself and without the vertices that lie closer to the slot's face than the
/// pre-dock point (the original's leaves sit nearer the plate than our pick pose), then
/// the pre-dock point `dock_length_m` behind the pick pose, then the pick pose.
fn approach(mut graph_points: Vec<Vec2>, slot: &Slot, dock_length_m: f64) -> Vec<Vec2> {
    let normal = Vec2::from_angle(slot.face_normal_rad);
    let pick = slot.pick_pose.position();
    let pre_dock = pick + normal * dock_length_m;
    let depth = |p: Vec2| (p - slot.plate_face_center).dot(normal);
    graph_points.pop();
    while graph_points.len() > 1
        && graph_points
            .last()
            .is_some_and(|&p| depth(p) < depth(pre_dock) - MERGE_TOLERANCE_M)
    {
        graph_points.pop();
    }
    graph_points.push(pre_dock);
    graph_points.push(pick);
    graph_points
}

/// How far straight out of a slot the robot goes before it moves sideways or turns, m.
/// 0.08: the carried part (0.06 m deep) and the gripper clear the 0.07 m dividers.
pub const SLOT_EXIT_M: f64 = 0.08;

/// Across-the-face offset within which a robot counts as standing in a slot's approach, m
/// (the slot's capture width, `ratf_sim::parts`).
const IN_SLOT_ACROSS_M: f64 = 0.02;

/// The slot whose approach the robot at `pose` stands in, facing it, closer to its face
/// than [`SLOT_EXIT_M`] (just docked or just released), if any.
fn slot_to_leave(field: &Field, pose: Pose2) -> Option<&Slot> {
    field.slots().find(|slot| {
        let normal = Vec2::from_angle(slot.face_normal_rad);
        let offset = pose.position() - slot.pick_pose.position();
        let out = offset.dot(normal);
        offset.cross(normal).abs() < IN_SLOT_ACROSS_M
            && (-IN_SLOT_ACROSS_M..SLOT_EXIT_M - IN_SLOT_ACROSS_M).contains(&out)
            && wrap_angle(pose.yaw_rad - slot.pick_pose.yaw_rad).abs() < IN_SLOT_MAX_YAW_RAD
    })
}

/// Where a robot standing in a slot's approach at `pose` ([`slot_to_leave`]) first drives
/// to: straight out along the slot's face normal to [`SLOT_EXIT_M`] from its pick pose,
/// keeping the robot's own offset across the slot. The part it picked left its slot where
/// it stood, up to 20 mm off the slot's centre in a 130 mm slot, so the part and the face
/// leave the dividers only along their own line: an exit that steered onto the slot's
/// centre line moved them across by the robot's docking offset while they were still
/// between the dividers, and grazed one (harsh world, tuning seeds 61–76, every round:
/// 20 → 3 collisions of a part carried out of an incoming slot with its dividers).
fn slot_exit(field: &Field, pose: Pose2) -> Option<Vec2> {
    slot_to_leave(field, pose).map(|docked| {
        let normal = Vec2::from_angle(docked.face_normal_rad);
        let out = (pose.position() - docked.pick_pose.position()).dot(normal);
        pose.position() + normal * (SLOT_EXIT_M - out)
    })
}

/// The route through `points` from `start`'s heading to `slot`'s pick heading, with the
/// configured docking length (`None` where the points make no route, [`Route::new`]).
fn leg_route(
    points: Vec<Vec2>,
    start: Pose2,
    slot: &Slot,
    config: &NavigationConfig,
) -> Option<Route> {
    Route::new(
        points,
        start.yaw_rad,
        slot.pick_pose.yaw_rad,
        config.dock_length_m,
    )
}

/// Heading error within which a robot in a slot's approach counts as facing it, rad (10°).
const IN_SLOT_MAX_YAW_RAD: f64 = 0.175;

/// Drop consecutive points closer than [`MERGE_TOLERANCE_M`] (keeping the last one).
fn dedup(points: Vec<Vec2>) -> Vec<Vec2> {
    let mut out: Vec<Vec2> = Vec::with_capacity(points.len());
    for p in points {
        if out
            .last()
            .is_some_and(|q| q.distance(p) < MERGE_TOLERANCE_M)
        {
            out.pop();
        }
        out.push(p);
    }
    out
}

/// The turn ends this far before the free stretch does, m: the heading lags its plan by
/// about the loop's lag (0.12 s) at up to 0.4 m/s.
const TURN_END_INSET_M: f64 = 0.05;

/// Step of the search for a stretch where the robot can turn, m.
const TURN_SEARCH_STEP_M: f64 = 0.01;

/// Where on `route` the robot turns: the longest stretch between `rotate_after_m` from the
/// start and `align_before_m` from the end along which it can turn on the spot (its swept
/// disc is free). If there is none, the most open point of that range (the robot then
/// turns there nearly in place, the follower slowing down until the heading is right).
///
/// Widening the stretch beyond the free disc, wherever the square body (and its part) at
/// every heading the follower may hold there keeps a margin off every obstacle, was
/// measured at `a210463` (realistic world, calibrated): with the shortcut margin (20 mm) no
/// route of the competition's widens; with 5 mm rounds 2 and 3 were 0.3 and 0.4 s faster
/// over seeds 61–80 and round 1 no faster (its turns are in the wheels' budget, which a
/// longer window eases little: at the body's diagonal the translation takes 1.41 of it),
/// but over seeds 11–60 the robot, still turning in the row above machine A, ran 17 mm
/// below the row and touched machine A (round 3, seed 24): not kept.
pub fn turn_window(route: &Route, space: &FreeSpace, config: &NavigationConfig) -> (f64, f64) {
    let length = route.length_m();
    let (lo, hi) = if length > config.rotate_after_m + config.align_before_m {
        (config.rotate_after_m, length - config.align_before_m)
    } else {
        (length / 3.0, 2.0 * length / 3.0)
    };
    let steps = ((hi - lo) / TURN_SEARCH_STEP_M).ceil().max(1.0) as usize;
    let samples: Vec<f64> = (0..=steps)
        .map(|k| lo + (hi - lo) * k as f64 / steps as f64)
        .collect();
    let mut best: Option<(f64, f64)> = None;
    let mut run_start: Option<f64> = None;
    for (k, &s) in samples.iter().enumerate() {
        let free = space.can_turn_at(route.point_at(s));
        if free && run_start.is_none() {
            run_start = Some(s);
        }
        let run_ends = !free || k + 1 == samples.len();
        if let (true, Some(from)) = (run_ends, run_start) {
            let to = if free { s } else { samples[k - 1] };
            if best.is_none_or(|(a, b)| to - from > b - a) {
                best = Some((from, to));
            }
            run_start = None;
        }
    }
    // End the turn a little inside the free stretch: the heading lags its plan.
    let best = best.map(|(a, b)| (a, (b - TURN_END_INSET_M).max(a + (b - a) / 2.0)));
    best.unwrap_or_else(|| {
        let open = samples
            .iter()
            .copied()
            .max_by(|a, b| {
                space
                    .clearance_m(route.point_at(*a))
                    .total_cmp(&space.clearance_m(route.point_at(*b)))
            })
            .unwrap_or(lo);
        (open, open)
    })
}

/// Our route from `start` to `slot`'s pick pose: the current position, straight out of the
/// slot the robot stands in if any ([`SLOT_EXIT_M`]), the nearest
/// non-task vertex reachable in a straight line, Dijkstra to the slot, the straight docking
/// approach, collinear points merged; with `config.shortcuts`, shortcuts (free at the start
/// and goal headings) everywhere except on the docking segment; the stretch where the
/// robot turns ([`turn_window`]); and a speed cap on every corner past which an overshoot
/// of [`CORNER_OVERSHOOT_S`] would leave less than [`OVERSHOOT_ALLOWANCE_M`] to an obstacle.
pub fn plan_route(
    field: &Field,
    map: &RoadMap,
    space: &FreeSpace,
    start: Pose2,
    slot: &Slot,
    config: &NavigationConfig,
) -> Result<Route, PlanError> {
    let mut points = vec![start.position()];
    // Standing in a slot, first straight out of it (never sideways between its dividers).
    if let Some(exit) = slot_exit(field, start) {
        points.push(exit);
    }
    let leave_from = points.last().copied().unwrap_or(start.position());
    let first = map.start_vertex(field, leave_from, 0.0)?;
    let path = map.shortest_path(first, slot.waypoint)?;
    points.extend(map.positions(&path));
    let points = approach(points, slot, config.dock_length_m);
    let mut points = merge_collinear(&dedup(points), MERGE_TOLERANCE_M);
    if config.shortcuts && points.len() > 2 {
        let pick = points.pop().unwrap_or(start.position());
        let mut cut = space.shortcut(&points, &[start.yaw_rad, slot.pick_pose.yaw_rad]);
        cut.push(pick);
        points = merge_collinear(&cut, MERGE_TOLERANCE_M);
    }
    let windowed = |points: Vec<Vec2>| {
        let route = leg_route(points, start, slot, config)?;
        let (from_m, to_m) = turn_window(&route, space, config);
        Some(route.with_turn_window(from_m, to_m))
    };
    let mut route = windowed(points).ok_or(PlanError::NoStartVertex(start.x, start.y))?;
    // Squaring one segment may move the turn window; a few rounds settle it.
    for _ in 0..MAX_SQUARING_ROUNDS {
        let Some(points) = square_off_blocked_segment(&route, space) else {
            break;
        };
        match windowed(points) {
            Some(squared) => route = squared,
            None => break,
        }
    }
    Ok(cap_tight_corners(route, space, config))
}

/// How long the follower's velocity keeps its old direction past a corner beyond what the
/// lag compensation foresees, s. 0.05: in the realistic world the robot coming down the
/// middle at 0.28 m/s overshoots the corner into the outgoing row by 14–15 mm (truth, tuning
/// seeds 61 and 70; the estimate's own latency is about 40 ms of it).
pub const CORNER_OVERSHOOT_S: f64 = 0.05;

/// Room an overshoot must leave for what the plan does not see, m. 0.005: about the
/// calibrated estimate's error at rest (3.5 mm RMSE in the realistic world) and a carried
/// part turned a degree on the magnet (its far corners 1–2 mm out). Chosen on the realistic
/// world's seeds 61–160 (calibrated, 300 rounds): without caps 36.0 / 38.2 / 48.8 s per
/// round and 4 collisions (each the carried part at the first outgoing divider's tip after
/// the corner into the row); 0.005: 36.7 / 38.9 / 49.5 s and none; 0.008: 38.7 / 40.3 /
/// 50.8 s and none.
pub const OVERSHOOT_ALLOWANCE_M: f64 = 0.005;

/// Lowest corner cap, m/s (the follower still creeps round).
const MIN_CORNER_CAP_M_S: f64 = 0.05;

/// How much of the follower's turning early a corner's inside must leave room for, as a
/// fraction of the speed times `navigation.lag_compensation_s` times the sine of half the
/// turn: the follower places itself that far ahead, so it turns onto the next segment
/// early and cuts the corner. 1 at first: traced in round 2 of the realistic world's
/// seeds 61 and 101 (calibrated, free-space routes), a 45° corner into the outgoing row
/// under machine B taken at 0.43–0.44 m/s left the robot 15–19 mm inside the row's line
/// (this model: 20 mm) still 3–5 cm after the corner, where the body touched the machine's
/// divider. 1.2, the least of 1.2 / 1.3 / 1.5 / 2.0 to clear the three contacts the seeds
/// 11–60 and 161–210 then showed, each a body's corner meeting a divider's corner after a
/// cut corner (round 1 of seed 60 rising to the outgoing row past its first divider;
/// round 2 of seed 40 leaving outgoing slot 3, where two corners 39 mm apart were cut as
/// one; round 2 of seed 189 coming down into the row under machine B): on the tuning
/// seeds 61–160 it costs 0.25 / 0.31 / 0.41 s a round, 0 collisions either way.
pub const CORNER_CUT_SHARE: f64 = 1.2;

/// How far along the next segment the cut is checked, in distances the cross-track
/// correction takes to shrink it by e (speed over `navigation.cross_track_gain_per_s`):
/// after 3 it is a twentieth of itself.
const CUT_DECAY_LENGTHS: f64 = 3.0;

/// The largest `x` in `[0, needed]` at which `free(x)` holds, for a `free` that holds up to
/// some point (bisection; 0 if it does not hold at 0), or `None` if it holds at `needed`:
/// the room short of a shift, or the fastest speed whose error stays free.
fn room_short_of(needed: f64, free: impl Fn(f64) -> bool) -> Option<f64> {
    if free(needed) {
        return None;
    }
    let (mut lo, mut hi) = (0.0, needed);
    if !free(0.0) {
        hi = 0.0;
    }
    for _ in 0..20 {
        let mid = (lo + hi) / 2.0;
        if free(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(lo)
}

/// Caps the speed of every corner (docking approach excluded) past which the robot would
/// touch an obstacle if it overshot across the next segment or cut the corner, standing
/// along the next segment as it will (holding a heading, or anyhow inside the turn window:
/// its swept disc):
/// - the overshoot is the speed times [`CORNER_OVERSHOOT_S`] along the incoming
///   direction's component across the outgoing segment; the room is how far the next
///   segment's poses can move that way and stay free (no margin);
/// - the cut is the speed times `lag_compensation_s` times the sine of half the turn
///   ([`CORNER_CUT_SHARE`]), the other way across the outgoing segment: the follower turns
///   early and comes onto the next segment from the inside, the error decaying as the
///   cross-track correction takes it back (`cross_track_gain_per_s`); the cap is the
///   fastest speed at which the next segment's poses, each moved across by its cut, stay
///   free ([`CUT_DECAY_LENGTHS`]);
///
/// each with [`OVERSHOOT_ALLOWANCE_M`] to spare.
fn cap_tight_corners(mut route: Route, space: &FreeSpace, config: &NavigationConfig) -> Route {
    let n = route.points().len();
    for i in 1..n.saturating_sub(2) {
        let (incoming, outgoing) = (route.tangent(i - 1), route.tangent(i));
        let across = incoming - outgoing * incoming.dot(outgoing);
        let sine = across.norm();
        if sine < 1e-6 {
            continue;
        }
        let turn_rad = route.turn_angle_rad(i);
        let corner_m_s = crate::control::profile::corner_speed_m_s(
            turn_rad,
            config.max_accel_m_s2.min(config.max_decel_m_s2),
            config.corner_blend_m,
        )
        .min(config.max_speed_m_s);
        let mut cap = corner_m_s;
        let stretches = stance_stretches(&route, i);
        let free_shifted = |shift_m: f64| {
            let by = across * (shift_m / sine);
            stretches.iter().all(|&(a, b, yaw)| {
                let room = space.segment_clearance_m(a + by, b + by, yaw, 1.0);
                FreeSpace::segment_guaranteed_m(room) > 0.0
            })
        };
        let overshoot_m = corner_m_s * sine * CORNER_OVERSHOOT_S + OVERSHOOT_ALLOWANCE_M;
        if !stretches.is_empty()
            && let Some(room) = room_short_of(overshoot_m, free_shifted)
        {
            cap = cap.min((room - OVERSHOOT_ALLOWANCE_M) / (sine * CORNER_OVERSHOOT_S));
        }
        // The cut at speed v: inwards across the next segment by v · lag · sin(φ/2) at the
        // corner, decaying as the cross-track correction takes it back.
        let cut_per_m_s = CORNER_CUT_SHARE * config.lag_compensation_s * (turn_rad / 2.0).sin();
        let gain = config.cross_track_gain_per_s;
        let cut_free = |v: f64| {
            let reach_m = CUT_DECAY_LENGTHS * v / gain;
            stretches.iter().all(|&(a, b, yaw)| {
                let from_corner = |p: Vec2| p.distance(route.points()[i]);
                let steps = (a.distance(b) / SAMPLE_STEP_M).ceil().max(1.0) as usize;
                (0..=steps)
                    .map(|k| a + (b - a) * (k as f64 / steps as f64))
                    .take_while(|&p| from_corner(p) <= reach_m)
                    .all(|p| {
                        let decay = (-from_corner(p) * gain / v.max(1e-6)).exp();
                        let shift = OVERSHOOT_ALLOWANCE_M + v * cut_per_m_s * decay;
                        let q = p - across * (shift / sine);
                        let room = match yaw {
                            Some(yaw) => space.pose_clearance_m(Pose2::new(q.x, q.y, yaw), 1.0),
                            None => space.turn_clearance_m(q, 1.0),
                        };
                        room > SAMPLE_STEP_M / 2.0
                    })
            })
        };
        // The fastest speed whose cut stays free.
        if !stretches.is_empty()
            && cut_per_m_s > 0.0
            && let Some(speed) = room_short_of(cap, cut_free)
        {
            cap = speed;
        }
        if cap < corner_m_s {
            route = route.with_corner_cap(i, cap.clamp(MIN_CORNER_CAP_M_S, corner_m_s));
        }
    }
    route
}

/// How far short of a slot's pick pose our robot lets a carried part go, m. 0.005: at the
/// pick pose the robot's front face stands 5 mm from the slot's divider tips, while the
/// calibrated localiser is a few millimetres off at rest (3.5 mm RMSE in the realistic
/// world, README: localisation), so a drop aimed at the pose itself touched a machine's
/// dividers whenever the estimate was short; a part let go up to
/// [`crate::mission::LET_GO_SHORT_OF_DROP_M`] short of the pose still lands in its slot.
pub const DROP_SHORT_M: f64 = 0.005;

/// Our route for one leg to `slot` on our road map: to pick its part (`carrying` false:
/// the docking approach that ends on the switch), or carrying a part into it
/// ([`Route::carrying_part_in`]), ending [`DROP_SHORT_M`] short of the pick pose.
/// [`LegPlanner`] plans through free space first and falls back on this.
pub fn plan_leg(
    field: &Field,
    map: &RoadMap,
    space: &FreeSpace,
    start: Pose2,
    slot: &Slot,
    config: &NavigationConfig,
    carrying: bool,
) -> Result<Route, PlanError> {
    if !carrying {
        return plan_route(field, map, space, start, slot, config);
    }
    plan_route(field, map, space, start, &drop_slot(slot), config).map(Route::carrying_part_in)
}

/// How thick the mark a stalled carry leaves is, along its way, m. 0.02: thick enough for
/// the free-space grids to see; thin enough to leave the next slot free, whose drop brings
/// the body's side to 0.03 m of a mark at the carried part's side in the slot beside it
/// (slots 0.15 m apart, the part 0.09 m wide, the body 0.30 m).
pub const STALL_MARK_M: f64 = 0.02;

/// Where something the routes do not know stands, as a carry that stalled against it at
/// `pose` (moving along `travel`, robot frame) tells it: a strip [`STALL_MARK_M`] thick
/// along the carried part's leading side (the part reaches past the body's front into the
/// slots' mouths, where the routes pass closest to parts they do not know: a part left
/// proud of its slot, traced at round 1 seed 74 of the wheel-slip faults). `None` when
/// the part trails (a reverse), or without a direction.
pub fn stall_mark(footprint: &Footprint, pose: Pose2, travel: Vec2) -> Option<Rect> {
    if travel.norm() < 1e-9 || travel.x < 0.0 && travel.x.abs() >= travel.y.abs() {
        return None;
    }
    let (near, far) = (footprint.magnet_m, footprint.magnet_m + PART_DEPTH_M);
    let half = PART_WIDTH_M / 2.0;
    let (x0, x1, y0, y1) = if travel.x.abs() >= travel.y.abs() {
        (far, far + STALL_MARK_M, -half, half)
    } else if travel.y > 0.0 {
        (near, far, half, half + STALL_MARK_M)
    } else {
        (near, far, -half - STALL_MARK_M, -half)
    };
    let corners = [(x0, y0), (x0, y1), (x1, y0), (x1, y1)]
        .map(|(x, y)| pose.transform_point(Vec2::new(x, y)));
    let (xs, ys) = (corners.map(|c| c.x), corners.map(|c| c.y));
    let min = |v: [f64; 4]| v.into_iter().fold(f64::INFINITY, f64::min);
    let max = |v: [f64; 4]| v.into_iter().fold(f64::NEG_INFINITY, f64::max);
    Some(Rect::from_spans(min(xs), max(xs), min(ys), max(ys)))
}

/// How our robot plans its legs: through free space ([`crate::planning::free_routes`],
/// with `navigation.free_routes`) wherever that finds a route, else on our road map
/// ([`plan_route`]: the waypoint graph with shortcuts). The navigator and the task
/// planner's route times both plan here, so the planner's times are those of the routes
/// the robot drives.
#[derive(Clone, Debug)]
pub struct LegPlanner {
    field: Field,
    map: RoadMap,
    config: NavigationConfig,
    /// The free space of the robot empty and carrying a part, with their free-space
    /// planners (`None` without `navigation.free_routes`).
    empty: (FreeSpace, Option<FreeRoutes>),
    carrying: (FreeSpace, Option<FreeRoutes>),
}

impl LegPlanner {
    /// The planner for our robot of `config` on its field ([`crate::config::RobotConfig::field`]).
    pub fn new(config: &Config) -> Self {
        Self::with_obstacles(config, &[])
    }

    /// [`Self::new`] with `obstacles` on the floor besides the field's walls, dividers and
    /// poles (marks of stalled carries, [`stall_mark`]). Builds the free-space grids again:
    /// a tenth of a second and more.
    pub fn with_obstacles(config: &Config, obstacles: &[Rect]) -> Self {
        let field = config.robot.field();
        let map = RoadMap::new(our_graph(&field, &Footprint::of_robot(&config.robot, true)));
        let spaces = |carrying: bool| {
            let space = FreeSpace::new(
                &field,
                obstacles,
                Footprint::of_robot(&config.robot, carrying),
                config.navigation.shortcut_margin_m,
            );
            let free = config
                .navigation
                .free_routes
                .then(|| FreeRoutes::new(&field, space.clone()));
            (space, free)
        };
        Self {
            empty: spaces(false),
            carrying: spaces(true),
            field,
            map,
            config: config.navigation.clone(),
        }
    }

    /// The field it plans on.
    pub fn field(&self) -> &Field {
        &self.field
    }

    /// Our route from `start` to `slot`: to pick its part, or `carrying` one into it
    /// ([`plan_leg`]'s ends: the docking approach, or [`DROP_SHORT_M`] short of the pick
    /// pose).
    pub fn plan(&self, start: Pose2, slot: &Slot, carrying: bool) -> Result<Route, PlanError> {
        self.plan_many(start, &[*slot], carrying).remove(0)
    }

    /// Our routes from `start` to each of `slots`, all to pick or all `carrying` a part in
    /// (one free-space search for all).
    pub fn plan_many(
        &self,
        start: Pose2,
        slots: &[Slot],
        carrying: bool,
    ) -> Vec<Result<Route, PlanError>> {
        let (space, free) = if carrying {
            &self.carrying
        } else {
            &self.empty
        };
        let goals: Vec<Slot> = slots
            .iter()
            .map(|slot| if carrying { drop_slot(slot) } else { *slot })
            .collect();
        let mut free_routes = match free {
            Some(free) => free_routes(free, &self.field, start, &goals, &self.config),
            None => vec![None; goals.len()],
        };
        goals
            .iter()
            .zip(free_routes.iter_mut())
            .map(|(goal, free)| {
                let route = match free.take() {
                    Some(route) => Ok(cap_tight_corners(route, space, &self.config)),
                    None => plan_route(&self.field, &self.map, space, start, goal, &self.config),
                };
                if carrying {
                    route.map(Route::carrying_part_in)
                } else {
                    route
                }
            })
            .collect()
    }
}

/// Where our robot lets a part go at a slot whose pick pose is `pick`: [`DROP_SHORT_M`]
/// out of the slot along the pick pose's heading.
pub fn drop_pose(pick: Pose2) -> Pose2 {
    pick.compose(Pose2::new(-DROP_SHORT_M, 0.0, 0.0))
}

/// `slot` as a drop aims at it: its pick pose moved to [`drop_pose`].
fn drop_slot(slot: &Slot) -> Slot {
    let mut short = *slot;
    short.pick_pose = drop_pose(slot.pick_pose);
    short
}

/// Free-space routes from `start` to the pick pose of each of `slots`
/// ([`crate::planning::free_routes`]): straight out of the slot the robot stands in, if
/// any ([`SLOT_EXIT_M`]), through free space to [`SLOT_EXIT_M`] in front of the goal's
/// pick pose, arriving with its heading, and straight in, the last `dock_length_m` the
/// docking approach. The robot turns where the free path says, its end
/// [`TURN_END_INSET_M`] earlier (the heading lags its plan), the turn widened only
/// `rotate_after_m` from the start and `align_before_m` from the end. `None` for a slot no
/// free path reaches.
fn free_routes(
    free: &FreeRoutes,
    field: &Field,
    start: Pose2,
    slots: &[Slot],
    config: &NavigationConfig,
) -> Vec<Option<Route>> {
    let departure = Departure {
        pose: start,
        lead_out: slot_exit(field, start),
    };
    let arrivals: Vec<Pose2> = slots.iter().map(|slot| slot.pick_pose).collect();
    let keep_off_m = (config.rotate_after_m, config.align_before_m);
    free.paths(departure, &arrivals, SLOT_EXIT_M, keep_off_m)
        .into_iter()
        .zip(slots)
        .map(|(path, slot)| {
            let FreePath { points, turn_m } = path?;
            let points = merge_collinear(&dedup(points), MERGE_TOLERANCE_M);
            let route = leg_route(points, start, slot, config)?;
            // Without a turn the robot holds its heading all the way.
            let (a, b) = turn_m.unwrap_or((route.length_m(), route.length_m()));
            Some(route.with_turn_window(a, (b - TURN_END_INSET_M).max(a + (b - a) / 2.0)))
        })
        .collect()
}

/// Rounds of [`square_off_blocked_segment`] per route (each fixes one segment).
const MAX_SQUARING_ROUNDS: usize = 3;

/// How the robot stands along segment `index` of `route`, stretch by stretch: holding the
/// start heading before the turn window (`Some(yaw)`), free to turn inside it (`None`),
/// holding the goal heading after it.
fn stance_stretches(route: &Route, index: usize) -> Vec<(Vec2, Vec2, Option<f64>)> {
    let (s0, s1) = (route.s_at_point_m(index), route.s_at_point_m(index + 1));
    let (from_m, to_m) = route.turn_window_m().unwrap_or((0.0, route.length_m()));
    let mut stretches = Vec::new();
    let mut add = |a: f64, b: f64, yaw: Option<f64>| {
        if b > a {
            stretches.push((route.point_at(a), route.point_at(b), yaw));
        }
    };
    add(s0, s1.min(from_m), Some(route.start_yaw_rad()));
    add(s0.max(from_m), s1.min(to_m), None);
    add(s0.max(to_m), s1, Some(route.goal().yaw_rad));
    stretches
}

/// The headings the robot holds on the part of segment `index` of `route` outside its turn
/// window, with the stretch each applies to: the start heading before the window, the goal
/// heading after it.
fn held_stretches(route: &Route, index: usize) -> Vec<(Vec2, Vec2, f64)> {
    stance_stretches(route, index)
        .into_iter()
        .filter_map(|(a, b, yaw)| yaw.map(|yaw| (a, b, yaw)))
        .collect()
}

/// A graph edge may be diagonal while the robot holds a heading square to the field; its
/// square body is then wider across the edge than the corridor the edge was drawn for
/// (a 30 cm square moving at 45° sweeps 42 cm). Finds the first segment (docking
/// approach excluded) whose held-heading stretch touches an obstacle (with no margin: the
/// graph's rows themselves pass dividers closer than the margin) and replaces it by
/// the two axis-parallel legs through one of its corners, if both legs are free at the
/// start and goal headings (with the space's margin if possible, else with none). `None` when every segment is free or no corner helps.
fn square_off_blocked_segment(route: &Route, space: &FreeSpace) -> Option<Vec<Vec2>> {
    let points = route.points();
    let last = points.len().saturating_sub(2);
    let yaws = [route.start_yaw_rad(), route.goal().yaw_rad];
    (0..last).find_map(|i| {
        let blocked = held_stretches(route, i)
            .iter()
            .any(|&(a, b, yaw)| !space.segment_is_free_with_margin(a, b, &[yaw], 0.0));
        if !blocked {
            return None;
        }
        let (a, b) = (points[i], points[i + 1]);
        let corners = [Vec2::new(b.x, a.y), Vec2::new(a.x, b.y)]
            .into_iter()
            .filter(|&c| c.distance(a) > MERGE_TOLERANCE_M && c.distance(b) > MERGE_TOLERANCE_M);
        let free = |c: Vec2, margin_m: f64| {
            space.segment_is_free_with_margin(a, c, &yaws, margin_m)
                && space.segment_is_free_with_margin(c, b, &yaws, margin_m)
        };
        // Prefer the configured margin; without it the legs still keep the body off every
        // obstacle, where the diagonal did not.
        corners
            .clone()
            .find(|&c| free(c, space.margin_m()))
            .or_else(|| corners.clone().find(|&c| free(c, 0.0)))
            .map(|corner| {
                let mut squared = points.to_vec();
                squared.insert(i + 1, corner);
                squared
            })
    })
}

/// Length of the original's straight final leg into a slot, m. 0.10: about its leaf edges
/// into the warehouses (0.105 m to 50–53, 0.14 m to 62–65; original-system.md §6.1), fixed
/// so the original's routes do not depend on our `navigation.dock_length_m`.
pub const ORIGINAL_APPROACH_M: f64 = 0.10;

/// The original's route (original-system.md §6.2) to the same goal: start at the nearest
/// vertex of all (task leaves included), Dijkstra, the same approach into the slot as ours
/// (the original's leaves are not our pick poses), consecutive segments merged only when
/// their unit directions are exactly equal. Its goal heading is that of the last segment.
pub fn plan_original_route(
    map: &RoadMap,
    start: Pose2,
    slot: &Slot,
    dock_length_m: f64,
) -> Result<Route, PlanError> {
    let first = map
        .graph()
        .nearest(start.position())
        .ok_or(PlanError::NoStartVertex(start.x, start.y))?;
    let path = map.shortest_path(first, slot.waypoint)?;
    let points = dedup(approach(map.positions(&path), slot, dock_length_m));
    let mut trimmed: Vec<Vec2> = Vec::with_capacity(points.len());
    for p in points {
        if trimmed.len() >= 2 {
            let a = trimmed[trimmed.len() - 2];
            let b = trimmed[trimmed.len() - 1];
            let u = (b - a) * (1.0 / (b - a).norm());
            let v = (p - b) * (1.0 / (p - b).norm());
            if u == v {
                trimmed.pop();
            }
        }
        trimmed.push(p);
    }
    if trimmed.len() < 2 {
        trimmed.insert(0, start.position());
    }
    let n = trimmed.len();
    let goal_yaw = (trimmed[n - 1] - trimmed[n - 2]).angle();
    Route::new(trimmed, start.yaw_rad, goal_yaw, 0.0)
        .ok_or(PlanError::NoStartVertex(start.x, start.y))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::SlotKind;
    use crate::field::WaypointGraph;
    use crate::field::geometry::Rect;
    use crate::field::waypoints::WaypointId;
    use crate::planning::shortcuts::Footprint;

    /// The free space of a 30 × 30 cm body, `carrying` a part or not, with the default
    /// shortcut margin.
    fn square_body_space(field: &Field, carrying: bool) -> FreeSpace {
        let footprint = Footprint::centred(0.30, 0.30, carrying);
        FreeSpace::new(
            field,
            &[],
            footprint,
            NavigationConfig::default().shortcut_margin_m,
        )
    }

    #[test]
    fn routes_end_square_at_every_pick_pose_from_the_start() {
        let field = Field::competition();
        let map = RoadMap::new(WaypointGraph::original());
        let config = NavigationConfig::default();
        let start = field.start_pose();
        let footprint = Footprint::centred(0.30, 0.30, false);
        let space = FreeSpace::new(&field, &[], footprint, config.shortcut_margin_m);
        for slot in field.slots() {
            let route = plan_route(&field, &map, &space, start, slot, &config).unwrap();
            let (from, to) = route.turn_window_m().unwrap();
            assert!(from <= to && to <= route.length_m());
            let n = route.points().len();
            assert_eq!(route.points()[n - 1], slot.pick_pose.position());
            // The last segment is the docking approach: dock_length_m long, along the face
            // normal.
            let last = route.points()[n - 1] - route.points()[n - 2];
            assert!(
                last.norm() >= config.dock_length_m - 1e-9,
                "{}",
                slot.waypoint
            );
            assert!(
                wrap_angle(last.angle() - slot.pick_pose.yaw_rad).abs() < 1e-9,
                "slot {} approached at {}",
                slot.waypoint,
                last.angle()
            );
            let original = plan_original_route(&map, start, slot, config.dock_length_m).unwrap();
            assert!(
                wrap_angle(original.goal().yaw_rad - slot.pick_pose.yaw_rad).abs() < 1e-9,
                "original into {}",
                slot.waypoint
            );
        }
    }

    #[test]
    fn a_leg_carrying_a_part_in_ends_short_of_the_pick_pose_square_to_the_face() {
        let field = Field::competition();
        let map = RoadMap::new(WaypointGraph::original());
        let config = NavigationConfig::default();
        let space = square_body_space(&field, true);
        let start = field.start_pose();
        for slot in field.slots() {
            let leg =
                |carrying| plan_leg(&field, &map, &space, start, slot, &config, carrying).unwrap();
            let (to_pick, carrying_in) = (leg(false), leg(true));
            assert!(!to_pick.carries_part_in() && carrying_in.carries_part_in());
            assert_eq!(to_pick.goal(), slot.pick_pose);
            let goal = carrying_in.goal();
            // Out along the face normal by DROP_SHORT_M, facing the face.
            let out = goal.position() - slot.pick_pose.position();
            let normal = Vec2::from_angle(slot.face_normal_rad);
            assert!(
                (out.dot(normal) - DROP_SHORT_M).abs() < 1e-12,
                "{}",
                slot.waypoint
            );
            assert!(out.cross(normal).abs() < 1e-12, "{}", slot.waypoint);
            assert!(wrap_angle(goal.yaw_rad - slot.pick_pose.yaw_rad).abs() < 1e-12);
        }
    }

    #[test]
    fn the_corner_into_the_outgoing_row_is_capped_where_an_overshoot_would_reach_a_divider() {
        let field = Field::competition();
        let config = NavigationConfig::default();
        let map = RoadMap::new(crate::planning::our_map::our_graph(
            &field,
            &Footprint::centred(0.30, 0.30, true),
        ));
        let space = square_body_space(&field, true);
        let (from, to) = (
            field.incoming_slot(1).unwrap(),
            field.outgoing_slot(1).unwrap(),
        );
        let carry = plan_leg(&field, &map, &space, from.pick_pose, to, &config, true).unwrap();
        let corner = |route: &Route, at: Vec2| {
            (1..route.points().len() - 1)
                .find(|&i| route.points()[i].distance(at) < 0.01)
                .map(|i| route.corner_cap_m_s(i))
                .expect("a corner there")
        };
        let free_speed = crate::control::profile::corner_speed_m_s(
            std::f64::consts::FRAC_PI_2,
            config.max_accel_m_s2,
            config.corner_blend_m,
        );
        // Down the middle into the outgoing row, the part facing the dividers' tips 17.5 mm
        // away: capped so that the overshoot leaves OVERSHOOT_ALLOWANCE_M.
        let into_row = corner(&carry, Vec2::new(0.0, -0.255));
        assert!(into_row < free_speed, "{into_row}");
        let overshoot = into_row * CORNER_OVERSHOOT_S + OVERSHOOT_ALLOWANCE_M;
        assert!((0.010..0.0175).contains(&overshoot), "{overshoot}");
        // Turning from the row into the middle, where there is room: no cap.
        assert_eq!(corner(&carry, Vec2::new(0.0, 0.255)), f64::INFINITY);
    }

    /// Every leg the rules make the robot drive between two slots of `field`: (carrying,
    /// from, to). Carrying, it comes from a pick slot and goes to a drop slot; empty, the
    /// other way round; out of a machine it carries from A (at −x) to B's input (at +x) or
    /// the outgoing warehouse, from B only to the outgoing.
    fn legs_the_rules_allow(field: &Field) -> Vec<(bool, Slot, Slot)> {
        let is_drop = |s: &Slot| matches!(s.kind, SlotKind::Outgoing | SlotKind::MachineInput);
        let mut legs = Vec::new();
        for carrying in [false, true] {
            for from in field.slots().filter(|s| is_drop(s) != carrying) {
                let allowed = |to: &&Slot| {
                    let out_of_machine = carrying && from.kind == SlotKind::MachineOutput;
                    is_drop(to) == carrying
                        && (!out_of_machine
                            || to.kind == SlotKind::Outgoing
                            || (from.box_center.x < 0.0 && to.box_center.x > 0.0))
                };
                for to in field.slots().filter(allowed) {
                    legs.push((carrying, *from, *to));
                }
            }
        }
        legs
    }

    #[test]
    fn a_corner_whose_inside_lacks_room_for_the_cut_is_capped() {
        // A 90° left turn at (0.5, 0) onto x = 0.5, holding heading 0; the follower turns
        // early and comes onto the next segment from its left.
        let route = || {
            Route::new(
                vec![
                    Vec2::new(0.0, 0.0),
                    Vec2::new(0.5, 0.0),
                    Vec2::new(0.5, 0.5),
                    Vec2::new(0.5, 0.6),
                ],
                0.0,
                0.0,
                0.0,
            )
            .unwrap()
            // Holding its heading all the way.
            .with_turn_window(0.6, 0.6)
        };
        let config = NavigationConfig::default();
        let footprint = Footprint::centred(0.30, 0.30, false);
        let open = FreeSpace::with_walls(Vec::new(), footprint, config.shortcut_margin_m);
        let uncapped = cap_tight_corners(route(), &open, &config);
        assert_eq!(uncapped.corner_cap_m_s(1), f64::INFINITY);
        // A wall 15 mm left of the body along the next segment from 1 cm past the corner.
        // The cut at speed v is 5 mm + 1.2 × v × 0.12 s × sin 45° there
        // (`CORNER_CUT_SHARE`), decaying over v / 5 per second: the 12.5 mm the segment
        // check leaves (half a sample step less) hold up to about 0.11 m/s, under the
        // corner's own 0.27 m/s.
        let wall = Rect::from_spans(0.2, 0.335, 0.16, 0.45);
        let near = FreeSpace::with_walls(vec![wall], footprint, config.shortcut_margin_m);
        let cap = cap_tight_corners(route(), &near, &config).corner_cap_m_s(1);
        assert!((0.105..0.125).contains(&cap), "{cap}");
        // Beyond the cut's reach, no cap: the same wall from 0.3 m past the corner.
        let far = Rect::from_spans(0.2, 0.335, 0.3, 0.45);
        let far = FreeSpace::with_walls(vec![far], footprint, config.shortcut_margin_m);
        assert_eq!(
            cap_tight_corners(route(), &far, &config).corner_cap_m_s(1),
            f64::INFINITY
        );
    }

    #[test]
    fn the_held_headings_keep_the_body_off_every_obstacle_between_any_two_slots() {
        // Regression: from machine B's input row to its output 55 the graph's diagonal edge
        // 4 → 30, driven at the goal heading 180°, grazed a divider of machine B.
        let field = Field::competition();
        let map = RoadMap::new(field.waypoints().clone());
        let config = NavigationConfig::default();
        let mut checked = 0;
        for (carrying, from, to) in legs_the_rules_allow(&field) {
            let footprint = Footprint::centred(0.30, 0.30, carrying);
            let space = FreeSpace::new(&field, &[], footprint, config.shortcut_margin_m);
            // Where the robot stands after backing out of `from`.
            let normal = Vec2::from_angle(from.face_normal_rad);
            let p = from.pick_pose.position() + normal * 0.08;
            let start = Pose2::new(p.x, p.y, from.pick_pose.yaw_rad);
            let route = plan_route(&field, &map, &space, start, &to, &config).unwrap();
            for i in 0..route.points().len() - 2 {
                for (a, b, yaw) in held_stretches(&route, i) {
                    assert!(
                        space.segment_is_free_with_margin(a, b, &[yaw], 0.0),
                        "{} → {} (carrying: {carrying}): segment {i} {a:?} → {b:?} at {yaw}",
                        from.waypoint,
                        to.waypoint
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 400, "{checked}");
    }

    /// Every pose `route` has the robot hold, sampled every 5 mm, keeps the body (and its
    /// part) off every obstacle: holding the start heading before the turn window and the
    /// goal heading after it, and inside the window at any heading (its swept disc). The
    /// start is not checked when `part_in_slot`: a part just picked stands against its
    /// slot's back wall.
    /// The least room `route` leaves in `space` (m) and where (m along it), from its start
    /// or, with `part_in_slot`, from its first step.
    fn least_room(route: &Route, space: &FreeSpace, part_in_slot: bool) -> (f64, f64) {
        let (from_m, to_m) = route
            .turn_window_m()
            .unwrap_or((route.length_m(), route.length_m()));
        let steps = (route.length_m() / 0.005).ceil() as usize;
        let mut least = (f64::INFINITY, 0.0);
        for k in usize::from(part_in_slot)..=steps {
            let s = route.length_m() * k as f64 / steps as f64;
            let p = route.point_at(s);
            let room = if s < from_m {
                space.pose_clearance_m(Pose2::new(p.x, p.y, route.start_yaw_rad()), 1.0)
            } else if s > to_m {
                space.pose_clearance_m(Pose2::new(p.x, p.y, route.goal().yaw_rad), 1.0)
            } else {
                space.turn_clearance_m(p, 1.0)
            };
            if room < least.0 {
                least = (room, s);
            }
        }
        least
    }

    fn assert_route_keeps_clear(route: &Route, space: &FreeSpace, part_in_slot: bool, leg: &str) {
        let (room, s) = least_room(route, space, part_in_slot);
        assert!(
            room > 0.0,
            "{leg}: at {s:.3} m of {:.3} m, {:?}",
            route.length_m(),
            route.point_at(s)
        );
    }

    #[test]
    fn a_stall_mark_lies_along_the_carried_part_s_leading_side() {
        let footprint = Footprint::centred(0.30, 0.30, true);
        let (near, far) = (footprint.magnet_m, footprint.magnet_m + PART_DEPTH_M);
        // Facing -y, strafing towards +x (the robot's left), as along the outgoing
        // warehouse's mouths (round 1 seed 74 of the wheel-slip faults).
        let pose = Pose2::new(0.321, -0.25, -std::f64::consts::FRAC_PI_2);
        let mark = stall_mark(&footprint, pose, Vec2::new(0.0, 0.3)).expect("a mark");
        let expected = Rect::from_spans(
            0.321 + PART_WIDTH_M / 2.0,
            0.321 + PART_WIDTH_M / 2.0 + STALL_MARK_M,
            -0.25 - far,
            -0.25 - near,
        );
        for (got, want) in [(mark.min, expected.min), (mark.max, expected.max)] {
            assert!(got.distance(want) < 1e-9, "{mark:?}, expected {expected:?}");
        }
        // Driving on: beyond the part's far face.
        let ahead = stall_mark(&footprint, Pose2::default(), Vec2::new(0.3, 0.05)).expect("a mark");
        assert!(
            (ahead.min.x - far).abs() < 1e-9 && (ahead.max.x - far - STALL_MARK_M).abs() < 1e-9
        );
        // Reversing, the part trails; standing, no way is known.
        assert_eq!(stall_mark(&footprint, pose, Vec2::new(-0.3, 0.1)), None);
        assert_eq!(stall_mark(&footprint, pose, Vec2::ZERO), None);
    }

    #[test]
    fn a_carry_plans_round_the_mark_of_one_that_stalled_at_a_part_left_proud() {
        // Round 1 seed 74 of the wheel-slip faults: a carry from incoming slot 3 to
        // outgoing slot 3 stalled against the part left proud in outgoing slot 2.
        let mut config = Config::default();
        config.navigation.free_routes = true;
        let plain = LegPlanner::new(&config);
        let field = plain.field().clone();
        let slot = |waypoint: u8| {
            *field
                .slots()
                .find(|s| s.waypoint.0 == waypoint)
                .expect("slot")
        };
        let (from, to) = (slot(52), slot(64));
        let mark = stall_mark(
            &Footprint::of_robot(&config.robot, true),
            Pose2::new(0.321, -0.25, -std::f64::consts::FRAC_PI_2),
            Vec2::new(0.0, 0.3),
        )
        .expect("a mark");
        let marked = LegPlanner::with_obstacles(&config, &[mark]);
        let marked_space = &marked.carrying.0;
        let before = plain.plan(from.pick_pose, &to, true).expect("a route");
        let after = marked
            .plan(from.pick_pose, &to, true)
            .expect("a route round the mark");
        assert!(
            least_room(&before, marked_space, true).0 <= 0.0,
            "the way along the mouths meets the mark"
        );
        assert_route_keeps_clear(&after, marked_space, true, "52 → 64 round the mark");
        assert_eq!(after.goal(), before.goal());
        // Round machine B's east side: longer, and still straight into the slot.
        assert!(
            after.length_m() > before.length_m() + 0.2,
            "{:.3} m",
            after.length_m()
        );
        // The slot beyond is still reached.
        let beyond = marked
            .plan(from.pick_pose, &slot(65), true)
            .expect("slot 4");
        assert_route_keeps_clear(&beyond, marked_space, true, "52 → 65 round the mark");
    }

    #[test]
    fn free_routes_join_every_two_slots_and_keep_the_body_off_every_obstacle() {
        let mut config = Config::default();
        config.navigation.free_routes = true;
        let legs = LegPlanner::new(&config);
        let field = legs.field().clone();
        let mut checked = 0;
        for (carrying, from, to) in legs_the_rules_allow(&field) {
            let (space, free) = if carrying {
                &legs.carrying
            } else {
                &legs.empty
            };
            let free = free.as_ref().expect("free routes on");
            let goal = if carrying { drop_slot(&to) } else { to };
            let leg = format!("{} → {} (carrying: {carrying})", from.waypoint, to.waypoint);
            // Docked in `from`, straight out of it first.
            let route = free_routes(free, &field, from.pick_pose, &[goal], &config.navigation)
                .remove(0)
                .unwrap_or_else(|| panic!("{leg}: no free route"));
            let exit = route.points()[1] - route.points()[0];
            let normal = Vec2::from_angle(from.face_normal_rad);
            assert!(exit.dot(normal) >= SLOT_EXIT_M - 1e-9, "{leg}: {exit:?}");
            // (Collinear points within a millimetre are merged.)
            assert!(
                exit.cross(normal).abs() < MERGE_TOLERANCE_M,
                "{leg}: {exit:?}"
            );
            // Straight into `to`, square to its face.
            assert_eq!(route.goal(), goal.pick_pose, "{leg}");
            let n = route.points().len();
            let entry = route.points()[n - 1] - route.points()[n - 2];
            assert!(entry.norm() >= SLOT_EXIT_M - 1e-9, "{leg}: {entry:?}");
            assert!(
                wrap_angle(entry.angle() - goal.pick_pose.yaw_rad).abs() < 1e-9,
                "{leg}"
            );
            assert_route_keeps_clear(&route, space, carrying, &leg);
            checked += 1;
        }
        assert!(checked > 100, "{checked}");
    }

    #[test]
    fn free_routes_are_faster_than_the_road_maps_over_all_legs() {
        let mut config = Config::default();
        config.navigation.free_routes = false;
        let graph = LegPlanner::new(&config);
        config.navigation.free_routes = true;
        let free = LegPlanner::new(&config);
        let timer = crate::control::route_time::RouteTimer::new(&config);
        let (mut graph_s, mut free_s) = (0.0, 0.0);
        for (carrying, from, to) in legs_the_rules_allow(free.field()) {
            graph_s += timer.seconds(&graph.plan(from.pick_pose, &to, carrying).unwrap());
            free_s += timer.seconds(&free.plan(from.pick_pose, &to, carrying).unwrap());
        }
        assert!(
            free_s < 0.95 * graph_s,
            "{free_s:.1} s against {graph_s:.1} s"
        );
    }

    #[test]
    fn from_inside_a_slot_the_route_first_leaves_it_straight() {
        let field = Field::competition();
        let map = RoadMap::new(field.waypoints().clone());
        let config = NavigationConfig::default();
        let space = square_body_space(&field, true);
        let goal = field.slot_for_waypoint(WaypointId(62)).unwrap();
        for from in field.slots().filter(|s| s.waypoint != goal.waypoint) {
            let normal = Vec2::from_angle(from.face_normal_rad);
            // Docked a little short of the pick pose and a few millimetres off its axis.
            let across = Vec2::from_angle(from.face_normal_rad + std::f64::consts::FRAC_PI_2);
            let p = from.pick_pose.position() + normal * 0.004 + across * 0.003;
            let start = Pose2::new(p.x, p.y, from.pick_pose.yaw_rad + 0.02);
            let route = plan_route(&field, &map, &space, start, goal, &config).unwrap();
            // The first leg goes straight out (it may run on past the exit point when the
            // next vertex lies on the same line: collinear points are merged).
            let exit = route.points()[1] - route.points()[0];
            assert!(
                exit.norm() >= SLOT_EXIT_M - 0.006,
                "{}: {exit:?}",
                from.waypoint
            );
            // Along the slot's normal, the docking's 3 mm across kept: the part leaves
            // between the dividers along its own line.
            assert!(
                exit.cross(normal).abs() < 1e-9 && exit.dot(normal) > 0.0,
                "{}: {exit:?}",
                from.waypoint
            );
            // Already out of the slot: no exit leg.
            let out = from.pick_pose.position() + normal * (SLOT_EXIT_M + 0.01);
            assert!(slot_to_leave(&field, Pose2::new(out.x, out.y, start.yaw_rad)).is_none());
        }
    }

    #[test]
    fn projection_progresses_along_a_u_turn() {
        let p = |x: f64, y: f64| Vec2::new(x, y);
        let route = Route::new(
            vec![p(0.0, 0.0), p(0.5, 0.0), p(0.5, 0.1), p(0.0, 0.1)],
            0.0,
            0.0,
            0.0,
        )
        .unwrap();
        // Near the start, the return leg (0.1 m away) must not capture the projection.
        let at = route.project(0, p(0.1, 0.04));
        assert_eq!(at.segment, 0);
        assert!((at.s_m - 0.1).abs() < 1e-12);
        let later = route.project(1, p(0.3, 0.09));
        assert_eq!(later.segment, 2);
        assert!((later.s_m - 0.8).abs() < 1e-9);
        assert!((route.turn_angle_rad(1) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(Route::new(vec![p(0.0, 0.0)], 0.0, 0.0, 0.0).is_none());
    }
}
