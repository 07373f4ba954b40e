//! The localiser and the beacon extraction on scans from the simulated X4 (beam geometry,
//! de-skew, serial timing).

use ratf_core::config::CentreMethod;
use ratf_core::config::{LocalisationConfig, RobotConfig};
use ratf_core::field::Field;
use ratf_core::field::geometry::wrap_angle;
use ratf_core::field::geometry::{Pose2, Vec2};
use ratf_core::localisation::PoseEstimator;
use ratf_core::localisation::beacons::{Expected, extract};
use ratf_core::localisation::localiser::*;
use ratf_core::odometry::BodyIncrement;
use ratf_sim::testkit::{self, simulated_scans};

/// Centre error of both methods on the simulated X4 at 0.3–2 m from a pole. Prints:
/// `cargo test -p ratf-host --lib localisation::localiser::simulated_lidar_tests -- --nocapture`
#[test]
fn centre_methods_on_the_simulated_x4() {
    let robot = RobotConfig::default();
    let mount = robot.lidar_mount();
    let b0 = Field::competition().beacons()[0].circle;
    let away = Vec2::from_angle(200f64.to_radians());
    println!("range_m  scans  circle_fit_err_m  centroid_err_m  (simulated X4, σ_r = 0.01 m)");
    let (mut fit_total, mut cen_total) = (0.0, 0.0);
    for (i, &range) in [0.3, 0.5, 0.75, 1.0, 1.5, 2.0].iter().enumerate() {
        let lidar_at = b0.center + away * range;
        // Face the pole with the robot; the lidar looks backwards (172°).
        let yaw = (-away).angle() + 0.3;
        let robot_pose = Pose2::new(lidar_at.x, lidar_at.y, yaw).compose(mount.inverse());
        let scans = simulated_scans(&|_| robot_pose, &[], 0.01, 4.0, 40 + i as u64);
        let lidar = robot_pose.compose(mount);
        let expected = [Expected {
            beacon: 0,
            centre: lidar.inverse_transform_point(b0.center),
            search_radius_m: 0.15,
        }];
        let mut errors = [0.0; 2];
        let mut counted = 0;
        for (_, scan) in &scans {
            let points: Vec<Vec2> = scan
                .points
                .iter()
                .map(|p| Vec2::from_angle(p.angle_rad) * p.range_m)
                .collect();
            let step = std::f64::consts::TAU / f64::from(scan.samples);
            let mut got = [None; 2];
            for (k, method) in [CentreMethod::CircleFit, CentreMethod::Centroid]
                .into_iter()
                .enumerate()
            {
                let config = LocalisationConfig {
                    centre_method: method,
                    ..LocalisationConfig::default()
                };
                let found = extract(&points, &[], &expected, step, b0.radius_m, &config);
                got[k] = found[0]
                    .candidates
                    .first()
                    .map(|o| lidar.transform_point(Vec2::from_angle(o.bearing_rad) * o.range_m));
            }
            if let [Some(a), Some(b)] = got {
                errors[0] += a.distance(b0.center);
                errors[1] += b.distance(b0.center);
                counted += 1;
            }
        }
        assert!(
            counted >= 20,
            "range {range}: only {counted} scans with the pole"
        );
        let (f, c) = (
            errors[0] / f64::from(counted),
            errors[1] / f64::from(counted),
        );
        println!("{range:7.2}  {counted:5}  {f:16.4}  {c:14.4}");
        fit_total += f;
        cen_total += c;
    }
    assert!(
        fit_total < cen_total,
        "circle fit {fit_total} vs centroid {cen_total}"
    );
}

#[test]
fn converges_on_simulated_x4_scans_with_a_person_beside_a_beacon() {
    let truth = Pose2::new(0.2, -0.1, 2.0);
    let b1 = Field::competition().beacons()[1].circle.center;
    let clutter = ratf_sim::lidar::person(b1 + Vec2::new(0.3, 0.0));
    let scans = simulated_scans(&|_| truth, &clutter, 0.01, 5.0, 3);
    let start = Pose2::new(
        truth.x + 0.07,
        truth.y - 0.07,
        truth.yaw_rad - 10f64.to_radians(),
    );
    let mut loc = Localiser::new(
        &LocalisationConfig::default(),
        &RobotConfig::default(),
        &Field::competition(),
        start,
        0,
    );
    let mut scans = scans.into_iter().peekable();
    let mut t = 0;
    while t < 5_000_000 {
        t += testkit::ODOM_US;
        loc.on_odometry(t, BodyIncrement::default());
        while let Some((_, scan)) = scans.next_if(|(at, _)| *at <= t) {
            loc.on_scan(&scan);
        }
    }
    let pose = loc.pose();
    assert!(
        pose.position().distance(truth.position()) < 0.01,
        "{pose:?}"
    );
    assert!(
        wrap_angle(pose.yaw_rad - truth.yaw_rad).abs() < 0.5f64.to_radians(),
        "{pose:?}"
    );
    let h = loc.health();
    assert!(
        h.scans_applied >= 30 && h.last_scan.beacons_used == 4,
        "{h:?}"
    );
    println!("simulated X4, person 0.3 m from B1: {h:?}");
}
