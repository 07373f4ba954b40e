//! A fixed-capacity byte FIFO for the serial link, shared by exactly one producer (an
//! interrupt handler or the main loop) and one consumer (the other), without critical
//! sections. Pure logic: the memory it lives in is a [`SharedByte`] per byte, which
//! `hw::usart` implements with single volatile loads and stores.
//!
//! The two indices run free (wrapping `u8`s): `tail` counts the bytes pushed and is written
//! only by the producer, `head` counts the bytes popped and is written only by the consumer,
//! and each is one byte, read or written whole. The producer stores the byte before it
//! moves `tail`, and the consumer reads the byte before it moves `head`, so either side may
//! be interrupted by the other anywhere: the other side then sees the ring as it was before
//! or after the move, never in between.
//!
//! A full ring refuses the byte and counts it, so the producer never waits: the main loop
//! never busy-waits on transmission, and a receive overrun is visible as a count.

/// One byte of memory shared by the producer and the consumer of a [`Ring`], read and
/// written whole.
pub trait SharedByte {
    /// The byte's value.
    fn get(&self) -> u8;
    /// Store `value`.
    fn set(&self, value: u8);
}

impl SharedByte for core::cell::Cell<u8> {
    fn get(&self) -> u8 {
        core::cell::Cell::get(self)
    }

    fn set(&self, value: u8) {
        core::cell::Cell::set(self, value);
    }
}

/// A FIFO of `N` slots, `N` a power of two no larger than 256; it holds
/// [`Ring::CAPACITY`] bytes (`N`, or 255 for 256 slots: the free-running one-byte indices
/// tell 0 from 255 bytes, not from 256).
pub struct Ring<B, const N: usize> {
    bytes: [B; N],
    /// Bytes popped (wrapping); written by the consumer only.
    head: B,
    /// Bytes pushed (wrapping); written by the producer only.
    tail: B,
    /// Bytes refused because the ring was full (wrapping); written by the producer only.
    dropped: B,
}

impl<B: SharedByte, const N: usize> Ring<B, N> {
    const SLOTS_OK: () = assert!(N.is_power_of_two() && N <= 256);
    /// Bytes the ring holds.
    pub const CAPACITY: usize = if N < 256 { N } else { 255 };

    /// An empty ring in the given memory (every byte 0).
    pub const fn new(bytes: [B; N], head: B, tail: B, dropped: B) -> Self {
        let () = Self::SLOTS_OK;
        Self {
            bytes,
            head,
            tail,
            dropped,
        }
    }

    /// Append `byte`; if the ring is full, drop it, count it and return false. Only the
    /// producer may call it.
    pub fn push(&self, byte: u8) -> bool {
        let tail = self.tail.get();
        if usize::from(tail.wrapping_sub(self.head.get())) >= Self::CAPACITY {
            self.dropped.set(self.dropped.get().wrapping_add(1));
            return false;
        }
        self.bytes[usize::from(tail) & (N - 1)].set(byte);
        self.tail.set(tail.wrapping_add(1));
        true
    }

    /// The oldest byte, if any. Only the consumer may call it.
    pub fn pop(&self) -> Option<u8> {
        let head = self.head.get();
        if head == self.tail.get() {
            return None;
        }
        let byte = self.bytes[usize::from(head) & (N - 1)].get();
        self.head.set(head.wrapping_add(1));
        Some(byte)
    }

    /// Bytes refused because the ring was full, since boot (wrapping).
    pub fn dropped(&self) -> u8 {
        self.dropped.get()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::cell::Cell;
    use proptest::prelude::*;
    use std::collections::VecDeque;

    fn ring<const N: usize>() -> Ring<Cell<u8>, N> {
        Ring::new(
            core::array::from_fn(|_| Cell::new(0)),
            Cell::new(0),
            Cell::new(0),
            Cell::new(0),
        )
    }

    #[test]
    fn bytes_come_out_in_order_and_a_full_ring_refuses_and_counts() {
        let ring = ring::<4>();
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
    fn a_128_slot_ring_holds_128_bytes_and_a_256_slot_ring_255() {
        let small = ring::<128>();
        for byte in 0..128u8 {
            assert!(small.push(byte));
        }
        assert!(!small.push(0));
        for byte in 0..128u8 {
            assert_eq!(small.pop(), Some(byte));
        }
        assert_eq!(small.pop(), None);
        let large = ring::<256>();
        // Wrap the indices a few times first.
        for round in 0..3u8 {
            for byte in 0..255u8 {
                assert!(large.push(byte ^ round));
            }
            assert!(!large.push(0));
            for byte in 0..255u8 {
                assert_eq!(large.pop(), Some(byte ^ round));
            }
            assert_eq!(large.pop(), None);
        }
        assert_eq!(large.dropped(), 3);
    }

    /// A ring byte that can "interrupt" the code using it: after a set number of accesses
    /// (to any byte of the ring), the pending handler runs to completion, as an interrupt
    /// would between two instructions.
    struct Interruptible(Cell<u8>);

    thread_local! {
        static ACCESSES_LEFT: Cell<Option<usize>> = const { Cell::new(None) };
        static HANDLER: core::cell::RefCell<Option<Box<dyn FnOnce()>>> =
            const { core::cell::RefCell::new(None) };
    }

    fn access() {
        let left = ACCESSES_LEFT.get();
        match left {
            Some(0) => {
                ACCESSES_LEFT.set(None);
                if let Some(handler) = HANDLER.take() {
                    handler();
                }
            }
            Some(n) => ACCESSES_LEFT.set(Some(n - 1)),
            None => {}
        }
    }

    /// Run `handler` before the `after`-th ring access from now (0: before the next one).
    fn interrupt_after(after: usize, handler: impl FnOnce() + 'static) {
        ACCESSES_LEFT.set(Some(after));
        HANDLER.set(Some(Box::new(handler)));
    }

    fn no_interrupt() {
        ACCESSES_LEFT.set(None);
        HANDLER.set(None);
    }

    impl SharedByte for Interruptible {
        fn get(&self) -> u8 {
            access();
            self.0.get()
        }

        fn set(&self, value: u8) {
            access();
            self.0.set(value);
        }
    }

    fn interruptible_ring() -> &'static Ring<Interruptible, 8> {
        Box::leak(Box::new(Ring::new(
            core::array::from_fn(|_| Interruptible(Cell::new(0))),
            Interruptible(Cell::new(0)),
            Interruptible(Cell::new(0)),
            Interruptible(Cell::new(0)),
        )))
    }

    proptest! {
        /// The transmit side: the main loop pushes, the consumer interrupts it at any ring
        /// access and pops any number of bytes. Every byte pushed is popped once, in order.
        #[test]
        fn a_push_interrupted_anywhere_by_pops_loses_and_reorders_nothing(
            steps in proptest::collection::vec((any::<u8>(), 0usize..6, 0usize..4), 0..200),
        ) {
            let ring = interruptible_ring();
            let popped = std::rc::Rc::new(core::cell::RefCell::new(Vec::new()));
            let mut accepted = Vec::new();
            for (byte, at, pops) in steps {
                let sink = popped.clone();
                interrupt_after(at, move || {
                    for _ in 0..pops {
                        if let Some(b) = ring.pop() {
                            sink.borrow_mut().push(b);
                        }
                    }
                });
                if ring.push(byte) {
                    accepted.push(byte);
                }
                no_interrupt();
            }
            while let Some(b) = ring.pop() {
                popped.borrow_mut().push(b);
            }
            prop_assert_eq!(&*popped.borrow(), &accepted);
        }

        /// The receive side: the main loop pops, the producer interrupts it at any ring
        /// access and pushes any number of bytes. Every byte accepted comes out once, in
        /// order, and a byte is refused only when 8 are waiting.
        #[test]
        fn a_pop_interrupted_anywhere_by_pushes_loses_and_reorders_nothing(
            steps in proptest::collection::vec((0usize..5, proptest::collection::vec(any::<u8>(), 0..4)), 0..200),
        ) {
            let ring = interruptible_ring();
            let accepted = std::rc::Rc::new(core::cell::RefCell::new(Vec::new()));
            let mut popped = Vec::new();
            for (at, bytes) in steps {
                let log = accepted.clone();
                interrupt_after(at, move || {
                    for b in bytes {
                        if ring.push(b) {
                            log.borrow_mut().push(b);
                        }
                    }
                });
                if let Some(b) = ring.pop() {
                    popped.push(b);
                }
                no_interrupt();
                prop_assert!(accepted.borrow().len() - popped.len() <= 8);
            }
            while let Some(b) = ring.pop() {
                popped.push(b);
            }
            prop_assert_eq!(&popped, &*accepted.borrow());
        }

        /// Any interleaving of pushes and pops behaves as a bounded FIFO that drops when full.
        #[test]
        fn behaves_as_a_bounded_fifo(ops in proptest::collection::vec(any::<Option<u8>>(), 0..600)) {
            let ring = ring::<16>();
            let mut model = VecDeque::new();
            let mut dropped = 0u8;
            for op in ops {
                match op {
                    Some(byte) => {
                        let accepted = model.len() < 16;
                        if accepted { model.push_back(byte) } else { dropped = dropped.wrapping_add(1) }
                        prop_assert_eq!(ring.push(byte), accepted);
                    }
                    None => prop_assert_eq!(ring.pop(), model.pop_front()),
                }
            }
            prop_assert_eq!(ring.dropped(), dropped);
        }

        /// The same with 256 slots (255 bytes held), the one-byte indices wrapping often.
        #[test]
        fn a_256_slot_ring_behaves_as_a_255_byte_fifo(
            ops in proptest::collection::vec(prop_oneof![3 => any::<u8>().prop_map(Some), 2 => Just(None)], 0..3000),
        ) {
            let ring = ring::<256>();
            let mut model = VecDeque::new();
            let mut dropped = 0u8;
            for op in ops {
                match op {
                    Some(byte) => {
                        let accepted = model.len() < 255;
                        if accepted { model.push_back(byte) } else { dropped = dropped.wrapping_add(1) }
                        prop_assert_eq!(ring.push(byte), accepted);
                    }
                    None => prop_assert_eq!(ring.pop(), model.pop_front()),
                }
            }
            prop_assert_eq!(ring.dropped(), dropped);
        }
    }
}
