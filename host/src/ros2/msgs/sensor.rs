//! `sensor_msgs`: the lidar's scan and the IMU's sample.

use serde::{Deserialize, Serialize};

use super::geometry::{Quaternion, Vector3};
use super::{Header, RosMessage};

/// `sensor_msgs/msg/LaserScan`: ranges at `angle_min + i·angle_increment`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LaserScan {
    /// Acquisition time of the first ray; the lidar's frame.
    pub header: Header,
    /// Angle of the first ray, rad.
    pub angle_min: f32,
    /// Angle of the last ray, rad.
    pub angle_max: f32,
    /// Angle between rays, rad (negative for a clockwise sweep).
    pub angle_increment: f32,
    /// Time between rays, s.
    pub time_increment: f32,
    /// Time between scans, s.
    pub scan_time: f32,
    /// Shortest valid range, m.
    pub range_min: f32,
    /// Longest valid range, m.
    pub range_max: f32,
    /// Ranges, m (+∞: no return on that ray, REP 117).
    pub ranges: Vec<f32>,
    /// Intensities (the X4 reports none: empty).
    pub intensities: Vec<f32>,
}

impl RosMessage for LaserScan {
    const TYPE_NAME: &'static str = "sensor_msgs/msg/LaserScan";
}

/// `sensor_msgs/msg/Imu`: covariances row-major; `orientation_covariance[0] = -1` says
/// there is no orientation (REP 145).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Read time; the IMU's frame.
    pub header: Header,
    /// Orientation (none: see the covariance).
    pub orientation: Quaternion,
    /// Its covariance.
    pub orientation_covariance: [f64; 9],
    /// Angular rate, rad/s.
    pub angular_velocity: Vector3,
    /// Its covariance, (rad/s)².
    pub angular_velocity_covariance: [f64; 9],
    /// Specific force, m/s².
    pub linear_acceleration: Vector3,
    /// Its covariance (0: unknown).
    pub linear_acceleration_covariance: [f64; 9],
}

impl RosMessage for Imu {
    const TYPE_NAME: &'static str = "sensor_msgs/msg/Imu";
}

#[cfg(test)]
mod tests {
    use super::super::{Time, hex, to_cdr};
    use super::*;

    #[test]
    fn a_scan_has_seven_floats_then_two_counted_float_sequences() {
        let scan = LaserScan {
            header: Header::new(Time { sec: 2, nanosec: 0 }, "laser"),
            angle_min: 1.0,
            angle_max: -1.0,
            angle_increment: -1.0,
            time_increment: 0.5,
            scan_time: 0.25,
            range_min: 0.125,
            range_max: 8.0,
            ranges: vec![1.5, f32::INFINITY, 2.0],
            intensities: vec![],
        };
        // Header: 8 + 4 + "laser\0" (6) = 18, pad to 20.
        let expected = concat!(
            "00010000",
            "02000000",
            "00000000",
            "06000000",
            "6c6173657200",
            "0000",
            "0000803f",
            "000080bf",
            "000080bf",
            "0000003f",
            "0000803e",
            "0000003e",
            "00000041",
            "03000000",
            "0000c03f",
            "0000807f",
            "00000040",
            "00000000",
        );
        assert_eq!(hex(&to_cdr(&scan).unwrap()), expected);
    }

    #[test]
    fn an_imu_sample_has_fixed_arrays_without_lengths() {
        let imu = Imu {
            header: Header::new(Time::default(), "imu"),
            orientation: Quaternion::default(),
            orientation_covariance: [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            angular_velocity: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 2.0,
            },
            angular_velocity_covariance: [0.0; 9],
            linear_acceleration: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 9.5,
            },
            linear_acceleration_covariance: [0.0; 9],
        };
        let bytes = to_cdr(&imu).unwrap();
        // Header 8 + 4 + 4 = 16 (aligned), then 4 + 9 + 3 + 9 + 3 + 9 doubles.
        assert_eq!(bytes.len(), 4 + 16 + 37 * 8);
        assert_eq!(hex(&bytes[4..20]), "000000000000000004000000696d7500");
        let doubles: Vec<f64> = bytes[20..]
            .chunks(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(doubles[..5], [0.0, 0.0, 0.0, 1.0, -1.0]);
        assert_eq!(doubles[15], 2.0);
        assert_eq!(doubles[27], 9.5);
    }
}
