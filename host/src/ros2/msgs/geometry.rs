//! `geometry_msgs`, `nav_msgs/Odometry` and `tf2_msgs/TFMessage`: poses, twists and
//! transforms, with the conversions from the core's planar [`Pose2`].

use serde::{Deserialize, Serialize};
use serde_big_array::BigArray;

use ratf_core::field::geometry::Pose2;

use super::{Header, RosMessage};

/// `geometry_msgs/msg/Point`, m.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Vector3`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion` (x, y, z, w).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self::from_yaw(0.0)
    }
}

impl Quaternion {
    /// A rotation of `yaw_rad` about z.
    pub fn from_yaw(yaw_rad: f64) -> Self {
        let half = 0.5 * yaw_rad;
        Self {
            x: 0.0,
            y: 0.0,
            z: half.sin(),
            w: half.cos(),
        }
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position, m.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

impl Pose {
    /// A planar pose at height `z_m`.
    pub fn planar(pose: Pose2, z_m: f64) -> Self {
        Self {
            position: Point {
                x: pose.x,
                y: pose.y,
                z: z_m,
            },
            orientation: Quaternion::from_yaw(pose.yaw_rad),
        }
    }
}

/// `geometry_msgs/msg/PoseWithCovariance`: the covariance is row-major over (x, y, z,
/// rot x, rot y, rot z).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// 6 × 6 covariance, row-major, m² / m·rad / rad².
    #[serde(with = "BigArray")]
    pub covariance: [f64; 36],
}

impl PoseWithCovariance {
    /// A planar pose with the covariance of (x, y, yaw) `p` (row-major 3 × 3) in the
    /// (x, y, rot z) entries; z, rot x and rot y are fixed by the floor (zero variance).
    pub fn planar(pose: Pose2, p: [[f64; 3]; 3]) -> Self {
        Self {
            pose: Pose::planar(pose, 0.0),
            covariance: planar_covariance(p),
        }
    }
}

/// A 3 × 3 (x, y, yaw) covariance in a ROS 6 × 6 row-major covariance.
pub fn planar_covariance(p: [[f64; 3]; 3]) -> [f64; 36] {
    const AXES: [usize; 3] = [0, 1, 5];
    let mut covariance = [0.0; 36];
    for (i, row) in AXES.iter().enumerate() {
        for (j, col) in AXES.iter().enumerate() {
            covariance[row * 6 + col] = p[i][j];
        }
    }
    covariance
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped`: the localiser's estimate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovarianceStamped {
    /// When and in which frame.
    pub header: Header,
    /// The estimate.
    pub pose: PoseWithCovariance,
}

impl RosMessage for PoseWithCovarianceStamped {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/PoseWithCovarianceStamped";
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// When and in which frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

impl RosMessage for PoseStamped {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/PoseStamped";
}

/// `geometry_msgs/msg/Twist`: linear m/s, angular rad/s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity, m/s.
    pub linear: Vector3,
    /// Angular velocity, rad/s.
    pub angular: Vector3,
}

impl RosMessage for Twist {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/Twist";
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// 6 × 6 covariance, row-major.
    #[serde(with = "BigArray")]
    pub covariance: [f64; 36],
}

/// `nav_msgs/msg/Odometry`: pose in `header.frame_id`, twist in `child_frame_id`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// When and the pose's frame (`odom`).
    pub header: Header,
    /// The twist's frame (`base_footprint`).
    pub child_frame_id: String,
    /// The pose.
    pub pose: PoseWithCovariance,
    /// The velocity.
    pub twist: TwistWithCovariance,
}

impl RosMessage for Odometry {
    const TYPE_NAME: &'static str = "nav_msgs/msg/Odometry";
}

/// `geometry_msgs/msg/Transform`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Translation, m.
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}

impl Transform {
    /// The planar transform `pose` (child in parent).
    pub fn planar(pose: Pose2, z_m: f64) -> Self {
        Self {
            translation: Vector3 {
                x: pose.x,
                y: pose.y,
                z: z_m,
            },
            rotation: Quaternion::from_yaw(pose.yaw_rad),
        }
    }
}

/// `geometry_msgs/msg/TransformStamped`: `child_frame_id` in `header.frame_id`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// When and the parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The child's pose in the parent.
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`: what `/tf` and `/tf_static` carry.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

impl RosMessage for TfMessage {
    const TYPE_NAME: &'static str = "tf2_msgs/msg/TFMessage";
}

#[cfg(test)]
mod tests {
    use super::super::{Time, hex, to_cdr};
    use super::*;

    /// Little-endian f64s as hex.
    fn f64s(values: &[f64]) -> String {
        values.iter().map(|v| hex(&v.to_le_bytes())).collect()
    }

    fn header_hex() -> String {
        // 1 s + 2 ns, "odom".
        format!("{}{}{}{}", "01000000", "02000000", "05000000", "6f646f6d00")
    }

    fn header() -> Header {
        Header::new(Time { sec: 1, nanosec: 2 }, "odom")
    }

    #[test]
    fn a_pose_stamped_aligns_its_doubles_to_eight_after_the_header() {
        let message = PoseStamped {
            header: header(),
            pose: Pose::planar(Pose2::new(1.0, -2.0, 0.0), 0.5),
        };
        // Header is 17 bytes; the first f64 is aligned to 8 (+7 padding → 24).
        let expected = format!(
            "00010000{}{}{}",
            header_hex(),
            "00000000000000",
            f64s(&[1.0, -2.0, 0.5, 0.0, 0.0, 0.0, 1.0])
        );
        assert_eq!(hex(&to_cdr(&message).unwrap()), expected);
    }

    #[test]
    fn a_pose_with_covariance_has_36_doubles_and_no_length() {
        let p = [[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [3.0, 5.0, 6.0]];
        let message = PoseWithCovarianceStamped {
            header: header(),
            pose: PoseWithCovariance::planar(Pose2::new(0.0, 0.0, 0.0), p),
        };
        let mut covariance = [0.0; 36];
        for (index, value) in [
            (0, 1.0),
            (1, 2.0),
            (5, 3.0),
            (6, 2.0),
            (7, 4.0),
            (11, 5.0),
            (30, 3.0),
            (31, 5.0),
            (35, 6.0),
        ] {
            covariance[index] = value;
        }
        let expected = format!(
            "00010000{}00000000000000{}{}",
            header_hex(),
            f64s(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
            f64s(&covariance)
        );
        let bytes = to_cdr(&message).unwrap();
        assert_eq!(bytes.len(), 4 + 24 + 7 * 8 + 36 * 8);
        assert_eq!(hex(&bytes), expected);
    }

    #[test]
    fn odometry_puts_the_child_frame_between_header_and_pose() {
        let message = Odometry {
            header: header(),
            child_frame_id: "base".into(),
            pose: PoseWithCovariance::planar(Pose2::new(0.0, 0.0, 0.0), [[0.0; 3]; 3]),
            twist: TwistWithCovariance {
                twist: Twist {
                    linear: Vector3 {
                        x: 0.25,
                        y: 0.0,
                        z: 0.0,
                    },
                    angular: Vector3 {
                        x: 0.0,
                        y: 0.0,
                        z: -1.0,
                    },
                },
                covariance: [0.0; 36],
            },
        };
        // Header 17 bytes, pad to 20, "base" string (4 + 5) → 29, pad to 32.
        let expected = format!(
            "00010000{}000000{}{}000000{}{}{}{}",
            header_hex(),
            "05000000",
            "6261736500",
            f64s(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
            f64s(&[0.0; 36]),
            f64s(&[0.25, 0.0, 0.0, 0.0, 0.0, -1.0]),
            f64s(&[0.0; 36])
        );
        assert_eq!(hex(&to_cdr(&message).unwrap()), expected);
    }

    #[test]
    fn a_tf_message_is_a_counted_sequence_of_stamped_transforms() {
        let message = TfMessage {
            transforms: vec![TransformStamped {
                header: header(),
                child_frame_id: "b".into(),
                transform: Transform::planar(Pose2::new(0.5, 0.0, 0.0), 0.0),
            }],
        };
        // count 4, header 17 → 21, pad 24, "b" (4 + 2) → 30, pad 32.
        let expected = format!(
            "00010000{}{}000000{}{}0000{}",
            "01000000",
            header_hex(),
            "02000000",
            "6200",
            f64s(&[0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
        );
        assert_eq!(hex(&to_cdr(&message).unwrap()), expected);
    }

    #[test]
    fn a_twist_is_six_doubles() {
        let message = Twist {
            linear: Vector3 {
                x: 0.1,
                y: 0.2,
                z: 0.0,
            },
            angular: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 0.3,
            },
        };
        assert_eq!(
            hex(&to_cdr(&message).unwrap()),
            format!("00010000{}", f64s(&[0.1, 0.2, 0.0, 0.0, 0.0, 0.3]))
        );
    }

    #[test]
    fn a_yaw_quaternion_is_unit_and_half_angle() {
        let q = Quaternion::from_yaw(std::f64::consts::PI);
        assert!(q.z > 0.999_999 && q.w.abs() < 1e-9);
        assert_eq!(Quaternion::default().w, 1.0);
    }
}
