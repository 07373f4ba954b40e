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
//! nothing consumed it. [`sim::SimMpu9255`] is the simulated chip.
//!
//! Axes are the chip's own (x, y, z as printed on the package); mounting is the caller's.

pub mod bias;
pub mod registers;
pub mod sim;

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
#[derive(Clone, Copy, Debug, PartialEq)]
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
    use super::bias::{BiasConfig, BiasError, estimate_gyro_bias};
    use super::registers::GYRO_CONFIG;
    use super::sim::{SimErrors, SimMotion, SimMpu9255};
    use super::*;
    use embedded_hal::i2c::NoAcknowledgeSource;

    /// One gyro LSB at ±500 °/s, rad/s.
    const GYRO_LSB_RAD_S: f64 = 1.0 / 65.5 * std::f64::consts::PI / 180.0;
    /// One accel LSB at ±4 g, m/s².
    const ACCEL_LSB_M_S2: f64 = 9.806_65 / 8192.0;

    #[test]
    fn identifies_and_configures_the_chip() {
        let mut sim = SimMpu9255::new(1);
        let imu = Mpu9255::new(&mut sim, ImuConfig::default()).unwrap();
        assert_eq!(imu.chip(), Chip::Mpu9255);
        assert_eq!(imu.config().sample_rate_hz(), 200.0);
        assert_eq!(
            sim.writes(),
            [
                (0x6B, 0x01), // PWR_MGMT_1: awake, PLL
                (0x6C, 0x00), // PWR_MGMT_2: all axes on
                (0x1A, 0x03), // CONFIG: DLPF 41 Hz
                (0x1B, 0x08), // GYRO_CONFIG: ±500 °/s
                (0x1C, 0x08), // ACCEL_CONFIG: ±4 g
                (0x1D, 0x03), // ACCEL_CONFIG2: DLPF 44.8 Hz
                (0x19, 0x04), // SMPLRT_DIV: 1 kHz / 5 = 200 Hz
            ]
        );
        let mpu9250 = SimMpu9255::new(1).with_who_am_i(0x71);
        assert_eq!(
            Mpu9255::new(mpu9250, ImuConfig::default()).unwrap().chip(),
            Chip::Mpu9250
        );
    }

    #[test]
    fn scales_readings_with_the_configured_range() {
        let mut sim = SimMpu9255::new(2);
        let motion = SimMotion {
            rate_rad_s: [0.5, -1.0, 2.0],
            accel_m_s2: [0.1, -0.2, 9.806_65],
        };
        sim.set_motion(motion);
        sim.set_temperature_c(30.0);
        let mut imu = Mpu9255::new(&mut sim, ImuConfig::default()).unwrap();
        let sample = imu.read_sample(1234).unwrap();
        assert_eq!(sample.time_us, 1234);
        assert!(!sample.saturated);
        for axis in 0..3 {
            let gyro_error = (sample.gyro_rad_s[axis] - motion.rate_rad_s[axis]).abs();
            assert!(gyro_error <= GYRO_LSB_RAD_S / 2.0 + 1e-12, "gyro {axis}");
            let accel_error = (sample.accel_m_s2[axis] - motion.accel_m_s2[axis]).abs();
            assert!(accel_error <= ACCEL_LSB_M_S2 / 2.0 + 1e-12, "accel {axis}");
        }
        assert!((sample.temperature_c - 30.0).abs() < 0.01);
        assert_eq!(imu.read_gyro_rad_s().unwrap(), sample.gyro_rad_s);
        assert_eq!(imu.read_accel_m_s2().unwrap(), sample.accel_m_s2);
        let before = sim.transactions();
        let mut imu = Mpu9255 {
            i2c: &mut sim,
            config: ImuConfig::default(),
            chip: Chip::Mpu9255,
        };
        imu.read_sample(0).unwrap();
        assert_eq!(sim.transactions(), before + 1, "one burst per sample");
    }

    #[test]
    fn another_range_changes_the_scale() {
        let mut sim = SimMpu9255::new(3);
        sim.set_motion(SimMotion {
            rate_rad_s: [0.0, 0.0, 10.0], // 573 °/s: beyond ±500, within ±1000
            ..SimMotion::default()
        });
        let config = ImuConfig {
            gyro_range: GyroRange::Dps1000,
            ..ImuConfig::default()
        };
        let mut imu = Mpu9255::new(&mut sim, config).unwrap();
        let sample = imu.read_sample(0).unwrap();
        assert!(!sample.saturated);
        assert!((sample.gyro_rad_s[2] - 10.0).abs() < 1e-3);
        assert_eq!(sim.register(GYRO_CONFIG), 0x10);
        // At ±500 °/s the same rate clips, and the sample says so.
        let mut imu = Mpu9255::new(&mut sim, ImuConfig::default()).unwrap();
        let sample = imu.read_sample(0).unwrap();
        assert!(sample.saturated);
        assert!((sample.gyro_rad_s[2] - (32767.0 / 65.5f64).to_radians()).abs() < 1e-9);
    }

    #[test]
    fn bias_is_estimated_from_still_samples() {
        let bias = [0.012, -0.021, 0.034];
        let noise = 0.002;
        let mut sim = SimMpu9255::new(4);
        sim.set_errors(SimErrors {
            gyro_bias_rad_s: bias,
            gyro_noise_std_rad_s: noise,
            accel_noise_std_m_s2: 0.02,
        });
        let mut imu = Mpu9255::new(&mut sim, ImuConfig::default()).unwrap();
        let samples: Vec<[f64; 3]> = (0..400)
            .map(|k| imu.read_sample(k * 5_000).unwrap().gyro_rad_s)
            .collect();
        let estimate = estimate_gyro_bias(&samples, &BiasConfig::default()).unwrap();
        // Within 4 standard errors of the mean plus one quantisation step.
        let tolerance = 4.0 * noise / 400f64.sqrt() + GYRO_LSB_RAD_S;
        for axis in 0..3 {
            let error = (estimate[axis] - bias[axis]).abs();
            assert!(error < tolerance, "axis {axis}: {error} ≥ {tolerance}");
        }
        // The same chip while the robot is pushed into a turn: refused.
        let mut samples = Vec::new();
        for k in 0..400 {
            if k == 200 {
                imu.release().set_motion(SimMotion {
                    rate_rad_s: [0.0, 0.0, 0.3],
                    ..SimMotion::default()
                });
                imu = Mpu9255 {
                    i2c: &mut sim,
                    config: ImuConfig::default(),
                    chip: Chip::Mpu9255,
                };
            }
            samples.push(imu.read_sample(0).unwrap().gyro_rad_s);
        }
        assert!(matches!(
            estimate_gyro_bias(&samples, &BiasConfig::default()),
            Err(BiasError::Moving { axis: 2, .. })
        ));
    }

    #[test]
    fn an_unknown_chip_is_named() {
        let sim = SimMpu9255::new(5).with_who_am_i(0x68);
        let err = Mpu9255::new(sim, ImuConfig::default()).unwrap_err();
        assert_eq!(err, ImuError::UnknownChip(0x68));
        assert!(err.to_string().contains("0x68"), "{err}");
    }

    #[test]
    fn i2c_errors_are_propagated() {
        // Nobody at the address.
        let sim = SimMpu9255::new(6).with_address(0x69);
        assert_eq!(
            Mpu9255::new(sim, ImuConfig::default()).unwrap_err(),
            ImuError::I2c(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address))
        );
        // The bus fails after configuration.
        let mut sim = SimMpu9255::new(7);
        let mut imu = Mpu9255::new(&mut sim, ImuConfig::default()).unwrap();
        imu.read_sample(0).unwrap();
        imu.release()
            .fail_with(Some(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data)));
        let mut imu = Mpu9255 {
            i2c: &mut sim,
            config: ImuConfig::default(),
            chip: Chip::Mpu9255,
        };
        let err = imu.read_sample(0).unwrap_err();
        assert_eq!(
            err,
            ImuError::I2c(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data))
        );
        assert!(err.to_string().contains("did not acknowledge"), "{err}");
    }

    #[test]
    fn a_register_that_does_not_keep_its_value_is_reported() {
        /// A bus where the chip ignores writes to GYRO_CONFIG.
        #[derive(Debug)]
        struct Stuck(SimMpu9255);
        impl embedded_hal::i2c::ErrorType for Stuck {
            type Error = sim::SimI2cError;
        }
        impl I2c for Stuck {
            fn transaction(
                &mut self,
                address: u8,
                operations: &mut [embedded_hal::i2c::Operation<'_>],
            ) -> Result<(), Self::Error> {
                use embedded_hal::i2c::Operation;
                if let [Operation::Write([GYRO_CONFIG, _])] = operations {
                    return Ok(());
                }
                self.0.transaction(address, operations)
            }
        }
        let err = Mpu9255::new(Stuck(SimMpu9255::new(8)), ImuConfig::default()).unwrap_err();
        assert_eq!(
            err,
            ImuError::ConfigMismatch {
                register: GYRO_CONFIG,
                written: 0x08,
                read: 0x00
            }
        );
    }
}
