//! The core's guard against driving blind: a lidar or a Mega that has spoken and then fell
//! silent holds the robot still, wheels at zero at once and the magnet off
//! [`MAGNET_OFF_AFTER_US`] later, until it speaks again. A revolution without a single
//! point counts as silence: in a walled field the X4 always sees something, so an empty
//! revolution is a blinded or failing lidar, and the robot would drive on odometry alone.
//!
//! The devices report a port that vanished ([`super::Input::DeviceFault`] with
//! `reconnecting`, which holds the robot the same way from that instant until the device
//! speaks again, [`SilenceGuard::lost`]), but a device that stays plugged in and stops
//! sending (an X4 whose motor stalled, a Mega that hangs or reboots, a cable that only
//! carries power) reaches the core only as silence. Before this guard the core drove on wheel odometry until the lidar
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
    /// When its port was lost (its thread reconnecting), µs: silent from then until it
    /// speaks again, whatever its limit.
    lost_us: Option<u64>,
    silent: bool,
}

impl Watch {
    fn new(device: DeviceKind, limit_us: u64) -> Self {
        Self {
            device,
            limit_us,
            last_us: None,
            lost_us: None,
            silent: false,
        }
    }

    /// How long the device has been silent past its limit (`None` while it speaks); an
    /// event on each change.
    fn check(&mut self, now_us: u64, events: &mut Vec<Event>) -> Option<u64> {
        let over_us = match (self.lost_us, self.last_us) {
            (Some(lost_us), _) => Some(now_us.saturating_sub(lost_us)),
            (None, Some(last_us)) => now_us
                .saturating_sub(last_us)
                .checked_sub(self.limit_us + 1),
            (None, None) => None,
        };
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
    /// with a point; an empty scan is silence. A lost device is back with the same data:
    /// the Mega with a telemetry batch (odometry flows again, not its reset frame alone),
    /// the lidar with a scan with a point.
    pub fn heard(&mut self, input: &Input, now_us: u64) {
        match input {
            Input::Scan(scan) if !scan.points.is_empty() => {
                self.lidar.last_us = Some(now_us);
                self.lidar.lost_us = None;
            }
            Input::Wheels(_) => {
                self.mega.last_us = Some(now_us);
                self.mega.lost_us = None;
            }
            Input::MegaReset if self.mega.last_us.is_some() => self.mega.last_us = Some(now_us),
            _ => {}
        }
    }

    /// `device`'s port was lost at `now_us` (its thread reports a fault and reconnects): it
    /// holds the robot as a silent device does, from now (wheels at the next tick, the
    /// magnet [`MAGNET_OFF_AFTER_US`] later), until it speaks again ([`Self::heard`]). The
    /// fault is the event: no [`Event::DeviceSilent`] follows, [`Event::DeviceBack`] does.
    /// False for a device the guard does not watch (the IMU, the server).
    pub fn lost(&mut self, device: DeviceKind, now_us: u64) -> bool {
        let watch = match device {
            DeviceKind::Lidar => &mut self.lidar,
            DeviceKind::Mega => &mut self.mega,
            DeviceKind::Imu | DeviceKind::Referee => return false,
        };
        // A second fault while lost (a failed reopen) keeps the first instant.
        watch.lost_us.get_or_insert(now_us);
        watch.silent = true;
        true
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
