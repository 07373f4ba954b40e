//! A faithful copy of the original 5dpo beacon EKF (original-system.md §5), for comparing
//! against [`super::Localiser`] on the same inputs. Every number and every weakness is the
//! original's; nothing is made worse:
//!
//! - state (x, y, θ), θ never wrapped; P0 = diag(0.1, 0.1, 0.1), also on reset;
//! - the first odometry message only initialises (and enables scan processing);
//! - prediction from the wheels only (the gyro is ignored), Q = diag(0.1, 0.1, 0.05) added
//!   at every odometry message whatever was travelled, F and G evaluated at the
//!   post-prediction angle;
//! - the odometry increment as the original EKF received it: the original odometry node
//!   rotated each step's chord by an extra dθ/2 (see `crate::odometry`'s doc), and the EKF
//!   takes its increments from consecutive odometry poses, so the chord it sees is
//!   rotated by dθ/2 ([`OriginalFilter::with_exact_chord`] removes this odometry-node bug
//!   to compare the filters alone);
//! - per scan, with the latest pose (no de-skew, no use of the acquisition stamp): every
//!   point pushed radially outwards by 0.045 m, transformed to the world, and associated
//!   with every beacon within 0.20 m; a beacon's observed centre is the centroid of its
//!   points (one point is enough); observations (range and bearing from the robot centre)
//!   computed once with the pre-update state;
//! - sequential updates in beacon order, each at the current state, R = diag(0.0001, 0.001),
//!   no gating, P = (I − KH)P.
//!
//! Not copied: the lidar driver's doubled angle correction (a driver bug, fixed in ours).

use nalgebra::{Matrix2, Matrix3, Matrix3x2, SMatrix, Vector2, Vector3};

use super::{Health, PoseEstimator, ScanReport};
use crate::config::RobotConfig;
use crate::drivers::imu::ImuSample;
use crate::drivers::x4::scan::Scan;
use crate::field::geometry::{Pose2, Vec2, wrap_angle};
use crate::field::{Beacon, Field};
use crate::odometry::BodyIncrement;

/// Initial and reset covariance diagonal (original §5).
pub const P0_DIAGONAL: [f64; 3] = [0.1, 0.1, 0.1];
/// Process noise added per odometry message (original §5).
pub const Q_DIAGONAL: [f64; 3] = [0.1, 0.1, 0.05];
/// Measurement noise of (range m, bearing rad) (original §5).
pub const R_DIAGONAL: [f64; 2] = [0.0001, 0.001];
/// Association radius around a beacon, m (`beacons_valid_dist`, original §5).
pub const VALID_DIST_M: f64 = 0.20;
/// Radial push of every point, m (the beacon radius, original §5).
pub const PUSH_M: f64 = 0.045;

/// The original filter.
#[derive(Clone, Debug)]
pub struct OriginalFilter {
    mount: Pose2,
    beacons: [Beacon; 4],
    x: Vector3<f64>,
    p: Matrix3<f64>,
    initialised: bool,
    over_rotate_chord: bool,
    health: Health,
}

impl OriginalFilter {
    /// The original filter at `pose` at `time_us`, for the robot's lidar mount and the
    /// field's beacons.
    pub fn new(robot: &RobotConfig, field: &Field, pose: Pose2, time_us: u64) -> Self {
        let mut f = Self {
            mount: Pose2::new(
                robot.lidar_x_m,
                robot.lidar_y_m,
                robot.lidar_yaw_deg.to_radians(),
            ),
            beacons: *field.beacons(),
            x: Vector3::zeros(),
            p: Matrix3::zeros(),
            initialised: false,
            over_rotate_chord: true,
            health: Health::default(),
        };
        f.reset(pose, time_us);
        f
    }

    /// The same filter fed the exact odometry chord, without the original odometry node's
    /// extra dθ/2 rotation.
    pub fn with_exact_chord(mut self) -> Self {
        self.over_rotate_chord = false;
        self
    }

    /// The state as the original holds it (θ not wrapped).
    pub fn raw_state(&self) -> Vector3<f64> {
        self.x
    }

    fn refresh_health(&mut self, time_us: u64) {
        self.health.time_us = time_us;
        let p = self.p;
        self.health.set_covariance(&p);
    }
}

impl PoseEstimator for OriginalFilter {
    fn on_odometry(&mut self, time_us: u64, increment: BodyIncrement) {
        if !self.initialised {
            self.initialised = true;
            self.refresh_health(time_us);
            return;
        }
        let extra = if self.over_rotate_chord {
            increment.dtheta_rad / 2.0
        } else {
            0.0
        };
        let chord = Vec2::new(increment.dx_m, increment.dy_m).rotated(extra);
        let (dd, ddn, dth) = (chord.x, chord.y, wrap_angle(increment.dtheta_rad));
        let (s, c) = self.x[2].sin_cos();
        self.x[0] += dd * c - ddn * s;
        self.x[1] += dd * s + ddn * c;
        self.x[2] += dth;
        let (s, c) = self.x[2].sin_cos();
        let f = Matrix3::new(
            1.0,
            0.0,
            -dd * s - ddn * c,
            0.0,
            1.0,
            dd * c - ddn * s,
            0.0,
            0.0,
            1.0,
        );
        let g = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        let q = Matrix3::from_diagonal(&Vector3::from(Q_DIAGONAL));
        self.p = f * self.p * f.transpose() + g * q * g.transpose();
        self.refresh_health(time_us);
    }

    fn on_gyro(&mut self, _sample: &ImuSample) {}

    fn on_scan(&mut self, scan: &Scan) {
        if !self.initialised {
            return;
        }
        let robot = Pose2::new(self.x[0], self.x[1], self.x[2]);
        let laser = robot.compose(self.mount);
        let mut sums = [(Vec2::ZERO, 0usize); 4];
        for point in &scan.points {
            let pushed = Vec2::from_angle(point.angle_rad) * (point.range_m + PUSH_M);
            let world = laser.transform_point(pushed);
            for (b, sum) in self.beacons.iter().zip(sums.iter_mut()) {
                if world.distance(b.circle.center) <= VALID_DIST_M {
                    sum.0 += world;
                    sum.1 += 1;
                }
            }
        }
        // Observations with the pre-update state.
        let (x0, y0, th0) = (self.x[0], self.x[1], self.x[2]);
        let observations: Vec<(usize, Vector2<f64>)> = sums
            .iter()
            .enumerate()
            .filter(|(_, (_, n))| *n > 0)
            .map(|(i, &(sum, n))| {
                let c = sum * (1.0 / n as f64);
                let d = Vec2::new(c.x - x0, c.y - y0);
                (i, Vector2::new(d.norm(), wrap_angle(d.y.atan2(d.x) - th0)))
            })
            .collect();
        let r = Matrix2::from_diagonal(&Vector2::from(R_DIAGONAL));
        let mut report = ScanReport {
            reference_time_us: self.health.time_us,
            ..ScanReport::default()
        };
        for (i, z) in observations {
            let b = self.beacons[i].circle.center;
            let delta = Vec2::new(b.x - self.x[0], b.y - self.x[1]);
            let d2 = delta.dot(delta);
            let d = d2.sqrt();
            if d.is_nan() || d <= 1e-9 {
                continue;
            }
            let h = Vector2::new(d, wrap_angle(delta.y.atan2(delta.x) - self.x[2]));
            let jac = SMatrix::<f64, 2, 3>::new(
                -delta.x / d,
                -delta.y / d,
                0.0,
                delta.y / d2,
                -delta.x / d2,
                -1.0,
            );
            let s = jac * self.p * jac.transpose() + r;
            let Some(s_inv) = s.try_inverse() else {
                continue;
            };
            let k: Matrix3x2<f64> = self.p * jac.transpose() * s_inv;
            self.p = (Matrix3::identity() - k * jac) * self.p;
            let nu = Vector2::new(z.x - h.x, wrap_angle(z.y - h.y));
            let nis = (nu.transpose() * s_inv * nu)[(0, 0)];
            self.x += k * nu;
            report.beacons_used += 1;
            report.nis[i] = Some(nis);
            self.health.nis_sum += nis;
        }
        report.beacons_unseen = 4 - report.beacons_used;
        self.health.last_scan = report;
        self.health.scans_applied += 1;
        self.health.beacons_used += u64::from(report.beacons_used);
        let t = self.health.time_us;
        self.refresh_health(t);
    }

    fn pose(&self) -> Pose2 {
        Pose2::new(self.x[0], self.x[1], wrap_angle(self.x[2]))
    }

    fn covariance(&self) -> Matrix3<f64> {
        self.p
    }

    fn health(&self) -> Health {
        self.health
    }

    fn reset(&mut self, pose: Pose2, time_us: u64) {
        self.x = Vector3::new(pose.x, pose.y, pose.yaw_rad);
        self.p = Matrix3::from_diagonal(&Vector3::from(P0_DIAGONAL));
        self.refresh_health(time_us);
    }
}
