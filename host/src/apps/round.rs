//! A complete simulated Robot@Factory round: the robot's whole stack against the simulated
//! world and a mock of the organisers' server over real UDP on loopback.
//!
//! - The mock server (`referee::server::MockServer`) holds the round's part list; an operator
//!   starts it [`START_DELAY_S`] after power-up, so the robot first hears `STOP`.
//! - The robot asks `IWP` every [`POLL_PERIOD_S`] with the real client
//!   (`referee::client::RefereeClient`) until it gets the part list, then builds its plan
//!   (`competition::TaskActions`) and runs the [`Mission`] with our navigation or the
//!   original's.
//! - While the mission drives to a pick, the client reads `IWP`, `OWP`, `MAP`, `MBP` one
//!   request at a time, a cycle every [`POLL_PERIOD_S`] at most
//!   (`referee::snapshot::SnapshotCycle`: pure, for the robot's own loop as well), and
//!   hands every complete
//!   snapshot to the planner, which re-plans from the server's strings (competition.md §6).
//!   The robot never waits for them: a silent server only means planning from what it knows.
//! - The world's part events are reported to the mock (`place`/`take`), so `IWP`, `OWP`,
//!   `MAP`, `MBP` answer what is really on the floor; the world's own machines turn the parts.
//! - Points are the rules' (competition.md §2): one per correct placement, on a machine that
//!   takes the part or a blue part in the outgoing warehouse. The round's time runs from the
//!   part list to the last placement.
//!
//! The loop is deterministic for a seed: every datagram is sent and answered within the same
//! simulated instant (loopback delivers it before `send` returns).

use std::net::SocketAddr;

use serde::Serialize;

use crate::referee::client::RefereeClient;
use crate::referee::server::MockServer;
use ratf_core::competition::{DrivePreset, RouteNavigator, SnapshotUse, TaskActions};
use ratf_core::config::Config;
use ratf_core::field::Field;
use ratf_core::field::PartColor;
use ratf_core::field::geometry::wrap_angle;
use ratf_core::mission::{Mission, MissionConfig, MissionEvent};
use ratf_core::planning::tasks::{
    BranchAndBound, Location, Model, Original, Policy, Rules, State, StraightLineTimes, Timing,
};
use ratf_core::referee::protocol::{Reply, Request, letters_to_string};
use ratf_core::referee::snapshot::SnapshotCycle;
use ratf_core::referee::tracker::RetryPolicy;
use ratf_sim::harness::SimulatedRobot;
use ratf_sim::parts::{PartEvent, PartPlace};
use ratf_sim::referee::{MockReferee, MockSettings, ServerSlot, round_parts};
use ratf_sim::world::Scenario;

/// When the operator starts the mock server, s after power-up.
pub const START_DELAY_S: f64 = 1.0;
/// How often the robot asks for the part list while waiting, and starts reading the
/// server's four strings while driving to a pick, s.
pub const POLL_PERIOD_S: f64 = 0.2;
/// A round that has not finished after this long is stopped, s of simulated time.
pub const ROUND_LIMIT_S: f64 = 300.0;

/// Which software drives the robot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RoundPolicy {
    /// Our task planner and navigation.
    Ours,
    /// The original's priority planner and line follower.
    Original,
}

/// Something that happened during the round, as it happened.
#[derive(Clone, Debug, PartialEq)]
pub enum RoundEvent {
    /// The server answered the first `IWP` with the part list.
    PartList {
        /// Simulated time, s.
        t_s: f64,
        /// The four letters.
        letters: String,
    },
    /// The mission reported something.
    Mission {
        /// Simulated time, s.
        t_s: f64,
        /// What.
        event: MissionEvent,
    },
    /// The robot (or the part it carries) ran into something.
    Collision(ratf_sim::world::Collision),
    /// A host tick (50 Hz): where the robot truly is and where it believes it is.
    Tick {
        /// Simulated time, s.
        t_s: f64,
        /// True pose.
        truth: ratf_core::field::geometry::Pose2,
        /// The localiser's estimate.
        estimate: ratf_core::field::geometry::Pose2,
    },
    /// The server's strings disagreed with what the robot knew; it re-plans from them.
    ServerDisagrees {
        /// Simulated time of the last answer, s.
        t_s: f64,
        /// Parts that vanished, appeared, moved or changed colour.
        parts: usize,
        /// The four strings, `IWP OWP MAP MBP`.
        letters: String,
    },
    /// A placement scored.
    Points {
        /// Simulated time, s.
        t_s: f64,
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
    pub policy: RoundPolicy,
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
}

/// Why a round could not run.
#[derive(Debug, thiserror::Error)]
pub enum RoundError {
    /// The round number or parts are not valid.
    #[error("{0}")]
    Setup(String),
    /// A socket failed.
    #[error("UDP on loopback: {0}")]
    Io(#[from] std::io::Error),
    /// The IMU driver failed.
    #[error("simulated IMU: {0}")]
    Imu(#[from] ratf_core::drivers::imu::ImuError),
}

/// How a round is run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoundOptions {
    /// Round number (1, 2, 3).
    pub round: u8,
    /// Seed: the part order and all the simulator's noise.
    pub seed: u64,
    /// Who drives.
    pub policy: RoundPolicy,
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
    pub fn new(round: u8, seed: u64, policy: RoundPolicy) -> Self {
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
}

/// Run a round; `on_event` hears the events as they happen.
pub fn run(
    config: &Config,
    options: &RoundOptions,
    mut on_event: impl FnMut(&RoundEvent),
) -> Result<RoundReport, RoundError> {
    let RoundOptions {
        round,
        seed,
        policy,
        machine_delay_s,
        force_start_s,
        silent_server,
        mut server_removes,
    } = *options;
    let mut config = config.clone();
    config.sim.seed = seed;
    let field = Field::competition();
    let letters = round_parts(round, seed).map_err(|e| RoundError::Setup(e.to_string()))?;
    let machine_delay_us = (machine_delay_s * 1e6) as u64;
    let settings = MockSettings::for_round(round, seed, Some(letters), machine_delay_us)
        .map_err(|e| RoundError::Setup(e.to_string()))?;
    let mut server = MockServer::bind(
        SocketAddr::from(([127, 0, 0, 1], 0)),
        MockReferee::new(settings),
    )?;
    let mut client = RefereeClient::new(
        server.local_addr()?,
        0,
        RetryPolicy::from_config(&config.referee),
    )
    .map_err(|e| RoundError::Setup(e.to_string()))?;

    let scenario = Scenario {
        incoming: letters,
        machine_delay_us,
        green_to_blue_at_a: settings.green_to_blue_at_a,
        ..Scenario::new(&config)
    };
    let mut sim = SimulatedRobot::new(&config, &scenario, scenario.start_pose)?;
    let rules = Rules::for_round(round);
    let model = Model::new(
        &StraightLineTimes::new(&field, 0.4, 0.8),
        Timing {
            pick_s: 1.0,
            drop_s: 0.8,
            machine_delay_s,
        },
        rules,
    )
    .map_err(|e| RoundError::Setup(e.to_string()))?;
    let (drive, planner): (DrivePreset, Box<dyn Policy>) = match policy {
        RoundPolicy::Ours => (DrivePreset::Ours, Box::new(BranchAndBound::default())),
        RoundPolicy::Original => (DrivePreset::Original, Box::new(Original::default())),
    };
    let navigator = RouteNavigator::new(&config, drive);
    let mut planner = Some(planner);
    let mut mission: Option<Mission<RouteNavigator, TaskActions>> = None;
    let mut navigator = Some(navigator);

    let mut started_at_s: Option<f64> = None;
    let mut next_poll_s = 0.0;
    let mut server_started = false;
    let mut points = 0u32;
    let mut last_point_s = 0.0;
    let mut timeouts = 0u32;
    let mut finished = false;
    let mut seen_part_events = 0;
    let (mut pos_sq, mut heading_sq, mut samples) = (0.0, 0.0, 0u64);
    let mut seen_collisions = 0;
    let mut last_batches = 0;
    let mut snapshots = SnapshotCycle::new((POLL_PERIOD_S * 1e6) as u64);

    while !finished && (sim.now_us() as f64) * 1e-6 < ROUND_LIMIT_S {
        let now_us = sim.now_us();
        let t_s = now_us as f64 * 1e-6;
        if !server_started && t_s >= START_DELAY_S {
            server.referee_mut().start(now_us);
            server_started = true;
        }
        if let Some((slot, at_s)) = server_removes
            && t_s >= at_s
        {
            let _ = server.referee_mut().take(slot, now_us);
            server_removes = None;
        }
        let mut error = None;
        let ticked = sim.step(|robot, now| {
            let t = now as f64 * 1e-6;
            match mission.as_mut() {
                None => {
                    robot.command_motion(Default::default());
                    if t >= next_poll_s && client.outstanding().is_none() {
                        next_poll_s = t + POLL_PERIOD_S;
                        if let Err(e) = client.send_request(Request::IncomingWarehouse, now) {
                            error = Some(e.to_string());
                        }
                    }
                    if !silent_server
                        && client.outstanding().is_some()
                        && let Err(e) = server.poll(now)
                    {
                        error = Some(e.to_string());
                    }
                    let from_server = match client.poll(now) {
                        Some(Ok(Reply::Slots(list))) => Some((list, "")),
                        _ => None,
                    };
                    let forced = force_start_s
                        .filter(|&at| t >= at)
                        .map(|_| (letters, " (forced by the operator)"));
                    if let Some((list, how)) = from_server.or(forced) {
                        let text: String = list
                            .iter()
                            .map(|c| c.map_or('X', PartColor::letter))
                            .collect();
                        on_event(&RoundEvent::PartList {
                            t_s: t,
                            letters: format!("{text}{how}"),
                        });
                        started_at_s = Some(t);
                        let state = State::from_incoming(&list, Location::Start, 0.0);
                        if let (Some(policy), Some(nav)) = (planner.take(), navigator.take()) {
                            let actions = TaskActions::new(model.clone(), policy, state);
                            mission = Some(Mission::new(
                                MissionConfig {
                                    exit_on_route_after_pick: drive == DrivePreset::Ours,
                                    ..MissionConfig::default()
                                },
                                nav,
                                actions,
                            ));
                        }
                    }
                }
                Some(m) => {
                    let out = m.tick(now, robot.pose(), robot.switch_pressed());
                    robot.command_motion(out.twist);
                    robot.command_solenoid(out.solenoid_on);
                    for event in out.events {
                        if matches!(event, MissionEvent::Skipped { .. }) {
                            timeouts += 1;
                        }
                        if event == MissionEvent::Finished {
                            finished = true;
                        }
                        on_event(&RoundEvent::Mission { t_s: t, event });
                    }
                    // Read the server while the floor is as the planner knows it.
                    if !m.is_before_pick() {
                        m.actions_mut().picking(now);
                        snapshots.restart();
                    } else if client.outstanding().is_none()
                        && let Some(request) = snapshots.request_due(now)
                        && let Err(e) = client.send_request(request, now)
                    {
                        error = Some(e.to_string());
                    }
                    let asked = client.outstanding();
                    if !silent_server
                        && asked.is_some()
                        && let Err(e) = server.poll(now)
                    {
                        error = Some(e.to_string());
                    }
                    let snapshot = client
                        .poll(now)
                        .and_then(|result| snapshots.on_reply(asked, result, now));
                    if let Some(snapshot) = snapshot
                        && let SnapshotUse::Applied { disagreements } =
                            m.actions_mut().offer_snapshot(&snapshot)
                        && disagreements > 0
                    {
                        on_event(&RoundEvent::ServerDisagrees {
                            t_s: t,
                            parts: disagreements,
                            letters: snapshot.areas.map(|a| letters_to_string(&a)).join(" "),
                        });
                    }
                }
            }
        })?;
        if let Some(e) = error {
            return Err(RoundError::Setup(e));
        }
        if ticked {
            on_event(&RoundEvent::Tick {
                t_s: sim.now_us() as f64 * 1e-6,
                truth: sim.world().body().pose,
                estimate: sim.robot().pose(),
            });
        }

        // Tell the referee what happened on the floor, and score it.
        let events = sim.world().part_events()[seen_part_events..].to_vec();
        seen_part_events += events.len();
        for (at_us, event) in events {
            match event {
                PartEvent::Picked { from, .. } => {
                    if let Some(slot) = from.and_then(|id| ServerSlot::of_waypoint(&field, id)) {
                        let _ = server.referee_mut().take(slot, at_us);
                    }
                }
                PartEvent::Placed { slot, color, .. } => {
                    if let Some(server_slot) = ServerSlot::of_waypoint(&field, slot) {
                        let _ = server.referee_mut().place(server_slot, color, at_us);
                    }
                    if scores(&field, rules, slot.0, color) {
                        points += 1;
                        last_point_s = at_us as f64 * 1e-6;
                        on_event(&RoundEvent::Points {
                            t_s: last_point_s,
                            slot: slot.0,
                            color,
                            total: points,
                        });
                    }
                }
                PartEvent::Dropped { .. } | PartEvent::Processed { .. } => {}
            }
        }

        for collision in &sim.world().collisions()[seen_collisions..] {
            on_event(&RoundEvent::Collision(*collision));
        }
        seen_collisions = sim.world().collisions().len();

        let batches = sim.robot().input_counts().wheel_batches;
        if batches != last_batches && started_at_s.is_some() {
            last_batches = batches;
            let Some(truth) = sim.truth_at_last_telemetry() else {
                continue;
            };
            let estimate = sim.robot().pose();
            pos_sq += (estimate.x - truth.x).powi(2) + (estimate.y - truth.y).powi(2);
            heading_sq += wrap_angle(estimate.yaw_rad - truth.yaw_rad).powi(2);
            samples += 1;
        }
    }

    let shop = sim.world().shop();
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
    let (server_disagreements, server_snapshots) = mission.as_ref().map_or((0, 0), |m| {
        let actions = m.actions();
        (
            count(actions.server_disagreements()),
            count(actions.snapshots_applied()),
        )
    });
    let robot_pose = sim.world().body().pose;
    let final_parts = (0..shop.parts().len())
        .map(|i| {
            let p = shop.footprint(i, robot_pose).pose;
            (shop.parts()[i].color, p.x, p.y)
        })
        .collect();
    Ok(RoundReport {
        final_parts,
        round,
        seed,
        policy,
        points,
        outgoing,
        time_s: started_at_s.map_or(0.0, |s| (last_point_s - s).max(0.0)),
        collisions: sim.world().stats().collisions,
        timeouts,
        server_disagreements,
        server_snapshots,
        pos_rmse_m: (pos_sq / n).sqrt(),
        heading_rmse_deg: (heading_sq / n).sqrt().to_degrees(),
    })
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
    pub policy: RoundPolicy,
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
}

/// Every round with both policies over seeds 1..=`seeds`; `on_run` hears each report.
pub fn bench(
    config: &Config,
    seeds: u64,
    machine_delay_s: f64,
    mut on_run: impl FnMut(&RoundReport),
) -> Result<Vec<BenchRow>, RoundError> {
    let mut rows = Vec::new();
    for round in 1..=3 {
        for policy in [RoundPolicy::Ours, RoundPolicy::Original] {
            let mut row = BenchRow {
                round,
                policy,
                full_score_rate: 0.0,
                mean_time_s: 0.0,
                max_time_s: 0.0,
                collisions: 0,
                timeouts: 0,
                runs: 0,
            };
            let mut full = 0u32;
            for seed in 1..=seeds {
                let options = RoundOptions {
                    machine_delay_s,
                    ..RoundOptions::new(round, seed, policy)
                };
                let report = run(config, &options, |_| {})?;
                on_run(&report);
                row.runs += 1;
                row.collisions += report.collisions;
                row.timeouts += report.timeouts;
                if report.points == full_score(round) && report.outgoing == 4 {
                    full += 1;
                    row.mean_time_s += report.time_s;
                    row.max_time_s = row.max_time_s.max(report.time_s);
                }
            }
            row.full_score_rate = f64::from(full) / f64::from(row.runs.max(1));
            row.mean_time_s /= f64::from(full.max(1));
            rows.push(row);
        }
    }
    Ok(rows)
}

/// Whether placing a `color` part at slot waypoint `slot` scores (competition.md §2).
fn scores(field: &Field, rules: Rules, slot: u8, color: PartColor) -> bool {
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

    fn round(round: u8, policy: RoundPolicy) -> RoundReport {
        run(
            &Config::default(),
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
            ..RoundOptions::new(1, 1, RoundPolicy::Ours)
        };
        let mut started = None;
        let report = run(&Config::default(), &options, |event| {
            if let RoundEvent::PartList { t_s, letters } = event {
                started = Some((*t_s, letters.clone()));
            }
        })
        .unwrap();
        let (t_s, letters) = started.expect("the round never started");
        // Nothing came from the server: the start is the operator's, at 3 s.
        assert!((3.0..3.03).contains(&t_s), "started at {t_s}");
        assert!(letters.ends_with("(forced by the operator)"), "{letters}");
        assert_eq!(report.points, 4);
        assert_eq!(
            report.server_snapshots, 0,
            "the robot planned from what it knew"
        );
    }

    #[test]
    fn every_round_reaches_full_score_at_seed_1() {
        for (r, points) in [(1, 4), (2, 6), (3, 8)] {
            let report = round(r, RoundPolicy::Ours);
            assert_eq!(report.points, points, "round {r}: {report:?}");
            assert_eq!(report.outgoing, 4, "round {r}: {report:?}");
            assert!(report.time_s > 0.0);
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_round() {
        assert_eq!(round(2, RoundPolicy::Ours), round(2, RoundPolicy::Ours));
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
    }

    #[test]
    fn every_round_reads_the_server_and_agrees_with_it_at_seed_1() {
        for r in 1..=3 {
            for policy in [RoundPolicy::Ours, RoundPolicy::Original] {
                let report = round(r, policy);
                assert!(report.server_snapshots > 0, "round {r}: {report:?}");
                assert_eq!(report.server_disagreements, 0, "round {r}: {report:?}");
            }
        }
    }

    #[test]
    fn a_part_the_server_stops_showing_is_not_fetched_and_the_rest_still_score() {
        // Which incoming slot the robot empties last in the normal round.
        let mut picks = Vec::new();
        let options = RoundOptions::new(1, 1, RoundPolicy::Ours);
        run(&Config::default(), &options, |event| {
            if let RoundEvent::Mission {
                event: MissionEvent::ActionStarted { action, .. },
                ..
            } = event
            {
                picks.push(action.pick);
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
        let report = run(&Config::default(), &options, |event| match event {
            RoundEvent::Mission { event, .. } => match event {
                MissionEvent::ActionStarted { action, .. } => picks.push(action.pick),
                MissionEvent::Finished => finished = true,
                _ => {}
            },
            RoundEvent::ServerDisagrees { parts, .. } => told += parts,
            _ => {}
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
