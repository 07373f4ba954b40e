//! `ratf`: the command-line entry point (wiring only).

use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use ratf_core::config::{Config, ConfigError, MagnetFace, Policy, WorldProfile};
use ratf_core::field::Field;
use ratf_core::field::OrientedRect;
use ratf_host::apps::drive::{self, DriveReport, DriveTrace};
use ratf_host::apps::scripts::Named;
use ratf_host::plot::FieldPlot;

/// `println!` that ends the program quietly when standard output is closed (piped into
/// `head`, say) instead of panicking: nobody is left to read the rest.
macro_rules! println {
    ($($arg:tt)*) => {{
        if writeln!(std::io::stdout().lock(), $($arg)*).is_err() {
            std::process::exit(0);
        }
    }};
}

/// ratf: the Robot@Factory 4.0 robot, on the robot or in simulation.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print the protocol's golden frames (a quick check that the build works).
    Frames,
    /// Print the default configuration or check a configuration file.
    Config(ConfigArgs),
    /// Run a complete simulated round: the robot's whole stack, the organisers' server
    /// mocked over UDP on loopback.
    Sim(SimArgs),
    /// Drive the simulated robot through a velocity script and measure odometry drift.
    Drive(DriveArgs),
    /// Run a mock of the organisers' UDP server for practice (start with Enter or `start`).
    Referee(RefereeArgs),
    /// Benchmarks in the simulator.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Re-run the robot's core over a recording (`ratf sim` writes one) and report the first
    /// divergence, or how another configuration changes the pose and the decisions.
    Replay(ReplayArgs),
    /// Run the robot on its real devices: the Mega, the lidar, the IMU and the organisers'
    /// server, as the configuration names them; recorded (ratf replay reads it).
    #[command(after_help = "Exit codes:\n  \
        0    the round finished (every action done); the robot is stopped\n  \
        1    could not start: the configuration, or a device missing or wrong (the message \
             says which, where it looked and what to do)\n  \
        2    bad command line\n  \
        3    a device was gone for good during the run ([link] give_up_after_s)\n  \
        4    a thread panicked\n  \
        130  stopped by Ctrl-C or SIGTERM\n\
        On every way out the Mega gets zero references and magnet off first.")]
    Run(RunArgs),
    /// The wiring check a team runs first: what each device sees (the Mega's telemetry,
    /// encoders and switch, the lidar's rate, points and beacons, the IMU's identity and
    /// gyro bias, the server), then each wheel turned open loop in turn and the magnet
    /// toggled; one summary line per device.
    #[command(after_help = "Exit codes:\n  \
        0    every device checked is ok (steps not run are listed as skipped, with why)\n  \
        1    the configuration could not be loaded\n  \
        2    bad command line\n  \
        3    at least one device has a problem (its summary line says what to check)\n  \
        4    a thread panicked\n  \
        130  stopped by Ctrl-C or SIGTERM\n\
        On every way out the Mega gets zero references and magnet off first.")]
    Check(CheckArgs),
    /// Calibrate the lidar (range scale and offset, mount yaw) and the beacons' layout from a
    /// 37 s drive around machine A with nine stops: in the simulator (the drawn world's
    /// truth is printed beside the fit), or with `--robot` on the robot's devices (placed at
    /// the start pose, the poles' distances measured with a tape and given with `--tape`,
    /// their centres measured from the floor sheet's edges with `--pole`). `--write FILE`
    /// saves the calibrated configuration.
    #[command(
        after_help = "The beacons, as [field] beacons_m numbers them (world frame, \
        +x towards the outgoing warehouse, +y towards the incoming one):\n  \
        0  (+0.888, +0.538) m    1  (-0.888, +0.538) m\n  \
        2  (+0.888, -0.538) m    3  (-0.888, -0.538) m\n\
        Exit codes with --robot: 0 calibrated, 1 could not start (configuration, device), \
        2 bad command line, 3 a device failed or the fit was refused, 4 a thread panicked, \
        130 Ctrl-C or SIGTERM. \
        On every way out the Mega gets zero references and magnet off first."
    )]
    Calibrate(CalibrateArgs),
    /// Fit the robot's wheel motors and tune the Mega's wheel PI (README, "Fit your robot").
    #[command(subcommand)]
    Tune(TuneCommand),
    /// `ratf run` against `ratf sim --serve-pty`, round after round in one process for a
    /// given time: resident memory, core latency, telemetry frames lost and recordings,
    /// per round and summed up.
    #[command(after_help = "Exit codes:\n  \
        0    every round finished with its recording complete, no telemetry frame lost \
             that the link did not report, resident memory grew by at most 1 MiB after the \
             first round\n  \
        1    a criterion failed (each failure is printed), or the soak could not go on\n  \
        2    bad command line\n  \
        130  stopped by Ctrl-C or SIGTERM")]
    Soak(SoakArgs),
}

#[derive(Debug, Subcommand)]
enum TuneCommand {
    /// Identify each wheel motor (gain, time constant, dead zone, delay) from open-loop PWM
    /// steps: on the robot's Mega (`--robot`), in the simulator (`--sim`) or from a
    /// tuning-node log (`--from-csv`). Ctrl-C stops the wheels at once.
    Motors(ratf_host::apps::tune::cli::MotorsArgs),
    /// PI gains by IMC tuning from the identified model (`[motor]`), with the predicted
    /// 10 rad/s step; `--write FILE` sets the `[mega]` keys.
    Gains(ratf_host::apps::tune::cli::GainsArgs),
}

#[derive(Debug, Args)]
struct SoakArgs {
    /// Start no new round after this many seconds (the round under way finishes; a round 1
    /// takes about 45 s).
    #[arg(long, value_name = "S", default_value_t = 3600.0)]
    duration_s: f64,
    /// The first round's seed; each next round takes the next.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Configuration file (defaults: the competition robot), for the world and the robot.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Folder for the device links and the recordings.
    #[arg(long, value_name = "DIR", default_value = "out/soak")]
    out: PathBuf,
    /// Keep every round's recording (otherwise each is deleted once read back).
    #[arg(long)]
    keep_recordings: bool,
    /// Pool the latencies of the rounds ending in each stretch of this many seconds, and
    /// report each stretch's p99 and the largest drift from the first's.
    #[arg(long, value_name = "S", default_value_t = 600.0, value_parser = positive_seconds)]
    window_s: f64,
    /// Print one JSON object with the figures as the last line of stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
struct CalibrateArgs {
    #[command(subcommand)]
    what: Option<CalibrateWhat>,
    /// Configuration file (defaults: the competition robot): the robot's beliefs before
    /// calibrating, from which the world is drawn.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Simulator seed (the world's draws).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// How the simulated world departs from the configuration (default: the
    /// configuration's `[sim] world`).
    #[arg(long, value_enum)]
    world: Option<WorldProfile>,
    /// Without the six pole-to-pole tape measures (the range scale then
    /// rests on the odometry and the nominal layout).
    #[arg(long)]
    no_tape: bool,
    /// Without the poles measured from the floor sheet's edges (the layout's common shift
    /// and turn then rest on the nominal centres).
    #[arg(long)]
    no_sheet: bool,
    /// Write the calibrated configuration to this file: the `--config` file with the
    /// calibrated keys set (`[lidar] range_scale`, `range_offset_m`, `[robot]
    /// lidar_yaw_deg`, `[field] beacons_m`).
    #[arg(long, value_name = "FILE")]
    write: Option<PathBuf>,
    /// On the robot's devices (`--config` is then the robot's file, required): the robot
    /// stands at the start pose, with machine A's surroundings clear.
    #[arg(long, requires = "config")]
    robot: bool,
    /// A pole-to-pole distance measured with a tape, centre to centre, as `A-B=METRES`
    /// (e.g. `0-1=1.776`), beacons numbered as below; give all six pairs if you can.
    #[arg(long, value_name = "A-B=METRES", value_parser = ratf_host::apps::calibrate::robot::parse_tape, requires = "robot")]
    tape: Vec<ratf_core::calibration::TapeMeasure>,
    /// A pole's centre measured from the floor sheet's edges, field frame, as `B=X,Y` in
    /// metres (e.g. `0=0.888,0.538`: pole 0's centre 47 mm right of the sheet's right edge
    /// at x = 0.841 and 57 mm below its top edge at y = 0.595); give all four if you can.
    /// Only these place the poles' layout on the field: the lidar sees it move with the
    /// robot.
    #[arg(long, value_name = "B=X,Y", value_parser = ratf_host::apps::calibrate::robot::parse_pole_from_sheet, requires = "robot")]
    pole: Vec<ratf_core::calibration::PoleFromSheet>,
    /// Do not ask before driving (the robot stands at the start pose with room around).
    #[arg(long, requires = "robot")]
    yes: bool,
    /// Folder for the drive's recording (with `--robot`).
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
}

#[derive(Debug, Subcommand)]
enum CalibrateWhat {
    /// The odometry's wheel radius and lx + ly from a 100 s drive around machine A with four
    /// quarter turns in place and the loop's left side twice more, each stop's pose fixed from
    /// the beacons: in the simulator (the lidar calibrated first), on the robot (`--robot`)
    /// or from its recording (`--from-recording`); `--write FILE` sets the `[robot]` keys.
    Odometry(ratf_host::apps::calibrate::odometry_cli::OdometryArgs),
}

/// Where `--hmi` without an address serves the page: this computer only.
const HMI_LOCAL: &str = "127.0.0.1:8080";

#[derive(Debug, Args)]
struct RunArgs {
    /// The robot's configuration (no simulator sections; `ratf config --check FILE --robot`).
    #[arg(long, value_name = "FILE")]
    config: PathBuf,
    /// Start at once with this part list (incoming slots 1–4, letters B, G, R, X), without
    /// waiting for the server's.
    #[arg(long, value_name = "PARTS")]
    force_start: Option<String>,
    /// Directory for the recording.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Status lines per second (0: none).
    #[arg(long, default_value_t = 4.0)]
    status_hz: f64,
    #[command(flatten)]
    ros2: Ros2Args,
    /// Serve the operator's web page on this address (HOST:PORT, e.g. 0.0.0.0:8080 for the
    /// robot's Wi-Fi; `--hmi` alone: 127.0.0.1:8080, this computer only); the URL with the
    /// control token is printed.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = HMI_LOCAL)]
    hmi: Option<String>,
}

/// The live ROS 2 bridge's options, the same for `ratf run` and `ratf sim`.
#[derive(Debug, Args)]
struct Ros2Args {
    /// Publish the robot live on ROS 2 (DDS domain from ROS_DOMAIN_ID; needs a ratf built
    /// with `--features ros2`).
    #[arg(long)]
    ros2: bool,
    /// The robot's ROS 2 namespace (e.g. /robot1), for several robots on one domain.
    #[arg(long, value_name = "NS", default_value = "", requires = "ros2")]
    ros2_namespace: String,
    /// Let `cmd_vel` drive the robot (manual mode, 0.5 s deadman); otherwise it is ignored.
    #[arg(long, requires = "ros2")]
    ros2_cmd_vel: bool,
    /// Talk DDS on 127.0.0.1 only.
    #[arg(long, requires = "ros2")]
    ros2_loopback: bool,
}

impl Ros2Args {
    /// The bridge's options when `--ros2` was given (the domain read from ROS_DOMAIN_ID).
    fn options(&self) -> Result<Option<ratf_host::ros2::live::BridgeOptions>, String> {
        use ratf_host::ros2::live::BridgeOptions;
        if !self.ros2 {
            return Ok(None);
        }
        Ok(Some(BridgeOptions {
            namespace: self.ros2_namespace.clone(),
            domain_id: BridgeOptions::domain_from_env().map_err(|e| e.to_string())?,
            loopback_only: self.ros2_loopback,
            cmd_vel: self.ros2_cmd_vel,
        }))
    }
}

#[derive(Debug, Args)]
struct CheckArgs {
    /// The robot's configuration (as for `ratf run`).
    #[arg(long, value_name = "FILE")]
    config: PathBuf,
    /// Ask nothing: the wheels are taken to be off the ground (CI, a robot on a stand);
    /// the steps that need a person (turning wheels by hand, watching) are skipped.
    #[arg(long)]
    yes: bool,
    /// Print one JSON object with every device's findings as the last line of stdout.
    #[arg(long)]
    json: bool,
    /// How long each device is watched, s.
    #[arg(long, default_value_t = 2.0)]
    observe_s: f64,
    /// The robot is not at the start pose among the beacons (on a stand): the beacons are
    /// counted but not judged.
    #[arg(long)]
    off_field: bool,
    /// Open-loop PWM of the bring-up, percent of `[mega] pwm_max`.
    #[arg(long, default_value_t = 20.0)]
    pwm_percent: f64,
    /// How long each wheel turns in the bring-up, s.
    #[arg(long, default_value_t = 1.0)]
    spin_s: f64,
}

#[derive(Debug, Args)]
struct ReplayArgs {
    /// The recording (MCAP).
    file: PathBuf,
    /// Re-run with this configuration instead of the recorded one (the world does not
    /// react: the recorded inputs are fed as they were).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Print the replayed events.
    #[arg(long)]
    events: bool,
    /// Print one JSON object with the figures as the last line of stdout.
    #[arg(long)]
    json: bool,
    /// Serve the operator's web page with a time slider over the recording instead (HOST:PORT;
    /// `--hmi` alone: 127.0.0.1:8080); runs until Ctrl-C.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = HMI_LOCAL)]
    hmi: Option<String>,
}

#[derive(Debug, Subcommand)]
enum BenchCommand {
    /// The round's trips with our follower and the original one, and ours on its other
    /// route planner (free space or the road map): time, goal error, cross-track error,
    /// collisions.
    Navigation(NavBenchArgs),
    /// Every round with both policies over many seeds: full-score rate, times, collisions.
    Rounds(RoundsBenchArgs),
    /// Our localiser and the original filter side by side on a tour of the floor, with the
    /// default noise and with faults: RMSE, largest error, NEES, divergences.
    Localisation(LocBenchArgs),
    /// `ratf calibrate` over many seeds: each quantity's error against the drawn truth,
    /// mean and worst, and before calibration.
    Calibration(CalibrationBenchArgs),
    /// Every round with each fault injected at random times (one kind at a time, then
    /// mixed): full-score rate, points, recoveries, time lost, collisions, unsafe events.
    Faults(FaultsBenchArgs),
    /// The lower bound on each round's time (`planning::bound`: what physics and the rules
    /// allow) over every colour arrangement, for the configured robot or for other magnet
    /// faces (a second magnet on the back carries two parts at once).
    Bound(BoundBenchArgs),
}

#[derive(Debug, Args)]
struct BoundBenchArgs {
    /// Configuration file (defaults: the competition robot).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// The faces carrying a magnet, comma-separated (default: the configuration's
    /// `robot.magnet_faces`, the competition robot's `front`).
    #[arg(long, value_enum, value_delimiter = ',')]
    magnet_faces: Vec<MagnetFace>,
    /// Print one JSON object with the figures as the last line of stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Args)]
struct FaultsBenchArgs {
    #[command(flatten)]
    bench: BenchArgs,
    /// The first seed (runs use first-seed .. first-seed + seeds − 1; recoveries were
    /// tuned on seeds 1–10).
    #[arg(long, default_value_t = 1)]
    first_seed: u64,
    /// Only these faults (names as printed, comma-separated; `mixed` for the mix).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Also print, for each faulted run short of full score or with a collision, what happened
    /// in order.
    #[arg(long)]
    verbose: bool,
    /// Calibrate each seed's world first (the calibration drive with tape measures, then
    /// the odometry drive); the robot believes the calibration.
    #[arg(long)]
    calibrated: bool,
}

#[derive(Debug, Args)]
struct CalibrationBenchArgs {
    #[command(flatten)]
    bench: BenchArgs,
    /// The first seed (runs use first-seed .. first-seed + seeds − 1).
    #[arg(long, default_value_t = 1)]
    first_seed: u64,
    /// Without the tape measures.
    #[arg(long)]
    no_tape: bool,
    /// Without the poles measured from the floor sheet's edges.
    #[arg(long)]
    no_sheet: bool,
}

#[derive(Debug, Args)]
struct BenchArgs {
    /// Number of simulator seeds.
    #[arg(long, default_value_t = 10)]
    seeds: u64,
    /// Configuration file (defaults: the competition robot).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Print one JSON object with the figures as the last line of stdout.
    #[arg(long)]
    json: bool,
    /// How the simulated world departs from the robot's configuration (default: the
    /// configuration's `[sim] world`, `realistic` unless set).
    #[arg(long, value_enum)]
    world: Option<WorldProfile>,
}

#[derive(Debug, Args)]
struct RoundsBenchArgs {
    #[command(flatten)]
    bench: BenchArgs,
    /// The first seed: the runs use seeds first-seed .. first-seed + seeds − 1 (report on
    /// seeds other than those anything was tuned on).
    #[arg(long, default_value_t = 1)]
    first_seed: u64,
    /// Machine processing time, s.
    #[arg(long, default_value_t = 0.0)]
    machine_delay_s: f64,
    /// Calibrate each seed's world first (the calibration drive with tape measures, then
    /// the odometry drive, and the body's outline measured with a rule) and run both
    /// policies with the calibrated configuration.
    #[arg(long)]
    calibrated: bool,
    /// Only this policy (both by default): half the time when comparing settings of one.
    #[arg(long, value_enum)]
    policy: Option<Policy>,
}

impl BenchArgs {
    /// The configuration with the chosen world.
    fn config(&self) -> anyhow::Result<Config> {
        let mut config = load_config(self.config.as_deref())?;
        if let Some(world) = self.world {
            config.sim.world = world;
        }
        Ok(config)
    }
}

#[derive(Debug, Args)]
struct LocBenchArgs {
    #[command(flatten)]
    bench: BenchArgs,
    /// The first seed: the runs use seeds first-seed .. first-seed + seeds − 1 (report on
    /// seeds other than those anything was tuned on).
    #[arg(long, default_value_t = 1)]
    first_seed: u64,
    /// Calibrate each seed's world first (the calibration drive with tape measures, then
    /// the odometry drive, and the body's outline measured with a rule) and run both
    /// estimators with the calibrated configuration.
    #[arg(long)]
    calibrated: bool,
}

#[derive(Debug, Args)]
struct NavBenchArgs {
    #[command(flatten)]
    bench: BenchArgs,
    /// Also print every trip: time, route length, goal error.
    #[arg(long)]
    verbose: bool,
}

#[derive(Debug, Args)]
struct RefereeArgs {
    /// Round preset: 1 = BBBB, 2 = a permutation of BBGG, 3 = a permutation of RGGB.
    #[arg(long, default_value_t = 3)]
    round: u8,
    /// The incoming parts instead of the preset, four letters from B, G, R, X (e.g. BGGR).
    #[arg(long)]
    parts: Option<String>,
    /// Seed choosing the preset's permutation.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// UDP port to serve (defaults to the configuration's `referee.server_port`).
    #[arg(long)]
    port: Option<u16>,
    /// Machine processing time, seconds.
    #[arg(long, default_value_t = 0.0)]
    machine_delay_s: f64,
    /// Start the run by itself this many seconds after launch (needed without a terminal).
    #[arg(long)]
    start_after_s: Option<f64>,
    /// Exit this many seconds after launch.
    #[arg(long)]
    exit_after_s: Option<f64>,
    /// Configuration file (defaults: the competition robot).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
}

/// A device whose cable `ratf sim --serve-pty --unplug` pulls out.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum UnplugDevice {
    /// The Arduino Mega (DIR/mega).
    Mega,
    /// The X4 lidar (DIR/lidar).
    Lidar,
}

#[derive(Debug, Args)]
struct SimArgs {
    /// The round: 1 (BBBB), 2 (BBGG in any order), 3 (RGGB in any order).
    #[arg(long, default_value_t = 3)]
    round: u8,
    /// Random seed: the part order and every noise in the simulator.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Who drives: ours, or the original's planner and follower.
    #[arg(long, value_enum, default_value_t = Policy::Ours)]
    policy: Policy,
    /// Machine processing time, s.
    #[arg(long, default_value_t = 0.0)]
    machine_delay_s: f64,
    /// Configuration file (defaults: the competition robot).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Print one JSON object with the round's figures as the last line of stdout.
    #[arg(long)]
    json: bool,
    /// Directory for the SVG plot and the JSON-lines log.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// The operator forces the start after this many seconds with the round's part list,
    /// whatever the server says (practice without a server).
    #[arg(long, value_name = "S")]
    force_start_s: Option<f64>,
    /// How the simulated world departs from the robot's configuration (default: the
    /// configuration's `[sim] world`, `realistic` unless set).
    #[arg(long, value_enum)]
    world: Option<WorldProfile>,
    /// Calibrate first, as a team does on the day (`ratf calibrate`'s drive with tape
    /// measures, then `ratf calibrate odometry`'s drive, in this seed's world, and the
    /// body's outline measured with a rule), and run the round with the calibrated beliefs.
    /// The world is drawn around `--config`: give the file as written, not a calibrated one
    /// (that would draw a new hall around the calibration).
    #[arg(long, conflicts_with = "serve_pty")]
    calibrated: bool,
    /// Serve the world in real time to `ratf run` instead: the simulated Mega and X4 as
    /// pseudo-terminals (symlinks DIR/mega and DIR/lidar), the mock server on UDP
    /// 127.0.0.1 (its port printed). The world starts when DIR/mega is opened and ends a
    /// few seconds after it is closed.
    #[arg(long, value_name = "DIR")]
    serve_pty: Option<PathBuf>,
    /// With --serve-pty: the server's UDP port (0: any free port).
    #[arg(long, default_value_t = 0, requires = "serve_pty")]
    server_port: u16,
    /// With --serve-pty: give up if nothing opens DIR/mega within this many seconds.
    #[arg(long, default_value_t = 120.0, requires = "serve_pty")]
    wait_for_robot_s: f64,
    /// With --serve-pty: the world pulls this device's USB cable out (issue 17's unplug and
    /// replug): at --unplug-at-s its pseudo-terminal goes (symlink removed, bytes dropped;
    /// the Mega runs on from the battery, the X4 stops), --unplug-for-s later a new one
    /// appears at the same name (a Mega opened again resets).
    #[arg(long, value_enum, requires_all = ["serve_pty", "unplug_at_s"])]
    unplug: Option<UnplugDevice>,
    /// With --unplug: when, s of world time (0: the robot opened DIR/mega).
    #[arg(long, value_name = "S", requires = "unplug")]
    unplug_at_s: Option<f64>,
    /// With --unplug: for how long, s (0.2 to 10; default 1).
    #[arg(long, value_name = "S", requires = "unplug")]
    unplug_for_s: Option<f64>,
    /// Serve the operator's web page on this address (HOST:PORT; `--hmi` alone:
    /// 127.0.0.1:8080); the URL with the control token is printed. After the round the page
    /// stays up: choose another round there, or press Ctrl-C.
    #[arg(
        long,
        value_name = "ADDR",
        num_args = 0..=1,
        default_missing_value = HMI_LOCAL,
        conflicts_with = "serve_pty"
    )]
    hmi: Option<String>,
    /// Run the simulated round at wall-clock speed, so a person can watch it.
    #[arg(long, conflicts_with = "serve_pty")]
    realtime: bool,
    /// The mock server never answers: only a forced start (--force-start-s or the page)
    /// starts the round.
    #[arg(long, conflicts_with = "serve_pty")]
    silent_server: bool,
    /// The live ROS 2 bridge: with `--ros2` the round runs at wall-clock speed (as with
    /// `--realtime`) so that rviz2 sees it as it would see the robot. With --serve-pty, give
    /// these to `ratf run` instead.
    #[command(flatten)]
    ros2: Ros2Args,
}

#[derive(Debug, Args)]
struct DriveArgs {
    /// The script (every one when omitted).
    #[arg(long, value_enum)]
    script: Option<Named>,
    /// Random seed (overrides the configuration's `sim.seed`).
    #[arg(long)]
    seed: Option<u64>,
    /// Configuration file (defaults: the competition robot).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Directory for the SVG plots and JSON-lines logs.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Print one JSON object with every script's figures as the last line of stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Args)]
struct ConfigArgs {
    /// Print the default configuration (the competition robot) as TOML.
    #[arg(long, conflicts_with = "check", required_unless_present = "check")]
    print_default: bool,
    /// Parse and validate FILE; print every problem with its key, exit non-zero if any.
    #[arg(long, value_name = "FILE")]
    check: Option<PathBuf>,
    /// With --check: FILE is a robot's configuration (for `ratf run`), which refuses the
    /// simulator's sections (`[sim]`, `[traction]`).
    #[arg(long, requires = "check")]
    robot: bool,
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", report(&error));
            ExitCode::FAILURE
        }
    }
}

/// `error` and its causes on one line, each said once. Our error types say their cause in
/// their own message (`"calibration: {0}"`), which anyhow's own report would print again
/// under "Caused by", with a backtrace when `RUST_BACKTRACE` is set: a team reading a
/// refused calibration needs the sentence, not the stack.
fn report(error: &anyhow::Error) -> String {
    let mut message = error.to_string();
    for cause in error.chain().skip(1) {
        let text = cause.to_string();
        if !message.contains(&text) {
            message = format!("{message}: {text}");
        }
    }
    message
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Frames => {
            use ratf_protocol::messages::{Command as MegaCommand, Wheel};
            let frame = MegaCommand::WheelSpeed {
                wheel: Wheel::BackRight,
                speed_rad_s: 1.0,
            }
            .to_frame();
            println!("{}", String::from_utf8_lossy(&frame.encode()));
        }
        Command::Drive(args) => drive_command(&args)?,
        Command::Sim(args) if args.serve_pty.is_some() => serve_pty_command(&args)?,
        Command::Sim(args) => sim_command(&args)?,
        Command::Run(args) => run_command(&args),
        Command::Check(args) => check_command(&args),
        Command::Referee(args) => referee_command(&args)?,
        Command::Bench(BenchCommand::Navigation(args)) => nav_bench_command(&args)?,
        Command::Bench(BenchCommand::Localisation(args)) => loc_bench_command(&args)?,
        Command::Bench(BenchCommand::Rounds(args)) => rounds_bench_command(&args)?,
        Command::Bench(BenchCommand::Calibration(args)) => calibration_bench_command(&args)?,
        Command::Bench(BenchCommand::Bound(args)) => bound_bench_command(&args)?,
        Command::Bench(BenchCommand::Faults(args)) => faults_bench_command(&args)?,
        Command::Calibrate(args) => calibrate_command(&args)?,
        Command::Tune(TuneCommand::Motors(args)) => {
            let interrupt = if args.robot {
                quit_on_signals_and_panics("ratf tune motors", 1)
            } else {
                ratf_host::devices::Shared::new()
            };
            ratf_host::apps::tune::cli::motors_command(&args, &interrupt)?
        }
        Command::Tune(TuneCommand::Gains(args)) => {
            ratf_host::apps::tune::cli::gains_command(&args)?
        }
        Command::Replay(args) => replay_command(&args)?,
        Command::Soak(args) => soak_command(&args),
        Command::Config(args) => {
            if let Some(path) = args.check {
                let loaded = if args.robot {
                    Config::load_robot(&path)
                } else {
                    Config::load(&path)
                };
                match loaded {
                    Ok(config) => {
                        // Valid values the robot's core still cannot drive (magnet faces
                        // the task planner does not plan for) are no "ok" either.
                        let start = Field::competition().start_pose();
                        if let Err(error) = ratf_core::runtime::Core::new(&config, start) {
                            eprintln!("{}: the robot cannot run with it: {error}", path.display());
                            std::process::exit(1);
                        }
                        println!("{}: ok", path.display());
                    }
                    Err(ConfigError::Invalid { issues, .. }) => {
                        eprintln!("{}: {} invalid value(s):", path.display(), issues.len());
                        for issue in issues {
                            eprintln!("  {issue}");
                        }
                        std::process::exit(1);
                    }
                    Err(e) => {
                        eprintln!("{e}");
                        std::process::exit(1);
                    }
                }
            } else {
                let text = Config::default()
                    .to_toml_string()
                    .context("serialising the default configuration")?;
                print!("{text}");
            }
        }
    }
    Ok(())
}

fn nav_bench_command(args: &NavBenchArgs) -> anyhow::Result<()> {
    use ratf_host::apps::nav_bench::{self, Preset, Summary};
    let config = args.bench.config()?;
    let trips = nav_bench::round_trips();
    // Ours again on the other planner: the road map if the config plans through free
    // space, free space if it plans on the road map.
    let mut other_planner = config.clone();
    other_planner.navigation.free_routes = !config.navigation.free_routes;
    let runs = [
        ("ours", &config, Preset::Ours),
        ("original", &config, Preset::Original),
        (
            if config.navigation.free_routes {
                "ours, road map"
            } else {
                "ours, free routes"
            },
            &other_planner,
            Preset::Ours,
        ),
    ];
    println!(
        "{} trips × {} seed(s) from seed {}",
        trips.len(),
        args.bench.seeds,
        config.sim.seed
    );
    println!(
        "{:<19} {:>6} {:>8} {:>9} {:>9} {:>12} {:>13} {:>14} {:>6} {:>9}",
        "preset",
        "trips",
        "timeouts",
        "mean s",
        "max s",
        "goal err m",
        "goal err deg",
        "cross-track m",
        "coll",
        "sim speed"
    );
    let mut summaries = Vec::new();
    for (name, run_config, preset) in runs {
        let started = Instant::now();
        let results = nav_bench::run_preset(
            run_config,
            preset,
            run_config.sim.seed,
            args.bench.seeds,
            &trips,
        )?;
        let wall_s = started.elapsed().as_secs_f64();
        let s = Summary::of(&results);
        let sim_s: f64 = results.iter().map(|r| r.time_s).sum();
        println!(
            "{:<19} {:>6} {:>8} {:>9.2} {:>9.2} {:>12.4} {:>13.2} {:>14.4} {:>6} {:>8.0}x",
            name,
            s.trips,
            s.timeouts,
            s.mean_trip_s,
            s.max_trip_s,
            s.goal_pos_err_m,
            s.goal_heading_err_deg,
            s.max_cross_track_m,
            s.collisions,
            sim_s / wall_s.max(1e-9)
        );
        if args.verbose {
            for r in &results {
                println!(
                    "  {:?} -> {} seed {}: {:.2} s, route {:.2} m, goal err {:.4} m {:.2} deg{}",
                    r.trip.from,
                    r.trip.to,
                    r.seed,
                    r.time_s,
                    r.route_length_m,
                    r.goal_pos_err_m,
                    r.goal_heading_err_deg,
                    if r.docked_on_switch { ", switch" } else { "" }
                );
            }
        }
        for r in results.iter().filter(|r| r.collisions > 0 || r.timed_out) {
            println!(
                "  {:?} -> {} seed {}: {} collision(s) (first: {}), timed out: {}",
                r.trip.from,
                r.trip.to,
                r.seed,
                r.collisions,
                r.first_collision.as_deref().unwrap_or("-"),
                r.timed_out
            );
        }
        summaries.push(s);
    }
    println!("goal err = largest over trips (true pose after 0.3 s at rest vs the pick pose)");
    if args.bench.json {
        println!(
            "{}",
            serde_json::json!({ "world": config.sim.world, "ours": summaries[0], "original": summaries[1] })
        );
    }
    Ok(())
}

/// A JSON-lines log file that keeps the first write error for the end, so that a run is not
/// interrupted half-way by a full disk but still fails loudly.
struct JsonLog {
    path: PathBuf,
    out: BufWriter<File>,
    result: anyhow::Result<()>,
}

impl JsonLog {
    fn create(path: PathBuf) -> anyhow::Result<Self> {
        let file = File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        Ok(Self {
            path,
            out: BufWriter::new(file),
            result: Ok(()),
        })
    }

    /// Append `value` as one line (after an error, nothing more is written).
    fn write(&mut self, value: &impl serde::Serialize) {
        if self.result.is_ok() {
            self.result = serde_json::to_writer(&mut self.out, value)
                .map_err(anyhow::Error::from)
                .and_then(|()| Ok(self.out.write_all(b"\n")?));
        }
    }

    /// Append the summary line and flush; the first error of the whole log, if any.
    fn finish(mut self, summary: &impl serde::Serialize) -> anyhow::Result<()> {
        self.write(summary);
        let flushed = self.out.flush().map_err(anyhow::Error::from);
        self.result
            .and(flushed)
            .with_context(|| format!("writing {}", self.path.display()))
    }
}

/// The configuration from `path`, or the defaults.
fn load_config(path: Option<&Path>) -> anyhow::Result<Config> {
    match path {
        Some(path) => Ok(Config::load(path)?),
        None => Ok(Config::default()),
    }
}

fn drive_command(args: &DriveArgs) -> anyhow::Result<()> {
    let mut config = load_config(args.config.as_deref())?;
    if let Some(seed) = args.seed {
        config.sim.seed = seed;
    }
    let scripts: Vec<Named> = args.script.map_or(Named::ALL.to_vec(), |named| vec![named]);
    fs::create_dir_all(&args.out)
        .with_context(|| format!("creating the output directory {}", args.out.display()))?;
    println!(
        "{:<13} {:>7} {:>8} {:>10} {:>10} {:>10} {:>9} {:>9} {:>9} {:>6} {:>6} {:>9}",
        "script",
        "sim s",
        "path m",
        "end err m",
        "end err °",
        "max err m",
        "max err °",
        "loc end m",
        "loc max m",
        "slip",
        "coll",
        "sim speed"
    );
    let mut reports = Vec::new();
    for named in scripts {
        let log_path = args.out.join(format!("drive-{named}.jsonl"));
        let mut log = JsonLog::create(log_path)?;
        let started = Instant::now();
        let (report, trace) = drive::run(&config, named, |record| log.write(record))?;
        let wall_s = started.elapsed().as_secs_f64();
        log.finish(&report)?;
        let svg_path = args.out.join(format!("drive-{named}.svg"));
        fs::write(&svg_path, plot_drive(&config, &report, &trace))
            .with_context(|| format!("writing {}", svg_path.display()))?;
        println!(
            "{:<13} {:>7.1} {:>8.2} {:>10.4} {:>10.2} {:>10.4} {:>9.2} {:>9.4} {:>9.4} {:>6} {:>6} {:>8.0}x",
            report.script,
            report.sim_s,
            report.distance_m,
            report.final_pos_err_m,
            report.final_heading_err_deg,
            report.max_pos_err_m,
            report.max_heading_err_deg,
            report.localiser_final_pos_err_m,
            report.localiser_max_pos_err_m,
            report.slip_steps,
            report.collisions,
            report.sim_s / wall_s.max(1e-9)
        );
        for c in &trace.collisions {
            println!(
                "  collision at {:.2} s with {:?}, robot at ({:.3}, {:.3}) m",
                c.time_us as f64 * 1e-6,
                c.with,
                c.pose.x,
                c.pose.y
            );
        }
        reports.push((report, wall_s));
    }
    println!(
        "err: wheel odometry against ground truth; loc: the localiser (odometry + gyro + \
         beacons); sim speed = simulated s per wall s; wrote {} (SVG plots, JSON-lines logs)",
        args.out.display()
    );
    if args.json {
        let runs: Vec<serde_json::Value> = reports
            .iter()
            .map(|(report, wall_s)| {
                let mut value = serde_json::to_value(report).unwrap_or_default();
                value["wall_s"] = serde_json::json!(wall_s);
                value
            })
            .collect();
        println!("{}", serde_json::json!({ "drives": runs }));
    }
    Ok(())
}

/// The field with the true path, the odometry, footprints once a second and collisions.
fn plot_drive(config: &Config, report: &DriveReport, trace: &DriveTrace) -> String {
    let mut plot = FieldPlot::new(&Field::competition());
    for &pose in &trace.footprints {
        let footprint = OrientedRect::new(
            pose,
            config.robot.footprint_length_m,
            config.robot.footprint_width_m,
        );
        plot.outline(&footprint.corners(), "#4a7bd0");
    }
    plot.path(&trace.truth, "#1f4e9c", false, "ground truth");
    plot.path(&trace.odometry, "#e07b00", true, "wheel odometry");
    for collision in &trace.collisions {
        plot.mark(
            collision.pose.position(),
            "#d01010",
            &format!("{:?}", collision.with),
        );
    }
    plot.finish(&format!(
        "ratf drive {}: {:.2} m, odometry error at the end {:.1} mm / {:.2} deg, {} collisions",
        report.script,
        report.distance_m,
        report.final_pos_err_m * 1000.0,
        report.final_heading_err_deg,
        report.collisions
    ))
}

fn referee_command(args: &RefereeArgs) -> anyhow::Result<()> {
    use ratf_core::referee::protocol::parse_letters;
    use ratf_host::referee::practice::{Practice, PracticeOptions};
    use ratf_sim::referee::MockSettings;
    use std::time::Duration;

    let config = load_config(args.config.as_deref())?;
    let parts = match &args.parts {
        Some(text) => Some(
            parse_letters(&text.trim().to_ascii_uppercase())
                .with_context(|| format!("--parts {text:?}: expected 4 letters from B, G, R, X"))?,
        ),
        None => None,
    };
    let seconds = |name: &str, s: f64| -> anyhow::Result<Duration> {
        Duration::try_from_secs_f64(s).with_context(|| format!("--{name} {s}: not a duration"))
    };
    let machine_delay = seconds("machine-delay-s", args.machine_delay_s)?;
    let settings = MockSettings::for_round(
        args.round,
        args.seed,
        parts,
        u64::try_from(machine_delay.as_micros()).unwrap_or(u64::MAX),
    )?;
    let options = PracticeOptions {
        bind: (
            [0, 0, 0, 0],
            args.port.unwrap_or(config.referee.server_port),
        )
            .into(),
        settings,
        start_after: args
            .start_after_s
            .map(|s| seconds("start-after-s", s))
            .transpose()?,
        exit_after: args
            .exit_after_s
            .map(|s| seconds("exit-after-s", s))
            .transpose()?,
    };
    let practice =
        Practice::bind(options.clone()).with_context(|| format!("binding UDP {}", options.bind))?;
    // Operator lines from the terminal; with no stdin the reader ends at once and the
    // channel closes, leaving only --start-after-s to start the run.
    let (lines_tx, lines_rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::stdin().lines() {
            let Ok(line) = line else { break };
            if lines_tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut stdout = std::io::stdout().lock();
    practice.run(&lines_rx, &mut stdout)?;
    Ok(())
}

fn loc_bench_command(
    LocBenchArgs {
        bench: args,
        first_seed,
        calibrated,
    }: &LocBenchArgs,
) -> anyhow::Result<()> {
    use ratf_host::apps::loc_bench::{self, Metrics, nees_band};
    let config = args.config()?;
    let started = Instant::now();
    if *calibrated {
        println!("each seed calibrated first (ratf calibrate, with tape)");
    }
    let figures = loc_bench::run(
        &config,
        *first_seed..=first_seed.saturating_add(args.seeds.saturating_sub(1)),
        *calibrated,
        |condition, seed, ours, original| {
            eprintln!(
                "{condition:?} seed {seed}: position RMSE ours {:.4} m (NEES {:.2}), original \
                 {:.4} m (NEES {:.2})",
                ours.pos_rmse_m, ours.nees_mean, original.pos_rmse_m, original.nees_mean
            );
        },
    )?;
    let row = |name: &str, condition: &str, m: &Metrics| {
        println!(
            "{name:<9} {condition:<8} {:>10.4} {:>12.3} {:>11.4} {:>9.2} {:>9.2} {:>9.2} {:>11} \
             {:>5}",
            m.pos_rmse_m,
            m.heading_rmse_deg,
            m.max_pos_err_m,
            m.nees_mean,
            m.nees_position_mean,
            m.nees_heading_mean,
            m.divergences,
            m.runs
        );
    };
    println!(
        "{:<9} {:<8} {:>10} {:>12} {:>11} {:>9} {:>9} {:>9} {:>11} {:>5}",
        "filter",
        "cond.",
        "pos RMSE m",
        "heading RMSE°",
        "max err m",
        "NEES",
        "NEES x,y",
        "NEES θ",
        "divergences",
        "runs"
    );
    row("ours", "default", &figures.ours.default);
    row("ours", "faults", &figures.ours.faults);
    row("original", "default", &figures.original.default);
    row("original", "faults", &figures.original.faults);
    if *calibrated {
        println!(
            "calibrations refused: {} (those runs keep the beliefs from before the refused step)",
            figures.calibrations_refused
        );
    }
    let (lo, hi) = nees_band(3, args.seeds as u32);
    println!(
        "scored after the first 2 s; divergence: > 0.05 m after 2 s; consistent NEES (3 dof, \
         {} runs): mean within [{lo:.2}, {hi:.2}]; its position and heading shares: about 2 and \
         1; {:.1} s wall",
        args.seeds,
        started.elapsed().as_secs_f64()
    );
    if args.json {
        let mut value = serde_json::to_value(figures)?;
        for filter in ["ours", "original"] {
            for condition in ["default", "faults"] {
                value[filter][condition]["nees_band"] = serde_json::json!([lo, hi]);
            }
        }
        value["world"] = serde_json::json!(config.sim.world);
        value["calibrated"] = serde_json::json!(calibrated);
        println!("{value}");
    }
    Ok(())
}

/// The HMI's side of a simulated round: its tap, the operator's commands and the page's
/// round choice.
struct SimHmi<'a> {
    tap: ratf_host::hmi::tap::HmiTap,
    operator: ratf_host::devices::operator::OperatorReceiver,
    /// The page's end of `operator`, which the ROS 2 bridge shares when there is one.
    sender: ratf_host::devices::operator::OperatorSender,
    rounds: &'a ratf_host::hmi::commands::RoundChoice,
}

fn sim_command(args: &SimArgs) -> anyhow::Result<()> {
    use ratf_host::devices::operator::operator_channel;
    use ratf_host::hmi::commands::{CONTROL_NAMES, RoundChoice};
    use ratf_host::hmi::server::{Controls, Info, OperatorSlot};
    use ratf_host::hmi::tap::HmiTap;
    let Some(address) = &args.hmi else {
        return sim_round(args, args.round, args.seed, None);
    };
    let config = load_config(args.config.as_deref())?;
    let hub = ratf_host::hmi::hub::Hub::new();
    let rounds = RoundChoice::default();
    let slot = OperatorSlot::default();
    let controls = Controls {
        operator: Some(slot.clone()),
        rounds: Some(rounds.clone()),
        replay: None,
    };
    let info = Info {
        mode: "sim",
        controls: CONTROL_NAMES
            .iter()
            .copied()
            .filter(|c| !c.starts_with("replay/"))
            .collect(),
        duration_s: None,
        timeline: Vec::new(),
        round: Some((args.round, args.seed)),
    };
    start_hmi(address, &config, hub.clone(), &info, controls)?;
    let (mut round, mut seed) = (args.round, args.seed);
    loop {
        let (sender, operator) = operator_channel();
        *slot
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(sender.clone());
        let mut tap = HmiTap::new(hub.clone(), "sim", &config);
        tap.round = Some((round, seed));
        let hmi = SimHmi {
            tap,
            operator,
            sender,
            rounds: &rounds,
        };
        sim_round(args, round, seed, Some(hmi))?;
        *slot
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = None;
        if !rounds.pending() {
            println!("round over: choose another round on the page, or press Ctrl-C to quit");
        }
        loop {
            if let Some(chosen) = rounds.take(std::time::Duration::from_secs(3600)) {
                (round, seed) = chosen;
                println!("the page chose round {round}, seed {seed}: restarting");
                break;
            }
        }
    }
}

/// Serve the HMI and print its address with the control token.
fn start_hmi(
    address: &str,
    config: &Config,
    hub: std::sync::Arc<ratf_host::hmi::hub::Hub>,
    info: &ratf_host::hmi::server::Info,
    controls: ratf_host::hmi::server::Controls,
) -> anyhow::Result<ratf_host::hmi::server::HmiServer> {
    use ratf_host::hmi::{auth::Token, floor::Floor, server};
    let token = Token::random()?;
    let floor = Floor::new(config);
    let server = server::serve(
        address,
        token,
        hub,
        &floor,
        config.field.field(),
        info,
        controls,
    )?;
    println!(
        "HMI: {} (open it on a phone or laptop on the same network; without ?token=… the \
         page only watches)",
        server.control_url()
    );
    Ok(server)
}

fn sim_round(
    args: &SimArgs,
    round_number: u8,
    seed: u64,
    hmi: Option<SimHmi<'_>>,
) -> anyhow::Result<()> {
    use ratf_host::apps::drive::PoseRecord;
    use ratf_host::apps::round::{self, RoundEvent};
    let mut config = load_config(args.config.as_deref())?;
    if let Some(world) = args.world {
        config.sim.world = world;
    }
    let field = Field::competition();
    fs::create_dir_all(&args.out)
        .with_context(|| format!("creating the output directory {}", args.out.display()))?;
    let stem = format!("sim-round{}-seed{}-{}", round_number, seed, args.policy);
    let log_path = args.out.join(format!("{stem}.jsonl"));
    let mut log = JsonLog::create(log_path.clone())?;
    println!(
        "ratf sim: round {}, seed {}, policy {}, machine delay {} s",
        round_number, seed, args.policy, args.machine_delay_s
    );
    let mut truth_path = Vec::new();
    let mut estimate_path = Vec::new();
    let mut collisions = Vec::new();
    let mut handling = Vec::new();
    let started = Instant::now();
    let options = round::RoundOptions {
        machine_delay_s: args.machine_delay_s,
        force_start_s: args.force_start_s,
        silent_server: args.silent_server,
        ..round::RoundOptions::new(round_number, seed, args.policy)
    };
    let notes = hmi.as_ref().map(|h| h.tap.notes());
    let note = |t_s: f64, kind: &'static str, text: &str, points: Option<u32>| {
        if let Some(notes) = &notes {
            let line = ratf_host::hmi::snapshot::EventLine {
                t_s,
                kind,
                text: text.to_owned(),
            };
            notes.push(line, points);
        }
    };
    let rounds = hmi.as_ref().map(|h| h.rounds);
    let pending = move || rounds.is_some_and(|r| r.pending());
    let ros2 = args.ros2.options().map_err(anyhow::Error::msg)?;
    // A live bridge shows the round as rviz2 would see the robot: at wall-clock speed.
    let speed = (args.realtime || ros2.is_some()).then_some(1.0);
    let (mut tap, operator, live) = match hmi {
        Some(SimHmi {
            tap,
            operator,
            sender,
            ..
        }) => {
            let abort: &dyn Fn() -> bool = &pending;
            (
                Some(tap),
                sender,
                round::Live {
                    operator: Some(operator),
                    speed,
                    abort: Some(abort),
                },
            )
        }
        None => {
            let (sender, operator) = ratf_host::devices::operator::operator_channel();
            (
                None,
                sender,
                round::Live {
                    operator: Some(operator),
                    speed,
                    abort: None,
                },
            )
        }
    };
    let mut bridge = ratf_host::ros2::live::live_bridge(&config, ros2.as_ref(), operator)?;
    let mut taps: Vec<&mut dyn ratf_core::runtime::Tap> = Vec::new();
    if let Some(tap) = &mut tap {
        taps.push(tap);
    }
    if let Some(bridge) = bridge.as_mut() {
        taps.push(bridge.as_mut());
    }
    let say = |t_s: f64, text: &str| println!("{t_s:7.2} s  {text}");
    let recording_path = args.out.join(format!("{stem}.mcap"));
    let beliefs = if args.calibrated {
        let (beliefs, refused) =
            ratf_host::apps::calibrate::beliefs(&options.apply_to(&config), true)?;
        match refused {
            Some(error) => println!(
                "calibration refused ({error}): the robot keeps what it believed before that step"
            ),
            None => println!(
                "calibrated: the robot believes the calibration drive's fit (lidar and beacons), \
                 then the odometry drive's (wheels), and its outline as a rule measured it"
            ),
        }
        beliefs
    } else {
        config.clone()
    };
    let report = round::run_recorded_live(
        &config,
        &beliefs,
        &options,
        &recording_path,
        &mut taps,
        live,
        |event| {
            let line = match event {
                RoundEvent::Tick {
                    time,
                    truth,
                    estimate,
                } => {
                    truth_path.push(truth.position());
                    estimate_path.push(estimate.position());
                    serde_json::json!({
                        "type": "tick",
                        "t_s": time.as_secs_f64(),
                        "truth": PoseRecord::from(*truth),
                        "estimate": PoseRecord::from(*estimate),
                    })
                }
                RoundEvent::Core { time, event } => {
                    let text = event.describe(&field);
                    if let Some(&at) = truth_path.last() {
                        match event {
                            ratf_core::runtime::Event::Picked { color, .. } => {
                                handling.push((at, true, *color))
                            }
                            ratf_core::runtime::Event::Placed { color, .. } => {
                                handling.push((at, false, *color))
                            }
                            _ => {}
                        }
                    }
                    say(time.as_secs_f64(), &text);
                    serde_json::json!({
                        "type": "event",
                        "t_s": time.as_secs_f64(),
                        "text": text,
                        "event": event,
                    })
                }
                RoundEvent::Collision(c) => {
                    collisions.push(*c);
                    let text = format!(
                        "collision with {:?}, robot at ({:.3}, {:.3}) m, {:.0}°",
                        c.with,
                        c.pose.x,
                        c.pose.y,
                        c.pose.yaw_rad.to_degrees()
                    );
                    say(c.time_us as f64 * 1e-6, &text);
                    note(c.time_us as f64 * 1e-6, "collision", &text, None);
                    serde_json::json!({
                        "type": "collision",
                        "t_s": c.time_us as f64 * 1e-6,
                        "text": text,
                        "pose": PoseRecord::from(c.pose),
                    })
                }
                RoundEvent::Points {
                    time,
                    slot,
                    color,
                    total,
                } => {
                    let text = format!(
                        "+1: {} on {} ({total} point{})",
                        color_name(*color),
                        ratf_core::runtime::slot_name(&field, ratf_core::field::WaypointId(*slot)),
                        if *total == 1 { "" } else { "s" }
                    );
                    say(time.as_secs_f64(), &text);
                    note(time.as_secs_f64(), "points", &text, Some(*total));
                    serde_json::json!({
                        "type": "points",
                        "t_s": time.as_secs_f64(),
                        "text": text,
                        "slot": slot,
                        "color": color,
                        "total": total,
                    })
                }
            };
            log.write(&line);
        },
    )?;
    drop(taps);
    let wall_s = started.elapsed().as_secs_f64();
    println!("{}", report.truth);
    log.write(&serde_json::json!({ "type": "truth", "truth": report.truth }));
    let mut summary = serde_json::to_value(&report)?;
    summary["type"] = serde_json::json!("summary");
    log.finish(&summary)?;

    let mut plot = FieldPlot::new(&Field::competition());
    plot.path(&truth_path, "#1f4e9c", false, "ground truth");
    plot.path(&estimate_path, "#e07b00", true, "localiser estimate");
    for c in &collisions {
        plot.collision(
            c.pose.position(),
            &format!("{:?} at {:.1} s", c.with, c.time_us as f64 * 1e-6),
        );
    }
    for &(at, picked, color) in &handling {
        let fill = match color {
            Some(ratf_core::field::PartColor::Red) => "#d03030",
            Some(ratf_core::field::PartColor::Green) => "#30a040",
            Some(ratf_core::field::PartColor::Blue) => "#3060d0",
            None => "#888888",
        };
        plot.pick_or_drop(at, picked, fill);
    }
    if !handling.is_empty() {
        plot.legend_entry(
            "#222222",
            "triangles: picks (up) and drops (down), in the part's colour",
        );
    }
    for &(color, x, y) in &report.final_parts {
        let fill = match color {
            ratf_core::field::PartColor::Red => "#d03030",
            ratf_core::field::PartColor::Green => "#30a040",
            ratf_core::field::PartColor::Blue => "#3060d0",
        };
        plot.filled(
            &[
                ratf_core::field::geometry::Vec2::new(x - 0.03, y - 0.03),
                ratf_core::field::geometry::Vec2::new(x + 0.03, y - 0.03),
                ratf_core::field::geometry::Vec2::new(x + 0.03, y + 0.03),
                ratf_core::field::geometry::Vec2::new(x - 0.03, y + 0.03),
            ],
            fill,
        );
    }
    let svg_path = args.out.join(format!("{stem}.svg"));
    fs::write(
        &svg_path,
        plot.finish(&format!(
            "ratf sim round {} seed {} ({}): {} points in {:.1} s, {} collisions",
            report.round, report.seed, args.policy, report.points, report.time_s, report.collisions
        )),
    )
    .with_context(|| format!("writing {}", svg_path.display()))?;

    println!(
        "round {}: {} points, {} in the outgoing warehouse, {:.1} s from the part list to the \
         last placement; {} collisions, {} actions given up; {} server disagreements over {} \
         snapshots; localisation RMSE {:.1} mm / {:.2}°; {:.1} s wall",
        report.round,
        report.points,
        report.outgoing,
        report.time_s,
        report.collisions,
        report.timeouts,
        report.server_disagreements,
        report.server_snapshots,
        report.pos_rmse_m * 1000.0,
        report.heading_rmse_deg,
        wall_s
    );
    println!(
        "wrote {}, {} and the recording {} (ratf replay {})",
        svg_path.display(),
        log_path.display(),
        recording_path.display(),
        recording_path.display()
    );
    if args.json {
        let mut value = serde_json::to_value(&report)?;
        value["wall_s"] = serde_json::json!(wall_s);
        println!("{value}");
    }
    Ok(())
}

fn replay_command(args: &ReplayArgs) -> anyhow::Result<()> {
    use ratf_host::apps::replay;
    use ratf_host::recording::Recording;
    let recording = Recording::read(&args.file)?;
    if let Some(address) = &args.hmi {
        return replay_hmi(address, recording);
    }
    let other = args.config.as_deref().map(Config::load).transpose()?;
    let field = Field::competition();
    let started = Instant::now();
    let report = replay::replay(&recording, other.as_ref(), |time, event| {
        if args.events {
            println!("{:7.2} s  {}", time.as_secs_f64(), event.describe(&field));
        }
    })?;
    let wall_s = started.elapsed().as_secs_f64();
    println!(
        "ratf replay {}: {} inputs over {:.1} s of robot time in {:.2} s wall ({:.0}× real time){}",
        args.file.display(),
        report.inputs,
        report.robot_time_s,
        wall_s,
        report.robot_time_s / wall_s.max(1e-9),
        if report.truncated {
            "; the file ends early (read up to its last complete chunk)"
        } else {
            ""
        }
    );
    match &report.first_divergence {
        None => println!("0 divergences: every output as recorded"),
        Some(d) => println!(
            "{} divergence(s); the first at {:.3} s, input {} ({}): {} recorded {} replayed {}",
            report.divergences,
            d.time.as_secs_f64(),
            d.input,
            d.input_kind,
            d.output,
            d.recorded,
            d.replayed
        ),
    }
    if args.config.is_some() {
        println!(
            "pose estimate against the recording: max {:.1} mm, RMS {:.1} mm; events {} \
             recorded, {} replayed",
            report.max_pose_difference_m * 1e3,
            report.rms_pose_difference_m * 1e3,
            report.recorded_events,
            report.replayed_events
        );
    }
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "inputs": report.inputs,
                "divergences": report.divergences,
                "first_divergence": report.first_divergence,
                "max_pose_difference_m": report.max_pose_difference_m,
                "rms_pose_difference_m": report.rms_pose_difference_m,
                "robot_time_s": report.robot_time_s,
                "wall_s": wall_s,
            })
        );
    }
    Ok(())
}

/// `ratf replay FILE --hmi ADDR`: the page with a time slider over the recording.
fn replay_hmi(address: &str, recording: ratf_host::recording::Recording) -> anyhow::Result<()> {
    use ratf_host::hmi::commands::CONTROL_NAMES;
    use ratf_host::hmi::{replay, server};
    let hub = ratf_host::hmi::hub::Hub::new();
    let (tx, rx) = std::sync::mpsc::channel();
    let info = server::Info {
        mode: "replay",
        controls: CONTROL_NAMES
            .iter()
            .copied()
            .filter(|c| c.starts_with("replay/"))
            .collect(),
        duration_s: Some(replay::duration_s(&recording)),
        timeline: replay::timeline(&recording),
        round: None,
    };
    let controls = server::Controls {
        replay: Some(tx),
        ..Default::default()
    };
    let config = recording.config.clone();
    let _server = start_hmi(address, &config, hub.clone(), &info, controls)?;
    println!(
        "replaying {:.1} s of robot time: use the slider, play and the timeline on the page; \
         Ctrl-C to quit",
        replay::duration_s(&recording)
    );
    replay::play(recording, hub, rx)?;
    Ok(())
}

/// A colour as a team says it.
fn color_name(color: ratf_core::field::PartColor) -> &'static str {
    match color {
        ratf_core::field::PartColor::Red => "red",
        ratf_core::field::PartColor::Green => "green",
        ratf_core::field::PartColor::Blue => "blue",
    }
}

fn rounds_bench_command(args: &RoundsBenchArgs) -> anyhow::Result<()> {
    use ratf_host::apps::round;
    let config = args.bench.config()?;
    println!(
        "world: {}{}",
        config.sim.world,
        if args.calibrated {
            ", each seed calibrated first (ratf calibrate, with tape)"
        } else {
            ""
        }
    );
    let started = Instant::now();
    let seeds = args.first_seed..=args.first_seed + args.bench.seeds.saturating_sub(1);
    println!("seeds {} to {}", seeds.start(), seeds.end());
    let mut refused = 0u32;
    let policies: Vec<Policy> = match args.policy {
        Some(policy) => vec![policy],
        None => Policy::ALL.to_vec(),
    };
    let rows = round::bench(
        &config,
        seeds.clone(),
        &policies,
        args.machine_delay_s,
        args.calibrated,
        |progress| match progress {
            round::BenchProgress::CalibrationRefused { seed, error } => {
                refused += 1;
                eprintln!(
                    "seed {seed}: calibration refused, the robot keeps what it believed before: \
                     {error}"
                );
            }
            round::BenchProgress::Run(r) => eprintln!(
                "round {} seed {} {:?}: {} points, {} out, {:.1} s, {} collisions, {} given up",
                r.round, r.seed, r.policy, r.points, r.outgoing, r.time_s, r.collisions, r.timeouts
            ),
        },
    )?;
    if args.calibrated {
        println!(
            "calibrations refused: {refused} (those robots keep the beliefs from before the refused \
             step)"
        );
    }
    println!(
        "{:<6} {:<9} {:>10} {:>10} {:>10} {:>8} {:>8} {:>11} {:>9} {:>5}",
        "round",
        "policy",
        "full score",
        "mean s",
        "max s",
        "bound s",
        "÷ bound",
        "collisions",
        "given up",
        "runs"
    );
    for r in &rows {
        println!(
            "{:<6} {:<9} {:>9.0}% {:>10.1} {:>10.1} {:>8.1} {:>7.2}× {:>11} {:>9} {:>5}",
            r.round,
            r.policy.name(),
            r.full_score_rate * 100.0,
            r.mean_time_s,
            r.max_time_s,
            r.bound_s,
            r.time_over_bound,
            r.collisions,
            r.timeouts,
            r.runs
        );
    }
    println!("where the time goes, mean s over the full-score runs (ratf_host::apps::time_split):");
    println!(
        "{:<6} {:<9} {:>8} {:>8} {:>8} {:>9} {:>8}",
        "round", "policy", "driving", "turning", "docking", "settling", "waiting"
    );
    for r in &rows {
        let t = &r.time_split;
        println!(
            "{:<6} {:<9} {:>8.1} {:>8.1} {:>8.1} {:>9.1} {:>8.1}",
            r.round,
            r.policy.name(),
            t.driving_s,
            t.turning_s,
            t.docking_s,
            t.settling_s,
            t.waiting_s
        );
    }
    println!(
        "what the collisions were, over all runs (ratf_host::apps::collision_causes): going to \
         a pick / carrying / elsewhere"
    );
    println!(
        "{:<6} {:<9} {:>17} {:>14} {:>14} {:>14} {:>11}",
        "round", "policy", "crowded neighbour", "part", "warehouse", "machine", "pole"
    );
    for r in &rows {
        let c = &r.collision_causes;
        let legs = |pick: u32, carry: u32, other: u32| format!("{pick} / {carry} / {other}");
        let cell = |f: fn(&ratf_host::apps::collision_causes::Struck) -> u32| {
            legs(f(&c.to_pick), f(&c.carrying), f(&c.elsewhere))
        };
        println!(
            "{:<6} {:<9} {:>17} {:>14} {:>14} {:>14} {:>11}",
            r.round,
            r.policy.name(),
            cell(|s| s.crowded_neighbour),
            cell(|s| s.part),
            cell(|s| s.warehouse),
            cell(|s| s.machine),
            cell(|s| s.pole)
        );
    }
    println!(
        "times: from the part list to the last placement, over the full-score runs; machine \
         delay {} s; bound: the least time physics and the rules allow each seed's arrangement \
         (ratf_core::planning::bound), mean over the seeds; {:.1} s wall",
        args.machine_delay_s,
        started.elapsed().as_secs_f64()
    );
    if args.bench.json {
        println!(
            "{}",
            serde_json::json!({
                "world": config.sim.world,
                "calibrated": args.calibrated,
                "calibrations_refused": refused,
                "seeds": [seeds.start(), seeds.end()],
                "rounds": rows
            })
        );
    }
    Ok(())
}

fn faults_bench_command(args: &FaultsBenchArgs) -> anyhow::Result<()> {
    use ratf_host::apps::fault_bench::{self, FaultProgress, Injection};
    let mut config = args.bench.config()?;
    // Issue 17: the fault bench runs in the realistic world unless told otherwise.
    config.sim.world = args.bench.world.unwrap_or(WorldProfile::Realistic);
    let mut injections = Injection::all();
    if !args.only.is_empty() {
        let known: Vec<&str> = injections.iter().map(|i| i.name()).collect();
        if let Some(bad) = args.only.iter().find(|n| !known.contains(&n.as_str())) {
            anyhow::bail!(
                "--only {bad}: no such fault; use one or more of {}",
                known.join(", ")
            );
        }
        injections.retain(|i| args.only.iter().any(|n| n == i.name()));
    }
    let started = Instant::now();
    let seeds = args.first_seed..=args.first_seed + args.bench.seeds.saturating_sub(1);
    println!(
        "world: {}{}; our policy; rounds 1–3",
        config.sim.world,
        if args.calibrated {
            ", each seed calibrated first (ratf calibrate, with tape)"
        } else {
            ""
        }
    );
    println!("seeds {} to {}", seeds.start(), seeds.end());
    let bench = fault_bench::bench(&config, seeds.clone(), &injections, args.calibrated, |p| {
        let (what, r, story) = match p {
            FaultProgress::Baseline(r) => ("no fault", r, &[][..]),
            FaultProgress::Faulted(name, r, story) => (name, r, story),
        };
        eprintln!(
            "round {} seed {} {what}: {} points, {} out, {:.1} s, {} collisions, {} given up",
            r.round, r.seed, r.points, r.outgoing, r.time_s, r.collisions, r.timeouts
        );
        let full = r.points == ratf_host::apps::round::full_score(r.round) && r.outgoing == 4;
        if args.verbose && (!full || r.collisions > 0) {
            for line in story {
                eprintln!("    {line}");
            }
        }
    })?;
    let rows = &bench.rows;
    println!(
        "fault-free runs of the same seeds: {:.0}% full score",
        bench.fault_free_full_score_rate * 100.0
    );
    println!(
        "{:<17} {:<5} {:>11} {:>14} {:>6} {:>8} {:>9} {:>7} {:>7} {:>7} {:>6} {:>7}",
        "fault",
        "recov",
        "full score",
        "by round",
        "points",
        "happened",
        "time lost",
        "coll.",
        "crowded",
        "gave up",
        "unsafe",
        "stop ms"
    );
    for r in rows {
        let by_round = r
            .full_score_rate_by_round
            .map(|f| format!("{:.0}", f * 100.0))
            .join("/");
        println!(
            "{:<17} {:<5} {:>10.0}% {:>14} {:>6.2} {:>8} {:>8.1}s {:>7} {:>7} {:>7} {:>6} {:>7}",
            r.fault,
            if r.recoverable { "yes" } else { "no" },
            r.full_score_rate * 100.0,
            by_round,
            r.mean_points,
            format!("{}/{}", r.injected, r.runs),
            r.mean_time_lost_s,
            format!("{}/{}", r.collisions, r.fault_free_collisions),
            r.crowded_collisions,
            r.given_up,
            r.unsafe_events,
            r.max_stop_ms
                .map_or("-".to_owned(), |ms| format!("{ms:.0}"))
        );
    }
    println!(
        "time lost: mean against the fault-free run of the same seed, over runs where both \
         scored fully; coll.: collisions with the fault / in the fault-free runs; crowded: of \
         those with the fault, a part standing where it crowds the pick the robot set out for \
         (ratf_sim::World::crowded_picks, unavoidable for this outline); unsafe: host ticks driving (wheels or magnet) more than 150 ms after \
         a stop fault became knowable (50 ms without a lidar packet, 3 Mega periods); stop ms: from \
         the fault itself to the last driving tick, worst run; {:.1} s wall",
        started.elapsed().as_secs_f64()
    );
    if args.bench.json {
        println!(
            "{}",
            serde_json::json!({
                "world": config.sim.world,
                "calibrated": args.calibrated,
                "seeds": [seeds.start(), seeds.end()],
                "fault_free_full_score_rate": bench.fault_free_full_score_rate,
                "faults": rows
            })
        );
    }
    Ok(())
}

fn calibrate_command(args: &CalibrateArgs) -> anyhow::Result<()> {
    use ratf_host::apps::calibrate;
    if let Some(CalibrateWhat::Odometry(odometry)) = &args.what {
        let shared = if odometry.robot {
            quit_on_signals_and_panics("ratf calibrate odometry", 1)
        } else {
            ratf_host::devices::Shared::new()
        };
        std::process::exit(calibrate::odometry_cli::odometry_command(odometry, &shared));
    }
    if args.robot {
        calibrate_on_robot(args);
    }
    let mut config = load_config(args.config.as_deref())?;
    config.sim.seed = args.seed;
    if let Some(world) = args.world {
        config.sim.world = world;
    }
    let run = calibrate::run_in_sim(&config, day_measures(args.no_tape, args.no_sheet))?;
    println!("{}", run.truth);
    let fit = &run.calibration;
    let e = &run.errors;
    println!(
        "{} stops over {:.1} s, {} collisions; residual RMS {:.2} σ, {} iterations",
        run.stops, run.sim_s, run.collisions, fit.residual_rms, fit.iterations
    );
    println!(
        "range scale   {:.5} ± {:.5}   (truth {:.5}; error {:+.3} %)",
        fit.range_scale, fit.range_scale_std, run.truth.lidar_range_scale, e.range_scale_pct
    );
    println!(
        "range offset  {:+.1} ± {:.1} mm  (truth {:+.1} mm; error {:+.1} mm)",
        fit.range_offset_m * 1e3,
        fit.range_offset_std_m * 1e3,
        run.truth.lidar_range_offset_m * 1e3,
        e.range_offset_mm
    );
    println!(
        "mount yaw     {:.2}° ± {:.2}°  (error {:+.2}°; before calibrating {:+.2}°)",
        fit.mount_yaw_rad.to_degrees(),
        fit.mount_yaw_std_rad.to_degrees(),
        e.mount_yaw_deg,
        e.uncalibrated_mount_yaw_deg
    );
    for (i, (b, std)) in fit.beacons.iter().zip(&fit.beacon_std_m).enumerate() {
        println!(
            "beacon {i}      ({:+.4}, {:+.4}) m ± {:.1} mm",
            b.x,
            b.y,
            std * 1e3
        );
    }
    println!(
        "beacons: largest error {:.1} mm (before: {:.1} mm); pole-to-pole distances within \
         {:.1} mm",
        e.beacon_max_mm, e.uncalibrated_beacon_max_mm, e.beacon_layout_max_mm
    );
    if let Some(path) = &args.write {
        write_calibrated(args.config.as_deref(), &config, fit, path)?;
    }
    Ok(())
}

/// Write `path`: the file `source` (or nothing) with the calibrated keys set.
fn write_calibrated(
    source: Option<&Path>,
    config: &Config,
    fit: &ratf_core::calibration::Calibration,
    path: &Path,
) -> anyhow::Result<()> {
    let mut file: toml::Table = match source {
        Some(source) => toml::from_str(
            &fs::read_to_string(source).with_context(|| format!("reading {}", source.display()))?,
        )
        .with_context(|| format!("parsing {}", source.display()))?,
        None => toml::Table::new(),
    };
    fit.write_into(config, &mut file);
    let text = toml::to_string(&file)?;
    Config::from_toml_str(&text).context("the calibrated configuration")?;
    fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    println!("wrote the calibrated configuration to {}", path.display());
    Ok(())
}

/// `ratf calibrate --robot`: exits with the documented codes.
fn calibrate_on_robot(args: &CalibrateArgs) -> ! {
    use ratf_host::apps::calibrate::robot::{self, RobotCalibrateError, RobotOptions};
    use ratf_host::apps::run;
    let exit = |code: i32, message: &str| -> ! {
        eprintln!("ratf calibrate: {message}");
        std::process::exit(code);
    };
    let Some(path) = args.config.as_deref() else {
        exit(2, "--robot needs --config FILE (the robot's configuration)");
    };
    let config = load_robot_or_exit(path, "ratf calibrate", 1);
    if args.tape.is_empty() {
        eprintln!(
            "ratf calibrate: no --tape: the range scale rests on the wheels' odometry and the \
             nominal layout (measure the six pole-to-pole distances for a better fit)"
        );
    }
    if args.pole.is_empty() {
        eprintln!(
            "ratf calibrate: no --pole: where the poles' layout stands on the field rests on \
             [field] beacons_m (measure each pole's centre from the floor sheet's edges)"
        );
    }
    if !args.yes {
        eprint!(
            "The robot must stand at the start pose (facing the incoming warehouse) with nothing \
             within 0.3 m of machine A's loop. Drive now? [y/N] "
        );
        let mut answer = String::new();
        let yes = std::io::stdin().read_line(&mut answer).is_ok()
            && answer.trim().eq_ignore_ascii_case("y");
        if !yes {
            exit(130, "not driven");
        }
    }
    if let Err(e) = fs::create_dir_all(&args.out) {
        exit(1, &format!("creating {}: {e}", args.out.display()));
    }
    let shared = quit_on_signals_and_panics("ratf calibrate", 1);
    let options = RobotOptions {
        tape: args.tape.clone(),
        poles_from_sheet: args.pole.clone(),
        recording: run::timestamped_recording(&args.out, "calibration"),
    };
    let result = robot::run_on_robot(&config, &options, &shared);
    if shared.panicked() {
        exit(
            4,
            "a thread panicked; the robot was sent zero references and magnet off",
        );
    }
    let calibrated = match result {
        Ok(calibrated) => calibrated,
        Err(RobotCalibrateError::Setup(e)) => exit(1, &e.to_string()),
        Err(RobotCalibrateError::Interrupted) => {
            exit(130, &RobotCalibrateError::Interrupted.to_string())
        }
        Err(e) => exit(3, &e.to_string()),
    };
    let fit = &calibrated.calibration;
    println!(
        "{} stops; residual RMS {:.2} σ, {} iterations; recording {}",
        calibrated.stops.len(),
        fit.residual_rms,
        fit.iterations,
        calibrated.recording.display()
    );
    println!(
        "range scale   {:.5} ± {:.5}\nrange offset  {:+.1} ± {:.1} mm\nmount yaw     {:.2}° ± {:.2}° (believed {:.2}°)",
        fit.range_scale,
        fit.range_scale_std,
        fit.range_offset_m * 1e3,
        fit.range_offset_std_m * 1e3,
        fit.mount_yaw_rad.to_degrees(),
        fit.mount_yaw_std_rad.to_degrees(),
        config.robot.lidar_yaw_deg
    );
    for (i, (b, std)) in fit.beacons.iter().zip(&fit.beacon_std_m).enumerate() {
        println!(
            "beacon {i}      ({:+.4}, {:+.4}) m ± {:.1} mm",
            b.x,
            b.y,
            std * 1e3
        );
    }
    if let Some(out) = &args.write
        && let Err(e) = write_calibrated(Some(path), &config, fit, out)
    {
        exit(1, &format!("{e:#}"));
    }
    std::process::exit(0);
}

fn bound_bench_command(args: &BoundBenchArgs) -> anyhow::Result<()> {
    use ratf_core::planning::bound::RoundBound;
    let mut config = load_config(args.config.as_deref())?;
    if !args.magnet_faces.is_empty() {
        config.robot.magnet_faces.clone_from(&args.magnet_faces);
        config.validate()?;
    }
    let faces = &config.robot.magnet_faces;
    let bound = RoundBound::new(&config, &Field::competition())?;
    println!(
        "lower bound on a round's time (ratf_core::planning::bound), robot.magnet_faces = {}: \
         {} carried at once",
        MagnetFace::list(faces),
        match faces.len() {
            1 => "one part".to_owned(),
            n => format!("{n} parts"),
        }
    );
    println!("round     mean s    least s  greatest s   (over the colour arrangements)");
    let mut rounds = Vec::new();
    for round in 1..=3 {
        let (mean, least, greatest) = bound.over_arrangements(round)?;
        println!("{round:<5} {mean:>10.2} {least:>10.2} {greatest:>11.2}");
        rounds.push(serde_json::json!({
            "round": round, "mean_s": mean, "least_s": least, "greatest_s": greatest,
        }));
    }
    if args.json {
        println!(
            "{}",
            serde_json::json!({ "magnet_faces": faces, "rounds": rounds })
        );
    }
    Ok(())
}

fn calibration_bench_command(args: &CalibrationBenchArgs) -> anyhow::Result<()> {
    use ratf_host::apps::calibrate::{self, CalibrationSummary};
    let config = args.bench.config()?;
    let seeds = args.first_seed..=args.first_seed + args.bench.seeds.saturating_sub(1);
    println!(
        "world: {}; seeds {} to {}; {}",
        config.sim.world,
        seeds.start(),
        seeds.end(),
        match (args.no_tape, args.no_sheet) {
            (false, false) => {
                "with the six pole-to-pole tape measures and the poles measured from the sheet"
            }
            (false, true) => "with the six pole-to-pole tape measures",
            (true, false) => "with the poles measured from the sheet",
            (true, true) => "no tape",
        }
    );
    let measures = day_measures(args.no_tape, args.no_sheet);
    let started = Instant::now();
    let mut runs = Vec::new();
    let mut refused = Vec::new();
    for seed in seeds.clone() {
        let mut seeded = config.clone();
        seeded.sim.seed = seed;
        let run = match calibrate::run_in_sim(&seeded, measures) {
            Ok(run) => run,
            Err(calibrate::CalibrateError::Fit(error)) => {
                eprintln!("seed {seed}: refused: {error}");
                refused.push(seed);
                continue;
            }
            Err(other) => return Err(other.into()),
        };
        let e = &run.errors;
        eprintln!(
            "seed {seed}: scale {:+.3} %, offset {:+.1} mm, yaw {:+.3}° (was {:+.2}°), \
             beacons {:.1} mm (layout {:.1} mm, shift {:.1} mm, rotation {:+.3}°), {} collisions",
            e.range_scale_pct,
            e.range_offset_mm,
            e.mount_yaw_deg,
            e.uncalibrated_mount_yaw_deg,
            e.beacon_max_mm,
            e.beacon_layout_max_mm,
            e.beacon_shift_mm,
            e.beacon_rotation_deg,
            run.collisions
        );
        runs.push(run);
    }
    let s = CalibrationSummary::of(&runs);
    println!("{:<28} {:>10} {:>10}", "|error|", "mean", "worst");
    let rows: [(&str, [f64; 2]); 9] = [
        ("range scale, %", s.range_scale_pct),
        ("range offset, mm", s.range_offset_mm),
        ("mount yaw, °", s.mount_yaw_deg),
        ("beacon centre, mm", s.beacon_max_mm),
        ("pole-to-pole, mm", s.beacon_layout_max_mm),
        ("layout's common shift, mm", s.beacon_shift_mm),
        ("layout's rotation, °", s.beacon_rotation_deg),
        ("mount yaw uncalibrated, °", s.uncalibrated_mount_yaw_deg),
        ("beacon uncalibrated, mm", s.uncalibrated_beacon_max_mm),
    ];
    for (name, [mean, worst]) in rows {
        println!("{name:<28} {mean:>10.3} {worst:>10.3}");
    }
    println!(
        "left for [localisation] (RMS): beacon_frame_shift_std_m {:.5}, \
         beacon_frame_rotation_std_deg {:.3}, lidar_zero_angle_std_deg {:.3}",
        s.left.beacon_shift_per_axis_mm * 1e-3,
        s.left.beacon_rotation_deg,
        s.left.zero_angle_deg
    );
    let collisions: u32 = runs.iter().map(|r| r.collisions).sum();
    println!(
        "{} fits, {} refused (seeds {refused:?}), {collisions} collisions, {:.1} s wall",
        s.runs,
        refused.len(),
        started.elapsed().as_secs_f64()
    );
    if args.bench.json {
        println!(
            "{}",
            serde_json::json!({
                "world": config.sim.world,
                "seeds": [seeds.start(), seeds.end()],
                "tape": !args.no_tape,
                "sheet": !args.no_sheet,
                "summary": s,
                "refused_seeds": refused,
            })
        );
    }
    Ok(())
}

fn serve_pty_command(args: &SimArgs) -> anyhow::Result<()> {
    use ratf_host::apps::round::{self, ROUND_LIMIT_S};
    use ratf_host::apps::serve_pty::{self, ServeEvent, ServeOptions};
    let mut config = load_config(args.config.as_deref())?;
    if let Some(world) = args.world {
        config.sim.world = world;
    }
    if args.ros2.ros2 {
        anyhow::bail!(
            "--ros2 with --serve-pty: the bridge belongs to the robot's side, give --ros2 to \
             `ratf run` instead"
        );
    }
    let dir = args.serve_pty.clone().context("--serve-pty DIR")?;
    let options = ServeOptions {
        dir,
        round: round::RoundOptions {
            machine_delay_s: args.machine_delay_s,
            ..round::RoundOptions::new(args.round, args.seed, args.policy)
        },
        server_port: args.server_port,
        limit_s: ROUND_LIMIT_S,
        wait_for_robot_s: args.wait_for_robot_s,
        unplug: match (args.unplug, args.unplug_at_s) {
            (Some(device), Some(at_s)) => Some(serve_pty::Unplug::new(
                match device {
                    UnplugDevice::Mega => serve_pty::ServedDevice::Mega,
                    UnplugDevice::Lidar => serve_pty::ServedDevice::Lidar,
                },
                at_s,
                args.unplug_for_s.unwrap_or(1.0),
                ROUND_LIMIT_S,
            )?),
            _ => None,
        },
    };
    let quit = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, std::sync::Arc::clone(&quit))
            .context("installing the signal handlers")?;
    }
    let started = Instant::now();
    let report = serve_pty::serve(
        &config,
        &options,
        || quit.load(std::sync::atomic::Ordering::Relaxed),
        |event| match event {
            ServeEvent::Ready {
                mega,
                lidar,
                server,
            } => {
                println!(
                    "ratf sim --serve-pty: round {}, seed {}: mega {}, lidar {}, server udp {}",
                    args.round,
                    args.seed,
                    mega.display(),
                    lidar.display(),
                    server
                );
                println!("server port {}", server.port());
            }
            ServeEvent::Connected => {
                println!("   0.00 s  the Mega's port was opened: world started")
            }
            ServeEvent::Lidar { t_s, command } => {
                println!("{t_s:7.2} s  lidar command {command:?}")
            }
            ServeEvent::Point { t_s, color, total } => println!(
                "{t_s:7.2} s  +1: {} ({total} point{})",
                color_name(*color),
                if *total == 1 { "" } else { "s" }
            ),
            ServeEvent::HungUp { t_s } => println!("{t_s:7.2} s  the Mega's port was closed"),
            ServeEvent::Unplugged { t_s, device } => {
                println!("{t_s:7.2} s  unplugged: the {device}'s USB cable is out")
            }
            ServeEvent::Replugged { t_s, device, path } => println!(
                "{t_s:7.2} s  replugged: the {device}'s USB cable is back at {}",
                path.display()
            ),
            ServeEvent::Reopened { t_s } => {
                println!("{t_s:7.2} s  the Mega's port was opened again: the Mega boots")
            }
        },
    )?;
    println!(
        "round {}: {} points, last at {:.1} s of world time; {} collisions; {:.1} s world in {:.1} s wall",
        args.round,
        report.points,
        report.last_point_s,
        report.collisions,
        report.world_s,
        started.elapsed().as_secs_f64()
    );
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "points": report.points,
                "last_point_s": report.last_point_s,
                "collisions": report.collisions,
                "world_s": report.world_s,
                "connected": report.connected,
            })
        );
    }
    Ok(())
}

/// The robot's configuration at `path`, or the program `program` ends with `exit_code`
/// after every problem, each with its key.
fn load_robot_or_exit(path: &Path, program: &str, exit_code: i32) -> Config {
    match Config::load_robot(path) {
        Ok(config) => config,
        Err(ConfigError::Invalid { issues, .. }) => {
            eprintln!("{}: {} invalid value(s):", path.display(), issues.len());
            for issue in issues {
                eprintln!("  {issue}");
            }
            std::process::exit(exit_code);
        }
        Err(e) => {
            eprintln!("{program}: {e}");
            std::process::exit(exit_code);
        }
    }
}

/// Flags for a run on the robot's devices: SIGINT and SIGTERM ask it to quit, and a panic in
/// any thread marks it and asks it to quit (the loop sees the flag within a tick, and the
/// robot is stopped on the way out); on failure the program ends with `exit_code`.
fn quit_on_signals_and_panics(program: &str, exit_code: i32) -> ratf_host::devices::Shared {
    let shared = ratf_host::devices::Shared::new();
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(e) = signal_hook::flag::register(signal, shared.quit_flag()) {
            eprintln!("{program}: installing the signal handlers: {e}");
            std::process::exit(exit_code);
        }
    }
    let previous = std::panic::take_hook();
    let on_panic = shared.clone();
    std::panic::set_hook(Box::new(move |info| {
        on_panic.mark_panicked();
        previous(info);
    }));
    shared
}

/// `ratf run`: exits with the codes its help lists.
fn run_command(args: &RunArgs) -> ! {
    use ratf_host::apps::run::{self, EXIT_SETUP, RunOptions};
    let fail = |message: &str| -> ! {
        eprintln!("ratf run: {message}");
        std::process::exit(EXIT_SETUP);
    };
    let config = load_robot_or_exit(&args.config, "ratf run", EXIT_SETUP);
    let force_start = args.force_start.as_ref().map(|text| {
        ratf_core::referee::protocol::parse_letters(&text.trim().to_ascii_uppercase())
            .unwrap_or_else(|| {
                fail(&format!(
                    "--force-start {text:?}: expected 4 letters from B, G, R, X"
                ))
            })
    });
    if let Err(e) = fs::create_dir_all(&args.out) {
        fail(&format!("creating {}: {e}", args.out.display()));
    }
    let shared = quit_on_signals_and_panics("ratf run", EXIT_SETUP);
    let options = RunOptions {
        force_start,
        recording: run::default_recording(&args.out),
        status_hz: args.status_hz,
        ros2: args.ros2.options().unwrap_or_else(|e| fail(&e)),
        print_events: true,
    };
    let hmi = args.hmi.as_ref().map(|address| {
        use ratf_host::hmi::{commands::CONTROL_NAMES, server};
        let hub = ratf_host::hmi::hub::Hub::new();
        let (sender, receiver) = ratf_host::devices::operator::operator_channel();
        let info = server::Info {
            mode: "robot",
            controls: CONTROL_NAMES
                .iter()
                .copied()
                .filter(|c| !c.starts_with("replay/") && *c != "round")
                .collect(),
            duration_s: None,
            timeline: Vec::new(),
            round: None,
        };
        let controls = server::Controls {
            operator: Some(std::sync::Arc::new(std::sync::Mutex::new(Some(sender)))),
            ..Default::default()
        };
        let server = start_hmi(address, &config, hub.clone(), &info, controls)
            .unwrap_or_else(|e| fail(&format!("{e:#}")));
        let tap = ratf_host::hmi::tap::HmiTap::new(hub, "robot", &config);
        (server, receiver, tap)
    });
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match hmi {
        Some((_server, receiver, mut tap)) => {
            run::run_robot_with(&config, &options, &shared, Some(receiver), &mut [&mut tap])
        }
        None => run::run_robot(&config, &options, &shared),
    }));
    let report = match outcome {
        Ok(Ok(report)) => report,
        Ok(Err(e)) => fail(&e.to_string()),
        Err(_) => {
            eprintln!("ratf run: panicked; the robot was sent zero references and magnet off");
            std::process::exit(run::EXIT_PANIC);
        }
    };
    println!(
        "ratf run: {}: placed {} part(s), {:.1} s from the part list to the last placement; \
         {:.1} s of robot time, {} inputs ({} dropped: the core fell behind)",
        match &report.outcome {
            run::Outcome::Finished => "finished".to_owned(),
            run::Outcome::Interrupted => "interrupted".to_owned(),
            run::Outcome::DeviceFailed(why) => format!("device failure: {why}"),
            run::Outcome::Panicked => "a thread panicked".to_owned(),
        },
        report.placed,
        report.time_s,
        report.robot_s,
        report.inputs,
        report.inputs_dropped
    );
    println!(
        "latency from an input's arrival to its references written: p50 {} µs, p99 {} µs, max \
         {} µs over {} batches; host watchdog batches {}; CPU {:.1} ms per s; peak RSS {} KiB",
        report.latency.p50_us,
        report.latency.p99_us,
        report.latency.max_us,
        report.latency.count,
        report.watchdog_batches,
        report.cpu_per_s * 1e3,
        report.max_rss_kib
    );
    println!(
        "recorded {} (ratf replay {})",
        report.recording.display(),
        report.recording.display()
    );
    if report.stop_written {
        println!("the robot was sent zero references and magnet off");
    } else {
        println!(
            "the Mega's port was gone at the end: no stop could be written (its own watchdog \
             stops the wheels 100 ms after the last command; the magnet may still be on)"
        );
    }
    std::process::exit(report.outcome.exit_code());
}

/// The day's measures a simulated calibration takes, from the `--no-tape` and `--no-sheet`
/// flags.
fn day_measures(no_tape: bool, no_sheet: bool) -> ratf_host::apps::calibrate::DayMeasures {
    ratf_host::apps::calibrate::DayMeasures {
        tape: !no_tape,
        poles_from_sheet: !no_sheet,
    }
}

/// A command-line number of seconds that must be finite and above zero.
fn positive_seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if s.is_finite() && s > 0.0 => Ok(s),
        _ => Err(format!("{text}: a number of seconds above 0")),
    }
}

/// `ratf soak`: exits with the codes its help lists.
fn soak_command(args: &SoakArgs) -> ! {
    use ratf_host::apps::soak::{self, SoakOptions};
    let config = load_config(args.config.as_deref()).unwrap_or_else(|e| {
        eprintln!("ratf soak: {e:#}");
        std::process::exit(1);
    });
    let shared = quit_on_signals_and_panics("ratf soak", 1);
    let options = SoakOptions {
        duration_s: args.duration_s,
        first_seed: args.seed,
        out: args.out.clone(),
        keep_recordings: args.keep_recordings,
        window_s: args.window_s,
    };
    println!(
        "ratf soak: round 1 after round 1 for {:.0} s (seeds from {}), recordings in {}",
        args.duration_s,
        args.seed,
        args.out.display()
    );
    println!(
        "round  seed  wall s  outcome   placed points  RSS KiB  p50 µs  p99 µs  max µs  \
         batches written/received/reported/unread at end/silent  recording"
    );
    let report = soak::soak(&config, &options, &shared, |round| {
        println!(
            "{:5} {:5} {:7.0}  {:8} {:6} {:6} {:8} {:7} {:7} {:7}  {}/{}/{}/{}/{}  {} KiB",
            round.index,
            round.seed,
            round.at_s,
            format!("{:?}", round.outcome).to_lowercase(),
            round.placed,
            round.points,
            round.rss_kib,
            round.latency.p50_us,
            round.latency.p99_us,
            round.latency.max_us,
            round.batches_written,
            round.batches_received,
            round.batches_reported_lost,
            round.batches_unread_at_end,
            round.batches_unreported_lost,
            round.recording_bytes / 1024,
        );
    })
    .unwrap_or_else(|e| {
        eprintln!("ratf soak: {e}");
        std::process::exit(1);
    });
    let (p99_min, p99_max) = report.p99_range_us();
    let failures = report.failures();
    println!(
        "ratf soak: {} round(s) in {:.0} s{}; resident memory {} KiB after the first round, \
         growth after it {} KiB (limit {} KiB); p99 latency {}–{} µs per round; telemetry \
         batches lost without the link reporting them: {}; {} recording(s) written, {} \
         complete",
        report.rounds.len(),
        report.wall_s,
        if report.interrupted {
            " (interrupted)"
        } else {
            ""
        },
        report.rounds.first().map_or(0, |r| r.rss_kib),
        report.rss_growth_kib(),
        soak::RSS_GROWTH_LIMIT_KIB,
        p99_min,
        p99_max,
        report.unreported_lost(),
        report.rounds.len(),
        report
            .rounds
            .iter()
            .filter(|r| r.recording_check.is_ok())
            .count()
    );
    println!(
        "p99 latency pooled per {:.0} s of wall time:",
        args.window_s
    );
    for window in &report.latency_windows {
        println!(
            "  {:6.0}–{:6.0} s: {:3} round(s), {:7} inputs, p50 {} µs, p99 {} µs",
            window.from_s,
            window.to_s,
            window.rounds,
            window.histogram.count(),
            window.histogram.quantile_us(0.5),
            window.p99_us()
        );
    }
    let drift = report.p99_window_drift();
    match drift {
        Some(drift) => println!(
            "largest drift of a stretch's p99 from the first's: {:.1} % (stretches with at \
             least half the first's inputs)",
            drift * 100.0
        ),
        None => println!("p99 drift: fewer than two full stretches to compare"),
    }
    for failure in &failures {
        println!("FAILED: {failure}");
    }
    if args.json {
        let windows: Vec<_> = report
            .latency_windows
            .iter()
            .map(|w| {
                serde_json::json!({
                    "from_s": w.from_s,
                    "to_s": w.to_s,
                    "rounds": w.rounds,
                    "inputs": w.histogram.count(),
                    "p50_us": w.histogram.quantile_us(0.5),
                    "p99_us": w.p99_us(),
                })
            })
            .collect();
        let rounds: Vec<_> = report
            .rounds
            .iter()
            .map(|r| {
                serde_json::json!({
                    "round": r.index,
                    "seed": r.seed,
                    "at_s": r.at_s,
                    "finished": r.outcome == ratf_host::apps::run::Outcome::Finished,
                    "placed": r.placed,
                    "points": r.points,
                    "collisions": r.collisions,
                    "rss_kib": r.rss_kib,
                    "p50_us": r.latency.p50_us,
                    "p99_us": r.latency.p99_us,
                    "max_us": r.latency.max_us,
                    "inputs_dropped": r.inputs_dropped,
                    "batches_written": r.batches_written,
                    "batches_received": r.batches_received,
                    "batches_reported_lost": r.batches_reported_lost,
                    "batches_unread_at_end": r.batches_unread_at_end,
                    "batches_unreported_lost": r.batches_unreported_lost,
                    "recording_bytes": r.recording_bytes,
                    "recording_complete": r.recording_check.is_ok(),
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({
                "rounds": rounds,
                "wall_s": report.wall_s,
                "interrupted": report.interrupted,
                "rss_growth_kib": report.rss_growth_kib(),
                "p99_min_us": p99_min,
                "p99_max_us": p99_max,
                "latency_windows": windows,
                "p99_window_drift": drift,
                "unreported_lost": report.unreported_lost(),
                "passed": failures.is_empty(),
            })
        );
    }
    if report.interrupted {
        std::process::exit(ratf_host::apps::run::EXIT_INTERRUPTED);
    }
    std::process::exit(if failures.is_empty() { 0 } else { 1 });
}

/// `ratf check`: exits with the codes its help lists.
fn check_command(args: &CheckArgs) -> ! {
    use ratf_host::apps::check::operator::{Operator, Terminal, Unattended};
    use ratf_host::apps::check::report::EXIT_SETUP;
    use ratf_host::apps::check::{self, CheckOptions};
    let config = load_robot_or_exit(&args.config, "ratf check", EXIT_SETUP);
    let interrupt = quit_on_signals_and_panics("ratf check", EXIT_SETUP);
    let options = CheckOptions {
        observe_s: args.observe_s,
        on_field: !args.off_field,
        pwm_percent: args.pwm_percent,
        spin_s: args.spin_s,
    };
    if let Err(e) = options.validate() {
        eprintln!("ratf check: {e}");
        std::process::exit(2);
    }
    let mut operator: Box<dyn Operator> = if args.yes {
        Box::new(Unattended)
    } else {
        Box::new(Terminal::default())
    };
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        check::run_check(&config, &options, &interrupt, operator.as_mut())
    }));
    let Ok(report) = outcome else {
        eprintln!("ratf check: panicked; the robot was sent zero references and magnet off");
        std::process::exit(ratf_host::apps::run::EXIT_PANIC);
    };
    println!("ratf check summary:");
    for line in report.lines() {
        println!("  {line}");
    }
    if args.json {
        println!("{}", report.json());
    }
    if interrupt.panicked() {
        eprintln!(
            "ratf check: a thread panicked; the robot was sent zero references and magnet off"
        );
        std::process::exit(ratf_host::apps::run::EXIT_PANIC);
    }
    if report.interrupted {
        eprintln!("ratf check: interrupted; the robot was sent zero references and magnet off");
    }
    std::process::exit(report.exit_code());
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `ratf ARGS` as the command line parses them.
    fn parse(args: &[&str]) -> Result<Cli, clap::Error> {
        Cli::try_parse_from(std::iter::once("ratf").chain(args.iter().copied()))
    }

    #[test]
    fn an_error_that_says_its_cause_is_reported_with_each_cause_once() {
        use ratf_core::calibration::CalibrationError;
        use ratf_host::apps::calibrate::CalibrateError;
        let fit = CalibrationError::Inconsistent { residual_rms: 6.5 };
        let error = anyhow::Error::from(CalibrateError::Fit(fit.clone()))
            .context("calibrating in seed 36's world");
        let text = report(&error);
        assert_eq!(text.matches(&fit.to_string()).count(), 1, "{text}");
        assert!(
            text.starts_with("calibrating in seed 36's world: calibration: the sightings"),
            "{text}"
        );
    }

    #[test]
    fn the_command_line_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }

    #[test]
    fn hmi_alone_serves_on_this_computer_only_and_an_address_is_kept() {
        let Command::Sim(sim) = parse(&["sim", "--hmi"]).unwrap().command else {
            panic!("not sim");
        };
        assert_eq!(sim.hmi.as_deref(), Some(HMI_LOCAL));
        let Command::Run(run) = parse(&["run", "--config", "r.toml", "--hmi", "0.0.0.0:9000"])
            .unwrap()
            .command
        else {
            panic!("not run");
        };
        assert_eq!(run.hmi.as_deref(), Some("0.0.0.0:9000"));
        let Command::Replay(replay) = parse(&["replay", "a.mcap", "--hmi"]).unwrap().command else {
            panic!("not replay");
        };
        assert_eq!(replay.hmi.as_deref(), Some(HMI_LOCAL));
        let Command::Sim(sim) = parse(&["sim"]).unwrap().command else {
            panic!("not sim");
        };
        assert_eq!(sim.hmi, None, "off by default");
    }

    #[test]
    fn sim_and_run_take_the_same_ros2_options_and_they_need_ros2() {
        for base in [&["sim"][..], &["run", "--config", "r.toml"][..]] {
            let with = |extra: &[&str]| parse(&[base, extra].concat());
            assert!(with(&["--ros2-namespace", "/r1"]).is_err(), "{base:?}");
            assert!(with(&["--ros2-loopback"]).is_err(), "{base:?}");
            let ros2 = match with(&["--ros2", "--ros2-namespace", "/r1", "--ros2-cmd-vel"])
                .unwrap()
                .command
            {
                Command::Sim(sim) => sim.ros2,
                Command::Run(run) => run.ros2,
                _ => panic!("{base:?}"),
            };
            assert!(ros2.ros2 && ros2.ros2_cmd_vel && !ros2.ros2_loopback);
            assert_eq!(ros2.ros2_namespace, "/r1");
        }
    }
}
