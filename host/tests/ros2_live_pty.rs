//! The live ROS 2 bridge seen by an independent DDS peer: Eclipse Cyclone DDS's Python
//! binding (`host/tests/python/dds_peer.py`) subscribes with ROS 2 naming, joins `tf_static`
//! late, drives the robot with `cmd_vel`, and asks for a QoS that cannot match, which `ratf`
//! must report. Once with `ratf run --ros2` against `ratf sim --serve-pty` in real time (the
//! robot's devices on pseudo-terminals), once with `ratf sim --ros2` (the world in process).
//!
//! Needs cargo feature `ros2` and a Python with `cyclonedds` in `RATF_DDS_PYTHON` (CI
//! makes one); run it inside a private network namespace (`unshare -rn`, `lo` up with
//! multicast) so no DDS traffic leaves the machine, as `.ci/run` does; hence `#[ignore]`
//! (`cargo test -p ratf-host --features ros2 --test ros2_live_pty -- --ignored`).
#![cfg(feature = "ros2")]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{Spawned, TempDir, one_at_a_time, read, serve};

/// The DDS domain of the test (away from the default 0).
const DOMAIN: &str = "17";

/// The Python with `cyclonedds` that CI made.
fn dds_python() -> String {
    std::env::var("RATF_DDS_PYTHON").unwrap_or_else(|_| {
        panic!(
            "set RATF_DDS_PYTHON to a Python with the PyPI package cyclonedds 11 \
             (python3 -m venv v && v/bin/pip install cyclonedds==11.0.1), as .ci/run does"
        )
    })
}

/// Runs the DDS peer against `ratf` (already started, its stderr in `ratf_err`) under
/// `namespace`; asserts every check of the peer passed and that `ratf` reported the peer's
/// QoS mismatch; prints the peer's lines.
fn peer_checks_the_bridge(robot: &mut Spawned, namespace: &str, dir: &Path, ratf_err: &Path) {
    let peer_log = dir.join("peer.out");
    let mut peer = Command::new(dds_python())
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/dds_peer.py"))
        .arg(namespace)
        .env("ROS_DOMAIN_ID", DOMAIN)
        .env(
            "CYCLONEDDS_URI",
            "<General><Interfaces><NetworkInterface address=\"127.0.0.1\"/></Interfaces></General>",
        )
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&peer_log).expect("peer log"))
        .stderr(Stdio::inherit())
        .spawn()
        .expect("the Python DDS peer starts");
    let deadline = Instant::now() + Duration::from_secs(90);
    let status = loop {
        if let Some(status) = peer.try_wait().expect("try_wait") {
            break Some(status);
        }
        if Instant::now() > deadline || robot.child.try_wait().ok().flatten().is_some() {
            let _ = peer.kill();
            let _ = peer.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let log = read(&peer_log);
    assert!(
        status.is_some_and(|s| s.success()) && log.contains(" 0 failed"),
        "the DDS peer: {status:?}\n{log}\nratf's stderr:\n{}",
        read(ratf_err)
    );
    // The peer's transient-local reader of the volatile scan: reported on our side.
    let deadline = Instant::now() + Duration::from_secs(10);
    while !read(ratf_err).contains("ROS 2: QoS mismatch with a subscriber")
        && Instant::now() < deadline
    {
        std::thread::sleep(Duration::from_millis(100));
    }
    let stderr = read(ratf_err);
    assert!(
        stderr.contains("ROS 2: QoS mismatch with a subscriber"),
        "ratf did not report the peer's QoS mismatch; its stderr:\n{stderr}"
    );
    print!("{log}");
}

/// `path` as the UTF-8 text of a command-line argument.
fn arg(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

#[test]
#[ignore = "needs RATF_DDS_PYTHON and a private network namespace: .ci/run runs it with --ignored"]
fn a_cyclone_dds_peer_sees_the_robot_late_joins_tf_static_drives_it_and_a_qos_mismatch_is_reported()
{
    let _serial = one_at_a_time();
    let tmp = TempDir::new("ros2-live");
    let dir = &tmp.0;
    let (_world, port) = serve(dir, "1", &[]);
    let config = common::robot_config(dir, &dir.join("dev/lidar"), port);
    let out = dir.join("out");
    let err: PathBuf = dir.join("run.err");
    let mut robot = Spawned::start_with_env(
        &[
            "run",
            "--config",
            arg(&config),
            "--out",
            arg(&out),
            "--status-hz",
            "0",
            "--ros2",
            "--ros2-namespace",
            "/robot1",
            "--ros2-loopback",
            "--ros2-cmd-vel",
        ],
        &[("ROS_DOMAIN_ID", DOMAIN)],
        &err,
    );
    peer_checks_the_bridge(&mut robot, "/robot1", dir, &err);
}

#[test]
#[ignore = "needs RATF_DDS_PYTHON and a private network namespace: .ci/run runs it with --ignored"]
fn ratf_sim_ros2_publishes_the_simulated_robot_and_takes_cmd_vel() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("ros2-sim");
    let dir = &tmp.0;
    let out = dir.join("out");
    let err: PathBuf = dir.join("sim.err");
    // The silent server keeps the mission waiting, so only the peer's cmd_vel moves it.
    let mut robot = Spawned::start_with_env(
        &[
            "sim",
            "--round",
            "1",
            "--silent-server",
            "--out",
            arg(&out),
            "--ros2",
            "--ros2-namespace",
            "/sim1",
            "--ros2-loopback",
            "--ros2-cmd-vel",
        ],
        &[("ROS_DOMAIN_ID", DOMAIN)],
        &err,
    );
    peer_checks_the_bridge(&mut robot, "/sim1", dir, &err);
}
