//! The encoder interrupt's lookup tables, generated at compile time from the shared
//! quadrature table (`ratf_protocol::quadrature`, the paper's Table I).
//!
//! The interrupt decodes the four encoders as two *pairs*: encoders 0 and 1 are the low
//! nibble of `PINA`, encoders 2 and 3 the high nibble. For a pair, the index is
//! `previous_nibble << 4 | current_nibble`, and within a nibble the pair's first encoder is
//! bits 0–1 (A, B) and its second bits 2–3. Three 256-entry tables give, per index, the
//! first encoder's count increment, the second's, and the skipped transitions packed as two
//! 4-bit counts (first encoder in the low nibble). The same three tables serve both pairs.

use ratf_protocol::quadrature::{delta, is_skipped};

/// Entries per table: every (previous, current) pair of 4-bit pin states.
pub const TABLE_LEN: usize = 256;

/// Which value of a pair transition a table holds.
#[derive(Clone, Copy)]
pub enum PairTable {
    /// The pair's first encoder's increment, as a two's-complement byte.
    FirstDelta,
    /// The pair's second encoder's increment, as a two's-complement byte.
    SecondDelta,
    /// Skipped transitions: 1 in the low nibble for the first encoder, 0x10 for the second.
    Skips,
}

/// The table `which`, computed from `ratf_protocol::quadrature`.
pub const fn pair_table(which: PairTable) -> [u8; TABLE_LEN] {
    let mut table = [0u8; TABLE_LEN];
    let mut index = 0;
    while index < TABLE_LEN {
        let previous = (index >> 4) as u8;
        let current = (index & 0x0F) as u8;
        let (p0, c0) = (previous & 0b11, current & 0b11);
        let (p1, c1) = (previous >> 2, current >> 2);
        table[index] = match which {
            PairTable::FirstDelta => delta(p0, c0) as u8,
            PairTable::SecondDelta => delta(p1, c1) as u8,
            PairTable::Skips => (is_skipped(p0, c0) as u8) | ((is_skipped(p1, c1) as u8) << 4),
        };
        index += 1;
    }
    table
}

const FIRST: [u8; TABLE_LEN] = pair_table(PairTable::FirstDelta);
const SECOND: [u8; TABLE_LEN] = pair_table(PairTable::SecondDelta);
const SKIPS: [u8; TABLE_LEN] = pair_table(PairTable::Skips);

// Spot checks against Table I (A, B → state A | B << 1): 00 → A=1 is +1, 00 → B=1 is −1,
// and a double change is a skip with no count.
const _: () = assert!(FIRST[0x01] == 1 && FIRST[0x02] == 0xFF && FIRST[0x03] == 0);
const _: () = assert!(SECOND[0x04] == 1 && SECOND[0x08] == 0xFF && SECOND[0x0C] == 0);
const _: () = assert!(SKIPS[0x03] == 0x01 && SKIPS[0x0C] == 0x10 && SKIPS[0x0F] == 0x11);
const _: () = assert!(SKIPS[0x12] == 0x01 && SKIPS[0x48] == 0x10 && SKIPS[0x11] == 0);

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_protocol::quadrature::QuadratureCounter;

    /// The encoder interrupt's index arithmetic (`hw::encoders`), in Rust: pair 0 is
    /// `previous << 4 | current & 0x0F`, pair 1 is `previous & 0xF0 | current >> 4`.
    fn isr_sample(previous: u8, current: u8) -> ([i32; 4], [u8; 4]) {
        let pair0 = usize::from((previous << 4) | (current & 0x0F));
        let pair1 = usize::from((previous & 0xF0) | (current >> 4));
        let mut counts = [0; 4];
        let mut skips = [0; 4];
        for (pair, index) in [pair0, pair1].into_iter().enumerate() {
            counts[2 * pair] = i32::from(FIRST[index] as i8);
            counts[2 * pair + 1] = i32::from(SECOND[index] as i8);
            skips[2 * pair] = SKIPS[index] & 0x0F;
            skips[2 * pair + 1] = SKIPS[index] >> 4;
        }
        (counts, skips)
    }

    #[test]
    fn every_pina_transition_matches_the_shared_quadrature_counter() {
        for previous in 0..=255u8 {
            for current in 0..=255u8 {
                let mut reference = QuadratureCounter::new(previous);
                reference.sample(current);
                assert_eq!(
                    isr_sample(previous, current),
                    (reference.counts, reference.skipped),
                    "PINA {previous:#04x} -> {current:#04x}"
                );
            }
        }
    }

    #[test]
    fn table_values_are_only_steps_and_skip_nibbles() {
        for index in 0..TABLE_LEN {
            assert!(matches!(FIRST[index], 0 | 1 | 0xFF));
            assert!(matches!(SECOND[index], 0 | 1 | 0xFF));
            assert!(matches!(SKIPS[index], 0x00 | 0x01 | 0x10 | 0x11));
        }
    }
}
