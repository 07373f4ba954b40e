//! The `ratf` binary as a user runs it: piped into a reader that stops early.

mod common;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

use common::{ratf, ratf_ok};

/// `path` as an argument (the temporary folder's paths are UTF-8).
fn arg(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// `ratf sim | head -1`: once the reader is gone the program ends quietly (exit 0, nothing
/// on stderr) instead of panicking on the broken pipe.
#[test]
fn a_reader_that_stops_early_ends_the_program_quietly() {
    let out_dir = std::env::temp_dir().join(format!("ratf-cli-test-{}", std::process::id()));
    let mut child = Command::new(env!("CARGO_BIN_EXE_ratf"))
        .args(["sim", "--round", "1", "--out"])
        .arg(&out_dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ratf starts");
    let stdout = child.stdout.take().expect("piped stdout");
    let mut first = String::new();
    BufReader::new(stdout)
        .read_line(&mut first)
        .expect("one line");
    assert!(first.starts_with("ratf sim: round 1"), "{first}");
    // The reader goes away here, like `head -1`.
    let output = child.wait_with_output().expect("ratf ends");
    let _ = std::fs::remove_dir_all(&out_dir);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{:?}: {stderr}", output.status);
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// The last line of stdout, parsed as JSON.
fn last_json_line(stdout: &[u8]) -> serde_json::Value {
    let text = String::from_utf8_lossy(stdout);
    let last = text.lines().last().unwrap_or_default();
    serde_json::from_str(last).unwrap_or_else(|e| panic!("{e}: {last}"))
}

/// `ratf sim` prints where its recording is; `ratf replay FILE --json` ends with one line
/// `{"inputs": N, "divergences": 0, "first_divergence": null, …}`.
#[test]
fn a_simulated_round_is_recorded_and_replays_without_divergence() {
    let out_dir = std::env::temp_dir().join(format!("ratf-cli-replay-{}", std::process::id()));
    let sim = ratf_ok(["sim", "--round", "1", "--json", "--out", arg(&out_dir)]);
    let text = String::from_utf8_lossy(&sim.stdout);
    let recording = out_dir.join("sim-round1-seed1-ours.mcap");
    assert!(
        text.contains(&format!("ratf replay {}", recording.display())),
        "{text}"
    );
    let replay = ratf_ok(["replay", arg(&recording), "--json"]);
    let _ = std::fs::remove_dir_all(&out_dir);
    let summary = last_json_line(&replay.stdout);
    assert!(summary["inputs"].as_u64().unwrap() > 10_000, "{summary}");
    assert_eq!(summary["divergences"], 0, "{summary}");
    assert!(summary["first_divergence"].is_null(), "{summary}");
}

/// A file that is not a recording is a clear error, not a panic.
#[test]
fn replaying_something_that_is_not_a_recording_says_so() {
    let path = std::env::temp_dir().join(format!("ratf-not-a-recording-{}", std::process::id()));
    std::fs::write(&path, b"not an MCAP file").unwrap();
    let replay = ratf(["replay", arg(&path)]);
    let _ = std::fs::remove_file(&path);
    let stderr = String::from_utf8_lossy(&replay.stderr);
    assert!(!replay.status.success());
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("ratf-not-a-recording"), "{stderr}");
}

/// `ratf calibrate --write FILE` writes a configuration that `ratf config --check` accepts
/// and that holds the fitted lidar calibration, not the defaults.
#[test]
fn a_calibration_is_written_as_a_configuration_that_checks() {
    let dir = std::env::temp_dir().join(format!("ratf-cli-calibrate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary folder");
    let written = dir.join("calibrated.toml");
    ratf_ok([
        "calibrate",
        "--world",
        "realistic",
        "--seed",
        "3",
        "--write",
        arg(&written),
    ]);
    ratf_ok(["config", "--check", arg(&written)]);
    let text = std::fs::read_to_string(&written).expect("the written file");
    let _ = std::fs::remove_dir_all(&dir);
    let config: toml::Table = toml::from_str(&text).expect("TOML");
    let scale = config["lidar"]["range_scale"]
        .as_float()
        .expect("range_scale");
    let yaw = config["robot"]["lidar_yaw_deg"]
        .as_float()
        .expect("lidar_yaw_deg");
    assert!(scale != 1.0 && (scale - 1.0).abs() < 0.03, "{scale}");
    // The default believes 172°; seed 3's lidar is turned 2.7° off it.
    assert!((yaw - 174.67).abs() < 0.3, "{yaw}");
}

/// `ratf bench bound --magnet-faces front,back --json`: the bound for a robot with a second
/// magnet on its back, below the competition robot's in every round, and the same from a
/// robot file naming both faces; `ratf sim` and `ratf config --check` with that file say why
/// the robot cannot drive it.
#[test]
fn the_bound_plans_for_a_second_magnet_that_the_robot_does_not_yet_drive() {
    let bound = |faces: &str| {
        last_json_line(&ratf_ok(["bench", "bound", "--json", "--magnet-faces", faces]).stdout)
    };
    let one = bound("front");
    let two = bound("front,back");
    assert_eq!(two["magnet_faces"], serde_json::json!(["front", "back"]));
    for round in 0..3 {
        let mean = |value: &serde_json::Value| value["rounds"][round]["mean_s"].as_f64().unwrap();
        assert!(
            mean(&two) < mean(&one),
            "round {}: {two} against {one}",
            round + 1
        );
    }
    let dir = std::env::temp_dir().join(format!("ratf-cli-magnets-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let robot = dir.join("two-magnets.toml");
    std::fs::write(&robot, "[robot]\nmagnet_faces = [\"front\", \"back\"]\n").unwrap();
    let sim = ratf([
        "sim",
        "--round",
        "1",
        "--out",
        arg(&dir),
        "--config",
        arg(&robot),
    ]);
    let check = ratf(["config", "--check", arg(&robot)]);
    let from_file = ratf(["bench", "bound", "--json", "--config", arg(&robot)]);
    let _ = std::fs::remove_dir_all(&dir);
    for refused in [&sim, &check] {
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert!(!refused.status.success(), "{stderr}");
        assert!(
            stderr.contains("the task planner and the mission carry one part"),
            "{stderr}"
        );
    }
    assert!(from_file.status.success());
    assert_eq!(last_json_line(&from_file.stdout), two);
}

/// `ratf run` builds the core before it opens any device: building it plans the route times
/// (0.8–1.0 s on a PC), and the devices' clock and threads, opened first, queued that long
/// behind the first tick (in a 2-minute soak each round's slowest reference write came
/// 0.56–0.78 s late; 12–17 ms with the core first). So a configuration the core refuses is
/// reported before the missing devices are.
#[test]
fn a_configuration_the_core_refuses_is_reported_before_any_device_is_opened() {
    let dir = std::env::temp_dir().join(format!("ratf-run-order-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary folder");
    let config = dir.join("robot.toml");
    std::fs::write(
        &config,
        "[robot]\nmagnet_faces = [\"front\", \"back\"]\n\
         [link]\nmega_port = \"/nonexistent/mega\"\nlidar_port = \"/nonexistent/lidar\"\n",
    )
    .expect("config written");
    let output = ratf(["run", "--config", arg(&config)]);
    let _ = std::fs::remove_dir_all(&dir);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(stderr.contains("task planner"), "{stderr}");
    assert!(!stderr.contains("no such device"), "{stderr}");
}
