//! The tf tree (REP 105): `map` (the field's world frame) → `odom` (wheel odometry's
//! frame) → `base_footprint` (the robot on the floor) → `laser`, `imu_link`.

use ratf_core::config::Config;
use ratf_core::field::geometry::Pose2;

use super::msgs::geometry::{TfMessage, Transform, TransformStamped};
use super::msgs::{Header, Time};

/// The field's world frame (origin at the floor's centre, x right).
pub const MAP: &str = "map";
/// Wheel odometry's frame (continuous, drifts).
pub const ODOM: &str = "odom";
/// The robot on the floor: x forward, y left, at the wheel-base centre.
pub const BASE: &str = "base_footprint";
/// The X4's frame (x towards its 0° mark, angles counter-clockwise).
pub const LASER: &str = "laser";
/// The IMU chip's frame.
pub const IMU: &str = "imu_link";

/// One transform `child` in `parent` at `stamp`.
pub fn transform(
    stamp: Time,
    parent: &str,
    child: &str,
    pose: Pose2,
    z_m: f64,
) -> TransformStamped {
    TransformStamped {
        header: Header::new(stamp, parent),
        child_frame_id: child.to_owned(),
        transform: Transform::planar(pose, z_m),
    }
}

/// `/tf_static`: the lidar and the IMU on the robot (`[robot] lidar_x_m`, `lidar_y_m`,
/// `lidar_yaw_deg`, `lidar_height_m`, `[robot.imu] yaw_deg`).
pub fn static_transforms(config: &Config) -> TfMessage {
    let robot = &config.robot;
    let stamp = Time::default();
    TfMessage {
        transforms: vec![
            transform(
                stamp,
                BASE,
                LASER,
                Pose2::new(
                    robot.lidar_x_m,
                    robot.lidar_y_m,
                    robot.lidar_yaw_deg.to_radians(),
                ),
                robot.lidar_height_m,
            ),
            transform(
                stamp,
                BASE,
                IMU,
                Pose2::new(0.0, 0.0, robot.imu.yaw_deg.to_radians()),
                0.0,
            ),
        ],
    }
}

/// `/tf`: `map → odom` (what the localiser corrects of the odometry) and `odom →
/// base_footprint` (the odometry), so `map → base_footprint` is the localiser's pose.
pub fn dynamic_transforms(stamp: Time, estimate: Pose2, odometry: Pose2) -> TfMessage {
    let map_to_odom = estimate.compose(odometry.inverse());
    TfMessage {
        transforms: vec![
            transform(stamp, MAP, ODOM, map_to_odom, 0.0),
            transform(stamp, ODOM, BASE, odometry, 0.0),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_to_odom_composed_with_the_odometry_is_the_estimate() {
        let estimate = Pose2::new(0.3, -0.2, 1.0);
        let odometry = Pose2::new(0.1, 0.4, -0.5);
        let tf = dynamic_transforms(Time::default(), estimate, odometry);
        let t = tf.transforms[0].transform;
        let yaw = 2.0 * t.rotation.z.atan2(t.rotation.w);
        let chained = Pose2::new(t.translation.x, t.translation.y, yaw).compose(odometry);
        assert!((chained.x - estimate.x).abs() < 1e-12);
        assert!((chained.y - estimate.y).abs() < 1e-12);
        assert!((chained.yaw_rad - estimate.yaw_rad).abs() < 1e-12);
        assert_eq!(tf.transforms[1].child_frame_id, BASE);
    }

    #[test]
    fn the_lidar_sits_where_the_config_mounts_it() {
        let config = Config::default();
        let tf = static_transforms(&config);
        let laser = &tf.transforms[0];
        assert_eq!(
            (
                laser.header.frame_id.as_str(),
                laser.child_frame_id.as_str()
            ),
            (BASE, LASER)
        );
        assert_eq!(laser.transform.translation.x, config.robot.lidar_x_m);
        assert_eq!(laser.transform.translation.z, config.robot.lidar_height_m);
    }
}
