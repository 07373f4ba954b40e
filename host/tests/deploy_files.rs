//! The deployment files in `host/deploy/` (the example robot configuration, the udev rules,
//! the systemd unit) against the code and against each other, so none of them can drift:
//! a renamed or re-bounded configuration key, or a device name changed in one file only,
//! fails here instead of on the robot.

use std::path::{Path, PathBuf};

use ratf_core::config::{Config, ImuDevice};

/// A file of `host/deploy/`.
fn deploy_file(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("deploy")
        .join(name)
}

/// The text of a file of `host/deploy/`.
fn read_deploy_file(name: &str) -> String {
    let path = deploy_file(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `host/deploy/robot.toml` loads with the loader `ratf run` uses (a robot's configuration:
/// every key known and within its bounds, no simulator section) and sets what a team sets on
/// the robot to something other than the desk defaults.
#[test]
fn the_example_robot_config_is_a_valid_robot_config() {
    let config = Config::load_robot(&deploy_file("robot.toml")).unwrap_or_else(|e| panic!("{e}"));
    let defaults = Config::default();
    assert_eq!(config.link.mega_port, "/dev/ratf-mega");
    assert_eq!(config.link.lidar_port, "/dev/ratf-lidar");
    assert_eq!(config.link.imu, ImuDevice::Mpu9255);
    assert_eq!(config.robot.imu.i2c_device, "/dev/i2c-1");
    assert_eq!(config.robot.imu.i2c_address, 0x68);
    assert_ne!(
        config.referee.server_address,
        defaults.referee.server_address
    );
    // Everything the file does not set stays the competition robot's default.
    assert_eq!(config.mega, defaults.mega);
    assert_eq!(config.localisation, defaults.localisation);
    assert_eq!(config.navigation, defaults.navigation);
}

/// The values of every `KEY+="VALUE"` or `KEY="VALUE"` assignment of `key` in udev rules
/// text, comments skipped.
fn udev_assignments(rules: &str, key: &str) -> Vec<String> {
    let needle = format!("{key}=\"");
    rules
        .lines()
        .filter(|line| !line.trim_start().starts_with('#'))
        .flat_map(|line| line.split(", "))
        .filter_map(|field| {
            let value = field
                .strip_prefix(&needle)
                .or_else(|| field.strip_prefix(&format!("{key}+=\"")))?;
            value.strip_suffix('"').map(str::to_owned)
        })
        .collect()
}

/// The udev rules give exactly the names the example configuration opens, in the group the
/// unit's user is in; the unit waits for those devices and runs `ratf run` on the installed
/// configuration, with no automatic restart.
#[test]
fn the_udev_rules_and_the_unit_name_the_ports_the_example_config_opens() {
    let config = Config::load_robot(&deploy_file("robot.toml")).unwrap_or_else(|e| panic!("{e}"));
    let rules = read_deploy_file("99-ratf.rules");
    let mut symlinks = udev_assignments(&rules, "SYMLINK");
    symlinks.sort();
    symlinks.dedup();
    let mut ports: Vec<String> = [&config.link.mega_port, &config.link.lidar_port]
        .iter()
        .map(|port| port.trim_start_matches("/dev/").to_owned())
        .collect();
    ports.sort();
    assert_eq!(
        symlinks, ports,
        "99-ratf.rules SYMLINK against robot.toml [link]"
    );
    let groups = udev_assignments(&rules, "GROUP");
    assert_eq!(groups.len(), 3, "one GROUP per rule: {groups:?}");
    assert!(groups.iter().all(|g| g == "dialout"), "{groups:?}");

    let unit = read_deploy_file("ratf.service");
    let line = |key: &str| {
        unit.lines()
            .find_map(|l| l.strip_prefix(&format!("{key}=")))
            .unwrap_or_else(|| panic!("ratf.service has no {key}="))
            .to_owned()
    };
    for port in &ports {
        let device_unit = format!("dev-{}.device", port.replace('-', "\\x2d"));
        assert!(
            line("Wants").contains(&device_unit),
            "Wants= lacks {device_unit}"
        );
        assert!(
            line("After").contains(&device_unit),
            "After= lacks {device_unit}"
        );
    }
    assert!(
        line("ExecStart").ends_with("ratf run --config /etc/ratf/robot.toml --status-hz 1"),
        "{}",
        line("ExecStart")
    );
    assert!(
        line("SupplementaryGroups")
            .split(' ')
            .any(|g| g == "dialout")
    );
    assert_eq!(line("Restart"), "no");
    assert_eq!(line("KillSignal"), "SIGTERM");
    assert_eq!(line("SuccessExitStatus"), "130");
}
