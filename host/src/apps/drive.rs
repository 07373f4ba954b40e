//! Drive the simulated robot through a velocity script and measure its odometry against the
//! ground truth.
//!
//! The robot's core believes it starts where it truly does. At every host tick (50 Hz) its
//! dead-reckoning (wheel odometry alone) is compared with the true pose *at the Mega tick
//! whose counts it has last integrated* (`World::tick_poses`), so the telemetry's few
//! milliseconds in flight are not counted as drift. The localiser's estimate (odometry, gyro
//! and beacons) is reported beside it. The run ends one second after the script's last
//! keyframe, at rest.

use serde::Serialize;

use crate::apps::scripts::{Named, Script};
use ratf_core::config::Config;
use ratf_core::drivers::imu::ImuError;
use ratf_core::field::geometry::{Pose2, Vec2, wrap_angle};
use ratf_sim::harness::SimulatedRobot;
use ratf_sim::world::{Collision, Scenario};

/// Seconds simulated after the script's last keyframe, for the robot to come to rest.
const SETTLE_S: f64 = 1.0;

/// A pose in a log line: metres and degrees.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PoseRecord {
    /// x, m.
    pub x_m: f64,
    /// y, m.
    pub y_m: f64,
    /// Yaw, degrees in (−180, 180].
    pub yaw_deg: f64,
}

impl From<Pose2> for PoseRecord {
    fn from(p: Pose2) -> Self {
        Self {
            x_m: p.x,
            y_m: p.y,
            yaw_deg: wrap_angle(p.yaw_rad).to_degrees(),
        }
    }
}

/// One line of the JSON-lines log, per host tick.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TickRecord {
    /// Simulated time, s.
    pub t_s: f64,
    /// True pose now.
    pub truth: PoseRecord,
    /// Odometry now.
    pub odometry: PoseRecord,
    /// Odometry minus the true pose at the tick it has integrated, m.
    pub odometry_error_m: f64,
    /// Commanded twist: vx m/s, vy m/s, ω rad/s (robot frame).
    pub command: [f64; 3],
    /// The factor the core scaled the command by for the wheel limit.
    pub twist_scale: f64,
    /// Motor PWMs applied by the Mega.
    pub pwm: [i16; 4],
    /// Wheel slip steps so far.
    pub slip_steps: u64,
    /// Collisions so far.
    pub collisions: u32,
}

/// What a run measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DriveReport {
    /// The script's name.
    pub script: String,
    /// The simulator's seed.
    pub seed: u64,
    /// Simulated time, s.
    pub sim_s: f64,
    /// Length of the true path, m.
    pub distance_m: f64,
    /// Position error of the odometry at the end, at rest, m.
    pub final_pos_err_m: f64,
    /// Heading error of the odometry at the end, degrees.
    pub final_heading_err_deg: f64,
    /// Largest position error of the odometry during the run, m.
    pub max_pos_err_m: f64,
    /// Largest heading error of the odometry during the run, degrees.
    pub max_heading_err_deg: f64,
    /// Position error of the localiser's estimate at the end, m.
    pub localiser_final_pos_err_m: f64,
    /// Largest position error of the localiser's estimate during the run, m.
    pub localiser_max_pos_err_m: f64,
    /// Simulator steps in which the wheels slipped.
    pub slip_steps: u64,
    /// Collisions with walls, dividers, beacons or parts.
    pub collisions: u32,
    /// Largest factor the commanded twist was scaled down by for the wheel limit (1 = never).
    pub min_twist_scale: f64,
}

/// What to draw: the paths, footprints once a second, the collisions.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DriveTrace {
    /// True positions, one per host tick.
    pub truth: Vec<Vec2>,
    /// Odometry positions, one per host tick.
    pub odometry: Vec<Vec2>,
    /// True poses once a second.
    pub footprints: Vec<Pose2>,
    /// Every collision.
    pub collisions: Vec<Collision>,
}

/// Run `named` with `config`; `on_tick` gets every log record as it is made.
pub fn run(
    config: &Config,
    named: Named,
    mut on_tick: impl FnMut(&TickRecord),
) -> Result<(DriveReport, DriveTrace), ImuError> {
    let script: Script = named.script();
    let scenario = Scenario {
        start_pose: script.start,
        ..Scenario::new(config)
    };
    let mut sim = SimulatedRobot::new(config, &scenario, script.start)?;
    let end_us = ((script.duration_s() + SETTLE_S) * 1e6) as u64;
    let mut trace = DriveTrace::default();
    let mut report = DriveReport {
        script: named.name().to_owned(),
        seed: config.sim.seed,
        sim_s: 0.0,
        distance_m: 0.0,
        final_pos_err_m: 0.0,
        final_heading_err_deg: 0.0,
        max_pos_err_m: 0.0,
        max_heading_err_deg: 0.0,
        localiser_final_pos_err_m: 0.0,
        localiser_max_pos_err_m: 0.0,
        slip_steps: 0,
        collisions: 0,
        min_twist_scale: 1.0,
    };
    let mut command = [0.0; 3];
    let mut next_footprint_us = 0;
    while sim.now_us() < end_us {
        let ticked = sim.step(|robot, now_us| {
            let twist = script.twist_at(now_us as f64 * 1e-6);
            command = [twist.vx_m_s, twist.vy_m_s, twist.omega_rad_s];
            robot.command_motion(twist);
        })?;
        if !ticked {
            continue;
        }
        let now_us = sim.now_us();
        let truth = sim.world().body().pose;
        let odometry = sim.robot().estimation().odometry_pose();
        let at_tick = sim.truth_at_last_telemetry();
        let (pos_err, heading_err) = at_tick.map_or((0.0, 0.0), |t| pose_error(odometry, t));
        let (estimate_err, _) = at_tick.map_or((0.0, 0.0), |t| pose_error(sim.robot().pose(), t));
        report.max_pos_err_m = report.max_pos_err_m.max(pos_err);
        report.max_heading_err_deg = report.max_heading_err_deg.max(heading_err);
        report.localiser_max_pos_err_m = report.localiser_max_pos_err_m.max(estimate_err);
        if let Some(&last) = trace.truth.last() {
            report.distance_m += last.distance(truth.position());
        }
        trace.truth.push(truth.position());
        trace.odometry.push(odometry.position());
        if now_us >= next_footprint_us {
            trace.footprints.push(truth);
            next_footprint_us += 1_000_000;
        }
        let output = sim.last_output();
        let scale = output.map_or(1.0, |o| o.twist_scale);
        report.min_twist_scale = report.min_twist_scale.min(scale);
        let stats = sim.world().stats();
        on_tick(&TickRecord {
            t_s: now_us as f64 * 1e-6,
            truth: truth.into(),
            odometry: odometry.into(),
            odometry_error_m: pos_err,
            command,
            twist_scale: scale,
            pwm: sim.world().actuation().pwm,
            slip_steps: stats.slip_steps,
            collisions: stats.collisions,
        });
    }
    let truth = sim.world().body().pose;
    let (final_pos, final_heading) = pose_error(sim.robot().estimation().odometry_pose(), truth);
    report.localiser_final_pos_err_m = pose_error(sim.robot().pose(), truth).0;
    let stats = sim.world().stats();
    report.sim_s = sim.now_us() as f64 * 1e-6;
    report.final_pos_err_m = final_pos;
    report.final_heading_err_deg = final_heading;
    report.slip_steps = stats.slip_steps;
    report.collisions = stats.collisions;
    trace.collisions = sim.world().collisions().to_vec();
    Ok((report, trace))
}

/// Position (m) and absolute heading (degrees) difference between two poses.
fn pose_error(estimate: Pose2, truth: Pose2) -> (f64, f64) {
    (
        estimate.position().distance(truth.position()),
        wrap_angle(estimate.yaw_rad - truth.yaw_rad)
            .abs()
            .to_degrees(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_square_runs_without_collision_and_odometry_stays_close() {
        let config = Config::default().in_world(ratf_core::config::WorldProfile::Ideal);
        let mut lines = 0;
        let (report, trace) = run(&config, Named::Square, |_| lines += 1).unwrap();
        assert_eq!(report.collisions, 0, "{:?}", trace.collisions);
        assert_eq!(
            report.slip_steps, 0,
            "0.3 m/s with 0.3 s ramps stays within traction"
        );
        // About 2.6 m of path; the odometry integrates exact wheel angles up to a tick.
        assert!(
            (report.distance_m - 2.6).abs() < 0.15,
            "{}",
            report.distance_m
        );
        assert!(report.final_pos_err_m < 0.005, "{report:?}");
        assert_eq!(lines, trace.truth.len());
    }

    #[test]
    fn the_dash_slips_and_its_odometry_drifts_more_than_the_square() {
        let config = Config::default().in_world(ratf_core::config::WorldProfile::Ideal);
        let (square, _) = run(&config, Named::Square, |_| {}).unwrap();
        let (dash, _) = run(&config, Named::Dash, |_| {}).unwrap();
        assert!(dash.slip_steps > 0);
        assert!(
            dash.min_twist_scale < 0.8,
            "1 m/s is beyond the wheels' limit"
        );
        assert!(dash.final_pos_err_m > square.final_pos_err_m);
    }

    #[test]
    fn the_same_seed_gives_a_byte_identical_log() {
        let config = Config::default();
        let log = |c: &Config| {
            let mut text = String::new();
            run(c, Named::FigureEight, |r| {
                text.push_str(&serde_json::to_string(r).unwrap());
                text.push('\n');
            })
            .unwrap();
            text
        };
        assert_eq!(log(&config), log(&config));
    }
}
