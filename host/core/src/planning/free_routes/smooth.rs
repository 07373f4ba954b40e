//! From a staircase of grid cells to a taut polyline: each stretch the robot drives one way
//! (holding a heading, or turning) pulled straight wherever a straight line keeps as much
//! room as the cells it replaces, checked on the exact geometry; then the corners where
//! the robot starts and stops turning dropped where the straight line allows, and the turn
//! spread over as much open floor as the route crosses.

use crate::field::geometry::{Pose2, Segment, Vec2};
use crate::planning::shortcuts::{FreeSpace, SAMPLE_STEP_M};

use super::grid::{CELL_M, ClearanceGrid, Stance};

/// How much less room a straight line may keep than the cells it replaces, m: the grid
/// measures the clearance at cell centres only, and a taut line passes the corners closer
/// than the staircase's centres did.
pub const PULL_TOLERANCE_M: f64 = 0.002;

/// How much less room the grid may show along a line than the exact geometry has, m: a
/// point of the line lies within half a cell's diagonal of the centre it is looked up at.
const GRID_SLACK_M: f64 = CELL_M * std::f64::consts::FRAC_1_SQRT_2;

/// A stretch of the search's path driven one way, with the room at each point.
#[derive(Clone, Debug)]
pub struct Stretch<'a> {
    /// How the robot stands along it.
    pub stance: Stance,
    /// Its grid.
    pub grid: &'a ClearanceGrid,
    /// The points, in order: cell centres, and the exact start or goal at the ends.
    pub points: Vec<Vec2>,
    /// The clearance at each point, m.
    pub clearance_m: Vec<f64>,
}

/// The room a straight line from `a` to `b` must keep to replace points whose least
/// clearance is `replaced_m`, m.
fn needed_m(replaced_m: f64, cap_m: f64) -> f64 {
    (replaced_m.min(cap_m) - PULL_TOLERANCE_M).max(0.0)
}

/// Whether the robot standing `stance` can drive straight from `a` to `b` keeping
/// `need_m`, and more than nothing: the grid first, cheaply, then the exact geometry.
fn straight_keeps(
    space: &FreeSpace,
    grid: &ClearanceGrid,
    stance: Stance,
    (a, b): (Vec2, Vec2),
    need_m: f64,
    cap_m: f64,
) -> bool {
    if grid.line_clearance_m(a, b) < need_m - GRID_SLACK_M {
        return false;
    }
    let exact = space.segment_clearance_m(a, b, stance.held_yaw_rad(), cap_m);
    exact >= need_m && FreeSpace::segment_guaranteed_m(exact) > 0.0
}

/// The stretch pulled taut: from each kept point, straight on to the farthest later point
/// the robot reaches keeping the room of the points between ([`PULL_TOLERANCE_M`] less);
/// the ends are kept. `None` when even the step to the next point would touch something
/// (two cells with room whose straight line between does not have it).
pub fn pull_taut(stretch: &Stretch<'_>, space: &FreeSpace, cap_m: f64) -> Option<Vec<Vec2>> {
    let points = &stretch.points;
    let first = *points.first()?;
    let mut kept = vec![first];
    let mut i = 0;
    while i + 1 < points.len() {
        let mut least = f64::INFINITY;
        let reach: Vec<f64> = points[i..]
            .iter()
            .zip(&stretch.clearance_m[i..])
            .map(|(_, &c)| {
                least = least.min(c);
                least
            })
            .collect();
        let keeps = |j: usize, need_m: f64| {
            straight_keeps(
                space,
                stretch.grid,
                stretch.stance,
                (points[i], points[j]),
                need_m,
                cap_m,
            )
        };
        let next = (i + 2..points.len())
            .rev()
            .find(|&j| keeps(j, needed_m(reach[j - i], cap_m)));
        let next = match next {
            Some(j) => j,
            None if keeps(i + 1, 0.0) => i + 1,
            None => return None,
        };
        kept.push(points[next]);
        i = next;
    }
    Some(kept)
}

/// A path `[a, b, c, d, …]` whose first segment is fixed in direction (the way straight out
/// of a slot) with the corner at `b`, a short segment and another corner at `c` (the step
/// onto the next line), made `[a, x, d, …]` with one corner at `x`, where the line through
/// `a` and `b` meets the line through `c` and `d`, if `x` lies beyond `b` and before `d`
/// and the robot standing `stance` keeps the room it had on `b → c → d` (less
/// [`PULL_TOLERANCE_M`]). Two corners close together slow the follower for each.
pub fn merge_step(points: &mut Vec<Vec2>, space: &FreeSpace, stance: Stance, cap_m: f64) {
    let [a, b, c, d] = match points.get(..4) {
        Some(&[a, b, c, d]) => [a, b, c, d],
        _ => return,
    };
    let (out, along) = (b - a, d - c);
    let across = out.cross(along);
    if across.abs() < 1e-12 {
        return;
    }
    // x = b + out·t on the line c + along·u.
    let t = (c - b).cross(along) / across;
    let x = b + out * t;
    if t <= 0.0 || (d - x).dot(along) <= 0.0 {
        return;
    }
    let yaw = stance.held_yaw_rad();
    let had = space
        .segment_clearance_m(b, c, yaw, cap_m)
        .min(space.segment_clearance_m(c, d, yaw, cap_m));
    let need = needed_m(had, cap_m);
    let keeps = |p: Vec2, q: Vec2| {
        let room = space.segment_clearance_m(p, q, yaw, cap_m);
        room >= need && FreeSpace::segment_guaranteed_m(room) > 0.0
    };
    if keeps(b, x) && keeps(x, d) {
        points.splice(1..3, [x]);
    }
}

/// Arc length at every point of `points`, m.
pub fn arc_lengths(points: &[Vec2]) -> Vec<f64> {
    let mut s = vec![0.0];
    for w in points.windows(2) {
        let last = s.last().copied().unwrap_or(0.0);
        s.push(last + w[0].distance(w[1]));
    }
    s
}

/// Where a turn that must keep `need_m` can start on the straight line from `a` to `b`
/// and go on to `b`: the earliest sample from which the swept disc keeps it all the way to
/// `b`, as a fraction of the way (`None` if not even at `b`).
fn turn_reaches_from(
    space: &FreeSpace,
    (a, b): (Vec2, Vec2),
    need_m: f64,
    cap_m: f64,
) -> Option<f64> {
    let steps = (a.distance(b) / SAMPLE_STEP_M).ceil().max(1.0) as usize;
    let mut earliest = None;
    for k in (0..=steps).rev() {
        let t = k as f64 / steps as f64;
        let room = space.turn_clearance_m(a + (b - a) * t, cap_m);
        if room < need_m || FreeSpace::segment_guaranteed_m(room) <= 0.0 {
            break;
        }
        earliest = Some(t);
    }
    earliest
}

/// The corner where the turn starts (`at`, between a held stretch before and the turn
/// after) dropped if the straight line across it keeps the room of both sides: held up to
/// where the disc is clear, turning from there. Returns the new points and the fraction of
/// the new segment where the turn starts, or `None` to keep the corner.
fn drop_turn_start(
    space: &FreeSpace,
    held: Stance,
    (before, at, after): (Vec2, Vec2, Vec2),
    cap_m: f64,
) -> Option<f64> {
    let need_held = needed_m(
        space.segment_clearance_m(before, at, held.held_yaw_rad(), cap_m),
        cap_m,
    );
    let need_turn = needed_m(space.segment_clearance_m(at, after, None, cap_m), cap_m);
    let from = turn_reaches_from(space, (before, after), need_turn, cap_m)?;
    let switch = before + (after - before) * from;
    let held_keeps = space.segment_clearance_m(before, switch, held.held_yaw_rad(), cap_m);
    (held_keeps >= need_held && FreeSpace::segment_guaranteed_m(held_keeps) > 0.0).then_some(from)
}

/// Where along a path a turn starts or ends: `fraction` of the way along the segment from
/// point `index` to the next.
#[derive(Clone, Copy, Debug, PartialEq)]
struct OnPath {
    index: usize,
    fraction: f64,
}

impl OnPath {
    fn arc_m(self, s: &[f64]) -> f64 {
        match s.get(self.index + 1) {
            Some(next) => s[self.index] + (next - s[self.index]) * self.fraction,
            None => s[self.index],
        }
    }
}

/// The taut stretches (each `(stance, points)`, consecutive ones sharing their joining
/// point; at most one turning) joined into one path, the corners where the turn starts
/// and ends dropped where the straight line across keeps the room of both sides
/// (`drop_turn_start`, and its mirror for the end) but for the lead-out point (the
/// second, if `lead_out`) and the lead-in point (the last but one, if `lead_in`), and the
/// turn widened along the path, no further than `limits` (arc lengths the caller allows),
/// wherever the disc keeps at least the room it has where the search put it. The turn the
/// search found is never narrowed to fit `limits` (clamped, it was once left 1.4 mm long
/// and the robot stalled turning in it): the lead-out and lead-in points, kept, already
/// hold it off the ends. Returns the points and the turn as arc lengths (`None`: no
/// turning stretch).
pub fn join(
    space: &FreeSpace,
    stretches: &[(Stance, Vec<Vec2>)],
    limits: (f64, f64),
    (lead_out, lead_in): (bool, bool),
    cap_m: f64,
) -> (Vec<Vec2>, Option<(f64, f64)>) {
    let mut points: Vec<Vec2> = Vec::new();
    let mut turn: Option<(usize, usize)> = None;
    for (stance, stretch) in stretches {
        let first = points.len().saturating_sub(1);
        points.extend(
            stretch
                .iter()
                .skip(usize::from(!points.is_empty()))
                .copied(),
        );
        if *stance == Stance::Turning {
            turn = Some((first, points.len() - 1));
        }
    }
    let Some((first, mut last)) = turn else {
        return (points, None);
    };
    let held_before = stretches.first().map(|(stance, _)| *stance);
    let held_after = stretches.last().map(|(stance, _)| *stance);
    let mut start = OnPath {
        index: first,
        fraction: 0.0,
    };
    // The lead-out point (index 1) and the lead-in point (the last but one) stay.
    let first_droppable = 1 + usize::from(lead_out);
    if let Some(held) = held_before
        && first >= first_droppable
        && first < last
        && let Some(from) = drop_turn_start(
            space,
            held,
            (points[first - 1], points[first], points[first + 1]),
            cap_m,
        )
    {
        points.remove(first);
        last -= 1;
        start = OnPath {
            index: first - 1,
            fraction: from,
        };
    }
    let mut end = OnPath {
        index: last,
        fraction: 0.0,
    };
    let whole_segment_before =
        start.index + 1 < last || (start.index + 1 == last && start.fraction == 0.0);
    if let Some(held) = held_after
        && last + 1 + usize::from(lead_in) < points.len()
        && whole_segment_before
        && let Some(from) = drop_turn_start(
            space,
            held,
            (points[last + 1], points[last], points[last - 1]),
            cap_m,
        )
    {
        points.remove(last);
        end = OnPath {
            index: last - 1,
            fraction: 1.0 - from,
        };
    }
    let s = arc_lengths(&points);
    let (a, b) = (start.arc_m(&s), end.arc_m(&s).max(start.arc_m(&s)));
    let (a, b) = widen_turn(space, &points, (a, b), limits, cap_m);
    if let (Some(Stance::Held(start_yaw)), Some(Stance::Held(goal_yaw))) = (held_before, held_after)
    {
        let droppable = (
            first_droppable,
            points.len().saturating_sub(2 + usize::from(lead_in)),
        );
        let stances = Stances {
            start_yaw,
            turn_m: (a, b),
            goal_yaw,
        };
        drop_small_bends(space, &mut points, &stances, droppable, cap_m);
    }
    (points, Some((a, b)))
}

/// How the robot stands along a path: holding its start heading before the turn (arc
/// lengths, m), turning inside it, holding its goal heading after it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Stances {
    start_yaw: f64,
    turn_m: (f64, f64),
    goal_yaw: f64,
}

impl Stances {
    fn at(&self, s_m: f64) -> Option<f64> {
        if s_m < self.turn_m.0 {
            Some(self.start_yaw)
        } else if s_m > self.turn_m.1 {
            Some(self.goal_yaw)
        } else {
            None
        }
    }

    /// The least clearance at samples along the straight line from `a`, at arc length
    /// `from_m`, to `b`, each standing as it does there, m, at most `cap_m`.
    fn room_along(&self, space: &FreeSpace, (a, b): (Vec2, Vec2), from_m: f64, cap_m: f64) -> f64 {
        let steps = (a.distance(b) / SAMPLE_STEP_M).ceil().max(1.0) as usize;
        (0..=steps)
            .map(|k| {
                let t = k as f64 / steps as f64;
                let p = a + (b - a) * t;
                match self.at(from_m + a.distance(b) * t) {
                    Some(yaw) => space.pose_clearance_m(Pose2::new(p.x, p.y, yaw), cap_m),
                    None => space.turn_clearance_m(p, cap_m),
                }
            })
            .fold(cap_m, f64::min)
    }
}

/// The largest deviation a bend may have from the straight line past it and still be
/// dropped, m: the grid's cells and the taut lines' ends leave bends of a millimetre or
/// two between stretches (a step of 1 mm at 60° slows the follower like any corner).
pub const SMALL_BEND_M: f64 = 0.003;

/// Drops each point with index in `droppable` (inclusive) that lies within
/// [`SMALL_BEND_M`] of the straight line between its neighbours, where that line keeps the
/// room the two segments it replaces kept (less [`PULL_TOLERANCE_M`]), standing as
/// `stances` says along it.
fn drop_small_bends(
    space: &FreeSpace,
    points: &mut Vec<Vec2>,
    stances: &Stances,
    (first, last): (usize, usize),
    cap_m: f64,
) {
    for i in (first.max(1)..=last.min(points.len().saturating_sub(2))).rev() {
        let (a, b, c) = (points[i - 1], points[i], points[i + 1]);
        if Segment::new(a, c).distance_to_point(b) >= SMALL_BEND_M {
            continue;
        }
        let from_m = arc_lengths(&points[..i])[i - 1];
        let had = stances
            .room_along(space, (a, b), from_m, cap_m)
            .min(stances.room_along(space, (b, c), from_m + a.distance(b), cap_m));
        let room = stances.room_along(space, (a, c), from_m, cap_m);
        if room >= needed_m(had, cap_m) && FreeSpace::segment_guaranteed_m(room) > 0.0 {
            points.remove(i);
        }
    }
}

/// The point at arc length `s_m` of the polyline with arc lengths `s`.
fn point_at(points: &[Vec2], s: &[f64], s_m: f64) -> Vec2 {
    let i = s
        .windows(2)
        .position(|w| s_m <= w[1])
        .unwrap_or(points.len().saturating_sub(2));
    let span = (s[i + 1] - s[i]).max(1e-12);
    points[i] + (points[i + 1] - points[i]) * ((s_m - s[i]) / span).clamp(0.0, 1.0)
}

/// The turn `[a, b]` (arc lengths) widened both ways while the swept disc keeps at least
/// the least room it has inside, within `limits`.
fn widen_turn(
    space: &FreeSpace,
    points: &[Vec2],
    (a, b): (f64, f64),
    limits: (f64, f64),
    cap_m: f64,
) -> (f64, f64) {
    if points.len() < 2 {
        return (a, b);
    }
    let s = arc_lengths(points);
    let room = |s_m: f64| space.turn_clearance_m(point_at(points, &s, s_m), cap_m);
    let steps = ((b - a) / SAMPLE_STEP_M).ceil().max(1.0) as usize;
    let inside = (0..=steps)
        .map(|k| room(a + (b - a) * k as f64 / steps as f64))
        .fold(f64::INFINITY, f64::min);
    let need = inside.min(cap_m);
    let keeps = |s_m: f64| {
        let here = room(s_m);
        here >= need && FreeSpace::segment_guaranteed_m(here) > 0.0
    };
    let (mut from, mut to) = (a, b);
    while from - SAMPLE_STEP_M >= limits.0 && keeps(from - SAMPLE_STEP_M) {
        from -= SAMPLE_STEP_M;
    }
    let end = limits.1.min(s[s.len() - 1]);
    while to + SAMPLE_STEP_M <= end && keeps(to + SAMPLE_STEP_M) {
        to += SAMPLE_STEP_M;
    }
    (from.min(a), to.max(b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::geometry::Rect;
    use crate::planning::shortcuts::Footprint;

    const CAP_M: f64 = 0.02;

    /// A floor with `walls`, the robot a 10 cm square (its disc 71 mm), no margin.
    fn space(walls: Vec<Rect>) -> FreeSpace {
        FreeSpace::with_walls(walls, Footprint::centred(0.10, 0.10, false), CAP_M)
    }

    /// The cells of `grid` along a staircase from `a`: `right` cells right, then `up` up
    /// (each its grid clearance).
    fn staircase(grid: &ClearanceGrid, a: Vec2, right: usize, up: usize) -> Stretch<'_> {
        let mut points = Vec::new();
        for k in 0..=right {
            points.push(a + Vec2::new(k as f64 * CELL_M, 0.0));
        }
        for k in 1..=up {
            points.push(a + Vec2::new(right as f64 * CELL_M, k as f64 * CELL_M));
        }
        let clearance_m = points
            .iter()
            .map(|&p| grid.clearance_m(grid.cell_at(p).unwrap()))
            .collect();
        Stretch {
            stance: grid.stance(),
            grid,
            points,
            clearance_m,
        }
    }

    fn length(points: &[Vec2]) -> f64 {
        arc_lengths(points).last().copied().unwrap_or(0.0)
    }

    #[test]
    fn a_staircase_on_open_floor_is_pulled_into_one_straight_line() {
        let space = space(Vec::new());
        let area = Rect::from_spans(0.0, 0.5, 0.0, 0.5);
        let grid = ClearanceGrid::new(&space, area, Stance::Held(0.0), CAP_M);
        let stretch = staircase(&grid, Vec2::new(0.105, 0.105), 20, 15);
        let taut = pull_taut(&stretch, &space, CAP_M).unwrap();
        assert_eq!(
            taut,
            vec![stretch.points[0], *stretch.points.last().unwrap()]
        );
    }

    #[test]
    fn round_a_wall_the_searched_path_bends_at_its_corner_and_keeps_the_room() {
        use crate::planning::free_routes::search::{Layers, State, StepCosts, cheapest};
        // From below a wall's lower right corner to beside its right side.
        let wall = Rect::from_spans(0.0, 0.2, 0.2, 0.5);
        let space = space(vec![wall]);
        let area = Rect::from_spans(0.0, 0.6, 0.0, 0.6);
        let grid = ClearanceGrid::new(&space, area, Stance::Held(0.0), CAP_M);
        let turning = ClearanceGrid::new(&space, area, Stance::Turning, CAP_M);
        let layers = Layers {
            start: &grid,
            turning: &turning,
            goals: &[],
        };
        let costs = StepCosts {
            cap_m: CAP_M,
            clearance_weight: 2.0,
            turn_discount: 1.0,
            turn_floor_m: CAP_M,
        };
        let from = grid.cell_at(Vec2::new(0.105, 0.125)).unwrap();
        let to = grid.cell_at(Vec2::new(0.305, 0.425)).unwrap();
        let tree = cheapest(
            &layers,
            &costs,
            &[(
                State {
                    layer: 0,
                    cell: from,
                },
                0.0,
            )],
        );
        let points: Vec<Vec2> = tree
            .path_to(State { layer: 0, cell: to })
            .iter()
            .map(|s| grid.centre(s.cell))
            .collect();
        let clearance_m: Vec<f64> = points
            .iter()
            .map(|&p| grid.clearance_m(grid.cell_at(p).unwrap()))
            .collect();
        let stretch = Stretch {
            stance: grid.stance(),
            grid: &grid,
            points,
            clearance_m,
        };
        let taut = pull_taut(&stretch, &space, CAP_M).unwrap();
        assert!((3..=5).contains(&taut.len()), "{taut:?}");
        assert!(length(&taut) < length(&stretch.points) - 0.005, "{taut:?}");
        let least = stretch.clearance_m.iter().copied().fold(CAP_M, f64::min);
        for pair in taut.windows(2) {
            let room = space.segment_clearance_m(pair[0], pair[1], Some(0.0), CAP_M);
            assert!(room >= least - PULL_TOLERANCE_M, "{pair:?}: {room}");
        }
    }

    #[test]
    fn a_step_off_the_way_out_becomes_one_corner() {
        let space = space(Vec::new());
        let stance = Stance::Held(0.0);
        // Out along −y to (0.2, 0.26), a short step to (0.21, 0.25), then along y = 0.25.
        let mut points = vec![
            Vec2::new(0.2, 0.34),
            Vec2::new(0.2, 0.26),
            Vec2::new(0.21, 0.25),
            Vec2::new(0.5, 0.25),
        ];
        merge_step(&mut points, &space, stance, CAP_M);
        assert_eq!(points.len(), 3);
        assert!(
            (points[1] - Vec2::new(0.2, 0.25)).norm() < 1e-12,
            "{points:?}"
        );
        // Where the next line would be met behind the way out, nothing changes.
        let mut behind = vec![
            Vec2::new(0.2, 0.34),
            Vec2::new(0.2, 0.26),
            Vec2::new(0.21, 0.28),
            Vec2::new(0.5, 0.28),
        ];
        let before = behind.clone();
        merge_step(&mut behind, &space, stance, CAP_M);
        assert_eq!(behind, before);
    }

    #[test]
    fn the_corners_of_the_turn_are_dropped_on_open_floor_and_the_turn_spread_over_it() {
        let space = space(Vec::new());
        let stretches = [
            (
                Stance::Held(0.0),
                vec![Vec2::new(0.1, 0.1), Vec2::new(0.3, 0.1)],
            ),
            (
                Stance::Turning,
                vec![Vec2::new(0.3, 0.1), Vec2::new(0.5, 0.2)],
            ),
            (
                Stance::Held(1.0),
                vec![Vec2::new(0.5, 0.2), Vec2::new(0.7, 0.3)],
            ),
        ];
        let (points, turn) = join(&space, &stretches, (0.05, 0.4), (false, false), CAP_M);
        // Open floor: one straight line, and with no lead points to hold it off the ends
        // the turn spreads over all of it (the search's turn is never narrowed).
        assert_eq!(points, vec![Vec2::new(0.1, 0.1), Vec2::new(0.7, 0.3)]);
        let (a, b) = turn.unwrap();
        assert!(a.abs() < 1e-9, "{a}");
        assert!((b - length(&points)).abs() < 1e-9, "{b}");
    }

    #[test]
    fn a_turn_is_widened_over_open_floor_up_to_the_limits() {
        let open = space(Vec::new());
        let line = [Vec2::new(0.0, 0.5), Vec2::new(1.0, 0.5)];
        let (a, b) = widen_turn(&open, &line, (0.4, 0.5), (0.3, 0.7), CAP_M);
        assert!((0.3..0.3 + SAMPLE_STEP_M).contains(&a), "{a}");
        assert!(b <= 0.7 && b > 0.7 - SAMPLE_STEP_M, "{b}");
        // A wall beside the line from 0.6 on: the disc (71 mm) has less room there than
        // where the search turned, so the turn stops short of it.
        let wall = Rect::from_spans(0.6, 1.0, 0.55, 0.6);
        let (_, b) = widen_turn(&space(vec![wall]), &line, (0.4, 0.5), (0.3, 0.7), CAP_M);
        assert!((0.5..0.6).contains(&b), "{b}");
    }

    #[test]
    fn a_turn_keeps_its_corners_where_the_floor_is_not_open_and_never_drops_the_leads() {
        // A wall above the first line: the held robot passes under it, the turning one
        // (its disc 71 mm) only well beyond it.
        let wall = Rect::from_spans(0.0, 0.35, 0.16, 0.3);
        let space = space(vec![wall]);
        let stretches = [
            (
                Stance::Held(0.0),
                vec![
                    Vec2::new(0.0, 0.1),
                    Vec2::new(0.1, 0.1),
                    Vec2::new(0.45, 0.1),
                ],
            ),
            (
                Stance::Turning,
                vec![Vec2::new(0.45, 0.1), Vec2::new(0.6, 0.3)],
            ),
            (
                Stance::Held(1.0),
                vec![Vec2::new(0.6, 0.3), Vec2::new(0.6, 0.5)],
            ),
        ];
        let (points, turn) = join(&space, &stretches, (0.0, 10.0), (true, true), CAP_M);
        // The lead-out (0.1, 0.1) and the lead-in (0.6, 0.3) stay.
        assert!(points.contains(&Vec2::new(0.1, 0.1)), "{points:?}");
        assert!(points.contains(&Vec2::new(0.6, 0.3)), "{points:?}");
        let (a, b) = turn.unwrap();
        let s = arc_lengths(&points);
        // The turn starts past the lead-out, where the disc first keeps the margin.
        assert!(a > 0.1, "{a}");
        let before = point_at(&points, &s, a - SAMPLE_STEP_M);
        assert!(space.turn_clearance_m(before, CAP_M) < CAP_M, "{a}");
        assert!(b <= s[s.len() - 1] + 1e-9);
        for k in 0..=100 {
            let p = point_at(&points, &s, a + (b - a) * k as f64 / 100.0);
            assert!(
                space.turn_clearance_m(p, CAP_M) >= CAP_M - PULL_TOLERANCE_M,
                "{p:?}"
            );
        }
    }

    #[test]
    fn a_bend_of_a_millimetre_is_dropped_unless_the_straight_line_would_touch() {
        let stances = Stances {
            start_yaw: 0.0,
            turn_m: (10.0, 10.0),
            goal_yaw: 0.0,
        };
        let bent = vec![
            Vec2::new(0.1, 0.1),
            Vec2::new(0.3, 0.099),
            Vec2::new(0.5, 0.1),
        ];
        let mut open = bent.clone();
        drop_small_bends(&space(Vec::new()), &mut open, &stances, (1, 1), CAP_M);
        assert_eq!(open, vec![bent[0], bent[2]]);
        // A wall 2.5 mm above the 10 cm robot at the bend: straight, it would pass 1.5 mm
        // off, within the half sample step between the checks.
        let wall = Rect::from_spans(0.25, 0.35, 0.1515, 0.3);
        let mut near = bent.clone();
        drop_small_bends(&space(vec![wall]), &mut near, &stances, (1, 1), CAP_M);
        assert_eq!(near, bent);
        // A bend of 5 mm is a corner, not a step: kept.
        let corner = vec![
            Vec2::new(0.1, 0.1),
            Vec2::new(0.3, 0.095),
            Vec2::new(0.5, 0.1),
        ];
        let mut kept = corner.clone();
        drop_small_bends(&space(Vec::new()), &mut kept, &stances, (1, 1), CAP_M);
        assert_eq!(kept, corner);
    }

    #[test]
    fn without_a_turning_stretch_the_path_has_no_turn() {
        let space = space(Vec::new());
        let line = vec![Vec2::new(0.1, 0.1), Vec2::new(0.3, 0.1)];
        let (points, turn) = join(
            &space,
            &[(Stance::Held(0.0), line.clone())],
            (0.0, 1.0),
            (false, false),
            CAP_M,
        );
        assert_eq!(points, line);
        assert_eq!(turn, None);
    }
}
