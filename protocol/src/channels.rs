//! The 5dpo "channels" wire format (original-system.md §2.6, §3.1), bit-exact.
//!
//! A frame is one channel letter (`G`..=`Z` or `g`..=`z`) followed by exactly 8 uppercase
//! hexadecimal digits carrying a 32-bit value, most significant nibble first. There is no
//! terminator and no framing byte: `G` with the float 1.0 is the 9 bytes `G3F800000`.
//!
//! [`Decoder`] reproduces the original receiver's state machine exactly, so it accepts a
//! frame if and only if the original would:
//!
//! - while idle, only a channel letter starts a frame; every other byte is ignored;
//! - inside a frame, an uppercase hex digit is stored; any other byte aborts the frame and
//!   is *consumed* (a channel letter that aborts a frame does not start a new one);
//! - exception: a lowercase channel may be ended early by CR, LF or `+`; the digits received
//!   so far are right-aligned (zero-extended), so `g1F\n` carries 0x1F;
//! - the eighth digit completes the frame.
//!
//! The decoder never allocates and never panics; it takes input one byte or one chunk at a
//! time, split anywhere.

use core::fmt;

/// Bytes in one encoded frame: the channel letter plus 8 hex digits.
pub const FRAME_LEN: usize = 9;

/// The uppercase hex digits, in value order.
const HEX_DIGITS: &[u8; 16] = b"0123456789ABCDEF";

/// Why a byte cannot be a channel letter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// The byte is not in `G`..=`Z` or `g`..=`z` (the original protocol's channel range).
    InvalidChannel(u8),
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidChannel(byte) => {
                write!(f, "byte 0x{byte:02X} is not a channel letter (G-Z or g-z)")
            }
        }
    }
}

impl core::error::Error for FrameError {}

/// True if `byte` is a channel letter: `G`..=`Z` (conventionally host → Mega) or
/// `g`..=`z` (Mega → host).
pub const fn is_channel_letter(byte: u8) -> bool {
    matches!(byte, b'G'..=b'Z' | b'g'..=b'z')
}

/// The value of an uppercase hex digit, or `None` for any other byte (the original accepts
/// uppercase only).
const fn hex_value(byte: u8) -> Option<u8> {
    match byte {
        b'0'..=b'9' => Some(byte - b'0'),
        b'A'..=b'F' => Some(byte - b'A' + 10),
        _ => None,
    }
}

/// One frame: a channel letter and its 32-bit payload.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Frame {
    channel: u8,
    value: u32,
}

impl Frame {
    /// A frame on `channel` carrying `value`; fails if `channel` is not a channel letter.
    pub const fn new(channel: u8, value: u32) -> Result<Self, FrameError> {
        if is_channel_letter(channel) {
            Ok(Self { channel, value })
        } else {
            Err(FrameError::InvalidChannel(channel))
        }
    }

    /// The channel letter (ASCII).
    pub const fn channel(&self) -> u8 {
        self.channel
    }

    /// The 32-bit payload, as received (interpretation is up to [`crate::messages`]).
    pub const fn value(&self) -> u32 {
        self.value
    }

    /// The 9 wire bytes: the letter, then the value as 8 uppercase hex digits, most
    /// significant first.
    pub const fn encode(&self) -> [u8; FRAME_LEN] {
        let mut out = [0u8; FRAME_LEN];
        out[0] = self.channel;
        // Byte by byte rather than nibble by nibble: the AVR has no barrel shifter, so a
        // variable 32-bit shift costs a loop per nibble.
        let bytes = self.value.to_be_bytes();
        let mut i = 0;
        while i < 4 {
            out[1 + 2 * i] = HEX_DIGITS[(bytes[i] >> 4) as usize];
            out[2 + 2 * i] = HEX_DIGITS[(bytes[i] & 0xF) as usize];
            i += 1;
        }
        out
    }
}

/// Counters kept by the [`Decoder`] for link diagnostics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Frames completed (including lowercase frames ended early).
    pub frames: u32,
    /// Frames started but abandoned because a non-hex byte arrived inside them.
    pub aborted: u32,
    /// Lowercase frames ended early by CR, LF or `+` (fewer than 8 digits).
    pub short: u32,
}

/// Where the decoder is in a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Waiting for a channel letter.
    Idle,
    /// Inside a frame on `channel`, `digits` hex digits (0..8) accumulated into `value`.
    InFrame { channel: u8, digits: u8, value: u32 },
}

/// Outcome of feeding one byte to the [`Decoder`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decoded {
    /// The byte completed a frame with all 8 digits.
    Frame(Frame),
    /// The byte ended a lowercase frame early; the value holds the right-aligned digits.
    ShortFrame(Frame),
    /// The byte was consumed without completing a frame.
    Pending,
}

/// The streaming channels decoder: the original receiver's state machine.
#[derive(Clone, Debug)]
pub struct Decoder {
    state: State,
    stats: DecoderStats,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder {
    /// A decoder waiting for a channel letter.
    pub const fn new() -> Self {
        Self {
            state: State::Idle,
            stats: DecoderStats {
                frames: 0,
                aborted: 0,
                short: 0,
            },
        }
    }

    /// Counters since construction.
    pub const fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Abandon any partial frame and wait for a channel letter (counters are kept).
    pub fn reset(&mut self) {
        self.state = State::Idle;
    }

    /// Feed one byte; see the module doc for the acceptance rules.
    pub fn push(&mut self, byte: u8) -> Decoded {
        match self.state {
            State::Idle => {
                if is_channel_letter(byte) {
                    self.state = State::InFrame {
                        channel: byte,
                        digits: 0,
                        value: 0,
                    };
                }
                Decoded::Pending
            }
            State::InFrame {
                channel,
                digits,
                value,
            } => {
                if let Some(nibble) = hex_value(byte) {
                    let value = (value << 4) | u32::from(nibble);
                    let digits = digits + 1;
                    if digits == 8 {
                        self.state = State::Idle;
                        self.stats.frames = self.stats.frames.wrapping_add(1);
                        Decoded::Frame(Frame { channel, value })
                    } else {
                        self.state = State::InFrame {
                            channel,
                            digits,
                            value,
                        };
                        Decoded::Pending
                    }
                } else if channel.is_ascii_lowercase() && matches!(byte, b'\r' | b'\n' | b'+') {
                    // Digits were accumulated most significant first, so `value` already
                    // holds them right-aligned.
                    self.state = State::Idle;
                    self.stats.frames = self.stats.frames.wrapping_add(1);
                    self.stats.short = self.stats.short.wrapping_add(1);
                    Decoded::ShortFrame(Frame { channel, value })
                } else {
                    self.state = State::Idle;
                    self.stats.aborted = self.stats.aborted.wrapping_add(1);
                    Decoded::Pending
                }
            }
        }
    }

    /// Feed a chunk of any size, calling `on_frame` for every frame it completes (full or
    /// short), in order.
    pub fn feed(&mut self, bytes: &[u8], mut on_frame: impl FnMut(Frame)) {
        for &byte in bytes {
            match self.push(byte) {
                Decoded::Frame(frame) | Decoded::ShortFrame(frame) => on_frame(frame),
                Decoded::Pending => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    fn decode_all(bytes: &[u8]) -> Vec<Frame> {
        let mut decoder = Decoder::new();
        let mut frames = Vec::new();
        decoder.feed(bytes, |f| frames.push(f));
        frames
    }

    /// An independent transcription of the original receiver (original-system.md §2.6),
    /// written as "scan for a letter, then look at the next bytes" rather than as a state
    /// machine, to check [`Decoder`] against.
    fn reference_decode(bytes: &[u8]) -> Vec<(u8, u32)> {
        let mut frames = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            let letter = bytes[i];
            i += 1;
            if !is_channel_letter(letter) {
                continue;
            }
            let mut digits: Vec<u8> = Vec::new();
            loop {
                let Some(&b) = bytes.get(i) else {
                    return frames; // stream ended inside a frame
                };
                i += 1;
                if b.is_ascii_digit() || (b'A'..=b'F').contains(&b) {
                    digits.push(b);
                    if digits.len() == 8 {
                        break;
                    }
                } else if letter.is_ascii_lowercase() && (b == b'\r' || b == b'\n' || b == b'+') {
                    break;
                } else {
                    digits.clear();
                    digits.push(0xFF); // marks "aborted"
                    break;
                }
            }
            if digits.first() == Some(&0xFF) {
                continue;
            }
            let text = core::str::from_utf8(&digits).unwrap();
            let value = if text.is_empty() {
                0
            } else {
                u32::from_str_radix(text, 16).unwrap()
            };
            frames.push((letter, value));
        }
        frames
    }

    #[test]
    fn golden_float_one_on_g() {
        let frame = Frame::new(b'G', 1.0f32.to_bits()).unwrap();
        assert_eq!(&frame.encode(), b"G3F800000");
    }

    #[test]
    fn golden_reset_frame() {
        assert_eq!(&Frame::new(b'r', 0).unwrap().encode(), b"r00000000");
    }

    #[test]
    fn golden_negative_int() {
        assert_eq!(
            &Frame::new(b'g', (-1i32) as u32).unwrap().encode(),
            b"gFFFFFFFF"
        );
    }

    #[test]
    fn rejects_non_letters_as_channels() {
        for byte in [b'A', b'F', b'0', b'a', b'{', b'@', 0u8, 0xFF] {
            assert_eq!(Frame::new(byte, 0), Err(FrameError::InvalidChannel(byte)));
        }
        assert!(Frame::new(b'G', 0).is_ok());
        assert!(Frame::new(b'z', 0).is_ok());
    }

    #[test]
    fn lowercase_hex_aborts_a_frame() {
        assert!(decode_all(b"G3f800000").is_empty());
        assert_eq!(decode_all(b"G3f800000").len(), 0);
        let mut decoder = Decoder::new();
        decoder.feed(b"G3f800000", |_| {});
        assert_eq!(decoder.stats().aborted, 1);
    }

    #[test]
    fn short_lowercase_frames_are_right_aligned() {
        let frames = decode_all(b"g1F\nh+k12345\r");
        assert_eq!(
            frames,
            [
                Frame::new(b'g', 0x1F).unwrap(),
                Frame::new(b'h', 0).unwrap(),
                Frame::new(b'k', 0x12345).unwrap()
            ]
        );
    }

    #[test]
    fn uppercase_frames_cannot_end_early() {
        assert!(decode_all(b"G12\nH12+").is_empty());
    }

    #[test]
    fn a_letter_that_aborts_a_frame_is_consumed() {
        // The original drops the aborting byte, so the second G does not start a frame.
        assert!(decode_all(b"G0000G3F800000").is_empty());
        // After an abort, the next letter starts a frame again.
        assert_eq!(
            decode_all(b"G0000xH3F800000"),
            [Frame::new(b'H', 0x3F80_0000).unwrap()]
        );
    }

    proptest! {
        #[test]
        fn encode_decode_round_trip(
            frames in proptest::collection::vec(
                (prop_oneof![b'G'..=b'Z', b'g'..=b'z'], any::<u32>()), 0..20)
        ) {
            let frames: Vec<Frame> =
                frames.iter().map(|&(c, v)| Frame::new(c, v).unwrap()).collect();
            let bytes: Vec<u8> = frames.iter().flat_map(|f| f.encode()).collect();
            prop_assert_eq!(decode_all(&bytes), frames);
        }

        #[test]
        fn any_split_decodes_identically(
            bytes in proptest::collection::vec(any::<u8>(), 0..200),
            cuts in proptest::collection::vec(any::<usize>(), 0..8),
        ) {
            let whole = decode_all(&bytes);
            let mut cuts: Vec<usize> =
                cuts.iter().map(|c| c % (bytes.len() + 1)).collect();
            cuts.sort_unstable();
            let mut decoder = Decoder::new();
            let mut pieces = Vec::new();
            let mut start = 0;
            for cut in cuts.into_iter().chain([bytes.len()]) {
                decoder.feed(&bytes[start..cut], |f| pieces.push(f));
                start = cut;
            }
            prop_assert_eq!(pieces, whole);
        }

        #[test]
        fn garbage_never_yields_a_frame_the_original_would_not(
            bytes in proptest::collection::vec(
                prop_oneof![
                    any::<u8>(),
                    prop_oneof![b'0'..=b'9', b'A'..=b'F'],
                    Just(b'G'), Just(b'g'), Just(b'\n'), Just(b'+'),
                ],
                0..300)
        ) {
            let ours: Vec<(u8, u32)> =
                decode_all(&bytes).iter().map(|f| (f.channel(), f.value())).collect();
            prop_assert_eq!(ours, reference_decode(&bytes));
        }
    }

    #[test]
    fn every_split_offset_of_a_stream_decodes_identically() {
        let mut stream = Vec::new();
        for (c, v) in [
            (b'g', 12u32),
            (b'k', 20_016),
            (b's', 1),
            (b'G', 0x3F80_0000),
        ] {
            stream.extend_from_slice(&Frame::new(c, v).unwrap().encode());
        }
        stream.extend_from_slice(b"\x00junk\r\n");
        stream.extend_from_slice(&Frame::new(b'z', 0xDEAD_BEEF).unwrap().encode());
        let whole = decode_all(&stream);
        assert_eq!(whole.len(), 5);
        for cut in 0..=stream.len() {
            let mut decoder = Decoder::new();
            let mut frames = Vec::new();
            decoder.feed(&stream[..cut], |f| frames.push(f));
            decoder.feed(&stream[cut..], |f| frames.push(f));
            assert_eq!(frames, whole, "split at {cut}");
        }
    }
}
