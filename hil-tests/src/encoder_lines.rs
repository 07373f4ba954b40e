//! The four quadrature encoders' A/B lines as the test drives them onto `PINA`.
//!
//! Encoder k's A is `PA(2k)` and B is `PA(2k+1)` (Arduino pins 22–29, original-system.md
//! §2.1), so `PINA` holds all four 2-bit states `A | B << 1` at once
//! ([`ratf_protocol::quadrature::encoder_state`]). The firmware turns the pull-ups on, which
//! in simavr drives idle inputs high (avr-toolchain.md §7 pitfall 6), so every encoder
//! starts in state `0b11` and the lines move from there.
//!
//! Forward (count up) walks the states 00 → 01 → 11 → 10 → 00, the paper's Table I
//! (`TABLE[prev << 2 | next] = +1`).

use ratf_protocol::messages::WHEEL_COUNT;

/// States in forward order (state = `A | B << 1`).
pub const FORWARD_STATES: [u8; 4] = [0b00, 0b01, 0b11, 0b10];
/// Index of the idle state `0b11` in [`FORWARD_STATES`].
const IDLE_INDEX: i64 = 2;

/// Positions (in edges, i.e. quadrature counts) of the four encoders and the `PINA` byte
/// they produce.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EncoderLines {
    position_edges: [i64; WHEEL_COUNT],
    /// Per encoder: the lines were set to a state two steps away (a skipped transition) this
    /// many times.
    skips: [u32; WHEEL_COUNT],
}

impl EncoderLines {
    /// All encoders at position 0, state `0b11`.
    pub fn new() -> Self {
        Self::default()
    }

    /// Move encoder `wheel` one edge forward (`forward`) or backward.
    pub fn step(&mut self, wheel: usize, forward: bool) {
        self.position_edges[wheel] += if forward { 1 } else { -1 };
    }

    /// Jump encoder `wheel` two states at once: both lines change together, which the
    /// firmware must count as an invalid (skipped) transition and not as a count. The
    /// position advances by two so the lines stay consistent with it.
    pub fn skip(&mut self, wheel: usize) {
        self.position_edges[wheel] += 2;
        self.skips[wheel] += 1;
    }

    /// Net edges moved by encoder `wheel` through [`Self::step`] (skips excluded).
    pub fn counted_edges(&self, wheel: usize) -> i64 {
        self.position_edges[wheel] - 2 * i64::from(self.skips[wheel])
    }

    /// Skipped transitions generated on encoder `wheel`.
    pub fn skips(&self, wheel: usize) -> u32 {
        self.skips[wheel]
    }

    /// The 2-bit state of encoder `wheel`.
    pub fn state(&self, wheel: usize) -> u8 {
        let index = (self.position_edges[wheel] + IDLE_INDEX).rem_euclid(4);
        FORWARD_STATES[index as usize]
    }

    /// The `PINA` byte: encoder k's state in bits 2k (A) and 2k+1 (B).
    pub fn pina(&self) -> u8 {
        (0..WHEEL_COUNT).fold(0u8, |pins, k| pins | (self.state(k) << (2 * k)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_protocol::quadrature::{QuadratureCounter, delta, is_skipped};

    #[test]
    fn starts_idle_high() {
        assert_eq!(EncoderLines::new().pina(), 0xFF);
    }

    #[test]
    fn forward_steps_count_up_in_the_protocol_table() {
        let mut lines = EncoderLines::new();
        for _ in 0..9 {
            let before = lines.state(1);
            lines.step(1, true);
            assert_eq!(delta(before, lines.state(1)), 1);
            let before = lines.state(3);
            lines.step(3, false);
            assert_eq!(delta(before, lines.state(3)), -1);
        }
    }

    #[test]
    fn reference_counter_agrees_with_positions() {
        let mut lines = EncoderLines::new();
        let mut counter = QuadratureCounter::new(lines.pina());
        for i in 0..100 {
            lines.step(i % 4, i % 3 != 0);
            counter.sample(lines.pina());
        }
        let before = lines.state(2);
        lines.skip(2);
        assert!(is_skipped(before, lines.state(2)));
        counter.sample(lines.pina());
        for k in 0..4 {
            assert_eq!(i64::from(counter.counts[k]), lines.counted_edges(k));
        }
        assert_eq!(counter.skipped[2], 1);
    }
}
