//! `ratf calibrate --robot` end to end with no hardware: the calibration drive through the
//! real devices' code, against `ratf sim --serve-pty` in the realistic world (the simulated
//! Mega and X4 behind pseudo-terminals, the world in real time: about 40 s).

mod common;

use std::time::Duration;

use common::{Spawned, TempDir, one_at_a_time, read, robot_config, serve};

#[test]
fn calibrating_on_the_served_devices_finds_the_lidar_s_true_zero_angle_and_writes_it() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("calibrate-pty");
    let dir = &tmp.0;
    // Seed 3 of the realistic world turns the lidar 2.67° off the believed 172°.
    let (_world, port) = serve(dir, "3", &["--world", "realistic"]);
    let config = robot_config(dir, &dir.join("dev/lidar"), port);
    let written = dir.join("calibrated.toml");
    let mut calibrate = Spawned::start(
        &[
            "calibrate",
            "--robot",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--yes",
            "--write",
            written.to_str().expect("utf-8 path"),
            "--out",
            dir.join("out").to_str().expect("utf-8 path"),
        ],
        &dir.join("calibrate.err"),
    );
    let status = calibrate.wait_exit(Duration::from_secs(120));
    assert_eq!(
        status.code(),
        Some(0),
        "{}\nstderr:\n{}",
        calibrate.seen.join("\n"),
        read(&dir.join("calibrate.err"))
    );
    assert!(
        calibrate.seen.iter().any(|l| l.starts_with("9 stops;")),
        "{}",
        calibrate.seen.join("\n")
    );
    let text = read(&written);
    let file: toml::Table = toml::from_str(&text).expect("TOML");
    let yaw = file["robot"]["lidar_yaw_deg"]
        .as_float()
        .expect("lidar_yaw_deg");
    assert!((yaw - 174.67).abs() < 0.3, "{yaw}\n{text}");
    // The team's own keys are kept, and the file is still a robot's file.
    assert_eq!(file["link"]["imu"].as_str(), Some("none"), "{text}");
    assert!(!file.contains_key("sim"), "{text}");
}
