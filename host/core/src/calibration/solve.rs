//! The calibration fit: every stop's lidar pose, the range scale and offset, the mount yaw
//! and the beacons, by Levenberg–Marquardt over normalised residuals.

use std::fmt;

use nalgebra::{DMatrix, DVector};

use super::sightings::Stop;
use crate::config::Config;
use crate::field::Field;
use crate::field::geometry::{Pose2, Vec2, wrap_angle};

/// The organisers' placement tolerance of a pole's centre, per axis, m (an assumption,
/// real-world-errors.md: poles placed by hand on marks).
pub const BEACON_PLACEMENT_SIGMA_M: f64 = 0.005;

/// Stops the fit needs at least (three poses to tell a turn from a mount error).
pub const MIN_STOPS: usize = 3;

/// Stops each beacon must be seen from.
pub const MIN_SIGHTINGS_PER_BEACON: usize = 2;

/// Odometry distance the drive must span between some two stops, m: the mount yaw is the
/// angle between the lidar's heading and the direction driven, which a shorter drive
/// cannot resolve.
pub const MIN_DRIVE_M: f64 = 0.2;

/// Largest RMS of the normalised residuals a fit may end with: about 1 when the sightings
/// and the odometry agree within their error model; well above it, something the model does
/// not have (a pole moved during the drive, something next to a pole taken for it, a wheel
/// that slipped) has pulled the fit, and its values must not be written to the robot.
pub const MAX_RESIDUAL_RMS: f64 = 2.0;

/// Iterations before the fit gives up.
const MAX_ITERATIONS: usize = 100;

/// Step in each parameter for the numerical Jacobian (central differences).
const JACOBIAN_STEP: f64 = 1e-7;

/// σ of a pole-to-pole distance measured with a tape, m (a 2 m tape read to the
/// millimetre, held centre to centre by eye).
pub const TAPE_SIGMA_M: f64 = 0.002;

/// A distance between two poles' centres measured with a tape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TapeMeasure {
    /// One pole (beacon index).
    pub from: usize,
    /// The other.
    pub to: usize,
    /// Centre to centre, m.
    pub distance_m: f64,
}

/// σ of a pole's centre measured from the floor sheet's edges, per axis, m (a tape and a
/// square over the few centimetres from the printed field's side and end lines to the
/// pole, plus its radius: an assumption, read to the millimetre like [`TAPE_SIGMA_M`]).
pub const POLE_FROM_SHEET_SIGMA_M: f64 = 0.002;

/// A pole's centre measured on the day from the printed floor sheet's edges (its side and
/// end lines give the field frame): the only measure of where the layout stands on the
/// field, which the robot's own sensors cannot see (every pose moves with the poles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoleFromSheet {
    /// The pole (beacon index).
    pub beacon: usize,
    /// Its centre, field frame, m.
    pub position: Vec2,
}

/// What the robot believes before calibration, and how firmly.
#[derive(Clone, Debug, PartialEq)]
pub struct Priors {
    /// The beacons' nominal centres, world frame, m.
    pub beacons: Vec<Vec2>,
    /// Centre-to-centre distances between poles measured with a tape on the day, if any:
    /// the only length the robot's own sensors cannot scale (without them the range
    /// scale rests on the odometry's lengths and the nominal layout).
    pub tape: Vec<TapeMeasure>,
    /// σ of a tape measurement, m.
    pub tape_sigma_m: f64,
    /// Poles' centres measured from the floor sheet's edges on the day, if any: without
    /// them the layout's common shift and turn rest on the nominal centres.
    pub poles_from_sheet: Vec<PoleFromSheet>,
    /// σ of such a measure per axis, m.
    pub pole_from_sheet_sigma_m: f64,
    /// Their placement tolerance per axis, m.
    pub beacon_sigma_m: f64,
    /// The poles' radius, m.
    pub beacon_radius_m: f64,
    /// The lidar's believed pose on the robot (x, y, m; yaw, rad).
    pub mount: Pose2,
    /// σ of the range scale about 1 (loose: the data decide).
    pub range_scale_sigma: f64,
    /// σ of the range offset about 0, m (loose).
    pub range_offset_sigma_m: f64,
    /// σ of the mount yaw about the believed one, rad (loose).
    pub mount_yaw_sigma_rad: f64,
    /// The odometry's length error along the robot's x (forward), as a fraction (wheel
    /// radii measured with callipers, worn tyres: 0.5 %).
    pub odometry_forward_fraction: f64,
    /// Its length error along y (strafe), as a fraction: mecanum rollers slip sideways, by
    /// 5–15 % (real-world-errors.md).
    pub odometry_strafe_fraction: f64,
    /// Sideways drift per metre driven, as a fraction.
    pub odometry_cross_fraction: f64,
    /// Error of every odometry leg, m.
    pub odometry_floor_m: f64,
    /// Error of the odometry's turn per leg, rad.
    pub turn_floor_rad: f64,
    /// Its error per radian turned (lx + ly off by a few per cent).
    pub turn_fraction: f64,
}

impl Priors {
    /// The beliefs of `config` on `field` (the beacons as `[field] beacons_m` places them).
    pub fn from_config(config: &Config, field: &Field) -> Self {
        let robot = &config.robot;
        Self {
            beacons: field.beacons().iter().map(|b| b.circle.center).collect(),
            tape: Vec::new(),
            tape_sigma_m: TAPE_SIGMA_M,
            poles_from_sheet: Vec::new(),
            pole_from_sheet_sigma_m: POLE_FROM_SHEET_SIGMA_M,
            beacon_sigma_m: BEACON_PLACEMENT_SIGMA_M,
            beacon_radius_m: field.beacons()[0].circle.radius_m,
            mount: robot.lidar_mount(),
            range_scale_sigma: 0.05,
            range_offset_sigma_m: 0.05,
            mount_yaw_sigma_rad: 10f64.to_radians(),
            odometry_forward_fraction: 0.02,
            odometry_strafe_fraction: 0.20,
            odometry_cross_fraction: 0.01,
            odometry_floor_m: 0.002,
            turn_floor_rad: 0.5f64.to_radians(),
            turn_fraction: 0.03,
        }
    }
}

/// The fitted calibration, with each quantity's standard deviation from the fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// The lidar reads `range_scale × true + range_offset_m`.
    pub range_scale: f64,
    /// See `range_scale`, m.
    pub range_offset_m: f64,
    /// The lidar's zero angle on the robot, rad (the config's `lidar_yaw_deg`).
    pub mount_yaw_rad: f64,
    /// The beacons' centres, world frame, m.
    pub beacons: Vec<Vec2>,
    /// σ of `range_scale`.
    pub range_scale_std: f64,
    /// σ of `range_offset_m`, m.
    pub range_offset_std_m: f64,
    /// σ of `mount_yaw_rad`, rad.
    pub mount_yaw_std_rad: f64,
    /// σ of each beacon's centre (the larger axis), m.
    pub beacon_std_m: Vec<f64>,
    /// RMS of the normalised residuals at the solution (about 1 when the error model
    /// holds).
    pub residual_rms: f64,
    /// Iterations taken.
    pub iterations: usize,
}

impl Calibration {
    /// Write the calibration into `config`: `[lidar] range_scale`, `range_offset_m`,
    /// `[robot] lidar_yaw_deg` (kept within a turn of the believed value) and `[field]
    /// beacons_m`.
    pub fn apply(&self, config: &mut Config) {
        config.lidar.range_scale = self.range_scale;
        config.lidar.range_offset_m = self.range_offset_m;
        let believed = config.robot.lidar_yaw_deg.to_radians();
        config.robot.lidar_yaw_deg =
            (believed + wrap_angle(self.mount_yaw_rad - believed)).to_degrees();
        for (slot, beacon) in config.field.beacons_m.iter_mut().zip(&self.beacons) {
            *slot = [beacon.x, beacon.y];
        }
    }

    /// Set the calibrated keys in `file`, a configuration file's table whose values are
    /// `config` (`[lidar] range_scale`, `range_offset_m`, `[robot] lidar_yaw_deg`, `[field]
    /// beacons_m`), keeping every other key the team wrote and no more: a robot's file stays
    /// a robot's file.
    pub fn write_into(&self, config: &Config, file: &mut toml::Table) {
        let mut calibrated = config.clone();
        self.apply(&mut calibrated);
        let mut set = |section: &str, key: &str, value: toml::Value| {
            let entry = file
                .entry(section)
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if !entry.is_table() {
                *entry = toml::Value::Table(toml::Table::new());
            }
            if let toml::Value::Table(table) = entry {
                table.insert(key.to_owned(), value);
            }
        };
        set("lidar", "range_scale", calibrated.lidar.range_scale.into());
        set(
            "lidar",
            "range_offset_m",
            calibrated.lidar.range_offset_m.into(),
        );
        set(
            "robot",
            "lidar_yaw_deg",
            calibrated.robot.lidar_yaw_deg.into(),
        );
        let beacons = calibrated
            .field
            .beacons_m
            .iter()
            .map(|&[x, y]| toml::Value::Array(vec![x.into(), y.into()]))
            .collect();
        set("field", "beacons_m", toml::Value::Array(beacons));
    }
}

/// Why the drive's data cannot be fitted.
#[derive(Clone, Debug, PartialEq)]
pub enum CalibrationError {
    /// Fewer stops than [`MIN_STOPS`].
    TooFewStops {
        /// Stops recorded.
        stops: usize,
    },
    /// A beacon was seen from fewer than [`MIN_SIGHTINGS_PER_BEACON`] stops.
    BeaconUnseen {
        /// Which.
        beacon: usize,
        /// From how many stops.
        stops: usize,
    },
    /// The stops span less than [`MIN_DRIVE_M`] of odometry.
    DriveTooShort {
        /// The longest distance between two stops, m.
        span_m: f64,
    },
    /// A tape measure between poles that do not exist or between a pole and itself.
    BadTape {
        /// One end.
        from: usize,
        /// The other.
        to: usize,
    },
    /// A pole measured from the sheet that does not exist.
    BadPoleFromSheet {
        /// The beacon index given.
        beacon: usize,
    },
    /// The fit did not converge to a finite solution.
    NoSolution,
    /// The fit ended with residuals larger than [`MAX_RESIDUAL_RMS`].
    Inconsistent {
        /// The RMS of the normalised residuals.
        residual_rms: f64,
    },
}

impl fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooFewStops { stops } => write!(
                f,
                "{stops} stops recorded; the calibration needs at least {MIN_STOPS}"
            ),
            Self::BeaconUnseen { beacon, stops } => write!(
                f,
                "beacon {beacon} was found from {stops} stop(s), it needs \
                 {MIN_SIGHTINGS_PER_BEACON}: is the pole in place, and nothing in the way \
                 at the lidar's height?"
            ),
            Self::DriveTooShort { span_m } => write!(
                f,
                "the stops span {:.0} mm; the mount yaw needs a drive of at least {:.0} mm",
                span_m * 1e3,
                MIN_DRIVE_M * 1e3
            ),
            Self::BadTape { from, to } => write!(
                f,
                "a tape measure from beacon {from} to beacon {to}: each end must be a \
                 different beacon, 0 to 3"
            ),
            Self::BadPoleFromSheet { beacon } => write!(
                f,
                "a pole measured from the sheet's edges is beacon {beacon}: beacons are 0 to 3"
            ),
            Self::NoSolution => write!(f, "the fit did not converge (the sightings disagree)"),
            Self::Inconsistent { residual_rms } => write!(
                f,
                "the sightings and the odometry disagree ({residual_rms:.1} σ RMS, at most \
                 {MAX_RESIDUAL_RMS} expected): was a pole moved or something standing next to \
                 one, or did a wheel slip? Nothing was written; clear the poles and drive again"
            ),
        }
    }
}

impl std::error::Error for CalibrationError {}

/// Where each unknown sits in the parameter vector.
struct Layout {
    beacons: usize,
    stops: usize,
}

impl Layout {
    const SCALE: usize = 0;
    const OFFSET: usize = 1;
    const MOUNT_YAW: usize = 2;
    const FIRST_BEACON: usize = 3;

    fn beacon(&self, j: usize) -> usize {
        Self::FIRST_BEACON + 2 * j
    }

    fn stop(&self, k: usize) -> usize {
        Self::FIRST_BEACON + 2 * self.beacons + 3 * k
    }

    fn len(&self) -> usize {
        self.stop(self.stops)
    }
}

/// Fit the calibration to `stops` (in the order driven) from `priors`.
pub fn solve(stops: &[Stop], priors: &Priors) -> Result<Calibration, CalibrationError> {
    check_data(stops, priors)?;
    let layout = Layout {
        beacons: priors.beacons.len(),
        stops: stops.len(),
    };
    let mut x = initial(stops, priors, &layout);
    let problem = Problem {
        stops,
        priors,
        layout: &layout,
    };
    let mut r = problem.residuals(&x);
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    for _ in 0..MAX_ITERATIONS {
        iterations += 1;
        let j = problem.jacobian(&x);
        let jtj = j.transpose() * &j;
        let g = j.transpose() * &r;
        let mut improved = false;
        while lambda < 1e12 {
            let mut damped = jtj.clone();
            for i in 0..damped.nrows() {
                damped[(i, i)] += lambda * jtj[(i, i)].max(1e-9);
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let candidate = &x + &step;
            let r_new = problem.residuals(&candidate);
            let cost_new = r_new.norm_squared();
            if cost_new.is_finite() && cost_new < cost {
                let converged = step.amax() < 1e-10 || (cost - cost_new) < 1e-12 * cost;
                x = candidate;
                r = r_new;
                cost = cost_new;
                lambda = (lambda / 3.0).max(1e-12);
                improved = !converged;
                break;
            }
            lambda *= 4.0;
        }
        if !improved {
            break;
        }
    }
    if !cost.is_finite() {
        return Err(CalibrationError::NoSolution);
    }
    let j = problem.jacobian(&x);
    let covariance = (j.transpose() * &j)
        .try_inverse()
        .ok_or(CalibrationError::NoSolution)?;
    let residual_rms = (cost / r.len() as f64).sqrt();
    if residual_rms > MAX_RESIDUAL_RMS {
        return Err(CalibrationError::Inconsistent { residual_rms });
    }
    let std = |i: usize| covariance[(i, i)].max(0.0).sqrt();
    Ok(Calibration {
        range_scale: x[Layout::SCALE],
        range_offset_m: x[Layout::OFFSET],
        mount_yaw_rad: x[Layout::MOUNT_YAW],
        beacons: (0..layout.beacons)
            .map(|b| Vec2::new(x[layout.beacon(b)], x[layout.beacon(b) + 1]))
            .collect(),
        range_scale_std: std(Layout::SCALE),
        range_offset_std_m: std(Layout::OFFSET),
        mount_yaw_std_rad: std(Layout::MOUNT_YAW),
        beacon_std_m: (0..layout.beacons)
            .map(|b| std(layout.beacon(b)).max(std(layout.beacon(b) + 1)))
            .collect(),
        residual_rms,
        iterations,
    })
}

fn check_data(stops: &[Stop], priors: &Priors) -> Result<(), CalibrationError> {
    if stops.len() < MIN_STOPS {
        return Err(CalibrationError::TooFewStops { stops: stops.len() });
    }
    for beacon in 0..priors.beacons.len() {
        let seen = stops
            .iter()
            .filter(|s| s.sightings.iter().any(|x| x.beacon == beacon))
            .count();
        if seen < MIN_SIGHTINGS_PER_BEACON {
            return Err(CalibrationError::BeaconUnseen {
                beacon,
                stops: seen,
            });
        }
    }
    for tape in &priors.tape {
        let n = priors.beacons.len();
        if tape.from >= n || tape.to >= n || tape.from == tape.to {
            return Err(CalibrationError::BadTape {
                from: tape.from,
                to: tape.to,
            });
        }
    }
    if let Some(pole) = priors
        .poles_from_sheet
        .iter()
        .find(|p| p.beacon >= priors.beacons.len())
    {
        return Err(CalibrationError::BadPoleFromSheet {
            beacon: pole.beacon,
        });
    }
    let span_m = stops
        .iter()
        .flat_map(|a| {
            stops
                .iter()
                .map(move |b| a.odometry.position().distance(b.odometry.position()))
        })
        .fold(0.0, f64::max);
    if span_m < MIN_DRIVE_M {
        return Err(CalibrationError::DriveTooShort { span_m });
    }
    Ok(())
}

/// The start: no range error, the believed mount and beacons, each stop's lidar where the
/// localiser put it.
fn initial(stops: &[Stop], priors: &Priors, layout: &Layout) -> DVector<f64> {
    let mut x = DVector::zeros(layout.len());
    x[Layout::SCALE] = 1.0;
    x[Layout::MOUNT_YAW] = priors.mount.yaw_rad;
    for (j, b) in priors.beacons.iter().enumerate() {
        x[layout.beacon(j)] = b.x;
        x[layout.beacon(j) + 1] = b.y;
    }
    for (k, stop) in stops.iter().enumerate() {
        let lidar = stop.estimate.compose(priors.mount);
        x[layout.stop(k)] = lidar.x;
        x[layout.stop(k) + 1] = lidar.y;
        x[layout.stop(k) + 2] = lidar.yaw_rad;
    }
    x
}

struct Problem<'a> {
    stops: &'a [Stop],
    priors: &'a Priors,
    layout: &'a Layout,
}

impl Problem<'_> {
    /// Every residual over its standard deviation.
    fn residuals(&self, x: &DVector<f64>) -> DVector<f64> {
        let (p, l) = (self.priors, self.layout);
        let mut r = Vec::new();
        let scale = x[Layout::SCALE];
        let offset = x[Layout::OFFSET];
        let mount_yaw = x[Layout::MOUNT_YAW];
        let beacon = |j: usize| Vec2::new(x[l.beacon(j)], x[l.beacon(j) + 1]);
        let lidar = |k: usize| Pose2::new(x[l.stop(k)], x[l.stop(k) + 1], x[l.stop(k) + 2]);
        // The robot's pose at a stop, from the lidar's: heading minus the mount yaw, centre
        // behind the mount's offset.
        let robot = |k: usize| {
            let lidar = lidar(k);
            let yaw = lidar.yaw_rad - mount_yaw;
            let mount = Vec2::new(p.mount.x, p.mount.y).rotated(yaw);
            Pose2::new(lidar.x - mount.x, lidar.y - mount.y, yaw)
        };
        for (k, stop) in self.stops.iter().enumerate() {
            let pose = lidar(k);
            for s in &stop.sightings {
                let local = pose.inverse_transform_point(beacon(s.beacon));
                let surface = local.norm() - p.beacon_radius_m;
                let range = scale * surface + offset + p.beacon_radius_m;
                r.push((s.range_m - range) / s.range_std_m);
                r.push(wrap_angle(s.bearing_rad - local.angle()) / s.bearing_std_rad);
            }
        }
        for k in 1..self.stops.len() {
            let (a, b) = (&self.stops[k - 1], &self.stops[k]);
            let odo = relative(a.odometry, b.odometry);
            let fit = relative(robot(k - 1), robot(k));
            let (dx, dy) = (odo.x.abs(), odo.y.abs());
            let sx = p.odometry_floor_m
                + p.odometry_forward_fraction * dx
                + p.odometry_cross_fraction * dy;
            let sy = p.odometry_floor_m
                + p.odometry_strafe_fraction * dy
                + p.odometry_cross_fraction * dx;
            let st = p.turn_floor_rad + p.turn_fraction * odo.yaw_rad.abs();
            r.push((fit.x - odo.x) / sx);
            r.push((fit.y - odo.y) / sy);
            r.push(wrap_angle(fit.yaw_rad - odo.yaw_rad) / st);
        }
        for (j, nominal) in p.beacons.iter().enumerate() {
            let b = beacon(j);
            r.push((b.x - nominal.x) / p.beacon_sigma_m);
            r.push((b.y - nominal.y) / p.beacon_sigma_m);
        }
        for tape in &p.tape {
            let fitted = beacon(tape.from).distance(beacon(tape.to));
            r.push((fitted - tape.distance_m) / p.tape_sigma_m);
        }
        for pole in &p.poles_from_sheet {
            let b = beacon(pole.beacon);
            r.push((b.x - pole.position.x) / p.pole_from_sheet_sigma_m);
            r.push((b.y - pole.position.y) / p.pole_from_sheet_sigma_m);
        }
        r.push((scale - 1.0) / p.range_scale_sigma);
        r.push(offset / p.range_offset_sigma_m);
        r.push(wrap_angle(mount_yaw - p.mount.yaw_rad) / p.mount_yaw_sigma_rad);
        DVector::from_vec(r)
    }

    fn jacobian(&self, x: &DVector<f64>) -> DMatrix<f64> {
        let rows = self.residuals(x).len();
        let mut j = DMatrix::zeros(rows, x.len());
        for i in 0..x.len() {
            let mut plus = x.clone();
            let mut minus = x.clone();
            plus[i] += JACOBIAN_STEP;
            minus[i] -= JACOBIAN_STEP;
            let column = (self.residuals(&plus) - self.residuals(&minus)) / (2.0 * JACOBIAN_STEP);
            j.set_column(i, &column);
        }
        j
    }
}

/// `b` in the frame of `a`.
fn relative(a: Pose2, b: Pose2) -> Pose2 {
    a.inverse().compose(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::Sighting;
    use crate::rng::SimRng;

    /// A drawn truth and the stops a robot driving `path` (robot poses) would record in it,
    /// with sighting noise `noise_m` and odometry that is exact up to `odometry_scale`.
    struct Synthetic {
        scale: f64,
        offset: f64,
        mount_yaw: f64,
        beacons: Vec<Vec2>,
        stops: Vec<Stop>,
    }

    fn synthetic(seed: u64, priors: &Priors, path: &[Pose2], noise_m: f64) -> Synthetic {
        let mut rng = SimRng::new(seed);
        let scale = 1.0 + rng.uniform_in(-0.015, 0.015);
        let offset = rng.uniform_in(-0.01, 0.01);
        let mount_yaw = priors.mount.yaw_rad + rng.uniform_in(-3.0, 3.0).to_radians();
        let beacons: Vec<Vec2> = priors
            .beacons
            .iter()
            .map(|b| *b + Vec2::new(rng.normal(0.005), rng.normal(0.005)))
            .collect();
        let mount = Pose2::new(priors.mount.x, priors.mount.y, mount_yaw);
        let odometry_scale = 1.0 + rng.normal(0.003);
        let stops = path
            .iter()
            .map(|&pose| {
                let lidar = pose.compose(mount);
                let sightings = beacons
                    .iter()
                    .enumerate()
                    .map(|(beacon, &b)| {
                        let local = lidar.inverse_transform_point(b);
                        let r = priors.beacon_radius_m;
                        Sighting {
                            beacon,
                            range_m: scale * (local.norm() - r) + offset + r + rng.normal(noise_m),
                            bearing_rad: local.angle() + rng.normal(noise_m / local.norm()),
                            range_std_m: noise_m.max(0.001),
                            bearing_std_rad: (noise_m / local.norm()).max(1e-3_f64.to_radians()),
                            scans: 10,
                        }
                    })
                    .collect();
                let start = path[0];
                let odometry_position =
                    start.position() + (pose.position() - start.position()) * odometry_scale;
                Stop {
                    odometry: Pose2::new(odometry_position.x, odometry_position.y, pose.yaw_rad),
                    // The uncalibrated localiser: a few cm and the mount's degrees off.
                    estimate: Pose2::new(
                        pose.x + 0.02,
                        pose.y - 0.01,
                        pose.yaw_rad + (mount_yaw - priors.mount.yaw_rad),
                    ),
                    sightings,
                }
            })
            .collect();
        Synthetic {
            scale,
            offset,
            mount_yaw,
            beacons,
            stops,
        }
    }

    /// Up 0.7 m and back facing +y, then right 0.55 m and back facing +x, from the start
    /// area: forward legs only.
    fn drive() -> Vec<Pose2> {
        use std::f64::consts::FRAC_PI_2;
        vec![
            Pose2::new(-0.64, -0.42, FRAC_PI_2),
            Pose2::new(-0.64, -0.07, FRAC_PI_2),
            Pose2::new(-0.64, 0.28, FRAC_PI_2),
            Pose2::new(-0.64, -0.07, FRAC_PI_2),
            Pose2::new(-0.64, -0.07, 0.0),
            Pose2::new(-0.36, -0.07, 0.0),
            Pose2::new(-0.09, -0.07, 0.0),
        ]
    }

    /// The four sides of the beacons' quadrilateral, measured exactly.
    fn tape(beacons: &[Vec2]) -> Vec<TapeMeasure> {
        [(0, 1), (1, 2), (2, 3), (3, 0)]
            .iter()
            .map(|&(from, to)| TapeMeasure {
                from,
                to,
                distance_m: beacons[from].distance(beacons[to]),
            })
            .collect()
    }

    fn priors() -> Priors {
        Priors::from_config(&Config::default(), &Field::competition())
    }

    #[test]
    fn the_fit_recovers_a_drawn_truth_from_noiseless_sightings_and_tape_measures() {
        let mut priors = priors();
        for seed in 1..=5 {
            let truth = synthetic(seed, &priors, &drive(), 0.0);
            priors.tape = tape(&truth.beacons);
            let fit = solve(&truth.stops, &priors).unwrap();
            assert!(
                wrap_angle(fit.mount_yaw_rad - truth.mount_yaw).abs() < 0.05f64.to_radians(),
                "seed {seed}: yaw {} vs {}",
                fit.mount_yaw_rad.to_degrees(),
                truth.mount_yaw.to_degrees()
            );
            assert!(
                (fit.range_offset_m - truth.offset).abs() < 0.003,
                "seed {seed}: {fit:?}"
            );
            assert!(
                (fit.range_scale - truth.scale).abs() < 0.004,
                "seed {seed}: {fit:?}"
            );
            // The beacons' layout (not their common shift, which nothing here can see).
            for a in 0..4 {
                for b in a + 1..4 {
                    let fitted = fit.beacons[a].distance(fit.beacons[b]);
                    let true_m = truth.beacons[a].distance(truth.beacons[b]);
                    assert!((fitted - true_m).abs() < 0.003, "seed {seed}: {a}-{b}");
                }
            }
            assert!(fit.residual_rms < 0.5, "seed {seed}: {}", fit.residual_rms);
        }
    }

    #[test]
    fn the_fit_corrects_most_of_a_three_degree_mount_error_with_noise() {
        let priors = priors();
        let mut worst: f64 = 0.0;
        for seed in 10..20 {
            let truth = synthetic(seed, &priors, &drive(), 0.002);
            let fit = solve(&truth.stops, &priors).unwrap();
            let error = wrap_angle(fit.mount_yaw_rad - truth.mount_yaw).abs();
            worst = worst.max(error);
            assert!(fit.mount_yaw_std_rad > 0.0);
        }
        assert!(worst < 0.3f64.to_radians(), "worst {}°", worst.to_degrees());
    }

    #[test]
    fn tape_measures_between_the_poles_narrow_the_range_scale_and_the_fit_knows_its_error() {
        let mut priors = priors();
        for seed in 1..=10 {
            let truth = synthetic(seed, &priors, &drive(), 0.001);
            priors.tape.clear();
            let without = solve(&truth.stops, &priors).unwrap();
            priors.tape = tape(&truth.beacons);
            let with = solve(&truth.stops, &priors).unwrap();
            assert!(
                with.range_scale_std < without.range_scale_std,
                "seed {seed}"
            );
            for fit in [&without, &with] {
                let error = (fit.range_scale - truth.scale).abs();
                assert!(error < 3.0 * fit.range_scale_std, "seed {seed}: {fit:?}");
            }
        }
    }

    #[test]
    fn poles_measured_from_the_sheet_place_the_layout_on_the_field() {
        let nominal = priors();
        // The robot believes the whole layout 8 mm off where it stands: no sighting nor
        // odometry can tell (every pose moves with it).
        let mut priors = nominal.clone();
        for b in &mut priors.beacons {
            *b = *b - Vec2::new(0.008, -0.008);
        }
        let (mut worst_without, mut worst_with) = (0.0f64, 0.0f64);
        for seed in 1..=10 {
            let truth = synthetic(seed, &nominal, &drive(), 0.001);
            priors.tape = tape(&truth.beacons);
            priors.poles_from_sheet.clear();
            let without = solve(&truth.stops, &priors).unwrap();
            priors.poles_from_sheet = truth
                .beacons
                .iter()
                .enumerate()
                .map(|(beacon, &position)| PoleFromSheet { beacon, position })
                .collect();
            let with = solve(&truth.stops, &priors).unwrap();
            let worst = |fit: &Calibration| {
                fit.beacons
                    .iter()
                    .zip(&truth.beacons)
                    .map(|(f, t)| f.distance(*t))
                    .fold(0.0, f64::max)
            };
            worst_without = worst_without.max(worst(&without));
            worst_with = worst_with.max(worst(&with));
        }
        assert!(worst_without > 0.008, "{worst_without}");
        assert!(worst_with < 0.003, "{worst_with}");
        priors.poles_from_sheet = vec![PoleFromSheet {
            beacon: 4,
            position: Vec2::ZERO,
        }];
        let truth = synthetic(1, &nominal, &drive(), 0.001);
        assert_eq!(
            solve(&truth.stops, &priors),
            Err(CalibrationError::BadPoleFromSheet { beacon: 4 })
        );
    }

    #[test]
    fn a_pole_moved_half_way_through_the_drive_is_refused_not_fitted() {
        let priors = priors();
        let mut truth = synthetic(3, &priors, &drive(), 0.001);
        assert!(solve(&truth.stops, &priors).is_ok());
        // Someone knocks beacon 2 by 5 cm after the fourth stop: its later sightings are
        // of a pole the earlier ones do not agree with.
        for stop in &mut truth.stops[4..] {
            for s in stop.sightings.iter_mut().filter(|s| s.beacon == 2) {
                s.range_m += 0.05;
            }
        }
        match solve(&truth.stops, &priors) {
            Err(CalibrationError::Inconsistent { residual_rms }) => {
                assert!(residual_rms > MAX_RESIDUAL_RMS)
            }
            other => panic!("expected Inconsistent, got {other:?}"),
        }
    }

    #[test]
    fn the_calibration_is_written_into_a_file_keeping_the_team_s_other_keys() {
        let priors = priors();
        let truth = synthetic(2, &priors, &drive(), 0.001);
        let fit = solve(&truth.stops, &priors).unwrap();
        let text = "[link]\nmega_port = \"/dev/ratf-mega\"\n[lidar]\nscan_rate_hz = 7.0\n";
        let config = Config::robot_from_toml_str(text).unwrap();
        let mut file: toml::Table = toml::from_str(text).unwrap();
        fit.write_into(&config, &mut file);
        let written = toml::to_string(&file).unwrap();
        let calibrated = Config::robot_from_toml_str(&written).unwrap();
        let mut expected = config.clone();
        fit.apply(&mut expected);
        assert_eq!(calibrated, expected);
        assert_eq!(calibrated.link.mega_port, "/dev/ratf-mega");
        assert!(
            !written.contains("[sim]") && !written.contains("[navigation]"),
            "{written}"
        );
    }

    #[test]
    fn missing_data_is_named() {
        let priors = priors();
        let truth = synthetic(1, &priors, &drive(), 0.0);
        assert_eq!(
            solve(&truth.stops[..2], &priors),
            Err(CalibrationError::TooFewStops { stops: 2 })
        );
        let mut blind = truth.stops.clone();
        for stop in &mut blind[1..] {
            stop.sightings.retain(|s| s.beacon != 3);
        }
        assert_eq!(
            solve(&blind, &priors),
            Err(CalibrationError::BeaconUnseen {
                beacon: 3,
                stops: 1
            })
        );
        let still: Vec<Stop> = (0..4).map(|_| truth.stops[0].clone()).collect();
        assert!(matches!(
            solve(&still, &priors),
            Err(CalibrationError::DriveTooShort { .. })
        ));
    }
}
