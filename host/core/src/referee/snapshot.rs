//! The server's view of the floor as the robot reads it: the four area strings (`IWP`,
//! `OWP`, `MAP`, `MBP`) asked one after the other, and when (competition.md §5). The task
//! planner folds a snapshot into what it knows (`competition::TaskActions::offer_snapshot`).

use crate::referee::protocol::{Reply, Request, SlotLetters};
use crate::referee::tracker::ClientError;

/// The server's four strings read one after the other, with when they were asked and
/// answered (the robot's clock, µs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServerSnapshot {
    /// The answers to `IWP`, `OWP`, `MAP`, `MBP`, in that order.
    pub areas: [SlotLetters; 4],
    /// When the first of the four requests was sent, µs.
    pub sent_us: u64,
    /// When the last of the four answers arrived, µs.
    pub answered_us: u64,
}

/// The requests of one snapshot, in [`ServerSnapshot::areas`] order.
pub const SNAPSHOT_REQUESTS: [Request; 4] = [
    Request::IncomingWarehouse,
    Request::OutgoingWarehouse,
    Request::MachineA,
    Request::MachineB,
];

/// Cycles through [`SNAPSHOT_REQUESTS`], one request outstanding at a time and a new cycle
/// every `period_us` at most: the answers so far and when the cycle's first request was
/// sent. Pure: the caller sends the requests and passes the time and the replies in.
#[derive(Clone, Copy, Debug)]
pub struct SnapshotCycle {
    /// Answers received, in order.
    areas: [SlotLetters; 4],
    /// How many of them.
    answered: usize,
    /// When the cycle's first request was sent, µs.
    sent_us: u64,
    /// When the next cycle may begin, µs.
    next_cycle_us: u64,
    /// Shortest time between the starts of two cycles, µs.
    period_us: u64,
}

impl SnapshotCycle {
    /// A cycle whose first request is due at once, then one cycle every `period_us` at most.
    pub fn new(period_us: u64) -> Self {
        Self {
            areas: [[None; 4]; 4],
            answered: 0,
            sent_us: 0,
            next_cycle_us: 0,
            period_us,
        }
    }

    /// Forget the answers so far: the next request is `IWP` again.
    pub fn restart(&mut self) {
        self.answered = 0;
    }

    /// The request to send at `now_us` when none is outstanding: the cycle's next one, or
    /// `IWP` once a new cycle is due (`None` until then).
    pub fn request_due(&mut self, now_us: u64) -> Option<Request> {
        if self.answered == 0 {
            if now_us < self.next_cycle_us {
                return None;
            }
            self.sent_us = now_us;
            self.next_cycle_us = now_us + self.period_us;
        }
        SNAPSHOT_REQUESTS.get(self.answered).copied()
    }

    /// The end of the request `asked` at `now_us`: the complete snapshot after the fourth
    /// answer. Anything but the expected strings (`STOP`, a timeout, an answer to an
    /// abandoned cycle) starts the cycle over.
    pub fn on_reply(
        &mut self,
        asked: Option<Request>,
        result: Result<Reply, ClientError>,
        now_us: u64,
    ) -> Option<ServerSnapshot> {
        let expected = SNAPSHOT_REQUESTS.get(self.answered).copied();
        match (result, asked == expected) {
            (Ok(Reply::Slots(letters)), true) => {
                self.areas[self.answered] = letters;
                self.answered += 1;
            }
            _ => {
                self.restart();
                return None;
            }
        }
        if self.answered < SNAPSHOT_REQUESTS.len() {
            return None;
        }
        self.restart();
        Some(ServerSnapshot {
            areas: self.areas,
            sent_us: self.sent_us,
            answered_us: now_us,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD_US: u64 = 200_000;

    #[test]
    fn a_snapshot_is_four_answers_in_order_and_anything_else_starts_over() {
        let letters = |text: &str| crate::referee::protocol::parse_letters(text).unwrap();
        let mut cycle = SnapshotCycle::new(PERIOD_US);
        let answer = |cycle: &mut SnapshotCycle, now_us: u64, reply: Reply| {
            let request = cycle.request_due(now_us);
            cycle.on_reply(request, Ok(reply), now_us)
        };
        assert_eq!(answer(&mut cycle, 0, Reply::Slots(letters("BBBB"))), None);
        assert_eq!(answer(&mut cycle, 20, Reply::Stop), None);
        // Started over: the next cycle waits for its period.
        assert_eq!(cycle.request_due(100), None);
        let period_us = PERIOD_US;
        let texts = ["BXBB", "XBXX", "XXXX", "XXXX"];
        let mut snapshot = None;
        for (k, text) in texts.into_iter().enumerate() {
            snapshot = answer(
                &mut cycle,
                period_us + k as u64,
                Reply::Slots(letters(text)),
            );
        }
        assert_eq!(
            snapshot,
            Some(ServerSnapshot {
                areas: texts.map(letters),
                sent_us: period_us,
                answered_us: period_us + 3,
            })
        );
        // A reply to something else is not taken for the expected strings.
        let request = cycle.request_due(3 * period_us);
        assert_eq!(request, Some(Request::IncomingWarehouse));
        let late = cycle.on_reply(
            Some(Request::MachineB),
            Ok(Reply::Slots(letters("XXXX"))),
            3 * period_us,
        );
        assert_eq!((late, cycle.answered), (None, 0));
    }
}
