//! [`Localiser`]: our estimator (model in the parent module's doc).

use nalgebra::{Matrix2, Matrix3, Matrix4, SMatrix, Vector2, Vector3};

use super::beacons::{Expected, extract};
use super::consider::Consider;
use super::ekf::{
    BIAS, EkfState, Observation, StepInput, THETA, UpdateOutcome, X, Y, predicted_measurement,
};
use super::gyro::GyroIntegrator;
use super::history::{History, Step};
use super::relock::{MIN_FIX_BEACONS, unique_fix};
use super::{AgreedFix, Health, PoseEstimator, ScanReport, chi2_99};
use crate::config::{LocalisationConfig, RobotConfig};
use crate::drivers::imu::ImuSample;
use crate::drivers::x4::scan::Scan;
use crate::field::geometry::{Pose2, Vec2, hypot, wrap_angle};
use crate::field::{Beacon, Field};
use crate::odometry::BodyIncrement;

/// Telemetry silent this long is a gap the gyro bridges, µs: 60 ms, three Mega control
/// periods, the same silence that holds the robot (`runtime::MEGA_SILENCE_PERIODS`).
pub const ODOMETRY_GAP_US: u64 = 60_000;

/// How long a robot may coast once its Mega stops hearing the host, s: 0.2, the Mega's
/// 100 ms watchdog on the host's references (after which it brakes) and the motors' 0.1 s
/// time constant. At 0.6 m/s, 12 cm.
pub const COAST_S: f64 = 0.2;

/// The beacon EKF with gyro fusion, gating, de-skew and late-scan re-application.
#[derive(Clone, Debug)]
pub struct Localiser {
    config: LocalisationConfig,
    gyro_noise_density: f64,
    mount: Pose2,
    beacons: [Beacon; 4],
    consider: Consider,
    history: History,
    gyro: GyroIntegrator,
    /// Speed of the last step the wheels measured, m/s (for a gap's coast).
    measured_speed_m_s: f64,
    /// The latest step bridges a telemetry gap.
    bridging: bool,
    health: Health,
}

impl Localiser {
    /// A localiser at `pose` at `time_us`, for the robot's lidar mount and gyro noise and
    /// the field's beacons. The gyro bias starts at 0 with
    /// `config.initial_gyro_bias_std_rad_s`.
    pub fn new(
        config: &LocalisationConfig,
        robot: &RobotConfig,
        field: &Field,
        pose: Pose2,
        time_us: u64,
    ) -> Self {
        let bias_std = config.initial_gyro_bias_std_rad_s;
        let state = EkfState::new(pose, 0.0, bias_std * bias_std, config);
        let mut health = Health {
            time_us,
            gyro_bias_rad_s: Some(0.0),
            ..Health::default()
        };
        health.set_covariance(&pose_covariance(&state));
        Self {
            config: config.clone(),
            gyro_noise_density: robot.imu.gyro_noise_density_rad_s_sqrt_hz,
            mount: robot.lidar_mount(),
            beacons: *field.beacons(),
            consider: Consider::new(config, field.beacons()),
            history: History::new(state, time_us, config.history_steps),
            gyro: GyroIntegrator::new(),
            measured_speed_m_s: 0.0,
            bridging: false,
            health,
        }
    }

    /// The full state (pose and gyro bias) at the latest odometry step.
    pub fn state(&self) -> &EkfState {
        &self.history.latest().state
    }

    /// Set the gyro bias estimate (e.g. from a start-up estimate while still) with its
    /// standard deviation, rad/s.
    pub fn set_gyro_bias(&mut self, bias_rad_s: f64, std_rad_s: f64) {
        let mut state = self.history.latest().state;
        state.mean[BIAS] = bias_rad_s;
        for i in 0..4 {
            state.covariance[(i, BIAS)] = 0.0;
            state.covariance[(BIAS, i)] = 0.0;
        }
        state.covariance[(BIAS, BIAS)] = std_rad_s * std_rad_s;
        let time_us = self.history.latest().time_us;
        self.history = History::new(state, time_us, self.config.history_steps);
    }

    fn refresh_health(&mut self) {
        let latest = self.history.latest();
        self.health.time_us = latest.time_us;
        self.health.gyro_bias_rad_s = Some(latest.state.mean[BIAS]);
        let p = self.world_covariance(&latest.state);
        self.health.set_covariance(&p);
    }

    /// The covariance of `state`'s pose in the field's frame: the filter's own, relative to
    /// the beacons, plus what the consider parameters (the beacons' frame and the lidar's
    /// zero angle) add through the state's sensitivity to them.
    fn world_covariance(&self, state: &EkfState) -> Matrix3<f64> {
        pose_covariance(state) + self.consider.pose_covariance(&state.sensitivity)
    }

    /// No telemetry for [`ODOMETRY_GAP_US`] by `now_us` (a gyro sample's time): step on to
    /// half that before `now_us` with the gyro's rotation and an unknown translation (the
    /// module documentation of [`super`]), leaving room for a batch sampled just before it
    /// arrives.
    fn bridge_telemetry_gap(&mut self, now_us: u64) {
        let latest = *self.history.latest();
        if now_us < latest.time_us + ODOMETRY_GAP_US {
            return;
        }
        let time_us = now_us - ODOMETRY_GAP_US / 2;
        let coast_m = if self.bridging {
            0.0
        } else {
            self.measured_speed_m_s * COAST_S
        };
        let input = StepInput {
            dt_s: (time_us - latest.time_us) as f64 * 1e-6,
            increment: BodyIncrement::default(),
            gyro_dtheta_rad: self.gyro.angle_between(
                latest.time_us,
                time_us,
                self.config.gyro_max_gap_us,
            ),
            unmeasured_translation_std_m: Some(coast_m),
        };
        let (state, _) = latest
            .state
            .predict(&input, &self.config, self.gyro_noise_density);
        self.history.push(Step {
            time_us,
            input: Some(input),
            state,
        });
        self.bridging = true;
        self.health.bridged_steps += 1;
        self.refresh_health();
    }

    /// Scan points de-skewed into the lidar frame at `reference` (the pose of the robot
    /// there), each point moved with the predicted motion between its time and then.
    fn deskewed_points(&self, scan: &Scan, reference: Pose2) -> Vec<Vec2> {
        let lidar_ref = reference.compose(self.mount);
        scan.points
            .iter()
            .map(|p| {
                let robot = self.history.pose_at(scan.stamp_us + p.time_offset_us);
                let world = robot
                    .compose(self.mount)
                    .transform_point(Vec2::from_angle(p.angle_rad) * p.range_m);
                lidar_ref.inverse_transform_point(world)
            })
            .collect()
    }

    /// Where each beacon should be, in the lidar frame of `state`, with a search radius
    /// grown by the predicted position's uncertainty (√(σx² + σy² + d²σθ²)), capped at
    /// `max_search_radius_m`.
    fn expected_beacons(&self, state: &EkfState) -> Vec<Expected> {
        let lidar = state.pose().compose(self.mount);
        let p = &state.covariance;
        self.beacons
            .iter()
            .map(|b| {
                let centre = lidar.inverse_transform_point(b.circle.center);
                let sigma = (p[(X, X)] + p[(Y, Y)] + centre.dot(centre) * p[(THETA, THETA)])
                    .max(0.0)
                    .sqrt();
                Expected {
                    beacon: b.index,
                    centre,
                    search_radius_m: (self.config.association_radius_m
                        + self.config.association_sigmas * sigma)
                        .min(self.config.max_search_radius_m),
                }
            })
            .collect()
    }

    /// The covariance, in (range, bearing), that the odometry between the reference step
    /// `index` and the observation's time adds to a de-skewed observation: the process
    /// noise of the steps in between (those whose middle falls between the two times),
    /// propagated from zero, moved through where the pole was seen.
    fn deskew_covariance(&self, index: usize, obs: &Observation) -> Matrix2<f64> {
        let Some(reference) = self.history.get(index) else {
            return Matrix2::zeros();
        };
        let t_ref = reference.time_us as f64;
        let (lo, hi) = (obs.time_us.min(t_ref), obs.time_us.max(t_ref));
        let mut relative = EkfState {
            covariance: Matrix4::zeros(),
            ..reference.state
        };
        for i in 0..self.history.len() {
            let Some(Step {
                time_us,
                input: Some(input),
                ..
            }) = self.history.get(i)
            else {
                continue;
            };
            let middle_us = *time_us as f64 - 0.5 * input.dt_s * 1e6;
            if lo < middle_us && middle_us < hi {
                relative = relative
                    .predict(input, &self.config, self.gyro_noise_density)
                    .0;
            }
        }
        let sigma = relative.covariance.fixed_view::<3, 3>(X, X).into_owned();
        if sigma == Matrix3::zeros() {
            return Matrix2::zeros();
        }
        let lidar_ref = reference.state.pose().compose(self.mount);
        let local = Vec2::from_angle(obs.bearing_rad) * obs.range_m;
        let lever = lidar_ref.transform_point(local) - self.history.pose_at(obs.time_us).position();
        // World displacement of the point per (δx, δy, δθ) of the relative pose.
        let world = SMatrix::<f64, 2, 3>::new(1.0, 0.0, -lever.y, 0.0, 1.0, lever.x);
        let (s, c) = lidar_ref.yaw_rad.sin_cos();
        let to_lidar = Matrix2::new(c, s, -s, c);
        let d2 = local.dot(local);
        let d = d2.sqrt();
        let to_polar = Matrix2::new(local.x / d, local.y / d, -local.y / d2, local.x / d2);
        let j = to_polar * to_lidar * world;
        j * sigma * j.transpose()
    }

    /// The candidate for the beacon at `centre` with the smallest NIS against `state`, with
    /// that NIS.
    fn best_candidate<'a>(
        &self,
        state: &EkfState,
        candidates: &'a [Observation],
        centre: Vec2,
    ) -> Option<(f64, &'a Observation)> {
        candidates
            .iter()
            .filter_map(|o| state.nis(o, centre, self.mount).map(|nis| (nis, o)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// Offer the candidate of `beacon` with the smallest NIS to the filter.
    fn offer(
        &mut self,
        state: &mut EkfState,
        candidates: &[Observation],
        beacon: &Beacon,
        report: &mut ScanReport,
    ) {
        let centre = beacon.circle.center;
        let best = self.best_candidate(state, candidates, centre);
        let Some((_, obs)) = best else {
            report.beacons_unseen += 1;
            return;
        };
        match state.update(
            obs,
            centre,
            self.mount,
            self.config.gate_chi2,
            &self.consider,
        ) {
            UpdateOutcome::Applied { nis } => {
                report.beacons_used += 1;
                report.nis[beacon.index] = Some(nis);
                self.health.nis_sum += nis;
            }
            UpdateOutcome::Gated { nis } => {
                report.beacons_gated += 1;
                report.nis[beacon.index] = Some(nis);
            }
            UpdateOutcome::Degenerate => report.beacons_unseen += 1,
        }
    }

    /// The median over the beacons of their best candidate's NIS against `state`, the pose
    /// covariance scaled by `scale`; `None` with fewer than three beacons seen (the median of
    /// three or four is robust to one bad observation; of two it is not).
    fn median_nis(
        &self,
        state: &EkfState,
        scale: f64,
        candidates: &[Vec<Observation>],
    ) -> Option<f64> {
        let scaled = scale_pose_covariance(state, scale);
        let mut nis: Vec<f64> = candidates
            .iter()
            .zip(&self.beacons)
            .filter_map(|(obs, b)| {
                self.best_candidate(&scaled, obs, b.circle.center)
                    .map(|(nis, _)| nis)
            })
            .collect();
        if nis.len() < 3 {
            return None;
        }
        nis.sort_by(f64::total_cmp);
        let m = nis.len() / 2;
        Some(if nis.len().is_multiple_of(2) {
            0.5 * (nis[m - 1] + nis[m])
        } else {
            nis[m]
        })
    }

    /// The pose correction the scan's beacons agree on, as one measurement: each beacon's
    /// best candidate (smallest NIS against `state`) linearised at `state`, combined by
    /// weighted least squares over (x, y, θ). `None` with fewer than three beacons seen (the
    /// fit then has no residual to show whether the beacons agree) or a singular geometry.
    fn joint_correction(
        &self,
        state: &EkfState,
        candidates: &[Vec<Observation>],
    ) -> Option<JointCorrection> {
        let mut rows = Vec::new();
        for (obs, beacon) in candidates.iter().zip(&self.beacons) {
            let centre = beacon.circle.center;
            let Some((_, best)) = self.best_candidate(state, obs, centre) else {
                continue;
            };
            let (h, jac) = predicted_measurement(&state.mean, centre, self.mount)?;
            let innovation = Vector2::new(best.range_m - h.x, wrap_angle(best.bearing_rad - h.y));
            let weight = best.covariance.try_inverse()?;
            rows.push((
                jac.fixed_view::<2, 3>(0, X).into_owned(),
                innovation,
                weight,
            ));
        }
        if rows.len() < 3 {
            return None;
        }
        let mut information = Matrix3::zeros();
        let mut projected = Vector3::zeros();
        for (h, nu, w) in &rows {
            information += h.transpose() * w * h;
            projected += h.transpose() * w * nu;
        }
        let covariance = information.try_inverse()?;
        let correction = covariance * projected;
        let residual_chi2 = rows
            .iter()
            .map(|(h, nu, w)| {
                let r = nu - h * correction;
                (r.transpose() * w * r)[(0, 0)]
            })
            .sum();
        Some(JointCorrection {
            correction,
            covariance,
            residual_chi2,
            residual_dof: 2 * rows.len() - 3,
        })
    }

    /// When the scan's beacons disagree with the prediction as a whole, scale the pose
    /// covariance up until they are typical again, at most by the factor that brings one
    /// of x, y, θ to its reset variance. Two tests, the larger scale kept: the median NIS
    /// of the beacons one by one (`inflate_above_median_nis`, brought to the χ²(2) median),
    /// and the NIS of the correction they agree on (`inflate_above_joint_nis`, brought to
    /// the χ²(3) median) when their residuals about it are within the χ² 99 % quantile
    /// (`agreed`: that correction, when they are), so that a ghost beside one beacon
    /// triggers neither.
    fn inflate_if_inconsistent(
        &mut self,
        state: &mut EkfState,
        candidates: &[Vec<Observation>],
        agreed: Option<JointCorrection>,
    ) {
        const CHI2_2_MEDIAN: f64 = 1.386;
        const CHI2_3_MEDIAN: f64 = 2.366;
        let median_triggered = self
            .median_nis(state, 1.0, candidates)
            .is_some_and(|median| median > self.config.inflate_above_median_nis);
        let joint = agreed.filter(|j| j.nis(state, 1.0) > self.config.inflate_above_joint_nis);
        if !median_triggered && joint.is_none() {
            return;
        }
        let reset = EkfState::new(state.pose(), 0.0, 0.0, &self.config);
        let max_log_scale = (X..=THETA)
            .map(|i| reset.covariance[(i, i)] / state.covariance[(i, i)].max(1e-12))
            .fold(f64::INFINITY, f64::min)
            .max(1.0)
            .ln();
        // Bisection on log(scale): both statistics fall as the covariance grows.
        let median_log_scale = if median_triggered {
            bisect_log_scale(max_log_scale, |scale| {
                self.median_nis(state, scale, candidates)
                    .is_some_and(|m| m > CHI2_2_MEDIAN)
            })
        } else {
            0.0
        };
        let joint_log_scale = joint.map_or(0.0, |j| {
            bisect_log_scale(max_log_scale, |scale| j.nis(state, scale) > CHI2_3_MEDIAN)
        });
        *state = scale_pose_covariance(state, median_log_scale.max(joint_log_scale).exp());
        self.health.inflations += 1;
    }

    /// A lost filter's candidates: per beacon, only the one that fixes the pose with the
    /// others ([`unique_fix`]), or none at all when the scan's beacons do not fix it on their
    /// own.
    fn fixing_candidates(
        &mut self,
        prediction: Pose2,
        mut candidates: Vec<Vec<Observation>>,
    ) -> Vec<Vec<Observation>> {
        let choice = unique_fix(prediction, &candidates, &self.beacons, self.mount);
        if choice.is_none() {
            self.health.relocks_refused += 1;
        }
        for (obs, pick) in candidates.iter_mut().zip(choice.unwrap_or_default()) {
            *obs = pick.map(|i| obs[i]).into_iter().collect();
        }
        candidates
    }

    /// After `relock_after_scans` scans without a beacon, raise the pose variances back to
    /// the reset values (the mean is kept).
    fn relock_if_lost(&mut self, state: &mut EkfState, report: &ScanReport) {
        if report.beacons_used == 0 {
            self.health.scans_without_beacons += 1;
        } else {
            self.health.scans_without_beacons = 0;
        }
        if self.health.scans_without_beacons < self.config.relock_after_scans {
            return;
        }
        self.health.scans_without_beacons = 0;
        self.health.relocks += 1;
        self.health.relocking = true;
        let reset = EkfState::new(state.pose(), 0.0, 0.0, &self.config);
        for i in X..=THETA {
            // Raising diagonal entries keeps the covariance positive semi-definite.
            state.covariance[(i, i)] = state.covariance[(i, i)].max(reset.covariance[(i, i)]);
        }
    }
}

/// A scan's beacons as one measurement of the pose ([`Localiser::joint_correction`]).
#[derive(Clone, Copy, Debug)]
struct JointCorrection {
    /// The (x, y, θ) correction to the prediction the beacons agree on, m and rad.
    correction: Vector3<f64>,
    /// Its covariance, from the beacons' own.
    covariance: Matrix3<f64>,
    /// The beacons' χ² about it.
    residual_chi2: f64,
    /// That χ²'s degrees of freedom: two per beacon less three.
    residual_dof: usize,
}

impl JointCorrection {
    /// The correction's NIS against `state`'s pose covariance scaled by `scale`: χ² with 3
    /// degrees of freedom when the prediction and the beacons are both as uncertain as
    /// they say.
    fn nis(&self, state: &EkfState, scale: f64) -> f64 {
        let total = pose_covariance(state) * scale + self.covariance;
        total.try_inverse().map_or(0.0, |t| {
            (self.correction.transpose() * t * self.correction)[(0, 0)]
        })
    }
}

/// The log of the smallest scale in [1, e^`max_log_scale`] at which `too_large` turns false
/// (it must fall as the scale grows), by bisection.
fn bisect_log_scale(max_log_scale: f64, too_large: impl Fn(f64) -> bool) -> f64 {
    let (mut lo, mut hi) = (0.0, max_log_scale);
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if too_large(mid.exp()) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// `state` with its pose covariance scaled by `scale` (the pose–bias cross terms by
/// √scale, so the covariance stays positive semi-definite).
fn scale_pose_covariance(state: &EkfState, scale: f64) -> EkfState {
    let root = scale.max(0.0).sqrt();
    let d = Matrix4::from_diagonal(&nalgebra::Vector4::new(root, root, root, 1.0));
    EkfState {
        covariance: d * state.covariance * d,
        ..*state
    }
}

/// The (x, y, θ) block of the covariance.
fn pose_covariance(state: &EkfState) -> Matrix3<f64> {
    state.covariance.fixed_view::<3, 3>(X, X).into_owned()
}

impl PoseEstimator for Localiser {
    fn on_odometry(&mut self, time_us: u64, increment: BodyIncrement) {
        let latest = *self.history.latest();
        if time_us <= latest.time_us {
            self.health.inputs_out_of_order += 1;
            return;
        }
        let input = StepInput {
            dt_s: (time_us - latest.time_us) as f64 * 1e-6,
            increment,
            gyro_dtheta_rad: self.gyro.angle_between(
                latest.time_us,
                time_us,
                self.config.gyro_max_gap_us,
            ),
            unmeasured_translation_std_m: None,
        };
        self.measured_speed_m_s = hypot(increment.dx_m, increment.dy_m) / input.dt_s;
        self.bridging = false;
        let (state, outcome) = latest
            .state
            .predict(&input, &self.config, self.gyro_noise_density);
        self.health.slip_steps += u64::from(outcome.slip);
        self.health.wheel_rotation_steps += u64::from(outcome.wheel_rotation);
        self.history.push(Step {
            time_us,
            input: Some(input),
            state,
        });
        self.refresh_health();
    }

    fn on_gyro(&mut self, sample: &ImuSample) {
        if sample.saturated {
            // A clipped rate would under-state the rotation: leave a gap, so the steps it
            // covers fall back to the wheels.
            self.gyro.clear();
            return;
        }
        if !self.gyro.push(sample.time_us, sample.gyro_rad_s[2]) {
            self.health.inputs_out_of_order += 1;
        }
        self.bridge_telemetry_gap(sample.time_us);
    }

    fn on_scan(&mut self, scan: &Scan) {
        let (Some(first), Some(last)) = (scan.points.first(), scan.points.last()) else {
            return;
        };
        let middle_us = scan.stamp_us + 0.5 * (first.time_offset_us + last.time_offset_us);
        if middle_us < self.history.oldest().time_us as f64 {
            self.health.scans_too_late += 1;
            return;
        }
        let index = self.history.nearest(middle_us);
        let Some(&reference) = self.history.get(index) else {
            return;
        };
        let mut state = reference.state;
        let points = self.deskewed_points(scan, state.pose());
        let samples = if scan.samples > 0 {
            scan.samples as usize
        } else {
            scan.points.len()
        };
        let step_rad = std::f64::consts::TAU / samples as f64;
        let radius_m = self.beacons[0].circle.radius_m;
        let expected = self.expected_beacons(&state);
        let times_us: Vec<f64> = scan
            .points
            .iter()
            .map(|p| scan.stamp_us + p.time_offset_us)
            .collect();
        let found = extract(
            &points,
            &times_us,
            &expected,
            step_rad,
            radius_m,
            &self.config,
        );
        let mut report = ScanReport {
            reference_time_us: reference.time_us,
            ..ScanReport::default()
        };
        let beacons = self.beacons;
        let candidates: Vec<Vec<Observation>> = found
            .iter()
            .map(|clusters| {
                report.clusters_rejected += clusters.rejected.len() as u32;
                clusters
                    .candidates
                    .iter()
                    .map(|o| Observation {
                        covariance: o.covariance + self.deskew_covariance(index, o),
                        ..*o
                    })
                    .collect()
            })
            .collect();
        let candidates = if self.health.relocking {
            self.fixing_candidates(state.pose(), candidates)
        } else {
            candidates
        };
        let prediction = state.pose();
        let agreed = self
            .joint_correction(&state, &candidates)
            .filter(|j| j.residual_chi2 <= chi2_99(j.residual_dof));
        self.inflate_if_inconsistent(&mut state, &candidates, agreed);
        // The nearest beacons first (their predicted positions are the best known when the
        // heading is uncertain): each update narrows the choice among the next one's
        // candidates.
        let mut order: Vec<usize> = (0..beacons.len()).collect();
        order.sort_by(|&a, &b| {
            expected[a]
                .centre
                .norm()
                .total_cmp(&expected[b].centre.norm())
                .then(a.cmp(&b))
        });
        for i in order {
            self.offer(&mut state, &candidates[i], &beacons[i], &mut report);
        }
        report.beacons_fix = agreed.map(|j| {
            let posterior = state.pose();
            AgreedFix {
                minus_estimate_m: Vec2::new(
                    prediction.x + j.correction[0] - posterior.x,
                    prediction.y + j.correction[1] - posterior.y,
                ),
                covariance_m2: j.covariance.fixed_view::<2, 2>(0, 0).into_owned(),
            }
        });
        if report.beacons_used as usize >= MIN_FIX_BEACONS {
            self.health.relocking = false;
        }
        self.relock_if_lost(&mut state, &report);
        let (config, density) = (&self.config, self.gyro_noise_density);
        self.history
            .rewrite_from(index, state, |s, i| s.predict(i, config, density).0);
        self.health.last_scan = report;
        self.health.scans_applied += 1;
        self.health.beacons_used += u64::from(report.beacons_used);
        self.health.beacons_gated += u64::from(report.beacons_gated);
        self.health.clusters_rejected += u64::from(report.clusters_rejected);
        self.refresh_health();
    }

    fn pose(&self) -> Pose2 {
        self.history.latest().state.pose()
    }

    fn covariance(&self) -> Matrix3<f64> {
        self.world_covariance(&self.history.latest().state)
    }

    fn health(&self) -> Health {
        self.health
    }

    fn set_gyro_bias(&mut self, bias_rad_s: f64, std_rad_s: f64) {
        Localiser::set_gyro_bias(self, bias_rad_s, std_rad_s);
    }

    fn reset(&mut self, pose: Pose2, time_us: u64) {
        // The gyro bias is a property of the chip, not of where the robot stands: kept.
        let latest = self.history.latest().state;
        let state = EkfState::new(
            pose,
            latest.mean[BIAS],
            latest.covariance[(BIAS, BIAS)],
            &self.config,
        );
        self.history = History::new(state, time_us, self.config.history_steps);
        self.health.relocking = false;
        self.refresh_health();
    }
}
