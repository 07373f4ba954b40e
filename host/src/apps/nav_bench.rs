//! The navigation benchmark: the trips a round needs, driven in the simulator by our
//! follower and by the original 5dpo one, with the robot core's pose estimate in the loop.
//!
//! Choice (stated): every trip is a fresh simulation that starts with the robot truly at the
//! trip's start pose (the field's start pose or the previous slot's pick pose) and the core
//! believing so, so each trip measures the follower and not the drift accumulated over the
//! earlier ones. The Mega boots during [`BOOT_S`] of standstill before the clock starts.
//! The incoming warehouse holds a part in each slot (docking there ends on the switch;
//! elsewhere it ends at the pick pose); the robot carries nothing, so our shortcuts are
//! checked for the bare robot's swept disc.
//!
//! A trip ends when the follower reports `Arrived` or `Docked`, or after [`TIMEOUT_S`]
//! (counted); into the incoming warehouse, our follower's docking approach that arrives with
//! the switch open goes on into the navigator's creep to contact
//! (`ratf_core::control::creep`), as in a round (the original follower's trips end where it
//! ends, as they always have here). Then the robot is left [`SETTLE_S`] at rest and its true pose compared with
//! the goal (the slot's pick pose). Cross-track error is the true position's distance to the
//! route polyline, every host tick.

use serde::Serialize;

use ratf_core::config::Config;
use ratf_core::control::creep::{Creep, CreepLimits};
use ratf_core::control::follower::{Follower, PathFollower, Status};
use ratf_core::control::original::{OriginalFollower, OriginalParams};
use ratf_core::control::route::{LegPlanner, ORIGINAL_APPROACH_M, Route, plan_original_route};
use ratf_core::drivers::imu::ImuError;
use ratf_core::field::PartColor;
use ratf_core::field::geometry::{Pose2, Segment, wrap_angle};
use ratf_core::field::{Field, SlotKind, WaypointId};
use ratf_core::planning::graph::{PlanError, RoadMap};
use ratf_sim::harness::SimulatedRobot;
use ratf_sim::world::{Collision, Scenario};

/// Standstill before each trip while the Mega boots and telemetry starts, s.
pub const BOOT_S: f64 = 0.2;
/// A trip that has not ended after this long counts as timed out, s.
pub const TIMEOUT_S: f64 = 20.0;
/// Standstill after the end before the pose is measured, s (the motors' 0.1 s time
/// constant, three times over).
pub const SETTLE_S: f64 = 0.3;

/// Which follower.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Preset {
    /// Ours, with `config.navigation` (shortcuts as configured).
    Ours,
    /// The original 5dpo follower on its own routes.
    Original,
}

/// Where a trip starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Place {
    /// The field's start pose.
    Start,
    /// A slot's pick pose, by its waypoint.
    Slot(u8),
}

/// One trip: from a place to a slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Trip {
    /// Start.
    pub from: Place,
    /// Goal slot's waypoint.
    pub to: u8,
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum NavBenchError {
    /// The simulated IMU failed (a simulator bug).
    #[error("simulated IMU: {0}")]
    Imu(#[from] ImuError),
    /// No route.
    #[error("planning {0:?}: {1}")]
    Plan(Trip, PlanError),
    /// A waypoint without a slot.
    #[error("waypoint {0} serves no slot")]
    NoSlot(u8),
}

/// What one trip measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TripResult {
    /// The trip.
    pub trip: Trip,
    /// The simulator seed.
    pub seed: u64,
    /// Time from the start to the end (or the timeout), s.
    pub time_s: f64,
    /// It did not end in time.
    pub timed_out: bool,
    /// It ended on the box switch.
    pub docked_on_switch: bool,
    /// True final position's distance to the goal, m.
    pub goal_pos_err_m: f64,
    /// True final heading's difference to the goal's, degrees.
    pub goal_heading_err_deg: f64,
    /// Largest true distance to the route, m.
    pub max_cross_track_m: f64,
    /// Collisions during the trip.
    pub collisions: u32,
    /// The first collision, if any: what was hit and the true pose then.
    pub first_collision: Option<String>,
    /// Route length, m.
    pub route_length_m: f64,
}

/// Per-preset figures, the shape of the `--json` output.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Summary {
    /// Trips run.
    pub trips: usize,
    /// Trips that timed out.
    pub timeouts: usize,
    /// Mean trip time, s (timed-out trips count at the timeout).
    pub mean_trip_s: f64,
    /// Longest trip, s.
    pub max_trip_s: f64,
    /// Largest final position error at the goal, m.
    pub goal_pos_err_m: f64,
    /// Largest final heading error at the goal, degrees.
    pub goal_heading_err_deg: f64,
    /// Largest cross-track error, m.
    pub max_cross_track_m: f64,
    /// Collisions over all trips.
    pub collisions: u32,
}

impl Summary {
    /// Summarise `results`.
    pub fn of(results: &[TripResult]) -> Self {
        let mut s = Self {
            trips: results.len(),
            ..Self::default()
        };
        for r in results {
            s.timeouts += usize::from(r.timed_out);
            s.mean_trip_s += r.time_s;
            s.max_trip_s = s.max_trip_s.max(r.time_s);
            s.goal_pos_err_m = s.goal_pos_err_m.max(r.goal_pos_err_m);
            s.goal_heading_err_deg = s.goal_heading_err_deg.max(r.goal_heading_err_deg);
            s.max_cross_track_m = s.max_cross_track_m.max(r.max_cross_track_m);
            s.collisions += r.collisions;
        }
        if !results.is_empty() {
            s.mean_trip_s /= results.len() as f64;
        }
        s
    }
}

/// The trips a round needs: start → each incoming slot; each incoming slot → each machine
/// input; each machine output → each outgoing slot; machine A outputs → machine B inputs;
/// each outgoing slot → the incoming slot above it in order (the next part).
pub fn round_trips() -> Vec<Trip> {
    let incoming = [50u8, 51, 52, 53];
    let outgoing = [62u8, 63, 64, 65];
    let inputs = [56u8, 60, 54, 58];
    let outputs = [57u8, 61, 55, 59];
    let mut trips: Vec<Trip> = incoming
        .iter()
        .map(|&to| Trip {
            from: Place::Start,
            to,
        })
        .collect();
    for &from in &incoming {
        for &to in &inputs {
            trips.push(Trip {
                from: Place::Slot(from),
                to,
            });
        }
    }
    for &from in &outputs {
        for &to in &outgoing {
            trips.push(Trip {
                from: Place::Slot(from),
                to,
            });
        }
    }
    for &from in &[57u8, 61] {
        for &to in &[54u8, 58] {
            trips.push(Trip {
                from: Place::Slot(from),
                to,
            });
        }
    }
    for (&from, &to) in outgoing.iter().zip(&incoming) {
        trips.push(Trip {
            from: Place::Slot(from),
            to,
        });
    }
    trips
}

/// The scenario: a part in every incoming slot.
fn scenario(config: &Config, start: Pose2) -> Scenario {
    Scenario {
        start_pose: start,
        incoming: [Some(PartColor::Red); 4],
        ..Scenario::new(config)
    }
}

/// The true pose at `place`.
fn start_pose(field: &Field, place: Place) -> Result<Pose2, NavBenchError> {
    match place {
        Place::Start => Ok(field.start_pose()),
        Place::Slot(id) => field
            .slot_for_waypoint(WaypointId(id))
            .map(|s| s.pick_pose)
            .ok_or(NavBenchError::NoSlot(id)),
    }
}

/// The route each preset drives for `trip`: ours as our navigator plans it
/// ([`LegPlanner`], empty: every trip ends docking on a part), the original's on its graph.
pub fn route_for(config: &Config, preset: Preset, trip: Trip) -> Result<Route, NavBenchError> {
    let field = Field::competition();
    let start = start_pose(&field, trip.from)?;
    let goal = field
        .slot_for_waypoint(WaypointId(trip.to))
        .ok_or(NavBenchError::NoSlot(trip.to))?;
    let route = match preset {
        Preset::Ours => LegPlanner::new(config).plan(start, goal, false),
        Preset::Original => {
            let map = RoadMap::new(field.waypoints().clone());
            plan_original_route(&map, start, goal, ORIGINAL_APPROACH_M)
        }
    };
    route.map_err(|e| NavBenchError::Plan(trip, e))
}

/// Distance from `p` to the polyline, m.
fn distance_to_route(route: &Route, p: ratf_core::field::Vec2) -> f64 {
    route
        .points()
        .windows(2)
        .map(|w| Segment::new(w[0], w[1]).distance_to_point(p))
        .fold(f64::INFINITY, f64::min)
}

/// Drive one trip with `preset` in a fresh simulation seeded `seed`.
pub fn run_trip(
    config: &Config,
    preset: Preset,
    trip: Trip,
    seed: u64,
) -> Result<TripResult, NavBenchError> {
    let mut config = config.clone();
    config.sim.seed = seed;
    let route = route_for(&config, preset, trip)?;
    let field = Field::competition();
    let start = start_pose(&field, trip.from)?;
    let slot = field
        .slot_for_waypoint(WaypointId(trip.to))
        .ok_or(NavBenchError::NoSlot(trip.to))?;
    let goal = slot.pick_pose;
    let mut follower: Box<dyn PathFollower> = match preset {
        Preset::Ours => Box::new(Follower::new(&config)),
        Preset::Original => {
            let left = match trip.from {
                Place::Start => None,
                Place::Slot(id) => field.waypoints().position(WaypointId(id)),
            };
            Box::new(OriginalFollower::new(OriginalParams::default()).with_start_location(left))
        }
    };
    let route_length_m = route.length_m();
    // Only the incoming warehouse holds parts here: elsewhere there is nothing to creep to.
    let creep = (preset == Preset::Ours && slot.kind == SlotKind::Incoming)
        .then(|| CreepLimits::ours(&config.navigation));
    let drive = drive_route(
        &config,
        &scenario(&config, start),
        &route,
        follower.as_mut(),
        creep,
        TIMEOUT_S,
    )?;
    Ok(TripResult {
        trip,
        seed,
        time_s: drive.time_s,
        timed_out: drive.status == Status::Following,
        docked_on_switch: drive.status == Status::Docked,
        goal_pos_err_m: drive.final_pose.position().distance(goal.position()),
        goal_heading_err_deg: wrap_angle(drive.final_pose.yaw_rad - goal.yaw_rad)
            .abs()
            .to_degrees(),
        max_cross_track_m: drive.max_cross_track_m,
        collisions: drive.collisions,
        first_collision: drive.collision_log.first().map(|c| {
            format!(
                "{:?} at ({:.3}, {:.3}, {:.0} deg)",
                c.with,
                c.pose.x,
                c.pose.y,
                c.pose.yaw_rad.to_degrees()
            )
        }),
        route_length_m,
    })
}

/// What driving one route measured (ground truth).
#[derive(Clone, Debug, PartialEq)]
pub struct DriveOutcome {
    /// How it ended (`Following` = timed out).
    pub status: Status,
    /// Time from the start to the end, s.
    pub time_s: f64,
    /// True pose after the settling time.
    pub final_pose: Pose2,
    /// Largest true distance to the route, m.
    pub max_cross_track_m: f64,
    /// Largest true speed, m/s.
    pub max_speed_m_s: f64,
    /// Largest true acceleration over one host period, m/s².
    pub max_accel_m_s2: f64,
    /// Largest true yaw rate, rad/s.
    pub max_yaw_rate_rad_s: f64,
    /// Collisions.
    pub collisions: u32,
    /// Wheel slip steps.
    pub slip_steps: u64,
    /// Each collision: time, what, true pose.
    pub collision_log: Vec<Collision>,
}

/// Drive `route` with `follower` in a fresh simulation of `scenario` (the core believes the
/// robot starts at the scenario's true start): [`BOOT_S`] at rest, then the follower until it
/// ends or `timeout_s` (with `creep`, a docking approach that arrives with the switch open
/// creeps on to contact), then [`SETTLE_S`] at rest.
pub fn drive_route(
    config: &Config,
    scenario: &Scenario,
    route: &Route,
    follower: &mut dyn PathFollower,
    creep: Option<CreepLimits>,
    timeout_s: f64,
) -> Result<DriveOutcome, NavBenchError> {
    let mut sim = SimulatedRobot::new(config, scenario, scenario.start_pose)?;
    let boot_us = (BOOT_S * 1e6) as u64;
    while sim.now_us() < boot_us {
        sim.step(|robot, _| robot.command_motion(Default::default()))?;
    }
    let collisions_before = sim.world().stats().collisions;
    follower.start(route.clone());
    let started_us = sim.now_us();
    let timeout_us = started_us + (timeout_s * 1e6) as u64;
    let mut status = Status::Following;
    let mut out = DriveOutcome {
        status,
        time_s: 0.0,
        final_pose: scenario.start_pose,
        max_cross_track_m: 0.0,
        max_speed_m_s: 0.0,
        max_accel_m_s2: 0.0,
        max_yaw_rate_rad_s: 0.0,
        collisions: 0,
        slip_steps: 0,
        collision_log: Vec::new(),
    };
    let mut last_velocity: Option<(u64, ratf_core::field::Vec2)> = None;
    let mut creeping: Option<Creep> = None;
    while status == Status::Following && sim.now_us() < timeout_us {
        let ticked = sim.step(|robot, now_us| {
            let (pose, switch) = (robot.pose(), robot.switch_pressed());
            let (twist, now_status) = match creeping {
                Some(creep) => creep.update(pose, switch),
                None => {
                    let command = follower.update(now_us, pose, switch);
                    match creep {
                        Some(limits)
                            if command.status == Status::Arrived && route.docks_on_switch() =>
                        {
                            let started = Creep::new(pose, limits);
                            creeping = Some(started);
                            started.update(pose, false)
                        }
                        _ => (command.twist, command.status),
                    }
                }
            };
            status = now_status;
            robot.command_motion(twist);
        })?;
        if ticked {
            let body = sim.world().body();
            let velocity = ratf_core::field::Vec2::new(body.twist.vx_m_s, body.twist.vy_m_s)
                .rotated(body.pose.yaw_rad);
            out.max_cross_track_m = out
                .max_cross_track_m
                .max(distance_to_route(route, body.pose.position()));
            out.max_speed_m_s = out.max_speed_m_s.max(velocity.norm());
            out.max_yaw_rate_rad_s = out.max_yaw_rate_rad_s.max(body.twist.omega_rad_s.abs());
            let now_us = sim.now_us();
            if let Some((t, v)) = last_velocity {
                let dt_s = (now_us - t) as f64 * 1e-6;
                out.max_accel_m_s2 = out.max_accel_m_s2.max((velocity - v).norm() / dt_s);
            }
            last_velocity = Some((now_us, velocity));
        }
    }
    out.status = status;
    out.time_s = (sim.now_us() - started_us) as f64 * 1e-6;
    let settle_until = sim.now_us() + (SETTLE_S * 1e6) as u64;
    while sim.now_us() < settle_until {
        sim.step(|robot, _| robot.command_motion(Default::default()))?;
    }
    out.final_pose = sim.world().body().pose;
    out.collisions = sim.world().stats().collisions - collisions_before;
    out.slip_steps = sim.world().stats().slip_steps;
    out.collision_log = sim.world().collisions().to_vec();
    Ok(out)
}

/// Every round trip for `preset`, for seeds `first_seed..first_seed + seeds`.
pub fn run_preset(
    config: &Config,
    preset: Preset,
    first_seed: u64,
    seeds: u64,
    trips: &[Trip],
) -> Result<Vec<TripResult>, NavBenchError> {
    let mut results = Vec::new();
    for seed in first_seed..first_seed + seeds {
        for &trip in trips {
            results.push(run_trip(config, preset, trip, seed)?);
        }
    }
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn the_round_has_44_distinct_trips_to_slots() {
        let trips = round_trips();
        assert_eq!(trips.len(), 4 + 16 + 16 + 4 + 4);
        let field = Field::competition();
        for t in &trips {
            assert!(field.slot_for_waypoint(WaypointId(t.to)).is_some());
        }
        let mut unique = trips.clone();
        unique.dedup();
        assert_eq!(unique.len(), trips.len());
    }

    #[test]
    fn summary_takes_means_and_maxima() {
        let r = |t: f64, e: f64, c: u32| TripResult {
            trip: Trip {
                from: Place::Start,
                to: 50,
            },
            seed: 0,
            time_s: t,
            timed_out: false,
            docked_on_switch: false,
            goal_pos_err_m: e,
            goal_heading_err_deg: 0.5,
            max_cross_track_m: 0.01,
            collisions: c,
            first_collision: None,
            route_length_m: 1.0,
        };
        let s = Summary::of(&[r(2.0, 0.004, 0), r(4.0, 0.002, 1)]);
        assert_eq!((s.trips, s.mean_trip_s, s.max_trip_s), (2, 3.0, 4.0));
        assert_eq!((s.goal_pos_err_m, s.collisions), (0.004, 1));
    }

    use ratf_core::control::route::turn_window;
    use ratf_core::field::{Rect, Vec2};
    use ratf_core::planning::shortcuts::{Footprint, FreeSpace};

    fn bare_space(config: &Config, parts: &[Rect]) -> FreeSpace {
        let footprint = Footprint::of_robot(&config.robot, false);
        FreeSpace::new(
            &Field::competition(),
            parts,
            footprint,
            config.navigation.shortcut_margin_m,
        )
    }

    /// Drive our follower along `points` from a true start at the first point with
    /// `start_yaw`, turning where the planner would let it.
    fn drive_ours(
        config: &Config,
        points: &[(f64, f64)],
        start_yaw: f64,
        goal_yaw: f64,
    ) -> DriveOutcome {
        let points: Vec<Vec2> = points.iter().map(|&(x, y)| Vec2::new(x, y)).collect();
        let start = Pose2::new(points[0].x, points[0].y, start_yaw);
        let route = Route::new(points, start_yaw, goal_yaw, 0.0).unwrap();
        let (from, to) = turn_window(&route, &bare_space(config, &[]), &config.navigation);
        let route = route.with_turn_window(from, to);
        let scenario = Scenario {
            start_pose: start,
            ..Scenario::new(config)
        };
        let mut follower = Follower::new(config);
        drive_route(config, &scenario, &route, &mut follower, None, 8.0).unwrap()
    }

    fn assert_reached(out: &DriveOutcome, goal: Pose2) {
        assert_eq!(out.status, Status::Arrived, "{out:?}");
        assert_eq!(out.collisions, 0, "{:?}", out.collision_log);
        let err = out.final_pose.position().distance(goal.position());
        assert!(err < 0.01, "position error {err} m: {out:?}");
        let heading = wrap_angle(out.final_pose.yaw_rad - goal.yaw_rad).abs();
        assert!(heading < 2f64.to_radians(), "heading error {heading} rad");
    }

    #[test]
    fn the_follower_reaches_the_goal_on_a_straight_path_within_the_limits() {
        let config = Config::default();
        let nav = &config.navigation;
        let out = drive_ours(
            &config,
            &[(-0.695, -0.355), (-0.695, 0.2)],
            FRAC_PI_2,
            FRAC_PI_2,
        );
        assert_reached(&out, Pose2::new(-0.695, 0.2, FRAC_PI_2));
        // The profile's limits hold on the true motion (the body lags the commands, so the
        // true acceleration over a 20 ms period may exceed the command's ramp by little).
        assert!(out.max_speed_m_s <= nav.max_speed_m_s * 1.02, "{out:?}");
        assert!(
            out.max_speed_m_s > nav.max_speed_m_s * 0.8,
            "it did speed up: {out:?}"
        );
        assert!(out.max_accel_m_s2 <= nav.max_accel_m_s2 * 1.25, "{out:?}");
        assert_eq!(out.slip_steps, 0);
        // 0.555 m at up to 0.6 m/s with 2 m/s² ramps: about 1.2 s plus the final hold.
        assert!(out.time_s < 2.0, "{out:?}");
    }

    #[test]
    fn lower_configured_limits_are_respected_in_simulation() {
        // The ideal world: the limits, not the realistic world's odometry error at the goal.
        let mut config = Config::default().in_world(ratf_core::config::WorldProfile::Ideal);
        config.navigation.max_speed_m_s = 0.3;
        config.navigation.max_accel_m_s2 = 1.0;
        config.navigation.max_yaw_rate_rad_s = 1.0;
        let out = drive_ours(&config, &[(-0.695, -0.355), (-0.695, 0.2)], FRAC_PI_2, 0.0);
        assert_reached(&out, Pose2::new(-0.695, 0.2, 0.0));
        assert!(out.max_speed_m_s <= 0.3 * 1.02, "{out:?}");
        assert!(out.max_accel_m_s2 <= 1.0 * 1.25, "{out:?}");
        assert!(out.max_yaw_rate_rad_s <= 1.0 * 1.05, "{out:?}");
    }

    #[test]
    fn the_follower_turns_an_l_shaped_path() {
        let config = Config::default();
        let out = drive_ours(
            &config,
            &[(-0.65, 0.1), (-0.65, -0.42), (-0.2, -0.42)],
            FRAC_PI_2,
            0.0,
        );
        assert_reached(&out, Pose2::new(-0.2, -0.42, 0.0));
        assert!(out.max_cross_track_m < 0.03, "{out:?}");
    }

    #[test]
    fn the_follower_turns_a_u_shaped_path() {
        let config = Config::default();
        let out = drive_ours(
            &config,
            &[
                (-0.65, 0.15),
                (-0.65, -0.42),
                (-0.05, -0.42),
                (-0.05, -0.10),
            ],
            -FRAC_PI_2,
            FRAC_PI_2,
        );
        assert_reached(&out, Pose2::new(-0.05, -0.10, FRAC_PI_2));
        assert!(out.max_cross_track_m < 0.03, "{out:?}");
    }

    #[test]
    fn docking_stops_on_the_switch_square_to_the_part() {
        let config = Config::default();
        let trip = Trip {
            from: Place::Start,
            to: 51,
        };
        let result = run_trip(&config, Preset::Ours, trip, config.sim.seed).unwrap();
        assert!(result.docked_on_switch, "{result:?}");
        assert_eq!(result.collisions, 0);
        assert!(
            result.goal_pos_err_m < 0.01 && result.goal_heading_err_deg < 2.0,
            "{result:?}"
        );
        // Without a part the switch never closes: docking ends on the distance.
        let mut scenario = scenario(&config, Field::competition().start_pose());
        scenario.incoming = [None; 4];
        let route = route_for(&config, Preset::Ours, trip).unwrap();
        let mut follower = Follower::new(&config);
        let out = drive_route(&config, &scenario, &route, &mut follower, None, 8.0).unwrap();
        assert_eq!(out.status, Status::Arrived);
        assert!(out.final_pose.position().distance(route.goal().position()) < 0.01);
    }

    #[test]
    fn the_original_preset_reaches_a_slot_at_its_constant_speed() {
        let config = Config::default();
        let trip = Trip {
            from: Place::Start,
            to: 50,
        };
        let result = run_trip(&config, Preset::Original, trip, config.sim.seed).unwrap();
        assert!(!result.timed_out, "{result:?}");
        // It stops within its 0.04 m switching distance (plus coasting) of the goal.
        assert!(result.goal_pos_err_m < 0.06, "{result:?}");
        // Constant 0.4 m/s then 0.159 m/s in the 0.2 m slow zone: no faster than that.
        assert!(
            result.time_s > (result.route_length_m - 0.2) / 0.4,
            "{result:?}"
        );
    }
}
