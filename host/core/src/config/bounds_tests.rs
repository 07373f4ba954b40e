//! The reproducers of issue 13, item 5 (values `ratf config --check` accepted and that then
//! broke the robot or the simulator), and a property test that validation never panics and
//! that what it accepts builds a core.

use proptest::prelude::*;

use super::*;
use crate::field::Field;
use crate::runtime::Core;

/// The issues of `text`, as printed (`key = value: reason`); panics if it is accepted.
fn rejected(text: &str) -> Vec<String> {
    match Config::from_toml_str(text) {
        Err(ConfigError::Invalid { issues, .. }) => issues.iter().map(Issue::to_string).collect(),
        other => panic!("expected Invalid for {text:?}, got {other:?}"),
    }
}

fn assert_one(text: &str, starts: &str, contains: &[&str]) {
    let issues = rejected(text);
    assert_eq!(issues.len(), 1, "{issues:#?}");
    assert!(issues[0].starts_with(starts), "{}", issues[0]);
    for part in contains {
        assert!(issues[0].contains(part), "{:?} not in {}", part, issues[0]);
    }
}

#[test]
fn a_dock_length_of_1e300_is_refused_before_the_route_planner_overflows() {
    assert_one(
        "[navigation]\ndock_length_m = 1e300\n",
        "navigation.dock_length_m = 1e300: must be within 0 … 0.26 m (",
        &["machine A's output faces machine B's input"],
    );
}

#[test]
fn a_history_of_4e9_steps_is_refused_before_allocating_864_gb() {
    assert_one(
        "[localisation]\nhistory_steps = 4000000000\n",
        "localisation.history_steps = 4000000000: must be within 2 … 1000 steps (",
        &["216 bytes"],
    );
}

#[test]
fn a_scan_rate_of_65535_hz_is_refused_before_the_lidar_line_grows_without_bound() {
    assert_one(
        "[lidar]\nscan_rate_hz = 65535\n",
        "lidar.scan_rate_hz = 65535: must be within 4 … 12.7 Hz (",
        &["6–12 Hz"],
    );
}

#[test]
fn a_control_period_of_1_us_is_refused_before_the_mega_line_grows_without_bound() {
    // Alone, and with the time step that used to let it through.
    for text in [
        "[mega]\ncontrol_period_us = 1\n",
        "[mega]\ncontrol_period_us = 1\n[sim]\ntime_step_us = 1\n",
    ] {
        let issues = rejected(text);
        assert!(
            issues[0].starts_with("mega.control_period_us = 1: must be within 1000 … 100000 µs"),
            "{issues:#?}"
        );
    }
}

#[test]
fn a_control_period_of_5000_us_is_refused_with_the_links_arithmetic() {
    assert_one(
        "[mega]\ncontrol_period_us = 5000\n",
        "mega.control_period_us = 5000: the Mega's telemetry does not fit: a batch of 81 bytes",
        &[
            "115200 baud (link.mega_baud) = 7.03 ms on the wire",
            "2.08 ms = 9.11 ms, more than 80 % of the period (4.00 ms)",
            "at least 12 ms",
        ],
    );
    // 12 ms is the shortest period that fits at 115 200 baud; without checksums 11 ms does.
    assert!(Config::from_toml_str("[mega]\ncontrol_period_us = 12000\n").is_ok());
    assert!(Config::from_toml_str("[mega]\ncontrol_period_us = 11000\n").is_err());
    assert!(
        Config::from_toml_str("[mega]\ncontrol_period_us = 11000\nsend_checksums = false\n")
            .is_ok()
    );
}

#[test]
fn an_angle_step_of_0_4_deg_is_refused_with_the_links_arithmetic() {
    assert_one(
        "[lidar]\nangle_step_deg = 0.4\n",
        "lidar.angle_step_deg = 0.4: the X4's stream does not fit its line: 900 samples",
        &[
            "14294 bytes/s × 10 bits = 142940 bit/s, 112 % of link.lidar_baud 128000",
            "At 7 Hz use angle_step_deg ≥ 0.48°",
        ],
    );
    // The suggested step fits, and so does the X4's finest at its slowest rate.
    assert!(Config::from_toml_str("[lidar]\nangle_step_deg = 0.48\n").is_ok());
    assert!(Config::from_toml_str("[lidar]\nangle_step_deg = 0.47\n").is_err());
    assert!(Config::from_toml_str("[lidar]\nscan_rate_hz = 6.0\nangle_step_deg = 0.43\n").is_ok());
    assert!(Config::from_toml_str("[lidar]\nscan_rate_hz = 12.0\nangle_step_deg = 0.86\n").is_ok());
}

#[test]
fn a_slow_mega_link_is_refused_for_the_references_too() {
    let issues = rejected("[link]\nmega_baud = 19200\n");
    assert!(
        issues.iter().any(|i| i
            .starts_with("link.mega_baud = 19200: the references do not fit: a batch of 63 bytes")
            && i.contains("at least 39375 baud")),
        "{issues:#?}"
    );
}

#[test]
fn cross_key_checks_name_the_arithmetic() {
    let issues = rejected("[localisation]\nhistory_steps = 5\n");
    assert!(
        issues[0].starts_with("localisation.history_steps = 5: too short to apply a scan")
            && issues[0].contains("At least 9 steps"),
        "{issues:#?}"
    );
    let issues = rejected("[navigation]\nmax_speed_m_s = 1.0\n");
    assert!(issues[0].contains("0.729 m/s at the rim"), "{issues:#?}");
    let issues = rejected("[robot]\nmax_wheel_speed_rad_s = 90.0\n");
    assert!(
        issues[0].starts_with("robot.max_wheel_speed_rad_s = 90: the Mega cannot count")
            && issues[0].contains("at most 85.2 rad/s"),
        "{issues:#?}"
    );
    // A rejected key does not also trip the cross-key checks built on it.
    assert_eq!(rejected("[robot]\nwheel_diameter_m = -0.06\n").len(), 1);
}

/// Numeric keys covered by the property test: name, getter and setter (integers set with a
/// saturating cast, as a wild value would be clamped by the TOML parser's type anyway).
type Getter = fn(&Config) -> f64;
type Setter = fn(&mut Config, f64);
const KEYS: &[(&str, Getter, Setter)] = &[
    (
        "navigation.dock_length_m",
        |c| c.navigation.dock_length_m,
        |c, v| c.navigation.dock_length_m = v,
    ),
    (
        "navigation.max_speed_m_s",
        |c| c.navigation.max_speed_m_s,
        |c, v| c.navigation.max_speed_m_s = v,
    ),
    (
        "navigation.corner_blend_m",
        |c| c.navigation.corner_blend_m,
        |c, v| c.navigation.corner_blend_m = v,
    ),
    (
        "navigation.rotate_after_m",
        |c| c.navigation.rotate_after_m,
        |c, v| c.navigation.rotate_after_m = v,
    ),
    (
        "navigation.align_before_m",
        |c| c.navigation.align_before_m,
        |c, v| c.navigation.align_before_m = v,
    ),
    (
        "localisation.history_steps",
        |c| c.localisation.history_steps as f64,
        |c, v| c.localisation.history_steps = v as usize,
    ),
    (
        "localisation.gyro_max_gap_us",
        |c| c.localisation.gyro_max_gap_us as f64,
        |c, v| c.localisation.gyro_max_gap_us = v as u64,
    ),
    (
        "localisation.max_search_radius_m",
        |c| c.localisation.max_search_radius_m,
        |c, v| c.localisation.max_search_radius_m = v,
    ),
    (
        "localisation.min_points",
        |c| c.localisation.min_points as f64,
        |c, v| c.localisation.min_points = v as usize,
    ),
    (
        "localisation.gate_chi2",
        |c| c.localisation.gate_chi2,
        |c, v| c.localisation.gate_chi2 = v,
    ),
    (
        "lidar.scan_rate_hz",
        |c| c.lidar.scan_rate_hz,
        |c, v| c.lidar.scan_rate_hz = v,
    ),
    (
        "lidar.angle_step_deg",
        |c| c.lidar.angle_step_deg,
        |c, v| c.lidar.angle_step_deg = v,
    ),
    (
        "lidar.min_range_m",
        |c| c.lidar.min_range_m,
        |c, v| c.lidar.min_range_m = v,
    ),
    (
        "lidar.max_range_m",
        |c| c.lidar.max_range_m,
        |c, v| c.lidar.max_range_m = v,
    ),
    (
        "mega.control_period_us",
        |c| c.mega.control_period_us as f64,
        |c, v| c.mega.control_period_us = v as u32,
    ),
    (
        "mega.watchdog_timeout_us",
        |c| c.mega.watchdog_timeout_us as f64,
        |c, v| c.mega.watchdog_timeout_us = v as u32,
    ),
    (
        "mega.telemetry_latency_us",
        |c| c.mega.telemetry_latency_us as f64,
        |c, v| c.mega.telemetry_latency_us = v as u32,
    ),
    (
        "mega.kc_v_per_rad_s",
        |c| c.mega.kc_v_per_rad_s,
        |c, v| c.mega.kc_v_per_rad_s = v,
    ),
    (
        "mega.pwm_slew_per_tick",
        |c| c.mega.pwm_slew_per_tick as f64,
        |c, v| c.mega.pwm_slew_per_tick = v as i16,
    ),
    (
        "link.mega_baud",
        |c| c.link.mega_baud as f64,
        |c, v| c.link.mega_baud = v as u32,
    ),
    (
        "link.lidar_baud",
        |c| c.link.lidar_baud as f64,
        |c, v| c.link.lidar_baud = v as u32,
    ),
    (
        "robot.wheel_diameter_m",
        |c| c.robot.wheel_diameter_m,
        |c, v| c.robot.wheel_diameter_m = v,
    ),
    (
        "robot.max_wheel_speed_rad_s",
        |c| c.robot.max_wheel_speed_rad_s,
        |c, v| c.robot.max_wheel_speed_rad_s = v,
    ),
    (
        "robot.ticks_per_wheel_rev",
        |c| c.robot.ticks_per_wheel_rev,
        |c, v| c.robot.ticks_per_wheel_rev = v,
    ),
    (
        "robot.lidar_x_m",
        |c| c.robot.lidar_x_m,
        |c, v| c.robot.lidar_x_m = v,
    ),
    (
        "motor.battery_voltage_v",
        |c| c.motor.battery_voltage_v,
        |c, v| c.motor.battery_voltage_v = v,
    ),
    (
        "motor.dead_zone_v",
        |c| c.motor.dead_zone_v,
        |c, v| c.motor.dead_zone_v = v,
    ),
    (
        "sim.time_step_us",
        |c| c.sim.time_step_us as f64,
        |c, v| c.sim.time_step_us = v as u32,
    ),
    (
        "competition.poll_period_s",
        |c| c.competition.poll_period_s,
        |c, v| c.competition.poll_period_s = v,
    ),
    (
        "competition.machine_delay_s",
        |c| c.competition.machine_delay_s,
        |c, v| c.competition.machine_delay_s = v,
    ),
    (
        "referee.request_timeout_ms",
        |c| c.referee.request_timeout_ms as f64,
        |c, v| c.referee.request_timeout_ms = v as u32,
    ),
    (
        "referee.max_tries",
        |c| c.referee.max_tries as f64,
        |c, v| c.referee.max_tries = v as u32,
    ),
    (
        "mission.drive_timeout_s",
        |c| c.mission.drive_timeout_s,
        |c, v| c.mission.drive_timeout_s = v,
    ),
    (
        "mission.stall_s",
        |c| c.mission.stall_s,
        |c, v| c.mission.stall_s = v,
    ),
    (
        "mission.server_word_wait_s",
        |c| c.mission.server_word_wait_s,
        |c, v| c.mission.server_word_wait_s = v,
    ),
    (
        "mission.back_out_m",
        |c| c.mission.back_out_m,
        |c, v| c.mission.back_out_m = v,
    ),
    (
        "field.beacons_m[0].x",
        |c| c.field.beacons_m[0][0],
        |c, v| c.field.beacons_m[0][0] = v,
    ),
];

/// Values near the defaults (mostly accepted) and wild ones (finite and not).
fn value() -> impl Strategy<Value = Value> {
    prop_oneof![
        3 => (0.5..1.5f64).prop_map(Value::TimesDefault),
        1 => wild().prop_map(Value::Set),
    ]
}

/// A value for a key: its default scaled, or a value of its own.
#[derive(Clone, Copy, Debug)]
enum Value {
    TimesDefault(f64),
    Set(f64),
}

fn wild() -> impl Strategy<Value = f64> {
    prop_oneof![
        prop::sample::select(vec![
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -0.0,
            1e300,
            -1e300,
            f64::MIN_POSITIVE,
            4e9,
            65_535.0,
        ]),
        any::<f64>(),
        -1.0e3..1.0e5,
        0.0..1.0,
    ]
}

proptest! {
    // Validation is cheap and runs on every case; building a core (its planner times every
    // route: about 0.3 s in the test profile) on about a quarter of the accepted ones, so
    // that the test takes some 25 s instead of 90.
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn validation_never_panics_and_what_it_accepts_builds_a_core(
        changes in prop::collection::vec((0..KEYS.len(), value()), 1..4),
        build_a_core in prop::bool::weighted(0.25),
    ) {
        let mut config = Config::default();
        for &(key, value) in &changes {
            let (_, get, set) = KEYS[key];
            let v = match value {
                Value::TimesDefault(factor) => get(&Config::default()) * factor,
                Value::Set(v) => v,
            };
            set(&mut config, v);
        }
        let issues = config.issues();
        for issue in &issues {
            // Every issue names a key and says why.
            prop_assert!(issue.key.contains('.') && !issue.reason.is_empty(), "{issue}");
        }
        if issues.is_empty() && build_a_core {
            let core = Core::new(&config, Field::competition().start_pose());
            prop_assert!(core.is_ok(), "{:?}", core.err());
        }
    }
}

#[test]
fn magnet_faces_name_at_least_one_face_once_each() {
    assert_one(
        "[robot]\nmagnet_faces = []\n",
        "robot.magnet_faces = []: must name at least one face",
        &[],
    );
    assert_one(
        "[robot]\nmagnet_faces = [\"front\", \"back\", \"front\"]\n",
        "robot.magnet_faces = [\"front\", \"back\", \"front\"]: names a face twice",
        &[],
    );
    assert!(Config::from_toml_str("[robot]\nmagnet_faces = [\"side\"]\n").is_err());
}

/// Two magnets describe a robot the configuration accepts and the bound plans for
/// (`planning::bound`), but the task planner and the mission carry one part on the front
/// magnet: the core refuses to drive it, and says so.
#[test]
fn the_core_refuses_a_robot_with_magnets_it_does_not_drive() {
    let config = Config::from_toml_str("[robot]\nmagnet_faces = [\"front\", \"back\"]\n").unwrap();
    let refused = Core::new(&config, Field::competition().start_pose()).err();
    let Some(error) = refused else {
        panic!("a core was built for magnets front and back");
    };
    assert_eq!(
        error,
        crate::planning::tasks::TaskError::MagnetFaces(vec![MagnetFace::Front, MagnetFace::Back])
    );
    assert!(
        error
            .to_string()
            .starts_with("robot.magnet_faces = [\"front\", \"back\"]: the task planner"),
        "{error}"
    );
    let back = Config::from_toml_str("[robot]\nmagnet_faces = [\"back\"]\n").unwrap();
    assert!(Core::new(&back, Field::competition().start_pose()).is_err());
}
