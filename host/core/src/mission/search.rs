//! The search for a part that fell off the magnet while it was carried (issue 17).
//!
//! The robot knows only its pose estimate and its switch. While it carries, the mission keeps
//! the trail of its estimated poses with the switch closed ([`Trail`]); the part left the
//! magnet at the face of one of the last of them, and lies a few centimetres ahead of it,
//! about square to the robot as it was then (a part on the floor moves only where the robot
//! pushes it). So the search does not creep on from wherever the robot stopped (it may have
//! turned or strafed away from the part meanwhile): it stands until it has stopped, then
//! takes a few bounded *looks*, each like a docking approach:
//!
//! 1. line up: drive (holonomic, slowly) to a pose `regrip_backoff_m` behind the look's
//!    anchor, with the anchor's heading;
//! 2. creep straight on along that heading, up to `regrip_reach_m`, until the switch closes.
//!
//! The looks, in order: the anchor is the last pose at which the part was known held, then
//! the same line moved `regrip_sweep_m` to one side and to the other (the part lands up to
//! 2 cm off the centre line, and a robot turning away sweeps it sideways with a front
//! corner: first the side the robot was turning to), then earlier poses of the trail, each
//! whose part centre is `regrip_sweep_m` from the previous anchor's (a switch read late
//! ends the trail after the part left: a Mega that resets lets its part go at once, but the
//! core counts it silent only 60 ms later, and the switch read closed until then). At most
//! `regrip_looks` looks. (Once the Mega is back, its switch counts as open until it reports
//! it: the closed reading from before the reset had extended the trail to where the robot
//! coasted to, and the first looks from there met the part with the body.)
//!
//! When the switch closes the part is found, but the lever closes on a plate up to a few
//! centimetres beside the magnet's centre, and the magnet keeps that offset: a part held
//! 2.5 cm aside meets a divider at the drop, and the carry pushes there until it gives up.
//! So the robot looks with the magnet off, and *centres* before it grips: the part standing
//! before the face, it strafes to its left until the switch opens (the plate's edge), then
//! to its right until it opens again, and grips midway between the two, where it then
//! stands for the grip to settle. (A switch that closes while the robot still stands after
//! the loss, the magnet on, is a part the face carried on: the magnet takes it up there.)
//! Both edges are read with the same estimate lag and the same speed, in opposite
//! directions, so the lag cancels in the midpoint. The robot holds its line a centimetre
//! on into the plate meanwhile, so the lever stays on it: less where that would bring the
//! body within [`LOOK_CLEARANCE_M`] of a divider (a part that fell back into its slot's
//! mouth is found with the face a few millimetres off the dividers' tips). A strafe that
//! finds no edge (blocked, or out of its span) grips where the switch first closed, as
//! without centring; a grip that does not hold (the part moved meanwhile) goes on to the
//! next look.
//!
//! Collisions: every look starts a few centimetres from poses the robot stood at moments
//! before with its heading (`regrip_backoff_m` behind, `regrip_sweep_m` to a side), and the
//! creep covers where the part was carried, so the search drives only where the robot and
//! its part have just been, give or take those few centimetres; it never plans across the
//! floor. Those centimetres matter where the routes pass close to the field's solids: under
//! a machine block the robot's back runs 2 cm from the dividers. So a look whose start would
//! put the bare body within [`LOOK_CLEARANCE_M`] of a wall, divider or pole starts further on
//! along its line ([`FreeSpace::first_free_ahead_m`]), and creeps to where it would have;
//! with no free start short of its anchor it is not taken. The way to a look's start and the
//! centring's strafes are checked too, for the gap they keep ([`MANOEUVRE_CLEARANCE_M`], or
//! the least at their ends where that is less): a line-up whose straight way would come
//! closer goes by a corner, across to the look's line first or along to its start first
//! (a look with no way there that misses every solid is not taken), and a strafe ends
//! where it would come closer, as one that finds no edge. The creep itself is not cut
//! short of the walls: a part that fell back into its slot lies where only a creep to the
//! dividers' tips reaches it (cut 3 mm short, on the tuning seeds 71–90, it gave up a part
//! after a Mega reset and saved no further collisions: the true body stands a few
//! millimetres off the believed one).

use std::collections::VecDeque;

use super::MissionConfig;
use crate::config::RobotConfig;
use crate::field::Field;
#[cfg(doc)]
use crate::field::PICK_STANDOFF_M;
use crate::field::geometry::{Pose2, Vec2, wrap_angle};
use crate::kinematics::BodyTwist;
use crate::planning::shortcuts::{Footprint, FreeSpace};

/// Most looks one search may take (the upper bound of `regrip_looks`).
pub const MAX_LOOKS: usize = 8;

/// The least gap between the body and a wall, divider or pole where a look starts, m.
/// 0.003: under the pick pose's 5 mm off the divider tips ([`PICK_STANDOFF_M`]), so a look
/// backed off from a pick pose starts where it was meant to.
pub const LOOK_CLEARANCE_M: f64 = 0.003;

/// Where a search's looks may start: clear of `field`'s walls, dividers and poles, for the
/// bare body of `robot` (the magnet is off while looking) grown by [`LOOK_CLEARANCE_M`].
pub fn search_floor(field: &Field, robot: &RobotConfig) -> FreeSpace {
    FreeSpace::new(
        field,
        &[],
        Footprint::of_robot(robot, false),
        LOOK_CLEARANCE_M,
    )
}

/// How long the trail of carried poses reaches back, s: 1.0, the Mega's 0.5 s reset, the
/// 0.1 s debounce after it, its coast to a stop, and a margin.
const TRAIL_S: f64 = 1.0;

/// Top speed while lining up for a look, m/s. 0.15: twice the creep; the line-up spans a
/// few centimetres to a decimetre, so it takes about a second.
const LINE_UP_SPEED_M_S: f64 = 0.15;
/// Top turn rate while lining up, rad/s. 1.0: the front face (0.2 m out) then moves at
/// 0.2 m/s, near the line-up speed.
const LINE_UP_TURN_RAD_S: f64 = 1.0;
/// Gain of the line-up and of the creep's hold on its line, 1/s. 2.0: a time constant of
/// 0.5 s, five times the estimate's 0.1 s lag, so the loop does not ring.
const GAIN_PER_S: f64 = 2.0;
/// The robot is lined up within this distance of the look's start, m: 1 cm, well inside the
/// switch's ±2.5 cm across the plate.
const LINE_UP_TOLERANCE_M: f64 = 0.01;
/// The robot is lined up within this heading error, rad: 2°, well inside the switch's 15°.
const LINE_UP_TOLERANCE_RAD: f64 = 0.035;
/// A creep that has not got [`STALL_PROGRESS_M`] further for this long is blocked (a wall,
/// a divider, a part wedged against one) and the look ends, s. 0.6: the creep covers 5 cm
/// in that time, and the estimate lags the wheels by 0.1 s.
const STALL_S: f64 = 0.6;
/// Progress that counts against [`STALL_S`], m: 5 mm, above the estimate's jitter.
const STALL_PROGRESS_M: f64 = 0.005;
/// Strafe speed while centring on the plate, m/s. 0.04: the switch is read every 20 ms, so
/// an edge is placed within 0.8 mm, and the estimate's 0.1 s lag (4 mm) cancels in the
/// midpoint of two edges crossed at the same speed.
const CENTRE_SPEED_M_S: f64 = 0.04;
/// Farthest a centring strafe goes past where it began looking for an edge, m. 0.09: more
/// than the 80 mm plate's width, so a lever anywhere on the plate has left it by then.
const CENTRE_SPAN_M: f64 = 0.09;
/// The gap to the field's walls, dividers and poles that the line-up and the centring's
/// strafes keep where they can, m: 0.01, about twice the estimate's error some tenths of a
/// second after a hold (3–6 mm, traced in the fault bench's Mega resets and replugs). A
/// move that starts or ends closer keeps the least gap of its ends instead (a part that fell
/// back into its slot's mouth is found with the face 5 mm off the dividers' tips).
const MANOEUVRE_CLEARANCE_M: f64 = 0.01;
/// Samples along a line-up or a strafe whose clearance is checked are this far apart at most,
/// m: 2 mm, under the clearance's slack for a pose between two samples.
const MANOEUVRE_STEP_M: f64 = 0.002;
/// Slack in comparing a move's least gap with that of its ends, m: 0.5 mm, for the sampling.
const MANOEUVRE_SLACK_M: f64 = 0.0005;
/// Within this distance of a line-up's corner the robot turns on to the look's start, m:
/// 3 mm, so the body does not cut the corner the route was chosen for.
const CORNER_TOLERANCE_M: f64 = 0.003;
/// Centred within this distance of the midpoint, m: 3 mm.
const CENTRE_TOLERANCE_M: f64 = 0.003;
/// How far ahead of where the switch closed the robot holds its line while centring, m.
/// 0.01: the creep stops with the plate about at the magnet's face, 15 mm beyond the body's
/// front face and only 5 mm short of the end of the lever's 20 mm reach; 1 cm on, the plate
/// is 5 mm from the face and 15 mm from the end of the reach. A robot
/// strafing on mecanum rollers drifts several millimetres along its heading that its
/// estimate does not see yet; drifting away, the lever would leave the plate (an edge that
/// is not one), drifting on, the face only pushes the part straight ahead.
const CENTRE_PRESS_M: f64 = 0.01;

/// The poses at which the robot last carried its part with the switch closed, oldest first,
/// over the last [`TRAIL_S`].
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Trail {
    poses: VecDeque<(u64, Pose2)>,
}

impl Trail {
    /// Forget the trail (a new carry begins).
    pub(super) fn clear(&mut self) {
        self.poses.clear();
    }

    /// The last pose at which the part was held, if any.
    pub(super) fn last(&self) -> Option<Pose2> {
        self.poses.back().map(|&(_, pose)| pose)
    }

    /// Every pose `held_us` later: the mission stood held that long (its clock stopped).
    pub(super) fn later(&mut self, held_us: u64) {
        for (t, _) in &mut self.poses {
            *t = t.saturating_add(held_us);
        }
    }

    /// The robot carried its part at `pose` at `now_us`, the switch closed.
    pub(super) fn push(&mut self, now_us: u64, pose: Pose2) {
        self.poses.push_back((now_us, pose));
        let horizon_us = (TRAIL_S * 1e6) as u64;
        while self
            .poses
            .front()
            .is_some_and(|&(t, _)| t + horizon_us < now_us)
        {
            self.poses.pop_front();
        }
    }
}

/// Where the search is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    /// Standing, magnet on, while the robot stops.
    Braking,
    /// Driving to the start of look `look`, for at most until `limit_us`, by way of the
    /// corner `via` first when the straight way is not clear ([`line_up_route`]).
    LiningUp { limit_us: u64, via: Option<Vec2> },
    /// Creeping along look `look`; the farthest it got along it so far, m, and when, µs.
    Creeping { best_m: f64, best_us: u64 },
    /// The switch closed with the robot at `origin`: magnet off, strafing along `origin`'s
    /// left (+y) until the switch opens at the plate's first edge, then to the right until
    /// it opens at the second; `first_edge_m`: the first edge across `origin`, m;
    /// `closed`: the switch read closed since the strafe began; at most until `limit_us`;
    /// the robot holds its line `press_m` on from `origin` ([`centre_press_m`]);
    /// `room_m`: how far it may strafe to the left and to the right ([`strafe_room_m`]).
    Centring {
        origin: Pose2,
        press_m: f64,
        room_m: [f64; 2],
        first_edge_m: Option<f64>,
        closed: bool,
        limit_us: u64,
    },
    /// Magnet off, strafing to `across_m` across `origin` (midway between the edges), for
    /// at most until `limit_us`, on the line `press_m` on from `origin`.
    ToMiddle {
        origin: Pose2,
        press_m: f64,
        across_m: f64,
        limit_us: u64,
    },
    /// Centred: magnet on, standing for the grip to settle.
    Holding,
}

/// How a search tick went.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Step {
    /// Still looking: command this twist.
    Searching(BodyTwist),
    /// The part is held again.
    Found,
    /// Every look is done and the part was not found, or it did not hold.
    Lost,
}

/// One look: a line-up, then a creep straight on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Look {
    /// Where the creep starts; it runs along this heading.
    pub(super) start: Pose2,
    /// How far the creep may go, m: `regrip_reach_m`, less what the start was moved on.
    pub(super) reach_m: f64,
}

impl Look {
    /// The look meant to start at `wanted` and creep `reach_m`, with its start clear of
    /// `floor`: the first free pose along its line, at most `backoff_m` on (where the
    /// wanted start's anchor is); it creeps to where it would have. `None` when no start up
    /// to there is free.
    fn clear_of(floor: &FreeSpace, wanted: Pose2, backoff_m: f64, reach_m: f64) -> Option<Self> {
        let moved_m = floor.first_free_ahead_m(wanted, backoff_m)?;
        Some(Self {
            start: wanted.compose(Pose2::new(moved_m, 0.0, 0.0)),
            reach_m: reach_m - moved_m,
        })
    }
}

/// The search: see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Search {
    /// The looks, at most [`MAX_LOOKS`], each starting where the body is clear of the field's
    /// solids.
    looks: Vec<Look>,
    /// The current look.
    look: usize,
    phase: Phase,
    /// When the phase began, µs.
    since_us: u64,
}

impl Search {
    /// A search that begins braking at `since_us`, the robot now at `pose`, for a part last
    /// known held along `trail`, its looks starting clear of `floor` ([`search_floor`]).
    pub(super) fn new(
        trail: &Trail,
        pose: Pose2,
        since_us: u64,
        config: &MissionConfig,
        floor: &FreeSpace,
    ) -> Self {
        let mut looks = Vec::with_capacity(MAX_LOOKS);
        let wanted = (config.regrip_looks as usize).clamp(1, MAX_LOOKS);
        let backoff = |anchor: Pose2, across_m: f64| {
            anchor.compose(Pose2::new(-config.regrip_backoff_m, across_m, 0.0))
        };
        let mut add = |start: Pose2| {
            let backoff_m = config.regrip_backoff_m;
            if looks.len() < wanted
                && let Some(look) = Look::clear_of(floor, start, backoff_m, config.regrip_reach_m)
            {
                looks.push(look);
            }
        };
        let anchor = trail.last().unwrap_or(pose);
        add(backoff(anchor, 0.0));
        let sweep = config.regrip_sweep_m;
        if sweep > 0.0 {
            // A robot turning to its left sweeps the part to the left with its right corner.
            let side = if wrap_angle(pose.yaw_rad - anchor.yaw_rad) >= 0.0 {
                1.0
            } else {
                -1.0
            };
            add(backoff(anchor, side * sweep));
            add(backoff(anchor, -side * sweep));
            let part_ahead_m = floor.footprint().part_ahead_m();
            let part = |p: Pose2| p.transform_point(Vec2::new(part_ahead_m, 0.0));
            let mut last = part(anchor);
            for &(_, earlier) in trail.poses.iter().rev() {
                if part(earlier).distance(last) >= sweep {
                    last = part(earlier);
                    add(backoff(earlier, 0.0));
                }
            }
        }
        Self {
            looks,
            look: 0,
            phase: Phase::Braking,
            since_us,
        }
    }

    /// A search for a part about to be let go on purpose at `pose`, right at the face
    /// (`mission::jam`): no braking (the magnet would take it up as it lies, off centre),
    /// straight to the first look. `None` when every look would start against a wall: then
    /// the part must not be let go.
    pub(super) fn reseat(
        trail: &Trail,
        pose: Pose2,
        now_us: u64,
        config: &MissionConfig,
        floor: &FreeSpace,
    ) -> Option<Self> {
        let mut search = Self::new(trail, pose, now_us, config, floor);
        match search.line_up(now_us, pose, floor) {
            Step::Lost => None,
            _ => Some(search),
        }
    }

    /// Every time of the search `held_us` later: the mission stood held that long (its clock
    /// stopped), so no phase's limit runs out meanwhile.
    pub(super) fn later(&mut self, held_us: u64) {
        let later = |t: &mut u64| *t = t.saturating_add(held_us);
        later(&mut self.since_us);
        match &mut self.phase {
            Phase::LiningUp { limit_us, .. }
            | Phase::Centring { limit_us, .. }
            | Phase::ToMiddle { limit_us, .. } => later(limit_us),
            Phase::Creeping { best_us, .. } => later(best_us),
            Phase::Braking | Phase::Holding => {}
        }
    }

    /// Whether the magnet is on: while standing (a part pushed along by the face is taken up
    /// as it was) and gripping; off while looking and centring, so the part is taken up only
    /// once the robot stands centred on its plate, and never let go on the way (a part let
    /// go between a slot's dividers drops into that slot).
    pub(super) fn magnet_on(&self) -> bool {
        matches!(self.phase, Phase::Braking | Phase::Holding)
    }

    /// The looks, in the order they are taken.
    #[cfg(test)]
    pub(super) fn looks(&self) -> &[Look] {
        &self.looks
    }

    /// One tick at `now_us` with the pose estimate and the switch.
    pub(super) fn tick(
        &mut self,
        now_us: u64,
        pose: Pose2,
        switch: bool,
        config: &MissionConfig,
        floor: &FreeSpace,
    ) -> Step {
        let stop = Step::Searching(BodyTwist::default());
        let elapsed_s = now_us.saturating_sub(self.since_us) as f64 * 1e-6;
        if self.phase == Phase::Holding {
            return if elapsed_s < config.grip_settle_s {
                stop
            } else if switch {
                Step::Found
            } else {
                // The part moved while the robot centred, or the centring went wrong: on
                // to the next look.
                self.next_look(now_us, pose, floor)
            };
        }
        match self.phase {
            Phase::Centring { .. } | Phase::ToMiddle { .. } => {
                return self.centre(now_us, pose, switch);
            }
            // Still standing: the face carried the part on, and the magnet took it up.
            Phase::Braking if switch => {
                self.enter(Phase::Holding, now_us);
                return stop;
            }
            _ if switch => {
                let limit_us = now_us + centre_limit_us(CENTRE_SPAN_M);
                let press_m = centre_press_m(floor, pose);
                let room_m = [1.0, -1.0].map(|side| strafe_room_m(floor, pose, press_m, side));
                self.enter(
                    Phase::Centring {
                        origin: pose,
                        press_m,
                        room_m,
                        first_edge_m: None,
                        closed: true,
                        limit_us,
                    },
                    now_us,
                );
                return stop;
            }
            _ => {}
        }
        match self.phase {
            Phase::Braking => {
                if elapsed_s < config.regrip_brake_s {
                    stop
                } else {
                    // Lost when every look would start against a wall, or has no clear way
                    // to its start: nowhere safe to look.
                    self.line_up(now_us, pose, floor)
                }
            }
            Phase::LiningUp { limit_us, via } => {
                let start = self.looks[self.look].start;
                let target = via.unwrap_or(start.position());
                let error = target - pose.position();
                let yaw_error = wrap_angle(start.yaw_rad - pose.yaw_rad);
                if via.is_some() && error.norm() <= CORNER_TOLERANCE_M {
                    self.phase = Phase::LiningUp {
                        limit_us,
                        via: None,
                    };
                    return self.tick(now_us, pose, switch, config, floor);
                }
                let lined_up = via.is_none()
                    && error.norm() <= LINE_UP_TOLERANCE_M
                    && yaw_error.abs() <= LINE_UP_TOLERANCE_RAD;
                if lined_up || now_us >= limit_us {
                    let best_m = 0.0;
                    self.enter(
                        Phase::Creeping {
                            best_m,
                            best_us: now_us,
                        },
                        now_us,
                    );
                    return stop;
                }
                let velocity = clamp_norm(error * GAIN_PER_S, LINE_UP_SPEED_M_S);
                let omega = (GAIN_PER_S * yaw_error).clamp(-LINE_UP_TURN_RAD_S, LINE_UP_TURN_RAD_S);
                Step::Searching(body_twist(velocity, omega, pose.yaw_rad))
            }
            Phase::Creeping { best_m, best_us } => {
                let Look { start, reach_m } = self.looks[self.look];
                let along_unit = Vec2::from_angle(start.yaw_rad);
                let across_unit = Vec2::new(-along_unit.y, along_unit.x);
                let offset = pose.position() - start.position();
                let along = offset.dot(along_unit);
                let across = offset.dot(across_unit);
                let speed = config.regrip_speed_m_s.max(1e-3);
                // Twice the creep's time: the estimate lags the wheels.
                let limit_s = 0.5 + 2.0 * config.regrip_reach_m / speed;
                let (best_m, best_us) = if along >= best_m + STALL_PROGRESS_M {
                    (along, now_us)
                } else {
                    (best_m, best_us)
                };
                self.phase = Phase::Creeping { best_m, best_us };
                let stalled = now_us.saturating_sub(best_us) as f64 * 1e-6 > STALL_S;
                if along >= reach_m || elapsed_s > limit_s || stalled {
                    return self.next_look(now_us, pose, floor);
                }
                let hold = (-GAIN_PER_S * across).clamp(-speed, speed);
                let velocity = along_unit * speed + across_unit * hold;
                let yaw_error = wrap_angle(start.yaw_rad - pose.yaw_rad);
                let omega = (GAIN_PER_S * yaw_error).clamp(-LINE_UP_TURN_RAD_S, LINE_UP_TURN_RAD_S);
                Step::Searching(body_twist(velocity, omega, pose.yaw_rad))
            }
            Phase::Centring { .. } | Phase::ToMiddle { .. } | Phase::Holding => stop,
        }
    }

    /// One tick of the centring on the plate (the phases [`Phase::Centring`] and
    /// [`Phase::ToMiddle`]).
    fn centre(&mut self, now_us: u64, pose: Pose2, switch: bool) -> Step {
        let stop = Step::Searching(BodyTwist::default());
        match self.phase {
            Phase::Centring {
                origin,
                press_m,
                room_m: [left_m, right_m],
                first_edge_m,
                closed,
                limit_us,
            } => {
                let (along, across) = along_across(origin, pose);
                let closed = closed || switch;
                let middle = match first_edge_m {
                    None if closed && !switch => {
                        // The first edge: now strafe back across the plate to the other.
                        self.phase = Phase::Centring {
                            origin,
                            press_m,
                            room_m: [left_m, right_m],
                            first_edge_m: Some(across),
                            closed: false,
                            limit_us: now_us + centre_limit_us(across + CENTRE_SPAN_M),
                        };
                        return stop;
                    }
                    Some(first) if closed && !switch => Some(0.5 * (first + across)),
                    None if across >= CENTRE_SPAN_M.min(left_m) || now_us >= limit_us => Some(0.0),
                    Some(first)
                        if across <= (first - CENTRE_SPAN_M).max(-right_m)
                            || now_us >= limit_us =>
                    {
                        Some(0.0)
                    }
                    _ => None,
                };
                if let Some(across_m) = middle {
                    let travel_m = (across_m - across).abs();
                    let limit_us = now_us + centre_limit_us(travel_m);
                    self.enter(
                        Phase::ToMiddle {
                            origin,
                            press_m,
                            across_m,
                            limit_us,
                        },
                        now_us,
                    );
                    return stop;
                }
                self.phase = Phase::Centring {
                    origin,
                    press_m,
                    room_m: [left_m, right_m],
                    first_edge_m,
                    closed,
                    limit_us,
                };
                let side = if first_edge_m.is_none() { 1.0 } else { -1.0 };
                let twist = hold_line(origin, pose, along - press_m, side * CENTRE_SPEED_M_S);
                Step::Searching(twist)
            }
            Phase::ToMiddle {
                origin,
                press_m,
                across_m,
                limit_us,
            } => {
                let (along, across) = along_across(origin, pose);
                let error = across_m - across;
                if error.abs() <= CENTRE_TOLERANCE_M || now_us >= limit_us {
                    self.enter(Phase::Holding, now_us);
                    return stop;
                }
                let speed = (GAIN_PER_S * error).clamp(-CENTRE_SPEED_M_S, CENTRE_SPEED_M_S);
                Step::Searching(hold_line(origin, pose, along - press_m, speed))
            }
            _ => stop,
        }
    }

    /// On to the next look from `pose`, or [`Step::Lost`] after the last.
    fn next_look(&mut self, now_us: u64, pose: Pose2, floor: &FreeSpace) -> Step {
        self.look += 1;
        self.line_up(now_us, pose, floor)
    }

    fn enter(&mut self, phase: Phase, now_us: u64) {
        self.phase = phase;
        self.since_us = now_us;
    }

    /// Begin lining up from `pose` for the current look, or the first later one with a
    /// clear way to its start ([`line_up_route`]), with a time limit of three times what the
    /// line-up takes at its top speeds, and half a second; [`Step::Lost`] when none is left.
    fn line_up(&mut self, now_us: u64, pose: Pose2, floor: &FreeSpace) -> Step {
        while let Some(look) = self.looks.get(self.look) {
            let target = look.start;
            if let Some(via) = line_up_route(floor, pose, target) {
                let path_m = via.map_or(target.position().distance(pose.position()), |v| {
                    v.distance(pose.position()) + v.distance(target.position())
                });
                let travel_s = path_m / LINE_UP_SPEED_M_S
                    + wrap_angle(target.yaw_rad - pose.yaw_rad).abs() / LINE_UP_TURN_RAD_S;
                let limit_us = now_us + ((0.5 + 3.0 * travel_s) * 1e6) as u64;
                self.enter(Phase::LiningUp { limit_us, via }, now_us);
                return Step::Searching(BodyTwist::default());
            }
            self.look += 1;
        }
        Step::Lost
    }
}

/// How far on from `origin` (where the switch closed) the robot holds its line while it
/// centres, m: [`CENTRE_PRESS_M`], or less where the body would come within `floor`'s margin
/// of a wall, divider or pole (a part that fell back into its slot is found with the face near
/// the dividers' tips: pressed on, the strafe met a divider's side). Checked on `origin`'s
/// line and at the far ends of the strafes, each where the body stands clear to begin with:
/// a body already within the margin (a part found against a drop's dividers) presses on as
/// before, since holding back there lifted the lever off the plate.
fn centre_press_m(floor: &FreeSpace, origin: Pose2) -> f64 {
    if !floor.pose_is_free(origin) {
        return CENTRE_PRESS_M;
    }
    [-CENTRE_SPAN_M, 0.0, CENTRE_SPAN_M]
        .into_iter()
        .map(|across_m| origin.compose(Pose2::new(0.0, across_m, 0.0)))
        .filter(|&start| floor.pose_is_free(start))
        .map(|start| floor.free_ahead_m(start, CENTRE_PRESS_M, floor.margin_m()))
        .fold(CENTRE_PRESS_M, f64::min)
}

/// The time limit of a centring strafe over `span_m`: twice its time at
/// [`CENTRE_SPEED_M_S`], and half a second, µs.
fn centre_limit_us(span_m: f64) -> u64 {
    ((0.5 + 2.0 * span_m.abs() / CENTRE_SPEED_M_S) * 1e6) as u64
}

/// How a line-up from `pose` drives to `start`: straight (`Some(None)`), or by way of a
/// corner (`Some(Some(corner))`), across to the start's line first or along to its depth
/// first, whichever keeps [`MANOEUVRE_CLEARANCE_M`] from the field's solids or, where an end
/// stands closer, the least gap of its ends; failing that the way with the widest gap;
/// `None` when every way runs into one. Only the start of a look used to be checked: the
/// straight way from a pose beneath machine A, its back 8 mm above a divider's tip, to a
/// start 3 cm behind and 5 cm aside swept the body's corner across the tip (fault bench,
/// Mega reset, round 1 seed 105).
fn line_up_route(floor: &FreeSpace, pose: Pose2, start: Pose2) -> Option<Option<Vec2>> {
    let cap_m = MANOEUVRE_CLEARANCE_M;
    let ends_m = floor
        .pose_clearance_m(pose, cap_m)
        .min(floor.pose_clearance_m(start, cap_m));
    let offset = start.relative(pose);
    let corners = [
        start.compose(Pose2::new(offset.x, 0.0, 0.0)).position(),
        start.compose(Pose2::new(0.0, offset.y, 0.0)).position(),
    ];
    let ways = std::iter::once(None).chain(corners.map(Some));
    let mut best: Option<(f64, Option<Vec2>)> = None;
    for via in ways {
        let gap_m = match via {
            None => move_clearance_m(floor, pose, start, cap_m),
            Some(corner) => {
                let turned = Pose2::new(corner.x, corner.y, start.yaw_rad);
                move_clearance_m(floor, pose, turned, cap_m)
                    .min(move_clearance_m(floor, turned, start, cap_m))
            }
        };
        if gap_m >= ends_m - MANOEUVRE_SLACK_M {
            return Some(via);
        }
        if best.is_none_or(|(widest_m, _)| gap_m > widest_m) {
            best = Some((gap_m, via));
        }
    }
    best.filter(|&(gap_m, _)| gap_m > 0.0).map(|(_, via)| via)
}

/// The least gap to `floor`'s solids of the body moving straight from `from` to `to`,
/// turning evenly on the way (as the line-up's equal gains on position and heading do), m,
/// at most `cap_m`: 0 where it touches one.
fn move_clearance_m(floor: &FreeSpace, from: Pose2, to: Pose2, cap_m: f64) -> f64 {
    let turn = wrap_angle(to.yaw_rad - from.yaw_rad);
    // The front corners move 0.2 m per radian of turn.
    let length_m = from.position().distance(to.position()) + 0.2 * turn.abs();
    let steps = (length_m / MANOEUVRE_STEP_M).ceil().max(1.0) as usize;
    let mut least = cap_m;
    for k in 0..=steps {
        let t = k as f64 / steps as f64;
        let p = from.position() + (to.position() - from.position()) * t;
        least =
            least.min(floor.pose_clearance_m(Pose2::new(p.x, p.y, from.yaw_rad + turn * t), least));
        if least <= 0.0 {
            break;
        }
    }
    least
}

/// How far the centring may strafe from `origin` to its left (`side` 1) or right (−1), m:
/// up to [`CENTRE_SPAN_M`], and no closer to `floor`'s solids than [`MANOEUVRE_CLEARANCE_M`]
/// or than the body stands where the strafe begins, on `origin`'s line and on the line
/// `press_m` on (the robot moves from one to the other as it strafes). Before, only the
/// press was kept off the walls: a strafe to find a plate's edge beside machine B swept the
/// body's back corner onto a divider's tip (fault bench, Mega replug, round 1 seed 68).
fn strafe_room_m(floor: &FreeSpace, origin: Pose2, press_m: f64, side: f64) -> f64 {
    let cap_m = MANOEUVRE_CLEARANCE_M;
    let gap_m = |across_m: f64| {
        [0.0, press_m]
            .map(|along_m| {
                let pose = origin.compose(Pose2::new(along_m, side * across_m, 0.0));
                floor.pose_clearance_m(pose, cap_m)
            })
            .into_iter()
            .fold(cap_m, f64::min)
    };
    let keep_m = gap_m(0.0) - MANOEUVRE_SLACK_M;
    let steps = (CENTRE_SPAN_M / MANOEUVRE_STEP_M).ceil() as usize;
    (1..=steps)
        .map(|k| (k as f64 * MANOEUVRE_STEP_M).min(CENTRE_SPAN_M))
        .take_while(|&d| gap_m(d) >= keep_m)
        .last()
        .unwrap_or(0.0)
}

/// Where `pose` is from `origin`: along its heading and to its left, m.
fn along_across(origin: Pose2, pose: Pose2) -> (f64, f64) {
    let along_unit = Vec2::from_angle(origin.yaw_rad);
    let across_unit = Vec2::new(-along_unit.y, along_unit.x);
    let offset = pose.position() - origin.position();
    (offset.dot(along_unit), offset.dot(across_unit))
}

/// Strafe along `origin`'s left at `speed_m_s` (negative: to the right), holding a line
/// square to `origin`'s heading, and that heading; the robot is `along_m` ahead of the
/// line.
fn hold_line(origin: Pose2, pose: Pose2, along_m: f64, speed_m_s: f64) -> BodyTwist {
    let along_unit = Vec2::from_angle(origin.yaw_rad);
    let across_unit = Vec2::new(-along_unit.y, along_unit.x);
    let hold = (-GAIN_PER_S * along_m).clamp(-CENTRE_SPEED_M_S, CENTRE_SPEED_M_S);
    let velocity = across_unit * speed_m_s + along_unit * hold;
    let yaw_error = wrap_angle(origin.yaw_rad - pose.yaw_rad);
    let omega = (GAIN_PER_S * yaw_error).clamp(-LINE_UP_TURN_RAD_S, LINE_UP_TURN_RAD_S);
    body_twist(velocity, omega, pose.yaw_rad)
}

/// `v` shortened to at most `max` long.
fn clamp_norm(v: Vec2, max: f64) -> Vec2 {
    let norm = v.norm();
    if norm > max { v * (max / norm) } else { v }
}

/// The body twist for a world-frame velocity and a turn rate, the robot heading `yaw_rad`.
fn body_twist(world: Vec2, omega_rad_s: f64, yaw_rad: f64) -> BodyTwist {
    let body = world.rotated(-yaw_rad);
    BodyTwist::new(body.x, body.y, omega_rad_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The competition floor for a 30 × 30 cm body.
    fn floor() -> FreeSpace {
        search_floor(&Field::competition(), &RobotConfig::default())
    }

    /// Where [`straight_trail`] begins, heading up the field's left side: the trail, its
    /// looks and their creeps keep clear of everything there.
    const OPEN: Pose2 = Pose2::new(-0.65, -0.25, std::f64::consts::FRAC_PI_2);

    /// A trail of `n` poses 1 cm apart straight on from [`OPEN`], one per 20 ms tick.
    fn straight_trail(n: u32) -> Trail {
        let mut trail = Trail::default();
        for k in 0..n {
            let pose = OPEN.compose(Pose2::new(f64::from(k) * 0.01, 0.0, 0.0));
            trail.push(u64::from(k) * 20_000, pose);
        }
        trail
    }

    #[test]
    fn the_looks_start_behind_the_last_held_pose_then_beside_it_then_back_along_the_trail() {
        let config = MissionConfig::default();
        let trail = straight_trail(20);
        // Stopped turned to the right of the last held heading: the right side comes first.
        let stopped = OPEN.compose(Pose2::new(0.2, 0.0, -0.1));
        let search = Search::new(&trail, stopped, 400_000, &config, &floor());
        // In the trail's frame.
        let looks: Vec<Pose2> = search
            .looks()
            .iter()
            .map(|l| OPEN.relative(l.start))
            .collect();
        assert_eq!(looks.len(), config.regrip_looks as usize);
        let near = |a: Pose2, x: f64, y: f64| {
            (a.x - x).abs() < 1e-9 && (a.y - y).abs() < 1e-9 && a.yaw_rad.abs() < 1e-12
        };
        let back = config.regrip_backoff_m;
        let sweep = config.regrip_sweep_m;
        assert!(near(looks[0], 0.19 - back, 0.0), "{looks:?}");
        assert!(near(looks[1], 0.19 - back, -sweep), "{looks:?}");
        assert!(near(looks[2], 0.19 - back, sweep), "{looks:?}");
        // Then earlier poses of the trail, each holding its part at least a sweep (3 cm)
        // behind the previous look's, and within a trail step (1 cm) of that.
        for (later, earlier) in [(looks[0], looks[3]), (looks[3], looks[4])] {
            let gap = later.x - earlier.x;
            assert!(gap > sweep - 1e-9 && gap < sweep + 0.01 + 1e-9, "{looks:?}");
            assert!(near(earlier, earlier.x, 0.0), "{looks:?}");
        }
    }

    #[test]
    fn in_open_floor_every_look_creeps_its_whole_reach() {
        let config = MissionConfig::default();
        let search = Search::new(&straight_trail(20), OPEN, 0, &config, &floor());
        assert_eq!(search.looks().len(), config.regrip_looks as usize);
        for look in search.looks() {
            assert_eq!(look.reach_m, config.regrip_reach_m, "{look:?}");
        }
    }

    /// The bug this guards: a part that fell as the robot drove beneath a machine block (its
    /// back 2 cm from the dividers) was looked for from 3 cm behind where it was held, and
    /// the line-up pressed the robot's back onto a divider (machine B's, in the fault bench).
    #[test]
    fn a_look_that_would_start_in_a_divider_starts_further_on() {
        let config = MissionConfig::default();
        // Beneath machine A, heading down the field (−y), the back 2 cm below its lowest
        // divider (y = −0.235).
        let held = Pose2::new(-0.35, -0.235 - 0.02 - 0.15, -std::f64::consts::FRAC_PI_2);
        let mut trail = Trail::default();
        trail.push(0, held);
        let search = Search::new(&trail, held, 20_000, &config, &floor());
        let first = search.looks()[0];
        assert!(floor().pose_is_free(first.start), "{first:?}");
        // Started 1 cm behind the held pose rather than 3 (the 2 cm gap less the
        // clearance, within a step), and creeps its whole reach from where it would have.
        let behind_m = first.start.position().distance(held.position());
        assert!(
            (behind_m - (0.02 - LOOK_CLEARANCE_M)).abs() <= 0.001,
            "{first:?}"
        );
        let from_wanted_m = config.regrip_backoff_m - behind_m;
        assert!((first.reach_m + from_wanted_m - config.regrip_reach_m).abs() < 1e-9);
    }

    /// Ticks `search` from `pose` until it ends (at most 20 s), the body moving exactly as
    /// commanded, the switch closed while the lever (on the body's centre line) is within
    /// the 80 mm plate centred at `plate`; the last step, the last pose and the least gap
    /// to `floor`'s solids on the way.
    fn run(
        search: &mut Search,
        mut pose: Pose2,
        plate: Pose2,
        floor: &FreeSpace,
    ) -> (Step, Pose2, f64) {
        let config = MissionConfig::default();
        let dt_s = 0.02;
        let mut least_gap_m = f64::INFINITY;
        for k in 0..1000u64 {
            least_gap_m = least_gap_m.min(floor.pose_clearance_m(pose, 1.0));
            let lever = plate.relative(pose);
            let switch = lever.x >= -0.005 && lever.y.abs() <= 0.04;
            match search.tick(k * 20_000, pose, switch, &config, floor) {
                Step::Searching(twist) => {
                    let step = Pose2::new(
                        twist.vx_m_s * dt_s,
                        twist.vy_m_s * dt_s,
                        twist.omega_rad_s * dt_s,
                    );
                    pose = pose.compose(step);
                }
                done => return (done, pose, least_gap_m),
            }
        }
        (Step::Searching(BodyTwist::default()), pose, least_gap_m)
    }

    /// The bug this guards: a part that fell off as the robot left incoming slot 4 lay back
    /// in the slot's mouth, and the creep found it 4 mm short of the pick pose (5 mm off the
    /// dividers' tips). Centring pressed 1 cm on from there, 1 mm past the tips, and the
    /// strafe met a divider's side (fault bench, part slip, round 1 seed 62).
    #[test]
    fn centring_on_a_part_in_its_slot_s_mouth_keeps_the_body_off_the_dividers() {
        let config = MissionConfig::default();
        let field = Field::competition();
        let pick = field.incoming_slot(3).expect("incoming slot 4").pick_pose;
        let found = pick.compose(Pose2::new(-0.004, 0.0, 0.0));
        let mut trail = Trail::default();
        trail.push(0, pick.compose(Pose2::new(-0.06, 0.0, 0.0)));
        let floor = floor();
        let mut search = Search::new(&trail, found, 0, &config, &floor);
        // The switch closes while the robot creeps: centring begins where it stands.
        search.phase = Phase::Creeping {
            best_m: 0.0,
            best_us: 0,
        };
        let plate_centre = found.compose(Pose2::new(0.0, 0.012, 0.0));
        let (step, pose, least_gap_m) = run(&mut search, found, plate_centre, &floor);
        let centred = step == Step::Found;
        assert!(least_gap_m >= LOOK_CLEARANCE_M, "{least_gap_m} {search:?}");
        assert!(centred, "{search:?}");
        // Gripped midway between the plate's edges.
        assert!(plate_centre.relative(pose).y.abs() < 0.005, "{pose:?}");
        // In open floor the press stays 1 cm.
        assert_eq!(centre_press_m(&floor, OPEN), CENTRE_PRESS_M);
    }

    /// The bug this guards (fault bench, Mega reset, round 1 seed 105): the hold let the
    /// part go beneath machine A as the robot strafed along the incoming row, its back 8 mm
    /// above the tip of the machine's top divider, and it coasted on 5 cm. The straight
    /// line-up to the first look's start, 3 cm behind and 5 cm back along the row, swept
    /// the body's back corner across the divider's tip; the line-up now goes along the row
    /// first, then back.
    #[test]
    fn a_line_up_whose_straight_way_crosses_a_divider_goes_round_it() {
        let config = MissionConfig::default();
        let floor = floor();
        let up = std::f64::consts::FRAC_PI_2;
        // The back 8 mm above machine A's top divider (y = 0.085).
        let held = Pose2::new(-0.598, 0.085 + 0.008 + 0.15, up);
        let coasted = Pose2::new(-0.548, held.y, up);
        let mut trail = Trail::default();
        trail.push(0, held);
        let mut search = Search::new(&trail, coasted, 0, &config, &floor);
        let start = search.looks()[0].start;
        assert!(
            move_clearance_m(&floor, coasted, start, 1.0) <= 0.0,
            "the straight way must cross the divider for this test to guard anything"
        );
        let (step, pose, least_gap_m) = run(&mut search, coasted, held, &floor);
        assert_eq!(step, Step::Found, "{search:?}");
        // Gripped centred on the plate.
        assert!(held.relative(pose).y.abs() < 0.005, "{pose:?}");
        // No closer than the body stood when it stopped.
        let stood_m = floor.pose_clearance_m(coasted, 1.0);
        assert!(
            least_gap_m >= stood_m - MANOEUVRE_SLACK_M,
            "{least_gap_m} < {stood_m}"
        );
    }

    /// The bug this guards (fault bench, Mega replug, round 1 seed 68): a part found before
    /// the face beside machine B, far to the lever's right, so that the strafe to the plate's
    /// left edge runs long: it brought the believed body within 3 mm of the machine's lower
    /// divider, and the true body, 3 mm off it, onto its tip. It now ends where the gap is
    /// down to 1 cm.
    #[test]
    fn a_centring_strafe_stops_short_of_a_divider() {
        let config = MissionConfig::default();
        let floor = floor();
        let found = Pose2::new(0.046, -0.127, (-118.7_f64).to_radians());
        let mut trail = Trail::default();
        trail.push(0, found);
        let mut search = Search::new(&trail, found, 0, &config, &floor);
        search.phase = Phase::Creeping {
            best_m: 0.0,
            best_us: 0,
        };
        // The lever 3.5 mm inside the plate's right edge: its left edge is 7.6 cm away.
        let plate = found.compose(Pose2::new(0.0, 0.0365, 0.0));
        let stood_m = floor.pose_clearance_m(found, 1.0);
        assert!(stood_m > MANOEUVRE_CLEARANCE_M, "{stood_m}");
        let left_edge = found.compose(Pose2::new(CENTRE_PRESS_M, 0.0765, 0.0));
        assert!(
            floor.pose_clearance_m(left_edge, 1.0) < 0.005,
            "the strafe to the left edge must come within the estimate's error of the divider \
             for this test to guard anything"
        );
        let (step, _, least_gap_m) = run(&mut search, found, plate, &floor);
        assert_eq!(step, Step::Found, "{search:?}");
        assert!(
            least_gap_m >= MANOEUVRE_CLEARANCE_M - MANOEUVRE_SLACK_M,
            "{least_gap_m}"
        );
    }

    #[test]
    fn with_every_look_against_a_wall_the_part_is_lost_after_braking() {
        let config = MissionConfig::default();
        // Inside the incoming warehouse's back wall: no look starts clear.
        let wall = Pose2::new(-0.395, 0.50, std::f64::consts::FRAC_PI_2);
        let mut trail = Trail::default();
        trail.push(0, wall);
        let mut search = Search::new(&trail, wall, 0, &config, &floor());
        assert!(search.looks().is_empty());
        let braking = search.tick(100_000, wall, false, &config, &floor());
        assert_eq!(braking, Step::Searching(BodyTwist::default()));
        let after_us = (config.regrip_brake_s * 1e6) as u64 + 1;
        assert_eq!(
            search.tick(after_us, wall, false, &config, &floor()),
            Step::Lost
        );
    }

    #[test]
    fn the_trail_keeps_the_last_second() {
        let trail = straight_trail(100);
        let oldest = trail.poses.front().map(|&(t, _)| t);
        assert_eq!(oldest, Some(99 * 20_000 - 1_000_000));
    }

    #[test]
    fn without_a_sweep_there_is_one_look() {
        let config = MissionConfig {
            regrip_sweep_m: 0.0,
            ..MissionConfig::default()
        };
        let search = Search::new(&straight_trail(20), OPEN, 0, &config, &floor());
        assert_eq!(search.looks().len(), 1);
    }
}
