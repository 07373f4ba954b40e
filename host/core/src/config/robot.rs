//! `[robot]`: geometry, wheel conventions, encoders, sensor mounts.

use serde::{Deserialize, Serialize};

use super::check::Checker;

/// The robot's geometry and sensor mounts. Defaults: the 5dpo competition robot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotConfig {
    /// Distance between the front and back axles, m. 0.152: original
    /// `sdpo_ros_odom.yaml` `rob_dist_between_front_back_wh` (original-system.md §1.3).
    pub front_back_wheel_distance_m: f64,
    /// Distance between the left and right wheel contact points, m. 0.193: original
    /// `rob_dist_between_left_right_wh` (§1.3).
    pub left_right_wheel_distance_m: f64,
    /// Wheel diameter, m. 0.060: original (§1.3, §2.2), all four wheels.
    pub wheel_diameter_m: f64,
    /// Body length along the robot's x (forward), m. 0.30: the competition's 30 × 30 cm
    /// robot (paper §III).
    pub footprint_length_m: f64,
    /// Body width along the robot's y (left), m. 0.30 (paper §III).
    pub footprint_width_m: f64,
    /// Per wheel (motor index 0 back-right, 1 back-left, 2 front-right, 3 front-left): the
    /// sign of the wheel speed on the wire that rolls that wheel forward (+x).
    /// [+1, −1, +1, −1]: derived from the original's `inv = true` and its kinematics
    /// (original-system.md §4.2: forward gives w_ref = −2·rim/D with rim FL = +v, FR = −v,
    /// BL = +v, BR = −v) and confirmed by the motor data's sign patterns. Physically: a
    /// positive wire speed turns every wheel clockwise seen from outside the robot.
    pub wheel_forward_sign: [i8; 4],
    /// Largest wheel speed the planner may ask for, wheel rad/s. 24.3: the DFRobot motor's
    /// 251 rpm no-load at 12 V (paper §III) = 26.3 rad/s, i.e. 2.19 (rad/s)/V, times the
    /// 11.1 V battery. No-load: under load and with the PI's headroom less is reached.
    pub max_wheel_speed_rad_s: f64,
    /// Encoder ticks per wheel revolution. 2803.2 = 16 counts × 4 (quadrature) × 43.8
    /// (gearbox), original `robotconfig.h` (§2.2); the paper's 2796.8 uses 43.7.
    pub ticks_per_wheel_rev: f64,
    /// Lidar origin along the robot's x, m. 0.07: original `laser_pose_x` (§1.3).
    pub lidar_x_m: f64,
    /// Lidar origin along the robot's y, m. 0: original `laser_pose_y` (§1.3).
    pub lidar_y_m: f64,
    /// Lidar yaw in the robot frame, degrees (its 0° ray's direction). 172: original
    /// `laser_pose_yaw` (§1.3). Must be within ±360.
    pub lidar_yaw_deg: f64,
    /// Height of the lidar's scan plane above the floor, m. 0.20: assumption (the original
    /// sets z = 0; the plane must clear the 0.13 m walls to see only the beacons).
    pub lidar_height_m: f64,
    /// The IMU.
    pub imu: ImuConfig,
}

impl Default for RobotConfig {
    fn default() -> Self {
        Self {
            front_back_wheel_distance_m: 0.152,
            left_right_wheel_distance_m: 0.193,
            wheel_diameter_m: 0.060,
            footprint_length_m: 0.30,
            footprint_width_m: 0.30,
            wheel_forward_sign: [1, -1, 1, -1],
            max_wheel_speed_rad_s: 24.3,
            ticks_per_wheel_rev: 2803.2,
            lidar_x_m: 0.07,
            lidar_y_m: 0.0,
            lidar_yaw_deg: 172.0,
            lidar_height_m: 0.20,
            imu: ImuConfig::default(),
        }
    }
}

/// `[robot.imu]`: the MPU9255 on a Waveshare 10-DOF (B) board (original-system.md §3.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImuConfig {
    /// I2C bus device on the Pi. `/dev/i2c-1`: the Pi's header bus (assumption; the
    /// original used wiringPi's default).
    pub i2c_device: String,
    /// MPU9255 I2C address, 7-bit. 0x68 = 104 (AD0 low): original (§3.3). The driver talks
    /// to this address; the simulated chip answers at 0x68 only.
    pub i2c_address: u8,
    /// Gyro full scale the driver configures, °/s: 250, 500, 1000 or 2000. 500: a turn on
    /// the spot peaks near 5 rad/s = 290 °/s at the wheel limit, beyond ±250; ±500 keeps
    /// 0.015 °/s resolution (65.5 LSB per °/s).
    pub gyro_range_dps: u16,
    /// Yaw of the IMU's x axis in the robot frame, degrees: the device turns each sample
    /// into the robot's axes (x forward, y left, z up) before the core sees it. 0:
    /// assumption (the original's static tf is not documented).
    pub yaw_deg: f64,
    /// Gyro z noise density, rad/s/√Hz. 1.75e-4 (0.01 °/s/√Hz): MPU-9250 datasheet typical.
    pub gyro_noise_density_rad_s_sqrt_hz: f64,
}

impl Default for ImuConfig {
    fn default() -> Self {
        Self {
            i2c_device: "/dev/i2c-1".to_owned(),
            i2c_address: 0x68,
            gyro_range_dps: 500,
            yaw_deg: 0.0,
            gyro_noise_density_rad_s_sqrt_hz: 1.75e-4,
        }
    }
}

impl ImuConfig {
    /// The gyro full scale of `gyro_range_dps`, if it is one the chip has.
    pub fn gyro_range(&self) -> Option<crate::drivers::imu::registers::GyroRange> {
        use crate::drivers::imu::registers::GyroRange;
        match self.gyro_range_dps {
            250 => Some(GyroRange::Dps250),
            500 => Some(GyroRange::Dps500),
            1000 => Some(GyroRange::Dps1000),
            2000 => Some(GyroRange::Dps2000),
            _ => None,
        }
    }

    /// The driver's settings: this address and gyro range, the driver's other defaults.
    pub fn driver_config(&self) -> crate::drivers::imu::ImuConfig {
        let defaults = crate::drivers::imu::ImuConfig::default();
        crate::drivers::imu::ImuConfig {
            address: self.i2c_address,
            gyro_range: self.gyro_range().unwrap_or(defaults.gyro_range),
            ..defaults
        }
    }
}

impl RobotConfig {
    /// Half the front-back distance plus half the left-right distance, m (lx + ly of the
    /// mecanum equations; 0.1725 for the defaults).
    pub fn half_wheelbase_sum_m(&self) -> f64 {
        (self.front_back_wheel_distance_m + self.left_right_wheel_distance_m) / 2.0
    }

    /// Wheel radius, m.
    pub fn wheel_radius_m(&self) -> f64 {
        self.wheel_diameter_m / 2.0
    }

    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        c.positive(
            "front_back_wheel_distance_m",
            self.front_back_wheel_distance_m,
        );
        c.positive(
            "left_right_wheel_distance_m",
            self.left_right_wheel_distance_m,
        );
        c.positive("wheel_diameter_m", self.wheel_diameter_m);
        c.positive("footprint_length_m", self.footprint_length_m);
        c.positive("footprint_width_m", self.footprint_width_m);
        for (i, s) in self.wheel_forward_sign.iter().enumerate() {
            c.require(&format!("wheel_forward_sign[{i}]"), s.abs() == 1, || {
                format!("must be +1 or -1 (got {s})")
            });
        }
        c.positive("max_wheel_speed_rad_s", self.max_wheel_speed_rad_s);
        c.positive("ticks_per_wheel_rev", self.ticks_per_wheel_rev);
        c.finite("lidar_x_m", self.lidar_x_m);
        c.finite("lidar_y_m", self.lidar_y_m);
        c.within("lidar_yaw_deg", self.lidar_yaw_deg, -360.0, 360.0);
        c.positive("lidar_height_m", self.lidar_height_m);
        c.non_empty("imu.i2c_device", &self.imu.i2c_device);
        c.require("imu.i2c_address", self.imu.i2c_address < 0x80, || {
            format!("must be a 7-bit address (got {})", self.imu.i2c_address)
        });
        c.require(
            "imu.gyro_range_dps",
            self.imu.gyro_range().is_some(),
            || {
                format!(
                    "must be 250, 500, 1000 or 2000 (got {})",
                    self.imu.gyro_range_dps
                )
            },
        );
        c.within("imu.yaw_deg", self.imu.yaw_deg, -360.0, 360.0);
        c.non_negative(
            "imu.gyro_noise_density_rad_s_sqrt_hz",
            self.imu.gyro_noise_density_rad_s_sqrt_hz,
        );
    }
}
