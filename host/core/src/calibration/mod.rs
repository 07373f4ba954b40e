//! Lidar and beacon calibration from a short drive: the lidar's range scale and offset,
//! its zero angle on the robot (mount yaw) and the four beacons' centres, estimated
//! together from what the robot sees at a few stops and the odometry between them.
//!
//! Why: the X4's datasheet allows a range error of about ±1.5 % and ±10 mm, its zero angle
//! moves by a few degrees with the mount, and the organisers place the poles by hand
//! (real-world-errors.md). Uncalibrated, the localiser is confidently wrong: a 3° mount
//! error is a 3° heading error at every dock.
//!
//! How, in two steps that keep I/O out:
//! 1. [`StopRecorder`]: at each stop, with the robot still, the pole centres found in every
//!    scan (raw ranges, the lidar's own frame) are averaged per beacon into a [`Sighting`];
//!    a [`Stop`] is those sightings and the odometry pose there.
//! 2. [`solve`]: a least-squares fit (Levenberg–Marquardt) of every stop's lidar pose, the
//!    range scale and offset, the mount yaw and the beacons, to the sightings, to the
//!    odometry between consecutive stops, and to priors (the beacons' nominal centres
//!    with the organisers' placement tolerance; loose ones on the rest).
//!
//! What makes each quantity observable: the mount yaw is the angle between where the
//! lidar says it points and where the odometry says the robot drove (straight legs along
//! the robot's own axes, whose direction the wheels give well even when their length is
//! off); the range offset separates from the scale because the stops see the poles at
//! different distances; the scale and the beacons' spread are pinned together by the
//! odometry's lengths and the beacons' nominal layout, so the scale is the least certain of
//! the three ([`Calibration::range_scale_std`] says how certain). The beacons' common
//! shift and rotation cannot be seen from the robot at all (every pose moves with them):
//! the fit places them where the poles measured from the floor sheet's edges say
//! ([`PoleFromSheet`]), or else where the nominal layout says, on average. That shift
//! moves every dock with it: a carried part has 20 mm on each side between a slot's
//! dividers.

mod sightings;
mod solve;

pub use sightings::{MIN_SCANS, SEARCH_RADIUS_M, Sighting, Stop, StopRecorder};
pub use solve::{
    BEACON_PLACEMENT_SIGMA_M, Calibration, CalibrationError, MAX_RESIDUAL_RMS, MIN_DRIVE_M,
    MIN_SIGHTINGS_PER_BEACON, MIN_STOPS, POLE_FROM_SHEET_SIGMA_M, PoleFromSheet, Priors,
    TAPE_SIGMA_M, TapeMeasure, solve,
};
