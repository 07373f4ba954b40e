//! The `ros2msg` definition text of a message type, built as rosbag2 (Jazzy,
//! `LocalMessageDefinitionSource::get_full_text`) builds it for an MCAP schema: the type's
//! `.msg` text, then for each dependency not yet written, in the sorted order of each
//! file's dependency set, depth first, a line of 80 `=`, `MSG: package/Name`, and that
//! type's text. Foxglove, `ros2 bag` and `mcap-ros2-support` decode messages by this text.

use std::collections::BTreeSet;

/// Every `.msg` file the messages here need, by `package/Name`.
const DEFINITIONS: &[(&str, &str)] = &[
    (
        "builtin_interfaces/Duration",
        include_str!("defs/builtin_interfaces/Duration.msg"),
    ),
    (
        "builtin_interfaces/Time",
        include_str!("defs/builtin_interfaces/Time.msg"),
    ),
    (
        "diagnostic_msgs/DiagnosticArray",
        include_str!("defs/diagnostic_msgs/DiagnosticArray.msg"),
    ),
    (
        "diagnostic_msgs/DiagnosticStatus",
        include_str!("defs/diagnostic_msgs/DiagnosticStatus.msg"),
    ),
    (
        "diagnostic_msgs/KeyValue",
        include_str!("defs/diagnostic_msgs/KeyValue.msg"),
    ),
    (
        "geometry_msgs/Point",
        include_str!("defs/geometry_msgs/Point.msg"),
    ),
    (
        "geometry_msgs/Pose",
        include_str!("defs/geometry_msgs/Pose.msg"),
    ),
    (
        "geometry_msgs/PoseStamped",
        include_str!("defs/geometry_msgs/PoseStamped.msg"),
    ),
    (
        "geometry_msgs/PoseWithCovariance",
        include_str!("defs/geometry_msgs/PoseWithCovariance.msg"),
    ),
    (
        "geometry_msgs/PoseWithCovarianceStamped",
        include_str!("defs/geometry_msgs/PoseWithCovarianceStamped.msg"),
    ),
    (
        "geometry_msgs/Quaternion",
        include_str!("defs/geometry_msgs/Quaternion.msg"),
    ),
    (
        "geometry_msgs/Transform",
        include_str!("defs/geometry_msgs/Transform.msg"),
    ),
    (
        "geometry_msgs/TransformStamped",
        include_str!("defs/geometry_msgs/TransformStamped.msg"),
    ),
    (
        "geometry_msgs/Twist",
        include_str!("defs/geometry_msgs/Twist.msg"),
    ),
    (
        "geometry_msgs/TwistWithCovariance",
        include_str!("defs/geometry_msgs/TwistWithCovariance.msg"),
    ),
    (
        "geometry_msgs/Vector3",
        include_str!("defs/geometry_msgs/Vector3.msg"),
    ),
    (
        "nav_msgs/Odometry",
        include_str!("defs/nav_msgs/Odometry.msg"),
    ),
    (
        "sensor_msgs/CompressedImage",
        include_str!("defs/sensor_msgs/CompressedImage.msg"),
    ),
    ("sensor_msgs/Imu", include_str!("defs/sensor_msgs/Imu.msg")),
    (
        "sensor_msgs/LaserScan",
        include_str!("defs/sensor_msgs/LaserScan.msg"),
    ),
    (
        "std_msgs/ColorRGBA",
        include_str!("defs/std_msgs/ColorRGBA.msg"),
    ),
    ("std_msgs/Header", include_str!("defs/std_msgs/Header.msg")),
    (
        "tf2_msgs/TFMessage",
        include_str!("defs/tf2_msgs/TFMessage.msg"),
    ),
    (
        "visualization_msgs/Marker",
        include_str!("defs/visualization_msgs/Marker.msg"),
    ),
    (
        "visualization_msgs/MarkerArray",
        include_str!("defs/visualization_msgs/MarkerArray.msg"),
    ),
    (
        "visualization_msgs/MeshFile",
        include_str!("defs/visualization_msgs/MeshFile.msg"),
    ),
    (
        "visualization_msgs/UVCoordinate",
        include_str!("defs/visualization_msgs/UVCoordinate.msg"),
    ),
];

/// The separator rosbag2 writes before each dependency.
const SEPARATOR: &str =
    "================================================================================\n";

/// Field types that are not messages.
const PRIMITIVES: &[&str] = &[
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
    "uint32", "int64", "uint64", "string",
];

/// The `.msg` text of `package/Name` (or `package/msg/Name`), if it is one of ours.
pub fn msg_text(type_name: &str) -> Option<&'static str> {
    let short = short_name(type_name);
    DEFINITIONS
        .iter()
        .find(|(name, _)| *name == short)
        .map(|(_, text)| *text)
}

/// `package/msg/Name` → `package/Name`.
fn short_name(type_name: &str) -> String {
    type_name.replacen("/msg/", "/", 1)
}

/// The full definition text of `type_name` (`package/msg/Name`), or `None` when it or
/// one of its dependencies is not among ours.
pub fn full_text(type_name: &str) -> Option<String> {
    let mut seen = BTreeSet::new();
    append(&short_name(type_name), &mut seen, 16)
}

fn append(type_name: &str, seen: &mut BTreeSet<String>, depth: u32) -> Option<String> {
    if depth == 0 {
        return None;
    }
    let text = msg_text(type_name)?;
    let package = type_name.split('/').next().unwrap_or_default();
    let mut result = text.to_owned();
    for dependency in dependencies(text, package) {
        if seen.insert(dependency.clone()) {
            result.push('\n');
            result.push_str(SEPARATOR);
            result.push_str("MSG: ");
            result.push_str(&dependency);
            result.push('\n');
            result.push_str(&append(&dependency, seen, depth - 1)?);
        }
    }
    Some(result)
}

/// The message types a `.msg` text's fields use, sorted (rosbag2's regex
/// `(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+`, line by line).
fn dependencies(text: &str, package: &str) -> BTreeSet<String> {
    let is_name = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '/';
    let mut found = BTreeSet::new();
    for line in text.lines() {
        let line = line.trim_start();
        let end = line.find(|c: char| !is_name(c)).unwrap_or(line.len());
        let (name, mut rest) = line.split_at(end);
        if name.is_empty() || PRIMITIVES.contains(&name) {
            continue;
        }
        if let Some(array) = rest.strip_prefix('[') {
            let Some(close) = array.find(']') else {
                continue;
            };
            rest = &array[close + 1..];
        }
        if !rest.starts_with(char::is_whitespace) {
            continue;
        }
        found.insert(if name.contains('/') {
            name.to_owned()
        } else {
            format!("{package}/{name}")
        });
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_laser_scan_embeds_its_header_and_time_after_separators() {
        let text = full_text("sensor_msgs/msg/LaserScan").unwrap();
        let scan = msg_text("sensor_msgs/LaserScan").unwrap();
        let expected = format!(
            "{scan}\n{SEPARATOR}MSG: std_msgs/Header\n{}\n{SEPARATOR}MSG: builtin_interfaces/Time\n{}",
            msg_text("std_msgs/Header").unwrap(),
            msg_text("builtin_interfaces/Time").unwrap()
        );
        assert_eq!(text, expected);
    }

    #[test]
    fn dependencies_are_package_relative_sorted_and_skip_comments_and_constants() {
        let deps = dependencies(
            "# Pose pose\nint32 A=1\n  Point[] points\nstd_msgs/Header header\nfloat64[36] c\n",
            "geometry_msgs",
        );
        assert_eq!(
            deps.into_iter().collect::<Vec<_>>(),
            ["geometry_msgs/Point", "std_msgs/Header"]
        );
    }

    #[test]
    fn a_marker_array_names_every_nested_type_once() {
        let text = full_text("visualization_msgs/msg/MarkerArray").unwrap();
        for name in [
            "visualization_msgs/Marker",
            "std_msgs/Header",
            "builtin_interfaces/Time",
            "builtin_interfaces/Duration",
            "geometry_msgs/Pose",
            "geometry_msgs/Point",
            "geometry_msgs/Quaternion",
            "geometry_msgs/Vector3",
            "std_msgs/ColorRGBA",
            "sensor_msgs/CompressedImage",
            "visualization_msgs/UVCoordinate",
            "visualization_msgs/MeshFile",
        ] {
            assert_eq!(
                text.matches(&format!("\nMSG: {name}\n")).count(),
                1,
                "{name}"
            );
        }
    }

    #[test]
    fn an_unknown_type_has_no_definition() {
        assert_eq!(full_text("sensor_msgs/msg/Image"), None);
    }
}
