//! `ratf run` end to end with no hardware: against `ratf sim --serve-pty` (the simulated
//! Mega and X4 behind pseudo-terminals, the mock server on UDP, the world in real time).
//!
//! The round runs in real time: round 1 takes about 40 s of wall time. Every wait has a
//! deadline, and both programs run in their own process groups, killed on drop.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{Spawned, TempDir, one_at_a_time, read, serve};

/// `dir/robot.toml` pointing at the world served under `dir/dev`.
fn robot_config(dir: &Path, port: u16) -> PathBuf {
    common::robot_config(dir, &dir.join("dev/lidar"), port)
}

#[test]
fn ratf_run_completes_round_1_with_full_score_against_the_served_world() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("run-pty");
    let dir = &tmp.0;
    let (mut world, port) = serve(dir, "1", &[]);
    let config = robot_config(dir, port);
    let mut robot = Spawned::start(
        &[
            "run",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--out",
            dir.join("out").to_str().expect("utf-8 path"),
            "--status-hz",
            "0",
        ],
        &dir.join("run.err"),
    );
    // Round 1 takes about 40 s of robot time, in real time.
    let status = robot.wait_exit(Duration::from_secs(150));
    assert_eq!(
        status.code(),
        Some(0),
        "ratf run: {status:?}\n{}\nstderr:\n{}",
        robot.seen.join("\n"),
        read(&dir.join("run.err"))
    );
    let summary = robot
        .seen
        .iter()
        .find(|l| l.starts_with("ratf run: finished: placed 4 part(s)"));
    assert!(summary.is_some(), "{}", robot.seen.join("\n"));
    assert!(
        robot
            .seen
            .iter()
            .any(|l| l == "the robot was sent zero references and magnet off"),
        "{}",
        robot.seen.join("\n")
    );
    // The world's referee scored it: the robot hung up, so the serve ends and tells.
    let end = world.wait_line(Duration::from_secs(30), |l| l.starts_with("round 1: "));
    assert!(end.starts_with("round 1: 4 points"), "{end}");
    assert_eq!(world.wait_exit(Duration::from_secs(10)).code(), Some(0));
}

#[test]
fn a_missing_device_is_named_with_where_it_looked_and_what_to_do() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("run-missing");
    let config = robot_config(&tmp.0, 39_899);
    let mut robot = Spawned::start(
        &[
            "run",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--out",
            tmp.0.join("out").to_str().expect("utf-8 path"),
        ],
        &tmp.0.join("run.err"),
    );
    let status = robot.wait_exit(Duration::from_secs(20));
    let stderr = read(&tmp.0.join("run.err"));
    assert_eq!(status.code(), Some(1), "{stderr}");
    let mega = tmp.0.join("dev/mega");
    assert!(
        stderr.contains(&format!("mega: {}: no such device", mega.display()))
            && stderr.contains("set [link] mega_port"),
        "{stderr}"
    );
}

#[test]
fn sigterm_stops_the_robot_and_exits_130() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("run-sigterm");
    let dir = &tmp.0;
    let (_world, port) = serve(dir, "2", &[]);
    let config = robot_config(dir, port);
    let mut robot = Spawned::start(
        &[
            "run",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--out",
            dir.join("out").to_str().expect("utf-8 path"),
            "--force-start",
            "BBBB",
            "--status-hz",
            "0",
        ],
        &dir.join("run.err"),
    );
    // The operator's forced start: the robot drives at once.
    robot.wait_line(Duration::from_secs(20), |l| l.contains("going for"));
    let pid = nix::unistd::Pid::from_raw(robot.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).expect("signal");
    let status = robot.wait_exit(Duration::from_secs(5));
    assert_eq!(
        status.code(),
        Some(130),
        "{}\n{}",
        robot.seen.join("\n"),
        read(&dir.join("run.err"))
    );
    assert!(
        robot
            .seen
            .iter()
            .any(|l| l.starts_with("ratf run: interrupted"))
            && robot
                .seen
                .iter()
                .any(|l| l == "the robot was sent zero references and magnet off"),
        "{}",
        robot.seen.join("\n")
    );
}

/// One HTTP request to the HMI on loopback: the status and the body.
fn http(address: &str, method: &str, path: &str, token: Option<&str>) -> (u16, String) {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(address).expect("the HMI listens");
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .expect("timeout");
    let auth = token.map_or_else(String::new, |t| format!("Authorization: Bearer {t}\r\n"));
    write!(
        stream,
        "{method} {path} HTTP/1.1\r\nHost: robot\r\nConnection: close\r\n{auth}Content-Length: 2\r\n\r\n{{}}"
    )
    .expect("request");
    let mut answer = String::new();
    stream.read_to_string(&mut answer).expect("answer");
    let status = answer
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let body = answer
        .split_once("\r\n\r\n")
        .map_or("", |(_, b)| b)
        .to_owned();
    (status, body)
}

/// Poll the HMI's state until `done` holds for it, within `timeout`.
fn state_until(address: &str, timeout: Duration, done: impl Fn(&serde_json::Value) -> bool) {
    let deadline = std::time::Instant::now() + timeout;
    loop {
        let (_, body) = http(address, "GET", "/api/state", None);
        let state: serde_json::Value = serde_json::from_str(&body).unwrap_or_default();
        if done(&state) {
            return;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "not within {timeout:?}; last state: {body}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn the_hmi_stops_the_robot_on_its_devices_and_the_recording_keeps_the_command() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("run-hmi");
    let dir = &tmp.0;
    let (_world, port) = serve(dir, "1", &[]);
    let config = robot_config(dir, port);
    let out = dir.join("out");
    let mut robot = Spawned::start(
        &[
            "run",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--out",
            out.to_str().expect("utf-8 path"),
            "--status-hz",
            "0",
            "--hmi",
            "127.0.0.1:0",
        ],
        &dir.join("run.err"),
    );
    let line = robot.wait_line(Duration::from_secs(20), |l| l.starts_with("HMI: "));
    let url = line["HMI: http://".len()..]
        .split_whitespace()
        .next()
        .expect("the URL");
    let (address, token) = url.split_once("/?token=").expect("a token in the URL");
    // The robot drives its round (the world's server gives the part list).
    state_until(address, Duration::from_secs(30), |s| {
        s["mode"] == "robot"
            && s["phase"] == "running"
            && s["wheels"]["reference_rad_s"]
                .as_array()
                .is_some_and(|r| r.iter().any(|v| v.as_f64() != Some(0.0)))
    });
    let (status, body) = http(address, "POST", "/api/stop", None);
    assert_eq!(status, 401, "{body}");
    let (status, body) = http(address, "POST", "/api/stop", Some(token));
    assert_eq!(status, 200, "{body}");
    state_until(address, Duration::from_secs(10), |s| {
        s["stopped"] == true
            && s["magnet"] == false
            && s["wheels"]["reference_rad_s"]
                .as_array()
                .is_some_and(|r| r.iter().all(|v| v.as_f64() == Some(0.0)))
    });
    let pid = nix::unistd::Pid::from_raw(robot.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).expect("signal");
    assert_eq!(robot.wait_exit(Duration::from_secs(10)).code(), Some(130));
    let recording = std::fs::read_dir(&out)
        .expect("the recording's folder")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|e| e == "mcap"))
        .expect("a recording");
    let mut replay = Spawned::start(
        &[
            "replay",
            recording.to_str().expect("utf-8 path"),
            "--events",
        ],
        &dir.join("replay.err"),
    );
    assert_eq!(replay.wait_exit(Duration::from_secs(30)).code(), Some(0));
    let seen = replay.seen.join("\n");
    assert!(seen.contains("stopped by the operator"), "{seen}");
    assert!(seen.contains("0 divergences"), "{seen}");
}
