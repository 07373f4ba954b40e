//! Quadrature decoding by lookup table (paper §V.A, Table I; original-system.md §2.3).
//!
//! Each encoder has two channels, A and B. Its 2-bit *state* is `A | B << 1`: on the Mega the
//! encoder `k` sits on `PINA` bits `2k` (A) and `2k + 1` (B), so `(PINA >> 2k) & 0b11` is the
//! state directly. The table is indexed by `previous_state << 2 | current_state` and gives the
//! counter increment: +1 or −1 for a one-step transition, 0 for no change, and 0 for a
//! *skipped* transition (both channels changed between two samples, so the direction is
//! unknown). The original silently dropped skipped transitions; [`is_skipped`] lets the
//! firmware count them.

/// Counter increment by `previous_state << 2 | current_state`, with state = `A | B << 1`.
///
/// This is the original firmware's table; the test below checks it against the paper's
/// Table I row by row.
pub const TABLE: [i8; 16] = [0, 1, -1, 0, -1, 0, 0, 1, 1, 0, 0, -1, 0, -1, 1, 0];

/// The 2-bit state of encoder `encoder` (0..=3) in a byte read from `PINA`.
pub const fn encoder_state(pins: u8, encoder: u8) -> u8 {
    (pins >> (2 * encoder)) & 0b11
}

/// The counter increment for a transition between two 2-bit states.
pub const fn delta(previous_state: u8, current_state: u8) -> i8 {
    TABLE[(((previous_state & 0b11) << 2) | (current_state & 0b11)) as usize]
}

/// True when both channels changed between two samples: a transition was missed and its
/// direction is unknown (the table gives 0).
pub const fn is_skipped(previous_state: u8, current_state: u8) -> bool {
    (previous_state ^ current_state) & 0b11 == 0b11
}

/// Per-wheel quadrature counting: the reference implementation of what the firmware's
/// encoder interrupt does (one `PINA` sample for all four encoders).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QuadratureCounter {
    previous_pins: u8,
    /// Net counts since construction, per encoder.
    pub counts: [i32; 4],
    /// Skipped transitions since construction, per encoder (wrapping).
    pub skipped: [u8; 4],
}

impl QuadratureCounter {
    /// A counter whose previous sample is `initial_pins`.
    pub const fn new(initial_pins: u8) -> Self {
        Self {
            previous_pins: initial_pins,
            counts: [0; 4],
            skipped: [0; 4],
        }
    }

    /// Account for a new sample of all four encoders' pins.
    pub fn sample(&mut self, pins: u8) {
        for encoder in 0..4u8 {
            let previous = encoder_state(self.previous_pins, encoder);
            let current = encoder_state(pins, encoder);
            let k = usize::from(encoder);
            self.counts[k] += i32::from(delta(previous, current));
            if is_skipped(previous, current) {
                self.skipped[k] = self.skipped[k].wrapping_add(1);
            }
        }
        self.previous_pins = pins;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Paper Table I, copied row by row: (A_{k-1}, B_{k-1}, A_k, B_k, Δ_k).
    const PAPER_TABLE_I: [(u8, u8, u8, u8, i8); 16] = [
        (0, 0, 0, 0, 0),
        (0, 0, 0, 1, -1),
        (0, 0, 1, 0, 1),
        (0, 0, 1, 1, 0),
        (0, 1, 0, 0, 1),
        (0, 1, 0, 1, 0),
        (0, 1, 1, 0, 0),
        (0, 1, 1, 1, -1),
        (1, 0, 0, 0, -1),
        (1, 0, 0, 1, 0),
        (1, 0, 1, 0, 0),
        (1, 0, 1, 1, 1),
        (1, 1, 0, 0, 0),
        (1, 1, 0, 1, 1),
        (1, 1, 1, 0, -1),
        (1, 1, 1, 1, 0),
    ];

    #[test]
    fn table_equals_paper_table_i_row_by_row() {
        for (a0, b0, a1, b1, expected) in PAPER_TABLE_I {
            let previous = a0 | (b0 << 1);
            let current = a1 | (b1 << 1);
            assert_eq!(
                delta(previous, current),
                expected,
                "A{a0}B{b0} -> A{a1}B{b1}"
            );
        }
    }

    #[test]
    fn skipped_transitions_are_exactly_the_double_changes() {
        let skipped: std::vec::Vec<(u8, u8)> = (0..4u8)
            .flat_map(|p| (0..4u8).map(move |c| (p, c)))
            .filter(|&(p, c)| is_skipped(p, c))
            .collect();
        assert_eq!(
            skipped,
            [(0b00, 0b11), (0b01, 0b10), (0b10, 0b01), (0b11, 0b00)]
        );
        for (p, c) in skipped {
            assert_eq!(delta(p, c), 0);
        }
    }

    /// The Gray sequence A leads B: 00 → 10 → 11 → 01 → 00 in (A, B), i.e. states 0, 1, 3, 2.
    const FORWARD: [u8; 4] = [0b00, 0b01, 0b11, 0b10];

    #[test]
    fn a_full_forward_cycle_counts_four_and_backward_minus_four() {
        let mut counter = QuadratureCounter::new(0);
        for state in FORWARD.iter().cycle().skip(1).take(4) {
            counter.sample(*state);
        }
        assert_eq!(counter.counts[0], 4);
        for state in FORWARD.iter().rev().cycle().take(4) {
            counter.sample(*state);
        }
        assert_eq!(counter.counts[0], 0);
    }

    #[test]
    fn encoders_are_independent_and_skips_are_counted() {
        let mut counter = QuadratureCounter::new(0);
        // Encoder 2 (bits 4-5) steps forward; encoder 3 (bits 6-7) jumps 00 -> 11.
        counter.sample(0b1101_0000);
        assert_eq!(counter.counts, [0, 0, 1, 0]);
        assert_eq!(counter.skipped, [0, 0, 0, 1]);
    }
}
