//! The faithful copy of the original 5dpo filter against simulated scans.

use nalgebra::{Matrix3, Vector3};
use ratf_core::config::{LocalisationConfig, RobotConfig};
use ratf_core::drivers::x4::scan::Scan;
use ratf_core::drivers::x4::scan::ScanPoint;
use ratf_core::field::Field;
use ratf_core::field::geometry::{Pose2, Vec2, wrap_angle};
use ratf_core::localisation::Localiser;
use ratf_core::localisation::PoseEstimator;
use ratf_core::localisation::original::*;
use ratf_core::odometry::BodyIncrement;
use ratf_core::rng::SimRng;
use ratf_sim::testkit::{Scenario, beacon_circles, figure_eight, rmse, run, synthetic_scan};

fn original(pose: Pose2) -> OriginalFilter {
    OriginalFilter::new(&RobotConfig::default(), &Field::competition(), pose, 0)
}

fn step(dx: f64, dth: f64) -> BodyIncrement {
    BodyIncrement {
        dx_m: dx,
        dy_m: 0.0,
        dtheta_rad: dth,
    }
}

#[test]
fn first_odometry_only_initialises_and_q_is_added_per_message() {
    let mut f = original(Pose2::new(-0.695, -0.355, std::f64::consts::FRAC_PI_2));
    let scan = synthetic_scan(
        0.0,
        &|_| Pose2::new(0.0, 0.0, 0.0),
        &RobotConfig::default(),
        &beacon_circles(),
        0.0,
        &mut SimRng::new(1),
    );
    f.on_scan(&scan);
    assert_eq!(
        f.health().scans_applied,
        0,
        "scans wait for the first odometry"
    );
    f.on_odometry(20_000, step(0.5, 0.0));
    assert_eq!(
        f.raw_state(),
        Vector3::new(-0.695, -0.355, std::f64::consts::FRAC_PI_2)
    );
    assert_eq!(
        f.covariance(),
        Matrix3::from_diagonal(&Vector3::from(P0_DIAGONAL))
    );
    // Standing still, every message adds Q: 0.1 m² per 20 ms.
    for k in 1..=10 {
        f.on_odometry(20_000 * (k + 1), step(0.0, 0.0));
    }
    assert!((f.covariance()[(0, 0)] - (0.1 + 10.0 * 0.1)).abs() < 1e-12);
    assert!((f.covariance()[(2, 2)] - (0.1 + 10.0 * 0.05)).abs() < 1e-12);
}

#[test]
fn theta_is_not_wrapped_and_the_chord_is_over_rotated() {
    let mut f = original(Pose2::new(0.0, 0.0, 3.0));
    f.on_odometry(0, step(0.0, 0.0));
    f.on_odometry(20_000, step(0.1, 0.4));
    let x = f.raw_state();
    assert!((x[2] - 3.4).abs() < 1e-12, "θ left at {}", x[2]);
    // The chord (0.1, 0) rotated by θ + dθ/2 = 3.2.
    assert!((x[0] - 0.1 * 3.2f64.cos()).abs() < 1e-12);
    assert!((x[1] - 0.1 * 3.2f64.sin()).abs() < 1e-12);
    assert!((f.pose().yaw_rad - wrap_angle(3.4)).abs() < 1e-12);
    let mut exact = original(Pose2::new(0.0, 0.0, 3.0)).with_exact_chord();
    exact.on_odometry(0, step(0.0, 0.0));
    exact.on_odometry(20_000, step(0.1, 0.4));
    assert!((exact.raw_state()[0] - 0.1 * 3.0f64.cos()).abs() < 1e-12);
}

#[test]
fn a_single_stray_point_counts_as_a_beacon() {
    let truth = Pose2::new(0.0, 0.0, 0.0);
    let mut f = original(truth);
    f.on_odometry(0, step(0.0, 0.0));
    // One point 0.15 m in front of B0 (as seen from the robot), nothing else.
    let mount = Pose2::new(0.07, 0.0, 172f64.to_radians());
    let b0 = beacon_circles()[0].center;
    let target = b0 - Vec2::new(0.15, 0.0);
    let local = mount.inverse_transform_point(target);
    let scan = Scan {
        stamp_us: 0.0,
        sample_period_us: 198.0,
        scan_frequency_hz: 7.0,
        points: vec![ScanPoint {
            angle_rad: local.angle(),
            range_m: local.norm(),
            time_offset_us: 0.0,
        }],
        samples: 720,
        points_out_of_range: 0,
        points_overflowed: 0,
        packets_dropped: 0,
    };
    f.on_scan(&scan);
    assert_eq!(f.health().last_scan.beacons_used, 1);
    assert!(f.pose().position().norm() > 0.05, "pulled: {:?}", f.pose());
}

/// Ours against the original on the same synthetic inputs, without and with faults.
/// Prints the figures:
/// `cargo test -p ratf-host --lib localisation::original::tests::ours_against -- --nocapture`
#[test]
fn ours_against_the_original_on_synthetic_runs() {
    fn slip(t: f64) -> f64 {
        if (t % 5.0) < 0.5 { 0.01 } else { 0.0 }
    }
    let start = figure_eight(0.0);
    let cases: [(&str, bool); 2] = [("default noise", false), ("faults", true)];
    for (name, faults) in cases {
        let (mut ours_p, mut orig_p, mut ours_h, mut orig_h) = (0.0, 0.0, 0.0, 0.0);
        let mut exact_p = 0.0;
        let mut ours_div = 0;
        let seeds = 3;
        for seed in 0..seeds {
            let mut scenario = Scenario::new(figure_eight, 20.0, 200 + seed);
            scenario.gyro_bias_rad_s = 0.01;
            let initial = if faults {
                // A person 0.3 m from B1 (its legs' centre), 20 % scans lost, slip bursts,
                // initial pose off by 10 cm / 10°.
                let b1 = beacon_circles()[1].center;
                scenario.clutter = ratf_sim::lidar::person(b1 + Vec2::new(0.3, 0.0))
                    .iter()
                    .filter_map(|s| match s.shape {
                        ratf_sim::lidar::Shape::Cylinder(c) => Some(c),
                        ratf_sim::lidar::Shape::Block(_) => None,
                    })
                    .collect();
                scenario.scan_drop_fraction = 0.2;
                scenario.wheel_slip = slip;
                Pose2::new(
                    start.x + 0.0707,
                    start.y + 0.0707,
                    start.yaw_rad + 10f64.to_radians(),
                )
            } else {
                start
            };
            let mut ours = Localiser::new(
                &LocalisationConfig::default(),
                &RobotConfig::default(),
                &Field::competition(),
                initial,
                0,
            );
            let mut orig = original(initial);
            let mut exact = original(initial).with_exact_chord();
            let a = run(&mut ours, &scenario);
            let b = run(&mut orig, &scenario);
            exact_p += rmse(&run(&mut exact, &scenario), 2.0).0 / seeds as f64;
            let (p, h) = rmse(&a, 2.0);
            let (q, g) = rmse(&b, 2.0);
            ours_div += a
                .iter()
                .filter(|s| s.time_us >= 2_000_000 && s.position_error_m() > 0.05)
                .count();
            ours_p += p / seeds as f64;
            ours_h += h / seeds as f64;
            orig_p += q / seeds as f64;
            orig_h += g / seeds as f64;
        }
        println!(
            "{name}: ours position RMSE {ours_p:.4} m heading {:.3}° (samples > 5 cm after 2 s: {ours_div}); \
             original {orig_p:.4} m {:.3}° (with the exact odometry chord {exact_p:.4} m)",
            ours_h.to_degrees(),
            orig_h.to_degrees()
        );
        assert!(ours_p < orig_p / 2.0, "{name}: {ours_p} vs {orig_p}");
        assert!(ours_p < exact_p / 2.0, "{name}: {ours_p} vs {exact_p}");
        assert_eq!(ours_div, 0, "{name}");
    }
}
