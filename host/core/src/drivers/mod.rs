//! Device protocol layers: bytes or register reads in → typed, timestamped data out.
//!
//! Layering: each module here is the *pure* protocol half of a device driver. It takes the
//! bytes received (or, for I2C, talks to an [`embedded_hal::i2c::I2c`]) and the receive time
//! passed in by the caller, and never opens a port or reads a clock. The simulator feeds
//! these layers the simulated devices' bytes; on the Pi, the real ports (serial via
//! `serialport`, I2C via `linux-embedded-hal`) will sit beside them and feed them the same
//! way, so the code that decodes the real robot's data is the code the simulation tests.
//!
//! - [`imu`]: the MPU9255 accelerometer + gyro over embedded-hal I2C, its start-up gyro
//!   bias estimate, and a simulated chip;
//! - [`mega_link`]: the host side of the Mega serial link (telemetry batches in, wheel
//!   references out, the host watchdog);
//! - [`mega_settings`]: when to send the Mega its controller settings (start-up, after a
//!   reset, when its acknowledgement does not confirm them);
//! - [`x4`]: the YDLIDAR X4 scan protocol (parser, scan assembler, encoder for the
//!   simulator).
//!
//! Times are microseconds on the caller's monotonic clock: `u64` for receive times passed
//! in, `f64` for estimated times (an X4 scan's acquisition stamp).
#![forbid(unsafe_code)]

pub mod imu;
pub mod mega_link;
pub mod mega_settings;
pub mod x4;
