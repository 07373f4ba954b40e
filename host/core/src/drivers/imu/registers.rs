//! MPU-9250/9255 register addresses and field encodings used by the driver.
//!
//! Source: InvenSense "MPU-9250 Register Map and Descriptions" rev 1.6 (the MPU9255 is
//! register-compatible; it differs in WHO_AM_I). Values are quoted with their meaning.

/// The chip's 7-bit I2C address with AD0 low (the Waveshare 10DOF (B) board,
/// original-system.md §3.3). AD0 high gives 0x69.
pub const DEFAULT_ADDRESS: u8 = 0x68;

/// SMPLRT_DIV: output rate = internal rate / (1 + value); the internal rate is 1 kHz when
/// the DLPF is on (DLPF_CFG 1..=6).
pub const SMPLRT_DIV: u8 = 0x19;
/// CONFIG: bits 2:0 DLPF_CFG (gyro and temperature low-pass filter); bits 5:3
/// EXT_SYNC_SET (0 = off); bit 6 FIFO_MODE (unused).
pub const CONFIG: u8 = 0x1A;
/// GYRO_CONFIG: bits 4:3 GYRO_FS_SEL (full scale); bits 1:0 FCHOICE_B (0 = use the DLPF).
pub const GYRO_CONFIG: u8 = 0x1B;
/// ACCEL_CONFIG: bits 4:3 ACCEL_FS_SEL (full scale).
pub const ACCEL_CONFIG: u8 = 0x1C;
/// ACCEL_CONFIG 2: bit 3 ACCEL_FCHOICE_B (0 = use the DLPF); bits 2:0 A_DLPFCFG.
pub const ACCEL_CONFIG2: u8 = 0x1D;
/// ACCEL_XOUT_H: first of 14 data registers: accel x, y, z, temperature, gyro x, y, z,
/// each a big-endian i16 (high byte first).
pub const ACCEL_XOUT_H: u8 = 0x3B;
/// GYRO_XOUT_H: first of the 6 gyro data registers.
pub const GYRO_XOUT_H: u8 = 0x43;
/// PWR_MGMT_1: bit 7 H_RESET, bit 6 SLEEP, bits 2:0 CLKSEL (1 = PLL when ready, else the
/// internal 20 MHz oscillator).
pub const PWR_MGMT_1: u8 = 0x6B;
/// PWR_MGMT_2: bits 5:0 disable individual accel/gyro axes (0 = all on).
pub const PWR_MGMT_2: u8 = 0x6C;
/// WHO_AM_I: chip identity.
pub const WHO_AM_I: u8 = 0x75;

/// WHO_AM_I of an MPU9250.
pub const WHO_AM_I_MPU9250: u8 = 0x71;
/// WHO_AM_I of an MPU9255.
pub const WHO_AM_I_MPU9255: u8 = 0x73;

/// PWR_MGMT_1 value: awake (SLEEP = 0), CLKSEL = 1 (PLL, the datasheet's recommended clock
/// for full performance).
pub const PWR_MGMT_1_WAKE_PLL: u8 = 0x01;
/// PWR_MGMT_1 SLEEP bit.
pub const PWR_MGMT_1_SLEEP: u8 = 0x40;

/// Temperature sensitivity, LSB/°C (MPU-9250 product specification §3.4.2).
pub const TEMP_LSB_PER_C: f64 = 333.87;
/// Temperature at a reading of 0, °C (register map: TEMP_degC = TEMP_OUT/333.87 + 21).
pub const TEMP_OFFSET_C: f64 = 21.0;
/// Standard gravity, m/s², to convert g to m/s² (the original used 9.8).
pub const STANDARD_GRAVITY_M_S2: f64 = 9.806_65;

/// Gyro full scale (GYRO_FS_SEL).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GyroRange {
    /// ±250 °/s, 131 LSB/(°/s).
    Dps250,
    /// ±500 °/s, 65.5 LSB/(°/s).
    Dps500,
    /// ±1000 °/s, 32.8 LSB/(°/s).
    Dps1000,
    /// ±2000 °/s, 16.4 LSB/(°/s).
    Dps2000,
}

impl GyroRange {
    /// GYRO_FS_SEL (0..=3).
    pub const fn fs_sel(self) -> u8 {
        self as u8
    }

    /// The range GYRO_CONFIG `value` selects.
    pub const fn from_register(value: u8) -> Self {
        match (value >> 3) & 0b11 {
            0 => Self::Dps250,
            1 => Self::Dps500,
            2 => Self::Dps1000,
            _ => Self::Dps2000,
        }
    }

    /// Sensitivity, LSB per °/s (product specification §3.1).
    pub const fn lsb_per_dps(self) -> f64 {
        match self {
            Self::Dps250 => 131.0,
            Self::Dps500 => 65.5,
            Self::Dps1000 => 32.8,
            Self::Dps2000 => 16.4,
        }
    }
}

/// Accelerometer full scale (ACCEL_FS_SEL).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AccelRange {
    /// ±2 g, 16384 LSB/g.
    G2,
    /// ±4 g, 8192 LSB/g.
    G4,
    /// ±8 g, 4096 LSB/g.
    G8,
    /// ±16 g, 2048 LSB/g.
    G16,
}

impl AccelRange {
    /// ACCEL_FS_SEL (0..=3).
    pub const fn fs_sel(self) -> u8 {
        self as u8
    }

    /// The range ACCEL_CONFIG `value` selects.
    pub const fn from_register(value: u8) -> Self {
        match (value >> 3) & 0b11 {
            0 => Self::G2,
            1 => Self::G4,
            2 => Self::G8,
            _ => Self::G16,
        }
    }

    /// Sensitivity, LSB per g (product specification §3.2).
    pub const fn lsb_per_g(self) -> f64 {
        match self {
            Self::G2 => 16384.0,
            Self::G4 => 8192.0,
            Self::G8 => 4096.0,
            Self::G16 => 2048.0,
        }
    }
}

/// Digital low-pass filter setting, written to both DLPF_CFG (gyro) and A_DLPFCFG (accel).
/// Every variant keeps the 1 kHz internal rate, so SMPLRT_DIV applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dlpf {
    /// Gyro 184 Hz (delay 2.9 ms); accel 218.1 Hz.
    Hz184 = 1,
    /// Gyro 92 Hz (3.9 ms); accel 99 Hz.
    Hz92 = 2,
    /// Gyro 41 Hz (5.9 ms); accel 44.8 Hz.
    Hz41 = 3,
    /// Gyro 20 Hz (9.9 ms); accel 21.2 Hz.
    Hz20 = 4,
    /// Gyro 10 Hz (17.85 ms); accel 10.2 Hz.
    Hz10 = 5,
    /// Gyro 5 Hz (33.48 ms); accel 5.05 Hz.
    Hz5 = 6,
}

impl Dlpf {
    /// The 3-bit register field.
    pub const fn code(self) -> u8 {
        self as u8
    }
}
