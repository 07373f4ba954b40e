//! The mock organisers' server as a pure state machine (time passed in, no I/O): the run's
//! phase and clock, the slot contents, and the machines' work.
//!
//! Behaviour (competition.md §3 "Mock server outline"): `Waiting` answers `STOP` to every
//! request except `PING`; an operator's start switches to `Running` and starts the clock;
//! `IWP`/`OWP`/`MAP`/`MBP` return the current four letters; `CTL` returns
//! `T{max(0, 600 − elapsed)}`. The real server learns part movements from referees watching
//! the floor; here the simulator (or a test) reports them through [`MockReferee::place`] and
//! [`MockReferee::take`]. A part placed on a machine's input that the machine accepts moves,
//! after the configured delay and once the row's output is empty, to the output with its new
//! colour (R→G at A, G→B at B, and G→B at A when greens may use either machine, round 2) —
//! the same rules as the simulator's `crate::parts::Shop`.

use std::fmt;

use ratf_core::field::PartColor;
use ratf_core::field::{Field, MachineKind, WaypointId};
use ratf_core::referee::protocol::{Reply, Request, SlotLetters};
use ratf_core::rng::SimRng;

/// Length of a team's slot in a round, s (competition.md §2: one 10-minute slot).
pub const ROUND_DURATION_S: u64 = 600;

/// A group of four slots the server reports together.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Area {
    /// Incoming warehouse (`IWP`).
    Incoming,
    /// Outgoing warehouse (`OWP`).
    Outgoing,
    /// Machine block A (`MAP`).
    MachineA,
    /// Machine block B (`MBP`).
    MachineB,
}

impl Area {
    /// The four areas in `IWP`, `OWP`, `MAP`, `MBP` order.
    pub const ALL: [Self; 4] = [
        Self::Incoming,
        Self::Outgoing,
        Self::MachineA,
        Self::MachineB,
    ];

    fn index(self) -> usize {
        match self {
            Self::Incoming => 0,
            Self::Outgoing => 1,
            Self::MachineA => 2,
            Self::MachineB => 3,
        }
    }

    fn machine(self) -> Option<MachineKind> {
        match self {
            Self::MachineA => Some(MachineKind::A),
            Self::MachineB => Some(MachineKind::B),
            _ => None,
        }
    }
}

/// One slot as the server numbers it: an area and an index 0..3 in the server's letter
/// order (machines: 0/1 = upper row input/output, 2/3 = lower row input/output).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ServerSlot {
    /// Which group of slots.
    pub area: Area,
    /// Index 0..3 within the area.
    pub index: usize,
}

impl fmt::Display for ServerSlot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?}[{}]", self.area, self.index)
    }
}

impl ServerSlot {
    /// The slot served by the task waypoint `id` (50–65) on `field`, or `None`.
    pub fn of_waypoint(field: &Field, id: WaypointId) -> Option<Self> {
        Area::ALL.into_iter().find_map(|area| {
            (0..4)
                .map(|index| Self { area, index })
                .find(|s| s.waypoint(field) == Some(id))
        })
    }

    /// The task waypoint of this slot on `field`, or `None` if the index is out of range.
    pub fn waypoint(&self, field: &Field) -> Option<WaypointId> {
        let slot = match self.area.machine() {
            None if self.area == Area::Incoming => field.incoming_slot(self.index)?,
            None => field.outgoing_slot(self.index)?,
            Some(kind) => {
                let machine = field.machine(kind, self.index / 2)?;
                if self.index.is_multiple_of(2) {
                    &machine.input
                } else {
                    &machine.output
                }
            }
        };
        Some(slot.waypoint)
    }
}

/// The run's phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Before the start: every request but `PING` gets `STOP`.
    Waiting,
    /// The run: the clock started at `started_us`.
    Running {
        /// Start time, µs (caller's clock).
        started_us: u64,
    },
    /// Stopped by the operator: `STOP` again (assumption: the rules do not say what the
    /// server answers after a run).
    Stopped {
        /// Start time, µs.
        started_us: u64,
        /// Stop time, µs.
        stopped_us: u64,
    },
}

/// What the mock is set up with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MockSettings {
    /// The incoming warehouse at the start.
    pub incoming: SlotLetters,
    /// Machine processing time, µs.
    pub machine_delay_us: u64,
    /// Whether machine A also turns green into blue (round 2: either machine).
    pub green_to_blue_at_a: bool,
}

impl MockSettings {
    /// The preset for `round` (1, 2 or 3) with parts from [`round_parts`], or the given
    /// `parts`, and `machine_delay_us`. Greens may use machine A in rounds 1 and 2.
    pub fn for_round(
        round: u8,
        seed: u64,
        parts: Option<SlotLetters>,
        machine_delay_us: u64,
    ) -> Result<Self, MockError> {
        let preset = round_parts(round, seed)?;
        Ok(Self {
            incoming: parts.unwrap_or(preset),
            machine_delay_us,
            green_to_blue_at_a: round < 3,
        })
    }
}

/// Why a notification or a preset was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MockError {
    /// The round is not 1, 2 or 3.
    #[error("no round {0}: rounds are 1, 2 and 3")]
    NoSuchRound(u8),
    /// The slot index is not 0..3.
    #[error("no slot {0}: indices are 0..3")]
    NoSuchSlot(ServerSlot),
    /// A part was placed where one already stands.
    #[error("slot {0} is already occupied")]
    Occupied(ServerSlot),
    /// A part was taken from an empty slot.
    #[error("slot {0} is empty")]
    Empty(ServerSlot),
}

/// The parts of a round's preset (competition.md §3): round 1 `BBBB`, round 2 a random
/// permutation of `BBGG`, round 3 a random permutation of `RGGB`; `seed` chooses it.
pub fn round_parts(round: u8, seed: u64) -> Result<SlotLetters, MockError> {
    use PartColor::{Blue, Green, Red};
    let mut parts = match round {
        1 => [Blue; 4],
        2 => [Blue, Blue, Green, Green],
        3 => [Red, Green, Green, Blue],
        other => return Err(MockError::NoSuchRound(other)),
    };
    let mut rng = SimRng::new(seed).fork("referee-parts");
    for i in (1..parts.len()).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        parts.swap(i, j);
    }
    Ok(parts.map(Some))
}

/// A part on a machine's input waiting to be turned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Job {
    area: Area,
    row: usize,
    new_color: PartColor,
    ready_at_us: u64,
}

/// The mock server's state.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MockReferee {
    settings: MockSettings,
    phase: Phase,
    slots: [SlotLetters; 4],
    jobs: Vec<Job>,
}

impl MockReferee {
    /// A server waiting for the start, the incoming warehouse filled.
    pub fn new(settings: MockSettings) -> Self {
        let mut slots = [[None; 4]; 4];
        slots[Area::Incoming.index()] = settings.incoming;
        Self {
            settings,
            phase: Phase::Waiting,
            slots,
            jobs: Vec::new(),
        }
    }

    /// The settings.
    pub fn settings(&self) -> &MockSettings {
        &self.settings
    }

    /// The phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Start the run at `now_us` (the attempt clock starts when the colours are given). No
    /// effect unless waiting.
    pub fn start(&mut self, now_us: u64) {
        if self.phase == Phase::Waiting {
            self.phase = Phase::Running { started_us: now_us };
        }
    }

    /// Stop the run at `now_us`. No effect unless running.
    pub fn stop(&mut self, now_us: u64) {
        if let Phase::Running { started_us } = self.phase {
            self.phase = Phase::Stopped {
                started_us,
                stopped_us: now_us,
            };
        }
    }

    /// Seconds left of the 10-minute slot at `now_us` (600 before the start), rounded down.
    pub fn time_left_s(&self, now_us: u64) -> u64 {
        let elapsed_us = match self.phase {
            Phase::Waiting => 0,
            Phase::Running { started_us } => now_us.saturating_sub(started_us),
            Phase::Stopped {
                started_us,
                stopped_us,
            } => stopped_us.saturating_sub(started_us),
        };
        (ROUND_DURATION_S * 1_000_000).saturating_sub(elapsed_us) / 1_000_000
    }

    /// The four letters of `area` at `now_us` (the machines advanced first).
    pub fn letters(&mut self, area: Area, now_us: u64) -> SlotLetters {
        self.advance(now_us);
        self.slots[area.index()]
    }

    /// The reply to `request` at `now_us`.
    pub fn respond(&mut self, request: Request, now_us: u64) -> Reply {
        self.advance(now_us);
        let running = matches!(self.phase, Phase::Running { .. });
        let area = match request {
            Request::Ping => return Reply::Pong,
            _ if !running => return Reply::Stop,
            Request::TimeLeft => {
                let seconds = u32::try_from(self.time_left_s(now_us)).unwrap_or(u32::MAX);
                return Reply::TimeLeft { seconds };
            }
            Request::IncomingWarehouse => Area::Incoming,
            Request::OutgoingWarehouse => Area::Outgoing,
            Request::MachineA => Area::MachineA,
            Request::MachineB => Area::MachineB,
        };
        Reply::Slots(self.slots[area.index()])
    }

    /// The reply text to one received datagram, or `None` if it is not a request (the
    /// mock stays silent, as an unknown request gets no documented answer).
    pub fn handle_datagram(&mut self, datagram: &[u8], now_us: u64) -> Option<String> {
        Request::parse(datagram).map(|r| self.respond(r, now_us).to_text())
    }

    /// Notification: a part of `color` was put in `slot` at `now_us`. On a machine's input
    /// that accepts the colour, processing starts.
    pub fn place(
        &mut self,
        slot: ServerSlot,
        color: PartColor,
        now_us: u64,
    ) -> Result<(), MockError> {
        self.advance(now_us);
        let cell = self.cell(slot)?;
        if cell.is_some() {
            return Err(MockError::Occupied(slot));
        }
        *cell = Some(color);
        let new_color = match (slot.area, color) {
            (Area::MachineA, PartColor::Red) => Some(PartColor::Green),
            (Area::MachineA, PartColor::Green) if self.settings.green_to_blue_at_a => {
                Some(PartColor::Blue)
            }
            (Area::MachineB, PartColor::Green) => Some(PartColor::Blue),
            _ => None,
        };
        if let Some(new_color) = new_color.filter(|_| slot.index.is_multiple_of(2)) {
            self.jobs.push(Job {
                area: slot.area,
                row: slot.index / 2,
                new_color,
                ready_at_us: now_us.saturating_add(self.settings.machine_delay_us),
            });
            self.advance(now_us);
        }
        Ok(())
    }

    /// Notification: the part in `slot` was taken at `now_us`; returns its colour.
    pub fn take(&mut self, slot: ServerSlot, now_us: u64) -> Result<PartColor, MockError> {
        self.advance(now_us);
        let color = self.cell(slot)?.take().ok_or(MockError::Empty(slot))?;
        self.jobs
            .retain(|j| !(j.area == slot.area && 2 * j.row == slot.index));
        self.advance(now_us);
        Ok(color)
    }

    fn cell(&mut self, slot: ServerSlot) -> Result<&mut Option<PartColor>, MockError> {
        self.slots[slot.area.index()]
            .get_mut(slot.index)
            .ok_or(MockError::NoSuchSlot(slot))
    }

    /// Move every finished part whose row's output is free to the output.
    fn advance(&mut self, now_us: u64) {
        let slots = &mut self.slots;
        self.jobs.retain(|job| {
            let area = &mut slots[job.area.index()];
            let (input, output) = (2 * job.row, 2 * job.row + 1);
            if now_us < job.ready_at_us || area[output].is_some() {
                return true;
            }
            area[input] = None;
            area[output] = Some(job.new_color);
            false
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use PartColor::{Blue, Green, Red};
    use proptest::prelude::*;
    use ratf_core::referee::protocol::letters_to_string;

    const S: u64 = 1_000_000;

    fn slot(area: Area, index: usize) -> ServerSlot {
        ServerSlot { area, index }
    }

    fn mock(parts: [PartColor; 4], delay_us: u64, green_at_a: bool) -> MockReferee {
        MockReferee::new(MockSettings {
            incoming: parts.map(Some),
            machine_delay_us: delay_us,
            green_to_blue_at_a: green_at_a,
        })
    }

    fn text(m: &mut MockReferee, r: Request, now_us: u64) -> String {
        m.respond(r, now_us).to_text()
    }

    #[test]
    fn stop_before_the_start_pong_always_then_the_parts() {
        let mut m = mock([Blue, Green, Green, Red], 0, false);
        for r in Request::ALL {
            let want = if r == Request::Ping { "PONG" } else { "STOP" };
            assert_eq!(text(&mut m, r, 5 * S), want);
        }
        m.start(10 * S);
        assert_eq!(text(&mut m, Request::IncomingWarehouse, 10 * S), "BGGR");
        assert_eq!(text(&mut m, Request::OutgoingWarehouse, 10 * S), "XXXX");
        assert_eq!(text(&mut m, Request::MachineA, 10 * S), "XXXX");
        assert_eq!(text(&mut m, Request::Ping, 10 * S), "PONG");
        m.stop(20 * S);
        assert_eq!(text(&mut m, Request::IncomingWarehouse, 21 * S), "STOP");
    }

    #[test]
    fn the_clock_counts_down_from_600_s_and_stops_at_zero() {
        let mut m = mock([Blue; 4], 0, false);
        assert_eq!(m.time_left_s(0), 600);
        m.start(3 * S);
        assert_eq!(text(&mut m, Request::TimeLeft, 3 * S), "T600");
        assert_eq!(text(&mut m, Request::TimeLeft, 3 * S + 1), "T599");
        assert_eq!(text(&mut m, Request::TimeLeft, 71 * S), "T532");
        assert_eq!(text(&mut m, Request::TimeLeft, 700 * S), "T0");
        m.stop(800 * S);
        assert_eq!(m.time_left_s(900 * S), 0);
    }

    #[test]
    fn machines_turn_parts_after_the_delay_into_a_free_output() {
        let mut m = mock([Red, Green, Blue, Blue], 2 * S, false);
        m.start(0);
        let red = m.take(slot(Area::Incoming, 0), S).unwrap();
        assert_eq!(red, Red);
        m.place(slot(Area::MachineA, 0), red, 2 * S).unwrap();
        assert_eq!(letters_to_string(&m.letters(Area::MachineA, 3 * S)), "RXXX");
        assert_eq!(letters_to_string(&m.letters(Area::MachineA, 4 * S)), "XGXX");
        // A green at machine A is not turned unless allowed; B turns it.
        let green = m.take(slot(Area::Incoming, 1), 5 * S).unwrap();
        m.place(slot(Area::MachineA, 2), green, 5 * S).unwrap();
        assert_eq!(
            letters_to_string(&m.letters(Area::MachineA, 60 * S)),
            "XGGX"
        );
        let green = m.take(slot(Area::MachineA, 2), 61 * S).unwrap();
        m.place(slot(Area::MachineB, 2), green, 61 * S).unwrap();
        assert_eq!(
            letters_to_string(&m.letters(Area::MachineB, 63 * S)),
            "XXXB"
        );
    }

    #[test]
    fn a_finished_part_waits_for_its_output_to_be_emptied() {
        let mut m = mock([Green, Green, Blue, Blue], 0, true);
        m.start(0);
        let g1 = m.take(slot(Area::Incoming, 0), 0).unwrap();
        m.place(slot(Area::MachineA, 0), g1, 0).unwrap();
        assert_eq!(letters_to_string(&m.letters(Area::MachineA, 0)), "XBXX");
        let g2 = m.take(slot(Area::Incoming, 1), S).unwrap();
        m.place(slot(Area::MachineA, 0), g2, S).unwrap();
        assert_eq!(letters_to_string(&m.letters(Area::MachineA, 9 * S)), "GBXX");
        m.take(slot(Area::MachineA, 1), 10 * S).unwrap();
        assert_eq!(
            letters_to_string(&m.letters(Area::MachineA, 10 * S)),
            "XBXX"
        );
    }

    #[test]
    fn taking_a_part_off_an_input_cancels_its_processing() {
        let mut m = mock([Red, Blue, Blue, Blue], 5 * S, false);
        m.start(0);
        let red = m.take(slot(Area::Incoming, 0), 0).unwrap();
        m.place(slot(Area::MachineA, 2), red, 0).unwrap();
        assert_eq!(m.take(slot(Area::MachineA, 2), S), Ok(Red));
        assert_eq!(
            letters_to_string(&m.letters(Area::MachineA, 10 * S)),
            "XXXX"
        );
    }

    #[test]
    fn bad_notifications_are_errors_naming_the_slot() {
        let mut m = mock([Blue; 4], 0, false);
        let out = slot(Area::Outgoing, 0);
        assert_eq!(m.take(out, 0), Err(MockError::Empty(out)));
        let inc = slot(Area::Incoming, 3);
        assert_eq!(m.place(inc, Red, 0), Err(MockError::Occupied(inc)));
        let bad = slot(Area::MachineB, 4);
        let e = m.place(bad, Red, 0).unwrap_err();
        assert_eq!(e, MockError::NoSuchSlot(bad));
        assert!(e.to_string().contains("MachineB[4]"));
        assert_eq!(round_parts(4, 0), Err(MockError::NoSuchRound(4)));
    }

    #[test]
    fn server_slots_map_to_the_fields_waypoints() {
        let field = Field::competition();
        let expect = [
            (Area::Incoming, [50, 51, 52, 53]),
            (Area::Outgoing, [62, 63, 64, 65]),
            (Area::MachineA, [56, 57, 60, 61]),
            (Area::MachineB, [54, 55, 58, 59]),
        ];
        for (area, ids) in expect {
            for (index, id) in ids.into_iter().enumerate() {
                let s = slot(area, index);
                assert_eq!(s.waypoint(&field), Some(WaypointId(id)));
                assert_eq!(ServerSlot::of_waypoint(&field, WaypointId(id)), Some(s));
            }
        }
        assert_eq!(ServerSlot::of_waypoint(&field, WaypointId(13)), None);
    }

    fn sorted(parts: SlotLetters) -> String {
        let mut letters: Vec<char> = letters_to_string(&parts).chars().collect();
        letters.sort_unstable();
        letters.into_iter().collect()
    }

    proptest! {
        #[test]
        fn presets_are_permutations_of_the_rounds_multisets(seed in any::<u64>()) {
            prop_assert_eq!(sorted(round_parts(1, seed).unwrap()), "BBBB");
            prop_assert_eq!(sorted(round_parts(2, seed).unwrap()), "BBGG");
            prop_assert_eq!(sorted(round_parts(3, seed).unwrap()), "BGGR");
        }
    }

    #[test]
    fn presets_cover_every_permutation_over_seeds() {
        let round2: std::collections::HashSet<String> = (0..200)
            .map(|seed| letters_to_string(&round_parts(2, seed).unwrap()))
            .collect();
        let round3: std::collections::HashSet<String> = (0..400)
            .map(|seed| letters_to_string(&round_parts(3, seed).unwrap()))
            .collect();
        assert_eq!(round2.len(), 6, "{round2:?}");
        assert_eq!(round3.len(), 12, "{round3:?}");
    }
}
