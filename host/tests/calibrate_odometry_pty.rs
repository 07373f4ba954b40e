//! `ratf calibrate odometry --robot` end to end with no hardware: against `ratf sim
//! --serve-pty` in the realistic world at seed 16 (the simulated Mega and X4 behind
//! pseudo-terminals, the world in real time), the lidar calibrated first as a team does
//! (`ratf calibrate --robot` with the six pole-to-pole tape measures), then the 100 s
//! odometry drive; then `--from-recording` on the recording that drive made.

mod common;

use std::path::Path;
use std::time::Duration;

use common::{Spawned, TempDir, float, one_at_a_time, read, robot_config, run_ok, serve};
use ratf_core::config::{Config, WorldProfile};
use ratf_sim::truth::WorldTruth;

/// The served world's seed: one whose wheels are off by more than twice the checks'
/// tolerances before calibrating (wheel diameter +0.52 %, lx + ly −2.0 %), so the checks
/// tell a fit from none.
const SEED: u64 = 16;

/// The served world's beliefs (no `--config`: the defaults) and its truth (the same draw
/// the served world makes from its seed and profile).
fn served_world() -> (Config, WorldTruth) {
    let mut config = Config::default();
    config.sim.world = WorldProfile::Realistic;
    config.sim.seed = SEED;
    let truth = WorldTruth::draw(&config, 0.0);
    (config, truth)
}

/// What a team measures with a tape on the day, as `ratf calibrate` options (here exact,
/// from the truth): the six pole-to-pole distances and each pole's centre from the floor
/// sheet's edges.
fn day_measures(config: &Config, truth: &WorldTruth) -> Vec<(&'static str, String)> {
    let field = truth.true_field(config);
    let centres: Vec<_> = field.beacons().iter().map(|b| b.circle.center).collect();
    let mut measures = Vec::new();
    for a in 0..centres.len() {
        for b in a + 1..centres.len() {
            let distance = centres[a].distance(centres[b]);
            measures.push(("--tape", format!("{a}-{b}={distance:.4}")));
        }
        let centre = centres[a];
        measures.push(("--pole", format!("{a}={:.4},{:.4}", centre.x, centre.y)));
    }
    measures
}

/// `path` with the robot's ports and server port taken from `devices` (another served
/// world's robot file), written to `to`.
fn with_devices(path: &Path, devices: &Path, to: &Path) {
    let mut file: toml::Table = toml::from_str(&read(path)).expect("TOML");
    let devices: toml::Table = toml::from_str(&read(devices)).expect("TOML");
    for section in ["link", "referee"] {
        file.insert(section.to_owned(), devices[section].clone());
    }
    std::fs::write(to, toml::to_string(&file).expect("TOML")).expect("config");
}

#[test]
fn the_odometry_drive_on_the_served_devices_fits_the_true_wheels_and_its_recording_gives_the_same_fit()
 {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("calibrate-odometry-pty");
    let dir = &tmp.0;
    let (config, truth) = served_world();
    let true_diameter_m = config.robot.wheel_diameter_m * truth.mean_wheel_radius_scale();
    let true_lx_plus_ly_m = config.robot.half_wheelbase_sum_m() * truth.turn_scale;

    // The lidar first, in one served world.
    let lidar_dir = dir.join("lidar");
    std::fs::create_dir_all(&lidar_dir).expect("dir");
    let (world, port) = serve(&lidar_dir, &SEED.to_string(), &["--world", "realistic"]);
    let robot = robot_config(&lidar_dir, &lidar_dir.join("dev/lidar"), port);
    let lidar_calibrated = dir.join("lidar.toml");
    let measures = day_measures(&config, &truth);
    let mut args = vec![
        "calibrate",
        "--robot",
        "--config",
        robot.to_str().expect("utf-8 path"),
        "--yes",
        "--write",
        lidar_calibrated.to_str().expect("utf-8 path"),
        "--out",
        lidar_dir.to_str().expect("utf-8 path"),
    ];
    for (option, measure) in &measures {
        args.extend([*option, measure.as_str()]);
    }
    run_ok(&args, &dir.join("calibrate.err"), Duration::from_secs(120));
    drop(world);

    // Then the odometry drive, in a fresh served world of the same seed.
    let odometry_dir = dir.join("odometry");
    std::fs::create_dir_all(&odometry_dir).expect("dir");
    let (_world, port) = serve(&odometry_dir, &SEED.to_string(), &["--world", "realistic"]);
    let devices = robot_config(&odometry_dir, &odometry_dir.join("dev/lidar"), port);
    let robot = dir.join("robot.toml");
    with_devices(&lidar_calibrated, &devices, &robot);
    let written = dir.join("odometry.toml");
    let driven = run_ok(
        &[
            "calibrate",
            "odometry",
            "--robot",
            "--config",
            robot.to_str().expect("utf-8 path"),
            "--yes",
            "--write",
            written.to_str().expect("utf-8 path"),
            "--out",
            odometry_dir.to_str().expect("utf-8 path"),
            "--json",
        ],
        &dir.join("odometry.err"),
        Duration::from_secs(300),
    );
    let live = driven.json();
    let text = read(&written);
    let file: toml::Table = toml::from_str(&text).expect("TOML");
    let key = |name: &str| {
        file["robot"][name]
            .as_float()
            .unwrap_or_else(|| panic!("{name} in\n{text}"))
    };
    let diameter_m = key("wheel_diameter_m");
    let lx_plus_ly_m =
        (key("front_back_wheel_distance_m") + key("left_right_wheel_distance_m")) / 2.0;
    let diameter_error_pct = (diameter_m / true_diameter_m - 1.0) * 100.0;
    let lx_plus_ly_error_pct = (lx_plus_ly_m / true_lx_plus_ly_m - 1.0) * 100.0;
    let before_pct = [
        (config.robot.wheel_diameter_m / true_diameter_m - 1.0) * 100.0,
        (config.robot.half_wheelbase_sum_m() / true_lx_plus_ly_m - 1.0) * 100.0,
    ];
    let strafe = key("strafe_factor");
    let figures = format!(
        "wheel diameter {diameter_m:.5} m, truth {true_diameter_m:.5} m, error \
         {diameter_error_pct:+.3} % (before {:+.3} %); lx+ly {lx_plus_ly_m:.5} m, truth \
         {true_lx_plus_ly_m:.5} m, error {lx_plus_ly_error_pct:+.3} % (before {:+.3} %); \
         strafe factor {strafe:.4}, truth {:.4}\n{}",
        before_pct[0],
        before_pct[1],
        truth.lateral_factor,
        driven.seen.join("\n")
    );
    eprintln!("{figures}");
    // The simulated drive at this seed is within 0.04 % of both. In real time the drive,
    // closed loop on the estimate, steers with what the devices' threads' timing gave the
    // localiser, so its fit is a draw from its spread (over the realistic world's seeds 1–20
    // in the simulator: 0.17 % and 0.19 % at worst); the tolerances allow that and stay
    // under half the errors before calibrating.
    let (diameter_tolerance_pct, lx_plus_ly_tolerance_pct) = (0.2, 0.5);
    assert!(
        before_pct[0].abs() > 2.0 * diameter_tolerance_pct,
        "{figures}"
    );
    assert!(
        before_pct[1].abs() > 2.0 * lx_plus_ly_tolerance_pct,
        "{figures}"
    );
    assert!(
        diameter_error_pct.abs() < diameter_tolerance_pct,
        "{figures}"
    );
    assert!(
        lx_plus_ly_error_pct.abs() < lx_plus_ly_tolerance_pct,
        "{figures}"
    );
    assert!(
        (diameter_m - float(&live["fit"], "wheel_diameter_m")).abs() < 1e-9,
        "{figures}"
    );
    // The rollers' sideways slip, from the strafe legs: the world's 0.93 where the
    // configuration said 1.
    assert!(
        (strafe - truth.lateral_factor).abs() < 0.01
            && (config.robot.strafe_factor - 1.0).abs() < 1e-12,
        "strafe factor {strafe:.4}, truth {:.4}\n{figures}",
        truth.lateral_factor
    );
    // The lidar's place on the robot, from the turns in place: the world drew it 3.5 mm
    // from the file's (the simulated drive at this seed leaves 0.4 mm).
    let [dx, dy] = truth.lidar_position_error_m;
    let lidar_before_mm = dx.hypot(dy) * 1e3;
    let lidar_error_mm = (key("lidar_x_m") - (config.robot.lidar_x_m + dx))
        .hypot(key("lidar_y_m") - (config.robot.lidar_y_m + dy))
        * 1e3;
    let lidar_tolerance_mm = 1.5;
    assert!(
        lidar_before_mm > 2.0 * lidar_tolerance_mm && lidar_error_mm < lidar_tolerance_mm,
        "lidar {lidar_error_mm:.2} mm off (before {lidar_before_mm:.2} mm)\n{figures}"
    );
    // The team's own keys are kept, and the file is still a robot's file.
    assert_eq!(file["link"]["imu"].as_str(), Some("none"), "{text}");
    assert!(file["lidar"].get("range_scale").is_some(), "{text}");
    assert!(!file.contains_key("sim"), "{text}");

    // The recording that drive made gives the same fit, and writes the same keys.
    let recording = live["recording"].as_str().expect("the recording's path");
    let rewritten = dir.join("from-recording.toml");
    let replayed = run_ok(
        &[
            "calibrate",
            "odometry",
            "--from-recording",
            recording,
            "--config",
            robot.to_str().expect("utf-8 path"),
            "--write",
            rewritten.to_str().expect("utf-8 path"),
            "--json",
        ],
        &dir.join("from-recording.err"),
        Duration::from_secs(120),
    );
    let from_recording = replayed.json();
    assert_eq!(from_recording["fit"], live["fit"], "{figures}");
    assert_eq!(from_recording["agreement"], live["agreement"]);
    assert_eq!(read(&rewritten), text);

    // The lidar calibration's recording is not an odometry drive's.
    let other = std::fs::read_dir(&lidar_dir)
        .expect("the lidar's recordings")
        .filter_map(Result::ok)
        .map(|entry| entry.path())
        .find(|path| path.extension().is_some_and(|e| e == "mcap"))
        .expect("the lidar calibration's recording");
    let mut refused = Spawned::start(
        &[
            "calibrate",
            "odometry",
            "--from-recording",
            other.to_str().expect("utf-8 path"),
        ],
        &dir.join("refused.err"),
    );
    let status = refused.wait_exit(Duration::from_secs(60));
    let stderr = read(&dir.join("refused.err"));
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("\"calibration\" run, not of the odometry drive"),
        "{stderr}"
    );
}
