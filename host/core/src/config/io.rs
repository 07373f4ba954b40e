//! `[lidar]`, `[link]` and `[referee]`: the sensors' and links' numbers.

use serde::{Deserialize, Serialize};

use super::check::{Checker, num};
use crate::drivers::x4::packet::{MAX_DISTANCE_MM, MAX_SCAN_FREQUENCY_HZ};

/// The YDLIDAR X4 (paper §VI; original-system.md §1.3, §3.2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LidarConfig {
    /// Scan rate, Hz. 7: the X4's typical rate powered over USB (paper §VI).
    pub scan_rate_hz: f64,
    /// Angle between consecutive rays, degrees. 0.5: typical at 7 Hz (paper §VI).
    pub angle_step_deg: f64,
    /// Range noise standard deviation, m. 0.01: assumption, the σ_d the original's EKF
    /// uses (R = 0.0001 m², original §5); the datasheet gives only resolution.
    pub range_noise_std_m: f64,
    /// Shortest valid range, m. 0.12: datasheet and original `dist_min` (§1.3).
    pub min_range_m: f64,
    /// Longest valid range, m. 10: datasheet and original `dist_max` (§1.3).
    pub max_range_m: f64,
    /// The lidar's range scale: it reads `range_scale × true + range_offset_m`. 1: nominal;
    /// the X4's datasheet allows about ±1.5 % (real-world-errors.md); `ratf calibrate`
    /// measures it.
    pub range_scale: f64,
    /// The lidar's range offset, m (see `range_scale`). 0: nominal; the datasheet allows
    /// about ±10 mm.
    pub range_offset_m: f64,
}

impl Default for LidarConfig {
    fn default() -> Self {
        Self {
            scan_rate_hz: 7.0,
            angle_step_deg: 0.5,
            range_noise_std_m: 0.01,
            min_range_m: 0.12,
            max_range_m: 10.0,
            range_scale: 1.0,
            range_offset_m: 0.0,
        }
    }
}

impl LidarConfig {
    /// The true range of a reading `raw_m`, m: the calibration (`range_scale`,
    /// `range_offset_m`) undone.
    pub fn corrected_range_m(&self, raw_m: f64) -> f64 {
        (raw_m - self.range_offset_m) / self.range_scale
    }

    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        c.within(
            "range_scale",
            self.range_scale,
            0.9,
            1.1,
            "",
            "the X4's datasheet allows about ±1.5 %, ±3.5 % at worst; ±10 % is a broken unit",
        );
        c.within(
            "range_offset_m",
            self.range_offset_m,
            -0.1,
            0.1,
            "m",
            "the datasheet allows about ±10 mm, ±20 mm at worst",
        );
        c.within(
            "scan_rate_hz",
            self.scan_rate_hz,
            4.0,
            MAX_SCAN_FREQUENCY_HZ,
            "Hz",
            "the X4 turns at 6–12 Hz as its motor voltage sets (datasheet), and its packets \
             carry at most 12.7 Hz; 4 Hz leaves room for a slow motor",
        );
        c.within(
            "angle_step_deg",
            self.angle_step_deg,
            0.1,
            2.0,
            "°",
            "the X4's 5 kHz ranging gives 0.43° at 6 Hz to 0.86° at 12 Hz; a 90 mm beacon 2 m \
             away spans 2.6°, so coarser steps leave it fewer than two rays",
        );
        c.within(
            "range_noise_std_m",
            self.range_noise_std_m,
            0.0,
            0.1,
            "m",
            "five times the datasheet's 2 cm systematic error",
        );
        c.within(
            "min_range_m",
            self.min_range_m,
            0.01,
            0.2,
            "m",
            "the X4 measures from 0.12 m; at the start pose the nearest beacon's surface is \
             0.22 m from the robot's centre, and a longer minimum would hide it",
        );
        let max_m = MAX_DISTANCE_MM / 1000.0;
        let min_m = if (0.01..=0.2).contains(&self.min_range_m) {
            self.min_range_m
        } else {
            0.0
        };
        c.require(
            "max_range_m",
            num(self.max_range_m),
            self.max_range_m.is_finite() && self.max_range_m > min_m && self.max_range_m <= max_m,
            || {
                format!(
                    "must be within lidar.min_range_m = {} … {} m (the X4's packets carry \
                     distances in 16-bit quarter millimetres; it measures to 10 m)",
                    num(self.min_range_m),
                    num(max_m)
                )
            },
        );
    }
}

/// Which IMU `ratf run` reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImuDevice {
    /// The MPU9255 on `[robot.imu] i2c_device`; if the bus is not there, the robot runs
    /// without it (a warning says so).
    #[default]
    Mpu9255,
    /// No IMU: the core gets no IMU samples.
    None,
}

/// The robot's devices on the Pi: serial ports, the IMU, and how `ratf run` keeps them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LinkConfig {
    /// The Mega's port. `/dev/ttyACM0`: original `serial_port_name` (§1.3); a udev rule can
    /// give it a stable name such as `/dev/ratf-mega`.
    pub mega_port: String,
    /// The Mega's baud rate. 115200 8N1: original firmware (§2.1).
    pub mega_baud: u32,
    /// The lidar's port. `/dev/ttyUSB0`: original (§1.3).
    pub lidar_port: String,
    /// The lidar's baud rate. 128000: X4 datasheet, original `baud_rate` (§1.3).
    pub lidar_baud: u32,
    /// The IMU `ratf run` reads: `mpu9255` (on `[robot.imu] i2c_device`) or `none`.
    pub imu: ImuDevice,
    /// After opening the Mega's port (which resets the board through DTR), how long to
    /// wait for its `r` or a telemetry batch before sending references anyway, ms. 3000:
    /// the bootloader takes 1–2 s (crates.md §1). At most 60 000.
    pub mega_sync_timeout_ms: u32,
    /// How often a lost serial port is tried again, ms. 500: assumption (the original's
    /// ROS 2 driver retries every 1 s). 10 to 60 000.
    pub reconnect_period_ms: u32,
    /// After the lidar's start command, how long it may stay silent (spin-up) before the
    /// port is reopened and the command sent again, ms. 5000: the X4 spins up within about
    /// 2 s (assumption, to be measured). 100 to 60 000.
    pub lidar_spinup_timeout_ms: u32,
    /// A device away (port gone, silent) this long ends `ratf run` with a device failure,
    /// s. 10: long enough to replug a cable. 1 to 600 (the 10-minute slot).
    pub give_up_after_s: u32,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            mega_port: "/dev/ttyACM0".to_owned(),
            mega_baud: 115_200,
            lidar_port: "/dev/ttyUSB0".to_owned(),
            lidar_baud: 128_000,
            imu: ImuDevice::Mpu9255,
            mega_sync_timeout_ms: 3_000,
            reconnect_period_ms: 500,
            lidar_spinup_timeout_ms: 5_000,
            give_up_after_s: 10,
        }
    }
}

impl LinkConfig {
    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        c.non_empty(
            "mega_port",
            &self.mega_port,
            "the Mega's serial port, e.g. /dev/ttyACM0",
        );
        c.within_int(
            "mega_baud",
            self.mega_baud,
            1_200,
            2_000_000,
            "baud",
            "the ATmega2560's UART reaches 2 Mbaud (16 MHz / 8); the firmware uses 115 200",
        );
        c.non_empty(
            "lidar_port",
            &self.lidar_port,
            "the lidar's serial port, e.g. /dev/ttyUSB0",
        );
        c.within_int(
            "lidar_baud",
            self.lidar_baud,
            1_200,
            1_000_000,
            "baud",
            "the X4's CP2102 bridge reaches 1 Mbaud; the X4 speaks 128 000",
        );
        c.within_int(
            "mega_sync_timeout_ms",
            self.mega_sync_timeout_ms,
            0,
            60_000,
            "ms",
            "the bootloader takes 1–2 s after the reset on opening",
        );
        c.within_int(
            "reconnect_period_ms",
            self.reconnect_period_ms,
            10,
            60_000,
            "ms",
            "often enough to catch a replugged cable, not so often that it spins",
        );
        c.within_int(
            "lidar_spinup_timeout_ms",
            self.lidar_spinup_timeout_ms,
            100,
            60_000,
            "ms",
            "the X4 spins up within about 2 s",
        );
        c.within_int(
            "give_up_after_s",
            self.give_up_after_s,
            1,
            600,
            "s",
            "long enough to replug a cable, at most the 10-minute slot (competition.md §2)",
        );
    }
}

/// The organisers' UDP server (competition.md §3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefereeConfig {
    /// Server host name or IP. 127.0.0.1: 5dpo's launch config for local testing (§3);
    /// the venue's address is handed out on site.
    pub server_address: String,
    /// Server UDP port. 39899: 5dpo's launch config (§3).
    pub server_port: u16,
    /// Local UDP port to bind, 0 = any. 0: assumption (5dpo bound 38689; nothing requires it).
    pub local_port: u16,
    /// Reply timeout per request, ms. 400: within the 0.3–0.5 s of competition.md §3.
    pub request_timeout_ms: u32,
    /// Tries per request before giving up. 3: competition.md §3 ("a few tries").
    pub max_tries: u32,
}

impl Default for RefereeConfig {
    fn default() -> Self {
        Self {
            server_address: "127.0.0.1".to_owned(),
            server_port: 39_899,
            local_port: 0,
            request_timeout_ms: 400,
            max_tries: 3,
        }
    }
}

impl RefereeConfig {
    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        c.non_empty(
            "server_address",
            &self.server_address,
            "the organisers' server, handed out at the venue",
        );
        c.within_int(
            "server_port",
            self.server_port,
            1,
            65_535,
            "",
            "a UDP port; 0 is not one a server listens on",
        );
        c.within_int(
            "request_timeout_ms",
            self.request_timeout_ms,
            10,
            10_000,
            "ms",
            "a Wi-Fi round trip takes milliseconds to tens of ms; 5dpo waited at most 10 s",
        );
        c.within_int(
            "max_tries",
            self.max_tries,
            1,
            20,
            "",
            "with the timeout doubling to ×8, 20 tries of 0.4 s take 57 s",
        );
    }
}
