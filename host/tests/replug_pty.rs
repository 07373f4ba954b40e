//! Issue 17's USB unplug and replug, end to end: `ratf run` drives round 1 of the served
//! world (`ratf sim --serve-pty`, real time), and the world pulls the Mega's or the lidar's
//! cable out for a second mid-round (`--unplug`): its pseudo-terminal goes and a new one
//! comes back at the same name. The robot must finish the round with the full score and
//! never drive blind: from the device thread's fault until the device
//! speaks again (the Mega's telemetry, a lidar scan with a point) every wheel command the
//! core produced is zero, and the magnet is off from the silence guard's
//! `MAGNET_OFF_AFTER_US` (60 ms) plus one tick on. The recording holds every input and output.
//!
//! The Mega's cable goes out while the robot drives empty (seed 1: between the first
//! placement and the second pick). Out while it carries, the Mega's own watchdog stops the
//! wheels and holds the magnet 300 ms more while they coast down (it cannot hear the host's
//! hold); how that goes is measured over random unplug times (`host/bench/replug.sh`), not
//! asserted here. The served world is the realistic one and the robot is not calibrated
//! for it, so the round may graze a divider (the bench counts the collisions); this test
//! does not pin them.
//!
//! Each round takes about a minute of wall time. Both programs run in their own process
//! groups, killed on drop (`common`); every wait has a deadline.

mod common;

use std::path::Path;
use std::time::Duration;

use common::{Spawned, TempDir, one_at_a_time, read, serve};
use ratf_core::runtime::{DeviceKind, Input, MAGNET_OFF_AFTER_US, Outputs};
use ratf_host::recording::Recording;

/// The magnet's grace after the wheels stop, plus one 50 Hz tick, µs.
const MAGNET_GRACE_US: u64 = MAGNET_OFF_AFTER_US + 20_000;

/// What the recording shows of the device's absences.
#[derive(Debug, Default)]
struct Absences {
    /// Faults with `reconnecting` for the device.
    faults: u32,
    /// Host ticks while it was away.
    ticks_away: u32,
    /// Of those, ticks that drove a wheel, or held the magnet past the grace.
    blind_ticks: Vec<String>,
    /// The longest absence, fault to data, µs.
    longest_us: u64,
}

/// Walk the recording: every host tick between `device`'s fault and its data again.
fn absences(recording: &Recording, device: DeviceKind) -> Absences {
    let mut outputs = recording.outputs.iter().peekable();
    let mut found = Absences::default();
    let mut away_since: Option<u64> = None;
    for (index, stamped) in recording.inputs.iter().enumerate() {
        let now_us = stamped.time.as_us();
        let mut produced: Option<&Outputs> = None;
        while let Some(record) = outputs.peek() {
            match record.input.cmp(&(index as u64)) {
                std::cmp::Ordering::Less => {
                    outputs.next();
                }
                std::cmp::Ordering::Equal => {
                    produced = outputs.next().map(|r| &r.outputs);
                    break;
                }
                std::cmp::Ordering::Greater => break,
            }
        }
        match &stamped.input {
            Input::DeviceFault {
                device: d,
                reconnecting: true,
                ..
            } if *d == device => {
                found.faults += 1;
                away_since.get_or_insert(now_us);
            }
            Input::Wheels(_) if device == DeviceKind::Mega => {
                if let Some(since) = away_since.take() {
                    found.longest_us = found.longest_us.max(now_us - since);
                }
            }
            Input::Scan(scan) if device == DeviceKind::Lidar && !scan.points.is_empty() => {
                if let Some(since) = away_since.take() {
                    found.longest_us = found.longest_us.max(now_us - since);
                }
            }
            Input::HostTick => {
                if let Some(since) = away_since {
                    found.ticks_away += 1;
                    let wheels = produced.and_then(|o| o.wheels);
                    let driving = wheels.is_some_and(|w| {
                        w.open_loop_pwm.is_some() || w.wheel_speeds_rad_s.iter().any(|s| *s != 0.0)
                    });
                    let magnet =
                        wheels.is_some_and(|w| w.solenoid_on) && now_us - since > MAGNET_GRACE_US;
                    if driving || magnet {
                        found.blind_ticks.push(format!(
                            "{:.3} s ({} ms after the fault): {wheels:?}",
                            now_us as f64 * 1e-6,
                            (now_us - since) / 1_000
                        ));
                    }
                }
            }
            _ => {}
        }
    }
    found
}

/// Round 1 at `seed` with the world pulling `device`'s cable at `at_s` for 1 s.
fn round_with_unplug(name: &str, seed: &str, device: DeviceKind, flag: &str, at_s: &str) {
    let _serial = one_at_a_time();
    let tmp = TempDir::new(name);
    let dir = &tmp.0;
    let (mut world, port) = serve(
        dir,
        seed,
        &[
            "--unplug",
            flag,
            "--unplug-at-s",
            at_s,
            "--unplug-for-s",
            "1",
        ],
    );
    let config = common::robot_config(dir, &dir.join("dev/lidar"), port);
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
        ],
        &dir.join("run.err"),
    );
    // Round 1 takes about 40 s of robot time, in real time, and a second or two more here.
    let status = robot.wait_exit(Duration::from_secs(180));
    let robot_said = robot.seen.join("\n");
    assert_eq!(
        status.code(),
        Some(0),
        "ratf run: {status:?}\n{robot_said}\nstderr:\n{}",
        read(&dir.join("run.err"))
    );
    assert!(
        robot
            .seen
            .iter()
            .any(|l| l.starts_with("ratf run: finished: placed 4 part(s)")),
        "{robot_said}"
    );
    let lost = format!("{device} lost: ");
    let back = format!("{device} speaks again: going on");
    assert!(
        robot_said.contains(&lost) && robot_said.contains(&back),
        "{robot_said}"
    );
    let end = world.wait_line(Duration::from_secs(30), |l| l.starts_with("round 1: "));
    let world_said = world.seen.join("\n");
    assert!(
        world_said.contains("unplugged: ") && world_said.contains("replugged: "),
        "{world_said}"
    );
    assert!(end.starts_with("round 1: 4 points"), "{world_said}");
    assert_eq!(world.wait_exit(Duration::from_secs(10)).code(), Some(0));
    let found = absences(
        &Recording::read(&recording_in(&out)).expect("the recording"),
        device,
    );
    assert!(
        found.faults >= 1 && found.ticks_away >= 10,
        "{device}: not seen away for 10 ticks: {found:?}"
    );
    assert!(
        found.blind_ticks.is_empty(),
        "{device}: drove blind at {:#?}",
        found.blind_ticks
    );
    assert!(
        found.longest_us < 5_000_000,
        "{device}: away {} ms",
        found.longest_us / 1_000
    );
}

/// The run's recording in `out`.
fn recording_in(out: &Path) -> std::path::PathBuf {
    std::fs::read_dir(out)
        .expect("the recording's folder")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|e| e == "mcap"))
        .expect("a recording")
}

/// Ignored for a while after it failed once in CI (at `1b9de53`: every pick after the replug
/// given up): the mission's clock ran on while the core held the robot, so its timeouts ran
/// out on a robot that could not move, and the grip was judged on the switch from before the
/// unplug (fixed: `Mission::hold`).
#[test]
fn the_megas_cable_out_for_a_second_mid_round_holds_the_robot_and_round_1_scores_fully() {
    round_with_unplug("replug-mega", "1", DeviceKind::Mega, "mega", "10");
}

#[test]
fn the_lidars_cable_out_for_a_second_mid_round_holds_the_robot_and_round_1_scores_fully() {
    round_with_unplug("replug-lidar", "1", DeviceKind::Lidar, "lidar", "20");
}
