//! A complete simulated Robot@Factory round: the robot's core (`ratf_core::runtime::Core`,
//! the very software that runs on the robot) driven by [`ratf_core::runtime::run`] with the
//! simulated world as its devices and a mock of the organisers' server over real UDP on
//! loopback.
//!
//! - The mock server ([`MockServer`]) holds the round's part list; an operator starts it
//!   [`START_DELAY_S`] after power-up, so the robot first hears `STOP`.
//! - The core asks for the part list, plans, runs the mission and reads the server's four
//!   areas while driving to a pick (`ratf_core::runtime::Brain`); its requests go out on
//!   the robot's [`RefereeLink`], and the answers come back as inputs.
//! - The world's part events are reported to the mock (`place`/`take`), so `IWP`, `OWP`,
//!   `MAP`, `MBP` answer what is really on the floor; the world's own machines turn the parts.
//! - Points are the rules' (competition.md §2): one per correct placement, on a machine that
//!   takes the part or a blue part in the outgoing warehouse. The round's time runs from the
//!   part list to the last placement.
//!
//! The loop is deterministic for a seed: every datagram is sent and answered within the same
//! simulated instant (loopback delivers it before `send` returns).

use std::net::SocketAddr;
use std::path::Path;

use serde::Serialize;

use crate::apps::calibrate::{self, CalibrateError};
use crate::apps::collision_causes::{CollisionCauses, CollisionClassifier};
use crate::apps::fault_round::{AFTER_STOP_FAULT_US, FaultOutcome, RoundFaults};
use crate::apps::time_split::{TimeSplit, TimeSplitTap};
use crate::devices::operator::{OperatorReceiver, WithOperator, operator_channel};
use crate::devices::realtime::Paced;
use crate::recording::{Recorder, RecordingError, Session};
use crate::referee::client::{LinkError, RefereeLink};
use crate::referee::server::MockServer;
use ratf_core::config::{Config, Policy, WorldProfile};
use ratf_core::drivers::imu::ImuError;
use ratf_core::field::geometry::{Pose2, wrap_angle};
use ratf_core::field::{Field, PartColor, WaypointId};
use ratf_core::planning::bound::{BoundError, RoundBound};
use ratf_core::planning::tasks::{Rules, TaskError};
use ratf_core::runtime::{
    Core, Devices, Event, Flow, Input, OperatorCommand, Outputs, Stamped, Tap, Timestamp, run,
};
use ratf_sim::devices::SimDevices;
use ratf_sim::faults::FaultPlan;
use ratf_sim::parts::{PartEvent, PartPlace};
use ratf_sim::referee::{MockError, MockReferee, MockSettings, ServerSlot, round_parts};
use ratf_sim::truth::WorldTruth;
use ratf_sim::world::{Collision, Scenario, World};

/// When the operator starts the mock server, s after power-up.
pub const START_DELAY_S: f64 = 1.0;
/// A round that has not finished after this long is stopped, s of simulated time.
pub const ROUND_LIMIT_S: f64 = 300.0;
/// How long the world runs on after the robot reports it has finished, µs: a part let go at
/// the very end comes to rest in its slot (and scores) within this (the magnet releases in
/// tens of ms; assumption, with margin).
pub const SETTLE_AFTER_FINISH_US: u64 = 500_000;

/// Something that happened during the round, as it happened.
#[derive(Clone, Debug, PartialEq)]
pub enum RoundEvent {
    /// The robot's core reported something.
    Core {
        /// When.
        time: Timestamp,
        /// What.
        event: Event,
    },
    /// The robot (or the part it carries) ran into something.
    Collision(Collision),
    /// A host tick (50 Hz): where the robot truly is and where it believes it is.
    Tick {
        /// When.
        time: Timestamp,
        /// True pose.
        truth: Pose2,
        /// The localiser's estimate.
        estimate: Pose2,
    },
    /// A placement scored (the referee's view, from the simulated floor).
    Points {
        /// When the part came to rest in its slot.
        time: Timestamp,
        /// Where (slot waypoint).
        slot: u8,
        /// The part's colour when placed.
        color: PartColor,
        /// Total so far.
        total: u32,
    },
}

/// What a round measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RoundReport {
    /// Where each part ended: (colour, world position x, y), for plots.
    #[serde(skip)]
    pub final_parts: Vec<(PartColor, f64, f64)>,
    /// Round number.
    pub round: u8,
    /// Seed.
    pub seed: u64,
    /// Policy.
    pub policy: Policy,
    /// How the world departed from the robot's beliefs.
    pub world: WorldProfile,
    /// The world's drawn truth.
    #[serde(skip)]
    pub truth: WorldTruth,
    /// Points scored.
    pub points: u32,
    /// Parts in the outgoing warehouse at the end.
    pub outgoing: u32,
    /// From the part list to the last placement, simulated s.
    pub time_s: f64,
    /// Collisions.
    pub collisions: u32,
    /// Actions given up after their retries (mission timeouts and failures).
    pub timeouts: u32,
    /// Parts on which the server's strings disagreed with what the robot knew, summed over
    /// the snapshots the planner folded in.
    pub server_disagreements: u32,
    /// Server snapshots (`IWP`, `OWP`, `MAP`, `MBP`) the planner folded in.
    #[serde(skip)]
    pub server_snapshots: u32,
    /// Localisation position RMSE over the round, m.
    pub pos_rmse_m: f64,
    /// Localisation heading RMSE over the round, degrees.
    pub heading_rmse_deg: f64,
    /// Inputs the core consumed.
    #[serde(skip)]
    pub inputs: u64,
    /// Where the time from the part list to the last placement went.
    pub time_split: TimeSplit,
    /// What the collisions were.
    pub collision_causes: CollisionCauses,
}

/// Why a round could not run.
#[derive(Debug, thiserror::Error)]
pub enum RoundError {
    /// The round's parts or the mock server's settings are not valid.
    #[error("round setup: {0}")]
    Mock(#[from] MockError),
    /// The task planner's model could not be built from the configuration.
    #[error("task planner: {0}")]
    Planner(#[from] TaskError),
    /// The mock server's socket failed.
    #[error("mock server on loopback: {0}")]
    Server(#[source] std::io::Error),
    /// The robot's link to the server failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The IMU driver failed.
    #[error("simulated IMU: {0}")]
    Imu(#[from] ImuError),
    /// The recording could not be written.
    #[error("recording: {0}")]
    Recording(#[from] Box<RecordingError>),
    /// The calibration before a calibrated round failed.
    #[error(transparent)]
    Calibration(#[from] CalibrateError),
    /// The lower bound of a round could not be computed.
    #[error("lower bound: {0}")]
    Bound(#[from] BoundError),
}

/// How a round is run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoundOptions {
    /// Round number (1, 2, 3).
    pub round: u8,
    /// Seed: the part order and all the simulator's noise.
    pub seed: u64,
    /// Who drives.
    pub policy: Policy,
    /// Machine processing time, s.
    pub machine_delay_s: f64,
    /// The operator forces the start at this time (s) with the round's part list, whether
    /// or not the server has answered (competition practice without a server).
    pub force_start_s: Option<f64>,
    /// The server never answers (it is down or unreachable): only a forced start starts.
    pub silent_server: bool,
    /// At this time (s) the server stops showing the part in this slot, as if a referee had
    /// taken it away; the simulated floor keeps it, so only the server's strings tell the
    /// robot (a test of re-planning from the server).
    pub server_removes: Option<(ServerSlot, f64)>,
}

impl RoundOptions {
    /// Round `round` with `seed` and `policy`, no machine delay, started by the server.
    pub fn new(round: u8, seed: u64, policy: Policy) -> Self {
        Self {
            round,
            seed,
            policy,
            machine_delay_s: 0.0,
            force_start_s: None,
            silent_server: false,
            server_removes: None,
        }
    }

    /// `config` with this round's settings: the seed, round, policy and machine delay.
    pub fn apply_to(&self, config: &Config) -> Config {
        let mut config = config.clone();
        config.sim.seed = self.seed;
        config.competition.round = self.round;
        config.competition.policy = self.policy;
        config.competition.machine_delay_s = self.machine_delay_s;
        config
    }
}

/// The devices of a simulated round: the simulated world, the robot's UDP link to a mock of
/// the organisers' server on loopback, and the operator (a forced start at a set time). The
/// floor's events are reported to the mock server and scored by the rules.
struct RoundDevices {
    sim: SimDevices,
    link: RefereeLink,
    server: MockServer,
    field: Field,
    scorer: Scorer,
    silent_server: bool,
    server_started: bool,
    server_removes: Option<(ServerSlot, f64)>,
    force_start: Option<(f64, OperatorCommand)>,
    queued: std::collections::VecDeque<Stamped>,
    seen_part_events: usize,
    seen_collisions: usize,
    points: u32,
    last_point_us: u64,
    ticked: bool,
    skipped: u32,
    events: Vec<RoundEvent>,
    faults: Option<RoundFaults>,
}

impl RoundDevices {
    /// Tell the server what happened on the floor since the last call, and score it.
    fn settle_floor(&mut self) {
        let world = self.sim.world();
        let part_events = world.part_events()[self.seen_part_events..].to_vec();
        self.seen_part_events += part_events.len();
        for (at_us, event) in part_events {
            match event {
                PartEvent::Picked { from, .. } => {
                    if let Some(slot) = from.and_then(|id| ServerSlot::of_waypoint(&self.field, id))
                    {
                        let _ = self.server.referee_mut().take(slot, at_us);
                    }
                }
                PartEvent::Placed { part, slot, color } => {
                    if let Some(server_slot) = ServerSlot::of_waypoint(&self.field, slot) {
                        let _ = self.server.referee_mut().place(server_slot, color, at_us);
                    }
                    if self.scorer.placed(part, slot, color) {
                        self.points += 1;
                        self.last_point_us = at_us;
                        self.events.push(RoundEvent::Points {
                            time: Timestamp::from_us(at_us),
                            slot: slot.0,
                            color,
                            total: self.points,
                        });
                    }
                }
                PartEvent::Dropped { .. } | PartEvent::Processed { .. } => {}
            }
        }
        let world = self.sim.world();
        for collision in &world.collisions()[self.seen_collisions..] {
            self.events.push(RoundEvent::Collision(*collision));
        }
        self.seen_collisions = world.collisions().len();
    }

    /// The referee's and the operator's doings at `now_us`, before the world steps.
    fn before_step(&mut self, now_us: u64) {
        let t_s = now_us as f64 * 1e-6;
        if !self.server_started && t_s >= START_DELAY_S {
            self.server.referee_mut().start(now_us);
            self.server_started = true;
        }
        if let Some((slot, at_s)) = self.server_removes
            && t_s >= at_s
        {
            let _ = self.server.referee_mut().take(slot, now_us);
            self.server_removes = None;
        }
        if let Some(faults) = &mut self.faults {
            faults.before_step(&mut self.sim);
        }
    }
}

impl Devices for RoundDevices {
    type Error = RoundError;

    fn next_input(&mut self) -> Result<Option<Stamped>, RoundError> {
        if let Some(input) = self.queued.pop_front() {
            return Ok(Some(input));
        }
        loop {
            if let Some(datagram) = self
                .faults
                .as_mut()
                .and_then(|f| f.late_answer(self.sim.now_us()))
            {
                let time = Timestamp::from_us(self.sim.now_us());
                return Ok(Some(Stamped::new(time, Input::Referee { datagram })));
            }
            if let Some(input) = self.sim.pop_input() {
                if input.input == Input::HostTick {
                    self.ticked = true;
                    // The operator presses "start" on this tick's heels.
                    if let Some((_, command)) = self
                        .force_start
                        .take_if(|(at_s, _)| input.time.as_secs_f64() >= *at_s)
                    {
                        self.queued
                            .push_back(Stamped::new(input.time, Input::Operator(command)));
                    }
                }
                return Ok(Some(input));
            }
            self.settle_floor();
            self.before_step(self.sim.now_us());
            self.sim.advance()?;
        }
    }

    fn ground_truth(&self) -> Option<Pose2> {
        Some(self.sim.world().body().pose)
    }

    fn apply(&mut self, input: &Stamped, outputs: &Outputs) -> Result<(), RoundError> {
        self.sim.apply_outputs(outputs);
        if let Some(faults) = &mut self.faults {
            faults.watch(input.time.as_us(), outputs);
        }
        for event in &outputs.events {
            if matches!(event, Event::Skipped { .. }) {
                self.skipped += 1;
            }
            self.events.push(RoundEvent::Core {
                time: input.time,
                event: event.clone(),
            });
        }
        // The mock server answers only when polled, and it is polled right after each
        // request: loopback delivers before `send` returns, so the answer is in before the
        // next input, stamped now.
        if let Some(request) = outputs.referee {
            self.link.send(request)?;
            if !self.silent_server {
                self.server
                    .poll(input.time.as_us())
                    .map_err(RoundError::Server)?;
            }
            for datagram in self.link.receive() {
                let delivered = match &mut self.faults {
                    Some(faults) => faults.answer(input.time.as_us(), datagram),
                    None => vec![datagram],
                };
                for datagram in delivered {
                    self.queued
                        .push_back(Stamped::new(input.time, Input::Referee { datagram }));
                }
            }
        }
        Ok(())
    }
}

/// Run a round; `on_event` hears the events as they happen, and every tap sees every step.
pub fn run_with_taps(
    config: &Config,
    options: &RoundOptions,
    taps: &mut [&mut dyn Tap],
    on_event: impl FnMut(&RoundEvent),
) -> Result<RoundReport, RoundError> {
    run_in_world(config, config, options, taps, on_event)
}

/// What a round watched by a person adds (`ratf sim --hmi`): the operator's commands, wall
/// clock pacing and a way to end the round early.
#[derive(Default)]
pub struct Live<'a> {
    /// Commands from the HMI, joined into the world's inputs (so they are recorded).
    pub operator: Option<OperatorReceiver>,
    /// Robot seconds per wall second (`Some(1.0)`: real time); `None`: as fast as possible.
    pub speed: Option<f64>,
    /// Asked after every world step: true ends the round now (the operator chose another).
    pub abort: Option<&'a dyn Fn() -> bool>,
}

/// Run a round in the world drawn for `world` (the configuration the team wrote, with the
/// seed's errors) with a robot that believes `robot` (e.g. `world` after `ratf calibrate`:
/// calibrating changes what the robot believes, not the hall).
pub fn run_in_world(
    world: &Config,
    robot: &Config,
    options: &RoundOptions,
    taps: &mut [&mut dyn Tap],
    on_event: impl FnMut(&RoundEvent),
) -> Result<RoundReport, RoundError> {
    run_live(world, robot, options, taps, Live::default(), on_event)
}

/// [`run_in_world`] with a person watching: see [`Live`].
pub fn run_live(
    world: &Config,
    robot: &Config,
    options: &RoundOptions,
    taps: &mut [&mut dyn Tap],
    live: Live<'_>,
    on_event: impl FnMut(&RoundEvent),
) -> Result<RoundReport, RoundError> {
    run_faulted(world, robot, options, None, taps, live, on_event).map(|(report, _)| report)
}

/// [`run_in_world`] with the faults of `plan` injected into the world, its devices and the
/// server's answers (`None`: none); also what the faults did. After a fault that must stop
/// the robot the round ends [`AFTER_STOP_FAULT_US`] later.
pub fn run_faulted(
    world: &Config,
    robot: &Config,
    options: &RoundOptions,
    plan: Option<FaultPlan>,
    taps: &mut [&mut dyn Tap],
    live: Live<'_>,
    mut on_event: impl FnMut(&RoundEvent),
) -> Result<(RoundReport, FaultOutcome), RoundError> {
    let RoundOptions {
        round,
        seed,
        policy,
        machine_delay_s,
        force_start_s,
        silent_server,
        server_removes,
    } = *options;
    let config = options.apply_to(world);
    let robot_config = options.apply_to(robot);
    let field = Field::competition();
    let letters = round_parts(round, seed)?;
    let machine_delay_us = (machine_delay_s * 1e6) as u64;
    let settings = MockSettings::for_round(round, seed, Some(letters), machine_delay_us)?;
    let server = MockServer::bind(
        SocketAddr::from(([127, 0, 0, 1], 0)),
        MockReferee::new(settings),
    )
    .map_err(RoundError::Server)?;
    let link = RefereeLink::connect(server.local_addr().map_err(RoundError::Server)?, 0)?;
    let scenario = Scenario {
        incoming: letters,
        machine_delay_us,
        green_to_blue_at_a: settings.green_to_blue_at_a,
        ..Scenario::new(&config)
    };
    let round_devices = RoundDevices {
        sim: SimDevices::new(&config, &scenario)?,
        link,
        server,
        scorer: Scorer::new(&field, Rules::for_round(round)),
        field: field.clone(),
        silent_server,
        server_started: false,
        server_removes,
        force_start: force_start_s
            .map(|at_s| (at_s, OperatorCommand::ForceStart { parts: letters })),
        queued: Default::default(),
        seen_part_events: 0,
        seen_collisions: 0,
        points: 0,
        last_point_us: 0,
        ticked: false,
        skipped: 0,
        events: Vec::new(),
        faults: plan.map(|plan| RoundFaults::new(plan, &robot_config, scenario.clutter.clone())),
    };
    let limit_us = round_devices
        .faults
        .as_ref()
        .and_then(|f| f.plan().first_unrecoverable())
        .map_or((ROUND_LIMIT_S * 1e6) as u64, |e| {
            e.start_us.saturating_add(AFTER_STOP_FAULT_US)
        });
    // Without an operator the channel's sender is dropped at once: nothing ever arrives.
    let commands = live.operator.unwrap_or_else(|| operator_channel().1);
    let mut devices = WithOperator::new(Paced::new(round_devices, live.speed), commands);
    let abort = live.abort;
    let mut core = Core::new(&robot_config, scenario.start_pose)?;
    let mut classifier = CollisionClassifier::new(
        field.clone(),
        devices
            .inner_mut()
            .inner_mut()
            .sim
            .world()
            .crowded_picks(0.0),
    );
    // Where the parts stand crowds a pick as the robot sets out for it: a part knocked out
    // of its slot or pushed out of it since the start crowds the picks beside it.
    let mut on_event = |event: &RoundEvent, world: &World| {
        if let RoundEvent::Core {
            event: Event::ActionStarted { .. },
            ..
        } = event
        {
            classifier.crowd(world.crowded_picks(0.0));
        }
        classifier.hear(event);
        on_event(event);
    };

    let (mut pos_sq, mut heading_sq, mut samples) = (0.0, 0.0, 0u64);
    let mut last_batches = 0;
    let mut finished_at_us: Option<u64> = None;
    let mut time_split = TimeSplitTap::new(&robot_config);
    let mut all_taps: Vec<&mut dyn Tap> = Vec::with_capacity(taps.len() + 1);
    for tap in taps.iter_mut() {
        all_taps.push(&mut **tap);
    }
    all_taps.push(&mut time_split);
    let summary = run(&mut core, &mut devices, &mut all_taps, |core, devices| {
        let devices = devices.inner_mut().inner_mut();
        for event in devices.events.drain(..) {
            on_event(&event, devices.sim.world());
        }
        if !devices.sim.step_complete() {
            return Flow::Continue;
        }
        // The world step's inputs are all in: measure against the truth.
        if std::mem::take(&mut devices.ticked) {
            on_event(
                &RoundEvent::Tick {
                    time: Timestamp::from_us(devices.sim.now_us()),
                    truth: devices.sim.world().body().pose,
                    estimate: core.pose(),
                },
                devices.sim.world(),
            );
        }
        let batches = devices.sim.wheel_batches();
        if batches != last_batches
            && core.brain().started_at_us().is_some()
            && let Some(truth) = devices.sim.truth_at_last_telemetry()
        {
            last_batches = batches;
            let estimate = core.pose();
            pos_sq += (estimate.x - truth.x).powi(2) + (estimate.y - truth.y).powi(2);
            heading_sq += wrap_angle(estimate.yaw_rad - truth.yaw_rad).powi(2);
            samples += 1;
        }
        // The robot may finish as it lets go of its last part: the floor gets a moment to
        // settle before the round ends, so that placement is seen and scored.
        let now_us = devices.sim.now_us();
        if core.brain().phase() == ratf_core::runtime::Phase::Finished {
            finished_at_us.get_or_insert(now_us);
        }
        let settled = finished_at_us.is_some_and(|at| now_us >= at + SETTLE_AFTER_FINISH_US);
        if settled || now_us >= limit_us || abort.is_some_and(|abort| abort()) {
            Flow::Stop
        } else {
            Flow::Continue
        }
    })?;
    let devices = devices.inner_mut().inner_mut();
    devices.settle_floor();
    for event in devices.events.drain(..) {
        on_event(&event, devices.sim.world());
    }

    let world = devices.sim.world();
    let shop = world.shop();
    let outgoing = shop
        .parts()
        .iter()
        .filter(|p| match p.place {
            PartPlace::Slot(id) => (62..=65).contains(&id.0),
            _ => false,
        })
        .count() as u32;
    let n = samples.max(1) as f64;
    let count = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    let (server_disagreements, server_snapshots) =
        core.brain().actions().map_or((0, 0), |actions| {
            (
                count(actions.server_disagreements()),
                count(actions.snapshots_applied()),
            )
        });
    let robot_pose = world.body().pose;
    let final_parts = (0..shop.parts().len())
        .map(|i| {
            let p = shop.footprint(i, robot_pose).pose;
            (shop.parts()[i].color, p.x, p.y)
        })
        .collect();
    let started_s = core.brain().started_at_us().map(|us| us as f64 * 1e-6);
    drop(all_taps);
    let time_split = core
        .brain()
        .started_at_us()
        .map_or_else(TimeSplit::default, |from| {
            time_split.split(from, devices.last_point_us)
        });
    let outcome = devices
        .faults
        .as_ref()
        .map(RoundFaults::outcome)
        .unwrap_or_default();
    let report = RoundReport {
        final_parts,
        round,
        seed,
        policy,
        world: world.truth().profile,
        truth: world.truth().clone(),
        points: devices.points,
        outgoing,
        time_s: started_s.map_or(0.0, |s| (devices.last_point_us as f64 * 1e-6 - s).max(0.0)),
        collisions: world.stats().collisions,
        timeouts: devices.skipped,
        server_disagreements,
        server_snapshots,
        pos_rmse_m: (pos_sq / n).sqrt(),
        heading_rmse_deg: (heading_sq / n).sqrt().to_degrees(),
        inputs: summary.inputs,
        time_split,
        collision_causes: classifier.causes(),
    };
    Ok((report, outcome))
}

/// Run a round and record it to `path` (see [`crate::recording`]); `on_event` hears the
/// events as they happen.
pub fn run_recorded(
    config: &Config,
    options: &RoundOptions,
    path: &Path,
    on_event: impl FnMut(&RoundEvent),
) -> Result<RoundReport, RoundError> {
    run_recorded_live(
        config,
        config,
        options,
        path,
        &mut [],
        Live::default(),
        on_event,
    )
}

/// [`run_recorded`] in the world drawn for `world` with a robot that believes `robot` (as
/// [`run_in_world`]; the recording holds the robot's beliefs, which replay rebuilds the core
/// from), with more taps (the HMI) and a person watching (see [`Live`]).
pub fn run_recorded_live(
    world: &Config,
    robot: &Config,
    options: &RoundOptions,
    path: &Path,
    taps: &mut [&mut dyn Tap],
    live: Live<'_>,
    on_event: impl FnMut(&RoundEvent),
) -> Result<RoundReport, RoundError> {
    let applied = options.apply_to(robot);
    let session = Session {
        kind: "sim".to_owned(),
        config_toml: applied.to_toml_string().map_err(|e| {
            RoundError::Recording(Box::new(RecordingError::Io {
                path: path.to_owned(),
                source: std::io::Error::other(e),
            }))
        })?,
        start_pose: Scenario::new(&applied).start_pose,
        version: env!("CARGO_PKG_VERSION").to_owned(),
    };
    let mut recorder = Recorder::create(path, &session).map_err(Box::new)?;
    let mut all: Vec<&mut dyn Tap> = vec![&mut recorder];
    all.extend(taps.iter_mut().map(|tap| &mut **tap as &mut dyn Tap));
    let report = run_live(world, robot, options, &mut all, live, on_event)?;
    recorder.finish().map_err(Box::new)?;
    Ok(report)
}

/// Run a round with no taps; `on_event` hears the events as they happen.
pub fn run_round(
    config: &Config,
    options: &RoundOptions,
    on_event: impl FnMut(&RoundEvent),
) -> Result<RoundReport, RoundError> {
    run_with_taps(config, options, &mut [], on_event)
}

/// The full score of round `round`: 4, 6 or 8 points (competition.md §2).
pub fn full_score(round: u8) -> u32 {
    match round {
        1 => 4,
        2 => 6,
        _ => 8,
    }
}

/// One round and policy over many seeds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BenchRow {
    /// Round number.
    pub round: u8,
    /// Policy.
    pub policy: Policy,
    /// Fraction of runs with full points and 4 parts in the outgoing warehouse.
    pub full_score_rate: f64,
    /// Mean time from the part list to the last placement over the full-score runs, s.
    pub mean_time_s: f64,
    /// Largest such time, s.
    pub max_time_s: f64,
    /// Collisions over all runs.
    pub collisions: u32,
    /// Actions given up over all runs.
    pub timeouts: u32,
    /// Runs.
    pub runs: u32,
    /// The lower bound on this round's time for each seed's colour arrangement
    /// ([`RoundBound`]), mean over the seeds, s.
    pub bound_s: f64,
    /// Time over bound, mean over the full-score runs (each against its own arrangement's
    /// bound).
    pub time_over_bound: f64,
    /// Where the time went, mean over the full-score runs.
    pub time_split: TimeSplit,
    /// What the collisions were, over all runs.
    pub collision_causes: CollisionCauses,
}

/// What a rounds benchmark tells as it goes.
#[derive(Debug)]
pub enum BenchProgress<'a> {
    /// A seed's calibration was refused: its robot keeps what it believed before the refused
    /// step.
    CalibrationRefused {
        /// The seed.
        seed: u64,
        /// Which step, and why.
        error: &'a calibrate::DayRefusal,
    },
    /// A round finished.
    Run(&'a RoundReport),
}

/// Every round with each of `policies` over `seeds` (e.g. `11..=60`: tune on some seeds,
/// report on others); `on_progress` hears each report. With `calibrated`, each seed's world
/// is first calibrated ([`calibrate::beliefs`]) and the robots believe the calibration.
pub fn bench(
    config: &Config,
    seeds: std::ops::RangeInclusive<u64>,
    policies: &[Policy],
    machine_delay_s: f64,
    calibrated: bool,
    mut on_progress: impl FnMut(BenchProgress<'_>),
) -> Result<Vec<BenchRow>, RoundError> {
    let mut beliefs = std::collections::BTreeMap::new();
    for seed in seeds.clone() {
        let mut seeded = config.clone();
        seeded.sim.seed = seed;
        let (believed, refused) = calibrate::beliefs(&seeded, calibrated)?;
        if let Some(error) = &refused {
            on_progress(BenchProgress::CalibrationRefused { seed, error });
        }
        beliefs.insert(seed, believed);
    }
    let bound = RoundBound::new(config, &Field::competition())?;
    let mut rows = Vec::new();
    for round in 1..=3 {
        let mut bounds = std::collections::BTreeMap::new();
        for seed in seeds.clone() {
            bounds.insert(seed, bound.seconds(round, round_parts(round, seed)?)?);
        }
        for &policy in policies {
            let mut row = BenchRow {
                round,
                policy,
                full_score_rate: 0.0,
                mean_time_s: 0.0,
                max_time_s: 0.0,
                collisions: 0,
                timeouts: 0,
                runs: 0,
                bound_s: bounds.values().sum::<f64>() / bounds.len().max(1) as f64,
                time_over_bound: 0.0,
                time_split: TimeSplit::default(),
                collision_causes: CollisionCauses::default(),
            };
            let mut full = 0u32;
            for seed in seeds.clone() {
                let options = RoundOptions {
                    machine_delay_s,
                    ..RoundOptions::new(round, seed, policy)
                };
                let report = run_in_world(config, &beliefs[&seed], &options, &mut [], |_| {})?;
                on_progress(BenchProgress::Run(&report));
                row.runs += 1;
                row.collisions += report.collisions;
                row.timeouts += report.timeouts;
                row.collision_causes += report.collision_causes;
                if report.points == full_score(round) && report.outgoing == 4 {
                    full += 1;
                    row.mean_time_s += report.time_s;
                    row.time_over_bound += report.time_s / bounds[&seed];
                    row.time_split += report.time_split;
                    row.max_time_s = row.max_time_s.max(report.time_s);
                }
            }
            row.full_score_rate = f64::from(full) / f64::from(row.runs.max(1));
            row.mean_time_s /= f64::from(full.max(1));
            row.time_over_bound /= f64::from(full.max(1));
            row.time_split = row.time_split.scaled(1.0 / f64::from(full.max(1)));
            rows.push(row);
        }
    }
    Ok(rows)
}

/// The points of a round as the organisers count them: a placement scores when its slot
/// takes the part's colour ([`scores`]), and each part scores each of its stages once
/// (competition.md §2: a blue part once, a green twice, a red three times). A part lifted
/// from its slot and put back (a Mega reset cuts the magnet over the slot, the robot grips
/// it again and releases it) is one placement, not two.
#[derive(Clone, Debug)]
pub struct Scorer {
    field: Field,
    rules: Rules,
    scored: Vec<(usize, PartColor)>,
}

impl Scorer {
    /// A scorer for a round played under `rules` on `field`.
    pub fn new(field: &Field, rules: Rules) -> Self {
        Self {
            field: field.clone(),
            rules,
            scored: Vec::new(),
        }
    }

    /// Part `part`, `color` when released, now stands in the slot of waypoint `slot`:
    /// whether that is a new point. A part's colour names its stage (red for machine A,
    /// green for a machine's input, blue for the outgoing warehouse).
    pub fn placed(&mut self, part: usize, slot: WaypointId, color: PartColor) -> bool {
        if !scores(&self.field, self.rules, slot.0, color) || self.scored.contains(&(part, color)) {
            return false;
        }
        self.scored.push((part, color));
        true
    }
}

/// Whether placing a `color` part at slot waypoint `slot` scores (competition.md §2).
pub fn scores(field: &Field, rules: Rules, slot: u8, color: PartColor) -> bool {
    if (62..=65).contains(&slot) {
        return color == PartColor::Blue;
    }
    [
        ratf_core::field::MachineKind::A,
        ratf_core::field::MachineKind::B,
    ]
    .into_iter()
    .any(|kind| {
        field
            .machine_block(kind)
            .machines
            .iter()
            .any(|m| m.input.waypoint.0 == slot)
            && rules.transform(kind, color).is_some()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::apps::time_split::TURNING_RAD_S;

    /// Round `round` at seed 1 in the ideal world: the regression pins of the first wave's
    /// world, which both policies score in.
    fn round(round: u8, policy: Policy) -> RoundReport {
        run_round(
            &Config::default().in_world(WorldProfile::Ideal),
            &RoundOptions::new(round, 1, policy),
            |_| {},
        )
        .unwrap()
    }

    #[test]
    fn a_silent_server_then_a_forced_start_still_runs_the_round() {
        let options = RoundOptions {
            force_start_s: Some(3.0),
            silent_server: true,
            ..RoundOptions::new(1, 1, Policy::Ours)
        };
        let mut started = None;
        let report = run_round(&Config::default(), &options, |event| {
            if let RoundEvent::Core {
                time,
                event: Event::PartList { forced, .. },
            } = event
            {
                started = Some((time.as_secs_f64(), *forced));
            }
        })
        .unwrap();
        let (t_s, forced) = started.expect("the round never started");
        // Nothing came from the server: the start is the operator's, at 3 s.
        assert!((3.0..3.03).contains(&t_s), "started at {t_s}");
        assert!(forced);
        assert_eq!(report.points, 4);
        assert_eq!(
            report.server_snapshots, 0,
            "the robot planned from what it knew"
        );
    }

    #[test]
    fn every_round_reaches_full_score_at_seed_1_with_ours() {
        for (r, points) in [(1, 4), (2, 6), (3, 8)] {
            let report = round(r, Policy::Ours);
            assert_eq!(report.points, points, "round {r}: {report:?}");
            assert_eq!(report.outgoing, 4, "round {r}: {report:?}");
            assert!(report.time_s > 0.0);
            assert!(report.pos_rmse_m < 0.005, "round {r}: {report:?}");
        }
    }

    /// The original preset is the 5dpo robot whole, its filter included
    /// (`EstimatorKind::for_policy`): it scores, and it localises to centimetres and
    /// degrees as that filter does (`bench localisation`), not to our localiser's
    /// millimetres.
    #[test]
    fn the_original_preset_plays_every_round_with_its_own_filter() {
        for r in 1..=3 {
            let report = round(r, Policy::Original);
            assert!(
                report.points > 0 && report.outgoing > 0,
                "round {r}: {report:?}"
            );
            assert!(report.pos_rmse_m > 0.010, "round {r}: {report:?}");
            assert!(report.heading_rmse_deg > 1.0, "round {r}: {report:?}");
        }
    }

    #[test]
    fn the_bench_sets_each_round_against_its_lower_bound_and_splits_its_time() {
        let config = Config::default().in_world(WorldProfile::Ideal);
        let mut reports = Vec::new();
        let rows = bench(&config, 1..=1, &Policy::ALL, 0.0, false, |progress| {
            if let BenchProgress::Run(report) = progress {
                reports.push(report.clone());
            }
        })
        .unwrap();
        let bound = RoundBound::new(&config, &Field::competition()).unwrap();
        for row in &rows {
            let expected = bound
                .seconds(row.round, round_parts(row.round, 1).unwrap())
                .unwrap();
            assert_eq!(row.bound_s, expected, "{row:?}");
            let report = reports
                .iter()
                .find(|r| r.round == row.round && r.policy == row.policy)
                .unwrap();
            // The original preset, with its own filter, need not score in full: the ratio
            // and the split are checked on ours.
            if row.policy == Policy::Original {
                continue;
            }
            assert_eq!(row.full_score_rate, 1.0, "{report:?}");
            // No run beats the bound, and the ratio is the run's own.
            assert!(report.time_s > row.bound_s, "{report:?} against {row:?}");
            assert!((row.time_over_bound - report.time_s / row.bound_s).abs() < 1e-12);
            // The time split covers the round but the moment before its first tick (≤ 20 ms).
            let split = report.time_split.total_s();
            assert!(
                split <= report.time_s && split >= report.time_s - 0.020 - 1e-9,
                "{report:?}"
            );
            assert!(report.time_split.settling_s > 0.0 && report.time_split.driving_s > 0.0);
            if row.round == 1 {
                // Round 1 turns the heading by π seven times: the ticks that count as
                // turning must hold what the rest (|ω| ≤ TURNING_RAD_S) cannot have turned,
                // at no more than the yaw-rate limit.
                let t = &report.time_split;
                let held_s = t.total_s() - t.turning_s;
                let least_s = (7.0 * std::f64::consts::PI - TURNING_RAD_S * held_s)
                    / config.navigation.max_yaw_rate_rad_s;
                assert!(
                    t.turning_s >= least_s,
                    "{t:?}: at least {least_s} s turning"
                );
            }
        }
        let json = serde_json::to_value(&rows).unwrap();
        assert!(
            json[0]["bound_s"].as_f64().is_some_and(|b| b > 20.0),
            "{json}"
        );
    }

    /// The route displays show (HMI, ROS 2) is the navigator's own: on the way to a slot
    /// it exists and ends at that slot's pick pose (short of it by
    /// [`ratf_core::control::route::DROP_SHORT_M`] carrying a part in, and off its line by
    /// where the part sits on the magnet); otherwise there is none.
    #[test]
    fn the_planned_route_is_the_navigators_and_ends_at_the_slot_it_goes_to() {
        use ratf_core::mission::Activity;
        struct Routes {
            field: Field,
            legs: u32,
            last: Option<Activity>,
        }
        impl Tap for Routes {
            fn on_step(&mut self, step: &ratf_core::runtime::StepView<'_>) {
                let brain = step.core.brain();
                let activity = brain.activity();
                match activity {
                    Some(Activity::ToPick { slot } | Activity::ToDrop { slot }) => {
                        let route = brain.planned_route().expect("a route on the way");
                        let pick = self.field.slot_for_waypoint(slot).unwrap().pick_pose;
                        // A part is let go a little short of the pick pose, the robot off
                        // the slot's line as far as the part sits off the magnet's centre.
                        let goal = pick.relative(route.goal());
                        match activity {
                            Some(Activity::ToDrop { .. }) => {
                                let short = ratf_core::control::route::DROP_SHORT_M;
                                let across = ratf_core::competition::MAX_HELD_PART_ACROSS_M;
                                assert!((goal.x + short).abs() < 1e-9, "{goal:?}");
                                assert!(goal.y.abs() <= across + 1e-12, "{goal:?}");
                            }
                            _ => assert_eq!(route.goal(), pick),
                        }
                        assert!(goal.yaw_rad.abs() < 1e-12, "{goal:?}");
                        if activity != self.last {
                            self.legs += 1;
                        }
                    }
                    _ => assert!(brain.planned_route().is_none(), "{activity:?}"),
                }
                self.last = activity;
            }
        }
        let mut routes = Routes {
            field: Field::competition(),
            legs: 0,
            last: None,
        };
        let config = Config::default();
        let options = RoundOptions::new(1, 1, Policy::Ours);
        let report = run_in_world(&config, &config, &options, &mut [&mut routes], |_| {}).unwrap();
        assert_eq!(report.points, 4);
        assert_eq!(routes.legs, 8, "one leg to each pick and each drop");
    }

    #[test]
    fn the_realistic_world_is_not_the_robots_belief() {
        let ideal = round(1, Policy::Ours);
        let mut config = Config::default();
        config.sim.world = WorldProfile::Realistic;
        let realistic = run_round(&config, &RoundOptions::new(1, 1, Policy::Ours), |_| {}).unwrap();
        assert_eq!(
            (ideal.world, realistic.world),
            (WorldProfile::Ideal, WorldProfile::Realistic)
        );
        assert_ne!(realistic.truth, ideal.truth);
        // Calibration errors the robot does not know of show in its localisation.
        assert!(
            realistic.pos_rmse_m > 2.0 * ideal.pos_rmse_m,
            "{} vs {}",
            realistic.pos_rmse_m,
            ideal.pos_rmse_m
        );
    }

    /// A regression pin in the realistic world: at seed 4 the parts of rounds 2 and 3 stand
    /// where the robot's estimate puts its pick pose short of the switch; the creep to
    /// contact picks them all (without it: 5 points and 1, then 3, actions given up).
    #[test]
    fn in_the_realistic_world_seed_4_scores_fully_in_every_round() {
        let mut config = Config::default();
        config.sim.world = WorldProfile::Realistic;
        for (r, points) in [(1, 4), (2, 6), (3, 8)] {
            let report =
                run_round(&config, &RoundOptions::new(r, 4, Policy::Ours), |_| {}).unwrap();
            assert_eq!(
                (report.points, report.outgoing, report.timeouts),
                (points, 4, 0),
                "round {r}: {report:?}"
            );
        }
    }

    #[test]
    fn calibrating_first_turns_a_faltering_realistic_round_into_a_clean_full_score() {
        // Seed 70's world makes round 2 falter uncalibrated: 5 points of 6 and 2 actions
        // given up before a stalled carry left a mark for the later legs (`14da9c8`); 6
        // points since, with one action given up and 14 collisions. Of rounds 1–3 at the
        // tuning seeds 61–110 only it and seed 63's round 2 lost uncalibrated since the
        // approach to a part hands over to the creep without stopping (`3aabff7`), which
        // saved seed 70's round 1, pinned here before. Which round the uncalibrated robot
        // loses moves with every change of its motion (seed 23's round 2, seed 2's round 3,
        // seed 17's and seed 109's round 1 were pinned here before too). The calibration
        // drive fixes the robot's beliefs, not the world.
        let mut world = Config::default();
        world.sim.world = WorldProfile::Realistic;
        world.sim.seed = 70;
        let options = RoundOptions::new(2, 70, Policy::Ours);
        let uncalibrated = run_in_world(&world, &world, &options, &mut [], |_| {}).unwrap();
        assert!(uncalibrated.timeouts > 0, "{uncalibrated:?}");
        let mut calibrated = world.clone();
        calibrate::run_in_sim(&world, calibrate::DayMeasures::ALL)
            .unwrap()
            .calibration
            .apply(&mut calibrated);
        let report = run_in_world(&world, &calibrated, &options, &mut [], |_| {}).unwrap();
        assert_eq!((report.points, report.timeouts), (6, 0), "{report:?}");
    }

    /// A body that stands 2 cm ahead of its wheels (its magnet too): a robot that believes
    /// the centred square carries its parts along the warehouses' rows with their far faces
    /// 2 cm nearer the dividers' tips than the 17.5 mm it plans (`planning::our_map`): 13
    /// contacts and a drive timed out at `[sim] seed` 5. The same robot with its outline
    /// measured centres its own faces there and touches nothing.
    #[test]
    fn a_robot_that_measured_its_outline_scores_without_touching_where_its_guess_collides() {
        let mut world = Config::default();
        world.sim.world = WorldProfile::Realistic;
        world.sim.seed = 5;
        world.robot.body_center_x_m = 0.02;
        let (measured, refused) = calibrate::beliefs(&world, true).unwrap();
        assert!(refused.is_none(), "{refused:?}");
        assert!((measured.robot.body_center_x_m - 0.02).abs() < 0.008);
        let mut unmeasured = measured.clone();
        unmeasured.robot.body_center_x_m = 0.0;
        unmeasured.robot.body_center_y_m = 0.0;
        let options = RoundOptions::new(1, 5, Policy::Ours);
        let run = |beliefs: &Config| run_in_world(&world, beliefs, &options, &mut [], |_| {});
        let knows = run(&measured).unwrap();
        assert_eq!((knows.points, knows.collisions), (4, 0), "{knows:?}");
        let guesses = run(&unmeasured).unwrap();
        assert!(guesses.collisions > 0, "{guesses:?}");
    }

    /// A regression pin in the realistic world, calibrated: in round 1 of seed 23 the robot
    /// turned into outgoing slot 4 still running along the row at 0.17 m/s in truth (its
    /// last command 0.075 m/s), ran 12 mm past the slot's line, and the carried part touched
    /// the slot's divider. The slot-entry gate now also weighs where the commands in flight
    /// take the robot (`control::follower`).
    #[test]
    fn a_carried_part_enters_its_slot_clear_of_the_dividers_after_a_fast_row() {
        let mut world = Config::default();
        world.sim.world = WorldProfile::Realistic;
        world.sim.seed = 23;
        let (calibrated, refused) = calibrate::beliefs(&world, true).unwrap();
        assert!(refused.is_none(), "{refused:?}");
        let options = RoundOptions::new(1, 23, Policy::Ours);
        let report = run_in_world(&world, &calibrated, &options, &mut [], |_| {}).unwrap();
        assert_eq!((report.points, report.collisions), (4, 0), "{report:?}");
    }

    /// The free-space routes' contacts and stalls found on the realistic world's seeds
    /// (calibrated), each pinned: round 2 of seed 61, a 45° corner into the outgoing row
    /// under machine B cut 15 mm inside at 0.43 m/s (`control::route::CORNER_CUT_SHARE`);
    /// round 1 of seed 83, braking along the outgoing row the robot ran 14 mm past outgoing
    /// slot 4's line (the slot corner braked from the commands in flight,
    /// `control::follower`); round 3 of seed 28, a quarter turn planned over 1.4 mm beside
    /// incoming slot 1, which the robot crawled up to at millimetres a second, 66.2 s for
    /// the round (`control::profile::MIN_TURN_SPEED_M_S` floors the wheels' cap, and
    /// `planning::free_routes` no longer narrows a turn to its limits); round 1 of seed 60,
    /// round 2 of seeds 40 and 189, a body's corner on a divider's corner after a corner
    /// cut deeper than the caps allowed for (`control::route::CORNER_CUT_SHARE`).
    #[test]
    fn free_routes_keep_clear_where_the_follower_overshoots_and_cuts_corners() {
        for (round, seed, points, within_s) in [
            (2, 61, 6, 45.0),
            (1, 83, 4, 45.0),
            (3, 28, 8, 55.0),
            (1, 60, 4, 45.0),
            (2, 40, 6, 45.0),
            (2, 189, 6, 45.0),
        ] {
            let mut world = Config::default();
            world.sim.world = WorldProfile::Realistic;
            world.sim.seed = seed;
            let (calibrated, refused) = calibrate::beliefs(&world, true).unwrap();
            assert!(refused.is_none(), "{refused:?}");
            let options = RoundOptions::new(round, seed, Policy::Ours);
            let report = run_in_world(&world, &calibrated, &options, &mut [], |_| {}).unwrap();
            assert_eq!(
                (report.points, report.collisions),
                (points, 0),
                "round {round}, seed {seed}: {report:?}"
            );
            assert!(
                report.time_s < within_s,
                "round {round}, seed {seed}: {report:?}"
            );
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_round() {
        assert_eq!(round(2, Policy::Ours), round(2, Policy::Ours));
    }

    #[test]
    fn placements_score_by_the_rules() {
        let field = Field::competition();
        let round3 = Rules::for_round(3);
        assert!(scores(&field, round3, 62, PartColor::Blue));
        assert!(!scores(&field, round3, 62, PartColor::Green));
        assert!(scores(&field, round3, 56, PartColor::Red)); // machine A input
        assert!(!scores(&field, round3, 56, PartColor::Green)); // A takes greens in round 2 only
        assert!(scores(&field, Rules::for_round(2), 56, PartColor::Green));
        assert!(scores(&field, round3, 54, PartColor::Green)); // machine B input
        assert!(!scores(&field, round3, 55, PartColor::Green)); // an output is no placement
        // Each part scores each stage once: a blue part put back on its outgoing slot, or
        // moved to another, is still one point; a red part scores at A, B and outgoing.
        let mut scorer = Scorer::new(&field, round3);
        assert!(scorer.placed(0, WaypointId(62), PartColor::Blue));
        assert!(!scorer.placed(0, WaypointId(62), PartColor::Blue));
        assert!(!scorer.placed(0, WaypointId(63), PartColor::Blue));
        assert!(scorer.placed(1, WaypointId(62), PartColor::Blue));
        assert!(!scorer.placed(2, WaypointId(55), PartColor::Green));
        assert!(scorer.placed(2, WaypointId(56), PartColor::Red));
        assert!(scorer.placed(2, WaypointId(54), PartColor::Green));
        assert!(scorer.placed(2, WaypointId(64), PartColor::Blue));
    }

    #[test]
    fn every_round_reads_the_server_and_agrees_with_it_at_seed_1() {
        for r in 1..=3 {
            for policy in Policy::ALL {
                let report = round(r, policy);
                assert!(report.server_snapshots > 0, "round {r}: {report:?}");
                // The original preset, localising to centimetres, knocks or drops parts,
                // which the server then no longer shows where the robot left them.
                if policy == Policy::Ours {
                    assert_eq!(report.server_disagreements, 0, "round {r}: {report:?}");
                }
            }
        }
    }

    #[test]
    fn a_part_the_server_stops_showing_is_not_fetched_and_the_rest_still_score() {
        // Which incoming slot the robot empties last in the normal round.
        let mut picks = Vec::new();
        let options = RoundOptions::new(1, 1, Policy::Ours);
        run_round(&Config::default(), &options, |event| {
            if let RoundEvent::Core {
                event: Event::ActionStarted { pick, .. },
                ..
            } = event
            {
                picks.push(*pick);
            }
        })
        .unwrap();
        let field = Field::competition();
        let last = *picks.last().unwrap();
        let slot = ServerSlot::of_waypoint(&field, last).unwrap();

        // Now a referee takes that part away soon after the start.
        let options = RoundOptions {
            server_removes: Some((slot, START_DELAY_S + 0.5)),
            ..options
        };
        let (mut picks, mut told, mut finished) = (Vec::new(), 0, false);
        let report = run_round(&Config::default(), &options, |event| {
            if let RoundEvent::Core { event, .. } = event {
                match event {
                    Event::ActionStarted { pick, .. } => picks.push(*pick),
                    Event::Finished => finished = true,
                    Event::ServerDisagrees { parts, .. } => told += parts,
                    _ => {}
                }
            }
        })
        .unwrap();
        assert!(!picks.contains(&last), "fetched {last:?}: {picks:?}");
        assert!(finished, "{report:?}");
        assert_eq!((report.points, report.outgoing), (3, 3), "{report:?}");
        assert_eq!(report.timeouts, 0, "{report:?}");
        assert_eq!(report.server_disagreements, 1, "{report:?}");
        assert_eq!(told, 1);
    }
}
