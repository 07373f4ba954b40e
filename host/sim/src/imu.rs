//! A simulated MPU9255 on an embedded-hal 1.0 I2C bus, for the simulator and the tests.
//!
//! It holds a 128-register file at power-on values (all 0 except PWR_MGMT_1 = 0x01 and
//! WHO_AM_I, register map rev 1.6), accepts writes (auto-incrementing from the register
//! named by the first byte) and records each one, and answers reads. At the start of every
//! transaction that reads, it takes a new sample into the data registers 0x3B..=0x48:
//! true value + bias + Gaussian noise, quantised with the full scale currently written in
//! GYRO_CONFIG / ACCEL_CONFIG and clipped to i16, exactly as the chip reports it. While the
//! SLEEP bit is set the data registers read 0.
//!
//! Deterministic: noise comes from the simulator's generator ([`SimRng`]) seeded by the
//! caller.

use embedded_hal::i2c::{ErrorKind, ErrorType, I2c, NoAcknowledgeSource, Operation};
use ratf_core::drivers::imu::registers::{
    ACCEL_CONFIG, ACCEL_XOUT_H, AccelRange, DEFAULT_ADDRESS, GYRO_CONFIG, GyroRange, PWR_MGMT_1,
    PWR_MGMT_1_SLEEP, STANDARD_GRAVITY_M_S2, TEMP_LSB_PER_C, TEMP_OFFSET_C, WHO_AM_I,
    WHO_AM_I_MPU9255,
};
use ratf_core::rng::SimRng;

/// Data registers: accel (6), temperature (2), gyro (6).
const DATA_LEN: usize = 14;

/// The simulated chip's error: an [`ErrorKind`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimI2cError(pub ErrorKind);

impl embedded_hal::i2c::Error for SimI2cError {
    fn kind(&self) -> ErrorKind {
        self.0
    }
}

/// The physical state the simulated chip measures, in its own axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimMotion {
    /// True angular rate, rad/s.
    pub rate_rad_s: [f64; 3],
    /// True specific force, m/s² (at rest, flat: [0, 0, 9.80665]).
    pub accel_m_s2: [f64; 3],
}

impl Default for SimMotion {
    fn default() -> Self {
        Self {
            rate_rad_s: [0.0; 3],
            accel_m_s2: [0.0, 0.0, STANDARD_GRAVITY_M_S2],
        }
    }
}

/// The simulated chip's imperfections.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SimErrors {
    /// Gyro bias added to every reading, rad/s.
    pub gyro_bias_rad_s: [f64; 3],
    /// Standard deviation of the gyro's white noise, rad/s.
    pub gyro_noise_std_rad_s: f64,
    /// Standard deviation of the accelerometer's white noise, m/s².
    pub accel_noise_std_m_s2: f64,
}

/// The simulated MPU9255: see the module documentation.
#[derive(Clone, Debug)]
pub struct SimMpu9255 {
    address: u8,
    registers: [u8; 128],
    pointer: u8,
    motion: SimMotion,
    errors: SimErrors,
    temperature_c: f64,
    rng: SimRng,
    writes: Vec<(u8, u8)>,
    transactions: u32,
    fail_with: Option<ErrorKind>,
}

impl SimMpu9255 {
    /// A chip at `address` (0x68 on the robot) answering WHO_AM_I with 0x73, at rest, with
    /// no bias or noise, at 25 °C; `seed` seeds the noise.
    pub fn new(seed: u64) -> Self {
        let mut registers = [0u8; 128];
        registers[usize::from(PWR_MGMT_1)] = 0x01;
        registers[usize::from(WHO_AM_I)] = WHO_AM_I_MPU9255;
        Self {
            address: DEFAULT_ADDRESS,
            registers,
            pointer: 0,
            motion: SimMotion::default(),
            errors: SimErrors::default(),
            temperature_c: 25.0,
            rng: SimRng::new(seed),
            writes: Vec::new(),
            transactions: 0,
            fail_with: None,
        }
    }

    /// Answer WHO_AM_I with `id` instead (0x71 = MPU9250; anything else = another chip).
    pub fn with_who_am_i(mut self, id: u8) -> Self {
        self.registers[usize::from(WHO_AM_I)] = id;
        self
    }

    /// Sit at another 7-bit address (0x69 = AD0 high).
    pub fn with_address(mut self, address: u8) -> Self {
        self.address = address;
        self
    }

    /// Set what the chip measures from now on.
    pub fn set_motion(&mut self, motion: SimMotion) {
        self.motion = motion;
    }

    /// Set the chip's bias and noise.
    pub fn set_errors(&mut self, errors: SimErrors) {
        self.errors = errors;
    }

    /// Set the die temperature, °C.
    pub fn set_temperature_c(&mut self, temperature_c: f64) {
        self.temperature_c = temperature_c;
    }

    /// Make every following transaction fail with `kind` (`None` to heal the bus).
    pub fn fail_with(&mut self, kind: Option<ErrorKind>) {
        self.fail_with = kind;
    }

    /// Every register write so far, in order, as (register, value).
    pub fn writes(&self) -> &[(u8, u8)] {
        &self.writes
    }

    /// A register's current value.
    pub fn register(&self, register: u8) -> u8 {
        self.registers[usize::from(register & 0x7F)]
    }

    /// Transactions addressed to this chip so far.
    pub fn transactions(&self) -> u32 {
        self.transactions
    }

    fn quantise(value: f64, lsb_per_unit: f64) -> i16 {
        (value * lsb_per_unit)
            .round()
            .clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
    }

    /// Take a new sample into the data registers.
    fn sample(&mut self) {
        let mut words = [0i16; DATA_LEN / 2];
        if self.register(PWR_MGMT_1) & PWR_MGMT_1_SLEEP == 0 {
            let gyro_lsb_per_rad_s = GyroRange::from_register(self.register(GYRO_CONFIG))
                .lsb_per_dps()
                .to_degrees();
            let accel_lsb_per_m_s2 = AccelRange::from_register(self.register(ACCEL_CONFIG))
                .lsb_per_g()
                / STANDARD_GRAVITY_M_S2;
            for axis in 0..3 {
                let accel = self.motion.accel_m_s2[axis]
                    + self.errors.accel_noise_std_m_s2 * self.rng.standard_normal();
                words[axis] = Self::quantise(accel, accel_lsb_per_m_s2);
                let rate = self.motion.rate_rad_s[axis]
                    + self.errors.gyro_bias_rad_s[axis]
                    + self.errors.gyro_noise_std_rad_s * self.rng.standard_normal();
                words[4 + axis] = Self::quantise(rate, gyro_lsb_per_rad_s);
            }
            words[3] = Self::quantise(self.temperature_c - TEMP_OFFSET_C, TEMP_LSB_PER_C);
        }
        for (k, word) in words.iter().enumerate() {
            let at = usize::from(ACCEL_XOUT_H) + 2 * k;
            self.registers[at..at + 2].copy_from_slice(&word.to_be_bytes());
        }
    }
}

impl ErrorType for SimMpu9255 {
    type Error = SimI2cError;
}

impl I2c for SimMpu9255 {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        if let Some(kind) = self.fail_with {
            return Err(SimI2cError(kind));
        }
        if address != self.address {
            return Err(SimI2cError(ErrorKind::NoAcknowledge(
                NoAcknowledgeSource::Address,
            )));
        }
        self.transactions += 1;
        if operations.iter().any(|op| matches!(op, Operation::Read(_))) {
            self.sample();
        }
        for operation in operations {
            match operation {
                Operation::Write(bytes) => {
                    let Some((&register, data)) = bytes.split_first() else {
                        continue;
                    };
                    self.pointer = register & 0x7F;
                    for &value in data {
                        // WHO_AM_I and the data registers are read-only.
                        let read_only = self.pointer == WHO_AM_I
                            || (ACCEL_XOUT_H..ACCEL_XOUT_H + DATA_LEN as u8)
                                .contains(&self.pointer);
                        if !read_only {
                            self.registers[usize::from(self.pointer)] = value;
                        }
                        self.writes.push((self.pointer, value));
                        self.pointer = (self.pointer + 1) & 0x7F;
                    }
                }
                Operation::Read(buffer) => {
                    for byte in buffer.iter_mut() {
                        *byte = self.registers[usize::from(self.pointer)];
                        self.pointer = (self.pointer + 1) & 0x7F;
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gyro_z(sim: &mut SimMpu9255) -> i16 {
        let mut raw = [0u8; 2];
        sim.write_read(DEFAULT_ADDRESS, &[0x47], &mut raw).unwrap();
        i16::from_be_bytes(raw)
    }

    #[test]
    fn noise_is_deterministic_and_has_the_set_spread() {
        let errors = SimErrors {
            gyro_noise_std_rad_s: 0.01,
            ..SimErrors::default()
        };
        let mut a = SimMpu9255::new(42);
        let mut b = SimMpu9255::new(42);
        a.set_errors(errors);
        b.set_errors(errors);
        let xs: Vec<i16> = (0..4000).map(|_| gyro_z(&mut a)).collect();
        let ys: Vec<i16> = (0..4000).map(|_| gyro_z(&mut b)).collect();
        assert_eq!(xs, ys);
        // Power-on range is ±250 °/s: 131 LSB per °/s.
        let lsb_rad_s = (1.0f64 / 131.0).to_radians();
        let values: Vec<f64> = xs.iter().map(|&x| f64::from(x) * lsb_rad_s).collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let std = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>()
            / (values.len() - 1) as f64)
            .sqrt();
        assert!(mean.abs() < 0.001, "mean {mean}");
        assert!((std - 0.01).abs() < 0.001, "std {std}");
        let mut c = SimMpu9255::new(43);
        c.set_errors(errors);
        let zs: Vec<i16> = (0..100).map(|_| gyro_z(&mut c)).collect();
        assert_ne!(zs, xs[..100]);
    }

    #[test]
    fn sleeping_chip_reads_zero_and_read_only_registers_hold() {
        let mut sim = SimMpu9255::new(0);
        sim.set_motion(SimMotion {
            rate_rad_s: [0.0, 0.0, 1.0],
            ..SimMotion::default()
        });
        assert_ne!(gyro_z(&mut sim), 0);
        sim.write(DEFAULT_ADDRESS, &[PWR_MGMT_1, 0x41]).unwrap();
        assert_eq!(gyro_z(&mut sim), 0);
        sim.write(DEFAULT_ADDRESS, &[WHO_AM_I, 0x00]).unwrap();
        assert_eq!(sim.register(WHO_AM_I), WHO_AM_I_MPU9255);
        assert_eq!(sim.writes(), [(PWR_MGMT_1, 0x41), (WHO_AM_I, 0x00)]);
    }
}
