//! The core's guard against driving blind: a lidar or a Mega that has spoken and then fell
//! silent holds the robot still, wheels at zero at once and the magnet off
//! [`MAGNET_OFF_AFTER_US`] later, until it speaks again. A revolution without a single
//! point counts as silence: in a walled field the X4 always sees something, so an empty
//! revolution is a blinded or failing lidar, and the robot would drive on odometry alone.
//! A lidar that still streams but sees nothing (its port is there, its packets flow) holds
//! the wheels alone: the robot stands still with its part on the magnet for up to
//! [`BLIND_MAGNET_HOLD_US`], so a dropout costs the wait and nothing more (issue 17: with
//! the magnet off, the part fell in front of the robot and was looked for and gripped
//! again after the dropout, and that search ran into walls and parts).
//!
//! The devices report a port that vanished ([`super::Input::DeviceFault`] with
//! `reconnecting`, which holds the robot the same way from that instant until the device
//! speaks again, [`SilenceGuard::lost`]), but a device that stays plugged in and stops
//! sending (an X4 whose motor stalled, a Mega that hangs or reboots, a cable that only
//! carries power) reaches the core only as silence. Before this guard the core drove on wheel odometry until the lidar
//! thread's `[link] lidar_spinup_timeout_ms` (5 s) or for ever in the simulator (issue 17).
//! The lidar's device also watches its packet stream ([`PacketWatch`]): an X4 that stops
//! sending is reported as a fault with `reconnecting` [`LIDAR_PACKET_SILENCE_US`] after its
//! last packet, long before two revolutions are missed; the revolutions' limit stays for a
//! lidar that sends packets without a point.
//!
//! The hold is not latched: a lidar dropout or a Mega reset is over when data flows again,
//! and the mission goes on (the magnet comes back on where the mission wants it, taking up
//! again a part it let go in place; a part it let go on the way, away from its drop, the
//! mission grips again centred on its plate, `mission`'s "Held"). Nothing is armed before
//! the device's first data, so bring-up is unchanged.

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

/// X4 packet silence after which the lidar's device reports its stream stopped, µs: 50 ms.
/// The X4 sends a packet of 40 samples every 8 ms while it scans (5 kHz sampling), and the
/// budget's worst packet latency adds 10 ms spikes to it, the CP2102 5 ms and the host's
/// timestamps a 20 ms tail (real-world-errors.md §1, §8): 50 ms is six packet periods, and
/// it lets the robot stop within issue 17's 150 ms of an X4 that stops for good, which
/// [`LIDAR_SILENCE_REVOLUTIONS`] of silent revolutions (286 ms at 7 Hz) cannot.
pub const LIDAR_PACKET_SILENCE_US: u64 = 50_000;

/// How long after the wheels stop the magnet lets go, µs: 60 ms. Late enough that the robot
/// has shed about half its speed (the motors' 0.1 s time constant), so a carried part falls
/// close to the magnet's face, where it is gripped again when the hold ends (centred on its
/// plate, since the face slides along it as the robot coasts: `mission`'s "Held"); early
/// enough that a device gone for good has the wheels and the magnet off within issue 17's
/// 150 ms: a Mega's last batch + [`MEGA_SILENCE_PERIODS`] (60 ms) + 60 ms + one 20 ms host
/// tick is 141 ms; an X4's last packet + [`LIDAR_PACKET_SILENCE_US`] + 60 ms + a tick, 131 ms.
pub const MAGNET_OFF_AFTER_US: u64 = 60_000;

/// How long a lidar that streams but sees nothing keeps the robot's part on the magnet while
/// the wheels hold, µs: 10 s. A robot standing still with its part held is no danger, and
/// the part needs no search afterwards; past this the lidar is likely broken rather than
/// blinded, and the solenoid is not left on for good (its coil heats). An assumption, far
/// beyond a person's shadow on the lidar or the fault bench's 0.5–3 s dropouts. A lidar
/// whose stream stopped (a port lost, [`LIDAR_PACKET_SILENCE_US`]) lets the part go after
/// [`MAGNET_OFF_AFTER_US`], as a Mega does: issue 17's 150 ms for a device gone for good.
pub const BLIND_MAGNET_HOLD_US: u64 = 10_000_000;

/// What the guard asks of the robot now.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Hold {
    /// Wheels at zero.
    pub wheels: bool,
    /// Magnet off.
    pub magnet: bool,
    /// Whether the Mega speaks, and if not how it fell silent: its magnet then is its own.
    pub mega: MegaHeard,
}

/// Whether the Mega speaks, as the hold sees it; a silent Mega's magnet does what the Mega
/// does, not what the core commands.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MegaHeard {
    /// It speaks: it applies the core's commands within a frame.
    #[default]
    Speaking,
    /// Silent on a port still there: a reset or a hang, whose outputs go off at once (a
    /// reset drops the magnet before the core knows).
    Silent,
    /// Its port lost (the cable out): it runs on the last commands until its own watchdog
    /// stops the wheels, and lets the magnet go
    /// [`ratf_protocol::mcu::SOLENOID_HOLD_AFTER_STOP_US`] later, with the robot almost at
    /// rest.
    PortLost,
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

    /// How long past its limit this device's silence lets the magnet hold, µs: a lidar that
    /// streams but sees nothing, [`BLIND_MAGNET_HOLD_US`]; a lost port or a silent Mega,
    /// [`MAGNET_OFF_AFTER_US`].
    fn magnet_off_after_us(&self) -> u64 {
        match (self.device, self.lost_us) {
            (DeviceKind::Lidar, None) => BLIND_MAGNET_HOLD_US,
            _ => MAGNET_OFF_AFTER_US,
        }
    }

    /// Whether a silence `over_us` past the limit has the magnet off.
    fn magnet_off(&self, over_us: Option<u64>) -> bool {
        over_us.is_some_and(|us| us >= self.magnet_off_after_us())
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
        Hold {
            wheels: lidar.is_some() || mega.is_some(),
            magnet: self.lidar.magnet_off(lidar) || self.mega.magnet_off(mega),
            mega: match (mega, self.mega.lost_us) {
                (None, _) => MegaHeard::Speaking,
                (Some(_), None) => MegaHeard::Silent,
                (Some(_), Some(_)) => MegaHeard::PortLost,
            },
        }
    }
}

/// A device thread's watch on its packet stream (the lidar's: its
/// [`crate::drivers::x4::X4Driver::last_packet_us`]): says once when the stream has been
/// silent longer than its limit, so the thread reports [`Input::DeviceFault`] with
/// `reconnecting` and the core holds the robot ([`SilenceGuard::lost`]) until the device
/// speaks again. Pure: the thread passes the time of its last packet and its clock's now,
/// read after feeding what it read, so a thread that was late to read finds the packets
/// that waited for it and reports nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PacketWatch {
    limit_us: u64,
    reported_after: Option<u64>,
}

impl PacketWatch {
    /// A watch that reports a silence longer than `limit_us`.
    pub const fn new(limit_us: u64) -> Self {
        Self {
            limit_us,
            reported_after: None,
        }
    }

    /// True once per silence: the last packet came at `last_packet_us` (`None`: none yet,
    /// nothing to watch) and `now_us` is more than the limit later.
    pub fn fell_silent(&mut self, last_packet_us: Option<u64>, now_us: u64) -> bool {
        let Some(last_us) = last_packet_us else {
            return false;
        };
        let silent = now_us.saturating_sub(last_us) > self.limit_us;
        let new = silent && self.reported_after != Some(last_us);
        if new {
            self.reported_after = Some(last_us);
        }
        new
    }

    /// What the device reports when its stream fell silent, for an operator.
    pub fn message(&self, port: &str) -> String {
        format!(
            "{port}: no packet for {} ms; holding until it streams again",
            self.limit_us / 1_000
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_packet_stream_is_reported_silent_once_past_its_limit_and_again_after_it_resumes() {
        let mut watch = PacketWatch::new(LIDAR_PACKET_SILENCE_US);
        assert!(
            !watch.fell_silent(None, 1_000_000),
            "nothing before the first packet"
        );
        assert!(!watch.fell_silent(Some(100_000), 150_000), "at the limit");
        assert!(watch.fell_silent(Some(100_000), 150_001));
        assert!(
            !watch.fell_silent(Some(100_000), 900_000),
            "once per silence"
        );
        assert!(
            !watch.fell_silent(Some(910_000), 920_000),
            "streaming again"
        );
        assert!(
            watch.fell_silent(Some(910_000), 960_001),
            "a second silence"
        );
    }

    fn scan_with_points() -> Input {
        Input::Scan(crate::drivers::x4::scan::Scan::points_at_one_metre(0.0, 1))
    }

    /// A lidar that streams but sees nothing holds the wheels and keeps a held part on the
    /// magnet for [`BLIND_MAGNET_HOLD_US`]; the same lidar's port lost lets the part go
    /// [`MAGNET_OFF_AFTER_US`] after the loss. (Before, every hold let the part go after
    /// 60 ms: a dropout dropped it.)
    #[test]
    fn a_blind_lidar_keeps_the_part_and_a_lost_one_lets_it_go() {
        let config = Config::default();
        let limit_us = (LIDAR_SILENCE_REVOLUTIONS * 1e6 / config.lidar.scan_rate_hz) as u64;
        let mut events = Vec::new();
        let mut guard = SilenceGuard::new(&config);
        guard.heard(&scan_with_points(), 0);
        let blind = |guard: &mut SilenceGuard, us: u64, events: &mut Vec<Event>| {
            guard.check(limit_us + 1 + us, events)
        };
        assert_eq!(guard.check(limit_us, &mut events), Hold::default());
        let held = blind(&mut guard, MAGNET_OFF_AFTER_US, &mut events);
        assert!(held.wheels && !held.magnet, "{held:?}");
        let held = blind(&mut guard, BLIND_MAGNET_HOLD_US - 1, &mut events);
        assert!(held.wheels && !held.magnet, "{held:?}");
        let held = blind(&mut guard, BLIND_MAGNET_HOLD_US, &mut events);
        assert!(held.wheels && held.magnet, "{held:?}");
        assert_eq!(
            events,
            [Event::DeviceSilent {
                device: DeviceKind::Lidar,
                silent_ms: limit_us / 1_000
            }]
        );

        // Blind, then its port lost: the part goes 60 ms after the loss.
        let mut guard = SilenceGuard::new(&config);
        guard.heard(&scan_with_points(), 0);
        let lost_at = limit_us + 100_000;
        assert!(!guard.check(lost_at, &mut events).magnet);
        assert!(guard.lost(DeviceKind::Lidar, lost_at));
        assert!(
            !guard
                .check(lost_at + MAGNET_OFF_AFTER_US - 1, &mut events)
                .magnet
        );
        assert!(
            guard
                .check(lost_at + MAGNET_OFF_AFTER_US, &mut events)
                .magnet
        );
        // It streams and sees again: nothing held.
        guard.heard(&scan_with_points(), lost_at + 200_000);
        assert_eq!(guard.check(lost_at + 200_000, &mut events), Hold::default());
    }

    /// The hold says whether the Mega speaks, and if not whether its port is lost or it is
    /// silent on it (its magnet is then its own: the mission does not take the core's
    /// letting go as where the part was left).
    #[test]
    fn a_hold_says_how_the_mega_stands() {
        let config = Config::default();
        let limit_us = MEGA_SILENCE_PERIODS * u64::from(config.mega.control_period_us);
        let mut events = Vec::new();
        let mut guard = SilenceGuard::new(&config);
        guard.heard(&scan_with_points(), 0);
        let batch = Input::Wheels(crate::drivers::mega_link::WheelTelemetry::for_test(
            [0; 4], false, 0,
        ));
        guard.heard(&batch, 0);
        assert!(guard.lost(DeviceKind::Lidar, 1_000));
        let held = guard.check(2_000, &mut events);
        assert!(held.wheels && held.mega == MegaHeard::Speaking, "{held:?}");
        guard.heard(&scan_with_points(), 3_000);
        let held = guard.check(limit_us + 1_000, &mut events);
        assert!(held.wheels && held.mega == MegaHeard::Silent, "{held:?}");
        assert!(guard.lost(DeviceKind::Mega, limit_us + 2_000));
        let held = guard.check(limit_us + 3_000, &mut events);
        assert!(held.wheels && held.mega == MegaHeard::PortLost, "{held:?}");
    }
}
