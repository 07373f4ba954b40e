//! The organisers' UDP protocol (competition.md §3; original-system.md §6.5): the requests,
//! the replies, and the validation of a reply's text.
//!
//! Every request and reply is one datagram of plain ASCII with no terminator, length prefix
//! or request id. Replies are trimmed of surrounding whitespace (a server may add a newline)
//! and upper-cased before they are checked; `STOP` is a valid reply to any request (the run
//! has not started).

use std::fmt;

use crate::field::PartColor;

/// The contents of four slots in the server's order (`None` = `X`, empty).
///
/// Warehouses: slot 0..3 from left to right (increasing x, 5dpo's mapping). Machines: the
/// 2 × 2 layout read `1 2 / 3 4`, i.e. index 0 = upper row input, 1 = upper row output,
/// 2 = lower row input, 3 = lower row output (competition.md §3).
pub type SlotLetters = [Option<PartColor>; 4];

/// A request the robot sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Request {
    /// `PING`: connectivity check, answered `PONG`.
    Ping,
    /// `IWP`: the incoming warehouse's four slots.
    IncomingWarehouse,
    /// `OWP`: the outgoing warehouse's four slots.
    OutgoingWarehouse,
    /// `MAP`: machine A's four slots.
    MachineA,
    /// `MBP`: machine B's four slots.
    MachineB,
    /// `CTL`: the competition time left, `T<seconds>`.
    TimeLeft,
}

impl Request {
    /// Every request, in the order of competition.md §3's table.
    pub const ALL: [Self; 6] = [
        Self::IncomingWarehouse,
        Self::OutgoingWarehouse,
        Self::MachineA,
        Self::MachineB,
        Self::TimeLeft,
        Self::Ping,
    ];

    /// The datagram text.
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Ping => "PING",
            Self::IncomingWarehouse => "IWP",
            Self::OutgoingWarehouse => "OWP",
            Self::MachineA => "MAP",
            Self::MachineB => "MBP",
            Self::TimeLeft => "CTL",
        }
    }

    /// Parse a received request (trimmed, any case); `None` if it is not one of the six.
    pub fn parse(datagram: &[u8]) -> Option<Self> {
        let text = std::str::from_utf8(datagram)
            .ok()?
            .trim()
            .to_ascii_uppercase();
        Self::ALL.into_iter().find(|r| r.as_str() == text)
    }
}

impl fmt::Display for Request {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A validated reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reply {
    /// `PONG`, the answer to `PING`.
    Pong,
    /// `STOP`: the run has not started (or has ended); the robot must stay still.
    Stop,
    /// Four slot letters (answer to `IWP`, `OWP`, `MAP`, `MBP`).
    Slots(SlotLetters),
    /// `T<seconds>`: the competition time left (answer to `CTL`).
    TimeLeft {
        /// Seconds left in the 10-minute slot.
        seconds: u32,
    },
}

impl Reply {
    /// The datagram text (what the mock server sends).
    pub fn to_text(&self) -> String {
        match self {
            Self::Pong => "PONG".to_owned(),
            Self::Stop => "STOP".to_owned(),
            Self::Slots(slots) => letters_to_string(slots),
            Self::TimeLeft { seconds } => format!("T{seconds}"),
        }
    }
}

/// Why a reply was rejected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// The datagram was empty or only whitespace.
    #[error("empty reply to {request}")]
    Empty {
        /// The request it answered.
        request: Request,
    },
    /// The datagram was not printable ASCII.
    #[error("reply to {request} is not printable ASCII: {text:?}")]
    NotAscii {
        /// The request it answered.
        request: Request,
        /// The text, lossily decoded.
        text: String,
    },
    /// The text does not have the form the request expects.
    #[error("bad reply to {request}: {text:?} (expected {expected})")]
    Malformed {
        /// The request it answered.
        request: Request,
        /// The trimmed, upper-cased text.
        text: String,
        /// What was expected, in words.
        expected: &'static str,
    },
}

/// The four letters for `slots` (`X` for empty).
pub fn letters_to_string(slots: &SlotLetters) -> String {
    slots
        .iter()
        .map(|s| s.map_or('X', PartColor::letter))
        .collect()
}

/// Parse four slot letters from {B, G, R, X} (already trimmed and upper-cased).
pub fn parse_letters(text: &str) -> Option<SlotLetters> {
    let chars: Vec<char> = text.chars().collect();
    if chars.len() != 4 {
        return None;
    }
    let mut slots = [None; 4];
    for (slot, &c) in slots.iter_mut().zip(&chars) {
        *slot = match c {
            'X' => None,
            other => Some(PartColor::from_letter(other)?),
        };
    }
    Some(slots)
}

/// What each request expects, in words (for error messages).
const fn expected(request: Request) -> &'static str {
    match request {
        Request::Ping => "PONG or STOP",
        Request::TimeLeft => "T<seconds> or STOP",
        _ => "4 letters from B, G, R, X, or STOP",
    }
}

/// Validate the datagram `datagram` received in answer to `request`.
pub fn parse_reply(request: Request, datagram: &[u8]) -> Result<Reply, ReplyError> {
    let printable = datagram
        .iter()
        .all(|&b| b.is_ascii_graphic() || b.is_ascii_whitespace());
    if !printable {
        return Err(ReplyError::NotAscii {
            request,
            text: String::from_utf8_lossy(datagram).into_owned(),
        });
    }
    // Only printable ASCII is left, so this conversion cannot fail.
    let text = String::from_utf8_lossy(datagram)
        .trim()
        .to_ascii_uppercase();
    if text.is_empty() {
        return Err(ReplyError::Empty { request });
    }
    if text == "STOP" {
        return Ok(Reply::Stop);
    }
    let reply = match request {
        Request::Ping => (text == "PONG").then_some(Reply::Pong),
        Request::TimeLeft => parse_time_left(&text),
        _ => parse_letters(&text).map(Reply::Slots),
    };
    reply.ok_or(ReplyError::Malformed {
        request,
        text,
        expected: expected(request),
    })
}

/// `T` followed by 1 to 9 decimal digits (the digit count is not fixed; competition.md §3).
fn parse_time_left(text: &str) -> Option<Reply> {
    let digits = text.strip_prefix('T')?;
    let valid = (1..=9).contains(&digits.len()) && digits.bytes().all(|b| b.is_ascii_digit());
    valid.then(|| Reply::TimeLeft {
        seconds: digits.parse().unwrap_or(u32::MAX),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use PartColor::{Blue, Green, Red};
    use proptest::prelude::*;

    #[test]
    fn requests_round_trip_and_are_trimmed() {
        for r in Request::ALL {
            assert_eq!(Request::parse(r.as_str().as_bytes()), Some(r));
        }
        assert_eq!(Request::parse(b" iwp\n"), Some(Request::IncomingWarehouse));
        assert_eq!(Request::parse(b"IWPX"), None);
        assert_eq!(Request::parse(b""), None);
    }

    #[test]
    fn slot_replies_are_trimmed_upper_cased_and_validated() {
        let r = parse_reply(Request::IncomingWarehouse, b" bggr\r\n").unwrap();
        assert_eq!(
            r,
            Reply::Slots([Some(Blue), Some(Green), Some(Green), Some(Red)])
        );
        let r = parse_reply(Request::MachineA, b"BXXG").unwrap();
        assert_eq!(r, Reply::Slots([Some(Blue), None, None, Some(Green)]));
        for bad in [&b"BGG"[..], b"BGGRR", b"BGYR", b"B GR", b"PONG", b"T12"] {
            let e = parse_reply(Request::MachineB, bad).unwrap_err();
            assert!(matches!(e, ReplyError::Malformed { .. }), "{bad:?}: {e}");
            assert!(e.to_string().contains("MBP"), "{e}");
        }
    }

    #[test]
    fn stop_is_valid_for_every_request_and_pong_only_for_ping() {
        for r in Request::ALL {
            assert_eq!(parse_reply(r, b"STOP\n"), Ok(Reply::Stop));
        }
        assert_eq!(parse_reply(Request::Ping, b"pong"), Ok(Reply::Pong));
        assert!(parse_reply(Request::TimeLeft, b"PONG").is_err());
    }

    #[test]
    fn time_left_has_a_variable_digit_count() {
        for (text, seconds) in [("T0", 0), ("T7", 7), ("T532", 532), ("t600\n", 600)] {
            assert_eq!(
                parse_reply(Request::TimeLeft, text.as_bytes()),
                Ok(Reply::TimeLeft { seconds })
            );
        }
        for bad in ["T", "T-1", "532", "T5 3", "T12a", "T1234567890"] {
            assert!(
                parse_reply(Request::TimeLeft, bad.as_bytes()).is_err(),
                "{bad}"
            );
        }
    }

    #[test]
    fn empty_and_binary_replies_are_named_errors() {
        assert_eq!(
            parse_reply(Request::Ping, b" \n"),
            Err(ReplyError::Empty {
                request: Request::Ping
            })
        );
        let e = parse_reply(Request::IncomingWarehouse, &[0x42, 0x00, 0xff, 0x47]).unwrap_err();
        assert!(matches!(e, ReplyError::NotAscii { .. }));
        assert!(e.to_string().contains("IWP"));
    }

    fn slot_strategy() -> impl Strategy<Value = Option<PartColor>> {
        prop_oneof![
            Just(None),
            Just(Some(Red)),
            Just(Some(Green)),
            Just(Some(Blue))
        ]
    }

    proptest! {
        #[test]
        fn every_reply_round_trips_through_its_text(
            slots in proptest::array::uniform4(slot_strategy()),
            seconds in 0u32..1_000_000,
        ) {
            let reply = Reply::Slots(slots);
            prop_assert_eq!(parse_reply(Request::OutgoingWarehouse, reply.to_text().as_bytes()), Ok(reply));
            let reply = Reply::TimeLeft { seconds };
            prop_assert_eq!(parse_reply(Request::TimeLeft, reply.to_text().as_bytes()), Ok(reply));
        }

        #[test]
        fn arbitrary_bytes_give_an_error_or_a_reply_that_round_trips(
            bytes in proptest::collection::vec(any::<u8>(), 0..12),
        ) {
            for r in Request::ALL {
                if let Ok(reply) = parse_reply(r, &bytes) {
                    prop_assert_eq!(parse_reply(r, reply.to_text().as_bytes()), Ok(reply));
                }
            }
        }
    }
}
