//! Encoder edge-rate trials: drive all four encoders at a given edge rate and check the
//! firmware counted every edge.
//!
//! A trial boots the firmware, waits for its first telemetry batch (pull-ups on, encoder
//! ISR running), then moves wheels 0 and 2 forward and wheels 1 and 3 backward, one edge
//! per wheel at each instant, with the instants spaced `16 MHz / rate` cycles apart
//! (rounded per edge from the exact times, so the average rate is exact). It then waits
//! two control periods and compares the `g h i j` totals and the `q` error counters.

use crate::firmware::FirmwareError;
use crate::sim::{CLOCK_HZ, CYCLES_PER_MS, Hil};
use ratf_protocol::messages::WHEEL_COUNT;

/// Direction of each wheel during a trial (true = forward).
pub const TRIAL_DIRECTIONS: [bool; WHEEL_COUNT] = [true, false, true, false];

/// The outcome of one trial.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeTrial {
    /// Edges per second per encoder.
    pub rate_hz: f64,
    /// Edges driven per encoder (signed by direction).
    pub expected: [i64; WHEEL_COUNT],
    /// Totals the firmware reported.
    pub counted: [i32; WHEEL_COUNT],
    /// Invalid transitions the firmware reported (`q`).
    pub quadrature_errors: [u8; WHEEL_COUNT],
}

impl EdgeTrial {
    /// Every edge counted, no transition seen as invalid.
    pub fn lossless(&self) -> bool {
        self.expected
            .iter()
            .zip(self.counted)
            .all(|(&e, c)| e == i64::from(c))
            && self.quadrature_errors == [0; WHEEL_COUNT]
    }
}

/// Run one trial of `edges` edges per encoder at `rate_hz`.
pub fn run_trial(rate_hz: f64, edges: u32) -> Result<EdgeTrial, FirmwareError> {
    let mut hil = Hil::boot()?;
    let booted = hil.run_until_telemetry_batches(1, 60 * CYCLES_PER_MS);
    let start = hil.cycle() + CYCLES_PER_MS;
    if booted {
        let cycles_per_edge = CLOCK_HZ as f64 / rate_hz;
        for i in 0..edges {
            hil.run_until(start + (f64::from(i) * cycles_per_edge).round() as u64);
            hil.update_lines(|lines| {
                for (wheel, &forward) in TRIAL_DIRECTIONS.iter().enumerate() {
                    lines.step(wheel, forward);
                }
            });
        }
        let batches = hil.telemetry_batches().len();
        hil.run_until_telemetry_batches(batches + 2, 60 * CYCLES_PER_MS);
    }
    let expected = std::array::from_fn(|k| hil.lines().counted_edges(k) * i64::from(booted));
    let (counted, quadrature_errors) = match hil.latest_telemetry() {
        Some(t) => (t.ticks, t.quadrature_errors),
        // No telemetry at all: nothing was counted.
        None => ([i32::MIN; WHEEL_COUNT], [u8::MAX; WHEEL_COUNT]),
    };
    Ok(EdgeTrial {
        rate_hz,
        expected,
        counted,
        quadrature_errors,
    })
}

/// Highest rate (within `resolution_hz`) in `[low_hz, high_hz]` at which a trial is
/// lossless, by bisection; `None` if even `low_hz` loses counts. Every trial run is
/// returned too, so the caller can print them.
pub fn max_lossless_rate(
    low_hz: f64,
    high_hz: f64,
    resolution_hz: f64,
    edges: u32,
) -> Result<(Option<f64>, Vec<EdgeTrial>), FirmwareError> {
    let mut trials = Vec::new();
    let first = run_trial(low_hz, edges)?;
    trials.push(first);
    if !first.lossless() {
        return Ok((None, trials));
    }
    let (mut good, mut bad) = (low_hz, high_hz);
    let top = run_trial(high_hz, edges)?;
    trials.push(top);
    if top.lossless() {
        return Ok((Some(high_hz), trials));
    }
    while bad - good > resolution_hz {
        let mid = ((good + bad) / 2.0).round();
        let trial = run_trial(mid, edges)?;
        trials.push(trial);
        if trial.lossless() {
            good = mid;
        } else {
            bad = mid;
        }
    }
    Ok((Some(good), trials))
}
