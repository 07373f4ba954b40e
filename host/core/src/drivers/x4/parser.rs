//! Streaming parser: X4 bytes (any chunking) → verified packets.
//!
//! Fixes of the original (original-system.md §3.2, §10.11):
//!
//! - the check code is verified; a bad packet is dropped and counted;
//! - a packet is handed over as soon as its last byte arrives, not when the next header
//!   does;
//! - the buffer is a fixed array of the largest possible packet (LSN ≤ 255), so it cannot
//!   overflow;
//! - the 7-byte response header `A5 5A 05 00 00 40 81` that follows the start command is
//!   recognised and skipped (the original hunted past it).
//!
//! Resynchronisation: bytes that cannot start a packet or a response header are skipped
//! one at a time. When a packet fails its check code, only its first byte is discarded and
//! the bytes after it are examined again, so a real header that arrived inside a false one
//! (`AA 55` occurring in sample data after a lost byte) is still found.

use super::RESPONSE_HEADER;
use super::packet::{MAX_PACKET_LEN, PACKET_HEADER, PACKET_HEADER_LEN, Packet};

/// Counters kept by the [`PacketParser`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ParserStats {
    /// Packets whose check code matched.
    pub packets_ok: u32,
    /// Packets dropped because their check code did not match.
    pub checksum_errors: u32,
    /// Bytes skipped while hunting for a header (noise, or the remains of a bad packet).
    pub bytes_skipped: u32,
    /// Response headers recognised and skipped.
    pub response_headers: u32,
}

/// What the parser found.
#[derive(Clone, Copy, Debug)]
pub enum Event<'a> {
    /// A packet whose check code matched.
    Packet(Packet<'a>),
    /// A packet was dropped because its check code did not match.
    ChecksumError,
}

/// The X4 streaming parser. Owns one packet-sized buffer; never allocates.
#[derive(Clone, Debug)]
pub struct PacketParser {
    buf: [u8; MAX_PACKET_LEN],
    start: usize,
    end: usize,
    stats: ParserStats,
}

impl Default for PacketParser {
    fn default() -> Self {
        Self::new()
    }
}

/// What the bytes at the front of the buffer are.
enum Front {
    /// More bytes are needed to decide.
    NeedMore,
    /// The first byte cannot start anything: skip it.
    Skip,
    /// A response header of this length.
    Response(usize),
    /// A complete packet of this length (check code not yet verified).
    Packet(usize),
}

impl PacketParser {
    /// An empty parser.
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_PACKET_LEN],
            start: 0,
            end: 0,
            stats: ParserStats {
                packets_ok: 0,
                checksum_errors: 0,
                bytes_skipped: 0,
                response_headers: 0,
            },
        }
    }

    /// Counters since construction.
    pub const fn stats(&self) -> ParserStats {
        self.stats
    }

    /// Forget any partial packet (e.g. after re-opening the port); counters are kept.
    pub fn reset(&mut self) {
        self.start = 0;
        self.end = 0;
    }

    /// Feed received bytes (any chunking); `on_event` gets every verified packet, in order,
    /// as soon as its last byte has been fed, and one [`Event::ChecksumError`] per packet
    /// dropped for a bad check code.
    pub fn feed(&mut self, mut bytes: &[u8], mut on_event: impl FnMut(Event<'_>)) {
        while !bytes.is_empty() {
            if self.end == self.buf.len() {
                self.buf.copy_within(self.start..self.end, 0);
                self.end -= self.start;
                self.start = 0;
            }
            let room = self.buf.len() - self.end;
            let take = room.min(bytes.len());
            self.buf[self.end..self.end + take].copy_from_slice(&bytes[..take]);
            self.end += take;
            bytes = &bytes[take..];
            self.drain(&mut on_event);
        }
    }

    /// Consume everything at the front of the buffer that can be decided.
    fn drain(&mut self, on_event: &mut impl FnMut(Event<'_>)) {
        loop {
            match self.front() {
                Front::NeedMore => return,
                Front::Skip => {
                    self.start += 1;
                    self.stats.bytes_skipped = self.stats.bytes_skipped.wrapping_add(1);
                }
                Front::Response(len) => {
                    self.start += len;
                    self.stats.response_headers = self.stats.response_headers.wrapping_add(1);
                }
                Front::Packet(len) => {
                    let bytes = &self.buf[self.start..self.start + len];
                    if let Some(packet) = Packet::new(bytes) {
                        self.stats.packets_ok = self.stats.packets_ok.wrapping_add(1);
                        on_event(Event::Packet(packet));
                        self.start += len;
                    } else {
                        self.stats.checksum_errors = self.stats.checksum_errors.wrapping_add(1);
                        on_event(Event::ChecksumError);
                        // Re-examine everything after the false header's first byte.
                        self.start += 1;
                    }
                }
            }
            if self.start == self.end {
                self.start = 0;
                self.end = 0;
                return;
            }
        }
    }

    fn front(&self) -> Front {
        let pending = &self.buf[self.start..self.end];
        let Some(&first) = pending.first() else {
            return Front::NeedMore;
        };
        if first == PACKET_HEADER[0] {
            match pending.get(1) {
                None => Front::NeedMore,
                Some(&b) if b != PACKET_HEADER[1] => Front::Skip,
                Some(_) => match pending.get(3) {
                    None => Front::NeedMore,
                    Some(&lsn) => {
                        let len = PACKET_HEADER_LEN + 2 * usize::from(lsn);
                        if pending.len() >= len {
                            Front::Packet(len)
                        } else {
                            Front::NeedMore
                        }
                    }
                },
            }
        } else if first == RESPONSE_HEADER[0] {
            let n = pending.len().min(RESPONSE_HEADER.len());
            if pending[..n] != RESPONSE_HEADER[..n] {
                Front::Skip
            } else if n == RESPONSE_HEADER.len() {
                Front::Response(n)
            } else {
                Front::NeedMore
            }
        } else {
            Front::Skip
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::packet::{PacketSpec, encode_packet};
    use super::*;
    use proptest::prelude::*;

    fn packet_bytes(first_deg: f64, distances: &[f64], start: bool) -> Vec<u8> {
        let mut out = Vec::new();
        encode_packet(
            &PacketSpec {
                start_of_revolution: start,
                scan_frequency_hz: 7.0,
                first_angle_deg: first_deg,
                last_angle_deg: first_deg + distances.len() as f64,
                distances_mm: distances,
            },
            &mut out,
        )
        .unwrap();
        out
    }

    /// Every packet's bytes, in order, plus the number of check-code errors.
    fn parse(chunks: &[&[u8]]) -> (Vec<Vec<u8>>, u32, ParserStats) {
        let mut parser = PacketParser::new();
        let mut packets = Vec::new();
        let mut errors = 0;
        for chunk in chunks {
            parser.feed(chunk, |event| match event {
                Event::Packet(p) => packets.push(p.bytes().to_vec()),
                Event::ChecksumError => errors += 1,
            });
        }
        (packets, errors, parser.stats())
    }

    #[test]
    fn a_packet_is_delivered_as_soon_as_it_is_complete() {
        let bytes = packet_bytes(10.0, &[500.0, 600.0], false);
        let (last, head) = bytes.split_last().unwrap();
        let (packets, _, _) = parse(&[head]);
        assert!(packets.is_empty());
        let (packets, _, _) = parse(&[head, &[*last]]);
        assert_eq!(packets, [bytes]);
    }

    #[test]
    fn a_corrupted_packet_is_dropped_and_counted() {
        let good1 = packet_bytes(10.0, &[500.0, 600.0, 700.0], false);
        let mut bad = packet_bytes(20.0, &[800.0, 900.0], false);
        bad[12] ^= 0x40;
        let good2 = packet_bytes(30.0, &[1000.0], false);
        let stream = [good1.clone(), bad, good2.clone()].concat();
        let (packets, errors, stats) = parse(&[&stream]);
        assert_eq!(packets, [good1, good2]);
        assert_eq!(errors, 1);
        assert_eq!(stats.checksum_errors, 1);
        assert_eq!(stats.packets_ok, 2);
    }

    #[test]
    fn the_response_header_and_noise_are_skipped() {
        let good = packet_bytes(10.0, &[500.0], true);
        let stream = [
            &[0x00, 0xAA, 0x13][..],
            &RESPONSE_HEADER,
            &[0xA5, 0x00],
            &good,
        ]
        .concat();
        let (packets, errors, stats) = parse(&[&stream]);
        assert_eq!(packets, [good]);
        assert_eq!(errors, 0);
        assert_eq!(stats.response_headers, 1);
        assert_eq!(stats.bytes_skipped, 5);
    }

    #[test]
    fn a_real_header_inside_a_false_one_is_found() {
        // A lone `AA 55` with LSN 3 swallows the real packet's first bytes; the real packet
        // must still be found once the false one fails its check.
        let good = packet_bytes(10.0, &[500.0, 600.0], false);
        let stream = [&[0xAA, 0x55, 0x00, 0x03][..], &good].concat();
        let (packets, errors, _) = parse(&[&stream]);
        assert_eq!(packets, [good]);
        assert_eq!(errors, 1);
    }

    #[test]
    fn the_largest_packets_fit() {
        let distances = vec![1234.5; 255];
        let good = packet_bytes(0.0, &distances, false);
        assert_eq!(good.len(), MAX_PACKET_LEN);
        let stream = [good.clone(), good.clone(), good.clone()].concat();
        for cut in [1, 7, 100, MAX_PACKET_LEN, MAX_PACKET_LEN + 3] {
            let (packets, errors, _) = parse(&[&stream[..cut], &stream[cut..]]);
            assert_eq!(packets.len(), 3, "cut {cut}");
            assert_eq!(errors, 0);
        }
    }

    proptest! {
        #[test]
        fn random_bytes_never_panic(
            chunks in proptest::collection::vec(
                proptest::collection::vec(
                    prop_oneof![any::<u8>(), Just(0xAA), Just(0x55), Just(0xA5), Just(0x5A)],
                    0..700),
                0..6),
        ) {
            let refs: Vec<&[u8]> = chunks.iter().map(Vec::as_slice).collect();
            let (packets, _, stats) = parse(&refs);
            // Whatever comes out is a verified packet.
            for p in &packets {
                prop_assert!(Packet::new(p).is_some());
            }
            prop_assert_eq!(stats.packets_ok as usize, packets.len());
        }

        #[test]
        fn any_chunking_gives_the_same_packets(
            noise in proptest::collection::vec(any::<u8>(), 0..40),
            cuts in proptest::collection::vec(any::<usize>(), 0..6),
        ) {
            let stream = [
                noise.clone(),
                packet_bytes(0.0, &[1.0, 2.0, 3.0], true),
                packet_bytes(3.0, &[400.0; 40], false),
                noise,
                packet_bytes(50.0, &[9000.0; 7], false),
            ]
            .concat();
            let (whole, whole_errors, _) = parse(&[&stream]);
            let mut cuts: Vec<usize> = cuts.iter().map(|c| c % (stream.len() + 1)).collect();
            cuts.sort_unstable();
            let mut pieces: Vec<&[u8]> = Vec::new();
            let mut at = 0;
            for cut in cuts.into_iter().chain([stream.len()]) {
                pieces.push(&stream[at..cut]);
                at = cut;
            }
            let (split, split_errors, _) = parse(&pieces);
            prop_assert_eq!(split, whole);
            prop_assert_eq!(split_errors, whole_errors);
        }
    }
}
