//! The check's thin I/O layer: the device threads' messages sorted into the current
//! windows, the Mega's open-loop hold, questions polled while the devices keep being read.

use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use ratf_core::drivers::mega_link::MegaLinkStats;
use ratf_core::runtime::{DeviceKind, Input, Stamped};

use super::imu::ImuWindow;
use super::lidar::{BeaconSearch, LidarWindow};
use super::mega::MegaWindow;
use super::operator::{Answer, Operator, yes_no};
use crate::devices::lidar::LidarHandle;
use crate::devices::mega::MegaHandle;
use crate::devices::open_loop::OpenLoopHold;
use crate::devices::{Clock, LinkState, Message, Shared};

/// Longest the loop sleeps before looking at the interrupt flag again.
const POLL: Duration = Duration::from_millis(20);

/// What a question got.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Asked {
    /// Yes.
    Yes,
    /// No (or an empty line).
    No,
    /// Something else.
    Unknown,
    /// Nobody answers (standard input closed).
    NoAnswer,
}

/// The devices as the check sees them.
pub struct Session<'a> {
    clock: Clock,
    rx: Receiver<Message>,
    interrupt: &'a Shared,
    search: BeaconSearch,
    /// Some telemetry came since the port was opened: a reset before it is the boot that
    /// opening the port caused, not a fault.
    telemetry_seen: bool,
    /// The Mega's writer (holds, stop, link counters).
    pub mega: MegaHandle,
    /// The lidar's handle (what the X4 said of itself).
    pub lidar: LidarHandle,
    /// Telemetry since the window began.
    pub mega_window: MegaWindow,
    /// The Mega link's counters when the window's first batch came.
    pub mega_stats_start: Option<MegaLinkStats>,
    /// Scans since the window began.
    pub lidar_window: LidarWindow,
    /// IMU samples since the window began.
    pub imu_window: ImuWindow,
}

impl<'a> Session<'a> {
    /// A session on `rx` (the device threads' channel); `interrupt` is Ctrl-C's flag.
    pub fn new(
        clock: Clock,
        rx: Receiver<Message>,
        interrupt: &'a Shared,
        search: BeaconSearch,
        mega: MegaHandle,
        lidar: LidarHandle,
    ) -> Self {
        Self {
            clock,
            rx,
            interrupt,
            search,
            telemetry_seen: false,
            mega,
            lidar,
            mega_window: MegaWindow::default(),
            mega_stats_start: None,
            lidar_window: LidarWindow::default(),
            imu_window: ImuWindow::default(),
        }
    }

    /// Now, on the robot's clock, µs.
    pub fn now_us(&self) -> u64 {
        self.clock.now().as_us()
    }

    /// Start a new Mega window.
    pub fn restart_mega_window(&mut self) {
        self.mega_window = MegaWindow::default();
        self.mega_stats_start = None;
    }

    /// Hold `hold` on the Mega now (resent every tick by its thread).
    pub fn hold(&self, hold: OpenLoopHold) {
        self.mega.hold_open_loop(hold, self.clock.now());
    }

    /// Read the devices for `wait` (at least what has arrived); false if interrupted
    /// (Ctrl-C) meanwhile.
    pub fn pump(&mut self, wait: Duration) -> bool {
        let deadline = Instant::now() + wait;
        loop {
            if self.interrupt.quitting() {
                return false;
            }
            while let Ok(message) = self.rx.try_recv() {
                self.dispatch(message);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return true;
            }
            match self.rx.recv_timeout(left.min(POLL)) {
                Ok(message) => self.dispatch(message),
                Err(RecvTimeoutError::Timeout) => {}
                // No device thread left: only time passes.
                Err(RecvTimeoutError::Disconnected) => std::thread::sleep(left.min(POLL)),
            }
        }
    }

    fn dispatch(&mut self, message: Message) {
        match message {
            Message::Input(Stamped { time, input }) => match input {
                Input::Wheels(telemetry) => {
                    if self.mega_window.batches() == 0 {
                        self.mega_stats_start = self.mega.link_stats();
                    }
                    self.mega_window.on_telemetry(&telemetry, time.as_us());
                    self.telemetry_seen = true;
                }
                Input::MegaReset if self.telemetry_seen => self.mega_window.on_reset(),
                Input::Scan(scan) => self.lidar_window.on_scan(&scan, time.as_us(), &self.search),
                Input::Imu(sample) => self.imu_window.on_sample(&sample, time.as_us()),
                Input::DeviceFault {
                    device, message, ..
                } => self.fault(device, &message),
                _ => {}
            },
            Message::Link(DeviceKind::Imu, LinkState::Reconnecting) => self.imu_window.on_lost(),
            Message::Link(..) => {}
            Message::Gone { device, message } => self.fault(device, &message),
        }
    }

    fn fault(&mut self, device: DeviceKind, message: &str) {
        match device {
            DeviceKind::Mega => self.mega_window.on_fault(message),
            DeviceKind::Lidar => self.lidar_window.on_fault(message),
            DeviceKind::Imu => self.imu_window.on_lost(),
            DeviceKind::Referee => {}
        }
    }

    /// Ask `question` and read the devices until it is answered; `None` if interrupted.
    pub fn ask(&mut self, operator: &mut dyn Operator, question: &str) -> Option<Asked> {
        operator.ask(question);
        loop {
            if !self.pump(Duration::ZERO) {
                return None;
            }
            match operator.poll(POLL) {
                Answer::Line(line) => {
                    return Some(match yes_no(&line) {
                        Some(true) => Asked::Yes,
                        Some(false) => Asked::No,
                        None => Asked::Unknown,
                    });
                }
                Answer::Pending => {}
                Answer::Closed => return Some(Asked::NoAnswer),
            }
        }
    }

    /// Ask for an action and wait for Enter (reading the devices): `Some(Some(line))`,
    /// `Some(None)` if nobody answers (standard input closed), `None` if interrupted.
    pub fn wait_enter(
        &mut self,
        operator: &mut dyn Operator,
        prompt: &str,
    ) -> Option<Option<String>> {
        operator.ask(prompt);
        loop {
            if !self.pump(Duration::ZERO) {
                return None;
            }
            match operator.poll(POLL) {
                Answer::Line(line) => return Some(Some(line)),
                Answer::Pending => {}
                Answer::Closed => return Some(None),
            }
        }
    }
}

/// Stops the robot when dropped — every way out of the check, unwinding from a panic
/// included: the open-loop hold ended, zero references and magnet off, the lidar stopped.
#[derive(Debug)]
pub struct StopGuard {
    /// The Mega.
    pub mega: MegaHandle,
    /// The lidar.
    pub lidar: LidarHandle,
    /// The robot's clock.
    pub clock: Clock,
}

impl Drop for StopGuard {
    fn drop(&mut self) {
        self.mega.stop(self.clock.now());
        self.lidar.stop_scan();
    }
}
