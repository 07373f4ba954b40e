//! `ratf calibrate`: drive the calibration drive through the robot's runtime ([`drive`]),
//! fit the lidar's range scale and offset, its mount yaw and the beacons
//! ([`ratf_core::calibration`]); in the simulator, compare the fit with the world's truth,
//! which the robot never sees.
//!
//! The world is built from the configuration the team wrote before calibrating (its
//! beliefs) plus the drawn errors; the calibration changes only the robot's beliefs, so
//! a round run after it (`ratf bench rounds --calibrated`) is in the same world.

use serde::Serialize;

pub mod drive;
pub mod odometry;
pub mod odometry_cli;
pub mod outline;
pub mod robot;

use crate::apps::scripts::calibration_drive;
use drive::drive_and_collect;
use outline::Outline;
use ratf_core::calibration::{
    self, Calibration, CalibrationError, PoleFromSheet, Priors, TapeMeasure,
};
use ratf_core::config::{Config, WorldProfile};
use ratf_core::drivers::imu::ImuError;
use ratf_core::field::geometry::{Vec2, wrap_angle};
use ratf_core::rng::SimRng;
use ratf_core::runtime::Core;
use ratf_sim::devices::SimDevices;
use ratf_sim::truth::WorldTruth;
use ratf_sim::world::Scenario;

/// The tape measures a team takes on the day, in the simulator: the distance between every
/// two poles (the four sides and both diagonals of their quadrilateral, which make the
/// layout rigid).
const TAPED_SIDES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// What a team measures on the day besides the drive, in the simulator (each drawn from the
/// world's truth with its σ, `Priors::tape_sigma_m` and `Priors::pole_from_sheet_sigma_m`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DayMeasures {
    /// The distance between every two poles (the four sides and both diagonals).
    pub tape: bool,
    /// Every pole's centre from the floor sheet's edges ([`PoleFromSheet`]).
    pub poles_from_sheet: bool,
}

impl DayMeasures {
    /// Both: what `ratf calibrate` asks a team for.
    pub const ALL: Self = Self {
        tape: true,
        poles_from_sheet: true,
    };
}

/// Why the simulated calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// The simulated IMU could not be brought up.
    #[error("simulated IMU: {0}")]
    Imu(#[from] ImuError),
    /// The drive's data could not be fitted.
    #[error("calibration: {0}")]
    Fit(#[from] CalibrationError),
    /// The core could not be built from the configuration.
    #[error("task planner: {0}")]
    Planner(#[from] ratf_core::planning::tasks::TaskError),
}

/// The fit against the truth, in the units a team reads.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CalibrationErrors {
    /// Fitted range scale minus the true one, per cent.
    pub range_scale_pct: f64,
    /// Fitted range offset minus the true one, mm.
    pub range_offset_mm: f64,
    /// Fitted mount yaw minus the true one, degrees.
    pub mount_yaw_deg: f64,
    /// Largest distance of a fitted beacon centre from the true one, mm.
    pub beacon_max_mm: f64,
    /// Largest error of a fitted pole-to-pole distance (the layout, whatever the frame), mm.
    pub beacon_layout_max_mm: f64,
    /// The fitted layout's common shift from the true one (the mean of the centres'
    /// errors), mm: what moves every dock with it.
    pub beacon_shift_mm: f64,
    /// The fitted layout's common rotation from the true one about the true poles' centroid,
    /// its shift taken out (least squares), degrees: what turns every heading with it.
    pub beacon_rotation_deg: f64,
    /// The same before calibration: the believed mount yaw minus the true one, degrees.
    pub uncalibrated_mount_yaw_deg: f64,
    /// Largest distance of a believed beacon centre from the true one, mm.
    pub uncalibrated_beacon_max_mm: f64,
}

/// One simulated calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct SimCalibration {
    /// The simulator's seed.
    pub seed: u64,
    /// The world profile.
    pub world: WorldProfile,
    /// The fit.
    pub calibration: Calibration,
    /// The world's truth.
    pub truth: WorldTruth,
    /// The fit against it.
    pub errors: CalibrationErrors,
    /// Stops recorded.
    pub stops: usize,
    /// Collisions during the drive.
    pub collisions: u32,
    /// Simulated time, s.
    pub sim_s: f64,
}

/// Drive the calibration drive in the world of `config` (its `[sim] seed` and `world`),
/// fit, and compare with the truth; the team also took the `measures`.
pub fn run_in_sim(
    config: &Config,
    measures: DayMeasures,
) -> Result<SimCalibration, CalibrateError> {
    let (script, windows) = calibration_drive();
    let scenario = Scenario {
        start_pose: script.start,
        ..Scenario::new(config)
    };
    let devices = SimDevices::new(config, &scenario)?;
    let mut core = Core::new(config, script.start)?;
    let driven = drive_and_collect(
        &mut core,
        devices,
        &script,
        windows,
        config,
        &mut [],
        || false,
    )?;
    let (stops, devices) = (driven.stops, driven.devices);
    let field = config.field.field();
    let world = devices.world();
    let truth = world.truth().clone();
    let true_field = truth.true_field(config);
    let true_beacons: Vec<Vec2> = true_field
        .beacons()
        .iter()
        .map(|b| b.circle.center)
        .collect();
    let mut priors = Priors::from_config(config, &field);
    if measures.poles_from_sheet {
        let mut rng = SimRng::new(config.sim.seed).fork("poles from the sheet");
        let sigma = priors.pole_from_sheet_sigma_m;
        priors.poles_from_sheet = true_beacons
            .iter()
            .enumerate()
            .map(|(beacon, &centre)| PoleFromSheet {
                beacon,
                position: centre + Vec2::new(rng.normal(sigma), rng.normal(sigma)),
            })
            .collect();
    }
    if measures.tape {
        let mut rng = SimRng::new(config.sim.seed).fork("tape");
        priors.tape = TAPED_SIDES
            .iter()
            .map(|&(from, to)| TapeMeasure {
                from,
                to,
                distance_m: true_beacons[from].distance(true_beacons[to])
                    + rng.normal(priors.tape_sigma_m),
            })
            .collect();
    }
    let fit = calibration::solve(&stops, &priors)?;
    let true_yaw = (config.robot.lidar_yaw_deg + truth.lidar_yaw_error_deg).to_radians();
    let believed_beacons: Vec<Vec2> = field.beacons().iter().map(|b| b.circle.center).collect();
    let errors = CalibrationErrors {
        range_scale_pct: (fit.range_scale - truth.lidar_range_scale) * 100.0,
        range_offset_mm: (fit.range_offset_m - truth.lidar_range_offset_m) * 1e3,
        mount_yaw_deg: wrap_angle(fit.mount_yaw_rad - true_yaw).to_degrees(),
        beacon_max_mm: max_distance(&fit.beacons, &true_beacons) * 1e3,
        beacon_layout_max_mm: layout_error(&fit.beacons, &true_beacons) * 1e3,
        beacon_shift_mm: common_shift(&fit.beacons, &true_beacons).norm() * 1e3,
        beacon_rotation_deg: common_rotation(&fit.beacons, &true_beacons).to_degrees(),
        uncalibrated_mount_yaw_deg: -truth.lidar_yaw_error_deg,
        uncalibrated_beacon_max_mm: max_distance(&believed_beacons, &true_beacons) * 1e3,
    };
    Ok(SimCalibration {
        seed: config.sim.seed,
        world: config.sim.world,
        calibration: fit,
        errors,
        stops: stops.len(),
        collisions: world.stats().collisions,
        sim_s: devices.now_us() as f64 * 1e-6,
        truth,
    })
}

/// A calibration the simulated team's day refused: the robot keeps what it believed before
/// that step.
#[derive(Debug, thiserror::Error)]
pub enum DayRefusal {
    /// The lidar and beacons' fit was refused: the robot keeps the configuration as written
    /// (the odometry drive rests on the lidar, so it is not driven).
    #[error("the lidar calibration: {0}")]
    Lidar(CalibrationError),
    /// The odometry drive's fit was refused: the robot keeps the lidar calibration.
    #[error("the odometry calibration: {0}")]
    Odometry(Box<odometry::OdometryCalibrateError>),
}

/// What the robot believes in the world of `config` (its `[sim] seed`): with `calibrate`,
/// the configuration after the team's day, as the README's "On the robot" has it: the
/// calibration drive with all the day's measures (`ratf calibrate`), then the odometry
/// drive (`ratf calibrate odometry`) by the robot that believes it, its fit checked as on
/// the robot ([`odometry::Agreement::check`]), and the body's outline measured with a rule
/// ([`outline`]). A refused fit leaves the robot with what it believed before that step, as
/// on the day for a team with no time to drive again, and the refusal beside it.
pub fn beliefs(
    config: &Config,
    calibrate: bool,
) -> Result<(Config, Option<DayRefusal>), CalibrateError> {
    let (mut beliefs, refused) = drive_beliefs(config, calibrate)?;
    if calibrate {
        Outline::measured_in_sim(config).apply(&mut beliefs);
    }
    Ok((beliefs, refused))
}

/// [`beliefs`] from the two drives, before the outline's rule measures.
fn drive_beliefs(
    config: &Config,
    calibrate: bool,
) -> Result<(Config, Option<DayRefusal>), CalibrateError> {
    let (mut beliefs, refused) = lidar_beliefs(config, calibrate)?;
    if !calibrate {
        return Ok((beliefs, None));
    }
    if let Some(refused) = refused {
        return Ok((beliefs, Some(DayRefusal::Lidar(refused))));
    }
    let refused = match odometry::drive_in_sim(config, &beliefs, None) {
        Ok(run) => match run.agreement.check(&run.fit) {
            Ok(()) => {
                run.fit.apply(&mut beliefs);
                return Ok((beliefs, None));
            }
            Err(refusal) => refusal.into(),
        },
        Err(odometry::OdometryCalibrateError::Drive(error)) => return Err(error),
        Err(refused) => refused,
    };
    Ok((beliefs, Some(DayRefusal::Odometry(Box::new(refused)))))
}

/// What the robot believes after the calibration drive alone (the lidar and the beacons),
/// as [`beliefs`] has it.
fn lidar_beliefs(
    config: &Config,
    calibrate: bool,
) -> Result<(Config, Option<CalibrationError>), CalibrateError> {
    let mut beliefs = config.clone();
    if !calibrate {
        return Ok((beliefs, None));
    }
    match run_in_sim(config, DayMeasures::ALL) {
        Ok(run) => {
            run.calibration.apply(&mut beliefs);
            Ok((beliefs, None))
        }
        Err(CalibrateError::Fit(refused)) => Ok((beliefs, Some(refused))),
        Err(other) => Err(other),
    }
}

fn max_distance(a: &[Vec2], b: &[Vec2]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| p.distance(*q))
        .fold(0.0, f64::max)
}

/// The mean of `points` (zero for none).
fn centroid(points: &[Vec2]) -> Vec2 {
    points.iter().fold(Vec2::ZERO, |sum, p| sum + *p) * (1.0 / points.len().max(1) as f64)
}

/// The mean of `fitted − truth` over the poles.
fn common_shift(fitted: &[Vec2], truth: &[Vec2]) -> Vec2 {
    centroid(fitted) - centroid(truth)
}

/// The rotation φ (rad, counter-clockwise) about the centroid c of `truth` that best carries
/// `truth` onto `fitted` once their common shift s is taken out: the least-squares small
/// angle Σ (tᵢ − c) × (fᵢ − s − tᵢ) / Σ |tᵢ − c|².
fn common_rotation(fitted: &[Vec2], truth: &[Vec2]) -> f64 {
    let shift = common_shift(fitted, truth);
    let centre = centroid(truth);
    let (mut cross, mut spread) = (0.0, 0.0);
    for (f, t) in fitted.iter().zip(truth) {
        let arm = *t - centre;
        let moved = *f - shift - *t;
        cross += arm.cross(moved);
        spread += arm.dot(arm);
    }
    if spread > 0.0 { cross / spread } else { 0.0 }
}

fn layout_error(fitted: &[Vec2], truth: &[Vec2]) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..fitted.len() {
        for j in i + 1..fitted.len() {
            let error = fitted[i].distance(fitted[j]) - truth[i].distance(truth[j]);
            worst = worst.max(error.abs());
        }
    }
    worst
}

/// The spread of calibrations over many seeds: mean |error| and worst |error| per
/// quantity.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CalibrationSummary {
    /// Runs.
    pub runs: usize,
    /// Mean and worst |range scale error|, per cent.
    pub range_scale_pct: [f64; 2],
    /// Mean and worst |range offset error|, mm.
    pub range_offset_mm: [f64; 2],
    /// Mean and worst |mount yaw error|, degrees.
    pub mount_yaw_deg: [f64; 2],
    /// Mean and worst largest beacon error, mm.
    pub beacon_max_mm: [f64; 2],
    /// Mean and worst pole-to-pole distance error, mm.
    pub beacon_layout_max_mm: [f64; 2],
    /// Mean and worst common shift of the layout, mm.
    pub beacon_shift_mm: [f64; 2],
    /// Mean and worst |common rotation| of the layout, degrees.
    pub beacon_rotation_deg: [f64; 2],
    /// Mean and worst |mount yaw error| before calibration, degrees.
    pub uncalibrated_mount_yaw_deg: [f64; 2],
    /// Mean and worst largest beacon error before calibration, mm.
    pub uncalibrated_beacon_max_mm: [f64; 2],
    /// What the calibration leaves, as the localiser's consider parameters take it.
    pub left: ConsiderSigmas,
}

/// The root mean squares over the runs of the errors the localiser cannot see and takes as
/// consider parameters (`[localisation]`'s `beacon_frame_shift_std_m`,
/// `beacon_frame_rotation_std_deg`, `lidar_zero_angle_std_deg`): the standard deviations a
/// zero-mean error of that spread has, so a team can set those keys from its own world.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ConsiderSigmas {
    /// The layout's common shift, per axis (the RMS norm over √2), mm.
    pub beacon_shift_per_axis_mm: f64,
    /// The layout's common rotation, degrees.
    pub beacon_rotation_deg: f64,
    /// The lidar's zero angle (its mount yaw), degrees.
    pub zero_angle_deg: f64,
}

impl CalibrationSummary {
    /// The summary of `runs`.
    pub fn of(runs: &[SimCalibration]) -> Self {
        let stat = |f: &dyn Fn(&CalibrationErrors) -> f64| {
            let values: Vec<f64> = runs.iter().map(|r| f(&r.errors).abs()).collect();
            let n = values.len().max(1) as f64;
            [
                values.iter().sum::<f64>() / n,
                values.iter().copied().fold(0.0, f64::max),
            ]
        };
        let rms = |f: &dyn Fn(&CalibrationErrors) -> f64| {
            let squares: f64 = runs.iter().map(|r| f(&r.errors).powi(2)).sum();
            (squares / runs.len().max(1) as f64).sqrt()
        };
        Self {
            runs: runs.len(),
            range_scale_pct: stat(&|e| e.range_scale_pct),
            range_offset_mm: stat(&|e| e.range_offset_mm),
            mount_yaw_deg: stat(&|e| e.mount_yaw_deg),
            beacon_max_mm: stat(&|e| e.beacon_max_mm),
            beacon_layout_max_mm: stat(&|e| e.beacon_layout_max_mm),
            beacon_shift_mm: stat(&|e| e.beacon_shift_mm),
            beacon_rotation_deg: stat(&|e| e.beacon_rotation_deg),
            uncalibrated_mount_yaw_deg: stat(&|e| e.uncalibrated_mount_yaw_deg),
            uncalibrated_beacon_max_mm: stat(&|e| e.uncalibrated_beacon_max_mm),
            left: ConsiderSigmas {
                beacon_shift_per_axis_mm: (rms(&|e| e.beacon_shift_mm) / 2f64.sqrt()),
                beacon_rotation_deg: rms(&|e| e.beacon_rotation_deg),
                zero_angle_deg: rms(&|e| e.mount_yaw_deg),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The defaults in the realistic world of seed 3.
    fn realistic_seed_3() -> Config {
        let mut config = Config::default();
        config.sim.world = WorldProfile::Realistic;
        config.sim.seed = 3;
        config
    }

    #[test]
    fn a_layout_turned_and_shifted_gives_back_its_rotation_and_shift() {
        let truth: Vec<Vec2> = ratf_core::field::Field::competition()
            .beacons()
            .iter()
            .map(|b| b.circle.center)
            .collect();
        let centre = centroid(&truth);
        let (angle, shift) = (0.002_f64, Vec2::new(0.003, -0.002));
        let fitted: Vec<Vec2> = truth
            .iter()
            .map(|t| {
                let arm = *t - centre;
                let turned = Vec2::new(
                    arm.x * angle.cos() - arm.y * angle.sin(),
                    arm.x * angle.sin() + arm.y * angle.cos(),
                );
                centre + turned + shift
            })
            .collect();
        assert!((common_rotation(&fitted, &truth) - angle).abs() < 1e-6);
        assert!((common_shift(&fitted, &truth) - shift).norm() < 1e-9);
        assert!(common_rotation(&truth, &truth).abs() < 1e-15);
    }

    #[test]
    fn the_day_s_beliefs_end_with_the_odometry_drive_s_wheels_rollers_and_lidar_position() {
        let config = realistic_seed_3();
        let lidar = run_in_sim(&config, DayMeasures::ALL).unwrap();
        let (believed, refused) = beliefs(&config, true).unwrap();
        assert!(refused.is_none(), "{refused:?}");
        // The lidar's fit is kept...
        assert_eq!(believed.lidar.range_scale, lidar.calibration.range_scale);
        // ...and the wheels are the world's, not the drawing's: the rollers' strafe (0.93
        // in the realistic world) within 0.01, the wheel radius within 0.3 %.
        let truth = lidar.truth;
        assert!(
            (believed.robot.strafe_factor - truth.lateral_factor).abs() < 0.01,
            "{} vs {}",
            believed.robot.strafe_factor,
            truth.lateral_factor
        );
        let true_diameter_m = config.robot.wheel_diameter_m * truth.mean_wheel_radius_scale();
        assert!(
            (believed.robot.wheel_diameter_m / true_diameter_m - 1.0).abs() < 0.003,
            "{} vs {true_diameter_m}",
            believed.robot.wheel_diameter_m
        );
        // The lidar sits where the turns in place put it (the world drew it 3.1 mm off).
        let [dx, dy] = truth.lidar_position_error_m;
        let off_m = (believed.robot.lidar_x_m - (config.robot.lidar_x_m + dx))
            .hypot(believed.robot.lidar_y_m - (config.robot.lidar_y_m + dy));
        assert!(dx.hypot(dy) > 0.003 && off_m < 0.0015, "{off_m} m");
        // Uncalibrated, the robot keeps the configuration as written.
        assert_eq!(beliefs(&config, false).unwrap().0, config);
    }

    #[test]
    fn the_calibration_drive_is_collision_free_and_recovers_the_mount_yaw_in_the_realistic_world() {
        let config = realistic_seed_3();
        let run = run_in_sim(&config, DayMeasures::ALL).unwrap();
        assert_eq!(run.collisions, 0);
        assert_eq!(run.stops, 9);
        assert!(
            run.errors.mount_yaw_deg.abs() < 0.3,
            "{:?} vs before {}",
            run.errors,
            run.errors.uncalibrated_mount_yaw_deg
        );
    }

    #[test]
    fn the_calibration_drive_clears_machine_a_when_the_strafe_falls_short() {
        // Harsh seed 31: strafe ×0.85; a 0.59 m right leg touched machine A's dividers
        // three times.
        let mut config = Config::default();
        config.sim.world = WorldProfile::Harsh;
        config.sim.seed = 31;
        let run = run_in_sim(&config, DayMeasures::ALL).unwrap();
        assert!(run.truth.lateral_factor < 0.9, "{}", run.truth);
        assert_eq!(run.collisions, 0);
    }

    #[test]
    fn poles_are_found_where_the_localiser_or_the_odometry_has_drifted() {
        // Harsh seed 36: the uncalibrated localiser stood 13° off at three stops and the
        // two poles found around it were misnamed (refused at 6.5 σ RMS). Harsh seed 13:
        // the strafe 15 % short put the odometry 12 cm off on the loop's far side, and the
        // localiser 17° off (refused at 5.8 σ RMS).
        for seed in [36, 13] {
            let mut config = Config::default();
            config.sim.world = WorldProfile::Harsh;
            config.sim.seed = seed;
            let run = run_in_sim(&config, DayMeasures::ALL)
                .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            assert!(
                run.errors.mount_yaw_deg.abs() < 0.3 && run.errors.beacon_max_mm < 6.0,
                "seed {seed}: {:?}",
                run.errors
            );
        }
    }
}
