//! Test helpers: a robot on a known trajectory, its odometry, gyro and synthetic scans of
//! the beacons (and of clutter), fed in time order to a [`PoseEstimator`].

use nalgebra::{Matrix3, Vector3};

use crate::lidar::{LidarScene, SimLidar, Solid};
use crate::serial::SerialLine;
use ratf_core::config::LidarConfig;
use ratf_core::config::{LocalisationConfig, RobotConfig};
use ratf_core::drivers::imu::ImuSample;
use ratf_core::drivers::x4::X4Driver;
use ratf_core::drivers::x4::scan::ScanConfig;
use ratf_core::drivers::x4::scan::{Scan, ScanPoint};
use ratf_core::field::Field;
use ratf_core::field::geometry::{Circle, Pose2, Vec2, wrap_angle};
use ratf_core::localisation::PoseEstimator;
use ratf_core::odometry::BodyIncrement;
use ratf_core::rng::SimRng;

/// Samples per revolution and revolutions per second of the simulated X4 (0.5°, 7 Hz).
pub const SAMPLES: usize = 720;
/// Revolution period, µs.
pub const REVOLUTION_US: f64 = 1e6 / 7.0;
/// Odometry period, µs (50 Hz).
pub const ODOM_US: u64 = 20_000;
/// Gyro period, µs (200 Hz).
pub const GYRO_US: u64 = 5_000;
/// Standard deviation of the synthetic wheels' yaw increment, as a fraction of it.
pub const WHEEL_YAW_ERROR_FRACTION: f64 = 0.02;

/// One revolution seen by a lidar mounted as in `robot`, the robot at `pose_at(t_us)`
/// while it sweeps, first sample at `stamp_us`; `circles` are what it can hit.
pub fn synthetic_scan(
    stamp_us: f64,
    pose_at: &dyn Fn(f64) -> Pose2,
    robot: &RobotConfig,
    circles: &[Circle],
    noise_m: f64,
    rng: &mut SimRng,
) -> Scan {
    let mount = robot.lidar_mount();
    let dt_us = REVOLUTION_US / SAMPLES as f64;
    let step = std::f64::consts::TAU / SAMPLES as f64;
    let mut points = Vec::new();
    for k in 0..SAMPLES {
        let offset_us = k as f64 * dt_us;
        let lidar = pose_at(stamp_us + offset_us).compose(mount);
        // The X4 turns clockwise: counter-clockwise angles decrease.
        let angle_rad = wrap_angle(-(k as f64) * step);
        let dir = Vec2::from_angle(lidar.yaw_rad + angle_rad);
        let hit = circles
            .iter()
            .filter_map(|c| c.ray_intersection(lidar.position(), dir))
            .min_by(f64::total_cmp);
        if let Some(range_m) = hit {
            points.push(ScanPoint {
                angle_rad,
                range_m: range_m + rng.normal(noise_m),
                time_offset_us: offset_us,
            });
        }
    }
    Scan {
        stamp_us,
        sample_period_us: dt_us,
        scan_frequency_hz: 7.0,
        points,
        samples: SAMPLES as u32,
        points_out_of_range: 0,
        points_overflowed: 0,
        packets_dropped: 0,
    }
}

/// The field's four beacon circles.
pub fn beacon_circles() -> Vec<Circle> {
    Field::competition()
        .beacons()
        .iter()
        .map(|b| b.circle)
        .collect()
}

/// A synthetic run.
pub struct Scenario {
    /// True pose at a time, s.
    pub trajectory: fn(f64) -> Pose2,
    /// Length, s.
    pub duration_s: f64,
    /// Lidar range noise, m.
    pub range_noise_m: f64,
    /// Odometry noise drawn from the localiser's model (`config`), if true.
    pub odometry_noise: bool,
    /// Gyro bias, rad/s.
    pub gyro_bias_rad_s: f64,
    /// Gyro noise density, rad/s/√Hz.
    pub gyro_noise_density: f64,
    /// Scan delivery after its last sample, µs.
    pub scan_delay_us: u64,
    /// Extra circles the lidar sees.
    pub clutter: Vec<Circle>,
    /// Extra wheel rotation reported per odometry step at a time (s) (wheel slip), rad.
    pub wheel_slip: fn(f64) -> f64,
    /// Fraction of scans lost.
    pub scan_drop_fraction: f64,
    /// Noise seed.
    pub seed: u64,
}

fn no_slip(_: f64) -> f64 {
    0.0
}

impl Scenario {
    /// A noisy run of `trajectory` with no faults.
    pub fn new(trajectory: fn(f64) -> Pose2, duration_s: f64, seed: u64) -> Self {
        Self {
            trajectory,
            duration_s,
            range_noise_m: 0.01,
            odometry_noise: true,
            gyro_bias_rad_s: 0.0,
            gyro_noise_density: 1.75e-4,
            scan_delay_us: 1_000,
            clutter: Vec::new(),
            wheel_slip: no_slip,
            scan_drop_fraction: 0.0,
            seed,
        }
    }
}

/// The estimate against the truth at one odometry time.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// Time, µs.
    pub time_us: u64,
    /// True pose.
    pub truth: Pose2,
    /// Estimated pose.
    pub estimate: Pose2,
    /// Estimated covariance.
    pub covariance: Matrix3<f64>,
}

impl Sample {
    /// Position error, m.
    pub fn position_error_m(&self) -> f64 {
        self.truth.position().distance(self.estimate.position())
    }

    /// Heading error, rad.
    pub fn heading_error_rad(&self) -> f64 {
        wrap_angle(self.estimate.yaw_rad - self.truth.yaw_rad)
    }

    /// Normalised estimation error squared over (x, y, θ).
    pub fn nees(&self) -> f64 {
        let e = Vector3::new(
            self.estimate.x - self.truth.x,
            self.estimate.y - self.truth.y,
            self.heading_error_rad(),
        );
        self.covariance
            .try_inverse()
            .map_or(f64::INFINITY, |p| (e.transpose() * p * e)[(0, 0)])
    }
}

enum Event {
    Gyro(ImuSample),
    Odometry(BodyIncrement),
    Scan(Box<Scan>),
}

/// Drive `estimator` (started by the caller at time 0) through `scenario`; one sample per
/// odometry step.
pub fn run(estimator: &mut dyn PoseEstimator, scenario: &Scenario) -> Vec<Sample> {
    let config = LocalisationConfig::default();
    let robot = RobotConfig::default();
    let mut rng = SimRng::new(scenario.seed);
    let end_us = (scenario.duration_s * 1e6) as u64;
    let truth = |t_us: f64| (scenario.trajectory)(t_us * 1e-6);
    let mut circles = beacon_circles();
    circles.extend(scenario.clutter.iter().copied());
    let mut events: Vec<(u64, u8, Event)> = Vec::new();
    let mut t = GYRO_US;
    while t <= end_us {
        let rate =
            wrap_angle(truth(t as f64 + 500.0).yaw_rad - truth(t as f64 - 500.0).yaw_rad) / 1e-3;
        let noise = scenario.gyro_noise_density * (1e6 / GYRO_US as f64).sqrt();
        let sample = ImuSample {
            time_us: t,
            gyro_rad_s: [
                0.0,
                0.0,
                rate + scenario.gyro_bias_rad_s + rng.normal(noise),
            ],
            accel_m_s2: [0.0, 0.0, 9.81],
            temperature_c: 25.0,
            saturated: false,
        };
        events.push((t, 0, Event::Gyro(sample)));
        t += GYRO_US;
    }
    let mut t = ODOM_US;
    while t <= end_us {
        let inc = truth((t - ODOM_US) as f64).relative(truth(t as f64));
        let mut increment = BodyIncrement {
            dx_m: inc.x,
            dy_m: inc.y,
            dtheta_rad: wrap_angle(inc.yaw_rad) + (scenario.wheel_slip)(t as f64 * 1e-6),
        };
        if scenario.odometry_noise {
            let d = inc.x.hypot(inc.y);
            let dth = increment.dtheta_rad.abs();
            let s = (config.translation_var_m2_per_m * d + config.translation_var_m2_per_rad * dth)
                .sqrt();
            increment.dx_m += rng.normal(s);
            increment.dy_m += rng.normal(s);
            // The wheels' yaw without slip: 2 % of the rotation (assumption; the model's
            // wheel-heading variance is the conservative fallback when the gyro is missing,
            // and drawing from it would flag normal steps as slip).
            increment.dtheta_rad += rng.normal(WHEEL_YAW_ERROR_FRACTION * dth);
        }
        events.push((t, 1, Event::Odometry(increment)));
        t += ODOM_US;
    }
    let mut stamp = 0.0;
    loop {
        let last_sample = stamp + REVOLUTION_US * (SAMPLES - 1) as f64 / SAMPLES as f64;
        let deliver = last_sample as u64 + scenario.scan_delay_us;
        if deliver > end_us {
            break;
        }
        let scan = synthetic_scan(
            stamp,
            &truth,
            &robot,
            &circles,
            scenario.range_noise_m,
            &mut rng,
        );
        events.push((deliver, 2, Event::Scan(Box::new(scan))));
        stamp += REVOLUTION_US;
    }
    events.sort_by_key(|(t, order, _)| (*t, *order));
    let mut samples = Vec::new();
    for (t, _, event) in events {
        match event {
            Event::Gyro(s) => estimator.on_gyro(&s),
            Event::Odometry(inc) => {
                estimator.on_odometry(t, inc);
                samples.push(Sample {
                    time_us: t,
                    truth: truth(t as f64),
                    estimate: estimator.pose(),
                    covariance: estimator.covariance(),
                });
            }
            Event::Scan(scan) => estimator.on_scan(&scan),
        }
    }
    samples
}

/// Root mean square of position (m) and heading (rad) errors over the samples after
/// `from_s`.
pub fn rmse(samples: &[Sample], from_s: f64) -> (f64, f64) {
    let kept: Vec<&Sample> = samples
        .iter()
        .filter(|s| s.time_us as f64 * 1e-6 >= from_s)
        .collect();
    let n = kept.len().max(1) as f64;
    let p = kept
        .iter()
        .map(|s| s.position_error_m().powi(2))
        .sum::<f64>()
        / n;
    let h = kept
        .iter()
        .map(|s| s.heading_error_rad().powi(2))
        .sum::<f64>()
        / n;
    (p.sqrt(), h.sqrt())
}

/// A figure-of-eight around the field centre, turning as it goes (0.3 m/s peak).
pub fn figure_eight(t_s: f64) -> Pose2 {
    let w = 0.5;
    Pose2::new(
        0.45 * (w * t_s).sin(),
        0.25 * (2.0 * w * t_s).sin(),
        0.3 + 0.9 * (0.4 * t_s).sin(),
    )
}

/// A straight drive along x at 0.3 m/s, heading fixed.
pub fn straight(t_s: f64) -> Pose2 {
    Pose2::new(-0.5 + 0.3 * t_s, -0.1, 0.2)
}

/// Standing still.
pub fn parked(_t_s: f64) -> Pose2 {
    Pose2::new(-0.2, 0.1, 0.7)
}

/// Scans from the lead's lidar simulator and the real X4 driver (the most faithful path):
/// the robot at `pose_at(t_s)`, `clutter` besides the field, for `duration_s`; each scan
/// with the time (µs) the driver handed it over.
pub fn simulated_scans(
    pose_at: &dyn Fn(f64) -> Pose2,
    clutter: &[Solid],
    noise_m: f64,
    duration_s: f64,
    seed: u64,
) -> Vec<(u64, Scan)> {
    let robot = RobotConfig::default();
    let config = LidarConfig {
        range_noise_std_m: noise_m,
        ..LidarConfig::default()
    };
    let scene = LidarScene::new(&Field::competition(), clutter, robot.lidar_height_m);
    let mut lidar = SimLidar::new(&config, &robot, SimRng::new(seed));
    let mut line = SerialLine::new(128_000);
    let mut driver = X4Driver::new(ScanConfig::default());
    let mut scans = Vec::new();
    let end_ns = (duration_s * 1e9) as u64;
    let mut t_ns = 0;
    while t_ns < end_ns {
        let next = t_ns + 1_000_000;
        let (a, b) = (pose_at(t_ns as f64 * 1e-9), pose_at(next as f64 * 1e-9));
        lidar.advance(t_ns, a, next, b, &scene, &mut line);
        let bytes = line.receive(next);
        driver.feed(&bytes, next / 1000, |s| scans.push((next / 1000, s)));
        t_ns = next;
    }
    scans
}

/// Turning on the spot at 1.5 rad/s (the sweep sees 12° of rotation).
pub fn spinning(t_s: f64) -> Pose2 {
    Pose2::new(0.1, -0.05, wrap_angle(1.5 * t_s))
}
