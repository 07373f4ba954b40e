//! The integrity extension: a checksum frame closes every batch of frames.
//!
//! The original protocol has no checksum, so a corrupted hex digit silently becomes a wrong
//! speed or tick count (original-system.md §10.3). This extension adds one frame per batch,
//! on a channel both original peers ignore (`Z` host → Mega, `z` Mega → host): the original
//! firmware's frame handler does nothing for a letter it does not know, and the original host
//! library reports an unregistered channel as soon as its letter arrives and discards the
//! digits that follow (original-system.md §2.6, §3.1). So a peer that speaks only the
//! original protocol interoperates with ours unchanged, in both directions.
//!
//! Checksum frame value, most significant byte first:
//!
//! | bits  | field | meaning |
//! |-------|-------|---------|
//! | 31–24 | `seq` | batch sequence number: 0 for the first batch after boot, then 1..=255, wrapping 255 → 1 |
//! | 23–16 | `count` | number of frames in the batch (the checksum frame excluded) |
//! | 15–0  | `crc` | CRC-16/CCITT-FALSE of the batch's frames' 9-byte encodings, in order, followed by the two bytes `seq`, `count` |
//!
//! A receiver starts in *compatible* mode and delivers every frame as it is decoded. The
//! first valid checksum frame switches it to *strict* mode for good (until
//! [`BatchReceiver::reset`]): frames are held until their checksum frame arrives and are
//! delivered only if the count and CRC match and the sequence follows the previous batch
//! (or is 0, a sender that rebooted). A batch that fails is discarded whole and counted. A
//! corrupted batch still counts as the batch that was due, so it costs only itself; a batch
//! lost entirely (its checksum frame never decoded) merges with the next one, which then
//! fails its count, and the batch after that is out of sequence: a lost checksum frame costs
//! three batches, a damaged one only one.
//! In strict mode a lowercase frame ended early (CR, LF, `+`) marks its batch as corrupt:
//! our senders always send full frames.
//!
//! Why this detects every single-byte corruption: a changed hex digit or letter is a burst of
//! at most 8 bits in the encoded bytes, which CRC-16 always detects; a byte that aborts or
//! shortens a frame drops that frame (and possibly the next), which the count detects; a
//! damaged checksum frame fails its CRC comparison, because the CRC also covers `seq` and
//! `count` (without that, a sequence digit corrupted to `0` would pass as a rebooted sender).

use crate::channels::{Decoded, Decoder, FRAME_LEN, Frame};

/// Checksum channel for batches sent by the host.
pub const HOST_CHECKSUM_CHANNEL: u8 = b'Z';
/// Checksum channel for batches sent by the Mega.
pub const MCU_CHECKSUM_CHANNEL: u8 = b'z';

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final XOR), computed a
/// nibble at a time from a 16-entry table (32 bytes: small enough for the AVR's RAM, and
/// about four times faster there than bit by bit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crc16(u16);

/// CRC of each 4-bit value shifted to the top of the register, for [`Crc16`].
const CRC16_NIBBLE_TABLE: [u16; 16] = {
    let mut table = [0u16; 16];
    let mut nibble = 0;
    while nibble < 16 {
        let mut crc = (nibble as u16) << 12;
        let mut bit = 0;
        while bit < 4 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[nibble] = crc;
        nibble += 1;
    }
    table
};

impl Default for Crc16 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc16 {
    /// The initial register value.
    pub const fn new() -> Self {
        Self(0xFFFF)
    }

    /// Fold `bytes` into the CRC.
    pub const fn update(mut self, bytes: &[u8]) -> Self {
        let mut i = 0;
        while i < bytes.len() {
            let byte = bytes[i];
            let high = ((self.0 >> 12) as u8 ^ (byte >> 4)) as usize;
            self.0 = (self.0 << 4) ^ CRC16_NIBBLE_TABLE[high];
            let low = ((self.0 >> 12) as u8 ^ (byte & 0x0F)) as usize;
            self.0 = (self.0 << 4) ^ CRC16_NIBBLE_TABLE[low];
            i += 1;
        }
        self
    }

    /// The CRC of everything folded in so far.
    pub const fn value(self) -> u16 {
        self.0
    }
}

/// The sequence number after `seq`: 1..=255, wrapping 255 → 1 (0 only starts a session).
pub const fn next_sequence(seq: u8) -> u8 {
    if seq == u8::MAX { 1 } else { seq + 1 }
}

/// The decoded fields of a checksum frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Checksum {
    /// Batch sequence number (0 = first batch after the sender booted).
    pub seq: u8,
    /// Frames in the batch.
    pub count: u8,
    /// CRC-16/CCITT-FALSE of the frames' encodings followed by `seq` and `count`.
    pub crc: u16,
}

impl Checksum {
    /// The checksum of a batch: `frames_crc` is the CRC of its frames' encodings so far.
    pub const fn seal(frames_crc: Crc16, seq: u8, count: u8) -> Self {
        Self {
            seq,
            count,
            crc: frames_crc.update(&[seq, count]).value(),
        }
    }

    /// The checksum frame on `channel` carrying these fields.
    pub fn to_frame(self, channel: u8) -> Option<Frame> {
        let value =
            (u32::from(self.seq) << 24) | (u32::from(self.count) << 16) | u32::from(self.crc);
        Frame::new(channel, value).ok()
    }

    /// The fields of a checksum frame's value.
    pub const fn from_value(value: u32) -> Self {
        Self {
            seq: (value >> 24) as u8,
            count: (value >> 16) as u8,
            crc: value as u16,
        }
    }
}

/// The output buffer was too small for the batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferTooSmall {
    /// Bytes the batch needs.
    pub needed: usize,
    /// Bytes available.
    pub available: usize,
}

/// Writes batches of frames, each closed by a checksum frame.
#[derive(Clone, Debug)]
pub struct BatchWriter {
    checksum_channel: u8,
    next_seq: u8,
    with_checksums: bool,
}

impl BatchWriter {
    /// A writer whose first batch has sequence 0. `checksum_channel` is
    /// [`HOST_CHECKSUM_CHANNEL`] or [`MCU_CHECKSUM_CHANNEL`]; with `with_checksums` false it
    /// writes plain original-protocol frames.
    pub const fn new(checksum_channel: u8, with_checksums: bool) -> Self {
        Self {
            checksum_channel,
            next_seq: 0,
            with_checksums,
        }
    }

    /// Bytes a batch of `frames` frames takes on the wire.
    pub const fn batch_len(&self, frames: usize) -> usize {
        (frames + self.with_checksums as usize) * FRAME_LEN
    }

    /// The checksum frame that closes a batch of `frames`, advancing the sequence number.
    /// `None` when checksums are off.
    pub fn close(&mut self, frames: &[Frame]) -> Option<Frame> {
        if !self.with_checksums {
            return None;
        }
        let frames_crc = frames
            .iter()
            .fold(Crc16::new(), |crc, f| crc.update(&f.encode()));
        let checksum = Checksum::seal(frames_crc, self.next_seq, frames.len() as u8);
        self.next_seq = if self.next_seq == u8::MAX {
            1
        } else {
            self.next_seq + 1
        };
        checksum.to_frame(self.checksum_channel)
    }

    /// Encode `frames` and their checksum frame into `out`; returns the bytes written.
    pub fn write_batch(
        &mut self,
        frames: &[Frame],
        out: &mut [u8],
    ) -> Result<usize, BufferTooSmall> {
        let needed = self.batch_len(frames.len());
        if out.len() < needed || frames.len() > usize::from(u8::MAX) {
            return Err(BufferTooSmall {
                needed,
                available: out.len(),
            });
        }
        for (frame, chunk) in frames.iter().zip(out.chunks_exact_mut(FRAME_LEN)) {
            chunk.copy_from_slice(&frame.encode());
        }
        if let Some(checksum) = self.close(frames) {
            let at = frames.len() * FRAME_LEN;
            out[at..at + FRAME_LEN].copy_from_slice(&checksum.encode());
        }
        Ok(needed)
    }
}

/// Counters kept by a [`BatchReceiver`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames delivered to the application.
    pub frames_delivered: u32,
    /// Batches delivered in strict mode.
    pub batches_ok: u32,
    /// Batches discarded because the CRC or frame count did not match, or a frame was short.
    pub batches_corrupt: u32,
    /// Batches discarded because the sequence number skipped.
    pub batches_out_of_sequence: u32,
    /// Batches discarded because they held more frames than the receiver can buffer.
    pub batches_overflowed: u32,
    /// Frames abandoned by the decoder (a non-hex byte inside a frame).
    pub frames_aborted: u32,
    /// Sequence number of the last batch whose frames were delivered (`None` before the
    /// first checksum frame): where in the sender's numbering the receiver has got to.
    pub last_delivered_sequence: Option<u8>,
}

impl LinkStats {
    /// All discarded batches, whatever the reason.
    pub const fn batches_discarded(&self) -> u32 {
        self.batches_corrupt + self.batches_out_of_sequence + self.batches_overflowed
    }
}

/// Compatible until the first checksum frame, strict after.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// No checksum frame seen: every frame is delivered as decoded.
    Compatible,
    /// Frames are delivered only in verified batches.
    Strict,
}

/// Decodes a byte stream into frames, verifying batches once the peer sends checksums.
///
/// `N` is the largest batch it can hold (frames, checksum excluded).
#[derive(Clone, Debug)]
pub struct BatchReceiver<const N: usize> {
    checksum_channel: u8,
    decoder: Decoder,
    mode: Mode,
    pending: [Option<Frame>; N],
    pending_len: usize,
    /// Frames seen in the current batch, including those that did not fit in `pending`.
    seen: usize,
    crc: Crc16,
    /// A short frame (or overflow) was seen in the current batch.
    tainted: bool,
    last_seq: Option<u8>,
    stats: LinkStats,
}

impl<const N: usize> BatchReceiver<N> {
    /// A receiver in compatible mode that recognises checksum frames on `checksum_channel`
    /// (the *peer's* channel: [`MCU_CHECKSUM_CHANNEL`] on the host, [`HOST_CHECKSUM_CHANNEL`]
    /// on the Mega).
    pub const fn new(checksum_channel: u8) -> Self {
        Self {
            checksum_channel,
            decoder: Decoder::new(),
            mode: Mode::Compatible,
            pending: [None; N],
            pending_len: 0,
            seen: 0,
            crc: Crc16::new(),
            tainted: false,
            last_seq: None,
            stats: LinkStats {
                frames_delivered: 0,
                batches_ok: 0,
                batches_corrupt: 0,
                batches_out_of_sequence: 0,
                batches_overflowed: 0,
                frames_aborted: 0,
                last_delivered_sequence: None,
            },
        }
    }

    /// Back to compatible mode with nothing pending (e.g. after re-opening the port).
    pub fn reset(&mut self) {
        let stats = self.stats;
        *self = Self::new(self.checksum_channel);
        self.stats = stats;
    }

    /// The current mode.
    pub const fn mode(&self) -> Mode {
        self.mode
    }

    /// Counters since construction.
    pub fn stats(&self) -> LinkStats {
        LinkStats {
            frames_aborted: self.decoder.stats().aborted,
            ..self.stats
        }
    }

    /// Feed received bytes (any chunking); `deliver` gets every accepted frame, in order.
    /// Checksum frames are consumed, never delivered.
    pub fn feed(&mut self, bytes: &[u8], mut deliver: impl FnMut(Frame)) {
        for &byte in bytes {
            let (frame, short) = match self.decoder.push(byte) {
                Decoded::Frame(frame) => (frame, false),
                Decoded::ShortFrame(frame) => (frame, true),
                Decoded::Pending => continue,
            };
            if frame.channel() == self.checksum_channel && !short {
                self.close_batch(Checksum::from_value(frame.value()), &mut deliver);
                continue;
            }
            match self.mode {
                Mode::Compatible => {
                    // Track the batch anyway: the first checksum frame must be able to verify
                    // the batch it closes.
                    self.track(frame, short);
                    self.stats.frames_delivered += 1;
                    deliver(frame);
                }
                Mode::Strict => self.track(frame, short),
            }
        }
    }

    fn track(&mut self, frame: Frame, short: bool) {
        self.crc = self.crc.update(&frame.encode());
        self.tainted |= short;
        if self.pending_len < N {
            self.pending[self.pending_len] = Some(frame);
            self.pending_len += 1;
        }
        self.seen = self.seen.saturating_add(1);
    }

    fn close_batch(&mut self, checksum: Checksum, deliver: &mut impl FnMut(Frame)) {
        let intact = !self.tainted
            && self.seen == usize::from(checksum.count)
            && Checksum::seal(self.crc, checksum.seq, checksum.count) == checksum;
        let in_sequence = match self.last_seq {
            None => true,
            Some(_) if checksum.seq == 0 => true,
            Some(last) => checksum.seq == next_sequence(last),
        };
        match self.mode {
            Mode::Compatible => {
                // The frames were already delivered; a valid checksum switches modes.
                if intact {
                    self.mode = Mode::Strict;
                    self.last_seq = Some(checksum.seq);
                    self.stats.last_delivered_sequence = Some(checksum.seq);
                }
            }
            Mode::Strict => {
                if !intact {
                    self.stats.batches_corrupt += 1;
                    // Its fields cannot be trusted, but a checksum frame did arrive: count it
                    // as the batch that was due, so the next intact batch is in sequence and
                    // one corrupted batch costs only itself.
                    self.last_seq = self.last_seq.map(next_sequence);
                } else {
                    if self.seen > N {
                        self.stats.batches_overflowed += 1;
                    } else if !in_sequence {
                        self.stats.batches_out_of_sequence += 1;
                    } else {
                        self.stats.batches_ok += 1;
                        self.stats.last_delivered_sequence = Some(checksum.seq);
                        for frame in self.pending[..self.pending_len].iter().flatten() {
                            self.stats.frames_delivered += 1;
                            deliver(*frame);
                        }
                    }
                    // An intact checksum frame is the sender's own numbering: follow it.
                    self.last_seq = Some(checksum.seq);
                }
            }
        }
        self.pending_len = 0;
        self.seen = 0;
        self.crc = Crc16::new();
        self.tainted = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::{Telemetry, Wheel};
    use proptest::prelude::*;
    use std::vec::Vec;

    #[test]
    fn crc16_ccitt_false_check_value() {
        // The standard check value of CRC-16/CCITT-FALSE over "123456789".
        assert_eq!(Crc16::new().update(b"123456789").value(), 0x29B1);
    }

    /// The bitwise definition, to check the table-driven implementation against.
    fn crc16_bitwise(bytes: &[u8]) -> u16 {
        let mut crc = 0xFFFFu16;
        for &byte in bytes {
            crc ^= u16::from(byte) << 8;
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 {
                    (crc << 1) ^ 0x1021
                } else {
                    crc << 1
                };
            }
        }
        crc
    }

    proptest! {
        #[test]
        fn table_crc_equals_the_bitwise_definition(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            prop_assert_eq!(Crc16::new().update(&bytes).value(), crc16_bitwise(&bytes));
        }
    }

    fn telemetry_batch(tick: i32) -> Vec<Frame> {
        Wheel::ALL
            .iter()
            .map(|&wheel| Telemetry::Ticks {
                wheel,
                total: tick * (wheel as i32 + 1),
            })
            .chain([
                Telemetry::LoopPeriod { period_us: 20_000 },
                Telemetry::Switch { pressed: false },
            ])
            .map(|m| m.to_frame())
            .collect()
    }

    fn stream(batches: usize, writer: &mut BatchWriter) -> (Vec<u8>, Vec<Vec<Frame>>) {
        let mut bytes = Vec::new();
        let mut sent = Vec::new();
        for b in 0..batches {
            let frames = telemetry_batch(b as i32 * 37 - 500);
            let mut buf = [0u8; 128];
            let n = writer.write_batch(&frames, &mut buf).unwrap();
            bytes.extend_from_slice(&buf[..n]);
            sent.push(frames);
        }
        (bytes, sent)
    }

    #[test]
    fn golden_checksum_frame() {
        // The Mega's boot batch: the reset frame, then seq 00, count 01 and the CRC of
        // "r00000000" followed by the bytes 0x00 0x01 (0x53E9, checked with a separate
        // implementation).
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let mut buf = [0u8; 18];
        assert_eq!(
            writer.write_batch(&[Telemetry::Reset.to_frame()], &mut buf),
            Ok(18)
        );
        assert_eq!(&buf, b"r00000000z000153E9");
    }

    #[test]
    fn sequence_wraps_from_255_to_1() {
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let seqs: Vec<u8> = (0..300)
            .map(|_| Checksum::from_value(writer.close(&[]).unwrap().value()).seq)
            .collect();
        assert_eq!(seqs[0], 0);
        assert_eq!(seqs[255], 255);
        assert_eq!(seqs[256], 1);
        assert!(seqs[1..].iter().all(|&s| s != 0));
    }

    #[test]
    fn without_checksums_the_writer_speaks_the_original_protocol() {
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, false);
        let mut buf = [0u8; 9];
        assert_eq!(
            writer.write_batch(&[Telemetry::Reset.to_frame()], &mut buf),
            Ok(9)
        );
        assert_eq!(&buf, b"r00000000");
    }

    #[test]
    fn too_small_a_buffer_is_an_error() {
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let mut buf = [0u8; 17];
        assert_eq!(
            writer.write_batch(&[Telemetry::Reset.to_frame()], &mut buf),
            Err(BufferTooSmall {
                needed: 18,
                available: 17
            })
        );
    }

    #[test]
    fn receiver_without_checksums_stays_compatible() {
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, false);
        let (bytes, sent) = stream(5, &mut writer);
        let mut rx = BatchReceiver::<16>::new(MCU_CHECKSUM_CHANNEL);
        let mut got = Vec::new();
        rx.feed(&bytes, |f| got.push(f));
        assert_eq!(rx.mode(), Mode::Compatible);
        assert_eq!(got, sent.concat());
    }

    #[test]
    fn receiver_switches_to_strict_and_delivers_every_batch() {
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let (bytes, sent) = stream(5, &mut writer);
        let mut rx = BatchReceiver::<16>::new(MCU_CHECKSUM_CHANNEL);
        let mut got = Vec::new();
        rx.feed(&bytes, |f| got.push(f));
        assert_eq!(rx.mode(), Mode::Strict);
        assert_eq!(got, sent.concat());
        assert_eq!(rx.stats().batches_ok, 4); // the first batch was delivered in compatible mode
        assert_eq!(rx.stats().batches_discarded(), 0);
    }

    #[test]
    fn a_lost_batch_makes_the_next_one_out_of_sequence() {
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let (bytes, sent) = stream(6, &mut writer);
        let batch_len = writer.batch_len(6);
        // Drop batch 2 entirely.
        let mut lossy = bytes[..2 * batch_len].to_vec();
        lossy.extend_from_slice(&bytes[3 * batch_len..]);
        let mut rx = BatchReceiver::<16>::new(MCU_CHECKSUM_CHANNEL);
        let mut got = Vec::new();
        rx.feed(&lossy, |f| got.push(f));
        assert_eq!(rx.stats().batches_out_of_sequence, 1);
        let expected: Vec<Frame> = [&sent[0], &sent[1], &sent[4], &sent[5]]
            .into_iter()
            .flatten()
            .copied()
            .collect();
        assert_eq!(got, expected);
    }

    #[test]
    fn a_corrupted_batch_costs_only_itself() {
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let (mut bytes, sent) = stream(5, &mut writer);
        let batch_len = writer.batch_len(6);
        bytes[2 * batch_len + 3] = b'G'; // a digit of batch 2's first frame becomes a letter
        let mut rx = BatchReceiver::<16>::new(MCU_CHECKSUM_CHANNEL);
        let mut got = Vec::new();
        rx.feed(&bytes, |f| got.push(f));
        assert_eq!(rx.stats().batches_corrupt, 1);
        assert_eq!(rx.stats().batches_out_of_sequence, 0);
        let expected: Vec<Frame> = [&sent[0], &sent[1], &sent[3], &sent[4]]
            .into_iter()
            .flatten()
            .copied()
            .collect();
        assert_eq!(got, expected);
    }

    #[test]
    fn a_rebooted_sender_is_accepted_at_sequence_zero() {
        let mut first = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let (mut bytes, mut sent) = stream(3, &mut first);
        let mut rebooted = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let (more, more_sent) = stream(2, &mut rebooted);
        bytes.extend(more);
        sent.extend(more_sent);
        let mut rx = BatchReceiver::<16>::new(MCU_CHECKSUM_CHANNEL);
        let mut got = Vec::new();
        rx.feed(&bytes, |f| got.push(f));
        assert_eq!(got, sent.concat());
    }

    #[test]
    fn oversized_batches_are_discarded() {
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let (bytes, sent) = stream(3, &mut writer);
        let mut rx = BatchReceiver::<4>::new(MCU_CHECKSUM_CHANNEL);
        let mut got = Vec::new();
        rx.feed(&bytes, |f| got.push(f));
        assert_eq!(got, sent[0]); // delivered before strict mode
        assert_eq!(rx.stats().batches_overflowed, 2);
    }

    /// Over 100 000 random single-byte corruptions of a strict-mode stream, no corrupted
    /// batch is ever delivered: every delivered frame is one that was sent, in its batch.
    #[test]
    fn no_corrupted_batch_is_accepted_in_strict_mode() {
        let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
        let (bytes, sent) = stream(4, &mut writer);
        let batch_len = writer.batch_len(6);
        let mut rng = proptest::test_runner::TestRng::deterministic_rng(
            proptest::test_runner::RngAlgorithm::ChaCha,
        );
        let mut detected = 0u32;
        let trials = 100_000;
        for _ in 0..trials {
            // Corrupt one byte of batch 2 or 3 (batch 0 switches to strict mode, 1 is clean).
            let pos = 2 * batch_len + (rng.next_u32() as usize) % (2 * batch_len);
            let mut byte = rng.next_u32() as u8;
            if byte == bytes[pos] {
                byte ^= 0x01;
            }
            let mut corrupted = bytes.clone();
            corrupted[pos] = byte;
            let mut rx = BatchReceiver::<16>::new(MCU_CHECKSUM_CHANNEL);
            let mut got = Vec::new();
            rx.feed(&corrupted, |f| got.push(f));
            let hit = pos / batch_len;
            let clean: Vec<Frame> = sent
                .iter()
                .enumerate()
                .filter(|&(i, _)| i != hit)
                .flat_map(|(_, b)| b.iter().copied())
                .collect();
            let with_hit = sent.concat();
            // Either the corrupted batch was dropped, or the byte changed nothing the
            // receiver can see (impossible here: every byte of a batch matters).
            assert!(
                got == clean || (got.len() < clean.len() && clean.starts_with(&got)),
                "corruption at {pos} to 0x{byte:02X} delivered {got:?}"
            );
            assert_ne!(got, with_hit);
            detected += 1;
        }
        assert_eq!(detected, trials);
    }

    proptest! {
        #[test]
        fn strict_streams_survive_any_chunking(cut in 0usize..400) {
            let mut writer = BatchWriter::new(MCU_CHECKSUM_CHANNEL, true);
            let (bytes, sent) = stream(6, &mut writer);
            let cut = cut.min(bytes.len());
            let mut rx = BatchReceiver::<16>::new(MCU_CHECKSUM_CHANNEL);
            let mut got = Vec::new();
            rx.feed(&bytes[..cut], |f| got.push(f));
            rx.feed(&bytes[cut..], |f| got.push(f));
            prop_assert_eq!(got, sent.concat());
        }
    }
}
