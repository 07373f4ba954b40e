//! Errors common to every scan that no scan can reveal: where the four beacons stand as a
//! whole and the lidar's zero angle, as left by the calibration, and where the lidar sits on
//! the robot. They are *consider*
//! parameters (consider covariance analysis, Schmidt 1966; Bar-Shalom, Li & Kirubarajan,
//! *Estimation with Applications to Tracking and Navigation*, 2001, §5.4): not estimated,
//! since the beacons are the only reference and cannot measure their own frame, but their
//! effect on the estimate is tracked so that the reported covariance covers it.
//!
//! The parameters p = (sx, sy, φ, δ, mx, my): the four beacons' common shift (m, world
//! frame), their common rotation about their centroid (rad), the lidar's zero-angle error
//! (rad, true mount yaw minus the believed one) and its position error on the robot (m,
//! robot frame, true minus believed). Each state carries its sensitivity M = ∂x̂/∂p; a
//! prediction maps it with the motion's Jacobian (M ← F M), a beacon update with the gain
//! (M ← (I − K Hₓ) M + K Hₚ), a reset clears it. The filter's own covariance P stays the
//! covariance of the error *relative to the beacons*, which is what the χ² gate and the
//! gain need (a shift common to all beacons moves every prediction alike); the pose's
//! covariance in the field's frame is P + M Σₚ Mᵀ.

use nalgebra::{Matrix3, SMatrix, SVector};

use crate::config::LocalisationConfig;
use crate::field::Beacon;
use crate::field::geometry::Vec2;

/// Index of the beacons' common shift along x in the consider parameters.
pub const SHIFT_X: usize = 0;
/// See [`SHIFT_X`].
pub const SHIFT_Y: usize = 1;
/// Index of the beacons' common rotation about their centroid.
pub const ROTATION: usize = 2;
/// Index of the lidar's zero-angle error.
pub const ZERO_ANGLE: usize = 3;
/// Index of the lidar's position error along the robot's x axis.
pub const MOUNT_X: usize = 4;
/// See [`MOUNT_X`].
pub const MOUNT_Y: usize = 5;
/// How many consider parameters there are.
pub const PARAMETERS: usize = 6;

/// The consider parameters' covariance.
pub type ParameterCovariance = SMatrix<f64, PARAMETERS, PARAMETERS>;
/// A state's sensitivity to the consider parameters: ∂(x, y, θ, b)/∂p.
pub type Sensitivity = SMatrix<f64, 4, PARAMETERS>;

/// The consider parameters' covariance and the point the beacons' rotation is about.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Consider {
    /// Σₚ, diagonal: m², m², rad², rad², m², m².
    pub covariance: ParameterCovariance,
    /// The believed beacons' centroid, world frame, m.
    pub centre: Vec2,
}

impl Consider {
    /// From the configured standard deviations, about the centroid of `beacons`.
    pub fn new(config: &LocalisationConfig, beacons: &[Beacon]) -> Self {
        let n = beacons.len().max(1) as f64;
        let centre = beacons.iter().fold(Vec2::ZERO, |a, b| a + b.circle.center) * (1.0 / n);
        let shift = config.beacon_frame_shift_std_m;
        let rotation = config.beacon_frame_rotation_std_deg.to_radians();
        let zero = config.lidar_zero_angle_std_deg.to_radians();
        let mount = config.lidar_mount_position_std_m;
        Self {
            covariance: ParameterCovariance::from_diagonal(&SVector::from([
                shift * shift,
                shift * shift,
                rotation * rotation,
                zero * zero,
                mount * mount,
                mount * mount,
            ])),
            centre,
        }
    }

    /// ∂(range, bearing)/∂p of the observation of the beacon believed at `beacon`, given
    /// `h_position`, the measurement's Jacobian with respect to the robot's (x, y): the
    /// beacon's true centre is `beacon` + s + φ·J(`beacon` − centre) (J the quarter turn),
    /// and the measurement depends on the beacon's position exactly opposite to the robot's;
    /// a zero-angle error δ turns every bearing by −δ; the lidar's true position is the
    /// robot's plus R(`yaw_rad`)(mount + m), so a mount error moves the measurement as the
    /// robot moving by R(`yaw_rad`) m does.
    pub fn jacobian(
        &self,
        beacon: Vec2,
        h_position: &SMatrix<f64, 2, 2>,
        yaw_rad: f64,
    ) -> SMatrix<f64, 2, PARAMETERS> {
        let lever = beacon - self.centre;
        let turned = nalgebra::Vector2::new(-lever.y, lever.x);
        let by_rotation = -(h_position * turned);
        let (sin, cos) = yaw_rad.sin_cos();
        let by_mount = h_position * nalgebra::Matrix2::new(cos, -sin, sin, cos);
        SMatrix::<f64, 2, PARAMETERS>::from_row_slice(&[
            -h_position[(0, 0)],
            -h_position[(0, 1)],
            by_rotation.x,
            0.0,
            by_mount[(0, 0)],
            by_mount[(0, 1)],
            -h_position[(1, 0)],
            -h_position[(1, 1)],
            by_rotation.y,
            -1.0,
            by_mount[(1, 0)],
            by_mount[(1, 1)],
        ])
    }

    /// The (x, y, θ) covariance the consider parameters add to a state whose sensitivity is
    /// `sensitivity`: (M Σₚ Mᵀ) restricted to the pose.
    pub fn pose_covariance(&self, sensitivity: &Sensitivity) -> Matrix3<f64> {
        let added = sensitivity * self.covariance * sensitivity.transpose();
        added.fixed_view::<3, 3>(0, 0).into_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Field;
    use crate::field::geometry::{Pose2, wrap_angle};
    use crate::localisation::ekf::{EkfState, Observation, predicted_measurement};
    use crate::rng::SimRng;
    use nalgebra::{Matrix2, Vector2};

    /// Mean NEES (3 dof) of a parked robot after 20 scans of the four beacons, over 400
    /// worlds whose beacons, zero angle and lidar mount are off by errors drawn from
    /// `config`'s consider distribution: with the consider term in the covariance (`true`)
    /// or without.
    fn mean_nees_with_common_errors(config: &LocalisationConfig, with_consider: bool) -> f64 {
        let field = Field::competition();
        let consider = Consider::new(config, field.beacons());
        let mount = Pose2::new(0.07, 0.0, 172f64.to_radians());
        let truth = Pose2::new(0.3, -0.2, 0.4);
        let noise = Vector2::new(0.008, 0.3f64.to_radians());
        let r = Matrix2::from_diagonal(&noise.component_mul(&noise));
        let mut rng = SimRng::new(7);
        let sd = consider.covariance.diagonal().map(f64::sqrt);
        let mut total = 0.0;
        let worlds = 400;
        for _ in 0..worlds {
            let (shift, phi, zero, mount_error) = (
                Vec2::new(rng.normal(sd[SHIFT_X]), rng.normal(sd[SHIFT_Y])),
                rng.normal(sd[ROTATION]),
                rng.normal(sd[ZERO_ANGLE]),
                Vec2::new(rng.normal(sd[MOUNT_X]), rng.normal(sd[MOUNT_Y])),
            );
            let start = Pose2::new(
                truth.x + rng.normal(config.initial_position_std_m),
                truth.y + rng.normal(config.initial_position_std_m),
                truth.yaw_rad + rng.normal(config.initial_heading_std_deg.to_radians()),
            );
            let mut state = EkfState::new(start, 0.0, 1e-6, config);
            let true_mount = Pose2::new(
                mount.x + mount_error.x,
                mount.y + mount_error.y,
                mount.yaw_rad + zero,
            );
            let true_mean = nalgebra::Vector4::new(truth.x, truth.y, truth.yaw_rad, 0.0);
            for _ in 0..20 {
                for b in field.beacons() {
                    let believed = b.circle.center;
                    let lever = believed - consider.centre;
                    let moved = believed + shift + Vec2::new(-lever.y, lever.x) * phi;
                    let (z, _) = predicted_measurement(&true_mean, moved, true_mount).unwrap();
                    let obs = Observation {
                        beacon: b.index,
                        range_m: z.x + rng.normal(noise.x),
                        bearing_rad: wrap_angle(z.y + rng.normal(noise.y)),
                        covariance: r,
                        points: 10,
                        time_us: 0.0,
                    };
                    state.update(&obs, believed, mount, f64::INFINITY, &consider);
                }
            }
            let e = nalgebra::Vector3::new(
                state.mean[0] - truth.x,
                state.mean[1] - truth.y,
                wrap_angle(state.mean[2] - truth.yaw_rad),
            );
            let mut p = state.covariance.fixed_view::<3, 3>(0, 0).into_owned();
            if with_consider {
                p += consider.pose_covariance(&state.sensitivity);
            }
            total += (e.transpose() * p.try_inverse().unwrap() * e)[(0, 0)];
        }
        total / f64::from(worlds)
    }

    #[test]
    fn a_filter_fed_beacons_with_a_common_bias_is_consistent_with_the_consider_term() {
        let config = LocalisationConfig::default();
        let consistent = mean_nees_with_common_errors(&config, true);
        // χ²(3·400)/400: 95 % of such means fall within [2.77, 3.24].
        assert!((2.7..3.3).contains(&consistent), "mean NEES {consistent}");
        // Without it, the filter is sure of a pose the common errors have moved.
        let overconfident = mean_nees_with_common_errors(&config, false);
        assert!(overconfident > 10.0, "mean NEES {overconfident}");
    }

    #[test]
    fn the_standard_deviations_land_on_the_diagonal_about_the_field_centre() {
        let config = LocalisationConfig {
            beacon_frame_shift_std_m: 0.002,
            beacon_frame_rotation_std_deg: 0.1,
            lidar_zero_angle_std_deg: 0.05,
            lidar_mount_position_std_m: 0.003,
            ..LocalisationConfig::default()
        };
        let consider = Consider::new(&config, Field::competition().beacons());
        assert!(consider.centre.norm() < 1e-9, "{:?}", consider.centre);
        assert!((d_mount(&consider) - 9e-6).abs() < 1e-15);
        let d = consider.covariance.diagonal();
        assert!((d[SHIFT_X] - 4e-6).abs() < 1e-15 && (d[SHIFT_Y] - 4e-6).abs() < 1e-15);
        assert!((d[ROTATION] - 0.1f64.to_radians().powi(2)).abs() < 1e-15);
        assert!((d[ZERO_ANGLE] - 0.05f64.to_radians().powi(2)).abs() < 1e-15);
    }

    fn d_mount(consider: &Consider) -> f64 {
        let d = consider.covariance.diagonal();
        assert_eq!(d[MOUNT_X], d[MOUNT_Y]);
        d[MOUNT_X]
    }

    /// The mount columns of the measurement's Jacobian against moving the lidar on the
    /// robot by a small step along each axis, at a heading where the two axes mix.
    #[test]
    fn the_mount_columns_match_finite_differences() {
        let consider = Consider::new(
            &LocalisationConfig::default(),
            Field::competition().beacons(),
        );
        let mount = Pose2::new(0.07, 0.01, 172f64.to_radians());
        let mean = nalgebra::Vector4::new(0.3, -0.2, 0.7, 0.0);
        let beacon = Field::competition().beacons()[2].circle.center;
        let (h, jac) = predicted_measurement(&mean, beacon, mount).unwrap();
        let h_position = jac.fixed_view::<2, 2>(0, 0).into_owned();
        let analytic = consider.jacobian(beacon, &h_position, mean[2]);
        let step = 1e-6;
        for (axis, column) in [(0, MOUNT_X), (1, MOUNT_Y)] {
            let moved = Pose2::new(
                mount.x + if axis == 0 { step } else { 0.0 },
                mount.y + if axis == 1 { step } else { 0.0 },
                mount.yaw_rad,
            );
            let (h_moved, _) = predicted_measurement(&mean, beacon, moved).unwrap();
            let numeric = Vector2::new(h_moved.x - h.x, wrap_angle(h_moved.y - h.y)) / step;
            for row in 0..2 {
                assert!(
                    (numeric[row] - analytic[(row, column)]).abs() < 1e-4,
                    "row {row} column {column}: {} vs {}",
                    numeric[row],
                    analytic[(row, column)]
                );
            }
        }
    }

    #[test]
    fn a_full_sensitivity_adds_the_shift_and_the_rotation_seen_from_the_robot() {
        let config = LocalisationConfig {
            beacon_frame_shift_std_m: 0.003,
            beacon_frame_rotation_std_deg: 0.2,
            lidar_zero_angle_std_deg: 0.0,
            lidar_mount_position_std_m: 0.0,
            ..LocalisationConfig::default()
        };
        let consider = Consider::new(&config, Field::competition().beacons());
        // A robot at (0.5, 0) that follows the beacons exactly: −1 per unit of shift, and a
        // rotation φ about the centre moves it by φ·(0, 0.5) and turns it by φ.
        let mut m = Sensitivity::zeros();
        m[(0, SHIFT_X)] = -1.0;
        m[(1, SHIFT_Y)] = -1.0;
        m[(1, ROTATION)] = 0.5;
        m[(2, ROTATION)] = 1.0;
        let p = consider.pose_covariance(&m);
        let phi2 = 0.2f64.to_radians().powi(2);
        assert!((p[(0, 0)] - 9e-6).abs() < 1e-15);
        assert!((p[(1, 1)] - (9e-6 + 0.25 * phi2)).abs() < 1e-15);
        assert!((p[(2, 2)] - phi2).abs() < 1e-15);
        assert!((p[(1, 2)] - 0.5 * phi2).abs() < 1e-15);
    }
}
