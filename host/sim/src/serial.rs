//! One direction of a UART link, byte by byte in simulated time.
//!
//! Each byte occupies the line for 10 bit times (8N1: start, 8 data, stop), so at 115 200 baud
//! a byte takes 86.8 µs and a 9-byte frame 781 µs. Bytes queued while the line is busy wait
//! their turn; a byte is delivered when its stop bit ends.

use std::collections::VecDeque;

/// Bits on the wire per byte with 8N1 framing.
pub const BITS_PER_BYTE_8N1: u64 = 10;

/// A simulated serial line (one direction).
#[derive(Clone, Debug)]
pub struct SerialLine {
    byte_time_ns: u64,
    line_free_at_ns: u64,
    in_flight: VecDeque<(u64, u8)>,
}

impl SerialLine {
    /// A line at `baud` bits per second.
    pub fn new(baud: u32) -> Self {
        Self {
            byte_time_ns: BITS_PER_BYTE_8N1 * 1_000_000_000 / u64::from(baud.max(1)),
            line_free_at_ns: 0,
            in_flight: VecDeque::new(),
        }
    }

    /// Time one byte occupies the line, ns.
    pub fn byte_time_ns(&self) -> u64 {
        self.byte_time_ns
    }

    /// Queue `bytes` for transmission starting no earlier than `now_ns`.
    pub fn send(&mut self, bytes: &[u8], now_ns: u64) {
        let mut start = self.line_free_at_ns.max(now_ns);
        for &byte in bytes {
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
    }
}
