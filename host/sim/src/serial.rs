//! One direction of a UART link, byte by byte in simulated time.
//!
//! Each byte occupies the line for 10 bit times (8N1: start, 8 data, stop), so at 115 200 baud
//! a byte takes 86.8 µs and a 9-byte frame 781 µs. Bytes queued while the line is busy wait
//! their turn; a byte is delivered when its stop bit ends.
//!
//! **Bounded.** The queue is the sender's transmit buffer: it holds at most `capacity` bytes
//! not yet delivered. A byte sent into a full buffer is dropped and counted
//! ([`SerialLine::bytes_dropped`]), as the Mega's transmit ring does (`firmware-mega`
//! `ring.rs`), so a sender faster than its line cannot grow memory without bound.

use std::collections::VecDeque;

/// Bits on the wire per byte with 8N1 framing.
pub const BITS_PER_BYTE_8N1: u64 = 10;

/// Default transmit buffer, bytes: 4 KiB, the order of a host's serial write buffer
/// (assumption); 75 of the host's 54-byte reference batches.
pub const DEFAULT_CAPACITY_BYTES: usize = 4096;

/// A simulated serial line (one direction).
#[derive(Clone, Debug)]
pub struct SerialLine {
    byte_time_ns: u64,
    line_free_at_ns: u64,
    in_flight: VecDeque<(u64, u8)>,
    capacity: usize,
    bytes_dropped: u64,
}

impl SerialLine {
    /// A line at `baud` bits per second with a [`DEFAULT_CAPACITY_BYTES`] transmit buffer.
    pub fn new(baud: u32) -> Self {
        Self::with_capacity(baud, DEFAULT_CAPACITY_BYTES)
    }

    /// A line at `baud` bits per second whose sender buffers at most `capacity` bytes not
    /// yet delivered.
    pub fn with_capacity(baud: u32, capacity: usize) -> Self {
        Self {
            byte_time_ns: BITS_PER_BYTE_8N1 * 1_000_000_000 / u64::from(baud.max(1)),
            line_free_at_ns: 0,
            in_flight: VecDeque::new(),
            capacity,
            bytes_dropped: 0,
        }
    }

    /// Time one byte occupies the line, ns.
    pub fn byte_time_ns(&self) -> u64 {
        self.byte_time_ns
    }

    /// Queue `bytes` for transmission starting no earlier than `now_ns`. Bytes that find
    /// the buffer full are dropped and counted.
    pub fn send(&mut self, bytes: &[u8], now_ns: u64) {
        let room = self.capacity.saturating_sub(self.in_flight.len());
        let (kept, dropped) = bytes.split_at(bytes.len().min(room));
        self.bytes_dropped = self.bytes_dropped.saturating_add(dropped.len() as u64);
        let mut start = self.line_free_at_ns.max(now_ns);
        for &byte in kept {
            start += self.byte_time_ns;
            self.in_flight.push_back((start, byte));
        }
        self.line_free_at_ns = start;
    }

    /// Bytes whose transmission has completed by `now_ns`, in order.
    pub fn receive(&mut self, now_ns: u64) -> Vec<u8> {
        let mut out = Vec::new();
        while let Some(&(arrival, byte)) = self.in_flight.front() {
            if arrival > now_ns {
                break;
            }
            out.push(byte);
            self.in_flight.pop_front();
        }
        out
    }

    /// Bytes queued but not yet delivered.
    pub fn pending(&self) -> usize {
        self.in_flight.len()
    }

    /// Bytes dropped because the sender's buffer was full, since the line was made.
    pub fn bytes_dropped(&self) -> u64 {
        self.bytes_dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_at_115200_takes_781_microseconds() {
        let mut line = SerialLine::new(115_200);
        line.send(b"G3F800000", 1_000_000);
        // 9 bytes × 86 805 ns = 781 245 ns: the last byte is not there 781 µs later.
        let early = line.receive(1_000_000 + 781_000);
        assert_eq!(early.len(), 8);
        let rest = line.receive(1_000_000 + 781_300);
        assert_eq!([early, rest].concat(), b"G3F800000");
    }

    #[test]
    fn bytes_queue_behind_a_busy_line() {
        let mut line = SerialLine::new(115_200);
        line.send(b"ab", 0);
        line.send(b"c", 0);
        let t = line.byte_time_ns();
        assert_eq!(line.receive(2 * t), b"ab");
        assert_eq!(line.receive(3 * t - 1), b"");
        assert_eq!(line.receive(3 * t), b"c");
        assert_eq!(line.pending(), 0);
        assert_eq!(line.bytes_dropped(), 0);
    }

    #[test]
    fn a_sender_faster_than_its_line_fills_the_buffer_and_the_rest_is_counted() {
        // 10 000 bytes at once into a 256-byte buffer: 256 queued, 9744 dropped and counted.
        let mut line = SerialLine::with_capacity(115_200, 256);
        let bytes: Vec<u8> = (0..10_000u32).map(|i| i as u8).collect();
        line.send(&bytes, 0);
        assert_eq!(line.pending(), 256);
        assert_eq!(line.bytes_dropped(), 9_744);
        // What was kept arrives in order, and the buffer takes bytes again as it drains.
        let t = line.byte_time_ns();
        assert_eq!(line.receive(10 * t), bytes[..10]);
        line.send(&bytes[..20], 10 * t);
        assert_eq!(line.pending(), 256);
        assert_eq!(line.bytes_dropped(), 9_744 + 10);
        let all = line.receive(u64::MAX);
        assert_eq!(all.len(), 256);
        assert_eq!(all[..246], bytes[10..256]);
        assert_eq!(all[246..], bytes[..10]);
    }
}
