//! The fault benchmark (`ratf bench faults`, issue 17): every round, our policy, each fault
//! kind alone and a mix of three recoverable kinds, against the fault-free run of the same
//! seed.
//!
//! Per seed and round the fault-free run comes first; its time sets the window the faults
//! are drawn in (from 1 s after the server's start to 90 % of the fault-free round), so each
//! fault falls while the robot works. Each faulted run is then a fresh round of the same
//! seed: the same world, parts and noise, with the plan's faults.

use serde::Serialize;

use ratf_core::config::{Config, Policy};
use ratf_core::field::Field;
use ratf_core::runtime::Event;
use ratf_sim::faults::{FaultKind, FaultPlan};

use super::calibrate;
use super::round::{
    Live, RoundError, RoundEvent, RoundOptions, RoundReport, START_DELAY_S, full_score, run_faulted,
};

/// How many recoverable kinds the mixed runs draw.
pub const MIXED_KINDS: usize = 3;

/// What a row injects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Injection {
    /// One kind.
    One(FaultKind),
    /// [`MIXED_KINDS`] recoverable kinds drawn per seed.
    Mixed,
}

impl Injection {
    /// Every row of the bench: each kind, then the mix.
    pub fn all() -> Vec<Self> {
        FaultKind::ALL
            .into_iter()
            .map(Self::One)
            .chain([Self::Mixed])
            .collect()
    }

    /// The row's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::One(kind) => kind.name(),
            Self::Mixed => "mixed",
        }
    }

    /// Whether a robot can still score fully through it.
    pub fn recoverable(self) -> bool {
        match self {
            Self::One(kind) => kind.recoverable(),
            Self::Mixed => true,
        }
    }

    /// The plan for `seed`, drawn in `window_us`.
    pub fn plan(self, seed: u64, window_us: std::ops::Range<u64>) -> FaultPlan {
        match self {
            Self::One(kind) => FaultPlan::draw(&[kind], seed, window_us),
            Self::Mixed => FaultPlan::draw_mixed(MIXED_KINDS, seed, window_us),
        }
    }
}

/// One fault over every round and seed: the `--json` row.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FaultRow {
    /// The fault's name.
    pub fault: &'static str,
    /// Whether a robot can still score fully through it.
    pub recoverable: bool,
    /// Runs (rounds × seeds).
    pub runs: u32,
    /// Runs in which the fault really happened (a slip needs a carried part, a knock a part
    /// standing in an incoming slot, a server fault an answer in its window).
    pub injected: u32,
    /// Fraction of runs with full points and 4 parts out, over all rounds.
    pub full_score_rate: f64,
    /// The same per round (1, 2, 3).
    pub full_score_rate_by_round: [f64; 3],
    /// Mean points per run.
    pub mean_points: f64,
    /// Runs in which the fault happened and the round still scored fully.
    pub recoveries: u32,
    /// Mean time lost against the fault-free run of the same seed and round, over the runs
    /// where both scored fully, s.
    pub mean_time_lost_s: f64,
    /// Largest such loss, s.
    pub max_time_lost_s: f64,
    /// Collisions over all runs.
    pub collisions: u32,
    /// Collisions over the fault-free runs of the same seeds and rounds (the world's own,
    /// without the fault).
    pub fault_free_collisions: u32,
    /// Of [`Self::collisions`], those with a part standing where it crowds the pick the robot
    /// was going to, as the parts stood when it set out (a part knocked out beside it):
    /// `ratf_sim::World::crowded_picks`, [`crate::apps::collision_causes`]. No outline that
    /// picks square on the slot's line can avoid them.
    pub crowded_collisions: u32,
    /// Actions given up over all runs.
    pub given_up: u32,
    /// Host ticks that drove (wheels non-zero or magnet on) later than 150 ms after a fault
    /// that must stop the robot became knowable ([`super::fault_round`]), over all runs.
    pub unsafe_events: u32,
    /// Largest time from such a fault to the robot's last driving command, ms.
    pub max_stop_ms: Option<f64>,
}

/// The bench's rows and the fault-free runs' own figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FaultBench {
    /// One row per fault (and the mix).
    pub rows: Vec<FaultRow>,
    /// Fraction of the fault-free runs (every round and seed) with full score: the ceiling
    /// the world itself sets.
    pub fault_free_full_score_rate: f64,
}

/// What the bench tells as it goes.
#[derive(Debug)]
pub enum FaultProgress<'a> {
    /// A fault-free run.
    Baseline(&'a RoundReport),
    /// A faulted run: its row's name, the report, and what happened in order (the faults
    /// with their times, then the robot's events, collisions and points, one line each).
    Faulted(&'static str, &'a RoundReport, &'a [String]),
}

/// Every row of `injections` over rounds 1–3 and `seeds`, our policy, in the world of
/// `config`. With `calibrated`, each seed's robot first believes its calibration
/// ([`calibrate::beliefs`]; a refused step keeps the beliefs from before it).
pub fn bench(
    config: &Config,
    seeds: std::ops::RangeInclusive<u64>,
    injections: &[Injection],
    calibrated: bool,
    mut on_progress: impl FnMut(FaultProgress<'_>),
) -> Result<FaultBench, RoundError> {
    let mut rows: Vec<FaultRow> = injections
        .iter()
        .map(|i| FaultRow {
            fault: i.name(),
            recoverable: i.recoverable(),
            runs: 0,
            injected: 0,
            full_score_rate: 0.0,
            full_score_rate_by_round: [0.0; 3],
            mean_points: 0.0,
            recoveries: 0,
            mean_time_lost_s: 0.0,
            max_time_lost_s: 0.0,
            collisions: 0,
            fault_free_collisions: 0,
            crowded_collisions: 0,
            given_up: 0,
            unsafe_events: 0,
            max_stop_ms: None,
        })
        .collect();
    let mut full_by_round = vec![[0u32; 3]; rows.len()];
    let mut runs_by_round = [0u32; 3];
    let mut timed = vec![0u32; rows.len()];
    let (mut base_runs, mut base_fulls) = (0u32, 0u32);
    let mut beliefs = std::collections::BTreeMap::new();
    for seed in seeds.clone() {
        let mut seeded = config.clone();
        seeded.sim.seed = seed;
        beliefs.insert(seed, calibrate::beliefs(&seeded, calibrated)?.0);
    }
    for round in 1..=3u8 {
        for seed in seeds.clone() {
            let robot = &beliefs[&seed];
            let options = RoundOptions::new(round, seed, Policy::Ours);
            let (base, _) = run_faulted(
                config,
                robot,
                &options,
                None,
                &mut [],
                Live::default(),
                |_| {},
            )?;
            on_progress(FaultProgress::Baseline(&base));
            let base_full = is_full(&base);
            base_runs += 1;
            base_fulls += u32::from(base_full);
            let start_us = ((START_DELAY_S + 1.0) * 1e6) as u64;
            let end_us = ((START_DELAY_S + 0.9 * base.time_s.max(2.0)) * 1e6) as u64;
            runs_by_round[usize::from(round - 1)] += 1;
            for (k, injection) in injections.iter().enumerate() {
                let plan = injection.plan(seed, start_us..end_us.max(start_us + 1));
                let mut story: Vec<String> = plan
                    .events
                    .iter()
                    .map(|e| {
                        let end = if e.end_us == u64::MAX {
                            "for good".to_owned()
                        } else {
                            format!("to {:.2} s", e.end_us as f64 * 1e-6)
                        };
                        format!("{:.2} s: fault {} {end}", e.start_us as f64 * 1e-6, e.kind)
                    })
                    .collect();
                let field = Field::competition();
                let (report, outcome) = run_faulted(
                    config,
                    robot,
                    &options,
                    Some(plan),
                    &mut [],
                    Live::default(),
                    |event| {
                        if let Some(line) = story_line(&field, event) {
                            story.push(line);
                        }
                    },
                )?;
                on_progress(FaultProgress::Faulted(injection.name(), &report, &story));
                let row = &mut rows[k];
                let full = is_full(&report);
                let happened = outcome.injected > 0;
                row.runs += 1;
                row.injected += u32::from(happened);
                row.mean_points += f64::from(report.points);
                row.collisions += report.collisions;
                row.fault_free_collisions += base.collisions;
                row.crowded_collisions += report.collision_causes.to_pick.crowded_neighbour;
                row.given_up += report.timeouts;
                row.unsafe_events += outcome.unsafe_ticks;
                if let Some(stop_us) = outcome.stop_after_fault_us {
                    let ms = stop_us as f64 * 1e-3;
                    row.max_stop_ms = Some(row.max_stop_ms.map_or(ms, |m: f64| m.max(ms)));
                }
                if full {
                    full_by_round[k][usize::from(round - 1)] += 1;
                    row.recoveries += u32::from(happened);
                    if base_full {
                        let lost = report.time_s - base.time_s;
                        timed[k] += 1;
                        row.mean_time_lost_s += lost;
                        row.max_time_lost_s = row.max_time_lost_s.max(lost);
                    }
                }
            }
        }
    }
    for (k, row) in rows.iter_mut().enumerate() {
        let runs = f64::from(row.runs.max(1));
        row.full_score_rate = f64::from(full_by_round[k].iter().sum::<u32>()) / runs;
        for r in 0..3 {
            row.full_score_rate_by_round[r] =
                f64::from(full_by_round[k][r]) / f64::from(runs_by_round[r].max(1));
        }
        row.mean_points /= runs;
        row.mean_time_lost_s /= f64::from(timed[k].max(1));
    }
    Ok(FaultBench {
        rows,
        fault_free_full_score_rate: f64::from(base_fulls) / f64::from(base_runs.max(1)),
    })
}

/// One line of a faulted run's story, for what a team reads when a run fails.
fn story_line(field: &Field, event: &RoundEvent) -> Option<String> {
    match event {
        RoundEvent::Core { time, event } => match event {
            Event::ActionStarted { .. }
            | Event::Picked { .. }
            | Event::PartSlipped { .. }
            | Event::PartJammed { .. }
            | Event::PartLetGoInHold { .. }
            | Event::PartLetGoNearDrop { .. }
            | Event::Regripped { .. }
            | Event::Placed { .. }
            | Event::Skipped { .. }
            | Event::ServerDisagrees { .. }
            | Event::RefereeFailed { .. }
            | Event::DeviceSilent { .. }
            | Event::DeviceBack { .. }
            | Event::DeviceFault { .. } => Some(format!(
                "{:.2} s: {}",
                time.as_secs_f64(),
                event.describe(field)
            )),
            _ => None,
        },
        RoundEvent::Collision(c) => Some(format!(
            "{:.2} s: collision with {:?} at ({:.3}, {:.3})",
            c.time_us as f64 * 1e-6,
            c.with,
            c.pose.x,
            c.pose.y
        )),
        RoundEvent::Points {
            time, slot, total, ..
        } => Some(format!(
            "{:.2} s: scored at waypoint {slot}, {total} in all",
            time.as_secs_f64()
        )),
        RoundEvent::Tick { .. } => None,
    }
}

/// Full points and every part out.
fn is_full(report: &RoundReport) -> bool {
    report.points == full_score(report.round) && report.outgoing == 4
}
