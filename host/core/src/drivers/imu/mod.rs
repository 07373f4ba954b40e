//! MPU9255 (or MPU9250) accelerometer + gyro over embedded-hal 1.0 I2C, fixed per
//! original-system.md §3.3 and §10.12.
//!
//! The original relied on power-on defaults, scaled the gyro for ±1000 °/s and then
//! multiplied by a ×0.25 fudge (which happens to give the real ±250 °/s default scale),
//! subtracted hard-coded biases, and read one byte per I2C transaction in an unthrottled
//! loop. This driver instead:
//!
//! - checks WHO_AM_I (0x71 = MPU9250, 0x73 = MPU9255) and names the value read otherwise;
//! - writes every setting it depends on and reads each one back ([`ImuConfig`]): awake on
//!   the PLL clock, all axes on, DLPF, gyro and accel full scale, sample-rate divider;
//! - reads the 14 data registers 0x3B..=0x48 in one burst (one transaction), so accel and
//!   gyro come from the same sample, and scales with the configured full scale;
//! - leaves bias estimation to [`bias::estimate_gyro_bias`], fed with samples taken at
//!   start-up while the robot is still.
//!
//! The magnetometer (AK8963 behind I2C bypass) is not used: the original published it but
//! nothing consumed it. `ratf_sim::imu::SimMpu9255` is the simulated chip.
//!
//! Axes are the chip's own (x, y, z as printed on the package); mounting is the caller's.

pub mod bias;
pub mod registers;

use embedded_hal::i2c::{ErrorKind, I2c};
use registers::{
    ACCEL_CONFIG, ACCEL_CONFIG2, ACCEL_XOUT_H, AccelRange, CONFIG, DEFAULT_ADDRESS, Dlpf,
    GYRO_CONFIG, GYRO_XOUT_H, GyroRange, PWR_MGMT_1, PWR_MGMT_1_WAKE_PLL, PWR_MGMT_2, SMPLRT_DIV,
    STANDARD_GRAVITY_M_S2, TEMP_LSB_PER_C, TEMP_OFFSET_C, WHO_AM_I, WHO_AM_I_MPU9250,
    WHO_AM_I_MPU9255,
};

/// Driver settings. Defaults and why:
///
/// - gyro ±500 °/s: the robot's yaw rate stays below ~3 rad/s (172 °/s), a bump can spin
///   it faster; ±500 keeps 0.015 °/s resolution;
/// - accel ±4 g: a ground robot sees ~1 g plus bumps; ±2 g can clip on impacts;
/// - DLPF 41 Hz: below the 100 Hz Nyquist limit of the 200 Hz output rate, 5.9 ms delay;
/// - sample-rate divider 4: 1 kHz / (1 + 4) = 200 Hz, four samples per 50 Hz control
///   period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImuConfig {
    /// 7-bit I2C address (0x68 with AD0 low).
    pub address: u8,
    /// Gyro full scale.
    pub gyro_range: GyroRange,
    /// Accelerometer full scale.
    pub accel_range: AccelRange,
    /// Low-pass filter for gyro and accel.
    pub dlpf: Dlpf,
    /// SMPLRT_DIV: output rate = 1000 Hz / (1 + divider).
    pub sample_rate_divider: u8,
}

impl Default for ImuConfig {
    fn default() -> Self {
        Self {
            address: DEFAULT_ADDRESS,
            gyro_range: GyroRange::Dps500,
            accel_range: AccelRange::G4,
            dlpf: Dlpf::Hz41,
            sample_rate_divider: 4,
        }
    }
}

impl ImuConfig {
    /// The chip's output data rate, Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        1000.0 / (1.0 + f64::from(self.sample_rate_divider))
    }

    /// The register writes that apply this configuration, in order.
    pub fn register_writes(&self) -> [(u8, u8); 7] {
        [
            (PWR_MGMT_1, PWR_MGMT_1_WAKE_PLL),
            (PWR_MGMT_2, 0x00),
            (CONFIG, self.dlpf.code()),
            (GYRO_CONFIG, self.gyro_range.fs_sel() << 3),
            (ACCEL_CONFIG, self.accel_range.fs_sel() << 3),
            (ACCEL_CONFIG2, self.dlpf.code()),
            (SMPLRT_DIV, self.sample_rate_divider),
        ]
    }
}

/// Which chip answered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chip {
    /// WHO_AM_I 0x71.
    Mpu9250,
    /// WHO_AM_I 0x73.
    Mpu9255,
}

/// Why the IMU could not be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ImuError {
    /// The I2C transfer failed (e.g. the chip did not acknowledge its address).
    #[error("I2C transfer to the IMU failed: {0}")]
    I2c(ErrorKind),
    /// WHO_AM_I holds an unknown identity.
    #[error(
        "unknown IMU chip: WHO_AM_I (0x75) reads 0x{0:02X}, expected 0x71 (MPU9250) or 0x73 (MPU9255)"
    )]
    UnknownChip(u8),
    /// A configuration register did not keep the value written.
    #[error("IMU register 0x{register:02X} reads 0x{read:02X} after writing 0x{written:02X}")]
    ConfigMismatch {
        /// Register address.
        register: u8,
        /// Value written.
        written: u8,
        /// Value read back.
        read: u8,
    },
}

/// One scaled reading, in the chip's axes.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImuSample {
    /// Time the read completed, µs (caller's monotonic clock).
    pub time_us: u64,
    /// Angular rate, rad/s, bias not removed.
    pub gyro_rad_s: [f64; 3],
    /// Specific force, m/s² (reads +9.81 on the upward axis at rest).
    pub accel_m_s2: [f64; 3],
    /// Die temperature, °C (the gyro bias drifts with it).
    pub temperature_c: f64,
    /// A raw value sat at the end of its range: the reading is clipped.
    pub saturated: bool,
}

impl ImuSample {
    /// This sample in axes turned by `yaw_rad` about z: with `yaw_rad` the yaw of the
    /// chip's x axis in the robot frame, the result is in the robot's axes (x forward, y
    /// left, z up). The time, temperature and saturation flag are kept.
    pub fn rotated_about_z(&self, yaw_rad: f64) -> Self {
        let (sin, cos) = yaw_rad.sin_cos();
        let turn = |v: [f64; 3]| [cos * v[0] - sin * v[1], sin * v[0] + cos * v[1], v[2]];
        Self {
            gyro_rad_s: turn(self.gyro_rad_s),
            accel_m_s2: turn(self.accel_m_s2),
            ..*self
        }
    }
}

/// The MPU9255 driver: see the module documentation.
#[derive(Debug)]
pub struct Mpu9255<I> {
    i2c: I,
    config: ImuConfig,
    chip: Chip,
}

fn i2c_error(e: impl embedded_hal::i2c::Error) -> ImuError {
    ImuError::I2c(e.kind())
}

fn be_i16(bytes: &[u8], at: usize) -> i16 {
    i16::from_be_bytes([bytes[at], bytes[at + 1]])
}

impl<I: I2c> Mpu9255<I> {
    /// Identify the chip and configure it (see [`ImuConfig`]); every written register is
    /// read back and checked.
    pub fn new(mut i2c: I, config: ImuConfig) -> Result<Self, ImuError> {
        let who = read_register(&mut i2c, config.address, WHO_AM_I)?;
        let chip = match who {
            WHO_AM_I_MPU9250 => Chip::Mpu9250,
            WHO_AM_I_MPU9255 => Chip::Mpu9255,
            other => return Err(ImuError::UnknownChip(other)),
        };
        for (register, value) in config.register_writes() {
            i2c.write(config.address, &[register, value])
                .map_err(i2c_error)?;
            let read = read_register(&mut i2c, config.address, register)?;
            if read != value {
                return Err(ImuError::ConfigMismatch {
                    register,
                    written: value,
                    read,
                });
            }
        }
        Ok(Self { i2c, config, chip })
    }

    /// The chip identified.
    pub const fn chip(&self) -> Chip {
        self.chip
    }

    /// The configuration in force.
    pub const fn config(&self) -> &ImuConfig {
        &self.config
    }

    /// Wrap a bus whose chip was already configured by [`Mpu9255::new`] (e.g. after
    /// [`Mpu9255::release`] lent the bus to something else), without writing a register.
    pub fn configured(i2c: I, config: ImuConfig, chip: Chip) -> Self {
        Self { i2c, config, chip }
    }

    /// Give the bus back.
    pub fn release(self) -> I {
        self.i2c
    }

    fn gyro_scale(&self) -> f64 {
        (1.0 / self.config.gyro_range.lsb_per_dps()).to_radians()
    }

    fn accel_scale(&self) -> f64 {
        STANDARD_GRAVITY_M_S2 / self.config.accel_range.lsb_per_g()
    }

    /// Read accel, temperature and gyro in one 14-byte burst (one transaction) and scale
    /// them; `now_us` stamps the sample.
    pub fn read_sample(&mut self, now_us: u64) -> Result<ImuSample, ImuError> {
        let mut raw = [0u8; 14];
        self.i2c
            .write_read(self.config.address, &[ACCEL_XOUT_H], &mut raw)
            .map_err(i2c_error)?;
        let words: [i16; 7] = core::array::from_fn(|k| be_i16(&raw, 2 * k));
        let (accel, gyro) = (self.accel_scale(), self.gyro_scale());
        let saturated = words
            .iter()
            .enumerate()
            .any(|(k, &w)| k != 3 && (w == i16::MAX || w == i16::MIN));
        Ok(ImuSample {
            time_us: now_us,
            accel_m_s2: core::array::from_fn(|k| f64::from(words[k]) * accel),
            temperature_c: f64::from(words[3]) / TEMP_LSB_PER_C + TEMP_OFFSET_C,
            gyro_rad_s: core::array::from_fn(|k| f64::from(words[4 + k]) * gyro),
            saturated,
        })
    }

    /// Read only the gyro (registers 0x43..=0x48, one transaction), rad/s.
    pub fn read_gyro_rad_s(&mut self) -> Result<[f64; 3], ImuError> {
        let mut raw = [0u8; 6];
        self.i2c
            .write_read(self.config.address, &[GYRO_XOUT_H], &mut raw)
            .map_err(i2c_error)?;
        let scale = self.gyro_scale();
        Ok(core::array::from_fn(|k| {
            f64::from(be_i16(&raw, 2 * k)) * scale
        }))
    }

    /// Read only the accelerometer (registers 0x3B..=0x40, one transaction), m/s².
    pub fn read_accel_m_s2(&mut self) -> Result<[f64; 3], ImuError> {
        let mut raw = [0u8; 6];
        self.i2c
            .write_read(self.config.address, &[ACCEL_XOUT_H], &mut raw)
            .map_err(i2c_error)?;
        let scale = self.accel_scale();
        Ok(core::array::from_fn(|k| {
            f64::from(be_i16(&raw, 2 * k)) * scale
        }))
    }
}

fn read_register(i2c: &mut impl I2c, address: u8, register: u8) -> Result<u8, ImuError> {
    let mut value = [0u8];
    i2c.write_read(address, &[register], &mut value)
        .map_err(i2c_error)?;
    Ok(value[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chip_turned_a_quarter_left_reads_its_x_as_the_robots_y() {
        let sample = ImuSample {
            time_us: 7,
            gyro_rad_s: [0.1, 0.0, 0.5],
            accel_m_s2: [1.0, 0.0, 9.81],
            temperature_c: 30.0,
            saturated: false,
        };
        let robot = sample.rotated_about_z(std::f64::consts::FRAC_PI_2);
        assert!(robot.accel_m_s2[0].abs() < 1e-12 && (robot.accel_m_s2[1] - 1.0).abs() < 1e-12);
        assert!((robot.gyro_rad_s[1] - 0.1).abs() < 1e-12);
        assert_eq!(
            robot.gyro_rad_s[2], 0.5,
            "the yaw rate does not depend on the mount yaw"
        );
        assert_eq!((robot.time_us, robot.temperature_c), (7, 30.0));
        // No turn is exactly no change.
        assert_eq!(sample.rotated_about_z(0.0), sample);
    }
}
