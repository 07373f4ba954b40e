//! The YDLIDAR X4 on a serial port at 128000 baud (`serialport` sets the rate through
//! termios2/BOTHER; crates.md §1).
//!
//! The thread reads with a short timeout and feeds the core's sans-I/O [`X4Driver`]
//! (which hunts packet headers, so a stream starting mid-packet, the 7-byte response
//! descriptor and garbage are skipped), stamping each revolution when its last byte
//! arrived. The X4 sends nothing until its start command `A5 60`, which the loop writes
//! when the core asks ([`LidarHandle::start_scan`]).
//!
//! - **Identity**: before each start command (after opening or reopening the port) the
//!   thread sends stop, then asks for the device information (`A5 90`) and the health
//!   (`A5 91`), waiting [`PROBE_TIMEOUT`] for each reply. What comes is kept in the handle
//!   ([`LidarHandle::identity`]); a health *error* is reported as [`Input::DeviceFault`]
//!   naming the X4's error code. A lidar that answers neither is still started and used:
//!   clones of the X4 may not implement the two requests.
//! - **Spin-up**: after the start command the X4 may stay silent while its motor comes up
//!   to speed; if no revolution arrives within `[link] lidar_spinup_timeout_ms` (or the
//!   stream stops that long), the port is reopened and the command sent again.
//! - **A stream that stops**: packets silent for [`LIDAR_PACKET_SILENCE_US`] (an X4 that
//!   stopped sending with its port open) are reported as [`Input::DeviceFault`] with
//!   `reconnecting`, so the core holds the robot at once, not two revolutions later; the
//!   port is reopened only after the spin-up timeout below.
//! - **Reconnection**: a read error or a vanished port reports [`Input::DeviceFault`] with
//!   `reconnecting` (the core holds the robot still until scans come again), and
//!   the thread reopens the port every `[link] reconnect_period_ms`, sending the start
//!   command again if the core had asked for it. Away longer than `[link] give_up_after_s`:
//!   [`Message::Gone`].

use std::io::{ErrorKind, Read};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ratf_core::drivers::x4::info::{DeviceInfo, Health, HealthStatus, Reply, ReplyParser, Request};
use ratf_core::drivers::x4::scan::ScanConfig;
use ratf_core::drivers::x4::{Command, X4Driver};
use ratf_core::runtime::{DeviceKind, Input, LIDAR_PACKET_SILENCE_US, PacketWatch, Stamped};
use serialport::SerialPort;

use super::mega::open_port;
use super::{Clock, DeviceSender, LinkState, Message, Shared, report};

/// How long the thread waits for each reply to the device-information and health requests
/// (the replies are 27 and 10 bytes, about 2 ms on the line; YDLIDAR's SDK waits 500 ms).
pub const PROBE_TIMEOUT: Duration = Duration::from_millis(300);

/// What the X4 said about itself at the last (re)opening: `None` where it did not answer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LidarIdentity {
    /// The reply to the device-information request.
    pub info: Option<DeviceInfo>,
    /// The reply to the health request.
    pub health: Option<Health>,
}

/// Where the lidar is and how to keep it.
#[derive(Clone, Debug, PartialEq)]
pub struct LidarSettings {
    /// The port's path.
    pub port: String,
    /// Baud rate (128000).
    pub baud: u32,
    /// Ranges kept.
    pub scan: ScanConfig,
    /// Silence after the start command (or in the stream) before starting over.
    pub spinup_timeout: Duration,
    /// How often a lost port is tried again.
    pub reconnect_period: Duration,
    /// Away this long: gone for good.
    pub give_up_after: Duration,
}

impl LidarSettings {
    /// The settings of `config`.
    pub fn from_config(config: &ratf_core::config::Config) -> Self {
        Self {
            port: config.link.lidar_port.clone(),
            baud: config.link.lidar_baud,
            scan: ScanConfig {
                range_min_m: config.lidar.min_range_m,
                range_max_m: config.lidar.max_range_m,
                ..ScanConfig::default()
            },
            spinup_timeout: Duration::from_millis(config.link.lidar_spinup_timeout_ms.into()),
            reconnect_period: Duration::from_millis(config.link.reconnect_period_ms.into()),
            give_up_after: Duration::from_secs(config.link.give_up_after_s.into()),
        }
    }
}

/// The loop's side of the lidar: the write half of the port and whether the core asked it
/// to scan.
#[derive(Clone, Debug)]
pub struct LidarHandle {
    port: Arc<Mutex<Option<Box<dyn SerialPort>>>>,
    wanted: Arc<AtomicBool>,
    identity: Arc<Mutex<Option<LidarIdentity>>>,
}

impl Default for LidarHandle {
    fn default() -> Self {
        Self::new()
    }
}

impl LidarHandle {
    /// A handle with no port yet.
    pub fn new() -> Self {
        Self {
            port: Arc::new(Mutex::new(None)),
            wanted: Arc::new(AtomicBool::new(false)),
            identity: Arc::new(Mutex::new(None)),
        }
    }

    /// What the X4 said about itself before its last start command (`None` before the
    /// first), for the wiring check and the logs.
    pub fn identity(&self) -> Option<LidarIdentity> {
        *self.identity.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn lock(&self) -> MutexGuard<'_, Option<Box<dyn SerialPort>>> {
        self.port.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The core asks for scans: the thread sends the start command within a read timeout
    /// (5 ms), and again after every reconnection.
    pub fn start_scan(&self) {
        self.wanted.store(true, Ordering::SeqCst);
    }

    /// Stop scanning (on the way out), best effort.
    pub fn stop_scan(&self) {
        self.wanted.store(false, Ordering::SeqCst);
        self.command(Command::StopScan);
    }

    fn scanning_wanted(&self) -> bool {
        self.wanted.load(Ordering::SeqCst)
    }

    fn command(&self, command: Command) -> bool {
        self.write(&command.bytes())
    }

    fn write(&self, bytes: &[u8]) -> bool {
        let mut port = self.lock();
        let Some(writer) = port.as_mut() else {
            return false;
        };
        if writer
            .write_all(bytes)
            .and_then(|()| writer.flush())
            .is_err()
        {
            *port = None;
            return false;
        }
        true
    }

    fn install(&self, port: Option<Box<dyn SerialPort>>) {
        *self.lock() = port;
    }
}

/// Run the lidar's thread on `port` (already opened and checked by the caller).
pub fn spawn(
    settings: LidarSettings,
    port: Box<dyn SerialPort>,
    clock: Clock,
    tx: DeviceSender,
    handle: LidarHandle,
    shared: Shared,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("lidar".to_owned())
        .spawn(move || run(&settings, port, clock, &tx, &handle, &shared))
}

fn run(
    settings: &LidarSettings,
    first: Box<dyn SerialPort>,
    clock: Clock,
    tx: &DeviceSender,
    handle: &LidarHandle,
    shared: &Shared,
) {
    let mut port = Some(first);
    let mut lost_since: Option<Instant> = None;
    while !shared.quitting() {
        let Some(open) = port.take() else {
            let since = *lost_since.get_or_insert_with(Instant::now);
            if since.elapsed() >= settings.give_up_after {
                report(
                    tx,
                    Message::Gone {
                        device: DeviceKind::Lidar,
                        message: format!(
                            "{}: away or silent for {} s; check the USB cable, the lidar's \
                             power and [link] lidar_port",
                            settings.port,
                            settings.give_up_after.as_secs()
                        ),
                    },
                );
                return;
            }
            std::thread::sleep(settings.reconnect_period);
            port = open_port(&settings.port, settings.baud).ok();
            continue;
        };
        let (reason, delivered) = session(settings, open, clock, tx, handle, shared);
        if shared.quitting() {
            // The write half stays for the way out's stop command, which may come after.
            return;
        }
        handle.install(None);
        if delivered {
            lost_since = None;
        }
        let alive = report(
            tx,
            Message::Input(Stamped::new(
                clock.now(),
                Input::DeviceFault {
                    device: DeviceKind::Lidar,
                    message: format!("{}: {reason}; reconnecting", settings.port),
                    reconnecting: true,
                },
            )),
        ) && report(
            tx,
            Message::Link(DeviceKind::Lidar, LinkState::Reconnecting),
        );
        if !alive {
            return;
        }
    }
}

/// Read from an open port until it fails or goes silent (the reason; whether any scan came)
/// or the run quits.
fn session(
    settings: &LidarSettings,
    mut port: Box<dyn SerialPort>,
    clock: Clock,
    tx: &DeviceSender,
    handle: &LidarHandle,
    shared: &Shared,
) -> (String, bool) {
    let mut driver = X4Driver::new(settings.scan);
    let mut packets = PacketWatch::new(LIDAR_PACKET_SILENCE_US);
    match port.try_clone() {
        Ok(clone) => handle.install(Some(clone)),
        Err(e) => return (format!("cannot share the port: {e}"), false),
    }
    let mut started_at: Option<Instant> = None;
    let mut last_scan: Option<Instant> = None;
    let mut delivered = false;
    let mut buf = [0u8; 1024];
    let mut scans = Vec::new();
    report(tx, Message::Link(DeviceKind::Lidar, LinkState::Syncing));
    while !shared.quitting() {
        if started_at.is_none() && handle.scanning_wanted() {
            // The core asked (once: after a reconnection the thread asks again).
            let identity = match probe(&mut port, handle, shared) {
                Ok(identity) => identity,
                Err(e) => return (format!("read failed: {e}"), delivered),
            };
            *handle
                .identity
                .lock()
                .unwrap_or_else(PoisonError::into_inner) = Some(identity);
            if let Some(health) = identity.health.filter(|h| h.status == HealthStatus::Error) {
                let message = format!(
                    "{}: the X4 reports a health error (error code 0x{:04X}); power it off \
                     and on again, and replace it if the error stays",
                    settings.port, health.error_code
                );
                // Not a reconnection: the robot stays stopped until the operator resumes.
                let fault = Input::DeviceFault {
                    device: DeviceKind::Lidar,
                    message,
                    reconnecting: false,
                };
                if !report(tx, Message::Input(Stamped::new(clock.now(), fault))) {
                    return ("the loop ended".to_owned(), delivered);
                }
            }
            handle.command(Command::StartScan);
            started_at = Some(Instant::now());
        }
        match port.read(&mut buf) {
            Ok(0) => return ("the port closed".to_owned(), delivered),
            Ok(n) => {
                let now = clock.now();
                driver.feed(&buf[..n], now.as_us(), |scan| scans.push(scan));
                for scan in scans.drain(..) {
                    if !delivered {
                        report(tx, Message::Link(DeviceKind::Lidar, LinkState::Up));
                    }
                    delivered = true;
                    last_scan = Some(Instant::now());
                    if !report(tx, Message::Input(Stamped::new(now, Input::Scan(scan)))) {
                        return ("the loop ended".to_owned(), delivered);
                    }
                }
            }
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::Interrupted) => {}
            Err(e) => return (format!("read failed: {e}"), delivered),
        }
        // Checked after feeding what was read: a thread late to read finds the packets that
        // waited for it and reports nothing.
        let now = clock.now();
        if packets.fell_silent(driver.last_packet_us(), now.as_us()) {
            let fault = Input::DeviceFault {
                device: DeviceKind::Lidar,
                message: packets.message(&settings.port),
                reconnecting: true,
            };
            if !report(tx, Message::Input(Stamped::new(now, fault))) {
                return ("the loop ended".to_owned(), delivered);
            }
        }
        if let Some(started) = started_at {
            let silent_since = last_scan.unwrap_or(started).max(started);
            if silent_since.elapsed() >= settings.spinup_timeout {
                let what = if delivered {
                    "the scans stopped"
                } else {
                    "no scan after the start command (spin-up)"
                };
                return (
                    format!("{what} for {} ms", settings.spinup_timeout.as_millis()),
                    delivered,
                );
            }
        }
    }
    ("quit".to_owned(), delivered)
}

/// Stop the X4, then ask for its device information and health, waiting [`PROBE_TIMEOUT`]
/// for each reply. A request without a reply is no error: clones of the X4 may not
/// implement them, and the lidar is started and used all the same. Only a read error fails.
fn probe(
    port: &mut Box<dyn SerialPort>,
    handle: &LidarHandle,
    shared: &Shared,
) -> std::io::Result<LidarIdentity> {
    // Stop first: the X4 takes requests in idle mode, and one still scanning from an
    // earlier run would keep streaming packets between the replies.
    handle.command(Command::StopScan);
    let mut identity = LidarIdentity::default();
    let mut parser = ReplyParser::new();
    let mut buf = [0u8; 256];
    for request in [Request::DeviceInfo, Request::Health] {
        handle.write(&request.bytes());
        let deadline = Instant::now() + PROBE_TIMEOUT;
        let mut answered = false;
        while !answered && Instant::now() < deadline && !shared.quitting() {
            let n = match port.read(&mut buf) {
                Ok(n) => n,
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::Interrupted) => 0,
                Err(e) => return Err(e),
            };
            parser.feed(&buf[..n], |reply| match reply {
                Reply::DeviceInfo(info) => {
                    answered |= request == Request::DeviceInfo;
                    identity.info = Some(info);
                }
                Reply::Health(health) => {
                    answered |= request == Request::Health;
                    identity.health = Some(health);
                }
            });
        }
    }
    Ok(identity)
}
