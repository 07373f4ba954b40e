//! `ratf tune motors --robot` end to end with no hardware: against `ratf sim --serve-pty` in
//! the realistic world at seed 3 (the simulated Mega and X4 behind pseudo-terminals, the
//! world in real time), the PWM steps through the robot's runtime as the operator's
//! open-loop commands; then `--from-recording` on the recording that run made.
//!
//! Real time makes it sensitive to a busy machine: beside two or three busy cores 3 runs of 12
//! fitted every dead zone 4.7–6.6 % high (the fit's RMSE 0.09 rad/s for 0.05), so `.ci/run`
//! runs it alone.

mod common;

use std::time::Duration;

use common::{TempDir, float, one_at_a_time, robot_config, run_ok, serve};
use ratf_core::config::{Config, WorldProfile};
use ratf_host::apps::tune::motors::true_models;
use ratf_sim::truth::WorldTruth;

#[test]
fn the_steps_on_the_served_devices_identify_the_true_motors_and_their_recording_fits_the_same() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("tune-motors-pty");
    let dir = &tmp.0;
    let mut config = Config::default();
    config.sim.world = WorldProfile::Realistic;
    config.sim.seed = 3;
    let truth = WorldTruth::draw(&config, 0.0);
    let models = true_models(&config, &truth);

    let (_world, port) = serve(dir, "3", &["--world", "realistic"]);
    let robot = robot_config(dir, &dir.join("dev/lidar"), port);
    // The team measured the battery with a multimeter.
    let battery = format!("{:.4}", truth.battery_voltage_v);
    let stepped = run_ok(
        &[
            "tune",
            "motors",
            "--robot",
            "--yes",
            "--config",
            robot.to_str().expect("utf-8 path"),
            "--battery-v",
            &battery,
            "--levels",
            "30,60",
            "--step-s",
            "0.6",
            "--rest-s",
            "0.4",
            "--out",
            dir.to_str().expect("utf-8 path"),
            "--json",
        ],
        &dir.join("tune.err"),
        Duration::from_secs(120),
    );
    let live = stepped.json();
    let wheels = live["wheels"].as_array().expect("wheels");
    assert_eq!(wheels.len(), 4, "{live}");
    let mut figures = Vec::new();
    for (wheel, model) in wheels.iter().zip(&models) {
        let error_pct = |key: &str, truth: f64| (float(wheel, key) / truth - 1.0) * 100.0;
        figures.push(format!(
            "wheel {}: K {:+.2} %, τ {:+.2} %, dead zone {:+.2} %, delay {:.3} s, R² {:.4}",
            wheel["wheel"],
            error_pct("gain_rad_s_per_v", model.gain_rad_s_per_v),
            error_pct("time_constant_s", model.time_constant_s),
            error_pct("dead_zone_v", model.dead_zone_v),
            float(wheel, "delay_s"),
            float(wheel, "r2"),
        ));
    }
    let figures = format!("{}\n{}", figures.join("\n"), stepped.seen.join("\n"));
    eprintln!("{figures}");
    for (wheel, model) in wheels.iter().zip(&models) {
        let rel = |key: &str, truth: f64| (float(wheel, key) / truth - 1.0).abs();
        // The 5 %, in real time through the devices' threads (measured: gain and
        // time constant within 0.7 %, dead zone within 3.5 %; the host's latency goes into
        // the delay, about one 20 ms host tick).
        assert!(
            rel("gain_rad_s_per_v", model.gain_rad_s_per_v) < 0.05,
            "{figures}"
        );
        assert!(rel("dead_zone_v", model.dead_zone_v) < 0.05, "{figures}");
        assert!(
            rel("time_constant_s", model.time_constant_s) < 0.05,
            "{figures}"
        );
        assert!(float(wheel, "r2") > 0.98, "{figures}");
    }

    // The recording that run made gives the same fit.
    let recording = stepped
        .seen
        .iter()
        .find_map(|line| line.split("recorded to ").nth(1))
        .expect("the recording's path")
        .to_owned();
    let replayed = run_ok(
        &["tune", "motors", "--from-recording", &recording, "--json"],
        &dir.join("replayed.err"),
        Duration::from_secs(60),
    );
    assert_eq!(replayed.json(), live);
}
