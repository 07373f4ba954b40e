//! `ratf run`: the robot's core on the real devices ([`crate::devices`]), recorded.
//!
//! Opens and checks every device (saying which, where it looked and what to do when one is
//! missing), waits for the server's part list or the operator's forced start, runs the core
//! with [`ratf_core::runtime::run`], shows a live status, records every input and output
//! (MCAP, session kind `robot`), and on every way out — the round finished, Ctrl-C or
//! SIGTERM, a device gone for good, a panic in any thread — writes zero references and
//! magnet off to the Mega before returning ([`StopGuard`]).

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ratf_core::config::{Config, ImuDevice};
use ratf_core::drivers::mega_link::MegaLinkStats;
use ratf_core::field::Field;
use ratf_core::referee::protocol::SlotLetters;
use ratf_core::runtime::{
    Core, Event, Flow, Input, OperatorCommand, Phase, StepView, Tap, Timestamp, run,
};

use crate::apps::latency_histogram::LatencyHistogram;
use crate::devices::lidar::{self, LidarHandle, LidarSettings};
use crate::devices::mega::{self, MegaHandle, MegaSettings, open_port};
use crate::devices::operator::{OperatorReceiver, WithOperator, operator_channel};
use crate::devices::{Clock, DeviceError, LinkStates, RealDevices, Shared, Writers, imu, referee};
use crate::recording::{Recorder, RecordingError, Session};
use crate::referee::client::RefereeLink;

/// Exit code: the round finished (every action done).
pub const EXIT_FINISHED: i32 = 0;
/// Exit code: could not start (the configuration, or a device missing or wrong).
pub const EXIT_SETUP: i32 = 1;
/// Exit code: a device was gone for good during the run.
pub const EXIT_DEVICE_FAILED: i32 = 3;
/// Exit code: a thread panicked.
pub const EXIT_PANIC: i32 = 4;
/// Exit code: stopped by Ctrl-C (SIGINT) or SIGTERM (128 + 2, as a shell reports SIGINT).
pub const EXIT_INTERRUPTED: i32 = 130;

/// Why `ratf run` could not start.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A device is missing or wrong: which, where, what to do.
    #[error("{0}")]
    Device(String),
    /// The task planner's model could not be built from the configuration.
    #[error("task planner: {0}")]
    Planner(#[from] ratf_core::planning::tasks::TaskError),
    /// The recording could not be written.
    #[error("recording: {0}")]
    Recording(#[from] Box<RecordingError>),
    /// The live ROS 2 bridge could not start.
    #[error("{0}")]
    Ros2(#[from] crate::ros2::live::BridgeError),
    /// A thread could not be started.
    #[error("starting the {what} thread: {source}")]
    Thread {
        /// Which.
        what: &'static str,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
}

/// How a run is made.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOptions {
    /// Start at once with this part list (the operator's forced start), whatever the server
    /// says.
    pub force_start: Option<SlotLetters>,
    /// Where the recording goes.
    pub recording: PathBuf,
    /// Status lines per second (0: none).
    pub status_hz: f64,
    /// The live ROS 2 bridge (`--ros2`), if asked for.
    pub ros2: Option<crate::ros2::live::BridgeOptions>,
    /// Print the core's events (picked, placed, …) on stdout as they happen.
    pub print_events: bool,
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Every action done.
    Finished,
    /// Ctrl-C or SIGTERM.
    Interrupted,
    /// A device gone for good.
    DeviceFailed(String),
    /// A thread panicked.
    Panicked,
}

impl Outcome {
    /// The process's exit code for this outcome.
    pub fn exit_code(&self) -> i32 {
        match self {
            Self::Finished => EXIT_FINISHED,
            Self::Interrupted => EXIT_INTERRUPTED,
            Self::DeviceFailed(_) => EXIT_DEVICE_FAILED,
            Self::Panicked => EXIT_PANIC,
        }
    }
}

/// Nearest-rank percentiles of reference-write latencies, µs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Latency {
    /// Batches measured.
    pub count: usize,
    /// Median.
    pub p50_us: u32,
    /// 99th percentile.
    pub p99_us: u32,
    /// Largest.
    pub max_us: u32,
}

impl Latency {
    /// The percentiles of `samples`.
    pub fn of(samples: &[u32]) -> Self {
        let mut sorted = samples.to_vec();
        sorted.sort_unstable();
        let rank = |q: f64| -> u32 {
            if sorted.is_empty() {
                return 0;
            }
            let k = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
            sorted[k - 1]
        };
        Self {
            count: sorted.len(),
            p50_us: rank(0.50),
            p99_us: rank(0.99),
            max_us: sorted.last().copied().unwrap_or(0),
        }
    }
}

/// What a run did and measured.
#[derive(Clone, Debug, PartialEq)]
pub struct RunReport {
    /// How it ended.
    pub outcome: Outcome,
    /// Parts placed (the robot's own count).
    pub placed: u32,
    /// From the part list to the last placement, s (0 if nothing was placed).
    pub time_s: f64,
    /// Robot time from start-up to the end, s.
    pub robot_s: f64,
    /// Inputs consumed.
    pub inputs: u64,
    /// Inputs the device threads dropped because the loop's inbox was full.
    pub inputs_dropped: u64,
    /// The Mega's port took the final zero references and magnet off.
    pub stop_written: bool,
    /// From an input's arrival to its references written.
    pub latency: Latency,
    /// The same latencies as a histogram, to pool with other runs' (`ratf soak`).
    pub latency_histogram: LatencyHistogram,
    /// Reference batches the host watchdog wrote (the core stalled).
    pub watchdog_batches: u64,
    /// CPU time (user + system) per second of robot time.
    pub cpu_per_s: f64,
    /// Peak resident memory, KiB.
    pub max_rss_kib: u64,
    /// The Mega link's counters at the end (batches received, and those it reported lost:
    /// incomplete, corrupt, out of sequence); `None` if the port was never read.
    pub mega_link: Option<MegaLinkStats>,
    /// The recording.
    pub recording: PathBuf,
}

/// Writes zero references and magnet off when dropped: every way out of [`run_robot`],
/// unwinding from a panic included, stops the robot.
#[derive(Debug)]
pub struct StopGuard {
    mega: MegaHandle,
    lidar: LidarHandle,
    clock: Clock,
    stopped: bool,
}

impl StopGuard {
    /// Stop the robot now; true if the Mega's port took the zero references and magnet off
    /// (false: it was gone, and only the Mega's own 100 ms watchdog stops the wheels).
    pub fn stop(mut self) -> bool {
        self.stopped = true;
        self.lidar.stop_scan();
        self.mega.stop(self.clock.now())
    }
}

impl Drop for StopGuard {
    fn drop(&mut self) {
        if !self.stopped {
            self.mega.stop(self.clock.now());
            self.lidar.stop_scan();
        }
    }
}

/// Prints the core's events and a live one-line status.
struct StatusTap {
    field: Field,
    links: Arc<Mutex<LinkStates>>,
    period: Option<Duration>,
    last: Instant,
    terminal: bool,
    last_placed: Option<Timestamp>,
    print_events: bool,
}

impl StatusTap {
    fn line(&self, view: &StepView<'_>) -> String {
        let status = view.core.status();
        let state = if status.stopped {
            "STOPPED"
        } else {
            match status.phase {
                Phase::WaitingForPartList => "waiting for the part list",
                Phase::Running => "running",
                Phase::Finished => "finished",
            }
        };
        let round_s = status.started.map_or(0.0, |s| {
            (status.time.as_us().saturating_sub(s.as_us())) as f64 * 1e-6
        });
        let links = *self.links.lock().unwrap_or_else(PoisonError::into_inner);
        format!(
            "{:7.2} s  {state}, placed {}, round {round_s:5.1} s, pose ({:.3}, {:.3}) m {:4.0}° ± {:.0} mm; {links}",
            status.time.as_secs_f64(),
            status.placed,
            status.pose.x,
            status.pose.y,
            status.pose.yaw_rad.to_degrees(),
            status.pose_std.0 * 1e3,
        )
    }
}

impl Tap for StatusTap {
    fn on_step(&mut self, view: &StepView<'_>) {
        for event in &view.outputs.events {
            if matches!(event, Event::Placed { .. }) {
                self.last_placed = Some(view.input.time);
            }
            if !self.print_events {
                continue;
            }
            let text = event.describe(&self.field);
            if self.terminal {
                eprint!("\r\x1b[K");
            }
            // A closed stdout (a reader gone) must not panic the loop: events are lost,
            // the robot runs on.
            let _ = writeln!(
                std::io::stdout(),
                "{:7.2} s  {text}",
                view.input.time.as_secs_f64()
            );
        }
        let Some(period) = self.period else { return };
        let now = Instant::now();
        if now.duration_since(self.last) >= period {
            self.last = now;
            let line = self.line(view);
            if self.terminal {
                eprint!("\r\x1b[K{line}");
            } else {
                eprintln!("{line}");
            }
        }
    }
}

/// Turn a port's open error into what to do (`ratf check` reports a missing port the same
/// way).
pub(crate) fn port_problem(
    device: &str,
    key: &str,
    path: &str,
    error: &serialport::Error,
) -> String {
    let advice = match error.kind() {
        serialport::ErrorKind::NoDevice => format!(
            "no such device; plug it in, or set [link] {key} = \"…\" (a udev rule can give it \
             a stable name)"
        ),
        serialport::ErrorKind::Io(std::io::ErrorKind::NotFound) => format!(
            "no such device; plug it in, or set [link] {key} = \"…\" (a udev rule can give it \
             a stable name)"
        ),
        serialport::ErrorKind::Io(std::io::ErrorKind::PermissionDenied) => {
            "permission denied; add the user to the dialout group (then log in again)".to_owned()
        }
        _ => format!("{error}; check [link] {key}"),
    };
    format!("{device}: {path}: {advice} ({error})")
}

/// The robot's real devices, open and read by their threads.
#[derive(Debug)]
pub struct OpenDevices {
    /// The devices for the runtime's loop.
    pub devices: RealDevices,
    /// What keeps them running, and stops the robot.
    pub running: Running,
}

/// The device threads and the guard that stops the robot when dropped.
#[derive(Debug)]
pub struct Running {
    /// Writes zero references and magnet off when dropped.
    pub guard: StopGuard,
    /// The Mega's writer (its counters).
    pub mega: MegaHandle,
    /// The clock every device stamps with.
    pub clock: Clock,
    threads: Vec<JoinHandle<()>>,
}

impl Running {
    /// Stop the robot (zero references, magnet off, lidar stopped), then the threads.
    pub fn close(self, shared: &Shared) {
        drop(self.guard);
        shared.request_quit();
        for thread in self.threads {
            let _ = thread.join();
        }
    }
}

/// Open and check every device the configuration names (saying which, where it looked and
/// what to do when one is missing), then start their threads; the core gets `initial`
/// before anything from the devices. `shared` carries the quit flag and the panic flag.
pub fn open_devices(
    config: &Config,
    shared: &Shared,
    initial: Vec<Input>,
) -> Result<OpenDevices, RunError> {
    let clock = Clock::start();
    let (tx, rx) = crate::devices::inbox(shared);
    let mega_settings = MegaSettings::from_config(config);
    let lidar_settings = LidarSettings::from_config(config);

    // Open and check every device before anything moves.
    let mega_port = open_port(&mega_settings.port, mega_settings.baud).map_err(|e| {
        RunError::Device(port_problem("mega", "mega_port", &mega_settings.port, &e))
    })?;
    let lidar_port = open_port(&lidar_settings.port, lidar_settings.baud).map_err(|e| {
        RunError::Device(port_problem(
            "lidar",
            "lidar_port",
            &lidar_settings.port,
            &e,
        ))
    })?;
    let link = RefereeLink::from_config(&config.referee).map_err(|e| {
        RunError::Device(format!(
            "server: {}:{}: {e}; set [referee] server_address and server_port",
            config.referee.server_address, config.referee.server_port
        ))
    })?;
    let imu_source = match config.link.imu {
        ImuDevice::None => None,
        ImuDevice::Mpu9255 => {
            match imu::open_i2c(&config.robot.imu.i2c_device, &config.robot.imu) {
                Ok(source) => Some(source),
                Err(e) => {
                    eprintln!(
                        "imu: {e}; running without the IMU (set [link] imu = \"none\" to say so, \
                         or [robot.imu] i2c_device)"
                    );
                    None
                }
            }
        }
    };

    let mega = MegaHandle::new(mega_settings.link, mega_settings.controller);
    let lidar_handle = LidarHandle::new();
    let guard = StopGuard {
        mega: mega.clone(),
        lidar: lidar_handle.clone(),
        clock,
        stopped: false,
    };
    let thread = |what: &'static str| move |source| RunError::Thread { what, source };
    let mut threads: Vec<JoinHandle<()>> = Vec::new();
    threads.push(
        mega::spawn(
            mega_settings,
            mega_port,
            clock,
            tx.clone(),
            mega.clone(),
            shared.clone(),
        )
        .map_err(thread("mega"))?,
    );
    threads.push(
        lidar::spawn(
            lidar_settings,
            lidar_port,
            clock,
            tx.clone(),
            lidar_handle.clone(),
            shared.clone(),
        )
        .map_err(thread("lidar"))?,
    );
    let (referee_handle, referee_thread) =
        referee::spawn(link, clock, tx.clone(), shared.clone()).map_err(thread("referee"))?;
    threads.push(referee_thread);
    if let Some(source) = imu_source {
        let yaw_rad = config.robot.imu.yaw_deg.to_radians();
        threads.push(
            imu::spawn(source, yaw_rad, clock, tx.clone(), shared.clone())
                .map_err(thread("imu"))?,
        );
    }
    drop(tx);

    let writers = Writers {
        mega: mega.clone(),
        lidar: lidar_handle,
        referee: referee_handle,
    };
    let devices = RealDevices::new(clock, rx, writers, shared.clone(), initial);
    Ok(OpenDevices {
        devices,
        running: Running {
            guard,
            mega,
            clock,
            threads,
        },
    })
}

/// Run the robot: see the module documentation. `shared` carries the quit flag (wire
/// signals to it first) and the panic flag.
pub fn run_robot(
    config: &Config,
    options: &RunOptions,
    shared: &Shared,
) -> Result<RunReport, RunError> {
    run_robot_with(config, options, shared, None, &mut [])
}

/// [`run_robot`] with an operator's commands joined into the inputs (the HMI) and more
/// taps (the HMI's).
pub fn run_robot_with(
    config: &Config,
    options: &RunOptions,
    shared: &Shared,
    operator: Option<OperatorReceiver>,
    taps: &mut [&mut dyn Tap],
) -> Result<RunReport, RunError> {
    let initial = options
        .force_start
        .map(|parts| Input::Operator(OperatorCommand::ForceStart { parts }))
        .into_iter()
        .collect();
    // The core first: building it plans the route times (0.8–1.0 s on a PC), and the
    // devices' clock and threads, once open, would queue that long behind its first tick.
    let start_pose = Field::competition().start_pose();
    let mut core = Core::new(config, start_pose)?;
    let OpenDevices {
        devices,
        running:
            Running {
                guard,
                mega,
                clock,
                threads,
            },
    } = open_devices(config, shared, initial)?;
    let session = Session {
        kind: "robot".to_owned(),
        config_toml: config.to_toml_string().map_err(|e| {
            RunError::Recording(Box::new(RecordingError::Io {
                path: options.recording.clone(),
                source: std::io::Error::other(e),
            }))
        })?,
        start_pose,
        version: env!("CARGO_PKG_VERSION").to_owned(),
    };
    let mut recorder = Recorder::create(&options.recording, &session).map_err(Box::new)?;
    let mut status = StatusTap {
        field: Field::competition(),
        links: devices.link_states(),
        period: (options.status_hz > 0.0)
            .then(|| Duration::from_secs_f64(1.0 / options.status_hz.min(50.0))),
        last: Instant::now(),
        terminal: std::io::stderr().is_terminal(),
        last_placed: None,
        print_events: options.print_events,
    };
    // The live ROS 2 bridge's commands come on a channel of their own.
    let (ros2_operator, ros2_commands) = operator_channel();
    let mut bridge = crate::ros2::live::live_bridge(config, options.ros2.as_ref(), ros2_operator)?;
    let cpu_start = cpu_time_s();
    // Without an operator the channel's sender is dropped at once: nothing ever arrives.
    let devices = WithOperator::new(devices, operator.unwrap_or_else(|| operator_channel().1));
    let mut devices = WithOperator::new(devices, ros2_commands);
    let mut all: Vec<&mut dyn Tap> = vec![&mut recorder, &mut status];
    all.extend(taps.iter_mut().map(|tap| &mut **tap as &mut dyn Tap));
    if let Some(bridge) = bridge.as_mut() {
        all.push(bridge.as_mut());
    }
    let result = run(&mut core, &mut devices, &mut all, |core, _| {
        if core.brain().phase() == Phase::Finished || shared.quitting() {
            Flow::Stop
        } else {
            Flow::Continue
        }
    });
    // Stop the robot first, then tidy up.
    let stop_written = guard.stop();
    if status.terminal && status.period.is_some() {
        eprintln!();
    }
    let outcome = if shared.panicked() {
        Outcome::Panicked
    } else {
        match &result {
            Err(DeviceError::Gone { .. } | DeviceError::Disconnected) => Outcome::DeviceFailed(
                result
                    .as_ref()
                    .err()
                    .map(ToString::to_string)
                    .unwrap_or_default(),
            ),
            Ok(_) if core.brain().phase() == Phase::Finished => Outcome::Finished,
            Ok(_) => Outcome::Interrupted,
        }
    };
    shared.request_quit();
    for thread in threads {
        let _ = thread.join();
    }
    let robot_s = clock.now().as_secs_f64();
    let cpu_s = cpu_time_s() - cpu_start;
    let recording = recorder.finish().map_err(Box::new)?;
    let started = core.brain().started_at_us();
    let time_s = match (started, status.last_placed) {
        (Some(s), Some(p)) => (p.as_us().saturating_sub(s)) as f64 * 1e-6,
        _ => 0.0,
    };
    Ok(RunReport {
        outcome,
        placed: core.status().placed,
        time_s,
        robot_s,
        inputs: result.map_or(0, |s| s.inputs),
        inputs_dropped: shared.inputs_dropped(),
        stop_written,
        latency: Latency::of(devices.inner().inner().latencies_us()),
        latency_histogram: LatencyHistogram::of(devices.inner().inner().latencies_us()),
        watchdog_batches: mega.batches_written().1,
        cpu_per_s: cpu_s / robot_s.max(1e-9),
        max_rss_kib: max_rss_kib(),
        mega_link: mega.link_stats(),
        recording,
    })
}

/// CPU time of this process so far (user + system), s.
fn cpu_time_s() -> f64 {
    nix::sys::resource::getrusage(nix::sys::resource::UsageWho::RUSAGE_SELF).map_or(0.0, |u| {
        let secs = |t: nix::sys::time::TimeVal| t.tv_sec() as f64 + t.tv_usec() as f64 * 1e-6;
        secs(u.user_time()) + secs(u.system_time())
    })
}

/// Peak resident memory of this process, KiB.
fn max_rss_kib() -> u64 {
    nix::sys::resource::getrusage(nix::sys::resource::UsageWho::RUSAGE_SELF)
        .map_or(0, |u| u64::try_from(u.max_rss()).unwrap_or(0))
}

/// The recording's default path: `DIR/run-<seconds since the Unix epoch>.mcap`.
pub fn default_recording(dir: &Path) -> PathBuf {
    timestamped_recording(dir, "run")
}

/// `DIR/<kind>-<seconds since the Unix epoch>.mcap`.
pub fn timestamped_recording(dir: &Path, kind: &str) -> PathBuf {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    dir.join(format!("{kind}-{secs}.mcap"))
}
