//! Time keeping and encoder accumulation at 1 kHz (pure logic, run by `hw::encoders`'
//! Timer3 interrupt).
//!
//! The 50 kHz encoder interrupt keeps only 8-bit state so that it fits its cycle budget:
//! per encoder a wrapping position counter (net quadrature counts mod 256), and per encoder
//! pair one byte holding two 4-bit wrapping counters of skipped transitions (low nibble:
//! the pair's first encoder). Every millisecond this fold turns the change of those bytes
//! since the previous millisecond into 16-bit counts, which is exact as long as, within one
//! millisecond, an encoder moves less than 128 counts (the motors' top speed gives about
//! 12: 251 rpm × 2803.2 counts/rev ÷ 60 000 ms) and skips fewer than 16 transitions (at
//! most 50 samples are taken per millisecond, so 16 skips in a millisecond means an encoder
//! that is electrically broken).
//!
//! Every [`CONTROL_PERIOD_MS`] milliseconds the fold closes a control window and returns
//! [`WindowTotals`]: the counts since boot (wrapping 16-bit), the skip totals and the
//! window's end time, numbered. The interrupt publishes them without a critical section
//! (`hw::encoders`), and the main loop's [`SampleTaker`] turns the totals into the
//! [`ControlSample`] of the windows since its previous take: if the main loop is late by a
//! whole window, the next sample holds both windows' counts, so no count is ever lost.

use crate::board::{CONTROL_PERIOD_MS, TIME_BASE_PERIOD_US};

/// Encoders on the board (one per wheel).
pub const ENCODERS: usize = 4;

/// What the main loop takes for one control tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ControlSample {
    /// End of the latest control window, µs since boot (wrapping).
    pub now_us: u32,
    /// Net encoder counts during the window(s) since the previous sample, per encoder.
    pub encoder_deltas: [i16; ENCODERS],
    /// Skipped quadrature transitions since boot, per encoder (wrapping).
    pub quadrature_errors: [u8; ENCODERS],
}

/// What the fold publishes when a control window closes: totals since boot, so that a
/// reader that missed a window loses nothing (the difference of two totals holds both).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WindowTotals {
    /// Windows closed since boot (wrapping): a new value means a new window.
    pub windows: u8,
    /// End of this window, µs since boot (wrapping).
    pub end_us: u32,
    /// Net encoder counts since boot, per encoder (wrapping).
    pub counts: [i16; ENCODERS],
    /// Skipped quadrature transitions since boot, per encoder (wrapping).
    pub quadrature_errors: [u8; ENCODERS],
}

/// The fold state: see the module documentation.
pub struct Fold {
    last_positions: [u8; ENCODERS],
    last_skips: [u8; ENCODERS / 2],
    window_deltas: [i16; ENCODERS],
    skips_total: [u8; ENCODERS],
    now_us: u32,
    ms_in_window: u8,
    totals: WindowTotals,
}

impl Fold {
    /// A fold whose previous readings are `positions` and `skips` (the interrupt's counters
    /// when it was started), at time 0.
    pub const fn new(positions: [u8; ENCODERS], skips: [u8; ENCODERS / 2]) -> Self {
        Self {
            last_positions: positions,
            last_skips: skips,
            window_deltas: [0; ENCODERS],
            skips_total: [0; ENCODERS],
            now_us: 0,
            ms_in_window: 0,
            totals: WindowTotals {
                windows: 0,
                end_us: 0,
                counts: [0; ENCODERS],
                quadrature_errors: [0; ENCODERS],
            },
        }
    }

    /// One millisecond has passed; `positions` and `skips` are the encoder interrupt's
    /// counters now. Returns the new totals when this millisecond closes a control window.
    pub fn on_millisecond(
        &mut self,
        positions: [u8; ENCODERS],
        skips: [u8; ENCODERS / 2],
    ) -> Option<WindowTotals> {
        self.now_us = self.now_us.wrapping_add(TIME_BASE_PERIOD_US);
        for (k, &position) in positions.iter().enumerate() {
            let step = position.wrapping_sub(self.last_positions[k]) as i8;
            self.last_positions[k] = position;
            self.window_deltas[k] = self.window_deltas[k].wrapping_add(i16::from(step));
        }
        for (pair, &packed) in skips.iter().enumerate() {
            let step = packed.wrapping_sub(self.last_skips[pair]);
            self.last_skips[pair] = packed;
            let first = 2 * pair;
            self.skips_total[first] = self.skips_total[first].wrapping_add(step & 0x0F);
            self.skips_total[first + 1] = self.skips_total[first + 1].wrapping_add(step >> 4);
        }
        self.ms_in_window += 1;
        if self.ms_in_window < CONTROL_PERIOD_MS {
            return None;
        }
        self.ms_in_window = 0;
        let totals = &mut self.totals;
        for (total, window) in totals.counts.iter_mut().zip(self.window_deltas) {
            *total = total.wrapping_add(window);
        }
        totals.windows = totals.windows.wrapping_add(1);
        totals.end_us = self.now_us;
        totals.quadrature_errors = self.skips_total;
        self.window_deltas = [0; ENCODERS];
        Some(*totals)
    }

    /// Time since boot at the last millisecond, µs (wrapping).
    pub fn now_us(&self) -> u32 {
        self.now_us
    }
}

/// The main loop's side of the hand-over: the totals it last took, to turn the latest
/// [`WindowTotals`] into the counts of the windows since then.
#[derive(Clone, Copy, Debug, Default)]
pub struct SampleTaker {
    windows: u8,
    counts: [i16; ENCODERS],
}

impl SampleTaker {
    /// A taker that has taken nothing: it matches a [`Fold`] that has closed no window.
    pub const fn new() -> Self {
        Self {
            windows: 0,
            counts: [0; ENCODERS],
        }
    }

    /// The sample of the windows closed since the last take, if `latest` (the fold's latest
    /// totals) is a window not taken yet. Exact while fewer than 256 windows (5.12 s) and
    /// 32 768 counts per encoder pass between two takes.
    pub fn take(&mut self, latest: &WindowTotals) -> Option<ControlSample> {
        if latest.windows == self.windows {
            return None;
        }
        self.windows = latest.windows;
        let encoder_deltas =
            core::array::from_fn(|k| latest.counts[k].wrapping_sub(self.counts[k]));
        self.counts = latest.counts;
        Some(ControlSample {
            now_us: latest.end_us,
            encoder_deltas,
            quadrature_errors: latest.quadrature_errors,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// What the encoder interrupt's bytes look like after the given per-millisecond changes.
    struct IsrModel {
        positions: [u8; ENCODERS],
        skips: [u8; ENCODERS / 2],
    }

    impl IsrModel {
        fn advance(&mut self, counts: [i8; ENCODERS], skipped: [u8; ENCODERS]) {
            for (position, count) in self.positions.iter_mut().zip(counts) {
                *position = position.wrapping_add(count as u8);
            }
            for pair in 0..ENCODERS / 2 {
                let packed = skipped[2 * pair] + (skipped[2 * pair + 1] << 4);
                self.skips[pair] = self.skips[pair].wrapping_add(packed);
            }
        }
    }

    /// The fold and the main loop's taker, with the latest published totals between them
    /// (what `hw::encoders` does with its sequence-checked cell).
    struct Handover {
        fold: Fold,
        published: WindowTotals,
        taker: SampleTaker,
    }

    impl Handover {
        fn new(isr: &IsrModel) -> Self {
            Self {
                fold: Fold::new(isr.positions, isr.skips),
                published: WindowTotals::default(),
                taker: SampleTaker::new(),
            }
        }

        fn on_millisecond(&mut self, isr: &IsrModel) {
            if let Some(totals) = self.fold.on_millisecond(isr.positions, isr.skips) {
                self.published = totals;
            }
        }

        fn take_sample(&mut self) -> Option<ControlSample> {
            self.taker.take(&self.published)
        }
    }

    #[test]
    fn a_window_closes_every_control_period_with_its_deltas() {
        let mut isr = IsrModel {
            positions: [250, 3, 0, 128],
            skips: [0xF0, 0x0F],
        };
        let mut handover = Handover::new(&isr);
        for ms in 1..=u32::from(CONTROL_PERIOD_MS) {
            assert_eq!(handover.take_sample(), None, "early sample at {ms} ms");
            isr.advance([10, -10, 1, -1], [0, 1, 0, 0]);
            handover.on_millisecond(&isr);
            assert_eq!(handover.fold.now_us(), ms * 1000);
        }
        assert_eq!(handover.published.windows, 1);
        let sample = handover.take_sample().expect("a closed window");
        assert_eq!(sample.now_us, 20_000);
        assert_eq!(sample.encoder_deltas, [200, -200, 20, -20]);
        assert_eq!(sample.quadrature_errors, [0, 20, 0, 0]);
        assert_eq!(handover.take_sample(), None);
    }

    #[test]
    fn a_missed_window_is_added_to_the_next() {
        let mut isr = IsrModel {
            positions: [0; 4],
            skips: [0; 2],
        };
        let mut handover = Handover::new(&isr);
        for _ in 0..2 * CONTROL_PERIOD_MS {
            isr.advance([5, 0, -3, 0], [0; 4]);
            handover.on_millisecond(&isr);
        }
        let sample = handover.take_sample().expect("a closed window");
        assert_eq!(sample.now_us, 40_000);
        assert_eq!(sample.encoder_deltas, [200, 0, -120, 0]);
        assert_eq!(handover.take_sample(), None);
    }

    #[test]
    fn totals_wrap_without_losing_counts() {
        let mut isr = IsrModel {
            positions: [0; 4],
            skips: [0; 2],
        };
        let mut handover = Handover::new(&isr);
        let mut taken = [0i64; 4];
        // 100 windows of 20 × 127 counts: the 16-bit totals wrap several times.
        for _ in 0..100 * u32::from(CONTROL_PERIOD_MS) {
            isr.advance([127, -127, 0, 1], [0; 4]);
            handover.on_millisecond(&isr);
            if let Some(sample) = handover.take_sample() {
                for (t, d) in taken.iter_mut().zip(sample.encoder_deltas) {
                    *t += i64::from(d);
                }
            }
        }
        let ms = 100 * i64::from(CONTROL_PERIOD_MS);
        assert_eq!(taken, [127 * ms, -127 * ms, 0, ms]);
    }

    proptest! {
        /// With fewer than 128 counts and 16 skips per encoder per millisecond, the samples
        /// carry exactly the counts and skips of the windows closed up to them, whether the
        /// main loop takes every window or misses some.
        #[test]
        fn folding_wrapping_bytes_is_exact(
            steps in proptest::collection::vec(
                (any::<[i8; 4]>().prop_map(|c| c.map(|v| v.clamp(-127, 127))),
                 proptest::array::uniform4(0u8..16),
                 any::<bool>()),
                1..400),
            start_positions in any::<[u8; 4]>(),
            start_skips in any::<[u8; 2]>(),
        ) {
            let mut isr = IsrModel { positions: start_positions, skips: start_skips };
            let mut handover = Handover::new(&isr);
            let mut expected_deltas = [0i32; 4];
            let mut expected_skips = [0u32; 4];
            let mut at_last_close = (expected_deltas, expected_skips);
            let mut taken_deltas = [0i32; 4];
            for (counts, skipped, take) in &steps {
                isr.advance(*counts, *skipped);
                let windows = handover.published.windows;
                handover.on_millisecond(&isr);
                for k in 0..4 {
                    expected_deltas[k] += i32::from(counts[k]);
                    expected_skips[k] += u32::from(skipped[k]);
                }
                if handover.published.windows != windows {
                    at_last_close = (expected_deltas, expected_skips);
                }
                if !take {
                    continue;
                }
                if let Some(sample) = handover.take_sample() {
                    for (taken, delta) in taken_deltas.iter_mut().zip(sample.encoder_deltas) {
                        *taken += i32::from(delta);
                    }
                    prop_assert_eq!(taken_deltas, at_last_close.0);
                    prop_assert_eq!(sample.quadrature_errors, at_last_close.1.map(|s| s as u8));
                } else {
                    prop_assert_eq!(taken_deltas, at_last_close.0);
                }
            }
        }
    }
}
