//! `[robot]`: geometry, wheel conventions, encoders, sensor mounts.

use serde::{Deserialize, Serialize};

use super::check::Checker;
use crate::field::Field;
#[cfg(doc)]
use crate::field::PICK_STANDOFF_M;
use crate::field::stations;

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
    /// Sideways (strafe) travel over what the wheels' kinematics says: a mecanum wheel's
    /// rollers slip sideways, so a strafe falls short (about 0.93 typical, 0.85 harsh, worse
    /// on carpet: real-world-errors.md). The odometry scales its sideways travel by it. 1.0:
    /// the kinematics, for a robot not yet measured; `ratf calibrate odometry` fits it from
    /// the strafe legs of its drive and writes it.
    pub strafe_factor: f64,
    /// Body length along the robot's x (forward), m. 0.30: the competition's 30 × 30 cm
    /// robot (paper §III).
    pub footprint_length_m: f64,
    /// Body width along the robot's y (left), m. 0.30 (paper §III).
    pub footprint_width_m: f64,
    /// Where the body's centre stands ahead of the robot frame's origin (the wheels' centre),
    /// m. 0: the 5dpo robot as far as known (its outline is not documented). A team measures
    /// its own with a rule, from the axles to the front and back faces (README: Fit your
    /// robot): the robot's pick and drop poses stand its magnet on the plate from the front
    /// face ([`Self::pick_standoff_m`]), and its routes keep the faces off the walls.
    pub body_center_x_m: f64,
    /// Where the body's centre stands to the left of the wheels' centre, m. 0: as
    /// [`Self::body_center_x_m`].
    pub body_center_y_m: f64,
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
    /// The faces of the body that carry a magnet, each holding one part against its plate
    /// (so the robot carries as many parts at once as it has faces here). `["front"]`: the
    /// 5dpo robot's one electromagnet (paper §III). A back magnet too (`["front", "back"]`)
    /// is what `ratf bench bound` can already plan for (`planning::bound`); the task planner
    /// and the mission carry one part on the front face, and refuse any other list
    /// (`planning::tasks::model::TaskError::MagnetFaces`).
    pub magnet_faces: Vec<MagnetFace>,
    /// The IMU.
    pub imu: ImuConfig,
}

/// Largest distance of the body's centre from the wheels' centre, per axis, m.
const MAX_BODY_CENTER_M: f64 = 0.05;

/// A face of the robot's square body that can carry a magnet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum MagnetFace {
    /// The +x face, the way the robot drives forward.
    Front,
    /// The −x face.
    Back,
}

impl MagnetFace {
    /// The robot's heading, relative to the plate's inward normal, when this face touches
    /// the plate, rad: 0 for the front face, π for the back one.
    pub fn heading_offset_rad(self) -> f64 {
        match self {
            Self::Front => 0.0,
            Self::Back => std::f64::consts::PI,
        }
    }

    /// `faces` as the configuration writes them, e.g. `["front", "back"]`.
    pub fn list(faces: &[MagnetFace]) -> String {
        let names: Vec<String> = faces.iter().map(|face| format!("\"{face}\"")).collect();
        format!("[{}]", names.join(", "))
    }
}

impl std::fmt::Display for MagnetFace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Front => "front",
            Self::Back => "back",
        })
    }
}

impl RobotConfig {
    /// From the wheels' centre to the body's front face, m.
    pub fn front_face_m(&self) -> f64 {
        self.footprint_length_m / 2.0 + self.body_center_x_m
    }

    /// From the wheels' centre to the magnet's face, which is where a part's plate stands at
    /// a pick or drop, m: 15 mm beyond the front face ([`stations::pick_standoff_m`];
    /// [`PICK_STANDOFF_M`] on the default 30 cm centred body).
    pub fn pick_standoff_m(&self) -> f64 {
        stations::pick_standoff_m(self.front_face_m())
    }

    /// The competition floor as this robot docks on it: each slot's pick and drop pose
    /// [`Self::pick_standoff_m`] from its plate.
    pub fn field(&self) -> Field {
        Field::competition().with_pick_standoff(self.pick_standoff_m())
    }
}

impl Default for RobotConfig {
    fn default() -> Self {
        Self {
            front_back_wheel_distance_m: 0.152,
            left_right_wheel_distance_m: 0.193,
            wheel_diameter_m: 0.060,
            strafe_factor: 1.0,
            footprint_length_m: 0.30,
            footprint_width_m: 0.30,
            body_center_x_m: 0.0,
            body_center_y_m: 0.0,
            wheel_forward_sign: [1, -1, 1, -1],
            max_wheel_speed_rad_s: 24.3,
            ticks_per_wheel_rev: 2803.2,
            lidar_x_m: 0.07,
            lidar_y_m: 0.0,
            lidar_yaw_deg: 172.0,
            lidar_height_m: 0.20,
            magnet_faces: vec![MagnetFace::Front],
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
    /// The lidar's pose on the robot (x, y, m; yaw, rad from `lidar_yaw_deg`): robot frame
    /// to lidar frame.
    pub fn lidar_mount(&self) -> crate::field::geometry::Pose2 {
        crate::field::geometry::Pose2::new(
            self.lidar_x_m,
            self.lidar_y_m,
            self.lidar_yaw_deg.to_radians(),
        )
    }

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
        const BODY: &str = "inside the 30 × 30 cm robot the rules allow (competition.md §2); \
                            the mecanum equations divide by it";
        c.within(
            "front_back_wheel_distance_m",
            self.front_back_wheel_distance_m,
            0.01,
            0.30,
            "m",
            BODY,
        );
        c.within(
            "left_right_wheel_distance_m",
            self.left_right_wheel_distance_m,
            0.01,
            0.30,
            "m",
            BODY,
        );
        c.within(
            "wheel_diameter_m",
            self.wheel_diameter_m,
            0.01,
            0.30,
            "m",
            "a wheel of the 30 cm tall robot (competition.md §2); speeds divide by it",
        );
        c.within(
            "strafe_factor",
            self.strafe_factor,
            0.5,
            1.1,
            "",
            "mecanum rollers lose sideways travel (about 0.93, 0.5 on carpet), they do not add it",
        );
        const FOOTPRINT: &str = "the rules' 30 cm at the start (competition.md §2), and up to \
                                 10 cm more unfolded later (checked only at the start since 2024)";
        c.within(
            "footprint_length_m",
            self.footprint_length_m,
            0.05,
            0.40,
            "m",
            FOOTPRINT,
        );
        c.within(
            "footprint_width_m",
            self.footprint_width_m,
            0.05,
            0.40,
            "m",
            FOOTPRINT,
        );
        const CENTRE: &str = "the wheels' centre stands within 5 cm of the body's centre \
                              (measured from the axles to the faces)";
        c.within(
            "body_center_x_m",
            self.body_center_x_m,
            -MAX_BODY_CENTER_M,
            MAX_BODY_CENTER_M,
            "m",
            CENTRE,
        );
        c.within(
            "body_center_y_m",
            self.body_center_y_m,
            -MAX_BODY_CENTER_M,
            MAX_BODY_CENTER_M,
            "m",
            CENTRE,
        );
        for (i, s) in self.wheel_forward_sign.iter().enumerate() {
            c.require(&format!("wheel_forward_sign[{i}]"), s, s.abs() == 1, || {
                "must be +1 or -1 (the sign of the wire speed that rolls that wheel forward)"
                    .to_owned()
            });
        }
        c.within(
            "max_wheel_speed_rad_s",
            self.max_wheel_speed_rad_s,
            0.1,
            100.0,
            "rad/s",
            "a geared wheel motor: the DFRobot's is 26 rad/s at 12 V; 100 rad/s is 955 rpm",
        );
        c.within(
            "ticks_per_wheel_rev",
            self.ticks_per_wheel_rev,
            1.0,
            100_000.0,
            "",
            "encoder counts × 4 × gearbox: 2803.2 on this robot; the Mega's counters and \
             the simulator's per-tick deltas stay exact well below 100 000",
        );
        self.check_lidar_mount(c);
        self.check_imu(c);
        self.check_magnet_faces(c);
    }

    fn check_magnet_faces(&self, c: &mut Checker<'_>) {
        let faces = &self.magnet_faces;
        let listed = MagnetFace::list(faces);
        c.require("magnet_faces", &listed, !faces.is_empty(), || {
            "must name at least one face (\"front\" or \"back\"): the robot needs a magnet to \
             carry a part"
                .to_owned()
        });
        let repeated = faces
            .iter()
            .enumerate()
            .any(|(i, face)| faces[..i].contains(face));
        c.require("magnet_faces", &listed, !repeated, || {
            "names a face twice: each face carries at most one magnet".to_owned()
        });
    }

    fn check_lidar_mount(&self, c: &mut Checker<'_>) {
        // A footprint out of its own range is reported there; bound the mount by the largest.
        let half = |m: f64| {
            if (0.05..=0.40).contains(&m) {
                m / 2.0
            } else {
                0.20
            }
        };
        let centre = |m: f64| {
            if (-MAX_BODY_CENTER_M..=MAX_BODY_CENTER_M).contains(&m) {
                m
            } else {
                0.0
            }
        };
        let half_length = half(self.footprint_length_m);
        let half_width = half(self.footprint_width_m);
        let (x, y) = (centre(self.body_center_x_m), centre(self.body_center_y_m));
        c.within(
            "lidar_x_m",
            self.lidar_x_m,
            x - half_length,
            x + half_length,
            "m",
            "the lidar stands on the robot: within half of robot.footprint_length_m of the \
             body's centre (robot.body_center_x_m)",
        );
        c.within(
            "lidar_y_m",
            self.lidar_y_m,
            y - half_width,
            y + half_width,
            "m",
            "the lidar stands on the robot: within half of robot.footprint_width_m of the \
             body's centre (robot.body_center_y_m)",
        );
        c.within(
            "lidar_yaw_deg",
            self.lidar_yaw_deg,
            -360.0,
            360.0,
            "°",
            "one turn either way",
        );
        c.within(
            "lidar_height_m",
            self.lidar_height_m,
            0.02,
            0.50,
            "m",
            "above the floor and below the beacons' top: they are at most 50 cm tall \
             (competition.md §1.5)",
        );
    }

    fn check_imu(&self, c: &mut Checker<'_>) {
        c.non_empty(
            "imu.i2c_device",
            &self.imu.i2c_device,
            "the I2C bus device, /dev/i2c-1 on the Pi's header",
        );
        c.require(
            "imu.i2c_address",
            self.imu.i2c_address,
            matches!(self.imu.i2c_address, 0x68 | 0x69),
            || "must be 104 (0x68) or 105 (0x69): the MPU9255's AD0 pin selects one".to_owned(),
        );
        c.require(
            "imu.gyro_range_dps",
            self.imu.gyro_range_dps,
            self.imu.gyro_range().is_some(),
            || "must be 250, 500, 1000 or 2000 (the MPU9255's gyro full scales)".to_owned(),
        );
        c.within(
            "imu.yaw_deg",
            self.imu.yaw_deg,
            -360.0,
            360.0,
            "°",
            "one turn either way",
        );
        c.within(
            "imu.gyro_noise_density_rad_s_sqrt_hz",
            self.imu.gyro_noise_density_rad_s_sqrt_hz,
            0.0,
            0.0175,
            "rad/s/√Hz",
            "a hundred times the MPU-9250's typical 1.75e-4",
        );
    }
}
