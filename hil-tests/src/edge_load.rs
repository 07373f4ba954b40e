//! Encoder edge-rate trials under full host traffic, at random phases (issue 16, item 5).
//!
//! A trial boots the firmware, waits for its first telemetry batch, then from a random
//! phase (0–1 ms later, so the edges fall anywhere against the 50 kHz sampling and the
//! 1 kHz time base) starts at once:
//!
//! - the host streaming command batches back to back at full line rate (`G H I J L`, each
//!   closed by `Z`: the receive interrupt fires for every byte time of the trial), while
//!   the firmware sends its telemetry every 20 ms (the transmit interrupt) and drives the
//!   motors (I2C writes every tick);
//! - all four encoders turning at `rate_hz` edges per second each (wheels 0 and 2 forward,
//!   1 and 3 backward, one edge per wheel at each instant), the instants rounded per edge
//!   from the exact times, so the rate is not phase-locked to the 50 kHz sampling.
//!
//! It is lossless when the `g h i j` totals equal the edges driven, `q` reports no invalid
//! transition, and the host's bytes all arrived (`x`: no byte dropped, no batch discarded).

use crate::edge_rate::TRIAL_DIRECTIONS;
use crate::firmware::FirmwareError;
use crate::host_link::{HostLink, wheel_speeds};
use crate::sim::{CLOCK_HZ, CYCLES_PER_MS, Hil, UART_BYTE_CYCLES};
use ratf_protocol::messages::{Command, Faults, WHEEL_COUNT};

/// The outcome of one loaded trial.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadedTrial {
    /// Edges per second per encoder.
    pub rate_hz: f64,
    /// Cycles between the first telemetry batch + 1 ms and the first edge.
    pub phase_cycles: u64,
    /// Edges driven per encoder (signed by direction).
    pub expected: [i64; WHEEL_COUNT],
    /// Totals the firmware reported.
    pub counted: [i32; WHEEL_COUNT],
    /// Invalid transitions the firmware reported (`q`).
    pub quadrature_errors: [u8; WHEEL_COUNT],
    /// The firmware's fault counters (`x`) at the end.
    pub faults: Faults,
    /// Host bytes sent during the trial.
    pub host_bytes: usize,
}

impl LoadedTrial {
    /// Every edge counted, no invalid transition, every host byte received.
    pub fn lossless(&self) -> bool {
        self.edges_exact()
            && self.faults.serial_bytes_dropped == 0
            && self.faults.rx_batches_discarded == 0
    }

    /// Every edge counted and no invalid transition seen.
    pub fn edges_exact(&self) -> bool {
        self.expected
            .iter()
            .zip(self.counted)
            .all(|(&e, c)| e == i64::from(c))
            && self.quadrature_errors == [0; WHEEL_COUNT]
    }
}

/// A seeded xorshift64* generator for the trials' phases (printed with the seed, so any
/// failing phase can be rerun).
#[derive(Clone, Debug)]
pub struct Phases(u64);

impl Phases {
    /// Phases drawn from `seed` (any value; 0 is mapped to 1).
    pub fn new(seed: u64) -> Self {
        Self(seed.max(1))
    }

    /// The next phase, cycles in `0..CYCLES_PER_MS`.
    pub fn next_phase(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) % CYCLES_PER_MS
    }
}

/// Run one trial of `edges` edges per encoder at `rate_hz`, starting `phase_cycles` after
/// the first telemetry batch + 1 ms, with the host streaming throughout.
pub fn run_loaded_trial(
    rate_hz: f64,
    edges: u32,
    phase_cycles: u64,
) -> Result<LoadedTrial, FirmwareError> {
    let mut hil = Hil::boot()?;
    let booted = hil.run_until_telemetry_batches(1, 60 * CYCLES_PER_MS);
    let start = hil.cycle() + CYCLES_PER_MS + phase_cycles;
    let cycles_per_edge = CLOCK_HZ as f64 / rate_hz;
    // Host bytes to cover the edges and the two periods after them.
    let duration = (f64::from(edges) * cycles_per_edge) as u64 + 45 * CYCLES_PER_MS;
    let mut host = HostLink::new(true);
    let mut stream = Vec::new();
    let mut i = 0u32;
    while (stream.len() as u64) * UART_BYTE_CYCLES < duration {
        let mut commands = wheel_speeds([0.5 + 0.1 * (i % 8) as f32; WHEEL_COUNT]);
        commands.push(Command::Solenoid {
            on: i.is_multiple_of(2),
        });
        stream.extend(host.batch(&commands));
        i += 1;
    }
    if booted {
        hil.run_until(start);
        hil.send(&stream);
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
    let latest = hil.latest_telemetry();
    Ok(LoadedTrial {
        rate_hz,
        phase_cycles,
        expected,
        // No telemetry at all: nothing was counted.
        counted: latest.map_or([i32::MIN; WHEEL_COUNT], |t| t.ticks),
        quadrature_errors: latest.map_or([u8::MAX; WHEEL_COUNT], |t| t.quadrature_errors),
        faults: latest.map_or(
            Faults {
                serial_bytes_dropped: u8::MAX,
                ..Faults::default()
            },
            |t| t.faults,
        ),
        host_bytes: stream.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phases_are_seeded_and_within_a_millisecond() {
        let a: Vec<u64> = (0..50)
            .scan(Phases::new(7), |p, _| Some(p.next_phase()))
            .collect();
        let b: Vec<u64> = (0..50)
            .scan(Phases::new(7), |p, _| Some(p.next_phase()))
            .collect();
        assert_eq!(a, b);
        assert!(a.iter().all(|&p| p < CYCLES_PER_MS));
        let distinct: std::collections::BTreeSet<_> = a.iter().collect();
        assert!(distinct.len() > 45, "phases repeat: {a:?}");
    }
}
