//! `ratf calibrate --robot`: the calibration drive on the real devices, through the same
//! runtime and the same drive as in the simulator ([`super::drive`]), recorded; the fit uses
//! the tape measures the team took between the poles.

use std::path::{Path, PathBuf};

use ratf_core::calibration::{
    self, Calibration, CalibrationError, PoleFromSheet, Priors, Stop, TapeMeasure,
};
use ratf_core::config::Config;
use ratf_core::field::geometry::{Pose2, Vec2};
use ratf_core::runtime::Core;

use super::drive::drive_and_collect;
use crate::apps::operator_script::OperatorScript;
use crate::apps::run::{RunError, open_devices};
use crate::apps::scripts::{StopWindow, calibration_drive};
use crate::devices::{DeviceError, Shared};
use crate::recording::{Recorder, RecordingError, Session};

/// `A-B=METRES`: a tape measure between beacons A and B.
pub fn parse_tape(text: &str) -> Result<TapeMeasure, String> {
    let bad = || format!("{text:?}: expected A-B=METRES with beacons 0 to 3, e.g. 0-1=1.776");
    let (pair, metres) = text.split_once('=').ok_or_else(bad)?;
    let (from, to) = pair.split_once('-').ok_or_else(bad)?;
    let from: usize = from.trim().parse().map_err(|_| bad())?;
    let to: usize = to.trim().parse().map_err(|_| bad())?;
    let distance_m: f64 = metres.trim().parse().map_err(|_| bad())?;
    if from > 3 || to > 3 || from == to || !(0.2..=3.0).contains(&distance_m) {
        return Err(format!(
            "{text:?}: two different beacons from 0 to 3, and a distance within 0.2 to 3 m"
        ));
    }
    Ok(TapeMeasure {
        from,
        to,
        distance_m,
    })
}

/// `B=X,Y`: beacon B's centre measured from the floor sheet's edges, field frame, m.
pub fn parse_pole_from_sheet(text: &str) -> Result<PoleFromSheet, String> {
    let bad = || format!("{text:?}: expected B=X,Y with a beacon 0 to 3, e.g. 0=0.888,0.538");
    let (beacon, position) = text.split_once('=').ok_or_else(bad)?;
    let (x, y) = position.split_once(',').ok_or_else(bad)?;
    let beacon: usize = beacon.trim().parse().map_err(|_| bad())?;
    let x: f64 = x.trim().parse().map_err(|_| bad())?;
    let y: f64 = y.trim().parse().map_err(|_| bad())?;
    // The field is 1.7 × 1.2 m about its centre and the poles stand beside it.
    if beacon > 3 || !(x.abs() <= 1.5 && y.abs() <= 1.5) {
        return Err(format!(
            "{text:?}: a beacon from 0 to 3, and a centre within 1.5 m of the field's centre"
        ));
    }
    Ok(PoleFromSheet {
        beacon,
        position: Vec2::new(x, y),
    })
}

/// How a calibration on the robot is made.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotOptions {
    /// Pole-to-pole distances measured with a tape (may be empty: the range scale then
    /// rests on the odometry and the nominal layout).
    pub tape: Vec<TapeMeasure>,
    /// Poles' centres measured from the floor sheet's edges (may be empty: the layout's
    /// place on the field then rests on the nominal centres).
    pub poles_from_sheet: Vec<PoleFromSheet>,
    /// Where the recording goes.
    pub recording: PathBuf,
}

/// Why a calibration on the robot failed.
#[derive(Debug, thiserror::Error)]
pub enum RobotCalibrateError {
    /// A device could not be opened or the core built.
    #[error(transparent)]
    Setup(#[from] RunError),
    /// A device failed during the drive.
    #[error("during the drive: {0}")]
    Device(#[from] DeviceError),
    /// The recording could not be written.
    #[error("recording: {0}")]
    Recording(#[from] Box<RecordingError>),
    /// Ctrl-C or SIGTERM during the drive.
    #[error("stopped during the drive; nothing was fitted")]
    Interrupted,
    /// The drive's data could not be fitted.
    #[error("{0}")]
    Fit(#[from] CalibrationError),
}

/// A calibration on the robot.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotCalibration {
    /// The fit.
    pub calibration: Calibration,
    /// The stops the fit used.
    pub stops: Vec<Stop>,
    /// The recording of the drive.
    pub recording: PathBuf,
}

/// What a drive on the robot brought back.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotDrive {
    /// The stops, as the fits take them (sightings in the beliefs of the configuration).
    pub stops: Vec<Stop>,
    /// The recording of the drive.
    pub recording: PathBuf,
}

/// A recorder of a drive's session of `kind` (its configuration `config` and start pose
/// `start`, world frame) writing to `path`.
pub fn open_recorder(
    config: &Config,
    start: Pose2,
    kind: &str,
    path: &Path,
) -> Result<Recorder, RecordingError> {
    let session = Session {
        kind: kind.to_owned(),
        config_toml: config.to_toml_string().map_err(|e| RecordingError::Io {
            path: path.to_owned(),
            source: std::io::Error::other(e),
        })?,
        start_pose: start,
        version: env!("CARGO_PKG_VERSION").to_owned(),
    };
    Recorder::create(path, &session)
}

/// Drive `script` (robot-frame twists, as the operator's `Drive` commands into the core)
/// from `start` on the devices of `config`, recorded to `recording` as a session of `kind`,
/// and collect the stops of `windows`. `shared` carries the quit flag (wire the signals to it first) and
/// the panic flag; on every way out the robot gets zero references and magnet off. Never
/// [`RobotCalibrateError::Fit`]: the caller fits.
pub fn drive_on_robot<S: OperatorScript + ?Sized>(
    config: &Config,
    (script, start, windows): (&S, Pose2, Vec<StopWindow>),
    kind: &str,
    recording: &Path,
    shared: &Shared,
) -> Result<RobotDrive, RobotCalibrateError> {
    let mut core = Core::new(config, start).map_err(RunError::from)?;
    let mut recorder = open_recorder(config, start, kind, recording).map_err(Box::new)?;
    let opened = open_devices(config, shared, Vec::new())?;
    let driven = drive_and_collect(
        &mut core,
        opened.devices,
        script,
        windows,
        config,
        &mut [&mut recorder],
        || shared.quitting(),
    );
    opened.running.close(shared);
    let recording = recorder.finish().map_err(Box::new)?;
    let driven = driven?;
    if !driven.finished {
        return Err(RobotCalibrateError::Interrupted);
    }
    Ok(RobotDrive {
        stops: driven.stops,
        recording,
    })
}

/// Drive the calibration drive on the devices of `config` (the robot placed at the field's
/// start pose, machine A's surroundings clear) and fit. `shared` carries the quit flag
/// (wire the signals to it first) and the panic flag; on every way out the robot gets zero
/// references and magnet off.
pub fn run_on_robot(
    config: &Config,
    options: &RobotOptions,
    shared: &Shared,
) -> Result<RobotCalibration, RobotCalibrateError> {
    let (script, windows) = calibration_drive();
    let RobotDrive { stops, recording } = drive_on_robot(
        config,
        (&script, script.start, windows),
        "calibration",
        &options.recording,
        shared,
    )?;
    let field = config.field.field();
    let mut priors = Priors::from_config(config, &field);
    priors.tape = options.tape.clone();
    priors.poles_from_sheet = options.poles_from_sheet.clone();
    let calibration = calibration::solve(&stops, &priors)?;
    Ok(RobotCalibration {
        calibration,
        stops,
        recording,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tape_measure_is_read_from_a_b_equals_metres_and_nonsense_is_named() {
        assert_eq!(
            parse_tape("0-1=1.776"),
            Ok(TapeMeasure {
                from: 0,
                to: 1,
                distance_m: 1.776
            })
        );
        for bad in [
            "0-1", "0:1=1.7", "0-4=1.7", "2-2=1.7", "0-1=17", "0-1=nan", "a-1=1",
        ] {
            let error = parse_tape(bad).unwrap_err();
            assert!(error.contains(bad), "{bad}: {error}");
        }
    }

    #[test]
    fn a_pole_from_the_sheet_is_read_from_b_equals_x_comma_y_and_nonsense_is_named() {
        assert_eq!(
            parse_pole_from_sheet("2=0.891,-0.535"),
            Ok(PoleFromSheet {
                beacon: 2,
                position: Vec2::new(0.891, -0.535)
            })
        );
        for bad in [
            "2=0.891",
            "2:0.8,0.5",
            "4=0.8,0.5",
            "1=8.8,0.5",
            "1=nan,0.5",
            "x=1,1",
        ] {
            let error = parse_pole_from_sheet(bad).unwrap_err();
            assert!(error.contains(bad), "{bad}: {error}");
        }
    }
}
