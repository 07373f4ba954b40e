//! `ratf calibrate odometry` in the simulator: the lidar calibrated first (the calibration
//! drive, with tape measures: [`super::beliefs`]), then the odometry drive
//! ([`crate::apps::scripts::odometry_drive`]) through the robot's runtime, each stop's pose
//! fixed from the beacons, and the wheel radius and lx + ly fitted
//! ([`ratf_core::identification::odometry_fit`]); the world's truth beside the fit.

use serde::Serialize;

use super::drive::drive_and_collect;
use super::{CalibrateError, beliefs};
use crate::apps::scripts::odometry_drive;
use ratf_core::calibration::CalibrationError;
use ratf_core::config::{Config, WorldProfile};
use ratf_core::identification::odometry_fit::{self, OdometryFit, OdometryFitError};
use ratf_core::runtime::Core;
use ratf_sim::devices::SimDevices;
use ratf_sim::truth::WorldTruth;
use ratf_sim::world::Scenario;

/// Why the simulated odometry calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum OdometryCalibrateError {
    /// The drive could not run.
    #[error(transparent)]
    Drive(#[from] CalibrateError),
    /// The lidar calibration before it was refused.
    #[error("the lidar calibration first: {0}")]
    Lidar(CalibrationError),
    /// The drive's legs could not be fitted.
    #[error("odometry: {0}")]
    Fit(#[from] OdometryFitError),
}

/// One simulated odometry calibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SimOdometry {
    /// The simulator's seed.
    pub seed: u64,
    /// The world profile.
    pub world: WorldProfile,
    /// The fit.
    pub fit: OdometryFit,
    /// The true wheel diameter (the wheels' mean), m.
    pub true_wheel_diameter_m: f64,
    /// The true lx + ly, m.
    pub true_lx_plus_ly_m: f64,
    /// Fitted wheel radius minus the true one, per cent of it.
    pub radius_error_pct: f64,
    /// Fitted lx + ly minus the true, per cent of it.
    pub lx_plus_ly_error_pct: f64,
    /// The same before calibrating (the configuration's values).
    pub uncalibrated_radius_error_pct: f64,
    /// The same before calibrating.
    pub uncalibrated_lx_plus_ly_error_pct: f64,
    /// Stops with a beacon fix, of all stops.
    pub fixed_stops: [usize; 2],
    /// Collisions during the odometry drive.
    pub collisions: u32,
    /// The world's truth.
    #[serde(skip)]
    pub truth: WorldTruth,
}

/// Calibrate the lidar, drive the odometry drive in the world of `config` (its `[sim] seed`
/// and `world`) and fit; compare with the truth.
pub fn run_in_sim(config: &Config) -> Result<SimOdometry, OdometryCalibrateError> {
    let (robot, refused) = beliefs(config, true)?;
    if let Some(refused) = refused {
        return Err(OdometryCalibrateError::Lidar(refused));
    }
    let (script, windows) = odometry_drive();
    let scenario = Scenario {
        start_pose: script.start,
        ..Scenario::new(config)
    };
    let devices = SimDevices::new(config, &scenario).map_err(CalibrateError::from)?;
    let mut core = Core::new(&robot, script.start).map_err(CalibrateError::from)?;
    let driven = drive_and_collect(
        &mut core,
        devices,
        &script,
        windows,
        &robot,
        &mut [],
        || false,
    )
    .map_err(CalibrateError::from)?;
    let field = robot.field.field();
    let fixes: Vec<_> = driven
        .stops
        .iter()
        .map(|stop| odometry_fit::beacon_fix(stop, &robot, &field))
        .collect();
    let legs = odometry_fit::legs(&driven.stops, &fixes);
    let fit = odometry_fit::fit(&legs, &robot)?;
    let world = driven.devices.world();
    let truth = world.truth().clone();
    let true_wheel_diameter_m = config.robot.wheel_diameter_m * truth.mean_wheel_radius_scale();
    let true_lx_plus_ly_m = config.robot.half_wheelbase_sum_m() * truth.turn_scale;
    let pct = |a: f64, b: f64| (a / b - 1.0) * 100.0;
    Ok(SimOdometry {
        seed: config.sim.seed,
        world: config.sim.world,
        fit,
        true_wheel_diameter_m,
        true_lx_plus_ly_m,
        radius_error_pct: pct(fit.wheel_diameter_m, true_wheel_diameter_m),
        lx_plus_ly_error_pct: pct(fit.lx_plus_ly_m, true_lx_plus_ly_m),
        uncalibrated_radius_error_pct: pct(robot.robot.wheel_diameter_m, true_wheel_diameter_m),
        uncalibrated_lx_plus_ly_error_pct: pct(
            robot.robot.half_wheelbase_sum_m(),
            true_lx_plus_ly_m,
        ),
        fixed_stops: [fixes.iter().flatten().count(), fixes.len()],
        collisions: world.stats().collisions,
        truth,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_odometry_drive_recovers_radius_within_0_3_pct_and_lx_plus_ly_within_1_pct_over_20_realistic_worlds()
     {
        let mut config = Config::default();
        config.sim.world = WorldProfile::Realistic;
        for seed in 1..=20 {
            config.sim.seed = seed;
            let run = run_in_sim(&config).unwrap();
            assert_eq!(run.collisions, 0, "seed {seed}");
            assert_eq!(run.fixed_stops, [21, 21], "seed {seed}");
            assert!(run.radius_error_pct.abs() < 0.3, "seed {seed}: {run:?}");
            assert!(run.lx_plus_ly_error_pct.abs() < 1.0, "seed {seed}: {run:?}");
        }
    }
}
