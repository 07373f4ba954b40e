//! `ratf soak`: `ratf run`'s robot against `ratf sim --serve-pty`'s world, round after round
//! in one process for a given time, watching what a long competition day would wear out:
//! resident memory, the core's latency, telemetry frames lost, recordings.
//!
//! Each round serves a fresh world (round 1, the next seed) on a thread behind real
//! pseudo-terminals and UDP, exactly as `ratf sim --serve-pty` does, and runs
//! [`run_robot`] on it as `ratf run` does; the robot, its device threads and its
//! recorder start and end with the round, in the same process, so a leak in any of them
//! shows as resident memory that grows from round to round. After each round:
//!
//! - the process's resident memory now (`VmRSS`, not the peak);
//! - the latency from an input's arrival to its references written (p50, p99, max);
//!   pooled over stretches of `window_s` too ([`LatencyWindow`]): a round's p99 is its
//!   ~25th-largest input and swings with one busy moment of the machine, ten minutes' is
//!   what "stable over the hour" is read from;
//! - telemetry batches: those that entered the Mega's terminal (the world counts them),
//!   those the robot's link delivered, those it reported lost (incomplete, corrupt, out
//!   of sequence), those written after the last one the robot read (its Mega thread stops
//!   reading when the run ends; found by the batches' sequence numbers), and the rest —
//!   lost without the link saying so;
//! - the recording's size; once every round is over, each recording is read back:
//!   complete (summary and footer), and holding every input the core consumed. (Reading
//!   them between rounds would put the reader's large buffers into the resident memory
//!   the soak is watching.)

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use ratf_core::config::{Config, ImuDevice, Policy};

use super::latency_histogram::LatencyHistogram;
use super::round::{ROUND_LIMIT_S, RoundOptions};
use super::run::{Latency, Outcome, RunError, RunOptions, run_robot};
use super::serve_pty::{ServeError, ServeEvent, ServeOptions, ServeReport, serve};
use crate::devices::Shared;
use crate::recording::{Recording, RecordingError};

/// How long a round's world waits for the robot to open its terminal, s.
const WAIT_FOR_ROBOT_S: f64 = 30.0;

/// How long to wait for the served world's device files and server, s.
const READY_TIMEOUT: Duration = Duration::from_secs(30);

/// Resident memory growth after the first round a soak accepts, KiB (issue 17: ≤ 1 MiB).
pub const RSS_GROWTH_LIMIT_KIB: u64 = 1024;

/// Why a soak could not go on.
#[derive(Debug, thiserror::Error)]
pub enum SoakError {
    /// The output folder could not be made.
    #[error("{}: {source}; check --out", .path.display())]
    Io {
        /// The folder.
        path: PathBuf,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// The world could not be served.
    #[error("round {round}: serving the world: {source}")]
    Serve {
        /// The round's number in the soak (1 = first).
        round: u32,
        /// Why.
        #[source]
        source: ServeError,
    },
    /// The served world never said where its devices are.
    #[error("round {round}: the served world was not ready within {READY_TIMEOUT:?}")]
    NotReady {
        /// The round's number in the soak.
        round: u32,
    },
    /// The world's thread panicked.
    #[error("round {round}: the world's thread panicked")]
    WorldPanicked {
        /// The round's number in the soak.
        round: u32,
    },
    /// The robot could not start.
    #[error("round {round}: ratf run: {source}")]
    Run {
        /// The round's number in the soak.
        round: u32,
        /// Why.
        #[source]
        source: RunError,
    },
}

/// How a soak is run.
#[derive(Clone, Debug, PartialEq)]
pub struct SoakOptions {
    /// Start no new round after this long, s (the round under way finishes).
    pub duration_s: f64,
    /// The first round's seed; each next round takes the next seed.
    pub first_seed: u64,
    /// Folder for the device links (`OUT/dev`) and the recordings.
    pub out: PathBuf,
    /// Keep every recording (otherwise each is deleted once read back, after the last
    /// round).
    pub keep_recordings: bool,
    /// Length of the stretches the latencies are pooled over, s ([`LatencyWindow`]).
    pub window_s: f64,
}

/// The latencies of the rounds that ended within one stretch of a soak's wall time, pooled.
#[derive(Clone, Debug, PartialEq)]
pub struct LatencyWindow {
    /// Wall time since the soak started where the stretch begins, s.
    pub from_s: f64,
    /// Where it ends, s.
    pub to_s: f64,
    /// Rounds that ended in it.
    pub rounds: u32,
    /// Their inputs' latencies.
    pub histogram: LatencyHistogram,
}

impl LatencyWindow {
    /// The pooled 99th percentile, µs (within [`super::latency_histogram::BUCKET_US`] above
    /// the exact one).
    pub fn p99_us(&self) -> u32 {
        self.histogram.quantile_us(0.99)
    }
}

/// What one round of a soak measured.
#[derive(Clone, Debug, PartialEq)]
pub struct SoakRound {
    /// 1 for the first round.
    pub index: u32,
    /// The world's seed.
    pub seed: u64,
    /// Wall time since the soak started when the round ended, s.
    pub at_s: f64,
    /// How the robot's run ended.
    pub outcome: Outcome,
    /// Parts placed (the robot's count).
    pub placed: u32,
    /// Points the world's referee scored.
    pub points: u32,
    /// Collisions in the world.
    pub collisions: u32,
    /// The process's resident memory after the round, KiB.
    pub rss_kib: u64,
    /// From an input's arrival to its references written.
    pub latency: Latency,
    /// Inputs the device threads dropped because the loop's inbox was full.
    pub inputs_dropped: u64,
    /// Complete telemetry batches that entered the Mega's terminal.
    pub batches_written: u32,
    /// Telemetry batches the robot's link delivered.
    pub batches_received: u32,
    /// Batches the link reported lost (incomplete, corrupt, out of sequence, overflowed).
    pub batches_reported_lost: u32,
    /// Written after the last batch the robot's link delivered: left unread when the run
    /// ended (the robot's Mega thread stops reading then, the world a little later).
    pub batches_unread_at_end: u32,
    /// Written, but neither delivered, nor reported, nor left unread at the end: lost
    /// silently.
    pub batches_unreported_lost: u32,
    /// The recording.
    pub recording: PathBuf,
    /// The recording's size, bytes.
    pub recording_bytes: u64,
    /// Inputs the core consumed (the recording must hold them all).
    pub inputs: u64,
    /// The recording read back complete with every consumed input (or why not); `Err`
    /// until it is read, after the last round.
    pub recording_check: Result<(), String>,
}

impl SoakRound {
    /// True when the round finished and nothing was lost.
    pub fn ok(&self) -> bool {
        self.outcome == Outcome::Finished
            && self.batches_unreported_lost == 0
            && self.recording_check.is_ok()
    }
}

/// What a whole soak measured.
#[derive(Clone, Debug, PartialEq)]
pub struct SoakReport {
    /// Every round, in order.
    pub rounds: Vec<SoakRound>,
    /// Wall time, s.
    pub wall_s: f64,
    /// Stopped early (Ctrl-C, SIGTERM, a panic).
    pub interrupted: bool,
    /// The latencies pooled per stretch of `SoakOptions::window_s`, in order (stretches in
    /// which no round ended are left out).
    pub latency_windows: Vec<LatencyWindow>,
}

impl SoakReport {
    /// Resident memory growth after the first round: the largest after any later round
    /// minus that after the first, KiB (0 with fewer than two rounds).
    pub fn rss_growth_kib(&self) -> u64 {
        let Some(first) = self.rounds.first() else {
            return 0;
        };
        self.rounds[1..]
            .iter()
            .map(|r| r.rss_kib.saturating_sub(first.rss_kib))
            .max()
            .unwrap_or(0)
    }

    /// The smallest and largest per-round p99 latency, µs.
    pub fn p99_range_us(&self) -> (u32, u32) {
        let p99 = self.rounds.iter().map(|r| r.latency.p99_us);
        (p99.clone().min().unwrap_or(0), p99.max().unwrap_or(0))
    }

    /// The largest relative change of a stretch's pooled p99 from the first stretch's, over
    /// the stretches holding at least half as many inputs as the first (a last stretch with
    /// a round or two in it is as noisy as one round); `None` with fewer than two such.
    pub fn p99_window_drift(&self) -> Option<f64> {
        let (first, rest) = self.latency_windows.split_first()?;
        let reference = f64::from(first.p99_us());
        if reference <= 0.0 {
            return None;
        }
        let full = first.histogram.count() / 2;
        rest.iter()
            .filter(|w| w.histogram.count() >= full.max(1))
            .map(|w| (f64::from(w.p99_us()) / reference - 1.0).abs())
            .reduce(f64::max)
    }

    /// Telemetry batches lost without the link reporting them, over all rounds.
    pub fn unreported_lost(&self) -> u64 {
        self.rounds
            .iter()
            .map(|r| u64::from(r.batches_unreported_lost))
            .sum()
    }

    /// What fails the soak's criteria (empty: passed): every round finished with its
    /// recording complete, no telemetry lost unreported, memory growth after the first
    /// round within [`RSS_GROWTH_LIMIT_KIB`]. Latency is reported, not judged.
    pub fn failures(&self) -> Vec<String> {
        let mut failures = Vec::new();
        if self.rounds.is_empty() {
            failures.push("no round was run".to_owned());
        }
        for round in &self.rounds {
            if round.outcome != Outcome::Finished {
                failures.push(format!(
                    "round {} (seed {}) did not finish: {:?}",
                    round.index, round.seed, round.outcome
                ));
            }
            if round.batches_unreported_lost > 0 {
                failures.push(format!(
                    "round {}: {} telemetry batch(es) lost that the link did not report",
                    round.index, round.batches_unreported_lost
                ));
            }
            if let Err(why) = &round.recording_check {
                failures.push(format!("round {}: recording: {why}", round.index));
            }
        }
        let growth = self.rss_growth_kib();
        if growth > RSS_GROWTH_LIMIT_KIB {
            failures.push(format!(
                "resident memory grew by {growth} KiB after the first round (limit \
                 {RSS_GROWTH_LIMIT_KIB} KiB)"
            ));
        }
        failures
    }
}

/// The process's resident memory now, KiB (`VmRSS` of `/proc/self/status`; 0 where there
/// is none).
pub fn current_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            status.lines().find_map(|line| {
                line.strip_prefix("VmRSS:")
                    .and_then(|rest| rest.trim().trim_end_matches("kB").trim().parse().ok())
            })
        })
        .unwrap_or(0)
}

/// Run rounds back to back until `options.duration_s` has passed or `shared` says quit;
/// `on_round` hears each round as it ends. `shared`'s quit and panic flags reach each
/// round's robot and world.
pub fn soak(
    config: &Config,
    options: &SoakOptions,
    shared: &Shared,
    mut on_round: impl FnMut(&SoakRound),
) -> Result<SoakReport, SoakError> {
    std::fs::create_dir_all(&options.out).map_err(|source| SoakError::Io {
        path: options.out.clone(),
        source,
    })?;
    let started = Instant::now();
    let mut rounds = Vec::new();
    let mut latency_windows: Vec<LatencyWindow> = Vec::new();
    let window_s = options.window_s.max(1.0);
    let mut index = 0u32;
    while !shared.quitting() && started.elapsed().as_secs_f64() < options.duration_s {
        index += 1;
        let seed = options.first_seed.wrapping_add(u64::from(index - 1));
        let (mut round, histogram) = one_round(config, options, shared, index, seed)?;
        round.at_s = started.elapsed().as_secs_f64();
        let from_s = (round.at_s / window_s).floor() * window_s;
        match latency_windows.last_mut() {
            Some(window) if window.from_s == from_s => {
                window.rounds += 1;
                window.histogram.merge(&histogram);
            }
            _ => latency_windows.push(LatencyWindow {
                from_s,
                to_s: from_s + window_s,
                rounds: 1,
                histogram,
            }),
        }
        on_round(&round);
        rounds.push(round);
    }
    for round in &mut rounds {
        round.recording_check = check_recording(&round.recording, round.inputs);
        if !options.keep_recordings {
            let _ = std::fs::remove_file(&round.recording);
        }
    }
    Ok(SoakReport {
        rounds,
        wall_s: started.elapsed().as_secs_f64(),
        interrupted: shared.quitting(),
        latency_windows,
    })
}

/// One round: the world on a thread, the robot on this one; with its latencies' histogram.
fn one_round(
    config: &Config,
    options: &SoakOptions,
    soak_shared: &Shared,
    index: u32,
    seed: u64,
) -> Result<(SoakRound, LatencyHistogram), SoakError> {
    let dev = options.out.join("dev");
    let serve_options = ServeOptions {
        dir: dev.clone(),
        round: RoundOptions::new(1, seed, Policy::Ours),
        server_port: 0,
        limit_s: ROUND_LIMIT_S,
        wait_for_robot_s: WAIT_FOR_ROBOT_S,
        unplug: None,
    };
    let robot_shared = Shared::new();
    let recording = options
        .out
        .join(format!("soak-round{index}-seed{seed}.mcap"));
    std::thread::scope(|scope| {
        let (ready_tx, ready_rx) = mpsc::channel();
        let (serve_options, robot_shared_ref) = (&serve_options, &robot_shared);
        let world = scope.spawn(move || {
            let robot_shared = robot_shared_ref;
            serve(
                config,
                serve_options,
                || {
                    // The soak's Ctrl-C or a panic reaches the round's robot; the world
                    // ends when the robot does, so no byte is written that it cannot read.
                    if soak_shared.panicked() {
                        robot_shared.mark_panicked();
                    }
                    if soak_shared.quitting() {
                        robot_shared.request_quit();
                    }
                    robot_shared.quitting()
                },
                |event| {
                    if let ServeEvent::Ready { server, .. } = event {
                        let _ = ready_tx.send(server.port());
                    }
                },
            )
        });
        let port = match ready_rx.recv_timeout(READY_TIMEOUT) {
            Ok(port) => port,
            Err(_) => {
                robot_shared.request_quit();
                return match world.join() {
                    Ok(Err(source)) => Err(SoakError::Serve {
                        round: index,
                        source,
                    }),
                    Ok(Ok(_)) => Err(SoakError::NotReady { round: index }),
                    Err(_) => Err(SoakError::WorldPanicked { round: index }),
                };
            }
        };
        let robot_config = robot_config(config, &dev, port);
        let run_options = RunOptions {
            force_start: None,
            recording: recording.clone(),
            status_hz: 0.0,
            print_events: false,
            ros2: None,
        };
        let run = run_robot(&robot_config, &run_options, &robot_shared);
        // Whatever happened, the world ends with the robot.
        robot_shared.request_quit();
        let served = world.join();
        let run = run.map_err(|source| SoakError::Run {
            round: index,
            source,
        })?;
        let served: ServeReport = match served {
            Ok(Ok(report)) => report,
            Ok(Err(source)) => {
                return Err(SoakError::Serve {
                    round: index,
                    source,
                });
            }
            Err(_) => return Err(SoakError::WorldPanicked { round: index }),
        };
        let (received, reported) = run.mega_link.map_or((0, 0), |stats| {
            (
                stats.batches,
                stats.incomplete_batches + stats.link.batches_discarded(),
            )
        });
        let recording_bytes = std::fs::metadata(&run.recording).map_or(0, |m| m.len());
        let written = u32::try_from(served.mega_batch_sequences.len()).unwrap_or(u32::MAX);
        let last = run
            .mega_link
            .and_then(|stats| stats.link.last_delivered_sequence);
        let read_up_to = read_up_to(&served.mega_batch_sequences, last);
        let unread_at_end = written - read_up_to;
        let unaccounted = read_up_to.saturating_sub(received.saturating_add(reported));
        let round = SoakRound {
            index,
            seed,
            at_s: 0.0,
            outcome: run.outcome,
            placed: run.placed,
            points: served.points,
            collisions: served.collisions,
            rss_kib: current_rss_kib(),
            latency: run.latency,
            inputs_dropped: run.inputs_dropped,
            batches_written: written,
            batches_received: received,
            batches_reported_lost: reported,
            batches_unread_at_end: unread_at_end,
            batches_unreported_lost: unaccounted,
            recording: run.recording,
            recording_bytes,
            inputs: run.inputs,
            recording_check: Err("not read back yet".to_owned()),
        };
        Ok((round, run.latency_histogram))
    })
}

/// How many of the batches `written` (their sequence numbers, in order) come up to the last
/// one the robot's link delivered, `last`: the last occurrence of that number (numbers wrap
/// after 255 batches, 5 s; what is left unread at the end is far less).
fn read_up_to(written: &[u8], last: Option<u8>) -> u32 {
    let Some(last) = last else { return 0 };
    written
        .iter()
        .rposition(|&seq| seq == last)
        .map_or(0, |i| u32::try_from(i + 1).unwrap_or(u32::MAX))
}

/// `config` as `ratf run` would load it for the world served under `dev`: its Mega and
/// lidar links, no IMU, the served server's `port`.
fn robot_config(config: &Config, dev: &Path, port: u16) -> Config {
    let mut robot = config.clone();
    robot.link.mega_port = dev.join("mega").display().to_string();
    robot.link.lidar_port = dev.join("lidar").display().to_string();
    robot.link.imu = ImuDevice::None;
    robot.referee.server_address = "127.0.0.1".to_owned();
    robot.referee.server_port = port;
    robot
}

/// The recording at `path` read back: complete (not truncated) and holding all `inputs`.
fn check_recording(path: &Path, inputs: u64) -> Result<(), String> {
    let recording = Recording::read(path).map_err(|e: RecordingError| e.to_string())?;
    if recording.truncated {
        return Err(format!("{}: ends early (no summary)", path.display()));
    }
    let recorded = recording.inputs.len() as u64;
    if recorded != inputs {
        return Err(format!(
            "{}: {recorded} inputs recorded, the core consumed {inputs}",
            path.display()
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round(index: u32, rss_kib: u64, p99_us: u32) -> SoakRound {
        SoakRound {
            index,
            seed: u64::from(index),
            at_s: 0.0,
            outcome: Outcome::Finished,
            placed: 4,
            points: 4,
            collisions: 0,
            rss_kib,
            latency: Latency {
                count: 10,
                p50_us: 100,
                p99_us,
                max_us: p99_us,
            },
            inputs_dropped: 0,
            batches_written: 100,
            batches_received: 99,
            batches_reported_lost: 1,
            batches_unread_at_end: 0,
            batches_unreported_lost: 0,
            recording: PathBuf::from("r.mcap"),
            recording_bytes: 1,
            inputs: 1,
            recording_check: Ok(()),
        }
    }

    fn report(rounds: Vec<SoakRound>) -> SoakReport {
        SoakReport {
            rounds,
            wall_s: 1.0,
            interrupted: false,
            latency_windows: Vec::new(),
        }
    }

    fn window(k: u32, samples_us: &[u32]) -> LatencyWindow {
        LatencyWindow {
            from_s: f64::from(k) * 600.0,
            to_s: f64::from(k + 1) * 600.0,
            rounds: 1,
            histogram: LatencyHistogram::of(samples_us),
        }
    }

    #[test]
    fn the_p99_drift_compares_each_full_stretch_with_the_first() {
        let mut soak = report(vec![round(1, 1, 1)]);
        let steady: Vec<u32> = (1..=100).map(|k| k * 10).collect();
        soak.latency_windows = vec![window(0, &steady)];
        assert_eq!(
            soak.p99_window_drift(),
            None,
            "one stretch: nothing to compare"
        );
        // p99 990 µs → 1 000 µs: the bucket's upper edge, 1 000 → 1 010.
        let slower: Vec<u32> = steady.iter().map(|us| us + 10).collect();
        soak.latency_windows.push(window(1, &slower));
        let drift = soak.p99_window_drift().unwrap();
        assert!((drift - 0.01).abs() < 1e-9, "{drift}");
        // A last stretch of a few inputs does not count, however slow.
        soak.latency_windows.push(window(2, &[5_000, 5_000]));
        assert!((soak.p99_window_drift().unwrap() - 0.01).abs() < 1e-9);
        // A full one that is twice as slow does.
        let doubled: Vec<u32> = steady.iter().map(|us| us * 2).collect();
        soak.latency_windows.push(window(3, &doubled));
        assert!(soak.p99_window_drift().unwrap() > 0.9);
    }

    #[test]
    fn memory_growth_counts_from_the_first_round() {
        let soak = report(vec![round(1, 50_000, 300), round(2, 50_800, 400)]);
        assert_eq!(soak.rss_growth_kib(), 800);
        assert_eq!(soak.p99_range_us(), (300, 400));
        assert!(soak.failures().is_empty(), "{:?}", soak.failures());
        let grown = report(vec![round(1, 50_000, 300), round(2, 51_100, 300)]);
        assert_eq!(grown.failures().len(), 1, "{:?}", grown.failures());
        assert!(grown.failures()[0].contains("1100 KiB"));
    }

    #[test]
    fn a_silent_loss_an_unfinished_round_or_a_bad_recording_fails_the_soak() {
        let mut lost = round(1, 1, 1);
        lost.batches_unreported_lost = 2;
        let mut unfinished = round(2, 1, 1);
        unfinished.outcome = Outcome::Interrupted;
        let mut bad = round(3, 1, 1);
        bad.recording_check = Err("ends early".to_owned());
        let soak = report(vec![lost, unfinished, bad]);
        let failures = soak.failures();
        assert_eq!(failures.len(), 3, "{failures:?}");
        assert!(failures[0].contains("2 telemetry batch(es) lost"));
        assert!(failures[1].contains("did not finish"));
        assert!(failures[2].contains("ends early"));
        assert_eq!(soak.unreported_lost(), 2);
        assert!(report(Vec::new()).failures()[0].contains("no round"));
    }

    #[test]
    fn batches_after_the_last_one_delivered_are_unread_not_lost() {
        let written = [0, 1, 2, 3, 4, 5, 6];
        assert_eq!(read_up_to(&written, Some(4)), 5);
        assert_eq!(read_up_to(&written, None), 0);
        // Numbers wrap (1..=255 after the first 0): the last occurrence counts.
        let wrapped: Vec<u8> = (0..=255u8).chain(1..=3).collect();
        assert_eq!(read_up_to(&wrapped, Some(2)), 258);
        assert_eq!(read_up_to(&wrapped, Some(9)), 10);
    }

    #[test]
    fn resident_memory_is_read_from_proc() {
        assert!(current_rss_kib() > 0);
    }
}
