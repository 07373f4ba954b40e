//! The odometry's wheel radius and lx + ly from a drive among the beacons with stops
//! (`ratf calibrate odometry`).
//!
//! At each stop the robot's pose is fixed from the beacons alone ([`beacon_fix`]: the
//! stop's averaged sightings, the lidar calibrated first by `ratf calibrate`), independently
//! of the wheels. Between consecutive stops, the wheel odometry's motion (in the first
//! stop's frame) and the beacons' are compared. With wheel radius `a·r` and `lx + ly =
//! b·L` the true motion of a leg that does not turn is `a` times the odometry's forward part
//! (the strafe part has its own factor, the rollers' lateral travel), and a turn in place is
//! `a/b` times the odometry's angle; each factor is the least-squares ratio over the legs.
//! Why: the mean wheel radius scales every distance the odometry reports and lx + ly every
//! angle (real-world-errors.md: −0.3 % and +1.1 % on the 5dpo robot).
//!
//! The turns in place also place the lidar on the robot. A fix made with the lidar believed
//! at `m̂` (robot frame) when it sits at `m = m̂ + δ` is the robot's pose moved by `δ` in its
//! own frame, so across a turn by `φ` about the robot's centre the fixes move by
//! `(R(φ) − I)·δ` (in the first stop's frame) beyond what the wheels say: `δ` is the
//! least-squares solution over the turns. No single scan can see it (every fix moves with
//! it), nor can a drive that keeps its heading; a ruler puts it within a few millimetres
//! (real-world-errors.md: the mount N(0, 2 mm) per axis, harsh 5 mm), and a fix off by that
//! much moves every dock by as much, turning with the robot.

use crate::calibration::Stop;
use crate::config::Config;
use crate::field::Field;
use crate::field::geometry::{Pose2, Vec2, hypot, wrap_angle};

/// A leg turning less than this (rad) counts as straight.
pub const STRAIGHT_LEG_MAX_TURN_RAD: f64 = 0.05;
/// A leg turning more than this (rad) and moving less than [`TURN_MAX_SHIFT_M`] is a turn.
pub const TURN_MIN_RAD: f64 = 0.5;
/// Largest shift of a turn in place, m.
pub const TURN_MAX_SHIFT_M: f64 = 0.05;
/// Beacons a fix needs.
pub const MIN_BEACONS: usize = 3;

/// The pose of the robot at `stop` from its beacon sightings alone, in the beliefs of
/// `config` (range scale and offset, lidar mount) and `field` (the beacons), by
/// Gauss–Newton from the localiser's estimate; `None` with fewer than [`MIN_BEACONS`]
/// beacons or no convergence.
pub fn beacon_fix(stop: &Stop, config: &Config, field: &Field) -> Option<Pose2> {
    if stop.sightings.len() < MIN_BEACONS {
        return None;
    }
    let mount = config.robot.lidar_mount();
    let beacons = field.beacons();
    let radius = beacons.first()?.circle.radius_m;
    let (scale, offset) = (config.lidar.range_scale, config.lidar.range_offset_m);
    let residuals = |lidar: Pose2| -> Option<Vec<f64>> {
        let mut r = Vec::with_capacity(2 * stop.sightings.len());
        for s in &stop.sightings {
            let centre: Vec2 = beacons.get(s.beacon)?.circle.center;
            let local = lidar.inverse_transform_point(centre);
            let range = scale * (local.norm() - radius) + offset + radius;
            r.push((s.range_m - range) / s.range_std_m);
            r.push(wrap_angle(s.bearing_rad - local.angle()) / s.bearing_std_rad);
        }
        Some(r)
    };
    let mut lidar = stop.estimate.compose(mount);
    for _ in 0..20 {
        let r0 = residuals(lidar)?;
        let h = 1e-6;
        let columns: Vec<Vec<f64>> = (0..3)
            .map(|i| {
                let mut d = [0.0; 3];
                d[i] = h;
                let moved = Pose2::new(lidar.x + d[0], lidar.y + d[1], lidar.yaw_rad + d[2]);
                residuals(moved).map(|r| r.iter().zip(&r0).map(|(a, b)| (a - b) / h).collect())
            })
            .collect::<Option<_>>()?;
        // Normal equations JᵀJ δ = −Jᵀr.
        let mut jtj = [[0.0; 3]; 3];
        let mut jtr = [0.0; 3];
        for i in 0..3 {
            for j in 0..3 {
                jtj[i][j] = columns[i].iter().zip(&columns[j]).map(|(a, b)| a * b).sum();
            }
            jtr[i] = columns[i].iter().zip(&r0).map(|(a, b)| a * b).sum();
        }
        let delta = solve3(jtj, jtr.map(|v| -v))?;
        lidar = Pose2::new(
            lidar.x + delta[0],
            lidar.y + delta[1],
            wrap_angle(lidar.yaw_rad + delta[2]),
        );
        if delta.iter().all(|d| d.abs() < 1e-9) {
            break;
        }
    }
    let robot = lidar.compose(mount.inverse());
    robot.is_finite().then_some(robot)
}

/// `A x = b` for a 3 × 3 system by Cramer's rule; `None` when singular.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if d.abs() < 1e-300 || !d.is_finite() {
        return None;
    }
    let mut x = [0.0; 3];
    for (i, xi) in x.iter_mut().enumerate() {
        let mut m = a;
        for row in 0..3 {
            m[row][i] = b[row];
        }
        *xi = det(m) / d;
    }
    Some(x)
}

/// One leg between two stops: the odometry's motion and the beacons', each in the first
/// stop's frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leg {
    /// What the wheels say.
    pub odometry: Pose2,
    /// What the beacons say.
    pub beacons: Pose2,
}

/// The legs between consecutive stops that both have a beacon fix.
pub fn legs(stops: &[Stop], fixes: &[Option<Pose2>]) -> Vec<Leg> {
    stops
        .windows(2)
        .zip(fixes.windows(2))
        .filter_map(|(s, f)| {
            Some(Leg {
                odometry: s[0].odometry.relative(s[1].odometry),
                beacons: f[0]?.relative(f[1]?),
            })
        })
        .collect()
}

/// The fitted factors and the configuration values they give.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct OdometryFit {
    /// True mean wheel radius over the believed one.
    pub radius_factor: f64,
    /// True lx + ly over the believed.
    pub lx_plus_ly_factor: f64,
    /// Strafe travel over the (radius-corrected) odometry's: the rollers' lateral slip
    /// beyond what `robot.strafe_factor` already says (1 when it is right).
    pub strafe_correction: f64,
    /// The wheel diameter to write, m (`robot.wheel_diameter_m`).
    pub wheel_diameter_m: f64,
    /// lx + ly to write, m (front-back and left-right distances scaled together).
    pub lx_plus_ly_m: f64,
    /// The strafe factor to write (`robot.strafe_factor`): the believed one times the
    /// correction.
    pub strafe_factor: f64,
    /// Where the turns in place put the lidar less where the configuration has it, robot
    /// frame, m (module documentation).
    pub lidar_shift_m: Vec2,
    /// The lidar's position to write (`robot.lidar_x_m`, `robot.lidar_y_m`), robot frame,
    /// m: the believed one moved by `lidar_shift_m`.
    pub lidar_position_m: Vec2,
    /// Distance driven straight over the legs used, m (odometry).
    pub straight_m: f64,
    /// Angle turned in place over the legs used, rad (odometry).
    pub turned_rad: f64,
    /// RMS of the legs' distance residuals after the fit, m.
    pub residual_m: f64,
}

/// Why the legs cannot be fitted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OdometryFitError {
    /// Not enough driving straight.
    #[error(
        "only {0:.2} m driven straight between stops with beacon fixes (0.5 m needed): drive \
         longer legs, with three or more beacons in view at each stop"
    )]
    TooLittleStraight(f64),
    /// Not enough turning.
    #[error(
        "only {0:.2} rad turned in place between stops with beacon fixes (1.5 rad needed): \
         add turns in place"
    )]
    TooLittleTurning(f64),
}

/// Fit the factors to `legs`, for a robot that believes `config`.
pub fn fit(legs: &[Leg], config: &Config) -> Result<OdometryFit, OdometryFitError> {
    let (mut xx, mut xt) = (0.0, 0.0);
    let (mut yy, mut yt) = (0.0, 0.0);
    let (mut tt, mut tb) = (0.0, 0.0);
    let (mut straight_m, mut turned_rad) = (0.0, 0.0);
    for leg in legs {
        let (o, b) = (leg.odometry, leg.beacons);
        if o.yaw_rad.abs() < STRAIGHT_LEG_MAX_TURN_RAD {
            xx += o.x * o.x;
            xt += o.x * b.x;
            yy += o.y * o.y;
            yt += o.y * b.y;
            straight_m += o.x.abs();
        } else if is_turn_in_place(o) {
            tt += o.yaw_rad * o.yaw_rad;
            tb += o.yaw_rad * b.yaw_rad;
            turned_rad += o.yaw_rad.abs();
        }
    }
    if straight_m < 0.5 {
        return Err(OdometryFitError::TooLittleStraight(straight_m));
    }
    if turned_rad < 1.5 {
        return Err(OdometryFitError::TooLittleTurning(turned_rad));
    }
    let radius_factor = xt / xx;
    let strafe_correction = if yy > 0.0 {
        yt / yy / radius_factor
    } else {
        1.0
    };
    let turn_ratio = tb / tt;
    let lx_plus_ly_factor = radius_factor / turn_ratio;
    let lidar_shift_m = lidar_shift_m(legs, radius_factor, strafe_correction);
    let residuals: Vec<f64> = legs
        .iter()
        .filter(|l| l.odometry.yaw_rad.abs() < STRAIGHT_LEG_MAX_TURN_RAD)
        .map(|l| {
            let dx = l.beacons.x - radius_factor * l.odometry.x;
            let dy = l.beacons.y - radius_factor * strafe_correction * l.odometry.y;
            hypot(dx, dy)
        })
        .collect();
    let residual_m =
        (residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len().max(1) as f64).sqrt();
    Ok(OdometryFit {
        radius_factor,
        lx_plus_ly_factor,
        strafe_correction,
        wheel_diameter_m: config.robot.wheel_diameter_m * radius_factor,
        lx_plus_ly_m: config.robot.half_wheelbase_sum_m() * lx_plus_ly_factor,
        strafe_factor: config.robot.strafe_factor * strafe_correction,
        lidar_shift_m,
        lidar_position_m: Vec2::new(config.robot.lidar_x_m, config.robot.lidar_y_m) + lidar_shift_m,
        straight_m,
        turned_rad,
        residual_m,
    })
}

/// The lidar's position less the believed one, robot frame, m, from the turns in place among
/// `legs` (zero without any): the least-squares `δ` of `beacons = wheels + (R(φ) − I)·δ`
/// (module documentation), the wheels' small shift over the turn scaled by the fitted
/// factors, `φ` the beacons' angle.
fn lidar_shift_m(legs: &[Leg], radius_factor: f64, strafe_correction: f64) -> Vec2 {
    let (mut weight, mut sum) = (0.0, Vec2::ZERO);
    for leg in legs.iter().filter(|l| is_turn_in_place(l.odometry)) {
        let (o, b) = (leg.odometry, leg.beacons);
        let wheels = Vec2::new(radius_factor * o.x, radius_factor * strafe_correction * o.y);
        let r = b.position() - wheels;
        let (c, s) = (b.yaw_rad.cos(), b.yaw_rad.sin());
        // (R(φ) − I)ᵀ·r, and (R(φ) − I)ᵀ(R(φ) − I) = 2(1 − cos φ)·I.
        sum += Vec2::new((c - 1.0) * r.x + s * r.y, -s * r.x + (c - 1.0) * r.y);
        weight += 2.0 * (1.0 - c);
    }
    if weight > 0.0 {
        sum * (1.0 / weight)
    } else {
        Vec2::ZERO
    }
}

/// Whether a leg whose wheels moved by `odometry` is a turn in place ([`TURN_MIN_RAD`],
/// [`TURN_MAX_SHIFT_M`]).
pub fn is_turn_in_place(odometry: Pose2) -> bool {
    odometry.yaw_rad.abs() > TURN_MIN_RAD && odometry.position().norm() < TURN_MAX_SHIFT_M
}

impl OdometryFit {
    /// Write the fit into `config`: the wheel diameter, both wheel distances scaled
    /// together (their ratio is the drawing's; only their sum matters to the odometry), the
    /// strafe factor and the lidar's position.
    pub fn apply(&self, config: &mut Config) {
        let robot = &mut config.robot;
        robot.wheel_diameter_m = self.wheel_diameter_m;
        robot.front_back_wheel_distance_m *= self.lx_plus_ly_factor;
        robot.left_right_wheel_distance_m *= self.lx_plus_ly_factor;
        robot.strafe_factor = self.strafe_factor;
        robot.lidar_x_m = self.lidar_position_m.x;
        robot.lidar_y_m = self.lidar_position_m.y;
    }

    /// Set the keys [`OdometryFit::apply`] changes in `file`, a configuration file's table
    /// whose values are `config`.
    pub fn write_into(&self, config: &Config, file: &mut toml::Table) {
        let mut fitted = config.clone();
        self.apply(&mut fitted);
        let r = &fitted.robot;
        for (key, value) in [
            ("wheel_diameter_m", r.wheel_diameter_m),
            ("front_back_wheel_distance_m", r.front_back_wheel_distance_m),
            ("left_right_wheel_distance_m", r.left_right_wheel_distance_m),
            ("strafe_factor", r.strafe_factor),
            ("lidar_x_m", r.lidar_x_m),
            ("lidar_y_m", r.lidar_y_m),
        ] {
            super::set_config_key(file, "robot", key, value.into());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::Sighting;
    use std::f64::consts::FRAC_PI_2;

    fn leg(odo: Pose2, a: f64, strafe: f64, turn: f64) -> Leg {
        Leg {
            odometry: odo,
            beacons: Pose2::new(a * odo.x, a * strafe * odo.y, turn * odo.yaw_rad),
        }
    }

    #[test]
    fn recovers_known_factors_from_exact_legs() {
        let config = Config::default();
        let (a, strafe, b) = (0.997, 0.93, 1.011);
        let legs = [
            leg(Pose2::new(0.35, 0.001, 0.002), a, strafe, a / b),
            leg(Pose2::new(-0.35, -0.002, -0.001), a, strafe, a / b),
            leg(Pose2::new(0.0, 0.33, 0.0), a, strafe, a / b),
            leg(Pose2::new(0.001, 0.0, 1.57), a, strafe, a / b),
            leg(Pose2::new(0.0, 0.001, -1.57), a, strafe, a / b),
        ];
        let fit = fit(&legs, &config).unwrap();
        assert!(fit.lidar_shift_m.norm() < 1e-9, "{fit:?}");
        assert!((fit.radius_factor - a).abs() < 1e-4, "{fit:?}");
        assert!((fit.lx_plus_ly_factor - b).abs() < 1e-3, "{fit:?}");
        assert!((fit.strafe_correction - strafe).abs() < 1e-2, "{fit:?}");
        let mut fitted = config.clone();
        fit.apply(&mut fitted);
        let sum = fitted.robot.half_wheelbase_sum_m();
        assert!((sum - config.robot.half_wheelbase_sum_m() * b).abs() < 1e-3);
        assert!(
            (fitted.robot.strafe_factor - strafe).abs() < 1e-2,
            "{fitted:?}"
        );
        // Driven again by a robot that believes the fit, its odometry strafes as far as the
        // beacons see: nothing left to correct, and the written factor stays.
        let believed = |o: Pose2| Pose2::new(o.x, o.y * strafe, o.yaw_rad);
        let again: Vec<Leg> = legs
            .iter()
            .map(|l| Leg {
                odometry: believed(l.odometry),
                beacons: l.beacons,
            })
            .collect();
        let refit = super::fit(&again, &fitted).unwrap();
        assert!((refit.strafe_correction - 1.0).abs() < 1e-2, "{refit:?}");
        let mut twice = fitted.clone();
        refit.apply(&mut twice);
        assert!(
            (twice.robot.strafe_factor - strafe).abs() < 1e-2,
            "{twice:?}"
        );
    }

    /// Turns in place about the robot's centre, seen from fixes made with the lidar believed
    /// `shift` (robot frame) from where it sits, and straight legs: the fit finds the shift
    /// from the turns, and writes the lidar where it sits.
    #[test]
    fn the_turns_in_place_place_the_lidar_on_the_robot() {
        let config = Config::default();
        let shift = Vec2::new(0.004, -0.006);
        let seen_with_shift = |odometry: Pose2| {
            // The fixes' robot poses are the true ones moved by `shift` in the robot's frame
            // at each end: `shift⁻¹ ∘ odometry ∘ shift` between them.
            let moved = Pose2::new(shift.x, shift.y, 0.0);
            Leg {
                odometry,
                beacons: moved.inverse().compose(odometry).compose(moved),
            }
        };
        let legs = [
            seen_with_shift(Pose2::new(0.35, 0.0, 0.0)),
            seen_with_shift(Pose2::new(-0.35, 0.0, 0.0)),
            seen_with_shift(Pose2::new(0.002, -0.001, FRAC_PI_2)),
            seen_with_shift(Pose2::new(-0.001, 0.002, FRAC_PI_2)),
            seen_with_shift(Pose2::new(0.0, 0.001, -FRAC_PI_2)),
            seen_with_shift(Pose2::new(0.001, 0.0, -FRAC_PI_2)),
        ];
        // The straight legs see nothing of it.
        let straight = legs[0].beacons.position() - legs[0].odometry.position();
        assert!(straight.norm() < 1e-12, "{straight:?}");
        let fit = fit(&legs, &config).unwrap();
        assert!((fit.lidar_shift_m - shift).norm() < 1e-9, "{fit:?}");
        let mut fitted = config.clone();
        fit.apply(&mut fitted);
        assert!((fitted.robot.lidar_x_m - (config.robot.lidar_x_m + shift.x)).abs() < 1e-9);
        assert!((fitted.robot.lidar_y_m - (config.robot.lidar_y_m + shift.y)).abs() < 1e-9);
    }

    #[test]
    fn refuses_a_drive_without_turns() {
        let legs = [leg(Pose2::new(0.6, 0.0, 0.0), 1.0, 1.0, 1.0)];
        assert!(matches!(
            fit(&legs, &Config::default()),
            Err(OdometryFitError::TooLittleTurning(_))
        ));
    }

    #[test]
    fn a_beacon_fix_finds_the_pose_the_sightings_were_made_from() {
        let config = Config::default();
        let field = config.field.field();
        let truth = Pose2::new(-0.3, 0.2, 1.2);
        let lidar = truth.compose(config.robot.lidar_mount());
        let sightings = field
            .beacons()
            .iter()
            .enumerate()
            .map(|(k, b)| {
                let local = lidar.inverse_transform_point(b.circle.center);
                Sighting {
                    beacon: k,
                    range_m: local.norm(),
                    bearing_rad: local.angle(),
                    range_std_m: 0.002,
                    bearing_std_rad: 0.001,
                    scans: 10,
                }
            })
            .collect();
        let stop = Stop {
            odometry: Pose2::default(),
            estimate: Pose2::new(-0.25, 0.25, 1.1),
            sightings,
        };
        let fix = beacon_fix(&stop, &config, &field).unwrap();
        assert!(fix.position().distance(truth.position()) < 1e-6, "{fix:?}");
        assert!(
            wrap_angle(fix.yaw_rad - truth.yaw_rad).abs() < 1e-6,
            "{fix:?}"
        );
    }
}
