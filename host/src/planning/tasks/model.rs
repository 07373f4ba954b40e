//! The task planner's world: places, travel times, the parts' state, and what one pick-and-
//! drop action does to it (with its timing).
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
    use crate::referee::protocol::parse_letters;
    use PartColor::{Blue, Green, Red};

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
