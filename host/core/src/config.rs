//! One typed configuration for the whole host, read from TOML.
//!
//! Defaults are the 5dpo competition robot; every number's doc comment gives its source or
//! says it is an assumption. Every section is `#[serde(default)]`, so a file only needs the
//! keys it changes, and `#[serde(deny_unknown_fields)]`, so a misspelt key is an error.
//! [`Config::validate`] rejects values no robot can have, naming the key, the value, the
//! allowed range and why: every key is bounded to what is physically meaningful (the
//! robot's geometry, the field, the datasheets, the links' capacity; shared facts in
//! `limits`), and cross-key checks (`links`, `cross`) refuse combinations a link cannot
//! carry or the robot cannot use. So no accepted value can exhaust memory, overflow
//! arithmetic or make a round silently score nothing.

mod check;
mod competition;
mod cross;
mod field;
mod io;
mod limits;
mod links;
mod localisation;
mod mega;
mod motor;
mod navigation;
mod robot;
mod sim;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use check::Issue;
pub use competition::{CompetitionConfig, Policy};
pub use field::FieldConfig;
pub use io::{ImuDevice, LidarConfig, LinkConfig, RefereeConfig};
pub use localisation::{CentreMethod, LocalisationConfig};
pub use mega::MegaConfig;
pub use motor::{MotorConfig, TractionConfig};
pub use navigation::NavigationConfig;
pub use robot::{ImuConfig, MagnetFace, RobotConfig};
pub use sim::{ClutterConfig, SimConfig, WorldProfile};

use check::Checker;

/// The whole configuration.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Geometry, wheel conventions, sensor mounts.
    pub robot: RobotConfig,
    /// Motor model (simulator).
    pub motor: MotorConfig,
    /// Wheel–floor contact (simulator).
    pub traction: TractionConfig,
    /// The Mega's control loop.
    pub mega: MegaConfig,
    /// The lidar's characteristics.
    pub lidar: LidarConfig,
    /// Serial ports.
    pub link: LinkConfig,
    /// The organisers' server.
    pub referee: RefereeConfig,
    /// The simulator.
    pub sim: SimConfig,
    /// The beacon localiser.
    pub localisation: LocalisationConfig,
    /// The path follower and docking.
    pub navigation: NavigationConfig,
    /// The round, the policy, the server polling and the planner's assumptions.
    pub competition: CompetitionConfig,
    /// The mission's timing and distances.
    pub mission: crate::mission::MissionConfig,
    /// The floor as measured on the day (the beacons).
    pub field: FieldConfig,
}

/// Why a configuration could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read configuration file {}: {error}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error (shown in the message, so not chained as a source).
        error: std::io::Error,
    },
    /// The text is not valid TOML for this schema (the message shows line and column).
    #[error("invalid configuration{}: {error}", origin(.path))]
    Parse {
        /// The file, if read from one.
        path: Option<PathBuf>,
        /// toml's error with the line and column (shown in the message, not chained).
        error: toml::de::Error,
    },
    /// Values out of range.
    #[error("invalid configuration{}: {}", origin(.path), join(.issues))]
    Invalid {
        /// The file, if read from one.
        path: Option<PathBuf>,
        /// Every bad key with its reason.
        issues: Vec<Issue>,
    },
}

fn origin(path: &Option<PathBuf>) -> String {
    path.as_ref()
        .map(|p| format!(" in {}", p.display()))
        .unwrap_or_default()
}

fn join(issues: &[Issue]) -> String {
    issues
        .iter()
        .map(Issue::to_string)
        .collect::<Vec<_>>()
        .join("; ")
}

/// Sections that describe the simulated world, not the robot: a robot's own configuration
/// (`ratf run`) refuses them, so a simulator key is never silently taken for a setting.
/// `[motor]` is the robot's identified motor model (the simulator draws its truth around
/// it), so it is a robot section.
pub const SIMULATOR_SECTIONS: [&str; 2] = ["sim", "traction"];

impl Config {
    /// This configuration with the simulated world drawn from `world` (`[sim] world`): the
    /// tests that pin the ideal world's exact geometry say so with it.
    pub fn in_world(mut self, world: WorldProfile) -> Self {
        self.sim.world = world;
        self
    }

    /// Parse a robot's configuration: as [`Config::from_toml_str`], and any simulator
    /// section ([`SIMULATOR_SECTIONS`]) is an error naming it.
    pub fn robot_from_toml_str(text: &str) -> Result<Self, ConfigError> {
        let table: toml::Table =
            toml::from_str(text).map_err(|error| ConfigError::Parse { path: None, error })?;
        let issues: Vec<Issue> = SIMULATOR_SECTIONS
            .iter()
            .filter(|section| table.contains_key(**section))
            .map(|section| Issue {
                key: (*section).to_owned(),
                value: None,
                reason: "a simulator section: the robot's configuration does not take it \
                         (keep it in the file given to `ratf sim`)"
                    .to_owned(),
            })
            .collect();
        if !issues.is_empty() {
            return Err(ConfigError::Invalid { path: None, issues });
        }
        Self::from_toml_str(text)
    }

    /// Read a robot's configuration file ([`Config::robot_from_toml_str`]).
    pub fn load_robot(path: &Path) -> Result<Self, ConfigError> {
        Self::load_with(path, Self::robot_from_toml_str)
    }

    /// Parse TOML text and validate it.
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        let config: Self =
            toml::from_str(text).map_err(|error| ConfigError::Parse { path: None, error })?;
        config.validate()?;
        Ok(config)
    }

    /// Read, parse and validate a TOML file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        Self::load_with(path, Self::from_toml_str)
    }

    fn load_with(
        path: &Path,
        parse: impl FnOnce(&str) -> Result<Self, ConfigError>,
    ) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|error| ConfigError::Read {
            path: path.to_owned(),
            error,
        })?;
        parse(&text).map_err(|e| match e {
            ConfigError::Parse { error, .. } => ConfigError::Parse {
                path: Some(path.to_owned()),
                error,
            },
            ConfigError::Invalid { issues, .. } => ConfigError::Invalid {
                path: Some(path.to_owned()),
                issues,
            },
            other => other,
        })
    }

    /// This configuration as TOML text (all keys).
    pub fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(self)
    }

    /// Every issue in the configuration, empty when it is usable.
    pub fn issues(&self) -> Vec<Issue> {
        let mut issues = Vec::new();
        self.robot.check(&mut Checker::new("robot", &mut issues));
        self.motor.check(&mut Checker::new("motor", &mut issues));
        self.traction
            .check(&mut Checker::new("traction", &mut issues));
        self.mega.check(&mut Checker::new("mega", &mut issues));
        self.lidar.check(&mut Checker::new("lidar", &mut issues));
        self.link.check(&mut Checker::new("link", &mut issues));
        self.referee
            .check(&mut Checker::new("referee", &mut issues));
        self.sim.check(
            &mut Checker::new("sim", &mut issues),
            self.mega.control_period_us,
        );
        self.localisation
            .check(&mut Checker::new("localisation", &mut issues));
        self.navigation
            .check(&mut Checker::new("navigation", &mut issues));
        self.competition
            .check(&mut Checker::new("competition", &mut issues));
        self.mission
            .check(&mut Checker::new("mission", &mut issues));
        self.field.check(&mut Checker::new("field", &mut issues));
        links::check(self, &mut issues);
        cross::check(self, &mut issues);
        issues
    }

    /// `Ok` when every value is usable; otherwise all the bad keys with their reasons.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let issues = self.issues();
        if issues.is_empty() {
            Ok(())
        } else {
            Err(ConfigError::Invalid { path: None, issues })
        }
    }

    /// The Mega's configuration (the protocol's `McuConfig`), from `[mega]` plus
    /// `robot.ticks_per_wheel_rev` and `motor.battery_voltage_v`.
    pub fn mcu_config(&self) -> ratf_protocol::mcu::McuConfig {
        self.mega
            .to_mcu_config(self.robot.ticks_per_wheel_rev, self.motor.battery_voltage_v)
    }
}

#[cfg(test)]
mod bounds_tests;

#[cfg(test)]
mod tests {
    use super::*;

    fn keys_of(text: &str) -> Vec<String> {
        match Config::from_toml_str(text) {
            Err(ConfigError::Invalid { issues, .. }) => issues.into_iter().map(|i| i.key).collect(),
            other => panic!("expected Invalid, got {other:?}"),
        }
    }

    #[test]
    fn default_is_valid_and_round_trips_through_toml() {
        let d = Config::default();
        assert!(d.issues().is_empty(), "{:?}", d.issues());
        let text = d.to_toml_string().unwrap();
        assert!(text.contains("[robot.imu]") && text.contains("wheel_diameter_m = 0.06"));
        assert_eq!(Config::from_toml_str(&text).unwrap(), d);
    }

    #[test]
    fn a_robot_configuration_refuses_simulator_sections() {
        let text = "[robot]\nwheel_diameter_m = 0.065\n[sim]\nseed = 7\n[traction]\n";
        match Config::robot_from_toml_str(text) {
            Err(ConfigError::Invalid { issues, .. }) => {
                let keys: Vec<&str> = issues.iter().map(|i| i.key.as_str()).collect();
                assert_eq!(keys, ["sim", "traction"]);
            }
            other => panic!("expected Invalid, got {other:?}"),
        }
        // The same file is fine for the simulator, and a robot file without them is too.
        assert!(Config::from_toml_str(text).is_ok());
        let robot = Config::robot_from_toml_str("[robot]\nwheel_diameter_m = 0.065\n").unwrap();
        assert_eq!(robot.robot.wheel_diameter_m, 0.065);
    }

    #[test]
    fn beacons_measured_on_the_day_reach_the_robots_field() {
        let c = Config::from_toml_str(
            "[field]\nbeacons_m = [[0.9, 0.54], [-0.888, 0.538], [-0.888, -0.538], [0.888, -0.538]]\n",
        )
        .unwrap();
        let field = c.field.field();
        assert_eq!(field.beacons()[0].circle.center.x, 0.9);
        assert_eq!(field.beacons()[1].circle.center.x, -0.888);
        assert_eq!(
            keys_of("[field]\nbeacons_m = [[0.0, 0.0], [0.0, 0.1], [1.0, 1.0], [-1.0, -1.0]]\n"),
            ["field.beacons_m"]
        );
        assert_eq!(
            keys_of("[robot.imu]\ngyro_range_dps = 300\n"),
            ["robot.imu.gyro_range_dps"]
        );
    }

    #[test]
    fn the_lidar_calibration_undoes_the_range_error_and_is_bounded() {
        let c = Config::from_toml_str("[lidar]\nrange_scale = 1.012\nrange_offset_m = -0.008\n")
            .unwrap();
        let true_m = 1.3;
        let read_m = 1.012 * true_m - 0.008;
        assert!((c.lidar.corrected_range_m(read_m) - true_m).abs() < 1e-12);
        assert_eq!(
            keys_of("[lidar]\nrange_scale = 1.5\nrange_offset_m = 0.2\n"),
            ["lidar.range_scale", "lidar.range_offset_m"]
        );
    }

    #[test]
    fn partial_file_keeps_other_defaults() {
        let c =
            Config::from_toml_str("[robot]\nwheel_diameter_m = 0.065\n[sim]\nseed = 7\n").unwrap();
        assert_eq!(c.robot.wheel_diameter_m, 0.065);
        assert_eq!(c.sim.seed, 7);
        assert_eq!(c.robot.front_back_wheel_distance_m, 0.152);
        assert_eq!(c.referee, RefereeConfig::default());
        assert_eq!(Config::from_toml_str("").unwrap(), Config::default());
    }

    #[test]
    fn unknown_key_and_bad_syntax_report_the_location() {
        let e = Config::from_toml_str("[robot]\nwheel_diameter = 0.06\n").unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("wheel_diameter") && msg.contains("line 2"),
            "{msg}"
        );
        let e = Config::from_toml_str("[robot\n").unwrap_err();
        assert!(
            matches!(e, ConfigError::Parse { .. }) && e.to_string().contains("line 1"),
            "{e}"
        );
        let e = Config::from_toml_str("[mega]\ncontrol_period_us = -5\n").unwrap_err();
        assert!(e.to_string().contains("control_period_us"), "{e}");
    }

    #[test]
    fn bad_values_name_their_full_key() {
        assert_eq!(
            keys_of("[robot]\nwheel_diameter_m = -0.06"),
            ["robot.wheel_diameter_m"]
        );
        assert_eq!(
            keys_of("[robot]\nlidar_yaw_deg = 400.0"),
            ["robot.lidar_yaw_deg"]
        );
        assert_eq!(
            keys_of("[robot]\nwheel_forward_sign = [1, 0, 1, -1]"),
            ["robot.wheel_forward_sign[1]"]
        );
        assert_eq!(
            keys_of("[robot.imu]\ngyro_range_dps = 0"),
            ["robot.imu.gyro_range_dps"]
        );
        assert_eq!(
            keys_of("[lidar]\nrange_noise_std_m = -0.1"),
            ["lidar.range_noise_std_m"]
        );
        assert_eq!(keys_of("[lidar]\nmax_range_m = 0.1"), ["lidar.max_range_m"]);
        assert_eq!(
            keys_of("[mega]\ncontrol_period_us = 0"),
            ["mega.control_period_us"]
        );
        assert_eq!(keys_of("[sim]\ntime_step_us = 3000"), ["sim.time_step_us"]);
        assert_eq!(
            keys_of("[motor]\ntime_constant_s = inf"),
            ["motor.time_constant_s"]
        );
        assert_eq!(
            keys_of("[referee]\nserver_port = 0"),
            ["referee.server_port"]
        );
        assert_eq!(
            keys_of("[robot]\nbody_center_y_m = 0.06"),
            ["robot.body_center_y_m"]
        );
        // The lidar stands within the body wherever the body stands.
        assert_eq!(
            keys_of("[robot]\nbody_center_x_m = -0.05\nlidar_x_m = 0.11"),
            ["robot.lidar_x_m"]
        );
        assert!(Config::from_toml_str("[robot]\nbody_center_x_m = 0.05\nlidar_x_m = 0.19").is_ok());
        let both = keys_of("[traction]\nrobot_mass_kg = 0.0\n[link]\nmega_port = ' '");
        assert_eq!(both, ["traction.robot_mass_kg", "link.mega_port"]);
        let e = Config::from_toml_str("[robot]\nwheel_diameter_m = 0.0").unwrap_err();
        assert!(
            e.to_string()
                .contains("robot.wheel_diameter_m = 0: must be within 0.01 … 0.3 m ("),
            "{e}"
        );
    }

    #[test]
    fn the_pick_standoff_follows_the_front_face() {
        let mut robot = RobotConfig::default();
        assert_eq!(robot.pick_standoff_m(), crate::field::PICK_STANDOFF_M);
        robot.footprint_length_m = 0.31;
        robot.body_center_x_m = 0.012;
        // The front face 0.167 m out, the magnet 15 mm beyond it.
        assert!((robot.front_face_m() - 0.167).abs() < 1e-12);
        assert!((robot.pick_standoff_m() - 0.182).abs() < 1e-12);
        let field = robot.field();
        let slot = field.incoming_slot(0).unwrap();
        let standoff = slot.pick_pose.position().distance(slot.plate_face_center);
        assert!((standoff - 0.182).abs() < 1e-12, "{standoff}");
    }

    #[test]
    fn mcu_config_matches_the_protocol_defaults() {
        assert_eq!(
            Config::default().mcu_config(),
            ratf_protocol::mcu::McuConfig::default()
        );
        let mut c = Config::default();
        c.mega.control_period_us = 10_000;
        c.robot.ticks_per_wheel_rev = 2796.8;
        let m = c.mcu_config();
        assert_eq!(
            (m.control_period_us, m.ticks_per_wheel_rev),
            (10_000, 2796.8)
        );
    }

    #[test]
    fn load_reports_missing_file_and_path() {
        let missing = Path::new("/nonexistent/ratf.toml");
        let e = Config::load(missing).unwrap_err();
        assert!(
            matches!(e, ConfigError::Read { .. })
                && e.to_string().contains("/nonexistent/ratf.toml")
        );
        let dir = std::env::temp_dir().join(format!("ratf-config-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("bad.toml");
        std::fs::write(&file, "[sim]\ntime_step_us = 0\n").unwrap();
        let e = Config::load(&file).unwrap_err();
        let msg = e.to_string();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(
            msg.contains("bad.toml") && msg.contains("sim.time_step_us"),
            "{msg}"
        );
    }
}
