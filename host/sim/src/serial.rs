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
//!
//! **USB delivery.** A byte that has crossed the UART is not yet in the host's hands (or,
//! host → Mega, in the Mega's): a USB-serial bridge forwards what it holds on its own timer,
//! and the receiving side's USB stack and scheduler add their own delay. With a
//! [`UsbTiming`] ([`SerialLine::with_usb`]) each byte is handed out at the bridge's next
//! flush instant after it landed, plus that flush's drawn delay, in order. The sender's
//! buffer is freed when the byte lands, as before: the bridge's own buffering does not count
//! against it.

use std::collections::VecDeque;

use serde::Serialize;

use ratf_core::rng::SimRng;

/// Bits on the wire per byte with 8N1 framing.
pub const BITS_PER_BYTE_8N1: u64 = 10;

/// Default transmit buffer, bytes: 4 KiB, the order of a host's serial write buffer
/// (assumption); 75 of the host's 54-byte reference batches.
pub const DEFAULT_CAPACITY_BYTES: usize = 4096;

/// How a USB-serial bridge and the receiving side deliver the bytes of one line: the
/// world's truth for that link (see `truth.rs` for the draws and their sources).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct UsbTiming {
    /// The bridge forwards what it holds every this long, µs (0: each byte as it lands).
    pub flush_period_us: f64,
    /// The bridge timer's phase, µs after time 0 (within one period).
    pub flush_phase_us: f64,
    /// Each flush is further delayed by U(0, this), µs (the bridge's and the USB bus's own
    /// scheduling).
    pub extra_max_us: f64,
    /// … and by |N(0, this)|, µs: the receiving side's scheduling (a user-space thread).
    pub host_sigma_us: f64,
    /// Probability that a flush is late by [`Self::tail_us`] more (a scheduling stall).
    pub tail_probability: f64,
    /// How late a late flush is, µs.
    pub tail_us: f64,
}

impl UsbTiming {
    /// Bytes handed over the moment they land: the ideal world's link.
    pub const IMMEDIATE: Self = Self {
        flush_period_us: 0.0,
        flush_phase_us: 0.0,
        extra_max_us: 0.0,
        host_sigma_us: 0.0,
        tail_probability: 0.0,
        tail_us: 0.0,
    };

    /// True when nothing delays a byte (the line hands bytes over as they land).
    pub fn is_immediate(&self) -> bool {
        *self == Self::IMMEDIATE
    }
}

/// The bridge and receiver stage of a line with [`UsbTiming`].
#[derive(Clone, Debug)]
struct UsbStage {
    period_ns: u64,
    phase_ns: u64,
    timing: UsbTiming,
    rng: SimRng,
    /// Landed bytes with their delivery times, in order.
    held: VecDeque<(u64, u8)>,
    /// The flush instant whose delay was drawn last, and that delay, ns.
    flush: Option<(u64, u64)>,
    last_delivery_ns: u64,
}

impl UsbStage {
    fn new(timing: UsbTiming, rng: SimRng) -> Self {
        let period_ns = (timing.flush_period_us.max(0.0) * 1e3).round() as u64;
        let phase_ns = (timing.flush_phase_us.max(0.0) * 1e3).round() as u64;
        Self {
            period_ns,
            phase_ns: if period_ns > 0 {
                phase_ns % period_ns
            } else {
                0
            },
            timing,
            rng,
            held: VecDeque::new(),
            flush: None,
            last_delivery_ns: 0,
        }
    }

    /// The first flush instant at or after `landed_ns`.
    fn flush_at(&self, landed_ns: u64) -> u64 {
        if self.period_ns == 0 || landed_ns <= self.phase_ns {
            return landed_ns.max(self.phase_ns);
        }
        self.phase_ns + (landed_ns - self.phase_ns).div_ceil(self.period_ns) * self.period_ns
    }

    /// Hold a byte that landed at `landed_ns` until its delivery time.
    fn hold(&mut self, landed_ns: u64, byte: u8) {
        let flush = self.flush_at(landed_ns);
        let delay_ns = match self.flush {
            Some((at, delay)) if at == flush => delay,
            _ => {
                let t = self.timing;
                let mut us = self.rng.uniform_in(0.0, t.extra_max_us.max(0.0))
                    + self.rng.normal(t.host_sigma_us.max(0.0)).abs();
                if self.rng.chance(t.tail_probability) {
                    us += t.tail_us.max(0.0);
                }
                let delay = (us * 1e3).round() as u64;
                self.flush = Some((flush, delay));
                delay
            }
        };
        let delivery = (flush + delay_ns).max(self.last_delivery_ns);
        self.last_delivery_ns = delivery;
        self.held.push_back((delivery, byte));
    }
}

/// A simulated serial line (one direction).
#[derive(Clone, Debug)]
pub struct SerialLine {
    byte_time_ns: u64,
    line_free_at_ns: u64,
    in_flight: VecDeque<(u64, u8)>,
    capacity: usize,
    bytes_dropped: u64,
    usb: Option<UsbStage>,
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
            usb: None,
        }
    }

    /// This line with a USB bridge and receiver that deliver as `timing` says, their delays
    /// drawn from `rng`. [`UsbTiming::IMMEDIATE`] leaves the line as it was.
    pub fn with_usb(mut self, timing: UsbTiming, rng: SimRng) -> Self {
        self.usb = (!timing.is_immediate()).then(|| UsbStage::new(timing, rng));
        self
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

    /// Bytes whose transmission has completed by `now_ns` (and, with [`Self::with_usb`],
    /// that the bridge and receiver have handed over by then), in order.
    pub fn receive(&mut self, now_ns: u64) -> Vec<u8> {
        let mut out = Vec::new();
        while let Some(&(arrival, byte)) = self.in_flight.front() {
            if arrival > now_ns {
                break;
            }
            match &mut self.usb {
                Some(usb) => usb.hold(arrival, byte),
                None => out.push(byte),
            }
            self.in_flight.pop_front();
        }
        if let Some(usb) = &mut self.usb {
            while let Some(&(delivery, byte)) = usb.held.front() {
                if delivery > now_ns {
                    break;
                }
                out.push(byte);
                usb.held.pop_front();
            }
        }
        out
    }

    /// Bytes queued in the sender's buffer, not yet across the UART.
    pub fn pending(&self) -> usize {
        self.in_flight.len()
    }

    /// Bytes across the UART that the USB bridge or the receiver still holds.
    pub fn held_by_usb(&self) -> usize {
        self.usb.as_ref().map_or(0, |usb| usb.held.len())
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

    fn usb(period_us: f64, phase_us: f64) -> UsbTiming {
        UsbTiming {
            flush_period_us: period_us,
            flush_phase_us: phase_us,
            ..UsbTiming::IMMEDIATE
        }
    }

    #[test]
    fn a_usb_bridge_hands_bytes_over_at_its_next_flush() {
        // The ATmega16U2's 4.096 ms flush timer, phase 1 ms: a byte landing at 2 ms waits
        // for the flush at 5.096 ms, the sender's buffer being free from 2 ms on.
        let mut line = SerialLine::new(115_200).with_usb(usb(4096.0, 1000.0), SimRng::new(1));
        let t = line.byte_time_ns();
        line.send(b"a", 2_000_000 - t);
        assert_eq!(line.receive(2_000_000), b"");
        assert_eq!((line.pending(), line.held_by_usb()), (0, 1));
        assert_eq!(line.receive(5_095_999), b"");
        assert_eq!(line.receive(5_096_000), b"a");
        // Bytes landing across a flush instant go in two flushes, in order.
        line.send(b"bc", 9_192_000 - t);
        assert_eq!(line.receive(9_192_000 + t), b"b");
        assert_eq!(line.receive(13_288_000), b"c");
    }

    #[test]
    fn late_flushes_delay_what_follows_and_order_holds() {
        let timing = UsbTiming {
            extra_max_us: 1000.0,
            tail_probability: 0.05,
            tail_us: 5000.0,
            ..usb(1000.0, 0.0)
        };
        let mut line = SerialLine::new(128_000).with_usb(timing, SimRng::new(7));
        // One byte a millisecond (the line is idle between them), for 200 ms.
        let mut got = Vec::new();
        let mut lags_ms = Vec::new();
        for ms in 0..200u64 {
            line.send(&[ms as u8], ms * 1_000_000);
            for byte in line.receive((ms + 1) * 1_000_000) {
                lags_ms.push(ms - u64::from(byte) + 1);
                got.push(byte);
            }
        }
        got.extend(line.receive(u64::MAX));
        assert_eq!(got, (0..200u64).map(|m| m as u8).collect::<Vec<_>>());
        // Landing 78 µs after sending, the flush at the next whole ms, up to 1 ms more,
        // and 5 ms for a late flush (5 % of them): 1 to 8 ms, mostly 2, some late ones.
        assert!(
            lags_ms.iter().all(|&lag| (1..=8).contains(&lag)),
            "{lags_ms:?}"
        );
        assert!(lags_ms.iter().any(|&lag| lag >= 6), "{lags_ms:?}");
        assert!(
            lags_ms.iter().filter(|&&lag| lag <= 2).count() > 100,
            "{lags_ms:?}"
        );
    }

    #[test]
    fn an_immediate_usb_is_the_plain_line() {
        let mut plain = SerialLine::new(115_200);
        let mut usb = SerialLine::new(115_200).with_usb(UsbTiming::IMMEDIATE, SimRng::new(3));
        for step in 0..50u64 {
            plain.send(b"T0123", step * 500_000);
            usb.send(b"T0123", step * 500_000);
            assert_eq!(plain.receive(step * 700_000), usb.receive(step * 700_000));
        }
    }
}
