//! `ratf check` end to end with no hardware: against `ratf sim --serve-pty` (the simulated
//! Mega and X4 behind pseudo-terminals, the mock server on UDP, the world in real time).
//!
//! Each test takes a few seconds of real time. Every wait has a deadline; both programs run
//! in their own process groups, killed on drop; the tests run one at a time (two real-time
//! worlds side by side starve each other on 2 cores).

mod common;

use std::time::Duration;

use serde_json::Value;

use common::{Spawned, TempDir, one_at_a_time, read, robot_config, serve};

fn device<'a>(json: &'a Value, name: &str) -> &'a Value {
    json["devices"]
        .as_array()
        .and_then(|d| d.iter().find(|d| d["device"] == name))
        .unwrap_or_else(|| panic!("no {name} in {json}"))
}

#[test]
fn ratf_check_finds_every_served_device_ok_and_each_wheel_turning_its_own_way() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("check-pty");
    let dir = &tmp.0;
    let (_world, port) = serve(dir, "1", &[]);
    let config = robot_config(dir, &dir.join("dev/lidar"), port);
    let mut check = Spawned::start(
        &[
            "check",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--yes",
            "--json",
        ],
        &dir.join("check.err"),
    );
    let status = check.wait_exit(Duration::from_secs(60));
    let json = check.json();
    assert_eq!(
        status.code(),
        Some(0),
        "{}\nstderr:\n{}",
        check.seen.join("\n"),
        read(&dir.join("check.err"))
    );
    for name in ["mega", "lidar", "server", "wheels", "magnet"] {
        assert_eq!(device(&json, name)["ok"], true, "{name}: {json}");
    }
    let mega = &device(&json, "mega")["data"];
    assert!(
        (mega["batches_per_s"].as_f64().unwrap() - 50.0).abs() < 5.0,
        "{mega}"
    );
    assert_eq!(mega["host_integrity_errors"], 0, "{mega}");
    assert_eq!(mega["resets"], 0, "{mega}");
    let lidar = &device(&json, "lidar")["data"];
    assert!(
        (lidar["rotation_hz"].as_f64().unwrap() - 7.0).abs() < 1.0,
        "{lidar}"
    );
    // The served X4 answered its device information and health requests.
    let identity = lidar["identity"].as_str().unwrap_or_default();
    assert!(
        identity.starts_with("X4, firmware 1.7") && identity.ends_with("health ok"),
        "{lidar}"
    );
    // From the start pose, every configured beacon is where the world put it.
    for beacon in lidar["beacons"].as_array().unwrap() {
        assert!(beacon["found_fraction"].as_f64().unwrap() >= 0.9, "{lidar}");
    }
    assert_eq!(device(&json, "imu")["skipped"], "[link] imu = \"none\"");
    // Each motor at 20 % open loop for 1 s turned its own wheel forwards, alone; the hold
    // was resent every tick (a single `K` would stop after 100 ms: a few dozen ticks).
    let wheels = device(&json, "wheels")["data"]["wheels"]
        .as_array()
        .unwrap();
    assert_eq!(wheels.len(), 4);
    for (k, wheel) in wheels.iter().enumerate() {
        assert_eq!(wheel["result"]["verdict"], "ok", "{wheel}");
        let ticks: Vec<i64> = wheel["ticks"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t.as_i64().unwrap())
            .collect();
        assert!(ticks[k] > 1000, "wheel {k}: {ticks:?}");
        for (j, &t) in ticks.iter().enumerate() {
            if j != k {
                assert!(t.abs() < 56, "wheel {k}: {ticks:?}");
            }
        }
    }
    // The magnet cannot be seen on the wire; what the Mega was sent can.
    let magnet = &device(&json, "magnet")["data"];
    assert!(magnet["on_batches"].as_u64().unwrap() >= 15, "{magnet}");
    assert!(magnet["off_batches"].as_u64().unwrap() >= 1, "{magnet}");
    assert!(
        check.seen.iter().any(|l| l.starts_with("  server   ok: ")),
        "{}",
        check.seen.join("\n")
    );
}

#[test]
fn a_missing_lidar_is_named_with_where_it_looked_and_the_check_carries_on() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("check-missing");
    let dir = &tmp.0;
    let (_world, port) = serve(dir, "1", &[]);
    let nowhere = dir.join("dev/no-lidar");
    let config = robot_config(dir, &nowhere, port);
    let mut check = Spawned::start(
        &[
            "check",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--yes",
            "--json",
            "--observe-s",
            "1",
            "--spin-s",
            "0.3",
        ],
        &dir.join("check.err"),
    );
    let status = check.wait_exit(Duration::from_secs(60));
    assert_eq!(status.code(), Some(3), "{}", check.seen.join("\n"));
    let json = check.json();
    let lidar = device(&json, "lidar");
    assert_eq!(lidar["ok"], false);
    let problem = lidar["problems"][0].as_str().unwrap();
    assert!(
        problem.starts_with(&format!("lidar: {}: no such device", nowhere.display()))
            && problem.contains("set [link] lidar_port"),
        "{problem}"
    );
    for name in ["mega", "server", "wheels"] {
        assert_eq!(device(&json, name)["ok"], true, "{name}: {json}");
    }
}

#[test]
fn sigint_during_the_bring_up_stops_the_robot_and_exits_130() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("check-sigint");
    let dir = &tmp.0;
    let (_world, port) = serve(dir, "1", &[]);
    let config = robot_config(dir, &dir.join("dev/lidar"), port);
    let mut check = Spawned::start(
        &[
            "check",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--yes",
            "--observe-s",
            "1",
        ],
        &dir.join("check.err"),
    );
    check.wait_line(Duration::from_secs(30), |l| {
        l.starts_with("turning the back-left wheel")
    });
    let pid = nix::unistd::Pid::from_raw(check.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).expect("signal");
    let status = check.wait_exit(Duration::from_secs(5));
    assert_eq!(status.code(), Some(130), "{}", check.seen.join("\n"));
    let stderr = read(&dir.join("check.err"));
    assert!(
        stderr
            .contains("ratf check: interrupted; the robot was sent zero references and magnet off"),
        "{stderr}"
    );
    // Wheel 0's verdict came before the signal; the bring-up stopped at wheel 1.
    assert!(
        !check
            .seen
            .iter()
            .any(|l| l.contains("wheel 1 (back-left):")),
        "{}",
        check.seen.join("\n")
    );
}
