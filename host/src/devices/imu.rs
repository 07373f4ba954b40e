//! The IMU (MPU9255) over I2C, optional: `[link] imu = "none"` or a missing bus means no
//! IMU inputs. The bus is behind [`ImuSource`], so the loop and its tests do not need I2C;
//! on the Pi it is `linux-embedded-hal`'s `I2cdev` ([`open_i2c`]).

use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ratf_core::drivers::imu::{Chip, ImuError, ImuSample, Mpu9255};
use ratf_core::runtime::{DeviceKind, Input, Stamped};

use super::{Clock, DeviceSender, LinkState, Message, Shared, report};

/// Read period, µs (200 Hz, the rate the driver configures).
pub const IMU_PERIOD_US: u64 = 5_000;
/// Consecutive failed reads after which the IMU is given up (the robot runs on without).
pub const MAX_FAILED_READS: u32 = 20;

/// Something that gives IMU samples in the chip's axes.
pub trait ImuSource: Send {
    /// One reading, taken now (`now_us` on the robot's clock).
    fn read(&mut self, now_us: u64) -> Result<ImuSample, ImuError>;
}

impl<I: embedded_hal::i2c::I2c + Send> ImuSource for Mpu9255<I> {
    fn read(&mut self, now_us: u64) -> Result<ImuSample, ImuError> {
        self.read_sample(now_us)
    }
}

/// Open the I2C bus `path` and configure the MPU9255 on it (`[robot.imu]`).
pub fn open_i2c(
    path: &str,
    config: &ratf_core::config::ImuConfig,
) -> Result<Box<dyn ImuSource>, String> {
    let bus = linux_embedded_hal::I2cdev::new(path).map_err(|e| format!("{path}: {e}"))?;
    let imu = Mpu9255::new(bus, config.driver_config()).map_err(|e| format!("{path}: {e}"))?;
    Ok(Box::new(imu))
}

/// Open the I2C bus `path` and configure the MPU9255 on it (`[robot.imu]`), telling which
/// chip answered (its `WHO_AM_I`), for `ratf check`.
pub fn open_i2c_chip(
    path: &str,
    config: &ratf_core::config::ImuConfig,
) -> Result<(Chip, Box<dyn ImuSource>), String> {
    let bus = linux_embedded_hal::I2cdev::new(path).map_err(|e| format!("{path}: {e}"))?;
    let imu = Mpu9255::new(bus, config.driver_config()).map_err(|e| format!("{path}: {e}"))?;
    Ok((imu.chip(), Box::new(imu)))
}

/// Read `source` every [`IMU_PERIOD_US`], turn each sample into the robot's axes (`yaw_rad`,
/// `[robot.imu] yaw_deg`) and send it stamped when it was read. After
/// [`MAX_FAILED_READS`] failures in a row the thread ends and the link shows as lost.
pub fn spawn(
    mut source: Box<dyn ImuSource>,
    yaw_rad: f64,
    clock: Clock,
    tx: DeviceSender,
    shared: Shared,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("imu".to_owned())
        .spawn(move || {
            report(&tx, Message::Link(DeviceKind::Imu, LinkState::Up));
            let period = Duration::from_micros(IMU_PERIOD_US);
            let mut next = Instant::now();
            let mut failures = 0;
            while !shared.quitting() {
                let now = clock.now();
                match source.read(now.as_us()) {
                    Ok(sample) => {
                        failures = 0;
                        let input = Input::Imu(sample.rotated_about_z(yaw_rad));
                        if !report(&tx, Message::Input(Stamped::new(now, input))) {
                            return;
                        }
                    }
                    Err(_) => {
                        failures += 1;
                        if failures >= MAX_FAILED_READS {
                            report(&tx, Message::Link(DeviceKind::Imu, LinkState::Reconnecting));
                            return;
                        }
                    }
                }
                next += period;
                let now = Instant::now();
                if next > now {
                    std::thread::sleep(next - now);
                } else {
                    next = now;
                }
            }
        })
}
