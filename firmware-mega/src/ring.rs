//! A fixed-capacity byte FIFO for the serial link: one side pushes (an interrupt handler or
//! the main loop), the other pops. Pure logic; `hw::usart` keeps one per direction behind an
//! interrupt mutex.
//!
//! A full ring refuses the byte and counts it, so the producer never waits: the main loop
//! never busy-waits on transmission, and a receive overrun is visible as a count.

/// A FIFO of at most `N` bytes, `N` a power of two no larger than 256.
pub struct Ring<const N: usize> {
    bytes: [u8; N],
    head: u8,
    len: u16,
    dropped: u16,
}

impl<const N: usize> Ring<N> {
    const CAPACITY_OK: () = assert!(N.is_power_of_two() && N <= 256);

    /// An empty ring.
    pub const fn new() -> Self {
        let () = Self::CAPACITY_OK;
        Self {
            bytes: [0; N],
            head: 0,
            len: 0,
            dropped: 0,
        }
    }

    /// Append `byte`; if the ring is full, drop it, count it and return false.
    pub fn push(&mut self, byte: u8) -> bool {
        if usize::from(self.len) == N {
            self.dropped = self.dropped.wrapping_add(1);
            return false;
        }
        let tail = (usize::from(self.head) + usize::from(self.len)) & (N - 1);
        self.bytes[tail] = byte;
        self.len += 1;
        true
    }

    /// The oldest byte, if any.
    pub fn pop(&mut self) -> Option<u8> {
        if self.len == 0 {
            return None;
        }
        let byte = self.bytes[usize::from(self.head)];
        self.head = ((usize::from(self.head) + 1) & (N - 1)) as u8;
        self.len -= 1;
        Some(byte)
    }

    /// Bytes refused because the ring was full, since boot (wrapping).
    pub fn dropped(&self) -> u16 {
        self.dropped
    }
}

impl<const N: usize> Default for Ring<N> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::VecDeque;

    #[test]
    fn bytes_come_out_in_order_and_a_full_ring_refuses_and_counts() {
        let mut ring = Ring::<4>::new();
        for byte in 1..=4 {
            assert!(ring.push(byte));
        }
        assert!(!ring.push(5));
        assert!(!ring.push(6));
        assert_eq!(ring.dropped(), 2);
        assert_eq!(ring.pop(), Some(1));
        assert!(ring.push(7));
        assert_eq!(
            core::iter::from_fn(|| ring.pop()).collect::<Vec<_>>(),
            [2, 3, 4, 7]
        );
        assert_eq!(ring.pop(), None);
    }

    #[test]
    fn a_256_byte_ring_holds_256_bytes() {
        let mut ring = Ring::<256>::new();
        for byte in 0..=255u8 {
            assert!(ring.push(byte));
        }
        assert!(!ring.push(0));
        for byte in 0..=255u8 {
            assert_eq!(ring.pop(), Some(byte));
        }
        assert_eq!(ring.pop(), None);
    }

    proptest! {
        /// Any interleaving of pushes and pops behaves as a bounded FIFO that drops when full.
        #[test]
        fn behaves_as_a_bounded_fifo(ops in proptest::collection::vec(any::<Option<u8>>(), 0..600)) {
            let mut ring = Ring::<16>::new();
            let mut model = VecDeque::new();
            let mut dropped = 0u16;
            for op in ops {
                match op {
                    Some(byte) => {
                        let accepted = model.len() < 16;
                        if accepted { model.push_back(byte) } else { dropped += 1 }
                        prop_assert_eq!(ring.push(byte), accepted);
                    }
                    None => prop_assert_eq!(ring.pop(), model.pop_front()),
                }
            }
            prop_assert_eq!(ring.dropped(), dropped);
        }
    }
}
