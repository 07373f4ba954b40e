//! The organisers' server request/reply logic without a socket: one outstanding request at a
//! time, a per-try reply timeout that doubles on every retry, validated replies, typed errors.
//!
//! [`RequestTracker`] is a pure state machine with time passed in; the host wraps it around
//! a UDP socket (`ratf_host::referee::client`). There are no request ids (competition.md §3),
//! so a reply is matched to the one outstanding request; a reply that does not validate for it
//! (garbage, or a late answer to an earlier request) is remembered but does not end the
//! request, which may still get a good answer before its tries run out. Nothing here exits or
//! panics because the server is silent: the caller gets [`ClientError::Timeout`] and decides.
use super::protocol::{Reply, ReplyError, Request, parse_reply};
use crate::config::RefereeConfig;

/// The per-try timeout doubles on each retry up to this multiple of the first one.
/// Assumption: ×8 keeps a retry within a few seconds with the default 0.4 s.
pub const MAX_BACKOFF_MULTIPLE: u64 = 8;

/// How long to wait for replies and how often to ask.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RetryPolicy {
    /// Reply timeout of the first try, µs.
    pub first_timeout_us: u64,
    /// Tries per request (the first send counts), at least 1.
    pub max_tries: u32,
}

impl RetryPolicy {
    /// The policy from `[referee]`: `request_timeout_ms` and `max_tries`.
    pub fn from_config(config: &RefereeConfig) -> Self {
        Self {
            first_timeout_us: u64::from(config.request_timeout_ms) * 1_000,
            max_tries: config.max_tries.max(1),
        }
    }

    /// The reply timeout of try `attempt` (1-based), µs: the first timeout doubled per
    /// retry, at most [`MAX_BACKOFF_MULTIPLE`] times it.
    pub fn timeout_us(&self, attempt: u32) -> u64 {
        let doublings = attempt.saturating_sub(1).min(3);
        let multiple = (1u64 << doublings).min(MAX_BACKOFF_MULTIPLE);
        self.first_timeout_us.saturating_mul(multiple)
    }
}

/// Why a request produced no reply.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ClientError {
    /// Another request is still outstanding (one at a time: there are no request ids).
    #[error("cannot send {request}: {outstanding} is still waiting for its reply")]
    Busy {
        /// The refused request.
        request: Request,
        /// The request in flight.
        outstanding: Request,
    },
    /// No reply at all in every try.
    #[error("no reply to {request} after {tries} tries")]
    Timeout {
        /// The request.
        request: Request,
        /// How many times it was sent.
        tries: u32,
    },
    /// Late answers to an earlier request may still arrive until `until_us`: a request now
    /// could be answered by one of them (there are no request ids).
    #[error(
        "cannot send {request} yet: late answers to the previous request are expected until {until_us} µs"
    )]
    Draining {
        /// The refused request.
        request: Request,
        /// When the tracker stops waiting for them, µs.
        until_us: u64,
    },
    /// Only invalid replies arrived in every try; the last one is given.
    #[error("no valid reply to {request} after {tries} tries; last: {last}")]
    BadReply {
        /// The request.
        request: Request,
        /// How many times it was sent.
        tries: u32,
        /// Why the last reply was rejected (names the text).
        last: ReplyError,
    },
}

/// What the tracker wants from its caller at a given time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Step {
    /// No request outstanding.
    Idle,
    /// Waiting for a reply until the deadline.
    Waiting {
        /// When the current try times out, µs.
        deadline_us: u64,
    },
    /// Send this request's text (again) now.
    Send(Request),
    /// The request ended.
    Done(Result<Reply, ClientError>),
}

#[derive(Clone, Debug, PartialEq, Eq)]
struct Outstanding {
    request: Request,
    tries: u32,
    /// When the request was first sent, µs.
    first_sent_us: u64,
    /// When it was last sent, µs.
    last_sent_us: u64,
    deadline_us: u64,
    last_bad: Option<ReplyError>,
}

/// Replies that may still come for sends the server has not answered, after their request
/// ended: a retried request that got one answer, or one that timed out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Draining {
    /// Datagrams still to be discarded.
    strays: u32,
    /// When the tracker stops waiting for them, µs.
    until_us: u64,
}

/// The request/reply logic without a socket.
///
/// The server's replies carry no request id, and the answers to `IWP`, `OWP`, `MAP` and
/// `MBP` look alike (four slot letters). So after a request ends while some of its sends are
/// unanswered (it was retried, or it timed out), the late answers to those sends are
/// discarded: the tracker refuses the next request ([`RequestTracker::ready`] is false)
/// until as many datagrams have arrived as there were unanswered sends, or until the last
/// try's deadline has passed (after a timeout: one more first timeout; after an answer to a
/// retried request: the last send plus the answer's delay from the first send, and a first
/// timeout, if that is later). A reply later still than that would be taken for the next
/// request's; the timeouts and the server's own delay bound how late that is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RequestTracker {
    policy: RetryPolicy,
    outstanding: Option<Outstanding>,
    draining: Option<Draining>,
}

impl RequestTracker {
    /// An idle tracker.
    pub fn new(policy: RetryPolicy) -> Self {
        Self {
            policy,
            outstanding: None,
            draining: None,
        }
    }

    /// The policy.
    pub fn policy(&self) -> RetryPolicy {
        self.policy
    }

    /// The request waiting for a reply, if any.
    pub fn outstanding(&self) -> Option<Request> {
        self.outstanding.as_ref().map(|o| o.request)
    }

    /// When the current try times out, µs, if a request is outstanding.
    pub fn deadline_us(&self) -> Option<u64> {
        self.outstanding.as_ref().map(|o| o.deadline_us)
    }

    /// True when a request may start at `now_us`: none is outstanding and no late answer
    /// to an earlier one is still expected.
    pub fn ready(&self, now_us: u64) -> bool {
        self.outstanding.is_none() && self.draining.is_none_or(|d| now_us >= d.until_us)
    }

    /// Begin `request` at `now_us`; the caller sends its text now.
    pub fn start(&mut self, request: Request, now_us: u64) -> Result<(), ClientError> {
        if let Some(outstanding) = self.outstanding() {
            return Err(ClientError::Busy {
                request,
                outstanding,
            });
        }
        if let Some(draining) = self.draining.filter(|d| now_us < d.until_us) {
            return Err(ClientError::Draining {
                request,
                until_us: draining.until_us,
            });
        }
        self.draining = None;
        self.outstanding = Some(Outstanding {
            request,
            tries: 1,
            first_sent_us: now_us,
            last_sent_us: now_us,
            deadline_us: now_us.saturating_add(self.policy.timeout_us(1)),
            last_bad: None,
        });
        Ok(())
    }

    /// Forget the outstanding request (a late reply to it will then be ignored).
    pub fn cancel(&mut self) {
        self.outstanding = None;
    }

    /// A datagram from the server arrived at `now_us`. Returns the valid reply that ends the
    /// outstanding request; `None` for an invalid reply (remembered), a late answer to an
    /// earlier request (discarded), or when idle.
    pub fn on_datagram(&mut self, now_us: u64, datagram: &[u8]) -> Option<Reply> {
        let Some(outstanding) = self.outstanding.as_mut() else {
            if let Some(draining) = self.draining.as_mut() {
                draining.strays = draining.strays.saturating_sub(1);
                if draining.strays == 0 {
                    self.draining = None;
                }
            }
            return None;
        };
        match parse_reply(outstanding.request, datagram) {
            Ok(reply) => {
                // Every other send of this request may still be answered. Taken as the answer
                // to the first send (the latest the server may be), the last send's answer
                // is as late, give or take a first timeout.
                let strays = outstanding.tries - 1;
                let round_trip_us = now_us.saturating_sub(outstanding.first_sent_us);
                let last_answer_us = outstanding
                    .last_sent_us
                    .saturating_add(round_trip_us)
                    .saturating_add(self.policy.first_timeout_us);
                self.draining = (strays > 0).then_some(Draining {
                    strays,
                    until_us: outstanding.deadline_us.max(last_answer_us),
                });
                self.outstanding = None;
                Some(reply)
            }
            Err(e) => {
                outstanding.last_bad = Some(e);
                None
            }
        }
    }

    /// What to do at `now_us`: keep waiting, resend, or report the failure.
    pub fn step(&mut self, now_us: u64) -> Step {
        let Some(o) = self.outstanding.as_mut() else {
            return Step::Idle;
        };
        if now_us < o.deadline_us {
            return Step::Waiting {
                deadline_us: o.deadline_us,
            };
        }
        if o.tries < self.policy.max_tries {
            o.tries += 1;
            o.last_sent_us = now_us;
            o.deadline_us = now_us.saturating_add(self.policy.timeout_us(o.tries));
            return Step::Send(o.request);
        }
        let (request, tries) = (o.request, o.tries);
        let error = match o.last_bad.take() {
            Some(last) => ClientError::BadReply {
                request,
                tries,
                last,
            },
            None => ClientError::Timeout { request, tries },
        };
        self.outstanding = None;
        self.draining = Some(Draining {
            strays: tries,
            until_us: now_us.saturating_add(self.policy.first_timeout_us),
        });
        Step::Done(Err(error))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::PartColor::{Blue, Green, Red};
    use proptest::prelude::*;

    const POLICY: RetryPolicy = RetryPolicy {
        first_timeout_us: 100_000,
        max_tries: 3,
    };

    #[test]
    fn timeouts_double_per_try_up_to_eight_times() {
        let t: Vec<u64> = (1..=6).map(|k| POLICY.timeout_us(k)).collect();
        assert_eq!(t, [100_000, 200_000, 400_000, 800_000, 800_000, 800_000]);
        let p = RetryPolicy::from_config(&RefereeConfig::default());
        assert_eq!((p.first_timeout_us, p.max_tries), (400_000, 3));
    }

    #[test]
    fn a_good_reply_ends_the_request() {
        let mut t = RequestTracker::new(POLICY);
        assert_eq!(t.step(0), Step::Idle);
        t.start(Request::IncomingWarehouse, 0).unwrap();
        assert_eq!(
            t.step(50_000),
            Step::Waiting {
                deadline_us: 100_000
            }
        );
        let reply = t.on_datagram(60_000, b"RGGB\n");
        assert_eq!(
            reply,
            Some(Reply::Slots([
                Some(Red),
                Some(Green),
                Some(Green),
                Some(Blue)
            ]))
        );
        assert_eq!(t.outstanding(), None);
        assert_eq!(
            t.on_datagram(70_000, b"RGGB"),
            None,
            "a duplicate is ignored when idle"
        );
    }

    #[test]
    fn silence_is_retried_with_backoff_then_a_timeout() {
        let mut t = RequestTracker::new(POLICY);
        t.start(Request::Ping, 1_000).unwrap();
        assert_eq!(
            t.step(100_999),
            Step::Waiting {
                deadline_us: 101_000
            }
        );
        assert_eq!(t.step(101_000), Step::Send(Request::Ping));
        assert_eq!(t.step(301_000), Step::Send(Request::Ping));
        assert_eq!(
            t.step(700_999),
            Step::Waiting {
                deadline_us: 701_000
            }
        );
        let done = t.step(701_000);
        assert_eq!(
            done,
            Step::Done(Err(ClientError::Timeout {
                request: Request::Ping,
                tries: 3
            }))
        );
        assert_eq!(t.step(701_001), Step::Idle);
    }

    #[test]
    fn garbage_is_remembered_and_a_later_good_reply_still_wins() {
        let mut t = RequestTracker::new(POLICY);
        t.start(Request::TimeLeft, 0).unwrap();
        assert_eq!(
            t.on_datagram(0, b"BGGR"),
            None,
            "late answer to an earlier IWP"
        );
        assert_eq!(
            t.on_datagram(0, b"T42"),
            Some(Reply::TimeLeft { seconds: 42 })
        );

        t.start(Request::TimeLeft, 0).unwrap();
        assert_eq!(t.on_datagram(0, b"hello"), None);
        for now in [100_000, 300_000] {
            assert_eq!(t.step(now), Step::Send(Request::TimeLeft));
        }
        let Step::Done(Err(e)) = t.step(700_000) else {
            panic!("expected a failure");
        };
        assert!(matches!(e, ClientError::BadReply { tries: 3, .. }), "{e}");
        assert!(e.to_string().contains("\"HELLO\""), "{e}");
    }

    #[test]
    fn one_request_at_a_time() {
        let mut t = RequestTracker::new(POLICY);
        t.start(Request::MachineA, 0).unwrap();
        assert_eq!(
            t.start(Request::MachineB, 0),
            Err(ClientError::Busy {
                request: Request::MachineB,
                outstanding: Request::MachineA
            })
        );
        t.cancel();
        assert!(t.start(Request::MachineB, 0).is_ok());
    }

    /// A tracker with a 400 ms first timeout whose `IWP`, sent at 0, was sent again at
    /// 400 ms.
    fn incoming_sent_twice() -> RequestTracker {
        let policy = RetryPolicy {
            first_timeout_us: 400_000,
            max_tries: 3,
        };
        let mut t = RequestTracker::new(policy);
        t.start(Request::IncomingWarehouse, 0).unwrap();
        assert_eq!(t.step(400_000), Step::Send(Request::IncomingWarehouse));
        t
    }

    /// The reproducer from the review: with a 400 ms timeout, the server answers every
    /// datagram 650 ms after it was sent. `IWP` is retried at 400 ms; the answer to its first
    /// send (650 ms) ends it; the answer to the retry (1050 ms) must not end the next request,
    /// `OWP`, whose strings look the same.
    #[test]
    fn a_late_answer_to_an_earlier_request_is_never_taken_for_the_next_one() {
        let mut t = incoming_sent_twice();
        let incoming = b"RGGB";
        assert!(matches!(
            t.on_datagram(650_000, incoming),
            Some(Reply::Slots(_))
        ));
        // The robot wants OWP on its next tick: not before the retry's answer is in.
        assert!(!t.ready(660_000));
        assert!(matches!(
            t.start(Request::OutgoingWarehouse, 660_000),
            Err(ClientError::Draining { .. })
        ));
        // The retry's answer arrives and is discarded.
        assert_eq!(t.on_datagram(1_050_000, incoming), None);
        assert!(t.ready(1_060_000));
        t.start(Request::OutgoingWarehouse, 1_060_000).unwrap();
        let outgoing = b"XXXB";
        assert_eq!(
            t.on_datagram(1_100_000, outgoing),
            Some(Reply::Slots([None, None, None, Some(Blue)]))
        );
    }

    /// Round 2, seed 58, the server 1 s late (`ratf bench faults`): `IWP` sent at 0 and again
    /// at 400 ms is answered at 1000 ms; the retry's answer comes at 1400 ms, after the
    /// retry's own deadline (1200 ms). It was taken for `OWP`'s, and the robot planned from a
    /// warehouse with the incoming parts in its outgoing slots.
    #[test]
    fn an_answer_later_than_the_retry_deadline_is_awaited_as_late_as_the_first() {
        let mut t = incoming_sent_twice();
        let incoming = b"XBGB";
        assert!(t.on_datagram(1_000_000, incoming).is_some());
        assert!(!t.ready(1_210_000), "the retry's answer is still to come");
        assert_eq!(t.on_datagram(1_400_000, incoming), None);
        assert!(t.ready(1_400_000));
        t.start(Request::OutgoingWarehouse, 1_400_000).unwrap();
        assert_eq!(
            t.on_datagram(2_400_000, b"XXXB"),
            Some(Reply::Slots([None, None, None, Some(Blue)]))
        );
    }

    #[test]
    fn after_a_timeout_late_answers_are_awaited_for_one_more_first_timeout() {
        let mut t = RequestTracker::new(POLICY);
        t.start(Request::MachineA, 0).unwrap();
        let mut now = 0;
        let result = loop {
            now += 10_000;
            if let Step::Done(result) = t.step(now) {
                break result;
            }
        };
        assert!(matches!(result, Err(ClientError::Timeout { tries: 3, .. })));
        assert!(!t.ready(now + POLICY.first_timeout_us - 1));
        assert_eq!(
            t.on_datagram(now + 1_000, b"BXXX"),
            None,
            "a late answer to MAP"
        );
        assert!(t.ready(now + POLICY.first_timeout_us));
        // A request answered at the first try leaves nothing to wait for.
        t.start(Request::MachineB, now + POLICY.first_timeout_us)
            .unwrap();
        assert!(
            t.on_datagram(now + POLICY.first_timeout_us, b"XXXX")
                .is_some()
        );
        assert!(t.ready(now + POLICY.first_timeout_us));
    }

    /// One event in a random exchange.
    #[derive(Clone, Debug)]
    enum Event {
        Wait(u64),
        Datagram(Vec<u8>),
    }

    proptest! {
        #[test]
        fn any_exchange_ends_by_a_valid_reply_or_after_every_try_and_timeout(
            first_timeout_us in 1u64..1_000_000,
            max_tries in 1u32..6,
            events in proptest::collection::vec(
                prop_oneof![
                    (0u64..3_000_000).prop_map(Event::Wait),
                    proptest::collection::vec(any::<u8>(), 0..6).prop_map(Event::Datagram),
                    Just(Event::Datagram(b"BGGR".to_vec())),
                ],
                0..40,
            ),
        ) {
            let policy = RetryPolicy { first_timeout_us, max_tries };
            let budget_us: u64 = (1..=max_tries).map(|k| policy.timeout_us(k)).sum();
            let mut t = RequestTracker::new(policy);
            t.start(Request::IncomingWarehouse, 0).unwrap();
            let (mut now, mut sends) = (0u64, 1u32);
            for e in events.into_iter().chain(std::iter::repeat_n(Event::Wait(budget_us), 8)) {
                match e {
                    Event::Wait(us) => now += us,
                    Event::Datagram(bytes) => {
                        if let Some(reply) = t.on_datagram(now, &bytes) {
                            prop_assert_eq!(parse_reply(Request::IncomingWarehouse, &bytes), Ok(reply));
                            prop_assert!(sends <= max_tries);
                            return Ok(());
                        }
                    }
                }
                loop {
                    match t.step(now) {
                        Step::Send(r) => {
                            prop_assert_eq!(r, Request::IncomingWarehouse);
                            sends += 1;
                        }
                        Step::Done(result) => {
                            prop_assert!(result.is_err());
                            prop_assert_eq!(sends, max_tries);
                            prop_assert!(now >= budget_us, "ended at {} < {}", now, budget_us);
                            return Ok(());
                        }
                        Step::Idle | Step::Waiting { .. } => break,
                    }
                }
            }
            prop_assert!(false, "still outstanding after {} s of silence", 8 * budget_us / 1_000_000);
        }
    }
}
