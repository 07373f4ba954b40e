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
//! - [`Unplug`] (`--unplug`): the world pulls a device's USB cable out for a while (issue
//!   17): its pseudo-terminal goes (the symlink removed, the master closed, its bytes
//!   dropped), and a new one appears at the same name later. The Mega runs on from the
//!   battery (hardware/README.md: the battery feeds the motors and the Mega), so its own
//!   watchdog stops the motors and lets the magnet go 100 ms after the host's last
//!   reference; opened again, it resets as on power-up (DTR; [`MEGA_BOOT_US`] later its
//!   `r`). The X4 is powered by its USB cable: it stops, and scans again only after a new
//!   start command. The world's own unplug does not count as a hang-up.

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
use ratf_sim::faults::MEGA_BOOT_US;
use ratf_sim::parts::PartEvent;
use ratf_sim::referee::{MockReferee, MockSettings, ServerSlot, round_parts};
use ratf_sim::world::{Scenario, World};

use super::round::{RoundOptions, START_DELAY_S, Scorer};
use crate::referee::server::MockServer;

/// How long the Mega's pseudo-terminal may stay closed after being opened before the
/// serve ends (a replug within it carries on).
pub const HANGUP_GRACE: Duration = Duration::from_secs(3);

/// The shortest unplug [`Unplug::new`] accepts, s: shorter is a loose contact, not a
/// replug (a device thread reopens its port every `[link] reconnect_period_ms`, 0.5 s).
pub const UNPLUG_MIN_S: f64 = 0.2;

/// The longest unplug [`Unplug::new`] accepts, s: `[link] give_up_after_s`'s default (10 s),
/// beyond which the robot gives the device up for good.
pub const UNPLUG_MAX_S: f64 = 10.0;

/// A device the world serves as a pseudo-terminal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ServedDevice {
    /// The Arduino Mega, `DIR/mega`.
    Mega,
    /// The X4 lidar, `DIR/lidar`.
    Lidar,
}

impl std::fmt::Display for ServedDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Mega => "Mega",
            Self::Lidar => "lidar",
        })
    }
}

/// The world pulls a device's USB cable out at a time, for a while (issue 17's USB unplug
/// and replug): see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unplug {
    /// Which device.
    pub device: ServedDevice,
    /// When, world time, s (world time 0: the robot opened the Mega).
    pub at_s: f64,
    /// For how long, s.
    pub for_s: f64,
}

/// An unplug that cannot be served.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum UnplugError {
    /// The time is not within the round.
    #[error("--unplug-at-s {0}: give a time after the start, in seconds, within the round's {1} s")]
    At(f64, f64),
    /// The duration is out of bounds.
    #[error("--unplug-for-s {0}: give a duration from {UNPLUG_MIN_S} to {UNPLUG_MAX_S} s")]
    For(f64),
}

impl Unplug {
    /// `device` pulled out at `at_s` (world time, within `(0, limit_s]`) for `for_s`
    /// ([`UNPLUG_MIN_S`] to [`UNPLUG_MAX_S`]).
    pub fn new(
        device: ServedDevice,
        at_s: f64,
        for_s: f64,
        limit_s: f64,
    ) -> Result<Self, UnplugError> {
        if !(at_s.is_finite() && at_s > 0.0 && at_s <= limit_s) {
            return Err(UnplugError::At(at_s, limit_s));
        }
        if !(UNPLUG_MIN_S..=UNPLUG_MAX_S).contains(&for_s) {
            return Err(UnplugError::For(for_s));
        }
        Ok(Self {
            device,
            at_s,
            for_s,
        })
    }
}

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
    /// A USB cable the world pulls out and plugs back, if any.
    pub unplug: Option<Unplug>,
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
    /// The world pulled a device's cable out ([`ServeOptions::unplug`]).
    Unplugged {
        /// World time, s.
        t_s: f64,
        /// Which.
        device: ServedDevice,
    },
    /// The cable is back: a new pseudo-terminal at the same name.
    Replugged {
        /// World time, s.
        t_s: f64,
        /// Which.
        device: ServedDevice,
        /// The symlink, to the new terminal.
        path: PathBuf,
    },
    /// The robot opened the replugged Mega: it boots.
    Reopened {
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

/// Where the world's unplug ([`ServeOptions::unplug`]) is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cable {
    /// Not yet pulled out (or no unplug planned).
    In,
    /// Out: no pseudo-terminal at the name.
    Out,
    /// The Mega's new terminal is there since this instant, not yet opened by the robot.
    Back(Instant),
    /// Plugged back (and the Mega reopened).
    Done,
}

/// Remove the symlink `link` (gone already is fine).
fn remove_link(link: &Path) -> Result<(), ServeError> {
    match std::fs::remove_file(link) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == ErrorKind::NotFound => Ok(()),
        Err(source) => Err(ServeError::Io {
            path: link.to_owned(),
            source,
        }),
    }
}

fn symlink(target: &Path, link: &Path) -> Result<(), ServeError> {
    remove_link(link)?;
    std::os::unix::fs::symlink(target, link).map_err(|source| ServeError::Io {
        path: link.to_owned(),
        source,
    })
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
    let mut scorer = Scorer::new(&field, Rules::for_round(round.round));
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
    let (mega_pty, lidar_pty) = (Pty::open("mega")?, Pty::open("lidar")?);
    let (mega_link, lidar_link) = (options.dir.join("mega"), options.dir.join("lidar"));
    symlink(&mega_pty.slave_path, &mega_link)?;
    symlink(&lidar_pty.slave_path, &lidar_link)?;
    on_event(&ServeEvent::Ready {
        mega: mega_link.clone(),
        lidar: lidar_link.clone(),
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
    while !mega_pty.connected() {
        if quit() || waiting.elapsed().as_secs_f64() >= options.wait_for_robot_s {
            return Ok(report);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    report.connected = true;
    on_event(&ServeEvent::Connected);
    // `None` while the world has the device's cable out.
    let (mut mega, mut lidar) = (Some(mega_pty), Some(lidar_pty));
    let mut cable = Cable::In;
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
        // The world's own unplug and replug.
        if let Some(unplug) = options.unplug {
            let t_s = world.now_us() as f64 * 1e-6;
            let (name, link) = match unplug.device {
                ServedDevice::Mega => ("mega", &mega_link),
                ServedDevice::Lidar => ("lidar", &lidar_link),
            };
            match cable {
                Cable::In if t_s >= unplug.at_s => {
                    remove_link(link)?;
                    match unplug.device {
                        ServedDevice::Mega => {
                            mega = None;
                            // Its bytes in flight are lost with it.
                            written = Decoder::new();
                            batch_has_telemetry = false;
                        }
                        ServedDevice::Lidar => {
                            lidar = None;
                            decoder = CommandDecoder::new();
                            streaming = false;
                        }
                    }
                    cable = Cable::Out;
                    on_event(&ServeEvent::Unplugged {
                        t_s,
                        device: unplug.device,
                    });
                }
                Cable::Out if t_s >= unplug.at_s + unplug.for_s => {
                    let pty = Pty::open(name)?;
                    symlink(&pty.slave_path, link)?;
                    cable = match unplug.device {
                        ServedDevice::Mega => {
                            mega = Some(pty);
                            Cable::Back(Instant::now())
                        }
                        ServedDevice::Lidar => {
                            lidar = Some(pty);
                            Cable::Done
                        }
                    };
                    on_event(&ServeEvent::Replugged {
                        t_s,
                        device: unplug.device,
                        path: link.clone(),
                    });
                }
                Cable::Back(_) if mega.as_ref().is_some_and(Pty::connected) => {
                    // Opening the port resets the board, as on the first opening.
                    world.reset_mega(Some(MEGA_BOOT_US));
                    cable = Cable::Done;
                    on_event(&ServeEvent::Reopened { t_s });
                }
                _ => {}
            }
        }
        let mega_up = mega.as_ref().is_some_and(Pty::connected);
        let lidar_up = lidar.as_ref().is_some_and(Pty::connected);
        // The robot's bytes first: they arrived before this instant.
        let from_robot = mega.as_mut().map(Pty::read_all).unwrap_or_default();
        if !from_robot.is_empty() {
            world.send_to_mega(&from_robot);
        }
        let commands = lidar.as_mut().map(Pty::read_all).unwrap_or_default();
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
        if let Some(lidar) = lidar.as_mut().filter(|_| lidar_up && !replies.is_empty()) {
            lidar.write(&replies);
        }
        while world.now_us() < target_us.min(limit_us) {
            if !server_started && world.now_us() >= start_us {
                server.referee_mut().start(world.now_us());
                server_started = true;
            }
            world.step();
            let to_mega = world.receive_from_mega();
            if let Some(mega) = mega.as_mut().filter(|_| mega_up && !to_mega.is_empty()) {
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
            if let Some(lidar) = lidar
                .as_mut()
                .filter(|_| streaming && lidar_up && !to_lidar.is_empty())
            {
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
                PartEvent::Placed { part, slot, color } => {
                    if let Some(server_slot) = ServerSlot::of_waypoint(&field, slot) {
                        let _ = server.referee_mut().place(server_slot, color, at_us);
                    }
                    if scorer.placed(part, slot, color) {
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
        let mega_out = cable == Cable::Out
            && options
                .unplug
                .is_some_and(|u| u.device == ServedDevice::Mega);
        match cable {
            // The world's own unplug is no hang-up, however long.
            _ if mega_out => hung_up_since = None,
            // Replugged: the robot reopens it within its reconnect period, or has given up.
            Cable::Back(since) => {
                if since.elapsed() >= HANGUP_GRACE {
                    break;
                }
            }
            _ if mega_up => hung_up_since = None,
            _ => {
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
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    report.world_s = world.now_us() as f64 * 1e-6;
    report.collisions = world.stats().collisions;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unplug_is_within_the_round_and_lasts_a_replug_not_a_loss() {
        let mega = ServedDevice::Mega;
        assert_eq!(
            Unplug::new(mega, 12.5, 1.0, 300.0),
            Ok(Unplug {
                device: mega,
                at_s: 12.5,
                for_s: 1.0
            })
        );
        assert!(Unplug::new(mega, 300.0, UNPLUG_MIN_S, 300.0).is_ok());
        assert!(Unplug::new(mega, 0.1, UNPLUG_MAX_S, 300.0).is_ok());
        for at_s in [0.0, -1.0, 301.0, f64::NAN, f64::INFINITY] {
            let error = Unplug::new(mega, at_s, 1.0, 300.0).unwrap_err();
            assert!(matches!(error, UnplugError::At(..)), "{at_s}: {error}");
            assert!(
                error.to_string().contains("--unplug-at-s") && error.to_string().contains("300"),
                "{error}"
            );
        }
        for for_s in [0.1, 10.5, -1.0, f64::NAN] {
            let error = Unplug::new(ServedDevice::Lidar, 5.0, for_s, 300.0).unwrap_err();
            assert!(matches!(error, UnplugError::For(..)), "{for_s}: {error}");
            assert!(error.to_string().contains("from 0.2 to 10 s"), "{error}");
        }
    }
}
