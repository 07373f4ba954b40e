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
//! Every [`CONTROL_PERIOD_MS`] milliseconds the fold closes a control window: the deltas of
//! exactly that window, with its end time, wait in [`ControlSample`] until the main loop
//! takes them. If the main loop is late by a whole window, the next window's deltas are
//! added to the waiting sample, so no count is ever lost.

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

/// The fold state: see the module documentation.
pub struct Fold {
    last_positions: [u8; ENCODERS],
    last_skips: [u8; ENCODERS / 2],
    window_deltas: [i16; ENCODERS],
    skips_total: [u8; ENCODERS],
    now_us: u32,
    ms_in_window: u8,
    pending: Option<ControlSample>,
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
            pending: None,
        }
    }

    /// One millisecond has passed; `positions` and `skips` are the encoder interrupt's
    /// counters now.
    pub fn on_millisecond(&mut self, positions: [u8; ENCODERS], skips: [u8; ENCODERS / 2]) {
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
        if self.ms_in_window >= CONTROL_PERIOD_MS {
            self.ms_in_window = 0;
            let mut sample = self.pending.unwrap_or_default();
            for (total, window) in sample.encoder_deltas.iter_mut().zip(self.window_deltas) {
                *total = total.wrapping_add(window);
            }
            sample.now_us = self.now_us;
            sample.quadrature_errors = self.skips_total;
            self.pending = Some(sample);
            self.window_deltas = [0; ENCODERS];
        }
    }

    /// The waiting control sample, if a window closed since the last call.
    pub fn take_sample(&mut self) -> Option<ControlSample> {
        self.pending.take()
    }

    /// Time since boot at the last millisecond, µs (wrapping).
    pub fn now_us(&self) -> u32 {
        self.now_us
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

    #[test]
    fn a_window_closes_every_control_period_with_its_deltas() {
        let mut isr = IsrModel {
            positions: [250, 3, 0, 128],
            skips: [0xF0, 0x0F],
        };
        let mut fold = Fold::new(isr.positions, isr.skips);
        for ms in 1..=u32::from(CONTROL_PERIOD_MS) {
            assert_eq!(fold.take_sample(), None, "early sample at {ms} ms");
            isr.advance([10, -10, 1, -1], [0, 1, 0, 0]);
            fold.on_millisecond(isr.positions, isr.skips);
            assert_eq!(fold.now_us(), ms * 1000);
        }
        let sample = fold.take_sample().expect("a closed window");
        assert_eq!(sample.now_us, 20_000);
        assert_eq!(sample.encoder_deltas, [200, -200, 20, -20]);
        assert_eq!(sample.quadrature_errors, [0, 20, 0, 0]);
        assert_eq!(fold.take_sample(), None);
    }

    #[test]
    fn a_missed_window_is_added_to_the_next() {
        let mut isr = IsrModel {
            positions: [0; 4],
            skips: [0; 2],
        };
        let mut fold = Fold::new(isr.positions, isr.skips);
        for _ in 0..2 * CONTROL_PERIOD_MS {
            isr.advance([5, 0, -3, 0], [0; 4]);
            fold.on_millisecond(isr.positions, isr.skips);
        }
        let sample = fold.take_sample().expect("a closed window");
        assert_eq!(sample.now_us, 40_000);
        assert_eq!(sample.encoder_deltas, [200, 0, -120, 0]);
    }

    proptest! {
        /// With fewer than 128 counts and 16 skips per encoder per millisecond, the fold's
        /// windows carry exactly the counts and skips that happened.
        #[test]
        fn folding_wrapping_bytes_is_exact(
            steps in proptest::collection::vec(
                (any::<[i8; 4]>().prop_map(|c| c.map(|v| v.clamp(-127, 127))),
                 proptest::array::uniform4(0u8..16)),
                1..200),
            start_positions in any::<[u8; 4]>(),
            start_skips in any::<[u8; 2]>(),
        ) {
            let mut isr = IsrModel { positions: start_positions, skips: start_skips };
            let mut fold = Fold::new(isr.positions, isr.skips);
            let mut expected_deltas = [0i32; 4];
            let mut expected_skips = [0u32; 4];
            let mut taken_deltas = [0i32; 4];
            for (counts, skipped) in &steps {
                isr.advance(*counts, *skipped);
                fold.on_millisecond(isr.positions, isr.skips);
                for k in 0..4 {
                    expected_deltas[k] += i32::from(counts[k]);
                    expected_skips[k] += u32::from(skipped[k]);
                }
                if let Some(sample) = fold.take_sample() {
                    for (taken, delta) in taken_deltas.iter_mut().zip(sample.encoder_deltas) {
                        *taken += i32::from(delta);
                    }
                    prop_assert_eq!(taken_deltas, expected_deltas);
                    prop_assert_eq!(sample.quadrature_errors, expected_skips.map(|s| s as u8));
                }
            }
        }
    }
}
