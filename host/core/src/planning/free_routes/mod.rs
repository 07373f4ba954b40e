//! Routes through free space for the robot's whole body with its heading (issue 14): not
//! the waypoint graph's rows, but the shortest way, weighted by how little room it leaves,
//! that the body (and the part it carries) can drive holding its start heading, then
//! turning where the disc it sweeps is clear, then holding its goal heading.
//!
//! The floor is a grid ([`grid`]) of clearances per stance: the footprint at each of the
//! four square headings (the slots' headings, built once), at the robot's own heading
//! when it is not square, and the swept disc. A search over the layered grids ([`search`])
//! finds the cheapest staircase of cells; each stretch driven one way is then pulled taut
//! on the exact geometry, the turn's corners dropped where a straight line allows, and the
//! turn spread over the open floor the route crosses ([`smooth`]). The follower turns only
//! inside that stretch (`control::profile::HeadingPlan`), so every pose it holds along the
//! route is one these checks kept clear.

pub mod grid;
pub mod search;
pub mod smooth;

use std::borrow::Cow;
use std::f64::consts::FRAC_PI_2;

use crate::field::Field;
use crate::field::geometry::{Pose2, Rect, Vec2, wrap_angle};
use crate::planning::shortcuts::FreeSpace;

use self::grid::{ClearanceGrid, Stance};
use self::search::{Layers, State, StepCosts, cheapest};
use self::smooth::{Stretch, join, merge_step, pull_taut};

/// How far inside the printed floor's edges the robot's centre stays, m: its 30 cm body
/// overhangs the sheet by 5 cm at most (the floor has no wall, and what stands beyond the
/// sheet in a hall is not known).
pub const KEEP_IN_M: f64 = 0.10;

/// How much dearer a metre with no room at all is than one with the margin's
/// ([`StepCosts::clearance_weight`]).
pub const CLEARANCE_WEIGHT: f64 = 2.0;

/// The factor on a metre driven while turning ([`StepCosts::turn_discount`]): below 1, the
/// search spreads the turn over open floor rather than turning in the first spot with
/// room. 0.7, chosen on the realistic world's tuning seeds 61–110 (calibrated, `bench
/// rounds --policy ours`): 0.6 gave 35.5 / 37.2 / 47.1 s per round, 0.7 35.4 / 37.2 /
/// 47.1 s, 0.8 35.8 / 37.6 / 47.4 s, and 1 (no discount, on seeds 61–70) 38.6 / 40.0 s in
/// rounds 1 and 2, where the robot turned on short stretches at a crawl.
pub const TURN_DISCOUNT: f64 = 0.7;

/// How far below the margin a turning cell's clearance may be read and still have all of
/// it, m (the grid keeps clearances as `f32`).
const TURN_FLOOR_SLACK_M: f64 = 1e-6;

/// Cells around an exact start or goal the search joins it to (a square of 2·2 + 1).
const JOIN_RADIUS_CELLS: usize = 2;

/// Where a free path leaves from: the robot's pose, and the point it first drives
/// straight to (out of the slot it stands in), if any.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Departure {
    /// The robot's pose; it holds this heading until it may turn.
    pub pose: Pose2,
    /// Where it first drives straight to, holding its heading.
    pub lead_out: Option<Vec2>,
}

/// The four points a free path runs between: the robot, its lead-out point (the robot
/// itself without one), the lead-in point and the arrival.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Ends {
    start: Vec2,
    from: Vec2,
    to: Vec2,
    end: Vec2,
}

/// A path the robot can drive through free space.
#[derive(Clone, Debug, PartialEq)]
pub struct FreePath {
    /// The points, from the start to the goal.
    pub points: Vec<Vec2>,
    /// Where the robot turns, as arc lengths from the start (m); `None` when the start and
    /// goal headings are the same.
    pub turn_m: Option<(f64, f64)>,
}

/// The free-space planner for one footprint on one floor: its grids, built once.
#[derive(Clone, Debug)]
pub struct FreeRoutes {
    space: FreeSpace,
    area: Rect,
    costs: StepCosts,
    turning: ClearanceGrid,
    /// The footprint at headings 0, π/2, π and −π/2.
    square: Vec<ClearanceGrid>,
}

/// How far off a square heading the robot may hold its start heading and be searched on
/// that heading's grid, rad (1°: the 30 cm square's corners move 4 mm; a robot docked in a
/// slot stands within half a degree of square).
pub const SQUARE_GRID_TOLERANCE_RAD: f64 = 0.0175;

/// The four square headings, rad.
const SQUARE_HEADINGS: [f64; 4] = [0.0, FRAC_PI_2, std::f64::consts::PI, -FRAC_PI_2];

impl FreeRoutes {
    /// The planner for `space` (its footprint, obstacles and margin: the least room the
    /// robot turns with, and the room beyond which more costs nothing) on `field`'s
    /// printed floor. (Paying for room up to twice the margin, so that routes would not
    /// hug what they pass, was measured on the realistic world's tuning seeds 61–110,
    /// calibrated: 36.5 / 38.0 / 49.3 s per round and 1 collision, against 36.0 / 37.8 /
    /// 47.9 s and none; 1.5 margins 36.2 / 38.1 / 49.0 s and 1: not kept. The follower's
    /// error at corners is the corner caps' to bound, `control::route`.)
    pub fn new(field: &Field, space: FreeSpace) -> Self {
        let area = field.printed_area().inflated(-KEEP_IN_M);
        let cap_m = space.margin_m();
        let costs = StepCosts {
            cap_m,
            clearance_weight: CLEARANCE_WEIGHT,
            turn_discount: TURN_DISCOUNT,
            // A turning cell's clearance is capped at the margin: it needs all of it.
            turn_floor_m: cap_m - TURN_FLOOR_SLACK_M,
        };
        let turning = ClearanceGrid::new(&space, area, Stance::Turning, cap_m);
        let square = SQUARE_HEADINGS
            .iter()
            .map(|&yaw| ClearanceGrid::new(&space, area, Stance::Held(yaw), cap_m))
            .collect();
        Self {
            space,
            area,
            costs,
            turning,
            square,
        }
    }

    /// The free space it plans in.
    pub fn space(&self) -> &FreeSpace {
        &self.space
    }

    /// The grid to search for the footprint holding `yaw_rad`: a square heading's, built
    /// once, within [`SQUARE_GRID_TOLERANCE_RAD`] of one (the exact heading is checked when
    /// the path is pulled taut), else one built now.
    fn held(&self, yaw_rad: f64) -> Cow<'_, ClearanceGrid> {
        match SQUARE_HEADINGS
            .iter()
            .position(|&square| wrap_angle(yaw_rad - square).abs() <= SQUARE_GRID_TOLERANCE_RAD)
        {
            Some(i) => Cow::Borrowed(&self.square[i]),
            None => Cow::Owned(ClearanceGrid::new(
                &self.space,
                self.area,
                Stance::Held(yaw_rad),
                self.costs.cap_m,
            )),
        }
    }

    /// The path from `departure` to `arrival` ([`Self::paths`] for one).
    pub fn path(
        &self,
        departure: Departure,
        arrival: Pose2,
        lead_in_m: f64,
        keep_off_m: (f64, f64),
    ) -> Option<FreePath> {
        self.paths(departure, &[arrival], lead_in_m, keep_off_m)
            .pop()
            .flatten()
    }

    /// The paths from `departure` (holding its heading, first straight to its lead-out
    /// point if it has one) to each of `arrivals` (its last `lead_in_m` straight on to
    /// it, holding its heading), from one search; the turn widened only where it stays
    /// `keep_off_m.0` from the start and `keep_off_m.1` from the end. `None` for an arrival
    /// the search finds no way to, or whose path the exact geometry refuses.
    pub fn paths(
        &self,
        departure: Departure,
        arrivals: &[Pose2],
        lead_in_m: f64,
        keep_off_m: (f64, f64),
    ) -> Vec<Option<FreePath>> {
        let start = departure.pose;
        let from = departure.lead_out.unwrap_or(start.position());
        let goals: Vec<Pose2> = arrivals
            .iter()
            .map(|arrival| arrival.compose(Pose2::new(-lead_in_m, 0.0, 0.0)))
            .collect();
        let start_grid = self.held(start.yaw_rad);
        let same_heading = |yaw: f64| wrap_angle(yaw - start.yaw_rad).abs() < 1e-9;
        let mut goal_yaws: Vec<f64> = Vec::new();
        for goal in &goals {
            if !same_heading(goal.yaw_rad)
                && !goal_yaws
                    .iter()
                    .any(|&yaw| wrap_angle(yaw - goal.yaw_rad).abs() < 1e-9)
            {
                goal_yaws.push(goal.yaw_rad);
            }
        }
        let goal_grids: Vec<Cow<'_, ClearanceGrid>> =
            goal_yaws.iter().map(|&yaw| self.held(yaw)).collect();
        let goal_refs: Vec<&ClearanceGrid> = goal_grids.iter().map(|g| g.as_ref()).collect();
        let layers = Layers {
            start: &start_grid,
            turning: &self.turning,
            goals: &goal_refs,
        };
        let layer_grid = |layer: usize| -> &ClearanceGrid {
            match layer {
                0 => &start_grid,
                1 => &self.turning,
                goal => goal_refs[goal - 2],
            }
        };
        let layer_stance = |layer: usize| match layer {
            0 => Stance::Held(start.yaw_rad),
            1 => Stance::Turning,
            goal => Stance::Held(goal_yaws[goal - 2]),
        };
        let sources: Vec<(State, f64)> = self
            .joins(&start_grid, Stance::Held(start.yaw_rad), from, true)
            .into_iter()
            .map(|(cell, cost)| (State { layer: 0, cell }, cost))
            .collect();
        let tree = cheapest(&layers, &self.costs, &sources);
        goals
            .iter()
            .zip(arrivals)
            .map(|(goal, arrival)| {
                let layer = if same_heading(goal.yaw_rad) {
                    0
                } else {
                    2 + goal_yaws
                        .iter()
                        .position(|&yaw| wrap_angle(yaw - goal.yaw_rad).abs() < 1e-9)?
                };
                let grid = layer_grid(layer);
                let (cell, _) = self
                    .joins(grid, layer_stance(layer), goal.position(), false)
                    .into_iter()
                    .map(|(cell, cost)| (cell, cost + tree.cost(State { layer, cell })))
                    .filter(|(_, total)| total.is_finite())
                    .min_by(|a, b| a.1.total_cmp(&b.1))?;
                let states = tree.path_to(State { layer, cell });
                let ends = Ends {
                    start: start.position(),
                    from,
                    to: goal.position(),
                    end: arrival.position(),
                };
                self.smoothed(&states, ends, (&layer_grid, &layer_stance), keep_off_m)
            })
            .collect()
    }

    /// The cells of `grid` near `point` that a straight line joins to it with room for the
    /// robot standing `stance` (from the point to the cell if `outward`, else back), each
    /// with the line's cost.
    fn joins(
        &self,
        grid: &ClearanceGrid,
        stance: Stance,
        point: Vec2,
        outward: bool,
    ) -> Vec<(usize, f64)> {
        let yaw = stance.held_yaw_rad();
        grid.cells_near(point, JOIN_RADIUS_CELLS)
            .into_iter()
            .filter(|&cell| grid.clearance_m(cell) > 0.0)
            .filter_map(|cell| {
                let centre = grid.centre(cell);
                let (a, b) = if outward {
                    (point, centre)
                } else {
                    (centre, point)
                };
                let room = self.space.segment_clearance_m(a, b, yaw, self.costs.cap_m);
                (FreeSpace::segment_guaranteed_m(room) > 0.0)
                    .then(|| (cell, a.distance(b) * self.costs.weight(room)))
            })
            .collect()
    }

    /// The search's states from `ends.from` to `ends.to` as a taut path ([`smooth`]),
    /// with the straight lead-out before it and lead-in after it.
    fn smoothed<'g>(
        &self,
        states: &[State],
        ends: Ends,
        (layer_grid, layer_stance): (
            &dyn Fn(usize) -> &'g ClearanceGrid,
            &dyn Fn(usize) -> Stance,
        ),
        keep_off_m: (f64, f64),
    ) -> Option<FreePath> {
        let cap_m = self.costs.cap_m;
        let mut stretches: Vec<Stretch<'_>> = Vec::new();
        for state in states {
            let (grid, stance) = (layer_grid(state.layer), layer_stance(state.layer));
            let point = grid.centre(state.cell);
            match stretches.last_mut() {
                Some(stretch) if stretch.stance == stance => {
                    stretch.points.push(point);
                    stretch.clearance_m.push(grid.clearance_m(state.cell));
                }
                _ => {
                    // A new stance begins where the last one ended (the same cell).
                    stretches.push(Stretch {
                        stance,
                        grid,
                        points: vec![point],
                        clearance_m: vec![grid.clearance_m(state.cell)],
                    });
                }
            }
        }
        let first = stretches.first_mut()?;
        let room = first.stance.clearance_m(&self.space, ends.from, cap_m);
        first.points.insert(0, ends.from);
        first.clearance_m.insert(0, room);
        let last = stretches.last_mut()?;
        let room = last.stance.clearance_m(&self.space, ends.to, cap_m);
        last.points.push(ends.to);
        last.clearance_m.push(room);
        let mut taut = Vec::with_capacity(stretches.len());
        for stretch in &stretches {
            taut.push((stretch.stance, pull_taut(stretch, &self.space, cap_m)?));
        }
        // The lead-out and lead-in, each with the step onto the path merged into one
        // corner where that keeps the room.
        if let Some((stance, points)) = taut.first_mut()
            && ends.from != ends.start
        {
            points.insert(0, ends.start);
            merge_step(points, &self.space, *stance, cap_m);
        }
        if let Some((stance, points)) = taut.last_mut()
            && ends.to != ends.end
        {
            points.push(ends.end);
            points.reverse();
            merge_step(points, &self.space, *stance, cap_m);
            points.reverse();
        }
        let length: f64 = smooth::arc_lengths(
            &taut
                .iter()
                .flat_map(|(_, points)| points.iter().copied())
                .collect::<Vec<_>>(),
        )
        .last()
        .copied()
        .unwrap_or(0.0);
        let limits = (keep_off_m.0, (length - keep_off_m.1).max(keep_off_m.0));
        let leads = (ends.from != ends.start, ends.to != ends.end);
        let (points, turn_m) = join(&self.space, &taut, limits, leads, cap_m);
        Some(FreePath { points, turn_m })
    }
}
