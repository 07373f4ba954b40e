//! The competition brain: wait for the part list (asking the server, or forced by the
//! operator), then run the mission with the task planner and the navigation, reading the
//! server's four areas while driving to a pick (competition.md §3, §6).
//!
//! Moved out of the simulator's round so that the robot, the simulator and a replay run the
//! very same decisions. Pure: time comes with each call.

use std::sync::Arc;

use crate::competition::{RouteNavigator, SnapshotUse, TaskActions};
use crate::config::{Config, Policy};
use crate::control::route::{LegPlanner, Route};
use crate::control::route_time::RouteTimes;
use crate::field::Field;
use crate::field::geometry::Pose2;
use crate::kinematics::BodyTwist;
use crate::mission::{
    Activity, BeaconFix, HeldMagnet, Mission, MissionConfig, MissionEvent, search_floor,
};
use crate::planning::tasks::{
    self, BranchAndBound, Location, Model, Original, Rules, State, StraightLineTimes, TaskError,
    Timing, TravelTimes, check_magnet_faces,
};
use crate::referee::protocol::{Reply, Request, SlotLetters, letters_to_string};
use crate::referee::snapshot::SnapshotCycle;
use crate::referee::tracker::{RequestTracker, RetryPolicy, Step};

use super::event::Event;
use super::silence::{Hold, MegaHeard};

/// Where the round is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Asking the server for the part list.
    WaitingForPartList,
    /// Running the mission.
    Running,
    /// Every action done: parked.
    Finished,
}

/// What the brain wants at a host tick.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BrainTick {
    /// Body twist, robot frame.
    pub twist: BodyTwist,
    /// Electromagnet level.
    pub solenoid_on: bool,
    /// Arm the Mega's stop on its switch ([`crate::mission::MissionOutput::stop_on_switch`]).
    pub stop_on_switch: bool,
    /// A request to send to the server now.
    pub request: Option<Request>,
}

/// The competition brain: see the module documentation.
pub struct Brain {
    config: Config,
    /// Our legs' planner (`None` for the original policy), built once with the brain: the
    /// task planner's route times and the round's navigator both plan with it.
    legs: Option<Arc<LegPlanner>>,
    model: Model,
    mission_config: MissionConfig,
    mission: Option<Mission<RouteNavigator, TaskActions>>,
    tracker: RequestTracker,
    snapshots: SnapshotCycle,
    next_poll_us: u64,
    poll_period_us: u64,
    started_at_us: Option<u64>,
    finished: bool,
}

impl std::fmt::Debug for Brain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Brain")
            .field("phase", &self.phase())
            .field("started_at_us", &self.started_at_us)
            .field("tracker", &self.tracker)
            .finish()
    }
}

impl Brain {
    /// A brain for `config`'s round and policy, waiting for the part list.
    pub fn new(config: &Config) -> Result<Self, TaskError> {
        check_magnet_faces(&config.robot.magnet_faces)?;
        let field = Field::competition();
        let competition = &config.competition;
        // Ours plans on the times of the routes it will drive; the original on straight
        // lines at its cruise speed and turn rate, as it did.
        let legs = (competition.policy == Policy::Ours).then(|| Arc::new(LegPlanner::new(config)));
        let travel: Box<dyn TravelTimes> = match &legs {
            Some(legs) => Box::new(RouteTimes::with_planner(legs, config)),
            None => Box::new(StraightLineTimes::new(
                &field,
                competition.planner_speed_m_s,
                competition.planner_turn_rate_rad_s,
            )),
        };
        let model = Model::new(
            travel.as_ref(),
            Timing {
                pick_s: competition.planner_pick_s,
                drop_s: competition.planner_drop_s,
                machine_delay_s: competition.machine_delay_s,
            },
            Rules::for_round(competition.round),
        )?;
        Ok(Self {
            mission_config: match competition.policy {
                Policy::Ours => MissionConfig {
                    exit_on_route_after_pick: true,
                    confirm_release: true,
                    watch_carried_part: true,
                    drop_creep_speed_m_s: config.navigation.dock_creep_speed_m_s,
                    ..config.mission
                },
                Policy::Original => config.mission.original(),
            },
            config: config.clone(),
            legs,
            model,
            mission: None,
            tracker: RequestTracker::new(RetryPolicy::from_config(&config.referee)),
            snapshots: SnapshotCycle::new(competition.poll_period_us()),
            next_poll_us: 0,
            poll_period_us: competition.poll_period_us(),
            started_at_us: None,
            finished: false,
        })
    }

    /// Where the round is.
    pub fn phase(&self) -> Phase {
        match (&self.mission, self.finished) {
            (None, _) => Phase::WaitingForPartList,
            (Some(_), false) => Phase::Running,
            (Some(_), true) => Phase::Finished,
        }
    }

    /// When the part list came (the round's clock started), µs.
    pub fn started_at_us(&self) -> Option<u64> {
        self.started_at_us
    }

    /// What the mission is doing, once running.
    pub fn activity(&self) -> Option<Activity> {
        self.mission.as_ref().map(|m| m.activity())
    }

    /// The route the robot follows on its way to a slot, as planned when the leg began
    /// (`None` while it handles a part, plans or stands still).
    pub fn planned_route(&self) -> Option<&Route> {
        self.mission
            .as_ref()
            .filter(|m| {
                matches!(
                    m.activity(),
                    Activity::ToPick { .. } | Activity::ToDrop { .. }
                )
            })
            .and_then(|m| m.navigator().route())
    }

    /// The task planner behind the mission, once running.
    pub fn actions(&self) -> Option<&TaskActions> {
        self.mission.as_ref().map(|m| m.actions())
    }

    /// The localiser's latest word on the pose from the beacons, for the mission's drops
    /// ([`Mission::observe_fix`]).
    pub fn observe_fix(&mut self, fix: BeaconFix) {
        if let Some(mission) = self.mission.as_mut() {
            mission.observe_fix(fix);
        }
    }

    /// One host tick at `now_us` with the pose estimate and the switch; `events` gets what
    /// happened. Without `may_drive` (the Mega has not been heard yet) the mission waits,
    /// still and with the magnet off; the server is still read. With `hold.wheels` (the core
    /// holds the robot still: a device silent or its port lost) the mission stands with its
    /// clock stopped and its magnet as it was ([`Mission::hold`], told whether the hold has
    /// the magnet off), and goes on from there at the next tick without.
    pub fn tick(
        &mut self,
        now_us: u64,
        pose: Pose2,
        switch_pressed: bool,
        may_drive: bool,
        hold: Hold,
        events: &mut Vec<Event>,
    ) -> BrainTick {
        let mut out = BrainTick::default();
        match self.mission.as_mut() {
            Some(_) if !may_drive => {}
            Some(mission) if hold.wheels => {
                mission.hold(now_us, pose, held_magnet(hold));
                out.solenoid_on = mission.solenoid_on();
            }
            None => {
                if now_us >= self.next_poll_us && self.tracker.ready(now_us) {
                    self.next_poll_us = now_us + self.poll_period_us;
                    out.request = start(&mut self.tracker, Request::IncomingWarehouse, now_us);
                }
            }
            Some(mission) => {
                let tick = mission.tick(now_us, pose, switch_pressed);
                out.twist = tick.twist;
                out.solenoid_on = tick.solenoid_on;
                out.stop_on_switch = tick.stop_on_switch;
                for event in tick.events {
                    if event == MissionEvent::Finished {
                        self.finished = true;
                    }
                    events.push(describe(mission.actions(), event));
                }
                // Read the server while the floor is as the planner knows it, or while the
                // mission waits for its word on a part let go near its drop.
                let awaiting = mission.activity() == Activity::AwaitingServer;
                if !mission.is_before_pick() {
                    mission.actions_mut().picking(now_us);
                    if !awaiting {
                        self.snapshots.restart();
                    }
                }
                if (mission.is_before_pick() || awaiting)
                    && self.tracker.ready(now_us)
                    && let Some(request) = self.snapshots.request_due(now_us)
                {
                    out.request = start(&mut self.tracker, request, now_us);
                }
            }
        }
        match self.tracker.step(now_us) {
            Step::Send(request) => out.request = Some(request),
            Step::Done(Err(error)) => {
                if self.mission.is_some() {
                    // The cycle starts over; the robot plans from what it knows.
                    self.snapshots.on_reply(None, Err(error.clone()), now_us);
                }
                events.push(Event::RefereeFailed {
                    message: error.to_string(),
                });
            }
            Step::Done(Ok(_)) | Step::Idle | Step::Waiting { .. } => {}
        }
        out
    }

    /// A datagram from the server at `now_us`.
    pub fn on_datagram(&mut self, now_us: u64, datagram: &[u8], events: &mut Vec<Event>) {
        let asked = self.tracker.outstanding();
        let Some(reply) = self.tracker.on_datagram(now_us, datagram) else {
            return;
        };
        match self.mission.as_mut() {
            None => {
                if let Reply::Slots(parts) = reply {
                    self.start(now_us, parts, false, events);
                }
            }
            Some(mission) => {
                let snapshot = self.snapshots.on_reply(asked, Ok(reply), now_us);
                if let Some(snapshot) = snapshot
                    && let SnapshotUse::Applied { disagreements } =
                        mission.actions_mut().offer_snapshot(&snapshot)
                    && disagreements > 0
                {
                    events.push(Event::ServerDisagrees {
                        parts: disagreements,
                        areas: snapshot.areas.map(|a| letters_to_string(&a)).join(" "),
                    });
                }
            }
        }
    }

    /// The operator starts the round with `parts`, server or not (ignored once running).
    pub fn force_start(&mut self, now_us: u64, parts: SlotLetters, events: &mut Vec<Event>) {
        if self.mission.is_none() {
            self.start(now_us, parts, true, events);
        }
    }

    fn start(&mut self, now_us: u64, parts: SlotLetters, forced: bool, events: &mut Vec<Event>) {
        events.push(Event::PartList { parts, forced });
        self.started_at_us = Some(now_us);
        let state = State::from_incoming(&parts, Location::Start, 0.0);
        let policy = self.config.competition.policy;
        let planner: Box<dyn tasks::Policy> = match policy {
            Policy::Ours => Box::new(BranchAndBound::default()),
            Policy::Original => Box::new(Original::default()),
        };
        let actions = TaskActions::new(self.model.clone(), planner, state);
        let navigator = RouteNavigator::with_legs(&self.config, policy, self.legs.clone());
        let field = navigator.field();
        let floor = search_floor(field, &self.config.robot);
        let slot_poses = field
            .slots()
            .map(|slot| (slot.waypoint, slot.pick_pose))
            .collect();
        self.mission = Some(Mission::new(
            self.mission_config,
            navigator,
            actions,
            floor,
            slot_poses,
        ));
    }
}

/// Start `request` on the tracker; the request to send, if it could start.
fn start(tracker: &mut RequestTracker, request: Request, now_us: u64) -> Option<Request> {
    tracker.start(request, now_us).ok().map(|()| request)
}

/// Who let the magnet go in `hold`, as the mission needs it to know where a carried part was
/// left: the core's command reaches a speaking Mega; a Mega with its cable out lets go on its
/// own watchdog, and one silent on its port (a reset) at once.
fn held_magnet(hold: Hold) -> HeldMagnet {
    match (hold.magnet, hold.mega) {
        (false, _) => HeldMagnet::On,
        (true, MegaHeard::Speaking) => HeldMagnet::LetGoByCore,
        (true, MegaHeard::PortLost) => HeldMagnet::LetGoByMegaWatchdog,
        (true, MegaHeard::Silent) => HeldMagnet::LetGoByMegaReset,
    }
}

/// A mission event in the core's terms, with the part's colour as the planner knows it.
fn describe(actions: &TaskActions, event: MissionEvent) -> Event {
    let color = actions.pending_color();
    match event {
        MissionEvent::ActionStarted { action, attempt } => Event::ActionStarted {
            pick: action.pick,
            drop: action.drop,
            color,
            attempt,
        },
        MissionEvent::Picked { slot } => Event::Picked { slot, color },
        MissionEvent::Placed { slot } => Event::Placed {
            slot,
            color: actions.last_placed_color().or(color),
        },
        MissionEvent::PartSlipped => Event::PartSlipped { color },
        MissionEvent::Regripped => Event::Regripped { color },
        MissionEvent::Jammed => Event::PartJammed { color },
        MissionEvent::LetGoInHold => Event::PartLetGoInHold { color },
        MissionEvent::LetGoNearDrop => Event::PartLetGoNearDrop { color },
        MissionEvent::Skipped { action, reason } => Event::Skipped {
            pick: action.pick,
            drop: action.drop,
            reason,
        },
        MissionEvent::Finished => Event::Finished,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;

    /// Regression: the part list built the navigator's leg planner inside the loop's tick
    /// (the free-space grids: a tenth of a second and more, the loop stalled at the start
    /// of every round; in real time, a served odometry drive fitted its wheels 0.12 % off).
    /// The navigator the part list starts plans with the planner the brain built before.
    #[test]
    fn the_round_starts_with_the_leg_planner_built_before_it() {
        let mut brain = Brain::new(&Config::default()).unwrap();
        let built = Arc::clone(brain.legs.as_ref().unwrap());
        let parts = crate::referee::protocol::parse_letters("BBBB").unwrap();
        brain.force_start(0, parts, &mut Vec::new());
        let mission = brain.mission.as_ref().unwrap();
        let navigating = mission.navigator().legs().unwrap();
        assert!(Arc::ptr_eq(&built, navigating));
    }
}
