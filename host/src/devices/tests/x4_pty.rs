//! The lidar's device thread over a pseudo-terminal against an emulated X4: check-code
//! errors, packets read in pieces, a stream starting mid-packet, a lidar that never answers,
//! the device information and health asked before the scan (answered, ignored, an error), a
//! lidar that stops sending with its port open.

use std::sync::mpsc::Receiver;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ratf_core::drivers::x4::info::{Health, HealthStatus, Request};
use ratf_core::drivers::x4::scan::{Scan, ScanConfig};
use ratf_core::drivers::x4::{Command, Received};
use ratf_core::runtime::{DeviceKind, Input};

use super::fake_x4::{FakeX4, Fault, HEALTH_ERROR_CODE, INFO, PER_PACKET, SAMPLES, distance_mm};
use super::pty::{Pty, TempDir};
use crate::devices::lidar::{self, LidarHandle, LidarIdentity, LidarSettings};
use crate::devices::mega::open_port;
use crate::devices::{Clock, LinkState, Message, Shared};

/// The lidar's thread on an emulated X4, the test playing the loop.
struct LidarBench {
    x4: FakeX4,
    handle: LidarHandle,
    messages: Vec<(Instant, Message)>,
    shared: Shared,
    rx: Receiver<Message>,
    thread: Option<JoinHandle<()>>,
    _dir: TempDir,
}

impl LidarBench {
    /// An X4 with `fault`, and the thread on it with a spin-up timeout of `spinup` and
    /// giving up after `give_up`.
    fn start(name: &str, fault: Fault, spinup: Duration, give_up: Duration) -> Self {
        let dir = TempDir::new(name);
        let pty = Pty::open(&dir.0.join("lidar"));
        let settings = LidarSettings {
            port: pty.path(),
            baud: 128_000,
            scan: ScanConfig::default(),
            spinup_timeout: spinup,
            reconnect_period: Duration::from_millis(50),
            give_up_after: give_up,
        };
        let port = open_port(&settings.port, settings.baud).expect("the pty opens");
        let shared = Shared::new();
        let (tx, rx) = crate::devices::inbox(&shared);
        let handle = LidarHandle::new();
        let thread = lidar::spawn(
            settings,
            port,
            Clock::start(),
            tx,
            handle.clone(),
            shared.clone(),
        )
        .expect("the thread starts");
        Self {
            x4: FakeX4::new(pty, fault),
            handle,
            messages: Vec::new(),
            shared,
            rx,
            thread: Some(thread),
            _dir: dir,
        }
    }

    fn scans(&self) -> Vec<&Scan> {
        self.messages
            .iter()
            .filter_map(|(_, m)| match m {
                Message::Input(s) => match &s.input {
                    Input::Scan(scan) => Some(scan),
                    _ => None,
                },
                _ => None,
            })
            .collect()
    }

    fn faults(&self) -> Vec<&str> {
        self.messages
            .iter()
            .filter_map(|(_, m)| match m {
                Message::Input(s) => match &s.input {
                    Input::DeviceFault {
                        device: DeviceKind::Lidar,
                        message,
                        ..
                    } => Some(message.as_str()),
                    _ => None,
                },
                _ => None,
            })
            .collect()
    }

    fn gone(&self) -> Option<&str> {
        self.messages.iter().find_map(|(_, m)| match m {
            Message::Gone {
                device: DeviceKind::Lidar,
                message,
            } => Some(message.as_str()),
            _ => None,
        })
    }

    fn links(&self) -> Vec<LinkState> {
        self.messages
            .iter()
            .filter_map(|(_, m)| match m {
                Message::Link(DeviceKind::Lidar, state) => Some(*state),
                _ => None,
            })
            .collect()
    }

    /// Be the X4 until `done`; panics naming `what` after `timeout`.
    fn wait_for(&mut self, timeout: Duration, what: &str, done: impl Fn(&Self) -> bool) {
        let deadline = Instant::now() + timeout;
        while !done(self) {
            assert!(
                Instant::now() < deadline,
                "{what}: not within {timeout:?}; X4 commands {:?}, {} scans, links {:?}, \
                 faults {:?}",
                self.x4.commands,
                self.scans().len(),
                self.links(),
                self.faults()
            );
            self.x4
                .service(deadline.min(Instant::now() + Duration::from_millis(2)));
            while let Ok(message) = self.rx.try_recv() {
                self.messages.push((Instant::now(), message));
            }
        }
    }
}

impl Drop for LidarBench {
    fn drop(&mut self) {
        self.shared.request_quit();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Every kept point of `scan` is a sample the X4 sent, in range and in order.
fn assert_points_are_the_samples_sent(scan: &Scan) {
    let sent: Vec<f64> = (0..SAMPLES)
        .map(|k| (distance_mm(k) * 4.0).round() / 4.0 / 1000.0)
        .collect();
    let mut at = 0;
    for point in &scan.points {
        let found = sent[at..].iter().position(|&r| r == point.range_m);
        let Some(offset) = found else {
            panic!("a range of {} m the X4 never sent", point.range_m);
        };
        at += offset + 1;
    }
}

#[test]
fn scans_come_whole_through_check_code_errors_and_packets_read_in_pieces() {
    let mut bench = LidarBench::start(
        "x4-checksum",
        Fault::CorruptOddRevolutions,
        Duration::from_secs(2),
        Duration::from_secs(10),
    );
    // The X4 stays silent until the core asks.
    bench.wait_for(Duration::from_secs(2), "the port open", |b| {
        b.links() == [LinkState::Syncing]
    });
    assert!(bench.x4.commands.is_empty());
    bench.handle.start_scan();
    bench.wait_for(Duration::from_secs(5), "six revolutions", |b| {
        b.scans().len() >= 6
    });
    let scans = bench.scans();
    for (k, scan) in scans.iter().enumerate() {
        let (dropped, samples) = if k % 2 == 1 {
            (1, SAMPLES - PER_PACKET)
        } else {
            (0, SAMPLES)
        };
        assert_eq!(
            (
                scan.packets_dropped,
                scan.samples as usize,
                scan.points.len()
            ),
            (dropped, samples, samples),
            "revolution {k}"
        );
        assert_points_are_the_samples_sent(scan);
    }
    assert!(
        scans.windows(2).all(|w| w[0].stamp_us < w[1].stamp_us),
        "stamps in order"
    );
    assert_eq!(bench.links(), [LinkState::Syncing, LinkState::Up]);
    assert!(bench.faults().is_empty(), "{:?}", bench.faults());
    assert_eq!(bench.x4.starts(), 1);

    // The way out: every thread quits, then the loop stops the lidar (one stop came
    // already, before the start command).
    let stops = |b: &LidarBench| {
        b.x4.commands
            .iter()
            .filter(|(_, c)| *c == Command::StopScan)
            .count()
    };
    let stops_before = stops(&bench);
    bench.shared.request_quit();
    let thread = bench.thread.take().expect("the thread");
    let deadline = Instant::now() + Duration::from_secs(2);
    while !thread.is_finished() {
        assert!(Instant::now() < deadline, "the thread did not end");
        bench.x4.service(Instant::now() + Duration::from_millis(5));
    }
    thread.join().expect("no panic");
    bench.handle.stop_scan();
    bench.wait_for(Duration::from_secs(1), "the stop command", |b| {
        stops(b) > stops_before
    });
}

#[test]
fn a_stream_starting_mid_packet_is_picked_up_at_the_next_revolution() {
    let mut bench = LidarBench::start(
        "x4-mid-packet",
        Fault::StartsMidPacket,
        Duration::from_secs(2),
        Duration::from_secs(10),
    );
    bench.handle.start_scan();
    bench.wait_for(Duration::from_secs(5), "three revolutions", |b| {
        b.scans().len() >= 3
    });
    for scan in bench.scans() {
        assert_eq!(
            (scan.packets_dropped, scan.points.len()),
            (0, SAMPLES),
            "{scan:?}"
        );
        assert_points_are_the_samples_sent(scan);
    }
    assert!(bench.faults().is_empty(), "{:?}", bench.faults());
}

#[test]
fn a_lidar_that_never_answers_is_reported_with_its_port_then_given_up() {
    let spinup = Duration::from_millis(300);
    let mut bench = LidarBench::start("x4-silent", Fault::Silent, spinup, Duration::from_secs(1));
    let port = bench.x4.pty.path();
    bench.handle.start_scan();
    bench.wait_for(Duration::from_secs(3), "a spin-up fault", |b| {
        !b.faults().is_empty()
    });
    assert_eq!(
        bench.faults()[0],
        format!("{port}: no scan after the start command (spin-up) for 300 ms; reconnecting")
    );
    let fault_at = bench
        .messages
        .iter()
        .find(
            |(_, m)| matches!(m, Message::Input(s) if matches!(s.input, Input::DeviceFault { .. })),
        )
        .map(|(at, _)| *at)
        .expect("the fault");
    let first_start = bench.x4.commands[0].0;
    assert!(fault_at >= first_start + spinup, "before the spin-up time");

    bench.wait_for(Duration::from_secs(5), "the lidar given up", |b| {
        b.gone().is_some()
    });
    let gone = bench.gone().expect("gone");
    assert!(
        gone.starts_with(&format!("{port}: away or silent for 1 s"))
            && gone.contains("[link] lidar_port"),
        "{gone}"
    );
    assert!(
        bench.x4.starts() >= 2,
        "the start command is sent again after reopening: {:?}",
        bench.x4.commands
    );
    let thread = bench.thread.take().expect("the thread");
    let deadline = Instant::now() + Duration::from_secs(2);
    while !thread.is_finished() {
        assert!(Instant::now() < deadline, "the thread did not end");
        bench.x4.service(Instant::now() + Duration::from_millis(5));
    }
    thread.join().expect("no panic");
}

#[test]
fn an_unplugged_lidar_is_reopened_and_started_again() {
    let mut bench = LidarBench::start(
        "x4-replug",
        Fault::CorruptOddRevolutions,
        Duration::from_secs(2),
        Duration::from_secs(10),
    );
    let port = bench.x4.pty.path();
    bench.handle.start_scan();
    bench.wait_for(Duration::from_secs(5), "scans", |b| b.scans().len() >= 2);
    bench.x4.pty.unplug();
    bench.wait_for(Duration::from_secs(2), "a fault naming the port", |b| {
        b.links().last() == Some(&LinkState::Reconnecting)
    });
    let faults = bench.faults();
    assert_eq!(faults.len(), 1, "{faults:?}");
    assert!(
        faults[0].starts_with(&format!("{port}: read failed"))
            && faults[0].ends_with("; reconnecting"),
        "{faults:?}"
    );
    let before = bench.scans().len();
    bench.x4.pty.replug();
    bench.wait_for(Duration::from_secs(5), "scans again", |b| {
        b.scans().len() >= before + 2
    });
    assert_eq!(
        bench.x4.starts(),
        2,
        "the start command again after reopening"
    );
    assert_eq!(
        bench.links(),
        [
            LinkState::Syncing,
            LinkState::Up,
            LinkState::Reconnecting,
            LinkState::Syncing,
            LinkState::Up
        ]
    );
    assert!(bench.gone().is_none());
}

#[test]
fn a_lidar_that_stops_sending_with_its_port_open_is_reported_before_a_revolution_is_missed() {
    let spinup = Duration::from_secs(2);
    let mut bench = LidarBench::start(
        "x4-stops",
        Fault::CorruptOddRevolutions,
        spinup,
        Duration::from_secs(10),
    );
    let port = bench.x4.pty.path();
    bench.handle.start_scan();
    bench.wait_for(Duration::from_secs(5), "scans", |b| b.scans().len() >= 2);
    assert_eq!(
        bench.faults(),
        Vec::<&str>::new(),
        "a stream paced as an X4's"
    );
    bench.x4.fall_silent();
    let silent_at = Instant::now();
    bench.wait_for(Duration::from_secs(1), "a fault", |b| {
        !b.faults().is_empty()
    });
    assert_eq!(
        bench.faults(),
        [format!("{port}: no packet for 50 ms; holding until it streams again").as_str()]
    );
    assert!(
        silent_at.elapsed() < spinup,
        "reported by the packets' watch, not by the spin-up timeout's reopening"
    );
    assert_eq!(
        bench.links().last(),
        Some(&LinkState::Up),
        "the port stays open"
    );
    assert!(
        bench.messages.iter().any(|(_, m)| matches!(
            m,
            Message::Input(s) if matches!(s.input, Input::DeviceFault { reconnecting: true, .. })
        )),
        "the core holds the robot until the lidar speaks again"
    );
}

/// What the thread sends before the scan: stop, device information, health, start.
const BEFORE_THE_SCAN: [Received; 4] = [
    Received::Command(Command::StopScan),
    Received::Request(Request::DeviceInfo),
    Received::Request(Request::Health),
    Received::Command(Command::StartScan),
];

#[test]
fn device_info_and_health_are_asked_for_before_the_scan_starts() {
    let mut bench = LidarBench::start(
        "x4-identity",
        Fault::CorruptOddRevolutions,
        Duration::from_secs(2),
        Duration::from_secs(10),
    );
    bench.handle.start_scan();
    bench.wait_for(Duration::from_secs(5), "two revolutions", |b| {
        b.scans().len() >= 2
    });
    assert_eq!(bench.x4.received[..4], BEFORE_THE_SCAN);
    assert_eq!(
        bench.handle.identity(),
        Some(LidarIdentity {
            info: Some(INFO),
            health: Some(Health {
                status: HealthStatus::Ok,
                error_code: 0,
            }),
        })
    );
    assert!(bench.faults().is_empty(), "{:?}", bench.faults());
}

#[test]
fn a_lidar_that_ignores_info_and_health_is_still_started_and_used() {
    let mut bench = LidarBench::start(
        "x4-clone",
        Fault::NoIdentity,
        Duration::from_secs(2),
        Duration::from_secs(10),
    );
    bench.handle.start_scan();
    bench.wait_for(Duration::from_secs(5), "two revolutions", |b| {
        b.scans().len() >= 2
    });
    assert_eq!(bench.x4.received[..4], BEFORE_THE_SCAN);
    assert_eq!(bench.handle.identity(), Some(LidarIdentity::default()));
    for scan in bench.scans() {
        assert_eq!(scan.points.len(), SAMPLES, "{scan:?}");
    }
    assert!(bench.faults().is_empty(), "{:?}", bench.faults());
    assert_eq!(bench.links(), [LinkState::Syncing, LinkState::Up]);
}

#[test]
fn a_health_error_is_a_device_fault_naming_the_error_code() {
    let mut bench = LidarBench::start(
        "x4-health",
        Fault::HealthError,
        Duration::from_secs(2),
        Duration::from_secs(10),
    );
    let port = bench.x4.pty.path();
    bench.handle.start_scan();
    bench.wait_for(Duration::from_secs(5), "the fault and a revolution", |b| {
        !b.faults().is_empty() && !b.scans().is_empty()
    });
    assert_eq!(
        bench.faults(),
        [format!(
            "{port}: the X4 reports a health error (error code 0x{HEALTH_ERROR_CODE:04X}); \
             power it off and on again, and replace it if the error stays"
        )]
    );
    assert_eq!(bench.x4.received[..4], BEFORE_THE_SCAN);
}
