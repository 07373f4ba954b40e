//! A configuration that validates must build the simulated world and the core and run them
//! without panicking (issue 13, item 5): changes to numeric keys, near their defaults or
//! wild (NaN, infinities, huge, negative), written as TOML, parsed and validated; what is
//! accepted runs for a second of simulated time.

use std::collections::BTreeMap;

use proptest::prelude::*;
use ratf_core::config::{Config, ConfigError};
use ratf_core::runtime::{Core, Devices};
use ratf_sim::devices::SimDevices;
use ratf_sim::world::Scenario;

/// A key's TOML type.
#[derive(Clone, Copy, Debug)]
enum Kind {
    Float,
    Int,
}

/// Keys that shape the world, the links and the core: section, key, type, default.
const KEYS: &[(&str, &str, Kind, f64)] = &[
    ("mega", "control_period_us", Kind::Int, 20_000.0),
    ("mega", "telemetry_latency_us", Kind::Int, 2_080.0),
    ("mega", "watchdog_timeout_us", Kind::Int, 100_000.0),
    ("mega", "kc_v_per_rad_s", Kind::Float, 0.4566),
    ("link", "mega_baud", Kind::Int, 115_200.0),
    ("link", "lidar_baud", Kind::Int, 128_000.0),
    ("lidar", "scan_rate_hz", Kind::Float, 7.0),
    ("lidar", "angle_step_deg", Kind::Float, 0.5),
    ("lidar", "min_range_m", Kind::Float, 0.12),
    ("lidar", "max_range_m", Kind::Float, 10.0),
    ("lidar", "range_noise_std_m", Kind::Float, 0.01),
    ("sim", "time_step_us", Kind::Int, 1_000.0),
    ("robot", "wheel_diameter_m", Kind::Float, 0.06),
    ("robot", "ticks_per_wheel_rev", Kind::Float, 2803.2),
    ("robot", "footprint_length_m", Kind::Float, 0.3),
    ("robot", "body_center_x_m", Kind::Float, 0.0),
    ("robot", "lidar_height_m", Kind::Float, 0.2),
    ("motor", "time_constant_s", Kind::Float, 0.1),
    ("motor", "battery_voltage_v", Kind::Float, 11.1),
    ("traction", "friction_coefficient", Kind::Float, 0.7),
    ("traction", "robot_mass_kg", Kind::Float, 2.0),
    ("localisation", "history_steps", Kind::Int, 64.0),
    ("localisation", "gyro_max_gap_us", Kind::Int, 20_000.0),
    ("navigation", "dock_length_m", Kind::Float, 0.05),
    ("navigation", "max_speed_m_s", Kind::Float, 0.6),
    ("competition", "poll_period_s", Kind::Float, 0.2),
];

/// A value: the default scaled, or a wild one.
fn value() -> impl Strategy<Value = Result<f64, f64>> {
    prop_oneof![
        3 => (0.5..2.0f64).prop_map(Ok),
        1 => prop_oneof![
            prop::sample::select(vec![
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
                0.0,
                -1.0,
                1e300,
                4e9,
                65_535.0,
            ]),
            any::<f64>(),
        ]
        .prop_map(Err),
    ]
}

/// The TOML text of `value` for a key of `kind`.
fn toml_value(kind: Kind, value: f64) -> String {
    match kind {
        Kind::Int => format!("{}", value.clamp(-9e18, 9e18) as i64),
        Kind::Float if value.is_nan() => "nan".to_owned(),
        Kind::Float if value.is_infinite() => (if value > 0.0 { "inf" } else { "-inf" }).to_owned(),
        Kind::Float => format!("{value:?}"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn a_configuration_that_validates_builds_and_runs_the_world_and_the_core(
        changes in prop::collection::vec((0..KEYS.len(), value()), 1..4),
    ) {
        // One table per section, the last value of a key kept.
        let mut sections: BTreeMap<&str, BTreeMap<&str, String>> = BTreeMap::new();
        for (index, value) in &changes {
            let (section, key, kind, default) = KEYS[*index];
            let v = match *value {
                Ok(factor) => default * factor,
                Err(wild) => wild,
            };
            sections.entry(section).or_default().insert(key, toml_value(kind, v));
        }
        let mut text = String::new();
        for (section, keys) in &sections {
            text.push_str(&format!("[{section}]\n"));
            for (key, value) in keys {
                text.push_str(&format!("{key} = {value}\n"));
            }
        }
        let config = match Config::from_toml_str(&text) {
            Ok(config) => config,
            // Out-of-type integers and rejected values are errors that name the problem.
            Err(ConfigError::Parse { .. } | ConfigError::Invalid { .. }) => return Ok(()),
            Err(e) => return Err(TestCaseError::fail(format!("{e}"))),
        };
        let scenario = Scenario::new(&config);
        let devices = SimDevices::new(&config, &scenario);
        prop_assert!(devices.is_ok(), "{text}: {:?}", devices.err());
        let core = Core::new(&config, scenario.start_pose);
        prop_assert!(core.is_ok(), "{text}: {:?}", core.err());
        let (mut devices, mut core) = (devices.unwrap(), core.unwrap());
        while devices.now_us() < 1_000_000 {
            let Ok(Some(input)) = devices.next_input() else {
                return Err(TestCaseError::fail(format!("{text}: the devices stopped")));
            };
            let outputs = core.step(&input);
            prop_assert!(devices.apply(&input, &outputs).is_ok());
        }
        let stats = devices.world().stats();
        prop_assert_eq!(
            (stats.from_mega_bytes_dropped, stats.from_lidar_bytes_dropped),
            (0, 0),
            "{}: a link dropped bytes",
            text
        );
    }
}
