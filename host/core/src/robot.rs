//! The robot's body in the core: pose estimation from the sensors, and the wheel references
//! for a commanded body twist. Part of [`crate::runtime::Core`], which feeds it the sensor
//! inputs ([`Robot::handle`]) and, on the host's own 50 Hz tick, asks it for the wheel
//! references and the solenoid level to send to the Mega ([`Robot::tick`]), so the host never
//! waits for the Mega to speak first (original-system.md §10.1).
//!
//! What it holds: the pose estimation ([`Estimation`]: wheel odometry feeding a
//! [`PoseEstimator`], the beacon EKF with gyro fusion by default), the latest sensor readings,
//! and the motion command. The commanded body twist is turned into wheel references by the
//! mecanum inverse kinematics, scaled down as a whole when a wheel would exceed its limit, so
//! the direction of motion is kept. The robot's software never sees the ground truth: its
//! pose is the estimator's.

use crate::config::{Config, LidarConfig, Policy};
use crate::field::geometry::Pose2;
use crate::kinematics::{BodyTwist, Mecanum};
use crate::localisation::{Health, Localiser, OriginalFilter, PoseEstimator};
use crate::odometry::{Odometry, OdometryStep};
use crate::runtime::{Input, Stamped};

/// What the core asks of the hardware at a tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Output {
    /// Wheel speed references, wheel rad/s, motor index order (wire convention).
    pub wheel_speeds_rad_s: [f32; 4],
    /// Electromagnet level.
    pub solenoid_on: bool,
    /// The factor the commanded twist was scaled by to respect the wheel limit (1 = none).
    pub twist_scale: f64,
}

/// Counters of what the core has received.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct InputCounts {
    /// Telemetry batches.
    pub wheel_batches: u64,
    /// Mega resets.
    pub mega_resets: u64,
    /// Lidar scans.
    pub scans: u64,
    /// IMU samples.
    pub imu_samples: u64,
}

/// Which pose estimator the core runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EstimatorKind {
    /// Ours: the beacon EKF with gyro fusion, gating, de-skew and late scans.
    Localiser,
    /// A faithful copy of the original 5dpo filter, for comparison.
    Original,
}

impl EstimatorKind {
    /// The estimator `policy` drives with: ours runs our localiser; the original preset runs
    /// the original filter, as the 5dpo robot did (a faithful baseline localises as the
    /// original did, no better).
    pub const fn for_policy(policy: Policy) -> Self {
        match policy {
            Policy::Ours => Self::Localiser,
            Policy::Original => Self::Original,
        }
    }

    /// A fresh estimator of this kind believing the robot is at `pose` at `time_us`.
    pub fn build(self, config: &Config, pose: Pose2, time_us: u64) -> Box<dyn PoseEstimator> {
        // The robot's beliefs: the beacons where the team measured them.
        let field = config.field.field();
        match self {
            EstimatorKind::Localiser => Box::new(Localiser::new(
                &config.localisation,
                &config.robot,
                &field,
                pose,
                time_us,
            )),
            EstimatorKind::Original => {
                Box::new(OriginalFilter::new(&config.robot, &field, pose, time_us))
            }
        }
    }
}

/// Wheel odometry feeding a pose estimator: turns the core's [`Input`]s into the estimator's
/// three inputs (odometry increments, gyro samples, scans).
pub struct Estimation {
    odometry: Odometry,
    estimator: Box<dyn PoseEstimator>,
    lidar: LidarConfig,
}

impl std::fmt::Debug for Estimation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Estimation")
            .field("odometry", &self.odometry)
            .field("pose", &self.estimator.pose())
            .finish()
    }
}

impl Estimation {
    /// Odometry and an estimator of `kind`, both starting at `pose`.
    pub fn new(config: &Config, kind: EstimatorKind, pose: Pose2) -> Self {
        let mut odometry = Odometry::new(&config.robot);
        odometry.reset(pose);
        Self {
            odometry,
            estimator: kind.build(config, pose, 0),
            lidar: config.lidar.clone(),
        }
    }

    /// Consume one input (the sensors'; others are ignored); returns the odometry step when
    /// it was a telemetry batch.
    pub fn handle(&mut self, stamped: &Stamped) -> Option<OdometryStep> {
        match &stamped.input {
            Input::Wheels(telemetry) => {
                let step = self.odometry.update(telemetry.totals, telemetry.period_us);
                if !step.is_first {
                    self.estimator
                        .on_odometry(telemetry.sampled_at_us, step.body_increment);
                }
                Some(step)
            }
            Input::MegaReset => {
                self.odometry.forget_totals();
                None
            }
            Input::Scan(scan) => {
                if self.lidar.range_scale == 1.0 && self.lidar.range_offset_m == 0.0 {
                    self.estimator.on_scan(scan);
                } else {
                    let mut corrected = scan.clone();
                    for point in &mut corrected.points {
                        point.range_m = self.lidar.corrected_range_m(point.range_m);
                    }
                    self.estimator.on_scan(&corrected);
                }
                None
            }
            Input::Imu(sample) => {
                self.estimator.on_gyro(sample);
                None
            }
            _ => None,
        }
    }

    /// The estimate.
    pub fn pose(&self) -> Pose2 {
        self.estimator.pose()
    }

    /// The estimator, for its covariance and health.
    pub fn estimator(&self) -> &dyn PoseEstimator {
        self.estimator.as_ref()
    }

    /// Dead-reckoning alone (wheel odometry from the start pose).
    pub fn odometry_pose(&self) -> Pose2 {
        self.odometry.pose()
    }

    /// Restart the estimator at `pose` at `time_us` (e.g. the operator placed the robot).
    pub fn reset(&mut self, pose: Pose2, time_us: u64) {
        self.estimator.reset(pose, time_us);
    }

    /// Hand the estimator the gyro's z bias measured at start-up, rad/s.
    pub fn set_gyro_bias(&mut self, bias_rad_s: f64, std_rad_s: f64) {
        self.estimator.set_gyro_bias(bias_rad_s, std_rad_s);
    }
}

/// The core: see the module documentation.
#[derive(Debug)]
pub struct Robot {
    mecanum: Mecanum,
    max_wheel_speed_rad_s: f64,
    estimation: Estimation,
    last_odometry: Option<OdometryStep>,
    switch_pressed: bool,
    yaw_rate_rad_s: f64,
    motion: BodyTwist,
    solenoid_on: bool,
    counts: InputCounts,
}

/// The kinematics the core commands the wheels through: ours the robot's model with the
/// rollers' slip (`robot.strafe_factor`); the original preset the rigid geometry, as the
/// original's table had no slip in it (a faithful baseline commands as the original did).
fn command_kinematics(config: &Config) -> Mecanum {
    match config.competition.policy {
        Policy::Ours => Mecanum::new(&config.robot),
        Policy::Original => Mecanum::rigid(&config.robot),
    }
}

impl Robot {
    /// A core for the robot in `config`, with the estimator of its policy
    /// ([`EstimatorKind::for_policy`]), believing it starts at `start_pose`.
    pub fn new(config: &Config, start_pose: Pose2) -> Self {
        let kind = EstimatorKind::for_policy(config.competition.policy);
        Self::with_estimator(config, kind, start_pose)
    }

    /// A core with the pose estimator `kind`.
    pub fn with_estimator(config: &Config, kind: EstimatorKind, start_pose: Pose2) -> Self {
        Self {
            mecanum: command_kinematics(config),
            max_wheel_speed_rad_s: config.robot.max_wheel_speed_rad_s,
            estimation: Estimation::new(config, kind, start_pose),
            last_odometry: None,
            switch_pressed: false,
            yaw_rate_rad_s: 0.0,
            motion: BodyTwist::default(),
            solenoid_on: false,
            counts: InputCounts::default(),
        }
    }

    /// Consume one sensor input (others are ignored).
    pub fn handle(&mut self, stamped: &Stamped) {
        match &stamped.input {
            Input::Wheels(telemetry) => {
                self.counts.wheel_batches += 1;
                self.switch_pressed = telemetry.switch_pressed;
            }
            Input::MegaReset => {
                self.counts.mega_resets += 1;
                // A Mega that restarted has not read its switch yet: as at power-up, the
                // switch counts as open until its first batch says otherwise.
                self.switch_pressed = false;
            }
            Input::Scan(_) => self.counts.scans += 1,
            Input::Imu(sample) => {
                self.counts.imu_samples += 1;
                self.yaw_rate_rad_s = sample.gyro_rad_s[2];
            }
            _ => return,
        }
        if let Some(step) = self.estimation.handle(stamped) {
            self.last_odometry = Some(step);
        }
    }

    /// Ask for a body velocity (robot frame) from now on.
    pub fn command_motion(&mut self, twist: BodyTwist) {
        self.motion = twist;
    }

    /// Energise or release the electromagnet.
    pub fn command_solenoid(&mut self, on: bool) {
        self.solenoid_on = on;
    }

    /// The 50 Hz host tick: the references to send now.
    pub fn tick(&mut self, _now_us: u64) -> Output {
        let limited = self
            .mecanum
            .limited_inverse(self.motion, self.max_wheel_speed_rad_s);
        Output {
            wheel_speeds_rad_s: limited.wheel_speeds_rad_s.map(|w| w as f32),
            solenoid_on: self.solenoid_on,
            twist_scale: limited.scale,
        }
    }

    /// The pose estimate (the localiser's).
    pub fn pose(&self) -> Pose2 {
        self.estimation.pose()
    }

    /// The pose estimation: odometry alone, the estimator's covariance and health.
    pub fn estimation(&self) -> &Estimation {
        &self.estimation
    }

    /// The estimator's health, for the HMI and the logs.
    pub fn localisation_health(&self) -> Health {
        self.estimation.estimator().health()
    }

    /// Restart the pose estimate at `pose` (the operator placed the robot).
    pub fn reset_pose(&mut self, pose: Pose2, time_us: u64) {
        self.estimation.reset(pose, time_us);
    }

    /// Hand the estimator the gyro's z bias measured at start-up, rad/s.
    pub fn set_gyro_bias(&mut self, bias_rad_s: f64, std_rad_s: f64) {
        self.estimation.set_gyro_bias(bias_rad_s, std_rad_s);
    }

    /// The last odometry step, if any.
    pub fn last_odometry(&self) -> Option<&OdometryStep> {
        self.last_odometry.as_ref()
    }

    /// The box switch as last reported since the Mega last (re)started; open before its first
    /// report.
    pub fn switch_pressed(&self) -> bool {
        self.switch_pressed
    }

    /// The gyro's latest yaw rate, rad/s (bias not removed).
    pub fn yaw_rate_rad_s(&self) -> f64 {
        self.yaw_rate_rad_s
    }

    /// What the core has received.
    pub fn input_counts(&self) -> InputCounts {
        self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drivers::mega_link::WheelTelemetry;
    use crate::runtime::Timestamp;
    use nalgebra::{Matrix3, Vector3};

    fn telemetry(totals: [i32; 4]) -> Stamped {
        with_switch(totals, false)
    }

    fn with_switch(totals: [i32; 4], switch_pressed: bool) -> Stamped {
        Stamped::new(
            Timestamp::ZERO,
            Input::Wheels(WheelTelemetry::for_test(totals, switch_pressed, 0)),
        )
    }

    #[test]
    fn each_policy_drives_with_its_own_estimator() {
        let original_p0 =
            Matrix3::from_diagonal(&Vector3::from(crate::localisation::original::P0_DIAGONAL));
        let mut config = Config::default();
        let ours = Robot::new(&config, Pose2::default());
        assert_ne!(ours.estimation().estimator().covariance(), original_p0);
        config.competition.policy = Policy::Original;
        let original = Robot::new(&config, Pose2::default());
        assert_eq!(original.estimation().estimator().covariance(), original_p0);
    }

    #[test]
    fn ours_strafes_through_the_rollers_slip_and_the_original_as_its_table_did() {
        let mut config = Config::default();
        config.robot.strafe_factor = 0.9;
        let strafe_wheels = |config: &Config| {
            let mut robot = Robot::new(config, Pose2::default());
            robot.command_motion(BodyTwist::new(0.0, 0.18, 0.0));
            robot.tick(0).wheel_speeds_rad_s
        };
        // 0.18 m/s to the left: 6 rad/s per wheel on the rigid table, 6 / 0.9 through the slip.
        let ours = strafe_wheels(&config);
        config.competition.policy = Policy::Original;
        let original = strafe_wheels(&config);
        for (o, r) in ours.iter().zip(original) {
            assert!((f64::from(r.abs()) - 6.0).abs() < 1e-5, "{original:?}");
            assert!((f64::from(o.abs()) - 6.0 / 0.9).abs() < 1e-5, "{ours:?}");
        }
    }

    #[test]
    fn a_commanded_twist_becomes_wheel_references_within_the_limit() {
        let config = Config::default();
        let mut robot = Robot::new(&config, Pose2::default());
        robot.command_motion(BodyTwist::new(0.3, 0.0, 0.0));
        let out = robot.tick(0);
        assert_eq!(out.twist_scale, 1.0);
        // Forward: right wheels positive, left wheels negative, 0.3 m/s / 0.03 m = 10 rad/s.
        assert_eq!(out.wheel_speeds_rad_s, [10.0, -10.0, 10.0, -10.0]);
        robot.command_motion(BodyTwist::new(1.0, 0.0, 0.0));
        let out = robot.tick(0);
        assert!(out.twist_scale < 1.0);
        let peak = out
            .wheel_speeds_rad_s
            .iter()
            .fold(0.0f32, |m, w| m.max(w.abs()));
        assert!((f64::from(peak) - config.robot.max_wheel_speed_rad_s).abs() < 1e-4);
    }

    #[test]
    fn odometry_follows_telemetry_and_survives_a_mega_reset() {
        let config = Config::default();
        let mut robot = Robot::new(&config, Pose2::default());
        let ticks_per_m = config.robot.ticks_per_wheel_rev / (std::f64::consts::PI * 0.06);
        let n = (0.1 * ticks_per_m).round() as i32;
        robot.handle(&telemetry([0; 4]));
        robot.handle(&telemetry([n, -n, n, -n]));
        let odometry = |r: &Robot| r.estimation().odometry_pose();
        assert!((odometry(&robot).x - 0.1).abs() < 1e-3);
        // The Mega reboots: its totals restart at 0, which must not read as a jump back.
        robot.handle(&Stamped::new(Timestamp::ZERO, Input::MegaReset));
        robot.handle(&telemetry([0; 4]));
        robot.handle(&telemetry([n, -n, n, -n]));
        assert!(
            (odometry(&robot).x - 0.2).abs() < 2e-3,
            "{:?}",
            odometry(&robot)
        );
        assert_eq!(robot.input_counts().mega_resets, 1);
    }

    #[test]
    fn a_restarted_mega_reads_its_switch_anew() {
        // Seed 67, round 1, Mega reset: the switch closed before the reset read closed for
        // two ticks after it, so the search for the dropped part looked from where the robot
        // had coasted to, and its body met the part beside its line.
        let mut robot = Robot::new(&Config::default(), Pose2::default());
        robot.handle(&with_switch([0; 4], true));
        assert!(robot.switch_pressed());
        robot.handle(&Stamped::new(Timestamp::ZERO, Input::MegaReset));
        assert!(!robot.switch_pressed());
        robot.handle(&with_switch([0; 4], true));
        assert!(robot.switch_pressed());
    }
}
