//! The X4's single replies: device information (`A5 90`) and health (`A5 91`).
//!
//! Source: the YDLIDAR X4 development manual §2.3 and §3.3–3.4 (the same layout in the G4
//! and F4PRO manuals): a reply is the start flag `A5 5A`, a 30-bit little-endian length
//! with the 2-bit mode in the top bits of the fourth length byte, a type byte, then the
//! content. Device information: length 20, mode 0 (single), type `04`; content model (1
//! byte), firmware (2 bytes), hardware (1), serial number (16). Health: length 3, mode 0,
//! type `06`; content status (1: 0 ok, 1 warning, 2 error) and error code (2 bytes,
//! little-endian).
//!
//! The firmware's two bytes: the manuals' prose says "the low byte is the major version",
//! while YDLIDAR's own SDK reads them as one little-endian `u16` and prints `>> 8` as the
//! major version; this follows the SDK (first byte minor, second major). The model code of
//! the X4 is 6 (the SDK's model table).

use super::COMMAND_PREFIX;

/// The start flag of every X4 reply.
pub const REPLY_FLAG: [u8; 2] = [0xA5, 0x5A];
/// Bytes of a reply's descriptor: flag, length and mode, type.
pub const DESCRIPTOR_LEN: usize = 7;
/// The device-information reply's type code and content length.
const INFO_TYPE: u8 = 0x04;
const INFO_LEN: usize = 20;
/// The health reply's type code and content length.
const HEALTH_TYPE: u8 = 0x06;
const HEALTH_LEN: usize = 3;
/// The model code of the X4 (YDLIDAR SDK, `YDLIDAR_X4 = 6`).
pub const MODEL_X4: u8 = 6;

/// A host → X4 question with a single reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// Device information: `A5 90`.
    DeviceInfo,
    /// Health: `A5 91`.
    Health,
}

impl Request {
    /// The two request bytes.
    pub const fn bytes(self) -> [u8; 2] {
        [COMMAND_PREFIX, self.code()]
    }

    pub(super) const fn code(self) -> u8 {
        match self {
            Self::DeviceInfo => 0x90,
            Self::Health => 0x91,
        }
    }

    pub(super) fn from_code(code: u8) -> Option<Self> {
        [Self::DeviceInfo, Self::Health]
            .into_iter()
            .find(|r| r.code() == code)
    }
}

/// What the X4 says it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceInfo {
    /// Model code (6 for the X4).
    pub model: u8,
    /// Firmware major version.
    pub firmware_major: u8,
    /// Firmware minor version.
    pub firmware_minor: u8,
    /// Hardware version.
    pub hardware: u8,
    /// Factory serial number (the X4 sends one decimal digit a byte).
    pub serial: [u8; 16],
}

impl DeviceInfo {
    /// The serial number as text: its digits when every byte is one (as the X4 sends it),
    /// hexadecimal otherwise.
    pub fn serial_text(&self) -> String {
        if self.serial.iter().all(|&b| b < 10) {
            self.serial.iter().map(|b| char::from(b'0' + b)).collect()
        } else {
            self.serial.iter().map(|b| format!("{b:02X}")).collect()
        }
    }

    /// One line for a person: model, firmware, hardware, serial number.
    pub fn describe(&self) -> String {
        let model = if self.model == MODEL_X4 {
            "X4".to_owned()
        } else {
            format!("model code {} (not an X4)", self.model)
        };
        format!(
            "{model}, firmware {}.{}, hardware {}, serial {}",
            self.firmware_major,
            self.firmware_minor,
            self.hardware,
            self.serial_text()
        )
    }
}

/// The X4's health status code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HealthStatus {
    /// 0: running normally.
    Ok,
    /// 1: a warning.
    Warning,
    /// 2: an error.
    Error,
    /// Any other code (not in the manual).
    Unknown(u8),
}

impl HealthStatus {
    const fn from_code(code: u8) -> Self {
        match code {
            0 => Self::Ok,
            1 => Self::Warning,
            2 => Self::Error,
            other => Self::Unknown(other),
        }
    }

    const fn code(self) -> u8 {
        match self {
            Self::Ok => 0,
            Self::Warning => 1,
            Self::Error => 2,
            Self::Unknown(code) => code,
        }
    }
}

/// The X4's health.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Health {
    /// Status.
    pub status: HealthStatus,
    /// The X4's error code (0: none); its meaning is not documented.
    pub error_code: u16,
}

/// A single reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reply {
    /// To [`Request::DeviceInfo`].
    DeviceInfo(DeviceInfo),
    /// To [`Request::Health`].
    Health(Health),
}

impl Reply {
    /// Append the reply's bytes (descriptor and content) to `out`, for simulated X4s.
    pub fn encode(&self, out: &mut Vec<u8>) {
        let (kind, len) = match self {
            Self::DeviceInfo(_) => (INFO_TYPE, INFO_LEN),
            Self::Health(_) => (HEALTH_TYPE, HEALTH_LEN),
        };
        out.extend(REPLY_FLAG);
        // Length below 2^6: the mode bits (single reply, 0) stay clear.
        out.extend([len as u8, 0, 0, 0, kind]);
        match self {
            Self::DeviceInfo(info) => {
                out.extend([
                    info.model,
                    info.firmware_minor,
                    info.firmware_major,
                    info.hardware,
                ]);
                out.extend(info.serial);
            }
            Self::Health(health) => {
                out.push(health.status.code());
                out.extend(health.error_code.to_le_bytes());
            }
        }
    }

    fn decode(kind: u8, content: &[u8]) -> Option<Self> {
        match (kind, content) {
            (INFO_TYPE, [model, minor, major, hardware, serial @ ..]) => {
                Some(Self::DeviceInfo(DeviceInfo {
                    model: *model,
                    firmware_major: *major,
                    firmware_minor: *minor,
                    hardware: *hardware,
                    serial: serial.try_into().ok()?,
                }))
            }
            (HEALTH_TYPE, [status, low, high]) => Some(Self::Health(Health {
                status: HealthStatus::from_code(*status),
                error_code: u16::from_le_bytes([*low, *high]),
            })),
            _ => None,
        }
    }
}

/// Counters kept by the [`ReplyParser`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReplyStats {
    /// Replies decoded.
    pub replies: u32,
    /// Bytes skipped while hunting for a reply flag.
    pub bytes_skipped: u32,
    /// Descriptors refused: not a single reply of a known type and length (the scan's
    /// descriptor among them).
    pub refused: u32,
}

/// Streaming parser of single replies: bytes (any chunking) → [`Reply`]s. Owns a buffer of
/// the longest reply; never allocates, never panics.
#[derive(Clone, Debug)]
pub struct ReplyParser {
    buf: [u8; DESCRIPTOR_LEN + INFO_LEN],
    len: usize,
    stats: ReplyStats,
}

impl Default for ReplyParser {
    fn default() -> Self {
        Self::new()
    }
}

/// What the bytes at the front of the buffer are.
enum Front {
    NeedMore,
    Skip,
    Refuse,
    Reply(Reply),
}

impl ReplyParser {
    /// An empty parser.
    pub const fn new() -> Self {
        Self {
            buf: [0; DESCRIPTOR_LEN + INFO_LEN],
            len: 0,
            stats: ReplyStats {
                replies: 0,
                bytes_skipped: 0,
                refused: 0,
            },
        }
    }

    /// Counters since construction.
    pub const fn stats(&self) -> ReplyStats {
        self.stats
    }

    /// Feed received bytes; `on_reply` gets every reply as soon as its last byte is fed.
    pub fn feed(&mut self, bytes: &[u8], mut on_reply: impl FnMut(Reply)) {
        for &byte in bytes {
            // The buffer never stays full: a full buffer holds a complete info reply or
            // something refused, and both are consumed below.
            if let Some(slot) = self.buf.get_mut(self.len) {
                *slot = byte;
                self.len += 1;
            }
            loop {
                match self.front() {
                    Front::NeedMore => break,
                    Front::Skip => {
                        self.stats.bytes_skipped = self.stats.bytes_skipped.wrapping_add(1);
                        self.shift(1);
                    }
                    Front::Refuse => {
                        // Examine again everything after the false flag's first byte.
                        self.stats.refused = self.stats.refused.wrapping_add(1);
                        self.shift(1);
                    }
                    Front::Reply(reply) => {
                        self.stats.replies = self.stats.replies.wrapping_add(1);
                        self.len = 0;
                        on_reply(reply);
                    }
                }
            }
        }
    }

    fn shift(&mut self, n: usize) {
        self.buf.copy_within(n..self.len, 0);
        self.len -= n;
    }

    fn front(&self) -> Front {
        let pending = &self.buf[..self.len];
        match pending {
            [] => Front::NeedMore,
            [first, ..] if *first != REPLY_FLAG[0] => Front::Skip,
            [_, second, ..] if *second != REPLY_FLAG[1] => Front::Skip,
            [_, _, l0, l1, l2, l3, kind, content @ ..] => {
                let word = u32::from_le_bytes([*l0, *l1, *l2, *l3]);
                let (length, mode) = (word & 0x3FFF_FFFF, word >> 30);
                let expected = match *kind {
                    INFO_TYPE => INFO_LEN,
                    HEALTH_TYPE => HEALTH_LEN,
                    _ => return Front::Refuse,
                };
                if mode != 0 || usize::try_from(length).ok() != Some(expected) {
                    Front::Refuse
                } else if content.len() < expected {
                    Front::NeedMore
                } else {
                    Reply::decode(*kind, &content[..expected]).map_or(Front::Refuse, Front::Reply)
                }
            }
            _ => Front::NeedMore,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A device-information reply as an X4 sends it: model 6, firmware 1.7 (minor first),
    /// hardware 1, serial 2017 0101 0000 0042 one digit a byte.
    const INFO_BYTES: [u8; 27] = [
        0xA5, 0x5A, 0x14, 0x00, 0x00, 0x00, 0x04, 0x06, 0x07, 0x01, 0x01, 2, 0, 1, 7, 0, 1, 0, 1,
        0, 0, 0, 0, 0, 0, 4, 2,
    ];
    /// A health reply: error, code 0x0102.
    const HEALTH_BYTES: [u8; 10] = [0xA5, 0x5A, 0x03, 0x00, 0x00, 0x00, 0x06, 0x02, 0x02, 0x01];

    fn info() -> DeviceInfo {
        DeviceInfo {
            model: MODEL_X4,
            firmware_major: 1,
            firmware_minor: 7,
            hardware: 1,
            serial: [2, 0, 1, 7, 0, 1, 0, 1, 0, 0, 0, 0, 0, 0, 4, 2],
        }
    }

    fn parse(bytes: &[u8]) -> (Vec<Reply>, ReplyStats) {
        let mut parser = ReplyParser::new();
        let mut replies = Vec::new();
        parser.feed(bytes, |r| replies.push(r));
        (replies, parser.stats())
    }

    #[test]
    fn requests() {
        assert_eq!(Request::DeviceInfo.bytes(), [0xA5, 0x90]);
        assert_eq!(Request::Health.bytes(), [0xA5, 0x91]);
    }

    #[test]
    fn golden_replies_decode() {
        let (replies, stats) = parse(&[INFO_BYTES.as_slice(), &HEALTH_BYTES].concat());
        let expected = [
            Reply::DeviceInfo(info()),
            Reply::Health(Health {
                status: HealthStatus::Error,
                error_code: 0x0102,
            }),
        ];
        assert_eq!(replies, expected);
        assert_eq!(stats.replies, 2);
        assert_eq!(
            info().describe(),
            "X4, firmware 1.7, hardware 1, serial 2017010100000042"
        );
    }

    #[test]
    fn encode_gives_the_golden_bytes() {
        let mut out = Vec::new();
        Reply::DeviceInfo(info()).encode(&mut out);
        Reply::Health(Health {
            status: HealthStatus::Error,
            error_code: 0x0102,
        })
        .encode(&mut out);
        assert_eq!(out, [INFO_BYTES.as_slice(), &HEALTH_BYTES].concat());
    }

    #[test]
    fn a_reply_split_at_every_offset_decodes_once() {
        let bytes = [INFO_BYTES.as_slice(), &HEALTH_BYTES].concat();
        let (whole, _) = parse(&bytes);
        for cut in 0..=bytes.len() {
            let mut parser = ReplyParser::new();
            let mut replies = Vec::new();
            parser.feed(&bytes[..cut], |r| replies.push(r));
            parser.feed(&bytes[cut..], |r| replies.push(r));
            assert_eq!(replies, whole, "split at {cut}");
        }
    }

    #[test]
    fn garbage_and_false_flags_before_a_reply_are_skipped() {
        // Noise, a lone flag byte, a flag cut short, and a scan's descriptor.
        let mut bytes = vec![0x00, 0xAA, 0x55, 0xA5, 0x13, 0xA5, 0xA5, 0x5A, 0x05, 0x00];
        bytes.extend([0xA5, 0x5A, 0x05, 0x00, 0x00, 0x40, 0x81]);
        bytes.extend(HEALTH_BYTES);
        let (replies, stats) = parse(&bytes);
        assert_eq!(replies.len(), 1);
        assert!(matches!(replies[0], Reply::Health(_)));
        assert!(stats.refused >= 1 && stats.bytes_skipped > 0, "{stats:?}");
    }

    #[test]
    fn a_wrong_length_or_mode_is_refused() {
        let mut short = HEALTH_BYTES;
        short[2] = 0x02;
        let mut continuous = HEALTH_BYTES;
        continuous[5] = 0x40;
        let mut long_info = INFO_BYTES;
        long_info[2] = 0x15;
        for bytes in [&short[..], &continuous, &long_info] {
            let (replies, stats) = parse(bytes);
            assert!(replies.is_empty(), "{bytes:02X?} gave {replies:?}");
            assert_eq!(stats.refused, 1, "{bytes:02X?}");
        }
    }

    #[test]
    fn serial_numbers_that_are_not_digits_show_in_hexadecimal() {
        let mut odd = info();
        odd.serial = [0xAB; 16];
        odd.model = 4;
        assert_eq!(
            odd.describe(),
            format!(
                "model code 4 (not an X4), firmware 1.7, hardware 1, serial {}",
                "AB".repeat(16)
            )
        );
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic_and_a_reply_after_them_is_found(
            noise in proptest::collection::vec(any::<u8>(), 0..200),
            cut in 0usize..300,
        ) {
            let mut bytes = noise;
            for _ in 0..3 {
                bytes.extend(HEALTH_BYTES);
            }
            let cut = cut.min(bytes.len());
            let mut parser = ReplyParser::new();
            let mut replies = Vec::new();
            parser.feed(&bytes[..cut], |r| replies.push(r));
            parser.feed(&bytes[cut..], |r| replies.push(r));
            // A false descriptor at the noise's end may swallow up to 20 bytes (two
            // copies) as its content; the third copy is always found.
            prop_assert!(replies.last().is_some_and(|r| matches!(r, Reply::Health(_))));
        }
    }
}
