//! Localisation: the robot's pose on the field from the four beacon poles its lidar sees,
//! wheel odometry and the gyro (issue 5; paper §VI.B; original-system.md §4–5, §10.10).
//!
//! Two estimators implement [`PoseEstimator`], so that the benchmark can run them side by
//! side on the same inputs: [`Localiser`] (ours) and [`original::OriginalFilter`] (a
//! faithful copy of the 5dpo filter, for comparison).
//!
//! # Frames and time
//!
//! World frame: the field's (origin at the shop-floor centre, x along the long side). Robot
//! frame: x forward, y left, at the wheel-base centre. Lidar frame: `robot.lidar_x_m`,
//! `lidar_y_m`, `lidar_yaw_deg` (0.07 m, 0, 172°) in the robot frame; scan angles are
//! counter-clockwise in it. Time: the host's µs clock, passed in; nothing here reads a clock
//! or does I/O.
//!
//! # Our model ([`Localiser`])
//!
//! State (x, y, θ, b): the pose and the gyro's z bias b (rad/s). The bias is a state
//! because the gyro gives the rotation, so an unmodelled bias would turn into heading drift
//! between scans; the beacons make it observable and standing still measures it directly.
//!
//! **Prediction**, per odometry step (one Mega batch, 50 Hz; the step covers the interval
//! since the previous batch's receive time): translation from the wheels' body increment,
//! rotation from the gyro integrated over the same interval minus b·dt. Process noise is
//! scaled by what was travelled, not added per message:
//! - translation, isotropic in the robot frame: `translation_var_m2_per_m`·|d| +
//!   `translation_var_m2_per_rad`·|dθ|; multiplied by `slip_translation_var_factor` when the
//!   step slipped (below);
//! - heading from the gyro: N²·dt (N the gyro's noise density, `robot.imu`, datasheet)
//!   plus (`gyro_scale_std`·dθ)² (a scale bias made a per-step noise, hence larger than
//!   the datasheet's tolerance: see the key); the bias random-walks with
//!   `gyro_bias_walk_rad_s_sqrt_s`;
//! - **wheel slip in rotation**: mecanum wheels slip most in rotation, the gyro does not. A
//!   step whose wheel yaw increment differs from the gyro's by more than
//!   `slip_threshold_rad` is counted as slipping (health) and its translation noise is
//!   inflated (wheels that slip in rotation slip in translation too); the heading follows
//!   the gyro whatever the wheels say;
//! - without fresh gyro data (none within `gyro_max_gap_us` of the step's end, or saturated),
//!   the wheels give the rotation with variance `wheel_heading_var_rad2_per_rad`·|dθ| +
//!   `wheel_heading_var_rad2_per_m`·|d|;
//! - standing still (the encoders report no motion and the gyro agrees within 4σ): the
//!   pose does not move, no noise is added (P does not balloon while parked, §10.10), and
//!   the gyro's mean rate is a direct measurement of b;
//! - **a gap in the telemetry** (none for [`ODOMETRY_GAP_US`]: a Mega that reset, hung or
//!   lost its cable, while the gyro and the lidar go on): the gyro bridges it in steps
//!   whose rotation is the gyro's and whose translation is unknown. The robot may still be
//!   coasting: the first such step adds (v·[`COAST_S`])² per axis, v the speed of the
//!   last step the wheels measured, and the mean stays (a Mega that comes back without a
//!   reset reports the motion in its next batch; after a reset, the beacons find it).
//!   Without it the estimate froze at the last batch while the robot turned on: a Mega
//!   unplugged in a turn left it 40° behind, and the beacons no longer matched.
//!
//! **Beacon update**, per scan, at the scan's acquisition time (see [`Localiser`]): each
//! point is de-skewed with the predicted pose at its own time into the lidar frame at one
//! reference time (the history step nearest the middle of the sweep); clusters near the
//! predicted beacons are checked for the shape of a 9 cm pole and their centres estimated
//! ([`beacons`]); each becomes a range–bearing observation of the centre from the lidar
//! origin (paper eq. 1–3 with the lidar's mount; with an identity mount it is exactly eq.
//! 3), with the covariance of the centre fit plus what the odometry noise between the
//! pole's acquisition time and the reference time adds through the de-skew. Per beacon the candidate with the smallest
//! Mahalanobis distance is taken and gated at χ²(2 dof) `gate_chi2`; sequential updates in
//! Joseph form, each re-linearised at the updated state, angles wrapped, the beacons whose
//! predicted position is best known (the nearest when the heading is uncertain) first, so
//! that each update narrows the choice among the next beacon's candidates. The inputs since
//! the reference time are then re-applied ([`history`]), so a scan handled late gives the
//! same result as the same scan handled on time.
//!
//! **Unmodelled slip.** A wheel slip that keeps the wheels' and the gyro's rotations in
//! agreement (the floor passing on only part of a straight motion) is invisible to the
//! prediction, and the beacons would then all be gated out while the error grows. So before
//! the updates, when the median NIS of the scan's beacons (at least three) exceeds
//! `inflate_above_median_nis`, the pose covariance is scaled up until the median is typical;
//! a median, so a single ghost beside one beacon cannot trigger it. A slip too small for
//! any beacon alone (a pure translation of 1–2 cm against beacons each known to about
//! 8 mm) is seen by the beacons together: the (x, y, θ) correction they agree on, fitted by
//! weighted least squares, is one measurement about twice as precise as any of them. When
//! its NIS against the prediction exceeds `inflate_above_joint_nis` (χ²(3)) while the
//! beacons' residuals about it are within the χ² 99 % quantile (they do agree: no ghost),
//! the covariance is scaled up until that NIS is typical, so the scan takes the slip at
//! once rather than a third of it per scan. When no beacon is applied for
//! `relock_after_scans` scans in a row, the pose covariance is raised back to the reset
//! values around the current mean, so that the beacons can be found and taken again. The
//! filter is then lost ([`Health::relocking`]) until a scan fixes the pose again: its
//! beacons are taken only when three or more agree on one pose and no other choice among
//! their candidates agrees on another ([`relock`]); the wide search regions of a lost
//! filter hold clutter, and a wrong candidate taken then would be tracked for seconds.
//!
//! **Errors common to every scan** ([`consider`]). After calibration the beacons still
//! stand, as a whole, a few millimetres and about a tenth of a degree off where the
//! configuration puts them, the lidar's zero angle is off by a few hundredths of a degree,
//! and the lidar sits up to a millimetre from where the robot's file puts it (fitted by the
//! odometry calibration's turns in place; a few millimetres where a ruler placed it). No
//! scan can see that (the beacons are the only reference), and treating it as
//! per-scan noise would make the filter ever more sure of a biased pose. These are consider
//! parameters: not estimated; each state carries the estimate's sensitivity to them, and
//! the covariance reported ([`PoseEstimator::covariance`], [`Health`]) adds what they
//! contribute (`beacon_frame_shift_std_m`, `beacon_frame_rotation_std_deg`,
//! `lidar_zero_angle_std_deg`, `lidar_mount_position_std_m`). The gate and the gain keep the covariance relative to the
//! beacons, which is what a shift common to all of them leaves unchanged.
//!
//! # The original ([`original::OriginalFilter`])
//!
//! original-system.md §5, number for number: see that module's doc.

pub mod beacons;
pub mod consider;
pub mod ekf;
pub mod gyro;
pub mod history;
pub mod localiser;
pub mod original;
pub mod relock;

use nalgebra::{Matrix2, Matrix3, Vector2};

use crate::drivers::imu::ImuSample;
use crate::drivers::x4::scan::Scan;
use crate::field::geometry::{Pose2, Vec2};
use crate::odometry::BodyIncrement;

pub use localiser::{COAST_S, Localiser, ODOMETRY_GAP_US};
pub use original::OriginalFilter;

/// A pose estimator fed with the robot's three inputs, in time order per input.
pub trait PoseEstimator {
    /// One wheel odometry step: `increment` (robot frame at the step's start) covers the
    /// interval since the previous call and ends at `time_us` (the batch's receive time).
    fn on_odometry(&mut self, time_us: u64, increment: BodyIncrement);
    /// One IMU sample (z rate used; bias not removed; robot axes).
    fn on_gyro(&mut self, sample: &ImuSample);
    /// One lidar revolution (points in the lidar frame, stamped at acquisition).
    fn on_scan(&mut self, scan: &Scan);
    /// The pose at the latest odometry step, world frame, yaw wrapped to (−π, π].
    fn pose(&self) -> Pose2;
    /// The covariance of (x, y, θ), m² / m·rad / rad².
    fn covariance(&self) -> Matrix3<f64>;
    /// Counters and statistics for the HMI and the logs.
    fn health(&self) -> Health;
    /// Restart at `pose` at `time_us` with the reset uncertainty.
    fn reset(&mut self, pose: Pose2, time_us: u64);
    /// The gyro's z bias measured while the robot stood still at start-up, with its
    /// standard deviation, rad/s. Estimators that do not use the gyro ignore it.
    fn set_gyro_bias(&mut self, _bias_rad_s: f64, _std_rad_s: f64) {}
}

/// What the last scan did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ScanReport {
    /// The time the observations refer to, µs.
    pub reference_time_us: u64,
    /// Beacons whose observation was applied.
    pub beacons_used: u32,
    /// Beacons whose best candidate failed the χ² gate.
    pub beacons_gated: u32,
    /// Clusters near the beacons rejected for their shape (count, extent, fit).
    pub clusters_rejected: u32,
    /// Beacons with no candidate at all.
    pub beacons_unseen: u32,
    /// Per beacon, the NIS of the observation offered (applied or gated).
    pub nis: [Option<f64>; 4],
    /// Where the scan's beacons, taken together, put the robot, against where the filter has
    /// it after the scan, both at `reference_time_us`: the correction three or more beacons
    /// agree on (their residuals about it within the χ² 99 % quantile), what the filter left
    /// of it, and how sure the beacons are. Near zero when the filter took the scan at its
    /// word. After a slip its prediction did not model (the floor passing on only part of a
    /// straight motion), the filter, sure of its pose, takes a quarter to a half of it per
    /// scan, and the rest shows here. `None` without three beacons that agree (the original
    /// filter: always).
    pub beacons_fix: Option<AgreedFix>,
}

/// Where three or more agreeing beacons of one scan put the robot, against the filter
/// ([`ScanReport::beacons_fix`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AgreedFix {
    /// Where the beacons put the robot, less where the filter has it after the scan, world
    /// frame, m.
    pub minus_estimate_m: Vec2,
    /// The covariance of where the beacons put the robot (its x, y block), from their own
    /// observations' covariances, m²: what one scan's noise alone could make of
    /// `minus_estimate_m` when the filter is right.
    pub covariance_m2: Matrix2<f64>,
}

impl AgreedFix {
    /// The standard deviation of where the beacons put the robot along the unit vector
    /// `direction` (world frame), m.
    pub fn std_along_m(&self, direction: Vec2) -> f64 {
        let d = Vector2::new(direction.x, direction.y);
        d.dot(&(self.covariance_m2 * d)).max(0.0).sqrt()
    }
}

/// Health of an estimator, for the HMI and the logs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Health {
    /// Time of the estimate (the latest odometry step), µs.
    pub time_us: u64,
    /// Square root of the largest eigenvalue of the position covariance, m.
    pub position_std_m: f64,
    /// Heading standard deviation, rad.
    pub heading_std_rad: f64,
    /// Estimated gyro z bias, rad/s (`None` when the estimator does not use the gyro).
    pub gyro_bias_rad_s: Option<f64>,
    /// The last scan.
    pub last_scan: ScanReport,
    /// Scans processed (recent enough for the history), whether or not a beacon was used.
    pub scans_applied: u64,
    /// Scans older than the history (not applied).
    pub scans_too_late: u64,
    /// Beacon observations applied, in total.
    pub beacons_used: u64,
    /// Beacon observations gated out, in total.
    pub beacons_gated: u64,
    /// Clusters rejected for their shape, in total.
    pub clusters_rejected: u64,
    /// Sum of the NIS of the applied observations (see [`Health::mean_nis`]).
    pub nis_sum: f64,
    /// Odometry steps whose wheels and gyro disagreed on the rotation (wheel slip).
    pub slip_steps: u64,
    /// Odometry steps rotated by the wheels for want of gyro data.
    pub wheel_rotation_steps: u64,
    /// Steps that bridged a gap in the telemetry with the gyro alone.
    pub bridged_steps: u64,
    /// Inputs ignored because they were not after the previous one of their kind.
    pub inputs_out_of_order: u64,
    /// Consecutive scans in which no beacon was applied.
    pub scans_without_beacons: u32,
    /// Times the pose uncertainty was raised after [`Health::scans_without_beacons`]
    /// reached the configured limit.
    pub relocks: u64,
    /// Lost: the pose uncertainty was raised ([`Health::relocks`]) and no scan since has
    /// fixed the pose again with at least three beacons that agree ([`relock`]).
    pub relocking: bool,
    /// Scans of a lost filter whose beacons did not fix the pose on their own (fewer than
    /// three that agree, or two choices of candidates that agree on different poses), so
    /// none of them was taken.
    pub relocks_refused: u64,
    /// Scans whose beacons disagreed with the prediction as a whole (median NIS above
    /// `inflate_above_median_nis`, or the correction they agree on above
    /// `inflate_above_joint_nis`), so the pose covariance was scaled up (unmodelled slip).
    pub inflations: u64,
}

impl Health {
    /// Mean NIS of the applied observations (2 dof: about 2 when consistent), or `None`.
    pub fn mean_nis(&self) -> Option<f64> {
        (self.beacons_used > 0).then(|| self.nis_sum / self.beacons_used as f64)
    }

    /// Fill the covariance-derived fields.
    fn set_covariance(&mut self, p: &Matrix3<f64>) {
        let xy = p.fixed_view::<2, 2>(0, 0).into_owned();
        self.position_std_m = xy.symmetric_eigenvalues().max().max(0.0).sqrt();
        self.heading_std_rad = p[(2, 2)].max(0.0).sqrt();
    }
}

/// The χ² quantile with `dof` degrees of freedom at the standard normal quantile `z` (for
/// example 2.326 for 99 %, ±1.96 for a 95 % two-sided band), by the Wilson–Hilferty
/// approximation: within 1 % from 3 degrees of freedom up. Used for the localiser's
/// consistency tests and the benchmark's NEES band.
pub fn chi2_quantile(dof: f64, z: f64) -> f64 {
    let k = dof.max(1.0);
    let h = 2.0 / (9.0 * k);
    k * (1.0 - h + z * h.sqrt()).powi(3)
}

/// The χ² 99 % quantile for `dof` degrees of freedom: the localiser's test of whether a
/// scan's beacons agree with each other.
pub(crate) fn chi2_99(dof: usize) -> f64 {
    const Z_99: f64 = 2.326;
    chi2_quantile(dof as f64, Z_99)
}
