//! The Arduino Mega on a serial port.
//!
//! The thread reads with a short timeout, feeds the bytes through the core's sans-I/O
//! [`MegaLink`] stamped at arrival, and sends telemetry and resets to the loop. The loop
//! writes the core's command (speed references, or the operator's open-loop PWM as `K`
//! frames) through a [`MegaHandle`] on its own 50 Hz tick, never only in reply to telemetry
//! (original-system.md §10.1).
//!
//! - **Opening resets the board** (DTR): nothing is written until the Mega has spoken (its
//!   `r`) or `[link] mega_sync_timeout_ms` has passed, so the bootloader never sees our
//!   frames; telemetry read before that `r` was sent before the reset and is dropped.
//! - **Unplug**: a read error or a vanished port reports [`Input::DeviceFault`] with
//!   `reconnecting` (the core holds the robot still until the Mega streams again), drops the write half, and the thread reopens the port every
//!   `[link] reconnect_period_ms` and resynchronises ([`MegaLink::reset`], wait for `r`)
//!   without restarting `ratf`. Away longer than `[link] give_up_after_s`: [`Message::Gone`].
//! - **Host watchdog** (§10.2, on the age of the last reference): if the core produced no
//!   references for [`DEFAULT_REFERENCE_TIMEOUT_US`], this thread writes zero references
//!   and magnet off every control period until the core speaks again.
//! - **Controller settings**: the config's gains, feed-forward, dead zone, battery voltage
//!   and ticks per revolution go to the Mega before the first write, after every `r` and
//!   when its `y` does not confirm them ([`SettingsSync`]), ahead of the next batch.
//! - **Open-loop hold** (`ratf check`): while a [`OpenLoopHold`] is in force this thread
//!   resends its `K` PWM and `L` every control period instead
//!   ([`MegaHandle::hold_open_loop`]).

use std::io::{ErrorKind, Read};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ratf_core::drivers::mega_link::{
    DEFAULT_REFERENCE_TIMEOUT_US, MegaEvent, MegaLink, MegaLinkConfig, MegaLinkStats,
    reference_is_stale,
};
use ratf_core::drivers::mega_settings::SettingsSync;
use ratf_core::runtime::{DeviceKind, Input, Stamped, Timestamp, WheelCommand};
use ratf_protocol::mcu::McuConfig;
use serialport::SerialPort;

use super::open_loop::{OpenLoopHold, batch_due};
use super::{Clock, DeviceSender, HOST_TICK_PERIOD_US, LinkState, Message, Shared, report};

/// Read timeout of the port: how often the thread looks at the watchdog and the quit flag.
const READ_TIMEOUT: Duration = Duration::from_millis(5);

/// Where the Mega is and how to keep it.
#[derive(Clone, Debug, PartialEq)]
pub struct MegaSettings {
    /// The port's path.
    pub port: String,
    /// Baud rate.
    pub baud: u32,
    /// The link's settings (checksums, the firmware's telemetry latency).
    pub link: MegaLinkConfig,
    /// How long to wait for the Mega to speak after opening before writing anyway.
    pub sync_timeout: Duration,
    /// How often a lost port is tried again.
    pub reconnect_period: Duration,
    /// Away this long: gone for good.
    pub give_up_after: Duration,
    /// The host watchdog's timeout, µs.
    pub watchdog_timeout_us: u64,
    /// The controller settings sent to the Mega (from `[mega]`, `robot` and `motor`).
    pub controller: McuConfig,
}

impl MegaSettings {
    /// The settings of `config`.
    pub fn from_config(config: &ratf_core::config::Config) -> Self {
        Self {
            port: config.link.mega_port.clone(),
            baud: config.link.mega_baud,
            link: MegaLinkConfig {
                send_checksums: config.mega.send_checksums,
                baud: config.link.mega_baud,
                telemetry_latency_us: config.mega.telemetry_latency_us,
            },
            sync_timeout: Duration::from_millis(config.link.mega_sync_timeout_ms.into()),
            reconnect_period: Duration::from_millis(config.link.reconnect_period_ms.into()),
            give_up_after: Duration::from_secs(config.link.give_up_after_s.into()),
            watchdog_timeout_us: DEFAULT_REFERENCE_TIMEOUT_US,
            controller: config.mcu_config(),
        }
    }
}

/// Open a serial port `path` at `baud`, 8N1, no flow control, with a short read timeout.
pub fn open_port(path: &str, baud: u32) -> serialport::Result<Box<dyn SerialPort>> {
    serialport::new(path, baud)
        .timeout(READ_TIMEOUT)
        .flow_control(serialport::FlowControl::None)
        .open()
}

/// The write half: the port (once the Mega has spoken), the encoder, the watchdog's memory.
struct Writer {
    port: Option<Box<dyn SerialPort>>,
    link: MegaLink,
    /// When the core last produced references (clock µs).
    last_reference_us: Option<u64>,
    /// When anything was last written (clock µs), for the watchdog's pace.
    last_write_us: Option<u64>,
    batches_written: u64,
    watchdog_batches: u64,
    /// The open-loop hold in force, if any.
    hold: Option<OpenLoopHold>,
    /// Batches written for holds: all, and those with the magnet on.
    held_batches: (u64, u64),
    /// The reading half's link counters, as last published by the thread.
    link_stats: Option<MegaLinkStats>,
    /// The controller settings and whether they are due.
    settings: SettingsSync,
}

impl std::fmt::Debug for Writer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Writer")
            .field("open", &self.port.is_some())
            .field("last_reference_us", &self.last_reference_us)
            .field("batches_written", &self.batches_written)
            .field("watchdog_batches", &self.watchdog_batches)
            .field("hold", &self.hold)
            .finish()
    }
}

impl Writer {
    /// Write the settings batch first if it is due; false if the port failed.
    fn settings_first(&mut self) -> bool {
        let Some(port) = self.port.as_mut() else {
            return false;
        };
        let Some(bytes) = self.settings.take_due(&mut self.link) else {
            return true;
        };
        if port.write_all(&bytes).is_ok() {
            return true;
        }
        // The reading thread sees the port go and reconnects; the settings stay due.
        self.settings.mark_due();
        self.port = None;
        false
    }

    fn write(&mut self, command: &WheelCommand, now_us: u64) -> bool {
        if !self.settings_first() {
            return false;
        }
        let Some(port) = self.port.as_mut() else {
            return false;
        };
        let Ok(bytes) = command.encode(&mut self.link) else {
            return false;
        };
        match port.write_all(&bytes).and_then(|()| port.flush()) {
            Ok(()) => {
                self.last_write_us = Some(now_us);
                self.batches_written += 1;
                true
            }
            // The reading thread sees the port go and reconnects.
            Err(_) => {
                self.port = None;
                false
            }
        }
    }

    /// Write `hold`'s PWM and magnet now (and count it); false if not writable.
    fn write_hold(&mut self, hold: &OpenLoopHold, now_us: u64) -> bool {
        if !self.settings_first() {
            return false;
        }
        let Some(port) = self.port.as_mut() else {
            return false;
        };
        let bytes = self.link.encode_pwm(hold.pwm, hold.solenoid_on);
        match port.write_all(&bytes).and_then(|()| port.flush()) {
            Ok(()) => {
                self.last_write_us = Some(now_us);
                self.held_batches.0 += 1;
                self.held_batches.1 += u64::from(hold.solenoid_on);
                true
            }
            Err(_) => {
                self.port = None;
                false
            }
        }
    }
}

/// The loop's side of the Mega: write references, stop the robot. Cloned into the thread
/// (watchdog) and the exit paths.
#[derive(Clone, Debug)]
pub struct MegaHandle {
    writer: Arc<Mutex<Writer>>,
}

impl MegaHandle {
    /// A handle with no port yet; `link` encodes the batches, `controller` holds the
    /// settings sent to the Mega.
    pub fn new(link: MegaLinkConfig, controller: McuConfig) -> Self {
        Self {
            writer: Arc::new(Mutex::new(Writer {
                port: None,
                link: MegaLink::new(link),
                last_reference_us: None,
                last_write_us: None,
                batches_written: 0,
                watchdog_batches: 0,
                hold: None,
                held_batches: (0, 0),
                link_stats: None,
                settings: SettingsSync::new(controller),
            })),
        }
    }

    // A panic elsewhere must not keep the robot from stopping: a poisoned lock is used as
    // it is (the writer holds no invariant a panic could break half-way).
    fn lock(&self) -> MutexGuard<'_, Writer> {
        self.writer.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Write the core's references now (and feed the host watchdog); false if the Mega is
    /// not writable (not synchronised yet, or lost).
    pub fn send_references(&self, command: &WheelCommand, now: Timestamp) -> bool {
        let mut writer = self.lock();
        writer.last_reference_us = Some(now.as_us());
        writer.write(command, now.as_us())
    }

    /// Zero references and magnet off, now, ending any open-loop hold (best effort: false
    /// if the Mega is not writable).
    pub fn stop(&self, now: Timestamp) -> bool {
        let mut writer = self.lock();
        writer.hold = None;
        writer.write(&WheelCommand::STOP, now.as_us())
    }

    /// Hold `hold` (open-loop PWM and the magnet): written now if the Mega is writable, then
    /// resent by the Mega's thread every control period while it is in force, so the
    /// Mega's 100 ms watchdog never cuts it. Replaces any earlier hold.
    pub fn hold_open_loop(&self, hold: OpenLoopHold, now: Timestamp) {
        let mut writer = self.lock();
        writer.hold = Some(hold);
        if hold.active_at(now.as_us()) {
            writer.write_hold(&hold, now.as_us());
        }
    }

    /// Batches written for open-loop holds so far: all, and those with the magnet on.
    pub fn held_batches_written(&self) -> (u64, u64) {
        self.lock().held_batches
    }

    /// The reading half's link counters (corrupt batches, resets, …), as the thread last
    /// published them; `None` before the port's first read.
    pub fn link_stats(&self) -> Option<MegaLinkStats> {
        self.lock().link_stats
    }

    fn note_link_stats(&self, stats: MegaLinkStats) {
        self.lock().link_stats = Some(stats);
    }

    fn note_event(&self, event: &MegaEvent) {
        self.lock().settings.on_event(event);
    }

    fn settings_due(&self) {
        self.lock().settings.mark_due();
    }

    /// Settings batches sent so far, and whether the Mega's latest `y` confirms them
    /// (false for an original Mega, which does not acknowledge).
    pub fn settings_state(&self) -> (u32, bool) {
        let writer = self.lock();
        (writer.settings.sends(), writer.settings.confirmed())
    }

    /// Batches written so far: by the core, and by the watchdog.
    pub fn batches_written(&self) -> (u64, u64) {
        let writer = self.lock();
        (writer.batches_written, writer.watchdog_batches)
    }

    fn install(&self, port: Option<Box<dyn SerialPort>>) {
        self.lock().port = port;
    }

    fn writable(&self) -> bool {
        self.lock().port.is_some()
    }

    /// The host watchdog at `now_us`: zero references if the core's last is stale, at most
    /// once per control period; an open-loop hold in force is resent instead.
    fn watchdog(&self, now_us: u64, timeout_us: u64) {
        let mut writer = self.lock();
        if let Some(hold) = writer.hold.filter(|h| h.active_at(now_us)) {
            if batch_due(writer.last_write_us, now_us, HOST_TICK_PERIOD_US) {
                writer.write_hold(&hold, now_us);
            }
            return;
        }
        let stale = reference_is_stale(writer.last_reference_us, now_us, timeout_us);
        let due = writer
            .last_write_us
            .is_none_or(|last| now_us.saturating_sub(last) >= HOST_TICK_PERIOD_US);
        if stale && due && writer.write(&WheelCommand::STOP, now_us) {
            writer.watchdog_batches += 1;
        }
    }
}

/// Run the Mega's thread on `port` (already opened and checked by the caller).
pub fn spawn(
    settings: MegaSettings,
    port: Box<dyn SerialPort>,
    clock: Clock,
    tx: DeviceSender,
    handle: MegaHandle,
    shared: Shared,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("mega".to_owned())
        .spawn(move || MegaThread::new(settings, clock, tx, handle, shared).run(port))
}

struct MegaThread {
    settings: MegaSettings,
    clock: Clock,
    tx: DeviceSender,
    handle: MegaHandle,
    shared: Shared,
    link: MegaLink,
}

impl MegaThread {
    fn new(
        settings: MegaSettings,
        clock: Clock,
        tx: DeviceSender,
        handle: MegaHandle,
        shared: Shared,
    ) -> Self {
        Self {
            link: MegaLink::new(settings.link),
            settings,
            clock,
            tx,
            handle,
            shared,
        }
    }

    fn run(mut self, first: Box<dyn SerialPort>) {
        let mut port = Some(first);
        let mut lost_since: Option<Instant> = None;
        while !self.shared.quitting() {
            let Some(open) = port.take() else {
                // Lost: wait, retry, give up after a while.
                let since = *lost_since.get_or_insert_with(Instant::now);
                if since.elapsed() >= self.settings.give_up_after {
                    report(
                        &self.tx,
                        Message::Gone {
                            device: DeviceKind::Mega,
                            message: format!(
                                "{}: away for {} s; check the USB cable and [link] mega_port",
                                self.settings.port,
                                self.settings.give_up_after.as_secs()
                            ),
                        },
                    );
                    return;
                }
                std::thread::sleep(self.settings.reconnect_period);
                port = open_port(&self.settings.port, self.settings.baud).ok();
                continue;
            };
            lost_since = None;
            let reason = self.session(open);
            if self.shared.quitting() {
                // The run is ending: the write half stays, for the way out's zero
                // references and magnet off (run.rs, StopGuard), which may come after.
                return;
            }
            self.handle.install(None);
            let alive = report(
                &self.tx,
                Message::Input(Stamped::new(
                    self.clock.now(),
                    Input::DeviceFault {
                        device: DeviceKind::Mega,
                        message: format!("{}: {reason}; reconnecting", self.settings.port),
                        reconnecting: true,
                    },
                )),
            ) && report(
                &self.tx,
                Message::Link(DeviceKind::Mega, LinkState::Reconnecting),
            );
            if !alive {
                return;
            }
        }
    }

    /// Read from an open port until it fails (the reason) or the run quits.
    fn session(&mut self, mut port: Box<dyn SerialPort>) -> String {
        // Opening reset the board: start over, and write nothing until it speaks.
        self.link.reset();
        self.handle.settings_due();
        let mut writer = match port.try_clone() {
            Ok(clone) => Some(clone),
            Err(e) => return format!("cannot share the port: {e}"),
        };
        report(
            &self.tx,
            Message::Link(DeviceKind::Mega, LinkState::Syncing),
        );
        let opened = Instant::now();
        let mut buf = [0u8; 512];
        let mut inputs = Vec::new();
        // Telemetry read before this session's `r` was sent before the reset (it waited in
        // the port's buffers): it would tell the core the Mega speaks again, with the wheel
        // counters of its life before. Dropped until the `r`, or until the sync timeout for a
        // Mega that does not reset on opening.
        let mut rebooted = false;
        while !self.shared.quitting() {
            match port.read(&mut buf) {
                Ok(0) => return "the port closed".to_owned(),
                Ok(n) => {
                    let now = self.clock.now();
                    let handle = &self.handle;
                    let unsynced_too_long = opened.elapsed() >= self.settings.sync_timeout;
                    self.link.feed(&buf[..n], now.as_us(), |event| match event {
                        MegaEvent::Telemetry(telemetry) if rebooted || unsynced_too_long => {
                            handle.note_event(&event);
                            inputs.push(Input::Wheels(telemetry));
                        }
                        MegaEvent::Telemetry(_) => {}
                        MegaEvent::Reset { .. } => {
                            rebooted = true;
                            handle.note_event(&event);
                            inputs.push(Input::MegaReset);
                        }
                    });
                    self.handle.note_link_stats(self.link.stats());
                    if !inputs.is_empty() && writer.is_some() {
                        self.handle.install(writer.take());
                        report(&self.tx, Message::Link(DeviceKind::Mega, LinkState::Up));
                    }
                    for input in inputs.drain(..) {
                        if !report(&self.tx, Message::Input(Stamped::new(now, input))) {
                            return "the loop ended".to_owned();
                        }
                    }
                }
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::Interrupted) => {}
                Err(e) => return format!("read failed: {e}"),
            }
            if writer.is_some() && opened.elapsed() >= self.settings.sync_timeout {
                // A Mega that did not reset on opening: it needs references all the same.
                self.handle.install(writer.take());
                report(&self.tx, Message::Link(DeviceKind::Mega, LinkState::Up));
            }
            if self.handle.writable() {
                self.handle
                    .watchdog(self.clock.now().as_us(), self.settings.watchdog_timeout_us);
            }
            super::drill::check();
        }
        "quit".to_owned()
    }
}

#[cfg(test)]
#[path = "tests/mega_session.rs"]
mod session_tests;
