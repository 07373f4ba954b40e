//! The task planner's world: places, travel times, the parts' state, and what one pick-and-
//! drop action does to it (with its timing); and the state as the organisers' server shows
//! it, and corrected by it ([`State::to_server_areas`], [`State::reconcile`]).
//!
//! Timing of an action from robot location `L` at time `t` moving part `p` from `P` to `D`:
//! travel `T(L, P)`, wait until the part is ready (a machine's output appears after the
//! processing delay), pick (`pick_s`), travel `T(P, D)`, drop (`drop_s`). A part dropped on a
//! machine input that accepts it is booked straight onto that row's output with its new
//! colour, ready `machine_delay_s` after the drop (competition.md §2); a row can be loaded
//! only while its input and output are both empty (competition.md §6: "empty an output before
//! loading that row again"), so the booking never overtakes the physical part.

use std::fmt;

use super::travel::{Location, TravelMatrix, TravelTimes};
use crate::config::MagnetFace;
use crate::field::MachineKind;
use crate::field::PartColor;
use crate::referee::protocol::SlotLetters;

/// Most parts a state may hold (the field has four incoming slots; eight leaves room for a
/// confused server report without overflowing the search's 64-bit state key).
pub const MAX_PARTS: usize = 8;

/// Fixed durations of the robot's handling and the machines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// From docked at a part to holding it, s.
    pub pick_s: f64,
    /// From docked at a slot to the part released and the robot free, s.
    pub drop_s: f64,
    /// Machine processing time (planned with the expected value), s.
    pub machine_delay_s: f64,
}

/// Which machine may turn which colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rules {
    /// Whether machine A also turns green into blue (round 2: greens may use either
    /// machine; competition.md §2). Machine B always does, and A always turns red to green.
    pub green_at_a: bool,
}

impl Rules {
    /// The rules of round `round`: greens may use either machine in rounds 1 and 2, only
    /// machine B in round 3 (where the rules text sends intermediate parts to B).
    pub fn for_round(round: u8) -> Self {
        Self {
            green_at_a: round < 3,
        }
    }

    /// The colour machine `kind` turns `color` into, or `None` if it does not take it.
    pub fn transform(self, kind: MachineKind, color: PartColor) -> Option<PartColor> {
        match (kind, color) {
            (MachineKind::A, PartColor::Red) => Some(PartColor::Green),
            (MachineKind::A, PartColor::Green) if self.green_at_a => Some(PartColor::Blue),
            (MachineKind::B, PartColor::Green) => Some(PartColor::Blue),
            _ => None,
        }
    }
}

/// Where a part is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Place {
    /// Standing at a location.
    At(Location),
    /// Held by the robot.
    Carried,
}

/// One part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartState {
    /// Its colour now.
    pub color: PartColor,
    /// Its colour in the incoming warehouse (the original preset's priorities use it).
    pub initial: PartColor,
    /// Where it is.
    pub place: Place,
    /// When it can be picked, s (a machine's output appears after the processing delay).
    pub ready_s: f64,
}

impl PartState {
    /// Whether the part is finished: blue in the outgoing warehouse.
    pub fn is_done(&self) -> bool {
        self.color == PartColor::Blue && matches!(self.place, Place::At(Location::Outgoing(_)))
    }
}

/// What the planner knows at one instant.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Where the robot is (the last location it docked at, or the start).
    pub robot: Location,
    /// Now, s (the planner's clock, e.g. seconds since the part list arrived).
    pub time_s: f64,
    /// The parts, in incoming-slot order at the start (ties in the original's priorities
    /// go to the lower index).
    pub parts: Vec<PartState>,
}

impl State {
    /// The start of a round: one part per non-empty incoming slot, the robot at `robot`.
    pub fn from_incoming(incoming: &SlotLetters, robot: Location, time_s: f64) -> Self {
        let parts = incoming
            .iter()
            .enumerate()
            .filter_map(|(i, c)| {
                c.map(|color| PartState {
                    color,
                    initial: color,
                    place: Place::At(Location::Incoming(i)),
                    ready_s: time_s,
                })
            })
            .collect();
        Self {
            robot,
            time_s,
            parts,
        }
    }

    /// The state from the server's four strings (`IWP`, `OWP`, `MAP`, `MBP`), the robot
    /// at `robot` and not carrying. A part on a machine input that the machine turns is
    /// booked on the output, ready after a full `timing.machine_delay_s` from now
    /// (conservative: the server does not say when it was placed); its initial colour is
    /// taken as the colour before that machine, and the same for parts on outputs.
    pub fn from_server(
        areas: [SlotLetters; 4],
        robot: Location,
        time_s: f64,
        timing: Timing,
        rules: Rules,
    ) -> Self {
        let [incoming, outgoing, machine_a, machine_b] = areas;
        let mut state = Self::from_incoming(&incoming, robot, time_s);
        for (i, c) in outgoing.iter().enumerate() {
            if let Some(color) = *c {
                state.parts.push(PartState {
                    color,
                    initial: color,
                    place: Place::At(Location::Outgoing(i)),
                    ready_s: time_s,
                });
            }
        }
        for (kind, letters) in [(MachineKind::A, machine_a), (MachineKind::B, machine_b)] {
            for (index, c) in letters.iter().enumerate() {
                let Some(color) = *c else { continue };
                let row = index / 2;
                let part = if index % 2 == 1 {
                    PartState {
                        color,
                        initial: before(kind, color),
                        place: Place::At(Location::MachineOutput(kind, row)),
                        ready_s: time_s,
                    }
                } else if let Some(new_color) = rules.transform(kind, color) {
                    PartState {
                        color: new_color,
                        initial: color,
                        place: Place::At(Location::MachineOutput(kind, row)),
                        ready_s: time_s + timing.machine_delay_s,
                    }
                } else {
                    PartState {
                        color,
                        initial: color,
                        place: Place::At(Location::MachineInput(kind, row)),
                        ready_s: time_s,
                    }
                };
                state.parts.push(part);
            }
        }
        state
    }

    /// What the organisers' server would answer for this state: the four strings (`IWP`,
    /// `OWP`, `MAP`, `MBP`) of every part standing at a slot. A part booked on a machine's
    /// output that is not ready at `time_s`, or is queued behind another one there, is shown
    /// on the row's input with its colour before the machine, as the server shows a part
    /// being processed. Carried parts are not shown; a second part on one slot is left out.
    pub fn to_server_areas(&self) -> [SlotLetters; 4] {
        let mut areas: [SlotLetters; 4] = [[None; 4]; 4];
        // The first ready part of a row takes its output.
        let mut order: Vec<usize> = (0..self.parts.len()).collect();
        order.sort_by(|&a, &b| {
            let (pa, pb) = (&self.parts[a], &self.parts[b]);
            pa.ready_s.total_cmp(&pb.ready_s).then(a.cmp(&b))
        });
        for i in order {
            let p = self.parts[i];
            let Place::At(location) = p.place else {
                continue;
            };
            let (area, index, color) = match location {
                Location::Start => continue,
                Location::Incoming(slot) => (0, slot, p.color),
                Location::Outgoing(slot) => (1, slot, p.color),
                Location::MachineInput(kind, row) => (machine_area(kind), 2 * row, p.color),
                Location::MachineOutput(kind, row) => {
                    let area = machine_area(kind);
                    let output_free = areas[area].get(2 * row + 1) == Some(&None);
                    if p.ready_s <= self.time_s && output_free {
                        (area, 2 * row + 1, p.color)
                    } else {
                        (area, 2 * row, before(kind, p.color))
                    }
                }
            };
            if let Some(cell) = areas[area].get_mut(index) {
                cell.get_or_insert(color);
            }
        }
        areas
    }

    /// This state corrected by `server`, the server's view (e.g. [`State::from_server`]),
    /// and how many parts disagreed.
    ///
    /// The server is the truth for where the parts stand and their colours
    /// (competition.md §6: "server strings are the ground truth"); we know better when a
    /// machine finishes and what a part was at the start. So a part of ours that the server
    /// shows at the same place with the same colour is kept, `initial` and `ready_s` included
    /// (`ready_s` is only brought forward to the server's when the server has the part ready,
    /// i.e. `ready_s <= server.time_s`, as `from_server` marks a part seen on an output); our
    /// other parts are dropped, the server's other parts are added after ours. Carried parts
    /// (the server cannot see them), `robot` and `time_s` are kept from `self`.
    ///
    /// The count is the larger of parts dropped and parts added: a part that vanished or
    /// appeared counts once, and so does one that moved or changed colour.
    pub fn reconcile(&self, server: &State) -> (State, usize) {
        let mut matched = vec![false; server.parts.len()];
        let mut kept: Vec<Option<PartState>> = vec![None; self.parts.len()];
        // Ours in the order they become ready meet the server's in the same order, so a
        // queue on a machine output pairs its first part with the one the server has ready.
        let mut order: Vec<usize> = (0..self.parts.len()).collect();
        order.sort_by(|&a, &b| {
            let (pa, pb) = (&self.parts[a], &self.parts[b]);
            pa.ready_s.total_cmp(&pb.ready_s).then(a.cmp(&b))
        });
        for i in order {
            let ours = self.parts[i];
            if ours.place == Place::Carried {
                kept[i] = Some(ours);
                continue;
            }
            let candidate = server
                .parts
                .iter()
                .enumerate()
                .filter(|&(j, s)| !matched[j] && s.place == ours.place && s.color == ours.color)
                .min_by(|(_, a), (_, b)| a.ready_s.total_cmp(&b.ready_s));
            if let Some((j, theirs)) = candidate {
                matched[j] = true;
                let mut part = ours;
                if theirs.ready_s <= server.time_s {
                    part.ready_s = part.ready_s.min(theirs.ready_s);
                }
                kept[i] = Some(part);
            }
        }
        let vanished = kept.iter().filter(|p| p.is_none()).count();
        let mut parts: Vec<PartState> = kept.into_iter().flatten().collect();
        let before_added = parts.len();
        parts.extend(
            server
                .parts
                .iter()
                .zip(&matched)
                .filter(|&(p, &m)| !m && p.place != Place::Carried)
                .map(|(p, _)| *p),
        );
        let appeared = parts.len() - before_added;
        let state = State {
            robot: self.robot,
            time_s: self.time_s,
            parts,
        };
        (state, vanished.max(appeared))
    }

    /// Whether every part is finished (full score).
    pub fn is_complete(&self) -> bool {
        self.parts.iter().all(PartState::is_done)
    }

    /// The part the robot holds, if any.
    pub fn carried(&self) -> Option<usize> {
        self.parts.iter().position(|p| p.place == Place::Carried)
    }

    /// Whether a part other than `except` stands at `location`.
    pub fn occupied(&self, location: Location, except: usize) -> bool {
        self.parts
            .iter()
            .enumerate()
            .any(|(i, p)| i != except && p.place == Place::At(location))
    }

    /// Whether part `part` can be picked now (not finished, not carried, and first in line
    /// at a machine output where a second finished part is queued behind it).
    pub fn pickable(&self, part: usize) -> bool {
        let Some(p) = self.parts.get(part) else {
            return false;
        };
        let Place::At(location) = p.place else {
            return false;
        };
        if p.is_done() || location == Location::Start {
            return false;
        }
        let first_in_line =
            self.parts.iter().enumerate().all(|(i, q)| {
                i == part || q.place != p.place || (q.ready_s, i) > (p.ready_s, part)
            });
        !matches!(location, Location::MachineOutput(..)) || first_in_line
    }

    /// Whether `to` is a useful drop for part `part`, given `rules`.
    pub fn can_drop(&self, part: usize, to: Location, rules: Rules) -> bool {
        let Some(p) = self.parts.get(part) else {
            return false;
        };
        match to {
            Location::Outgoing(i) => {
                i < 4 && p.color == PartColor::Blue && !self.occupied(to, part)
            }
            Location::MachineInput(kind, row) => {
                row < 2
                    && rules.transform(kind, p.color).is_some()
                    && !self.occupied(to, part)
                    && !self.occupied(Location::MachineOutput(kind, row), part)
            }
            _ => false,
        }
    }
}

/// The index of machine `kind`'s strings in [`State::to_server_areas`] (`MAP`, `MBP`).
pub(crate) fn machine_area(kind: MachineKind) -> usize {
    match kind {
        MachineKind::A => 2,
        MachineKind::B => 3,
    }
}

/// The colour a part on machine `kind`'s output had before it (for the original preset's
/// priorities; a blue part on A's output came from a green in round 2).
fn before(kind: MachineKind, color: PartColor) -> PartColor {
    match (kind, color) {
        (MachineKind::A, PartColor::Green) => PartColor::Red,
        (_, PartColor::Blue) => PartColor::Green,
        (_, other) => other,
    }
}

/// Move one part to one place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Action {
    /// Index of the part in [`State::parts`].
    pub part: usize,
    /// Where it is picked ([`Place::Carried`] if the robot already holds it).
    pub from: Place,
    /// Where it is dropped.
    pub to: Location,
}

impl fmt::Display for Action {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.from {
            Place::At(from) => write!(f, "part {}: {from} -> {}", self.part, self.to),
            Place::Carried => write!(f, "part {}: (carried) -> {}", self.part, self.to),
        }
    }
}

/// An action with its estimated times.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimedAction {
    /// The action.
    pub action: Action,
    /// When the pick begins (after travel and any wait for the machine), s; `None` if the
    /// part was already carried.
    pub pick_start_s: Option<f64>,
    /// When the drop is done and the robot free, s.
    pub done_s: f64,
}

/// Why a state or action was refused, or no plan exists.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TaskError {
    /// More parts than the planner handles.
    #[error("{0} parts: the planner handles at most {MAX_PARTS}")]
    TooManyParts(usize),
    /// A travel time is negative, not finite, or a location is out of range.
    #[error("travel times must be finite and >= 0 s between every pair of locations")]
    BadTravelTimes,
    /// A timing value is negative or not finite.
    #[error("pick, drop and machine times must be finite and >= 0 s")]
    BadTiming,
    /// The action cannot be done in this state.
    #[error("cannot do {action}: {reason}")]
    InvalidAction {
        /// The action.
        action: Action,
        /// Why, in words.
        reason: &'static str,
    },
    /// No sequence of actions finishes every part (e.g. no free outgoing slot).
    #[error("no sequence of actions finishes every part from this state")]
    NoPlan,
    /// The robot's magnets are not the one on the front face that the planner's actions
    /// (one part carried from its pick to its drop) and the mission drive.
    #[error(
        "robot.magnet_faces = {listed}: the task planner and the mission carry one part, on \
         the front magnet (robot.magnet_faces = [\"front\"]); `ratf bench bound` plans for other \
         faces",
        listed = MagnetFace::list(.0)
    )]
    MagnetFaces(Vec<MagnetFace>),
}

/// The magnet faces the task planner's actions carry a part on: one part at a time, on the
/// front face (each [`Action`] takes one part from its pick to its drop).
pub const PLANNED_MAGNET_FACES: [MagnetFace; 1] = [MagnetFace::Front];

/// `Ok` when the robot's `faces` are the ones the planner plans for
/// ([`PLANNED_MAGNET_FACES`]).
pub fn check_magnet_faces(faces: &[MagnetFace]) -> Result<(), TaskError> {
    if faces == PLANNED_MAGNET_FACES {
        Ok(())
    } else {
        Err(TaskError::MagnetFaces(faces.to_vec()))
    }
}

/// The planner's fixed inputs: travel times, durations, rules.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// Travel times, s.
    pub travel: TravelMatrix,
    /// Handling and machine durations.
    pub timing: Timing,
    /// Machine rules.
    pub rules: Rules,
}

impl Model {
    /// A model from any travel-time source (tabulated once).
    pub fn new(
        times: &(impl TravelTimes + ?Sized),
        timing: Timing,
        rules: Rules,
    ) -> Result<Self, TaskError> {
        let model = Self {
            travel: TravelMatrix::from_times(times),
            timing,
            rules,
        };
        model.check()?;
        Ok(model)
    }

    /// Refuse non-finite or negative numbers.
    pub fn check(&self) -> Result<(), TaskError> {
        if !self.travel.is_valid() {
            return Err(TaskError::BadTravelTimes);
        }
        let t = self.timing;
        let ok = [t.pick_s, t.drop_s, t.machine_delay_s]
            .iter()
            .all(|s| s.is_finite() && *s >= 0.0);
        if ok {
            Ok(())
        } else {
            Err(TaskError::BadTiming)
        }
    }

    fn seconds(&self, from: Location, to: Location) -> f64 {
        match (from.index(), to.index()) {
            (Some(i), Some(j)) => self.travel.between(i, j),
            _ => f64::INFINITY,
        }
    }

    /// Do `action` in `state`: the new state and the action's times.
    pub fn apply(&self, state: &State, action: Action) -> Result<(State, TimedAction), TaskError> {
        let invalid = |reason| TaskError::InvalidAction { action, reason };
        let part = state
            .parts
            .get(action.part)
            .ok_or_else(|| invalid("no such part"))?;
        if part.place != action.from {
            return Err(invalid("the part is not there"));
        }
        let carried = state.carried();
        let (mut t, pick_start_s, from) = match action.from {
            Place::Carried => (state.time_s, None, state.robot),
            Place::At(from) => {
                if carried.is_some() {
                    return Err(invalid("the robot already holds a part"));
                }
                if !state.pickable(action.part) {
                    return Err(invalid("the part cannot be picked now"));
                }
                let start = (state.time_s + self.seconds(state.robot, from)).max(part.ready_s);
                (start + self.timing.pick_s, Some(start), from)
            }
        };
        if !state.can_drop(action.part, action.to, self.rules) {
            return Err(invalid("the destination does not take this part now"));
        }
        t += self.seconds(from, action.to) + self.timing.drop_s;
        let mut next = state.clone();
        let moved = &mut next.parts[action.part];
        match action.to {
            Location::MachineInput(kind, row) => {
                // Checked by can_drop: the machine takes this colour.
                moved.color = self
                    .rules
                    .transform(kind, moved.color)
                    .unwrap_or(moved.color);
                moved.place = Place::At(Location::MachineOutput(kind, row));
                moved.ready_s = t + self.timing.machine_delay_s;
            }
            to => {
                moved.place = Place::At(to);
                moved.ready_s = t;
            }
        }
        next.robot = action.to;
        next.time_s = t;
        let timed = TimedAction {
            action,
            pick_start_s,
            done_s: t,
        };
        Ok((next, timed))
    }

    /// Every valid action in `state` (drops of the carried part if the robot holds one).
    pub fn actions(&self, state: &State) -> Vec<Action> {
        let parts: Vec<usize> = match state.carried() {
            Some(p) => vec![p],
            None => (0..state.parts.len())
                .filter(|&p| state.pickable(p))
                .collect(),
        };
        let mut actions = Vec::new();
        for p in parts {
            for &to in &Location::ALL {
                if state.can_drop(p, to, self.rules) {
                    actions.push(Action {
                        part: p,
                        from: state.parts[p].place,
                        to,
                    });
                }
            }
        }
        actions
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::tasks::travel::LOCATION_COUNT;
    use crate::referee::protocol::{letters_to_string, parse_letters};
    use PartColor::{Blue, Green, Red};
    use proptest::prelude::*;

    /// Travel 2 s between any two different locations.
    struct Flat;

    impl TravelTimes for Flat {
        fn travel_s(&self, from: Location, to: Location) -> f64 {
            if from == to { 0.0 } else { 2.0 }
        }
    }

    fn model(delay_s: f64, green_at_a: bool) -> Model {
        let timing = Timing {
            pick_s: 1.0,
            drop_s: 0.5,
            machine_delay_s: delay_s,
        };
        Model::new(&Flat, timing, Rules { green_at_a }).unwrap()
    }

    fn state(letters: &str) -> State {
        State::from_incoming(&parse_letters(letters).unwrap(), Location::Start, 0.0)
    }

    fn act(part: usize, from: Location, to: Location) -> Action {
        Action {
            part,
            from: Place::At(from),
            to,
        }
    }

    #[test]
    fn an_action_costs_travel_pick_travel_drop_and_a_machine_output_waits_for_the_delay() {
        let m = model(10.0, false);
        let s = state("RXXX");
        let (s1, t1) = m
            .apply(
                &s,
                act(
                    0,
                    Location::Incoming(0),
                    Location::MachineInput(MachineKind::A, 1),
                ),
            )
            .unwrap();
        assert_eq!(t1.pick_start_s, Some(2.0));
        assert_eq!(t1.done_s, 2.0 + 1.0 + 2.0 + 0.5);
        let p = s1.parts[0];
        assert_eq!((p.color, p.ready_s), (Green, 15.5));
        assert_eq!(
            p.place,
            Place::At(Location::MachineOutput(MachineKind::A, 1))
        );
        assert_eq!(s1.robot, Location::MachineInput(MachineKind::A, 1));
        let (s2, t2) = m
            .apply(
                &s1,
                act(
                    0,
                    Location::MachineOutput(MachineKind::A, 1),
                    Location::MachineInput(MachineKind::B, 0),
                ),
            )
            .unwrap();
        assert_eq!(
            t2.pick_start_s,
            Some(15.5),
            "arrives at 7.5, waits for the machine"
        );
        assert_eq!(s2.time_s, 15.5 + 1.0 + 2.0 + 0.5);
        assert_eq!(s2.parts[0].color, Blue);
    }

    #[test]
    fn invalid_actions_are_refused_with_a_reason() {
        let m = model(0.0, false);
        let s = state("GBXX");
        let bad = [
            act(0, Location::Incoming(0), Location::Outgoing(0)),
            act(
                0,
                Location::Incoming(0),
                Location::MachineInput(MachineKind::A, 0),
            ),
            act(1, Location::Incoming(0), Location::Outgoing(0)),
            act(5, Location::Incoming(0), Location::Outgoing(0)),
            act(1, Location::Incoming(1), Location::Incoming(2)),
        ];
        for a in bad {
            let e = m.apply(&s, a).unwrap_err();
            assert!(matches!(e, TaskError::InvalidAction { .. }), "{a}: {e}");
        }
        let (s1, _) = m
            .apply(&s, act(1, Location::Incoming(1), Location::Outgoing(0)))
            .unwrap();
        let e = m.apply(&s1, act(0, Location::Incoming(0), Location::Outgoing(0)));
        assert!(e.is_err(), "a green cannot go out");
        let mut holding = s1.clone();
        holding.parts[0].place = Place::Carried;
        let e = m.apply(
            &holding,
            act(1, Location::Outgoing(0), Location::Outgoing(1)),
        );
        assert!(e.is_err());
        assert_eq!(
            m.actions(&holding).len(),
            2,
            "only the carried part, to B's two rows"
        );
    }

    #[test]
    fn a_row_is_loaded_only_when_its_input_and_output_are_empty() {
        let m = model(0.0, true);
        let s = state("GGXX");
        let row = Location::MachineInput(MachineKind::A, 0);
        let (s1, _) = m.apply(&s, act(0, Location::Incoming(0), row)).unwrap();
        assert!(!s1.can_drop(1, row, m.rules), "output still holds part 0");
        assert!(s1.can_drop(1, Location::MachineInput(MachineKind::A, 1), m.rules));
    }

    #[test]
    fn server_strings_become_a_state_with_machine_work_booked() {
        let timing = Timing {
            pick_s: 1.0,
            drop_s: 0.5,
            machine_delay_s: 6.0,
        };
        let l = |t: &str| parse_letters(t).unwrap();
        let s = State::from_server(
            [l("BXXX"), l("XBXX"), l("RXXG"), l("XBBX")],
            Location::Outgoing(1),
            30.0,
            timing,
            Rules::for_round(3),
        );
        assert_eq!(s.parts.len(), 6);
        let find = |loc: Location| {
            s.parts
                .iter()
                .filter(|p| p.place == Place::At(loc))
                .copied()
                .collect::<Vec<_>>()
        };
        let a0 = find(Location::MachineOutput(MachineKind::A, 0));
        assert_eq!(a0.len(), 1);
        assert_eq!(
            (a0[0].color, a0[0].initial, a0[0].ready_s),
            (Green, Red, 36.0)
        );
        let a1 = find(Location::MachineOutput(MachineKind::A, 1));
        assert_eq!((a1[0].color, a1[0].initial), (Green, Red));
        let b0 = find(Location::MachineOutput(MachineKind::B, 0));
        assert_eq!(
            (b0[0].color, b0[0].initial, b0[0].ready_s),
            (Blue, Green, 30.0)
        );
        // A blue on B's lower input is not processed: it stays there, pickable.
        let b1 = find(Location::MachineInput(MachineKind::B, 1));
        assert_eq!(b1[0].color, Blue);
        let index = s.parts.iter().position(|p| p.place == b1[0].place).unwrap();
        assert!(s.pickable(index));
        assert!(!s.is_complete());
    }

    /// `state` as the server would show it, read back with `from_server` at the state's time.
    fn seen_by_server(m: &Model, state: &State) -> State {
        State::from_server(
            state.to_server_areas(),
            Location::Start,
            state.time_s,
            m.timing,
            m.rules,
        )
    }

    /// Round 3 after two moves: the red on machine A (ready at 15.5 s), the blue out.
    fn round_3_midway(m: &Model) -> State {
        let s = state("RGGB");
        let (s, _) = m
            .apply(
                &s,
                act(
                    0,
                    Location::Incoming(0),
                    Location::MachineInput(MachineKind::A, 0),
                ),
            )
            .unwrap();
        let (s, _) = m
            .apply(&s, act(3, Location::Incoming(3), Location::Outgoing(1)))
            .unwrap();
        s
    }

    #[test]
    fn the_server_view_of_a_state_shows_work_in_progress_on_the_input() {
        let m = model(10.0, false);
        let mut s = round_3_midway(&m);
        let text = |s: &State| s.to_server_areas().map(|a| letters_to_string(&a)).join(" ");
        assert_eq!(s.time_s, 11.0);
        assert_eq!(text(&s), "XGGX XBXX RXXX XXXX");
        s.time_s = 15.5;
        assert_eq!(text(&s), "XGGX XBXX XGXX XXXX");
    }

    #[test]
    fn a_server_that_agrees_changes_nothing() {
        let m = model(10.0, false);
        let mut s = round_3_midway(&m);
        for time_s in [11.0, 15.5, 40.0] {
            s.time_s = time_s;
            let (reconciled, disagreements) = s.reconcile(&seen_by_server(&m, &s));
            assert_eq!((reconciled, disagreements), (s.clone(), 0), "at {time_s} s");
        }
    }

    #[test]
    fn a_vanished_part_is_dropped_from_the_plan() {
        let m = model(0.0, false);
        let s = state("BBBB");
        let mut areas = s.to_server_areas();
        areas[0][2] = None;
        let server = State::from_server(areas, Location::Start, 0.0, m.timing, m.rules);
        let (reconciled, disagreements) = s.reconcile(&server);
        assert_eq!(disagreements, 1);
        let places: Vec<Place> = reconciled.parts.iter().map(|p| p.place).collect();
        let incoming = |i| Place::At(Location::Incoming(i));
        assert_eq!(places, [incoming(0), incoming(1), incoming(3)]);
        assert!(m.actions(&reconciled).iter().all(|a| a.from != incoming(2)));
    }

    #[test]
    fn an_unexpected_part_appears_with_its_machine_work_booked() {
        let m = model(6.0, false);
        let mut s = state("BXXX");
        s.time_s = 20.0;
        let mut areas = s.to_server_areas();
        areas[3][2] = Some(Green);
        let server = State::from_server(areas, Location::Start, 20.0, m.timing, m.rules);
        let (reconciled, disagreements) = s.reconcile(&server);
        assert_eq!(disagreements, 1);
        assert_eq!(reconciled.parts[0], s.parts[0]);
        let new = reconciled.parts[1];
        assert_eq!(
            (new.color, new.initial, new.place, new.ready_s),
            (
                Blue,
                Green,
                Place::At(Location::MachineOutput(MachineKind::B, 1)),
                26.0
            )
        );
    }

    #[test]
    fn a_moved_or_recoloured_part_counts_once() {
        let m = model(0.0, false);
        let s = state("BGXX");
        let l = |t: &str| parse_letters(t).unwrap();
        let none = l("XXXX");
        for (incoming, want) in [("BXGX", 1), ("BBXX", 1), ("XXGB", 2), ("BGXX", 0)] {
            let server = State::from_server(
                [l(incoming), none, none, none],
                Location::Start,
                0.0,
                m.timing,
                m.rules,
            );
            assert_eq!(s.reconcile(&server).1, want, "{incoming}");
        }
    }

    #[test]
    fn a_part_the_machine_is_turning_keeps_our_ready_time_until_the_server_shows_it_done() {
        let m = model(10.0, false);
        let mut s = round_3_midway(&m);
        let red = 0;
        assert_eq!(s.parts[red].ready_s, 15.5);
        // At 12 s the server still has the red on A's input: it books it ready at 22 s, but
        // we know when it went in.
        s.time_s = 12.0;
        let mut server = seen_by_server(&m, &s);
        server.robot = Location::Outgoing(3);
        let (reconciled, disagreements) = s.reconcile(&server);
        assert_eq!(disagreements, 0);
        assert_eq!(reconciled.parts[red].ready_s, 15.5);
        assert_eq!(reconciled.parts[red].initial, Red);
        assert_eq!(reconciled.robot, s.robot);
        // At 14 s the machine was faster than we planned: the green is out, ready now.
        let mut areas = s.to_server_areas();
        areas[2] = parse_letters("XGXX").unwrap();
        let server = State::from_server(areas, Location::Start, 14.0, m.timing, m.rules);
        let (reconciled, disagreements) = s.reconcile(&server);
        assert_eq!(disagreements, 0);
        assert_eq!(reconciled.parts[red].ready_s, 14.0);
        assert_eq!(reconciled.time_s, 12.0, "the time stays ours");
    }

    #[test]
    fn a_carried_part_is_kept_though_the_server_cannot_see_it() {
        let m = model(0.0, false);
        let mut s = state("BBXX");
        s.parts[1].place = Place::Carried;
        let (reconciled, disagreements) = s.reconcile(&seen_by_server(&m, &s));
        assert_eq!((reconciled, disagreements), (s, 0));
    }

    proptest! {
        #[test]
        fn any_reachable_state_reconciled_with_its_own_server_view_is_unchanged(
            letters in prop::array::uniform4(prop::option::of(prop_oneof![
                Just(Red),
                Just(Green),
                Just(Blue)
            ])),
            moves in prop::collection::vec((any::<prop::sample::Index>(), 0.0..30.0f64), 0..9),
            delay_s in 0.0..20.0f64,
            green_at_a in any::<bool>(),
        ) {
            let m = model(delay_s, green_at_a);
            let mut s = State::from_incoming(&letters, Location::Start, 0.0);
            for (choice, wait_s) in moves {
                let actions = m.actions(&s);
                if actions.is_empty() {
                    break;
                }
                s = m.apply(&s, actions[choice.index(actions.len())]).unwrap().0;
                s.time_s += wait_s;
            }
            prop_assert_eq!(s.reconcile(&seen_by_server(&m, &s)), (s.clone(), 0));
        }
    }

    #[test]
    fn a_part_queued_behind_a_full_output_is_picked_second() {
        let m = model(0.0, false);
        let out = Location::MachineOutput(MachineKind::B, 0);
        let mut s = state("XXXX");
        for (ready_s, color) in [(5.0, Blue), (1.0, Blue)] {
            s.parts.push(PartState {
                color,
                initial: Green,
                place: Place::At(out),
                ready_s,
            });
        }
        assert!(!s.pickable(0) && s.pickable(1));
        let (s1, _) = m.apply(&s, act(1, out, Location::Outgoing(0))).unwrap();
        assert!(s1.pickable(0));
    }

    #[test]
    fn bad_numbers_are_refused() {
        let timing = Timing {
            pick_s: f64::NAN,
            drop_s: 0.5,
            machine_delay_s: 0.0,
        };
        assert_eq!(
            Model::new(&Flat, timing, Rules::for_round(3)),
            Err(TaskError::BadTiming)
        );
        let mut table = [[1.0; LOCATION_COUNT]; LOCATION_COUNT];
        table[3][4] = -1.0;
        let m = Model {
            travel: TravelMatrix::from_table(table),
            timing: Timing {
                pick_s: 1.0,
                ..timing
            },
            rules: Rules::for_round(3),
        };
        assert_eq!(m.check(), Err(TaskError::BadTravelTimes));
    }
}
