//! The robot's real devices: one thread per device, each stamping what it reads with one
//! shared monotonic [`Clock`] at arrival and sending it to the loop over a channel;
//! [`RealDevices`] is the runtime's [`Devices`] on that channel, with the host's 50 Hz tick
//! made on the loop's side from the same clock (architecture.md, "The runtime").
//!
//! - [`mega`]: the Arduino Mega on a serial port (`serialport`, no default features): wait
//!   for its `r` after opening (DTR resets it), reopen and resynchronise after an unplug, and
//!   the host watchdog (zero references when the core stalls).
//! - [`lidar`]: the YDLIDAR X4 on a serial port at 128000: the start command when the core
//!   asks, spin-up, reconnection.
//! - [`referee`]: the organisers' server over UDP ([`crate::referee::client::RefereeLink`]:
//!   replies only from the configured address).
//! - [`imu`]: the MPU9255 over I2C, optional, behind [`imu::ImuSource`] so tests can run
//!   without a bus.
//! - [`operator`]: commands from the HMI or the ROS 2 bridge joined into any device set.
//! - [`realtime`]: wall-clock pacing of the simulated world, for watching a round.
//! - [`open_loop`]: the Mega's open-loop hold (`K` PWM and the magnet resent every tick),
//!   for `ratf check`.
//!
//! Device threads never stop the robot by themselves: they report faults as inputs
//! ([`Input::DeviceFault`]), and the core stops driving. [`drill`] makes one of them panic
//! on demand, to prove that a panic stops the robot.

pub mod drill;
pub mod imu;
pub mod lidar;
pub mod mega;
pub mod open_loop;
pub mod operator;
pub mod realtime;
pub mod referee;

#[cfg(test)]
mod tests;

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use ratf_core::runtime::{DeviceKind, Devices, Input, Outputs, Stamped, Timestamp};

use self::lidar::LidarHandle;
use self::mega::MegaHandle;
use self::referee::RefereeHandle;

/// Period of the host's reference timer, µs (50 Hz, the Mega's control rate).
pub const HOST_TICK_PERIOD_US: u64 = 20_000;

/// The robot's one monotonic clock: µs since an [`Instant`] taken at start-up. Every device
/// thread stamps with a copy of it.
#[derive(Clone, Copy, Debug)]
pub struct Clock {
    epoch: Instant,
}

impl Clock {
    /// A clock whose epoch is now.
    pub fn start() -> Self {
        Self {
            epoch: Instant::now(),
        }
    }

    /// Now, on this clock.
    pub fn now(&self) -> Timestamp {
        self.at(Instant::now())
    }

    /// `instant` on this clock (the epoch if earlier).
    pub fn at(&self, instant: Instant) -> Timestamp {
        let us = instant.saturating_duration_since(self.epoch).as_micros();
        Timestamp::from_us(u64::try_from(us).unwrap_or(u64::MAX))
    }

    /// The instant of `time`.
    pub fn instant(&self, time: Timestamp) -> Instant {
        self.epoch + Duration::from_micros(time.as_us())
    }
}

/// How a device's link is, for the status line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkState {
    /// Not opened yet.
    Opening,
    /// Open, waiting for the device to speak (the Mega's `r`, the lidar's spin-up).
    Syncing,
    /// Open and delivering.
    Up,
    /// Lost; reopening.
    Reconnecting,
    /// Not used (no IMU).
    Absent,
}

impl LinkState {
    /// A short word for the status line.
    pub fn word(self) -> &'static str {
        match self {
            Self::Opening => "opening",
            Self::Syncing => "sync",
            Self::Up => "ok",
            Self::Reconnecting => "LOST",
            Self::Absent => "-",
        }
    }
}

/// What a device thread tells the loop.
#[derive(Clone, Debug, PartialEq)]
pub enum Message {
    /// An input for the core, stamped at arrival.
    Input(Stamped),
    /// The device's link changed.
    Link(DeviceKind, LinkState),
    /// The device is gone for good (away longer than `[link] give_up_after_s`, or its
    /// thread ended): the run ends with a device failure.
    Gone {
        /// Which device.
        device: DeviceKind,
        /// What happened.
        message: String,
    },
}

/// Messages the device threads may leave waiting for the loop: a few seconds of every
/// device at full rate (the Mega's 50 batches, the X4's 7 scans, the IMU's samples a
/// second), so a core that stalls for a moment loses nothing and one that hangs cannot make
/// the queue grow without bound (its host watchdog has stopped the wheels by then).
pub const INBOX_CAPACITY: usize = 4096;

/// The device threads' end of the channel to the loop: bounded by [`INBOX_CAPACITY`]; an
/// input that finds it full is dropped and counted ([`Shared::inputs_dropped`]).
#[derive(Clone, Debug)]
pub struct DeviceSender {
    tx: SyncSender<Message>,
    dropped: Arc<AtomicU64>,
}

/// The channel from the device threads to the loop ([`RealDevices`]), counting drops in
/// `shared`.
pub fn inbox(shared: &Shared) -> (DeviceSender, Receiver<Message>) {
    let (tx, rx) = std::sync::mpsc::sync_channel(INBOX_CAPACITY);
    let sender = DeviceSender {
        tx,
        dropped: Arc::clone(&shared.inputs_dropped),
    };
    (sender, rx)
}

/// Flags every thread of a run shares: quit (asked by the loop, a signal, or a panic),
/// whether a thread panicked, and the inputs the loop's inbox had no room for.
#[derive(Clone, Debug, Default)]
pub struct Shared {
    quit: Arc<AtomicBool>,
    panicked: Arc<AtomicBool>,
    inputs_dropped: Arc<AtomicU64>,
}

impl Shared {
    /// Fresh flags.
    pub fn new() -> Self {
        Self::default()
    }

    /// Ask every thread to stop.
    pub fn request_quit(&self) {
        self.quit.store(true, Ordering::SeqCst);
    }

    /// True once a stop was asked.
    pub fn quitting(&self) -> bool {
        self.quit.load(Ordering::SeqCst)
    }

    /// The quit flag, for signal handlers.
    pub fn quit_flag(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.quit)
    }

    /// Record a panic (from the panic hook) and ask every thread to stop.
    pub fn mark_panicked(&self) {
        self.panicked.store(true, Ordering::SeqCst);
        self.request_quit();
    }

    /// True if a thread panicked.
    pub fn panicked(&self) -> bool {
        self.panicked.load(Ordering::SeqCst)
    }

    /// Inputs dropped because the loop's inbox was full (the core fell behind by
    /// [`INBOX_CAPACITY`] messages).
    pub fn inputs_dropped(&self) -> u64 {
        self.inputs_dropped.load(Ordering::Relaxed)
    }
}

/// Why the real devices stopped delivering.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DeviceError {
    /// A device is gone for good.
    #[error("{device}: {message}")]
    Gone {
        /// Which device.
        device: DeviceKind,
        /// What happened.
        message: String,
    },
    /// Every device thread ended.
    #[error("every device thread ended")]
    Disconnected,
}

/// Writes the core's outputs and latency figures; see [`RealDevices::latencies_us`].
#[derive(Clone, Debug)]
pub struct Writers {
    /// The Mega.
    pub mega: MegaHandle,
    /// The lidar.
    pub lidar: LidarHandle,
    /// The organisers' server.
    pub referee: RefereeHandle,
}

/// The real devices as the runtime's [`Devices`]: inputs from the device threads' channel,
/// in order of arrival, and the host tick every [`HOST_TICK_PERIOD_US`] from the shared
/// clock; outputs written at once by the loop's thread (the ports' write halves are shared
/// with their threads).
#[derive(Debug)]
pub struct RealDevices {
    clock: Clock,
    rx: Receiver<Message>,
    writers: Writers,
    shared: Shared,
    queued: VecDeque<Stamped>,
    next_tick: Timestamp,
    links: Arc<Mutex<LinkStates>>,
    latencies_us: Vec<u32>,
}

/// Every device's link, for the status line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkStates {
    /// The Mega.
    pub mega: LinkState,
    /// The lidar.
    pub lidar: LinkState,
    /// The IMU.
    pub imu: LinkState,
    /// The organisers' server.
    pub referee: LinkState,
}

impl Default for LinkStates {
    fn default() -> Self {
        Self {
            mega: LinkState::Opening,
            lidar: LinkState::Opening,
            imu: LinkState::Absent,
            referee: LinkState::Up,
        }
    }
}

impl std::fmt::Display for LinkStates {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "mega {} lidar {} imu {} server {}",
            self.mega.word(),
            self.lidar.word(),
            self.imu.word(),
            self.referee.word()
        )
    }
}

impl RealDevices {
    /// Devices fed by `rx` (the device threads' channel), writing through `writers`; the
    /// first host tick comes one period after now. `initial` inputs (an operator's forced
    /// start) are handed out first, stamped now. Arms the [`drill`] if the environment asks.
    pub fn new(
        clock: Clock,
        rx: Receiver<Message>,
        writers: Writers,
        shared: Shared,
        initial: Vec<Input>,
    ) -> Self {
        if let Err(problem) = drill::arm() {
            eprintln!("{problem}");
        }
        let now = clock.now();
        Self {
            queued: initial.into_iter().map(|i| Stamped::new(now, i)).collect(),
            next_tick: Timestamp::from_us(now.as_us() + HOST_TICK_PERIOD_US),
            clock,
            rx,
            writers,
            shared,
            links: Arc::new(Mutex::new(LinkStates::default())),
            latencies_us: Vec::new(),
        }
    }

    /// The links as the device threads last reported them.
    pub fn links(&self) -> LinkStates {
        *self.links.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The links, shared, for a status display on another thread or tap.
    pub fn link_states(&self) -> Arc<Mutex<LinkStates>> {
        Arc::clone(&self.links)
    }

    /// Latency of every reference batch written, µs: from the arrival of the input that
    /// produced it (the tick's time on the clock) to the end of the write.
    pub fn latencies_us(&self) -> &[u32] {
        &self.latencies_us
    }

    /// The writers (to stop the robot on the way out).
    pub fn writers(&self) -> &Writers {
        &self.writers
    }

    fn note_link(&self, device: DeviceKind, state: LinkState) {
        let mut links = self.links.lock().unwrap_or_else(PoisonError::into_inner);
        match device {
            DeviceKind::Mega => links.mega = state,
            DeviceKind::Lidar => links.lidar = state,
            DeviceKind::Imu => links.imu = state,
            DeviceKind::Referee => links.referee = state,
        }
    }
}

impl Devices for RealDevices {
    type Error = DeviceError;

    fn next_input(&mut self) -> Result<Option<Stamped>, DeviceError> {
        loop {
            if self.shared.quitting() {
                return Ok(None);
            }
            if let Some(input) = self.queued.pop_front() {
                return Ok(Some(input));
            }
            let now = self.clock.now();
            if now >= self.next_tick {
                // A loop that fell behind ticks once, now, and keeps its phase after.
                let behind = (now.as_us() - self.next_tick.as_us()) / HOST_TICK_PERIOD_US;
                let tick = self.next_tick;
                self.next_tick =
                    Timestamp::from_us(tick.as_us() + (behind + 1) * HOST_TICK_PERIOD_US);
                return Ok(Some(Stamped::new(tick, Input::HostTick)));
            }
            // Wake at the next tick at the latest, and now and then to see the quit flag.
            let wait = Duration::from_micros(self.next_tick.as_us() - now.as_us())
                .min(Duration::from_millis(50));
            match self.rx.recv_timeout(wait) {
                Ok(Message::Input(input)) => return Ok(Some(input)),
                Ok(Message::Link(device, state)) => self.note_link(device, state),
                Ok(Message::Gone { device, message }) => {
                    self.note_link(device, LinkState::Reconnecting);
                    return Err(DeviceError::Gone { device, message });
                }
                Err(RecvTimeoutError::Timeout) => {}
                // Threads that ended because the run is quitting: a quit, not a failure.
                Err(RecvTimeoutError::Disconnected) if self.shared.quitting() => return Ok(None),
                Err(RecvTimeoutError::Disconnected) => return Err(DeviceError::Disconnected),
            }
        }
    }

    fn apply(&mut self, input: &Stamped, outputs: &Outputs) -> Result<(), DeviceError> {
        if let Some(wheels) = outputs.wheels {
            let written = self.writers.mega.send_references(&wheels, self.clock.now());
            if written {
                let latency = self.clock.now().as_us().saturating_sub(input.time.as_us());
                self.latencies_us
                    .push(u32::try_from(latency).unwrap_or(u32::MAX));
            }
        }
        if outputs.lidar.is_some() {
            self.writers.lidar.start_scan();
        }
        if let Some(request) = outputs.referee {
            self.writers.referee.send(request);
        }
        Ok(())
    }
}

/// Send `message` on `tx`; false when the loop has gone (the thread should end). An input
/// that finds the inbox full is dropped and counted; a link change or a device gone waits
/// for room (the loop must hear it). Where an armed [`drill`] panics.
pub(crate) fn report(tx: &DeviceSender, message: Message) -> bool {
    drill::check();
    match message {
        Message::Input(_) => match tx.tx.try_send(message) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                tx.dropped.fetch_add(1, Ordering::Relaxed);
                true
            }
            Err(TrySendError::Disconnected(_)) => false,
        },
        _ => tx.tx.send(message).is_ok(),
    }
}
