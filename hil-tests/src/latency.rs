//! How long before a telemetry batch's first byte its control window closed: the age of
//! the data when the host starts receiving it, and the reason the batch start moves when
//! the tick's computation time changes.
//!
//! Method: a single encoder edge placed `d` µs before the expected start of batch n+1
//! (batch n's start + 20 ms) is counted in batch n+1 if the window closed after it, else in
//! batch n+2. The smallest `d` at which it is counted in batch n+1 is the latency, found by
//! bisection over fresh, deterministic simulations.

use crate::firmware::FirmwareError;
use crate::host_link::{HostLink, wheel_speeds};
use crate::sim::{CYCLES_PER_MS, CYCLES_PER_US, Hil};

/// Telemetry batch whose successor the probe edge targets (after boot settles).
const PROBE_BATCH: usize = 3;

/// Whether an edge `before_us` µs before the expected start of batch `PROBE_BATCH + 1` is
/// counted in that batch. With `driving`, the host sends `G` batches every 20 ms from
/// batch 1 on (5 ms after each batch start), so the PI controllers run.
pub fn edge_counted_in_next_batch(before_us: u64, driving: bool) -> Result<bool, FirmwareError> {
    let mut hil = Hil::boot()?;
    let mut host = HostLink::new(true);
    if !hil.run_until_telemetry_batches(2, 60 * CYCLES_PER_MS) {
        return Ok(false);
    }
    let first = hil.telemetry_batches()[1].0;
    for n in 0..PROBE_BATCH {
        hil.run_until(first + n as u64 * 20 * CYCLES_PER_MS + 5 * CYCLES_PER_MS);
        if driving {
            hil.send(&host.batch(&wheel_speeds([5.0; 4])));
        }
    }
    if !hil.run_until_telemetry_batches(PROBE_BATCH + 1, 60 * CYCLES_PER_MS) {
        return Ok(false);
    }
    let start = hil.telemetry_batches()[PROBE_BATCH].0;
    hil.run_until(start + 20 * CYCLES_PER_MS - before_us * CYCLES_PER_US);
    hil.step_encoder(0, true);
    if !hil.run_until_telemetry_batches(PROBE_BATCH + 2, 60 * CYCLES_PER_MS) {
        return Ok(false);
    }
    Ok(hil.telemetry_batches()[PROBE_BATCH + 1].1.ticks[0] == 1)
}

/// The latency from window close to the batch's first byte, µs, to `resolution_us`;
/// `None` if it is outside 0..=15 ms.
pub fn telemetry_latency_us(
    driving: bool,
    resolution_us: u64,
) -> Result<Option<u64>, FirmwareError> {
    let (mut low, mut high) = (0u64, 15_000u64);
    if !edge_counted_in_next_batch(high, driving)? {
        return Ok(None);
    }
    while high - low > resolution_us {
        let mid = (low + high) / 2;
        if edge_counted_in_next_batch(mid, driving)? {
            high = mid;
        } else {
            low = mid;
        }
    }
    Ok(Some(high))
}
