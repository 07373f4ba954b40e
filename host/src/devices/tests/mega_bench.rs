//! The Mega's real device thread ([`crate::devices::mega`]) on a pseudo-terminal whose far
//! end is [`FakeMega`], with the test playing the loop: it reads the thread's messages and,
//! when asked, writes the core's references every host tick.

use std::sync::mpsc::Receiver;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ratf_core::drivers::mega_link::MegaLinkConfig;
use ratf_core::runtime::{DeviceKind, Input, WheelCommand};
use ratf_protocol::mcu::McuConfig;

use super::fake_mega::FakeMega;
use super::pty::{Pty, TempDir};
use crate::devices::mega::{self, MegaHandle, MegaSettings, open_port};
use crate::devices::{Clock, HOST_TICK_PERIOD_US, LinkState, Message, Shared};

/// How long the fake Mega takes from its port's opening to its `r` (the bootloader's wait).
pub(crate) const BOOT_DELAY: Duration = Duration::from_millis(200);

/// The device thread's settings for the bench: waits for `r` far longer than the boot
/// delay, retries a lost port every 50 ms, gives up after 10 s, keeps
/// [`tuned_controller`] on the Mega.
pub(crate) fn settings(port: String) -> MegaSettings {
    MegaSettings {
        port,
        baud: 115_200,
        link: MegaLinkConfig::default(),
        sync_timeout: Duration::from_secs(2),
        reconnect_period: Duration::from_millis(50),
        give_up_after: Duration::from_secs(10),
        watchdog_timeout_us: 200_000,
        controller: tuned_controller(),
    }
}

/// The controller settings the bench's host keeps on the Mega: the defaults with other
/// gains and a lower voltage limit, so a Mega that did not get them is told apart.
pub(crate) fn tuned_controller() -> McuConfig {
    let mut config = McuConfig::default();
    config.pi.gains.kc_v_per_rad_s = 0.6;
    config.pi.gains.ki_v_per_rad = 5.0;
    config.voltage_limit_v = 10.5;
    config
}

/// The bench: see the module documentation.
pub(crate) struct MegaBench {
    /// The Mega.
    pub(crate) mega: FakeMega,
    /// The loop's handle on the Mega.
    pub(crate) handle: MegaHandle,
    /// The run's clock.
    pub(crate) clock: Clock,
    /// Every message from the thread, with its arrival.
    pub(crate) messages: Vec<(Instant, Message)>,
    /// When the loop last wrote the core's references (just before the write).
    pub(crate) last_sent: Option<Instant>,
    shared: Shared,
    rx: Receiver<Message>,
    thread: Option<JoinHandle<()>>,
    next_send: Instant,
    _dir: TempDir,
}

impl MegaBench {
    /// A Mega on a fresh pseudo-terminal and the device thread on it, opened as `ratf run`
    /// opens it.
    pub(crate) fn start(name: &str) -> Self {
        let dir = TempDir::new(name);
        let pty = Pty::open(&dir.0.join("mega"));
        let settings = settings(pty.path());
        let port = open_port(&settings.port, settings.baud).expect("the pty opens");
        let clock = Clock::start();
        let shared = Shared::new();
        let (tx, rx) = crate::devices::inbox(&shared);
        let handle = MegaHandle::new(settings.link, settings.controller);
        let thread = mega::spawn(settings, port, clock, tx, handle.clone(), shared.clone())
            .expect("the thread starts");
        Self {
            mega: FakeMega::new(pty, BOOT_DELAY),
            handle,
            clock,
            messages: Vec::new(),
            last_sent: None,
            shared,
            rx,
            thread: Some(thread),
            next_send: Instant::now(),
            _dir: dir,
        }
    }

    /// Quit the device thread and wait for it (the host goes quiet).
    pub(crate) fn stop_thread(&mut self) {
        self.shared.request_quit();
        if let Some(thread) = self.thread.take() {
            thread.join().expect("the Mega's thread does not panic");
        }
    }

    /// True while the device thread runs.
    pub(crate) fn thread_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// The inputs the thread sent at or after `since`.
    pub(crate) fn inputs_since(&self, since: Instant) -> impl Iterator<Item = &Input> {
        self.messages
            .iter()
            .filter(move |(at, _)| *at >= since)
            .filter_map(|(_, m)| match m {
                Message::Input(stamped) => Some(&stamped.input),
                _ => None,
            })
    }

    /// Telemetry batches received at or after `since`.
    pub(crate) fn telemetry_since(&self, since: Instant) -> usize {
        self.inputs_since(since)
            .filter(|i| matches!(i, Input::Wheels(_)))
            .count()
    }

    /// The Mega's link as the thread last reported it.
    pub(crate) fn link(&self) -> Option<LinkState> {
        self.messages.iter().rev().find_map(|(_, m)| match m {
            Message::Link(DeviceKind::Mega, state) => Some(*state),
            _ => None,
        })
    }

    /// Be the Mega (and, with `core`, the loop writing `core` every host tick) for `span`.
    pub(crate) fn run_for(&mut self, span: Duration, core: Option<WheelCommand>) {
        let end = Instant::now() + span;
        while Instant::now() < end {
            self.step(core, end);
        }
    }

    /// Run as [`MegaBench::run_for`] until `done`; panics naming `what` after `timeout`.
    pub(crate) fn wait_for(
        &mut self,
        timeout: Duration,
        core: Option<WheelCommand>,
        what: &str,
        done: impl Fn(&Self) -> bool,
    ) {
        let deadline = Instant::now() + timeout;
        while !done(self) {
            assert!(
                Instant::now() < deadline,
                "{what}: not within {timeout:?}\n{}",
                self.summary()
            );
            self.step(core, deadline);
        }
    }

    fn step(&mut self, core: Option<WheelCommand>, end: Instant) {
        let now = Instant::now();
        if let Some(command) = core {
            if now >= self.next_send {
                self.last_sent = Some(now);
                self.handle.send_references(&command, self.clock.now());
                self.next_send = now + Duration::from_micros(HOST_TICK_PERIOD_US);
            }
        } else {
            self.next_send = now;
        }
        let until = end.min(now + Duration::from_millis(2));
        let until = if core.is_some() {
            until.min(self.next_send)
        } else {
            until
        };
        self.mega.service(until);
        while let Ok(message) = self.rx.try_recv() {
            self.messages.push((Instant::now(), message));
        }
    }

    fn summary(&self) -> String {
        let last: Vec<String> = self
            .messages
            .iter()
            .rev()
            .take(8)
            .map(|(_, m)| match m {
                Message::Input(s) => format!("input {}", s.input.kind()),
                other => format!("{other:?}"),
            })
            .collect();
        format!(
            "{} messages (last first: {last:?}); Mega: {} boots, {} host batches, {} ticks; \
             batches written (core, watchdog) {:?}",
            self.messages.len(),
            self.mega.boots.len(),
            self.mega.batches.len(),
            self.mega.ticks.len(),
            self.handle.batches_written()
        )
    }
}

impl Drop for MegaBench {
    fn drop(&mut self) {
        self.shared.request_quit();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
