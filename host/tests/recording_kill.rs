//! Nothing lost: `ratf sim` killed with SIGKILL in the middle of a round leaves a recording
//! without its summary and footer, which `ratf replay` reads up to its last complete chunk
//! and replays without a divergence.

mod common;

use std::time::{Duration, Instant};

use common::{Spawned, TempDir, read};

#[test]
fn a_recording_cut_by_sigkill_mid_round_reads_and_replays_up_to_its_last_chunk() {
    let tmp = TempDir::new("kill");
    let out = tmp.0.join("out");
    let mut sim = Spawned::start(
        &[
            "sim",
            "--round",
            "1",
            "--out",
            out.to_str().expect("utf-8 path"),
        ],
        &tmp.0.join("sim.err"),
    );
    let path = out.join("sim-round1-seed1-ours.mcap");
    // Mid-round: a few chunks written, the round (about 40 s of robot time) not over.
    let deadline = Instant::now() + Duration::from_secs(120);
    while std::fs::metadata(&path).map_or(0, |m| m.len()) < 200 * 1024 {
        assert!(
            sim.child.try_wait().expect("try_wait").is_none(),
            "ratf sim ended before 200 KiB of recording: {}",
            read(&tmp.0.join("sim.err"))
        );
        assert!(
            Instant::now() < deadline,
            "no 200 KiB of recording in 120 s"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    let group = nix::unistd::Pid::from_raw(sim.child.id() as i32);
    nix::sys::signal::killpg(group, nix::sys::signal::Signal::SIGKILL).expect("SIGKILL");
    let status = sim.wait_exit(Duration::from_secs(10));
    assert_eq!(
        status.code(),
        None,
        "killed by a signal, not exited: {status:?}"
    );

    let mut replay = Spawned::start(
        &["replay", path.to_str().expect("utf-8 path"), "--json"],
        &tmp.0.join("replay.err"),
    );
    let status = replay.wait_exit(Duration::from_secs(120));
    assert_eq!(
        status.code(),
        Some(0),
        "{}\n{}",
        replay.seen.join("\n"),
        read(&tmp.0.join("replay.err"))
    );
    assert!(
        replay
            .seen
            .iter()
            .any(|l| l.contains("the file ends early (read up to its last complete chunk)")),
        "{}",
        replay.seen.join("\n")
    );
    let json = replay.json();
    assert_eq!(json["divergences"], 0, "{json}");
    let inputs = json["inputs"].as_u64().expect("inputs");
    // 200 KiB of compressed recording, its ROS 2 topics included, hold a few seconds of a
    // round (about 320 inputs a second).
    let robot_s = json["robot_time_s"].as_f64().expect("robot_time_s");
    assert!(inputs > 500 && robot_s > 2.0, "{json}");
}
