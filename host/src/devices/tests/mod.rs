//! The real device threads tested without hardware: the Mega and the X4 over
//! pseudo-terminals against emulated devices (the Mega's own `protocol::mcu`, an X4 built
//! on the simulator's packet encoder), and the IMU thread against a mock I2C bus (the
//! simulator's MPU9255). Every wait has a deadline; the emulated devices pace themselves on
//! the wall clock as the real ones do.

pub(crate) mod fake_mega;
pub(crate) mod fake_x4;
pub(crate) mod mega_bench;
pub(crate) mod pty;

mod imu_mock;
mod mega_pty;
mod real_devices;
mod x4_pty;
