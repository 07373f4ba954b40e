//! The MPU9255 driver against the simulated chip (`ratf_sim::imu`).

use embedded_hal::i2c::{ErrorKind, I2c, NoAcknowledgeSource};
use ratf_core::drivers::imu::bias::{BiasConfig, BiasError, estimate_gyro_bias};
use ratf_core::drivers::imu::registers::{GYRO_CONFIG, GyroRange};
use ratf_core::drivers::imu::*;
use ratf_sim::imu::{SimErrors, SimMotion, SimMpu9255};

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
    let mut imu = Mpu9255::configured(&mut sim, ImuConfig::default(), Chip::Mpu9255);
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
            imu = Mpu9255::configured(&mut sim, ImuConfig::default(), Chip::Mpu9255);
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
    let mut imu = Mpu9255::configured(&mut sim, ImuConfig::default(), Chip::Mpu9255);
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
        type Error = ratf_sim::imu::SimI2cError;
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
