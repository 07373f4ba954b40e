//! `ratf sim --serve-pty DIR`: the simulated world behind real device files, so `ratf run`
//! can drive it with no hardware. The simulated Mega and X4 speak through pseudo-terminals
//! (`DIR/mega` and `DIR/lidar` are symlinks to their slave ends) and the mock organisers'
//! server answers on UDP; the world runs in real time (world time follows the wall clock,
//! 1 ms steps), so every byte crosses a real tty at the pace the robot would see.
//!
//! - The world starts (its time 0, the Mega's power-up and `r`) when something opens
//!   `DIR/mega`, as a real Mega resets when its port is opened. The operator starts the
//!   server [`START_DELAY_S`] later.
//! - The X4 streams only after its start command `A5 60` (and stops at `A5 65`).
//! - Bytes for a pseudo-terminal nobody has open are dropped, as a cable would drop them.
//! - The floor's events go to the mock server (`IWP`, `OWP`, `MAP`, `MBP` answer what is
//!   on the floor) and are scored by the rules.
//! - It ends when the Mega's pseudo-terminal has been closed for [`HANGUP_GRACE`] after
//!   being opened (a replug within that time carries on), or after the time limit.

use std::fs::File;
use std::io::{ErrorKind, Read, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use ratf_core::config::Config;
use ratf_core::drivers::x4::{Command, CommandDecoder, Received};
use ratf_core::field::{Field, PartColor};
use ratf_core::planning::tasks::Rules;
use ratf_protocol::channels::Decoder;
use ratf_protocol::integrity::{Checksum, MCU_CHECKSUM_CHANNEL};
use ratf_protocol::messages::SWITCH_CHANNEL;
use ratf_sim::parts::PartEvent;
use ratf_sim::referee::{MockReferee, MockSettings, ServerSlot, round_parts};
use ratf_sim::world::{Scenario, World};

use super::round::{RoundOptions, START_DELAY_S, scores};
use crate::referee::server::MockServer;

/// How long the Mega's pseudo-terminal may stay closed after being opened before the
/// serve ends (a replug within it carries on).
pub const HANGUP_GRACE: Duration = Duration::from_secs(3);

/// Why the world could not be served.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// A pseudo-terminal could not be made or set up.
    #[error("pseudo-terminal: {what}: {source}")]
    Pty {
        /// What was being done.
        what: String,
        /// The system's error.
        #[source]
        source: nix::Error,
    },
    /// A file in the directory could not be made.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// The round's settings are not valid.
    #[error("round setup: {0}")]
    Mock(#[from] ratf_sim::referee::MockError),
    /// The mock server's socket failed.
    #[error("mock server: {0}")]
    Server(#[source] std::io::Error),
}

/// How the world is served.
#[derive(Clone, Debug, PartialEq)]
pub struct ServeOptions {
    /// Where the symlinks go.
    pub dir: PathBuf,
    /// The round, seed, policy (unused: the robot drives) and machine delay.
    pub round: RoundOptions,
    /// The server's UDP port on 127.0.0.1 (0 = any free port).
    pub server_port: u16,
    /// Stop after this long of world time, s.
    pub limit_s: f64,
    /// Stop if nothing opens the Mega's terminal within this long, s.
    pub wait_for_robot_s: f64,
}

/// What a served round measured.
#[derive(Clone, Debug, PartialEq)]
pub struct ServeReport {
    /// Points scored (the referee's view, from the simulated floor).
    pub points: u32,
    /// World time of the last scoring placement, s.
    pub last_point_s: f64,
    /// World time when the serve ended, s.
    pub world_s: f64,
    /// Collisions.
    pub collisions: u32,
    /// Whether a robot ever connected.
    pub connected: bool,
    /// The sequence number of every telemetry batch (one with a switch frame `s`: not the
    /// boot's `r` alone) whose checksum frame entered the Mega's pseudo-terminal, in order (bytes that found the terminal's buffer full are not
    /// counted): the truth against which a robot's link counts frames lost.
    pub mega_batch_sequences: Vec<u8>,
}

/// What the serve tells as it goes.
#[derive(Clone, Debug, PartialEq)]
pub enum ServeEvent {
    /// Ready: the device files and the server's address.
    Ready {
        /// `DIR/mega`.
        mega: PathBuf,
        /// `DIR/lidar`.
        lidar: PathBuf,
        /// The server.
        server: SocketAddr,
    },
    /// The robot opened the Mega's terminal: the world started.
    Connected,
    /// The X4 got a command.
    Lidar {
        /// World time, s.
        t_s: f64,
        /// The command.
        command: Command,
    },
    /// A scoring placement.
    Point {
        /// World time, s.
        t_s: f64,
        /// The part's colour.
        color: PartColor,
        /// Total so far.
        total: u32,
    },
    /// The robot closed the Mega's terminal.
    HungUp {
        /// World time, s.
        t_s: f64,
    },
}

/// One pseudo-terminal: the master end (non-blocking) and the slave's path.
struct Pty {
    master: File,
    slave_path: PathBuf,
}

impl Pty {
    fn open(name: &str) -> Result<Self, ServeError> {
        let problem = |e: crate::pty::PtyError| ServeError::Pty {
            what: format!("{name}: {}", e.what),
            source: e.source,
        };
        let (master, slave_path) = crate::pty::open_raw().map_err(problem)?;
        crate::pty::set_nonblocking(&master).map_err(problem)?;
        Ok(Self { master, slave_path })
    }

    /// True while some process has the slave end open.
    fn connected(&self) -> bool {
        crate::pty::slave_open(&self.master)
    }

    /// Everything the robot wrote since the last call.
    fn read_all(&mut self) -> Vec<u8> {
        let mut out = Vec::new();
        let mut buf = [0u8; 1024];
        loop {
            match self.master.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => out.extend_from_slice(&buf[..n]),
                // WouldBlock: nothing more; EIO: nobody on the other end.
                Err(_) => break,
            }
        }
        out
    }

    /// Send `bytes` to the robot; what does not fit in the terminal's buffer is lost, as
    /// on a serial line nobody reads. Returns how many bytes (from the start) went in.
    fn write(&mut self, bytes: &[u8]) -> usize {
        let mut rest = bytes;
        while !rest.is_empty() {
            match self.master.write(rest) {
                Ok(0) => break,
                Ok(n) => rest = &rest[n..],
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(_) => break,
            }
        }
        bytes.len() - rest.len()
    }
}

fn symlink(target: &Path, link: &Path) -> Result<(), ServeError> {
    let io = |source| ServeError::Io {
        path: link.to_owned(),
        source,
    };
    match std::fs::remove_file(link) {
        Ok(()) => {}
        Err(e) if e.kind() == ErrorKind::NotFound => {}
        Err(e) => return Err(io(e)),
    }
    std::os::unix::fs::symlink(target, link).map_err(io)
}

/// Serve the world of `options` until the robot hangs up, the limit, or `quit()` says so;
/// `on_event` hears what happens.
pub fn serve(
    config: &Config,
    options: &ServeOptions,
    quit: impl Fn() -> bool,
    mut on_event: impl FnMut(&ServeEvent),
) -> Result<ServeReport, ServeError> {
    let round = &options.round;
    let config = round.apply_to(config);
    let field = Field::competition();
    let rules = Rules::for_round(round.round);
    let letters = round_parts(round.round, round.seed)?;
    let machine_delay_us = (round.machine_delay_s * 1e6) as u64;
    let settings =
        MockSettings::for_round(round.round, round.seed, Some(letters), machine_delay_us)?;
    let mut server = MockServer::bind(
        SocketAddr::from(([127, 0, 0, 1], options.server_port)),
        MockReferee::new(settings),
    )
    .map_err(ServeError::Server)?;
    let scenario = Scenario {
        incoming: letters,
        machine_delay_us,
        green_to_blue_at_a: settings.green_to_blue_at_a,
        ..Scenario::new(&config)
    };
    let mut world = World::new(&config, &scenario);

    std::fs::create_dir_all(&options.dir).map_err(|source| ServeError::Io {
        path: options.dir.clone(),
        source,
    })?;
    let mut mega = Pty::open("mega")?;
    let mut lidar = Pty::open("lidar")?;
    let (mega_link, lidar_link) = (options.dir.join("mega"), options.dir.join("lidar"));
    symlink(&mega.slave_path, &mega_link)?;
    symlink(&lidar.slave_path, &lidar_link)?;
    on_event(&ServeEvent::Ready {
        mega: mega_link,
        lidar: lidar_link,
        server: server.local_addr().map_err(ServeError::Server)?,
    });

    let mut report = ServeReport {
        points: 0,
        last_point_s: 0.0,
        world_s: 0.0,
        collisions: 0,
        connected: false,
        mega_batch_sequences: Vec::new(),
    };
    // Finds the checksum frames that went into the Mega's terminal.
    let mut written = Decoder::new();
    let mut batch_has_telemetry = false;
    // Wait for the robot: the world is powered up when the Mega's port is opened.
    let waiting = Instant::now();
    while !mega.connected() {
        if quit() || waiting.elapsed().as_secs_f64() >= options.wait_for_robot_s {
            return Ok(report);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    report.connected = true;
    on_event(&ServeEvent::Connected);
    let epoch = Instant::now();
    let limit_us = (options.limit_s * 1e6) as u64;
    let start_us = (START_DELAY_S * 1e6) as u64;
    let mut server_started = false;
    let mut streaming = false;
    let mut decoder = CommandDecoder::new();
    let mut seen_part_events = 0;
    let mut hung_up_since: Option<Instant> = None;

    while !quit() && world.now_us() < limit_us {
        let target_us = u64::try_from(epoch.elapsed().as_micros()).unwrap_or(u64::MAX);
        let mega_up = mega.connected();
        let lidar_up = lidar.connected();
        // The robot's bytes first: they arrived before this instant.
        let from_robot = mega.read_all();
        if !from_robot.is_empty() {
            world.send_to_mega(&from_robot);
        }
        let commands = lidar.read_all();
        let mut replies = Vec::new();
        decoder.feed_all(&commands, |received| match received {
            Received::Command(command) => {
                streaming = match command {
                    Command::StartScan => true,
                    Command::StopScan => false,
                    Command::SoftRestart => streaming,
                };
                on_event(&ServeEvent::Lidar {
                    t_s: world.now_us() as f64 * 1e-6,
                    command,
                });
            }
            // The X4 answers its device information and health at once, scanning or not.
            Received::Request(request) => ratf_sim::lidar::reply(request).encode(&mut replies),
        });
        if lidar_up && !replies.is_empty() {
            lidar.write(&replies);
        }
        while world.now_us() < target_us.min(limit_us) {
            if !server_started && world.now_us() >= start_us {
                server.referee_mut().start(world.now_us());
                server_started = true;
            }
            world.step();
            let to_mega = world.receive_from_mega();
            if mega_up && !to_mega.is_empty() {
                let accepted = mega.write(&to_mega);
                written.feed(&to_mega[..accepted], |frame| {
                    if frame.channel() == MCU_CHECKSUM_CHANNEL {
                        if batch_has_telemetry {
                            let seq = Checksum::from_value(frame.value()).seq;
                            report.mega_batch_sequences.push(seq);
                        }
                        batch_has_telemetry = false;
                    } else if frame.channel() == SWITCH_CHANNEL {
                        batch_has_telemetry = true;
                    }
                });
            }
            let to_lidar = world.receive_from_lidar();
            if streaming && lidar_up && !to_lidar.is_empty() {
                lidar.write(&to_lidar);
            }
        }
        // The floor's news for the server and the score.
        let events = world.part_events()[seen_part_events..].to_vec();
        seen_part_events += events.len();
        for (at_us, event) in events {
            match event {
                PartEvent::Picked { from, .. } => {
                    if let Some(slot) = from.and_then(|id| ServerSlot::of_waypoint(&field, id)) {
                        let _ = server.referee_mut().take(slot, at_us);
                    }
                }
                PartEvent::Placed { slot, color, .. } => {
                    if let Some(server_slot) = ServerSlot::of_waypoint(&field, slot) {
                        let _ = server.referee_mut().place(server_slot, color, at_us);
                    }
                    if scores(&field, rules, slot.0, color) {
                        report.points += 1;
                        report.last_point_s = at_us as f64 * 1e-6;
                        on_event(&ServeEvent::Point {
                            t_s: report.last_point_s,
                            color,
                            total: report.points,
                        });
                    }
                }
                PartEvent::Dropped { .. } | PartEvent::Processed { .. } => {}
            }
        }
        server.poll(world.now_us()).map_err(ServeError::Server)?;
        if mega_up {
            hung_up_since = None;
        } else {
            let since = *hung_up_since.get_or_insert_with(|| {
                on_event(&ServeEvent::HungUp {
                    t_s: world.now_us() as f64 * 1e-6,
                });
                Instant::now()
            });
            if since.elapsed() >= HANGUP_GRACE {
                break;
            }
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    report.world_s = world.now_us() as f64 * 1e-6;
    report.collisions = world.stats().collisions;
    Ok(report)
}
