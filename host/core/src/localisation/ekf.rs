//! The EKF: state (x, y, θ, b) — pose in the world frame and the gyro's z bias —, its
//! prediction from one odometry step and its range–bearing beacon update.
//!
//! See the parent module's doc for the model; this file is the maths.

use nalgebra::{Matrix2, Matrix4, SMatrix, Vector2, Vector4};

use super::consider::{Consider, Sensitivity};

use crate::config::LocalisationConfig;
use crate::field::geometry::{Pose2, Vec2, hypot, wrap_angle};
use crate::odometry::BodyIncrement;

/// Index of x, y, θ and the gyro bias in the state vector.
pub const X: usize = 0;
/// See [`X`].
pub const Y: usize = 1;
/// See [`X`].
pub const THETA: usize = 2;
/// See [`X`].
pub const BIAS: usize = 3;

/// Below this many standard deviations of the gyro's rate noise (plus
/// [`ZERO_RATE_MARGIN_RAD_S`]) a step whose wheels did not turn counts as standing still.
const ZERO_RATE_SIGMAS: f64 = 4.0;
/// Margin on the zero-rate test, rad/s: assumption, a slow creep the encoders miss over
/// 20 ms turns a wheel less than one tick (2π/2803 rad), i.e. under 0.004 rad/s of yaw.
const ZERO_RATE_MARGIN_RAD_S: f64 = 0.01;

/// What one odometry step brings: the wheels' body increment and, when fresh, the gyro's
/// raw (bias included) yaw increment over the same interval.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepInput {
    /// Step length, s.
    pub dt_s: f64,
    /// Wheel odometry increment in the robot frame at the start of the step.
    pub increment: BodyIncrement,
    /// ∫ gyro z dt over the step, rad, bias not removed; `None` when the gyro had no fresh
    /// data.
    pub gyro_dtheta_rad: Option<f64>,
    /// `Some(σ)` when the wheels sent nothing over the step (a gap in the Mega's telemetry
    /// the gyro bridges, [`super::Localiser`]): `increment` is no measurement, the robot's
    /// translation is unknown with this standard deviation per axis, m, and the step can
    /// neither learn the gyro's bias nor call a disagreement slip.
    pub unmeasured_translation_std_m: Option<f64>,
}

/// What the prediction noticed about a step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepOutcome {
    /// The gyro and the wheels disagreed on the rotation by more than the slip threshold.
    pub slip: bool,
    /// The wheels stood still and the gyro agreed: the step measured the bias.
    pub zero_rate: bool,
    /// No fresh gyro data: the wheels gave the rotation.
    pub wheel_rotation: bool,
}

/// One beacon observation in the lidar frame: range and bearing of the pole's centre from
/// the lidar origin, with its covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// Which beacon (index into the field's beacons).
    pub beacon: usize,
    /// Range from the lidar origin to the centre, m.
    pub range_m: f64,
    /// Bearing of the centre, rad, counter-clockwise from the lidar's x axis.
    pub bearing_rad: f64,
    /// Covariance of (range, bearing), m² / m·rad / rad².
    pub covariance: Matrix2<f64>,
    /// Points the centre was estimated from.
    pub points: usize,
    /// Mean acquisition time of those points, µs (the caller's time origin).
    pub time_us: f64,
}

/// Result of offering one observation to the filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UpdateOutcome {
    /// Applied; the normalised innovation squared.
    Applied {
        /// νᵀ S⁻¹ ν.
        nis: f64,
    },
    /// Outside the χ² gate; not applied.
    Gated {
        /// νᵀ S⁻¹ ν.
        nis: f64,
    },
    /// The innovation covariance could not be inverted, or the beacon coincides with the
    /// lidar: not applied.
    Degenerate,
}

/// Mean and covariance of (x, y, θ, b), with the mean's sensitivity to the consider
/// parameters ([`super::consider`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EkfState {
    /// x (m), y (m), θ (rad, wrapped to (−π, π]), gyro z bias (rad/s).
    pub mean: Vector4<f64>,
    /// Covariance of the error relative to the beacons (what the gate and the gain use).
    pub covariance: Matrix4<f64>,
    /// ∂mean/∂p, p the consider parameters (beacons' common shift x, y and rotation, the
    /// lidar's zero-angle error and its position on the robot); zero after a reset.
    pub sensitivity: Sensitivity,
}

impl EkfState {
    /// A state at `pose` with the configured reset uncertainty and the given bias estimate.
    pub fn new(pose: Pose2, bias_rad_s: f64, bias_var: f64, config: &LocalisationConfig) -> Self {
        let sp = config.initial_position_std_m;
        let sh = config.initial_heading_std_deg.to_radians();
        Self {
            mean: Vector4::new(pose.x, pose.y, wrap_angle(pose.yaw_rad), bias_rad_s),
            covariance: Matrix4::from_diagonal(&Vector4::new(sp * sp, sp * sp, sh * sh, bias_var)),
            sensitivity: Sensitivity::zeros(),
        }
    }

    /// The pose part.
    pub fn pose(&self) -> Pose2 {
        Pose2::new(self.mean[X], self.mean[Y], self.mean[THETA])
    }

    /// Advance by one odometry step (see the module doc of `localisation` for the noise
    /// model); `gyro_noise_density` in rad/s/√Hz.
    pub fn predict(
        &self,
        input: &StepInput,
        config: &LocalisationConfig,
        gyro_noise_density: f64,
    ) -> (Self, StepOutcome) {
        let inc = input.increment;
        let dt = input.dt_s.max(0.0);
        let (theta, bias) = (self.mean[THETA], self.mean[BIAS]);
        let distance_m = hypot(inc.dx_m, inc.dy_m);
        let mut outcome = StepOutcome::default();
        let mut f = Matrix4::<f64>::identity();
        let mut zero_rate_z = None;
        let rate_var = if dt > 0.0 {
            gyro_noise_density * gyro_noise_density / dt
        } else {
            f64::INFINITY
        };
        let measured = input.unmeasured_translation_std_m.is_none();
        let wheels_still = measured && distance_m == 0.0 && inc.dtheta_rad == 0.0;
        let (dtheta, heading_var) = match input.gyro_dtheta_rad {
            Some(raw) if dt > 0.0 => {
                let rate = raw / dt - bias;
                let still_limit = ZERO_RATE_SIGMAS
                    * (rate_var + self.covariance[(BIAS, BIAS)]).sqrt()
                    + ZERO_RATE_MARGIN_RAD_S;
                if wheels_still && rate.abs() < still_limit {
                    outcome.zero_rate = true;
                    zero_rate_z = Some(raw / dt);
                    (0.0, 0.0)
                } else {
                    let gyro_dtheta = raw - bias * dt;
                    f[(THETA, BIAS)] = -dt;
                    outcome.slip = measured
                        && (gyro_dtheta - inc.dtheta_rad).abs() > config.slip_threshold_rad;
                    let scale = config.gyro_scale_std * gyro_dtheta;
                    (
                        gyro_dtheta,
                        gyro_noise_density * gyro_noise_density * dt + scale * scale,
                    )
                }
            }
            _ => {
                outcome.wheel_rotation = true;
                (
                    inc.dtheta_rad,
                    config.wheel_heading_var_rad2_per_rad * inc.dtheta_rad.abs()
                        + config.wheel_heading_var_rad2_per_m * distance_m,
                )
            }
        };
        let mut translation_var = config.translation_var_m2_per_m * distance_m
            + config.translation_var_m2_per_rad * dtheta.abs();
        if outcome.slip {
            translation_var *= config.slip_translation_var_factor;
        }
        if let Some(std_m) = input.unmeasured_translation_std_m {
            translation_var += std_m * std_m;
        }
        let (s, c) = theta.sin_cos();
        let mut mean = self.mean;
        mean[X] += c * inc.dx_m - s * inc.dy_m;
        mean[Y] += s * inc.dx_m + c * inc.dy_m;
        mean[THETA] = wrap_angle(theta + dtheta);
        f[(X, THETA)] = -s * inc.dx_m - c * inc.dy_m;
        f[(Y, THETA)] = c * inc.dx_m - s * inc.dy_m;
        // Translation noise is isotropic in the body frame, so rotating it to the world
        // frame leaves it unchanged.
        let walk = config.gyro_bias_walk_rad_s_sqrt_s;
        let q = Matrix4::from_diagonal(&Vector4::new(
            translation_var,
            translation_var,
            heading_var,
            walk * walk * dt,
        ));
        let covariance = f * self.covariance * f.transpose() + q;
        let mut next = Self {
            mean,
            covariance: symmetric(covariance),
            sensitivity: f * self.sensitivity,
        };
        if let Some(z) = zero_rate_z {
            next.update_bias(z, rate_var);
        }
        (next, outcome)
    }

    /// Scalar update of the bias with a gyro rate measured while still.
    fn update_bias(&mut self, rate_rad_s: f64, rate_var: f64) {
        let h = Vector4::new(0.0, 0.0, 0.0, 1.0);
        let s = self.covariance[(BIAS, BIAS)] + rate_var;
        if !(s.is_finite() && s > 0.0) {
            return;
        }
        let k = self.covariance * h / s;
        self.mean += k * (rate_rad_s - self.mean[BIAS]);
        let i_kh = Matrix4::identity() - k * h.transpose();
        let p = i_kh * self.covariance * i_kh.transpose() + k * k.transpose() * rate_var;
        self.covariance = symmetric(p);
        self.sensitivity = i_kh * self.sensitivity;
    }

    /// Offer one beacon observation (lidar mounted at `mount` in the robot frame, beacon
    /// centre `beacon` in the world); applied when its NIS is within `gate_chi2`. The
    /// sensitivity to the consider parameters `consider` follows the gain.
    pub fn update(
        &mut self,
        obs: &Observation,
        beacon: Vec2,
        mount: Pose2,
        gate_chi2: f64,
        consider: &Consider,
    ) -> UpdateOutcome {
        let Some((h, jac)) = predicted_measurement(&self.mean, beacon, mount) else {
            return UpdateOutcome::Degenerate;
        };
        let nu = Vector2::new(obs.range_m - h.x, wrap_angle(obs.bearing_rad - h.y));
        let s = jac * self.covariance * jac.transpose() + obs.covariance;
        let Some(s_inv) = s.try_inverse() else {
            return UpdateOutcome::Degenerate;
        };
        let nis = (nu.transpose() * s_inv * nu)[(0, 0)];
        if !nis.is_finite() {
            return UpdateOutcome::Degenerate;
        }
        if nis > gate_chi2 {
            return UpdateOutcome::Gated { nis };
        }
        let k = self.covariance * jac.transpose() * s_inv;
        // The consider Jacobian is taken where the measurement's was: at the prior.
        let prior_yaw_rad = self.mean[THETA];
        self.mean += k * nu;
        self.mean[THETA] = wrap_angle(self.mean[THETA]);
        // Joseph form: stays symmetric positive semi-definite with rounding errors.
        let i_kh = Matrix4::identity() - k * jac;
        let p = i_kh * self.covariance * i_kh.transpose() + k * obs.covariance * k.transpose();
        self.covariance = symmetric(p);
        let h_position = jac.fixed_view::<2, 2>(0, 0).into_owned();
        self.sensitivity =
            i_kh * self.sensitivity + k * consider.jacobian(beacon, &h_position, prior_yaw_rad);
        UpdateOutcome::Applied { nis }
    }

    /// The NIS an observation would have, without applying it.
    pub fn nis(&self, obs: &Observation, beacon: Vec2, mount: Pose2) -> Option<f64> {
        let (h, jac) = predicted_measurement(&self.mean, beacon, mount)?;
        let nu = Vector2::new(obs.range_m - h.x, wrap_angle(obs.bearing_rad - h.y));
        let s = jac * self.covariance * jac.transpose() + obs.covariance;
        let nis = (nu.transpose() * s.try_inverse()? * nu)[(0, 0)];
        nis.is_finite().then_some(nis)
    }
}

/// Paper eq. 1–3 with the lidar's mount: the beacon centre `beacon` (world) seen from the
/// lidar of a robot at `mean`, as (range m, bearing rad), and its Jacobian with respect to
/// (x, y, θ, b). `None` when the beacon coincides with the lidar.
pub fn predicted_measurement(
    mean: &Vector4<f64>,
    beacon: Vec2,
    mount: Pose2,
) -> Option<(Vector2<f64>, SMatrix<f64, 2, 4>)> {
    let theta = mean[THETA];
    let (s, c) = theta.sin_cos();
    let lidar = Vec2::new(
        mean[X] + c * mount.x - s * mount.y,
        mean[Y] + s * mount.x + c * mount.y,
    );
    // d(lidar position)/dθ.
    let dl = Vec2::new(-s * mount.x - c * mount.y, c * mount.x - s * mount.y);
    let q = beacon - lidar;
    let d2 = q.dot(q);
    let d = d2.sqrt();
    if d.is_nan() || d <= 1e-9 {
        return None;
    }
    let h = Vector2::new(d, wrap_angle(q.y.atan2(q.x) - theta - mount.yaw_rad));
    let jac = SMatrix::<f64, 2, 4>::new(
        -q.x / d,
        -q.y / d,
        -q.dot(dl) / d,
        0.0,
        q.y / d2,
        -q.x / d2,
        (q.y * dl.x - q.x * dl.y) / d2 - 1.0,
        0.0,
    );
    Some((h, jac))
}

fn symmetric(p: Matrix4<f64>) -> Matrix4<f64> {
    (p + p.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn mount() -> Pose2 {
        Pose2::new(0.07, 0.0, 172f64.to_radians())
    }

    fn no_consider() -> Consider {
        Consider {
            covariance: super::super::consider::ParameterCovariance::zeros(),
            centre: Vec2::ZERO,
        }
    }

    #[test]
    fn measurement_geometry_with_the_mount_pose() {
        // Robot at (0.1, −0.2) facing +y; lidar 0.07 ahead, i.e. at (0.1, −0.13), its x axis
        // at 90° + 172° = 262°. Beacon (0.888, 0.538).
        let mean = Vector4::new(0.1, -0.2, FRAC_PI_2, 0.0);
        let b = Vec2::new(0.888, 0.538);
        let (h, _) = predicted_measurement(&mean, b, mount()).unwrap();
        let (qx, qy): (f64, f64) = (0.888 - 0.1, 0.538 + 0.13);
        assert!((h.x - (qx * qx + qy * qy).sqrt()).abs() < 1e-12);
        let bearing = wrap_angle(qy.atan2(qx) - FRAC_PI_2 - 172f64.to_radians());
        assert!((h.y - bearing).abs() < 1e-12);
        // With the identity mount it is exactly paper eq. 1–3: Rᵀ(p − t).
        let (h0, _) = predicted_measurement(&mean, b, Pose2::default()).unwrap();
        let local = Pose2::new(0.1, -0.2, FRAC_PI_2).inverse_transform_point(b);
        assert!((h0.x - local.norm()).abs() < 1e-12);
        assert!((h0.y - local.y.atan2(local.x)).abs() < 1e-12);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let mean = Vector4::new(-0.3, 0.25, 2.9, 0.01);
        let b = Vec2::new(-0.888, -0.538);
        let (h, jac) = predicted_measurement(&mean, b, mount()).unwrap();
        for i in 0..4 {
            let mut m = mean;
            m[i] += 1e-7;
            let (h2, _) = predicted_measurement(&m, b, mount()).unwrap();
            let num = Vector2::new(h2.x - h.x, wrap_angle(h2.y - h.y)) / 1e-7;
            assert!(
                (num - jac.column(i)).norm() < 1e-5,
                "column {i}: {num} vs {jac}"
            );
        }
    }

    proptest::proptest! {
        #[test]
        fn jacobian_matches_finite_differences_anywhere(
            x in -0.8f64..0.8, y in -0.5f64..0.5, theta in -3.1f64..3.1,
            mx in -0.1f64..0.1, my in -0.1f64..0.1, myaw in -3.1f64..3.1,
        ) {
            let mean = Vector4::new(x, y, theta, 0.0);
            let mount = Pose2::new(mx, my, myaw);
            let b = Vec2::new(0.888, 0.538);
            // The lidar cannot stand inside or against the pole.
            let lidar = Pose2::new(x, y, theta).transform_point(mount.position());
            proptest::prop_assume!(lidar.distance(b) > 0.1);
            let (h, jac) = predicted_measurement(&mean, b, mount).unwrap();
            for i in 0..3 {
                let mut m = mean;
                m[i] += 1e-7;
                let (h2, _) = predicted_measurement(&m, b, mount).unwrap();
                let num = Vector2::new(h2.x - h.x, wrap_angle(h2.y - h.y)) / 1e-7;
                proptest::prop_assert!((num - jac.column(i)).norm() < 1e-4, "column {}", i);
            }
        }
    }

    #[test]
    fn an_update_pulls_towards_the_observation_and_shrinks_the_covariance() {
        let config = LocalisationConfig::default();
        let truth = Vector4::new(0.0, 0.0, 0.3, 0.0);
        let mut state = EkfState::new(Pose2::new(0.05, -0.03, 0.35), 0.0, 1e-4, &config);
        let b = Vec2::new(0.888, 0.538);
        let (z, _) = predicted_measurement(&truth, b, mount()).unwrap();
        let obs = Observation {
            beacon: 0,
            range_m: z.x,
            bearing_rad: z.y,
            covariance: Matrix2::from_diagonal(&Vector2::new(1e-4, 1e-4)),
            points: 5,
            time_us: 0.0,
        };
        let before = state;
        let outcome = state.update(&obs, b, mount(), 9.21, &no_consider());
        assert!(
            matches!(outcome, UpdateOutcome::Applied { .. }),
            "{outcome:?}"
        );
        let (h_before, _) = predicted_measurement(&before.mean, b, mount()).unwrap();
        let (h_after, _) = predicted_measurement(&state.mean, b, mount()).unwrap();
        assert!((h_after - z).norm() < (h_before - z).norm() / 5.0);
        assert!(state.covariance.trace() < before.covariance.trace());
        assert!(state.covariance.symmetric_eigenvalues().min() >= 0.0);
        // The same observation seen from far away is gated.
        let mut tight = EkfState::new(Pose2::new(0.3, 0.0, 0.3), 0.0, 1e-4, &config);
        tight.covariance = Matrix4::identity() * 1e-6;
        assert!(matches!(
            tight.update(&obs, b, mount(), 9.21, &no_consider()),
            UpdateOutcome::Gated { .. }
        ));
    }

    #[test]
    fn stationary_steps_add_no_noise_and_learn_the_bias() {
        let config = LocalisationConfig::default();
        let mut state = EkfState::new(Pose2::new(0.1, 0.2, 0.3), 0.0, 0.05 * 0.05, &config);
        let p0 = state.covariance;
        let input = StepInput {
            dt_s: 0.02,
            increment: BodyIncrement::default(),
            gyro_dtheta_rad: Some(0.02 * 0.02),
            unmeasured_translation_std_m: None,
        };
        for _ in 0..200 {
            let (next, outcome) = state.predict(&input, &config, 1.75e-4);
            assert!(outcome.zero_rate);
            state = next;
        }
        let pose = state.pose();
        assert_eq!((pose.x, pose.y), (0.1, 0.2));
        assert!((pose.yaw_rad - 0.3).abs() < 1e-12);
        assert!((state.covariance[(X, X)] - p0[(X, X)]).abs() < 1e-15);
        assert!(
            (state.mean[BIAS] - 0.02).abs() < 1e-4,
            "{}",
            state.mean[BIAS]
        );
    }

    #[test]
    fn gyro_rotation_replaces_the_wheels_and_flags_slip() {
        let config = LocalisationConfig::default();
        let state = EkfState::new(Pose2::new(0.0, 0.0, 0.0), 0.01, 1e-6, &config);
        let input = StepInput {
            dt_s: 0.02,
            increment: BodyIncrement {
                dx_m: 0.0,
                dy_m: 0.0,
                dtheta_rad: 0.05,
            },
            gyro_dtheta_rad: Some(0.02 + 0.01 * 0.02),
            unmeasured_translation_std_m: None,
        };
        let (next, outcome) = state.predict(&input, &config, 1.75e-4);
        assert!(outcome.slip && !outcome.wheel_rotation);
        assert!((next.mean[THETA] - 0.02).abs() < 1e-12);
        let (wheels, outcome) = state.predict(
            &StepInput {
                gyro_dtheta_rad: None,
                ..input
            },
            &config,
            1.75e-4,
        );
        assert!(outcome.wheel_rotation && !outcome.slip);
        assert!((wheels.mean[THETA] - 0.05).abs() < 1e-12);
        assert!(wheels.covariance[(THETA, THETA)] > next.covariance[(THETA, THETA)]);
    }
}
