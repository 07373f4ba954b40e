//! The core's guard against driving blind: a lidar or a Mega that has spoken and then fell
//! silent holds the robot still, wheels at zero at once and the magnet off
//! [`MAGNET_OFF_AFTER_US`] later, until it speaks again. A revolution without a single
//! point counts as silence: in a walled field the X4 always sees something, so an empty
//! revolution is a blinded or failing lidar, and the robot would drive on odometry alone.
//!
//! The devices report a port that vanished ([`super::Input::DeviceFault`], which stops the
//! robot for good), but a device that stays plugged in and stops sending (an X4 whose motor
//! stalled, a Mega that hangs or reboots, a cable that only carries power) reaches the core
//! only as silence. Before this guard the core drove on wheel odometry until the lidar
//! thread's `[link] lidar_spinup_timeout_ms` (5 s) or for ever in the simulator (issue 17).
//!
//! The hold is not latched: a lidar dropout or a Mega reset is over when data flows again,
//! and the mission goes on (the magnet comes back on where the mission wants it, taking up
//! again a part it let go in place). Nothing is armed before the device's first data, so
//! bring-up is unchanged.

use super::event::Event;
use super::input::{DeviceKind, Input};
use crate::config::Config;

/// Lidar silence that holds the robot, in revolution periods: 2, one revolution may be in
/// flight when the lidar stops and one late revolution is allowed for the X4's rotation
/// speed variation (its datasheet gives 6–12 Hz for the motor; ours is regulated, so one
/// period of slack is an assumption). At 7 Hz: 286 ms.
pub const LIDAR_SILENCE_REVOLUTIONS: f64 = 2.0;

/// Mega silence that holds the robot, in control periods: 3 (60 ms at 50 Hz): two missed
/// telemetry batches plus one period of USB jitter (assumption).
pub const MEGA_SILENCE_PERIODS: u64 = 3;

/// How long after the wheels stop the magnet lets go, µs: 100 ms, the motors' 0.1 s time
/// constant, so a carried part is let go with the robot nearly at rest and stays at the
/// magnet's face, where the magnet takes it up again when the hold ends (within the 150 ms
/// issue 17 allows for both).
pub const MAGNET_OFF_AFTER_US: u64 = 100_000;

/// What the guard asks of the robot now.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Hold {
    /// Wheels at zero.
    pub wheels: bool,
    /// Magnet off.
    pub magnet: bool,
}

/// One watched device.
#[derive(Clone, Copy, Debug)]
struct Watch {
    device: DeviceKind,
    limit_us: u64,
    last_us: Option<u64>,
    silent: bool,
}

impl Watch {
    fn new(device: DeviceKind, limit_us: u64) -> Self {
        Self {
            device,
            limit_us,
            last_us: None,
            silent: false,
        }
    }

    /// How long the device has been silent past its limit (`None` while it speaks); an
    /// event on each change.
    fn check(&mut self, now_us: u64, events: &mut Vec<Event>) -> Option<u64> {
        let last_us = self.last_us?;
        let over_us = now_us
            .saturating_sub(last_us)
            .checked_sub(self.limit_us + 1);
        let silent = over_us.is_some();
        if silent != self.silent {
            self.silent = silent;
            events.push(if silent {
                Event::DeviceSilent {
                    device: self.device,
                    silent_ms: self.limit_us / 1_000,
                }
            } else {
                Event::DeviceBack {
                    device: self.device,
                }
            });
        }
        over_us
    }
}

/// The lidar's and the Mega's silence, watched on the core's own inputs.
#[derive(Clone, Copy, Debug)]
pub struct SilenceGuard {
    lidar: Watch,
    mega: Watch,
}

impl SilenceGuard {
    /// Limits from `config`: [`LIDAR_SILENCE_REVOLUTIONS`] of `[lidar] scan_rate_hz` and
    /// [`MEGA_SILENCE_PERIODS`] of `[mega] control_period_us`.
    pub fn new(config: &Config) -> Self {
        let revolution_us = 1e6 / config.lidar.scan_rate_hz.max(1e-3);
        Self {
            lidar: Watch::new(
                DeviceKind::Lidar,
                (LIDAR_SILENCE_REVOLUTIONS * revolution_us) as u64,
            ),
            mega: Watch::new(
                DeviceKind::Mega,
                MEGA_SILENCE_PERIODS * u64::from(config.mega.control_period_us),
            ),
        }
    }

    /// A sensor input arrived at `now_us`. The Mega's watch is armed by its first telemetry
    /// batch (its reset frame alone comes before it streams), the lidar's by its first scan
    /// with a point; an empty scan is silence.
    pub fn heard(&mut self, input: &Input, now_us: u64) {
        match input {
            Input::Scan(scan) if !scan.points.is_empty() => self.lidar.last_us = Some(now_us),
            Input::Wheels(_) => self.mega.last_us = Some(now_us),
            Input::MegaReset if self.mega.last_us.is_some() => self.mega.last_us = Some(now_us),
            _ => {}
        }
    }

    /// What the robot must hold at `now_us`; events as devices fall silent and come back.
    pub fn check(&mut self, now_us: u64, events: &mut Vec<Event>) -> Hold {
        let lidar = self.lidar.check(now_us, events);
        let mega = self.mega.check(now_us, events);
        let over_us = lidar.max(mega);
        Hold {
            wheels: over_us.is_some(),
            magnet: over_us.is_some_and(|us| us >= MAGNET_OFF_AFTER_US),
        }
    }
}
