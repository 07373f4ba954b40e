//! The competition stack's wiring: the task planner as the mission's [`ActionSource`], and
//! the route planner with a path follower as its [`Navigator`].
//!
//! [`TaskActions`] keeps what the robot knows about the parts (a [`State`] of the planner),
//! asks its [`Policy`] for a plan whenever the mission wants an action (re-planning from the
//! known state after every action, competition.md §6), and updates the state with the
//! outcome: a placed part moves (and is turned by the machine it went to); a part whose
//! action failed is given up, so the mission carries on with the others.

use crate::config::Config;
use crate::control::follower::{Follower, PathFollower, Status};
use crate::control::original::{OriginalFollower, OriginalParams};
use crate::control::route::{ORIGINAL_APPROACH_M, plan_original_route, plan_route};
use crate::field::Field;
use crate::field::geometry::{Pose2, Vec2};
use crate::field::waypoints::WaypointId;
use crate::kinematics::BodyTwist;
use crate::mission::{Action, ActionSource, Arrival, Navigator};
use crate::planning::graph::RoadMap;
use crate::planning::shortcuts::{Footprint, FreeSpace};
use crate::planning::tasks::{self, Model, Place, Policy, State};

/// The task planner behind the mission's interface.
pub struct TaskActions {
    field: Field,
    model: Model,
    policy: Box<dyn Policy>,
    state: State,
    pending: Option<tasks::Action>,
    /// Parts given up after a failed action, by their index in the initial state.
    abandoned: usize,
}

impl std::fmt::Debug for TaskActions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TaskActions")
            .field("policy", &self.policy.name())
            .field("state", &self.state)
            .field("pending", &self.pending)
            .finish()
    }
}

impl TaskActions {
    /// Plan with `policy` over `model`, starting from `state` (e.g. the part list).
    pub fn new(model: Model, policy: Box<dyn Policy>, state: State) -> Self {
        Self {
            field: Field::competition(),
            model,
            policy,
            state,
            pending: None,
            abandoned: 0,
        }
    }

    /// What the planner believes now.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Parts given up so far.
    pub fn abandoned(&self) -> usize {
        self.abandoned
    }

    fn waypoint(&self, location: tasks::Location) -> Option<WaypointId> {
        location.waypoint(&self.field)
    }
}

impl ActionSource for TaskActions {
    fn next_action(&mut self, now_us: u64) -> Option<Action> {
        self.state.time_s = self.state.time_s.max(now_us as f64 * 1e-6);
        let plan = self.policy.plan(&self.model, &self.state).ok()?;
        let next = plan.next()?;
        let pick = match next.from {
            Place::At(location) => self.waypoint(location)?,
            // The mission always drops what it picked in the same action.
            Place::Carried => return None,
        };
        let drop = self.waypoint(next.to)?;
        self.pending = Some(next);
        Some(Action { pick, drop })
    }

    fn action_done(&mut self, _action: Action, placed: bool, now_us: u64) {
        let Some(pending) = self.pending.take() else {
            return;
        };
        if placed && let Ok((next, _)) = self.model.apply(&self.state, pending) {
            self.state = next;
        } else {
            // The part could not be moved: give it up and plan the others.
            self.state.parts.remove(pending.part);
            self.abandoned += 1;
        }
        self.state.time_s = now_us as f64 * 1e-6;
    }
}

/// Which driving the robot does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DrivePreset {
    /// Our route planner and follower (`control::follower`).
    Ours,
    /// The original 5dpo follower on the original's routes (`control::original`).
    Original,
}

/// The original's final creep into a part: after its last segment it keeps its slow-zone
/// speed (0.4 / 2.512 m/s) until the switch closes (original-system.md §6.4). Bounded here
/// by [`ORIGINAL_CREEP_LIMIT_M`] so it never drives blind.
const ORIGINAL_CREEP_M_S: f64 = 0.4 / 2.512;
/// How far the original's creep may go before the approach counts as failed, m.
const ORIGINAL_CREEP_LIMIT_M: f64 = 0.08;

/// Plans a route to each slot and follows it.
pub struct RouteNavigator {
    config: Config,
    field: Field,
    map: RoadMap,
    preset: DrivePreset,
    follower: Box<dyn PathFollower>,
    dock: bool,
    failed: bool,
    last_goal: Option<Vec2>,
    creep_from: Option<Pose2>,
}

impl std::fmt::Debug for RouteNavigator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RouteNavigator")
            .field("preset", &self.preset)
            .field("dock", &self.dock)
            .field("failed", &self.failed)
            .finish()
    }
}

impl RouteNavigator {
    /// A navigator for the robot in `config` driving with `preset`.
    pub fn new(config: &Config, preset: DrivePreset) -> Self {
        let field = Field::competition();
        Self {
            map: RoadMap::new(field.waypoints().clone()),
            follower: Box::new(Follower::new(config)),
            config: config.clone(),
            field,
            preset,
            dock: false,
            failed: false,
            last_goal: None,
            creep_from: None,
        }
    }
}

impl Navigator for RouteNavigator {
    fn go_to(&mut self, _now_us: u64, pose: Pose2, goal: WaypointId, dock: bool) {
        self.dock = dock;
        self.creep_from = None;
        let Some(slot) = self.field.slot_for_waypoint(goal).copied() else {
            self.failed = true;
            return;
        };
        let route = match self.preset {
            DrivePreset::Ours => {
                let footprint = Footprint {
                    length_m: self.config.robot.footprint_length_m,
                    width_m: self.config.robot.footprint_width_m,
                    carrying: !dock,
                };
                let space = FreeSpace::new(
                    &self.field,
                    &[],
                    footprint,
                    self.config.navigation.shortcut_margin_m,
                );
                plan_route(
                    &self.field,
                    &self.map,
                    &space,
                    pose,
                    &slot,
                    &self.config.navigation,
                )
            }
            DrivePreset::Original => {
                self.follower = Box::new(
                    OriginalFollower::new(OriginalParams::default())
                        .with_start_location(self.last_goal),
                );
                plan_original_route(&self.map, pose, &slot, ORIGINAL_APPROACH_M)
            }
        };
        self.last_goal = self.field.waypoints().position(goal);
        match route {
            Ok(route) => {
                self.failed = false;
                self.follower.start(route);
            }
            Err(_) => self.failed = true,
        }
    }

    fn update(&mut self, now_us: u64, pose: Pose2, switch_pressed: bool) -> (BodyTwist, Arrival) {
        if self.failed {
            return (BodyTwist::default(), Arrival::Failed);
        }
        if let Some(from) = self.creep_from {
            return if switch_pressed {
                (BodyTwist::default(), Arrival::Docked)
            } else if from.position().distance(pose.position()) > ORIGINAL_CREEP_LIMIT_M {
                (BodyTwist::default(), Arrival::Arrived)
            } else {
                (
                    BodyTwist::new(ORIGINAL_CREEP_M_S, 0.0, 0.0),
                    Arrival::Moving,
                )
            };
        }
        let command = self
            .follower
            .update(now_us, pose, self.dock && switch_pressed);
        let arrival = match command.status {
            Status::Following => Arrival::Moving,
            Status::Docked => Arrival::Docked,
            Status::Arrived | Status::Idle => {
                if self.dock && self.preset == DrivePreset::Original {
                    self.creep_from = Some(pose);
                    return (
                        BodyTwist::new(ORIGINAL_CREEP_M_S, 0.0, 0.0),
                        Arrival::Moving,
                    );
                }
                Arrival::Arrived
            }
        };
        (command.twist, arrival)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::PartColor;
    use crate::planning::tasks::{
        BranchAndBound, Location, Original, Rules, StraightLineTimes, Timing,
    };

    fn model(round: u8) -> Model {
        let field = Field::competition();
        Model::new(
            &StraightLineTimes::new(&field, 0.4, 0.8),
            Timing {
                pick_s: 1.0,
                drop_s: 0.8,
                machine_delay_s: 0.0,
            },
            Rules::for_round(round),
        )
        .unwrap()
    }

    fn run_all(mut actions: TaskActions) -> Vec<Action> {
        let mut done = Vec::new();
        let mut t = 0;
        while let Some(action) = actions.next_action(t) {
            done.push(action);
            t += 10_000_000;
            actions.action_done(action, true, t);
            assert!(done.len() <= 20, "the planner never finishes: {done:?}");
        }
        assert!(actions.state().is_complete());
        done
    }

    #[test]
    fn a_round_3_plan_runs_to_full_score_for_both_policies() {
        use PartColor::*;
        let incoming = [Some(Blue), Some(Green), Some(Green), Some(Red)];
        let state = State::from_incoming(&incoming, Location::Start, 0.0);
        for policy in [
            Box::new(BranchAndBound::default()) as Box<dyn Policy>,
            Box::new(Original::default()),
        ] {
            let done = run_all(TaskActions::new(model(3), policy, state.clone()));
            // 1 blue + 2 greens × 2 + 1 red × 3 = 8 placements.
            assert_eq!(done.len(), 8);
        }
    }

    #[test]
    fn the_original_reproduces_its_documented_first_moves() {
        use PartColor::*;
        let incoming = [Some(Blue), Some(Green), Some(Green), Some(Red)];
        let state = State::from_incoming(&incoming, Location::Start, 0.0);
        let done = run_all(TaskActions::new(
            model(3),
            Box::new(Original::default()),
            state,
        ));
        // original-system.md §6.4: R → machine A (56), then the greens → B (54, 58).
        let first: Vec<(u8, u8)> = done.iter().take(3).map(|a| (a.pick.0, a.drop.0)).collect();
        assert_eq!(first, [(53, 56), (51, 54), (52, 58)]);
    }

    #[test]
    fn a_failed_action_gives_the_part_up_and_the_others_go_on() {
        use PartColor::*;
        let incoming = [Some(Blue), Some(Blue), None, None];
        let state = State::from_incoming(&incoming, Location::Start, 0.0);
        let mut actions = TaskActions::new(model(1), Box::new(BranchAndBound::default()), state);
        let first = actions.next_action(0).unwrap();
        actions.action_done(first, false, 5_000_000);
        assert_eq!(actions.abandoned(), 1);
        let second = actions.next_action(5_000_000).unwrap();
        assert_ne!(second.pick, first.pick);
        actions.action_done(second, true, 10_000_000);
        assert_eq!(actions.next_action(10_000_000), None);
    }
}
