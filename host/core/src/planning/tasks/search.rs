//! The "ours" policy: depth-first branch and bound over pick-and-drop sequences, minimising
//! the time of the last drop that completes every part.
//!
//! Pruning (all exact, so the result is optimal unless the node limit stops the search):
//! * a lower bound on the finish time (below) no better than the best plan found;
//! * dominance: a state with the same robot location and the same parts' places and colours
//!   as one already explored, reached no earlier and with no part ready earlier, cannot do
//!   better than that one did.
//!
//! Lower bound: the larger of (1) now + the robot's remaining busy time: each remaining leg's
//! shortest carry plus its pick and drop, plus the shortest empty trip into each pick (from a
//! drop location, or from where the robot is for its next pick) — the robot carries one part
//! at a time, so none of these overlap; and (2) for each part alone, when
//! it can first be picked (the robot's shortest route to it, by way of any other places since
//! travel times need not obey the triangle inequality, or its machine's ready time) + its
//! remaining legs + between its legs the longer of the machine delay and the robot's shortest
//! return to the machine's output.
//! Children are tried earliest-finishing action first, so the first dive is the greedy plan.

use std::collections::HashMap;

use super::model::{Action, MAX_PARTS, Model, Place, State, TaskError, TimedAction};
use super::travel::{LOCATION_COUNT, Location};
use super::{Plan, Policy};
use crate::field::MachineKind;
use crate::field::PartColor;

/// Finish times closer than this are equal, s.
const EPS_S: f64 = 1e-9;

/// The branch-and-bound planner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BranchAndBound {
    /// Stop after expanding this many states and return the best plan found (then marked
    /// not proven optimal).
    pub max_nodes: u64,
}

impl Default for BranchAndBound {
    /// 1 000 000 nodes: far above what round 3 needs (see the planner bench test).
    fn default() -> Self {
        Self {
            max_nodes: 1_000_000,
        }
    }
}

impl Policy for BranchAndBound {
    fn name(&self) -> &'static str {
        "ours"
    }

    fn plan(&self, model: &Model, state: &State) -> Result<Plan, TaskError> {
        model.check()?;
        if state.parts.len() > MAX_PARTS {
            return Err(TaskError::TooManyParts(state.parts.len()));
        }
        let mut search = Search {
            model,
            bound: Bound::new(model),
            best_s: f64::INFINITY,
            best: None,
            path: Vec::new(),
            nodes: 0,
            max_nodes: self.max_nodes,
            truncated: false,
            seen: HashMap::new(),
        };
        search.dfs(state);
        let steps = search.best.ok_or(TaskError::NoPlan)?;
        Ok(Plan {
            finish_s: search.best_s,
            steps,
            optimal: !search.truncated,
            nodes: search.nodes,
        })
    }
}

/// Destination classes for the bound.
const OUTGOING: usize = 0;
const INPUT_A: usize = 1;
const GREEN_INPUTS: usize = 2;

/// Precomputed shortest legs.
struct Bound {
    /// Shortest travel from each location to any location of each class, s.
    to_class: [[f64; 3]; LOCATION_COUNT],
    /// Shortest route between locations through any others (the travel table need not obey
    /// the triangle inequality, and the robot may reach a part by way of other actions), s.
    route: [[f64; LOCATION_COUNT]; LOCATION_COUNT],
    /// Shortest empty trip into each location from a place where the robot drops parts
    /// (machine inputs, outgoing slots): every pick but the robot's next one follows a drop.
    arrive: [f64; LOCATION_COUNT],
    /// Shortest travel from an A output to a machine that takes greens, s.
    a_out_to_green: f64,
    /// Shortest travel from an output of a machine that takes greens to the outgoing
    /// warehouse, s.
    green_out_to_outgoing: f64,
    /// Shortest empty trip into an A output, s.
    arrive_a_out: f64,
    /// Shortest empty trip into the output of a machine that takes greens, s.
    arrive_green_out: f64,
    pick_s: f64,
    drop_s: f64,
    delay_s: f64,
}

/// What a part still needs, at least.
struct Remaining {
    /// Carry travel of every leg left, s.
    carry_s: f64,
    /// Empty trips into the picks of its later legs (at machine outputs), s.
    later_arrivals_s: f64,
    /// Between its drop on a machine and its pick there: the delay and the robot's return, s.
    gaps_s: f64,
    /// Legs left.
    legs: usize,
}

impl Bound {
    fn new(model: &Model) -> Self {
        let green_kinds: &'static [MachineKind] = if model.rules.green_at_a {
            &[MachineKind::A, MachineKind::B]
        } else {
            &[MachineKind::B]
        };
        let in_class = |l: Location, class: usize| match (class, l) {
            (OUTGOING, Location::Outgoing(_)) => true,
            (INPUT_A, Location::MachineInput(MachineKind::A, _)) => true,
            (GREEN_INPUTS, Location::MachineInput(k, _)) => green_kinds.contains(&k),
            _ => false,
        };
        let t = |i: usize, j: usize| model.travel.between(i, j);
        let mut to_class = [[f64::INFINITY; 3]; LOCATION_COUNT];
        for (i, row) in to_class.iter_mut().enumerate() {
            for (class, best) in row.iter_mut().enumerate() {
                for (j, &l) in Location::ALL.iter().enumerate() {
                    if in_class(l, class) {
                        *best = best.min(t(i, j));
                    }
                }
            }
        }
        let is_drop =
            |l: &Location| matches!(l, Location::Outgoing(_) | Location::MachineInput(..));
        let mut arrive = [f64::INFINITY; LOCATION_COUNT];
        for (j, best) in arrive.iter_mut().enumerate() {
            for (i, l) in Location::ALL.iter().enumerate() {
                if is_drop(l) && i != j {
                    *best = best.min(t(i, j));
                }
            }
        }
        let outputs = |kinds: &'static [MachineKind]| {
            Location::ALL
                .iter()
                .filter(move |l| matches!(l, Location::MachineOutput(k, _) if kinds.contains(k)))
                .filter_map(|l| l.index())
        };
        let min = |it: &mut dyn Iterator<Item = f64>| it.fold(f64::INFINITY, f64::min);
        let mut route = [[0.0; LOCATION_COUNT]; LOCATION_COUNT];
        for (i, row) in route.iter_mut().enumerate() {
            for (j, s) in row.iter_mut().enumerate() {
                *s = t(i, j);
            }
        }
        for k in 0..LOCATION_COUNT {
            for i in 0..LOCATION_COUNT {
                for j in 0..LOCATION_COUNT {
                    route[i][j] = route[i][j].min(route[i][k] + route[k][j]);
                }
            }
        }
        Self {
            a_out_to_green: min(&mut outputs(&[MachineKind::A]).map(|i| to_class[i][GREEN_INPUTS])),
            green_out_to_outgoing: min(&mut outputs(green_kinds).map(|i| to_class[i][OUTGOING])),
            arrive_a_out: min(&mut outputs(&[MachineKind::A]).map(|i| arrive[i])),
            arrive_green_out: min(&mut outputs(green_kinds).map(|i| arrive[i])),
            route,
            arrive,
            to_class,
            pick_s: model.timing.pick_s,
            drop_s: model.timing.drop_s,
            delay_s: model.timing.machine_delay_s,
        }
    }

    /// What a part of `color` at location index `at` still needs.
    fn remaining(&self, color: PartColor, at: usize) -> Remaining {
        let row = self.to_class[at];
        let gap = |arrive: f64| arrive.max(self.delay_s);
        match color {
            PartColor::Blue => Remaining {
                carry_s: row[OUTGOING],
                later_arrivals_s: 0.0,
                gaps_s: 0.0,
                legs: 1,
            },
            PartColor::Green => Remaining {
                carry_s: row[GREEN_INPUTS] + self.green_out_to_outgoing,
                later_arrivals_s: self.arrive_green_out,
                gaps_s: gap(self.arrive_green_out),
                legs: 2,
            },
            PartColor::Red => Remaining {
                carry_s: row[INPUT_A] + self.a_out_to_green + self.green_out_to_outgoing,
                later_arrivals_s: self.arrive_a_out + self.arrive_green_out,
                gaps_s: gap(self.arrive_a_out) + gap(self.arrive_green_out),
                legs: 3,
            },
        }
    }

    /// A lower bound on the finish time from `state`.
    fn finish_s(&self, model: &Model, state: &State) -> f64 {
        let robot = state.robot.index().unwrap_or(0);
        let carrying = state.carried().is_some();
        // Robot busy time: carries, handling and empty trips, the robot's next trip being
        // from where it is rather than from a drop.
        let mut busy_s = 0.0;
        let mut next_trip_adjust_s = if carrying { 0.0 } else { f64::INFINITY };
        let mut longest_chain_s = state.time_s;
        for part in state.parts.iter().filter(|p| !p.is_done()) {
            let (at, start_s, picks) = match part.place {
                Place::Carried => (robot, state.time_s, 0.0),
                Place::At(l) => {
                    let at = l.index().unwrap_or(0);
                    busy_s += self.arrive[at];
                    next_trip_adjust_s = f64::min(
                        next_trip_adjust_s,
                        model.travel.between(robot, at) - self.arrive[at],
                    );
                    let reach_s = state.time_s + self.route[robot][at];
                    (at, reach_s.max(part.ready_s), 1.0)
                }
            };
            let rest = self.remaining(part.color, at);
            let legs = rest.legs as f64;
            let handling_s = (legs - 1.0 + picks) * self.pick_s + legs * self.drop_s;
            busy_s += rest.carry_s + handling_s + rest.later_arrivals_s;
            longest_chain_s =
                longest_chain_s.max(start_s + rest.carry_s + handling_s + rest.gaps_s);
        }
        if !next_trip_adjust_s.is_finite() {
            next_trip_adjust_s = 0.0;
        }
        longest_chain_s.max(state.time_s + busy_s + next_trip_adjust_s)
    }
}

/// What was recorded for an explored state: its time and its parts' ready times (clamped
/// to that time: a part ready earlier is just as ready).
struct Seen {
    time_s: f64,
    ready_s: [f64; MAX_PARTS],
}

struct Search<'a> {
    model: &'a Model,
    bound: Bound,
    best_s: f64,
    best: Option<Vec<TimedAction>>,
    path: Vec<TimedAction>,
    nodes: u64,
    max_nodes: u64,
    truncated: bool,
    seen: HashMap<u64, Seen>,
}

/// The state's configuration as one number: robot location, then each part's place and
/// colour (5 + 7 bits per part; at most 8 parts fit in 64 bits).
fn key(state: &State) -> u64 {
    let mut key = state.robot.index().unwrap_or(0) as u64;
    for p in &state.parts {
        let place = match p.place {
            Place::At(l) => l.index().unwrap_or(0) as u64,
            Place::Carried => LOCATION_COUNT as u64,
        };
        let color = match p.color {
            PartColor::Red => 0,
            PartColor::Green => 1,
            PartColor::Blue => 2,
        };
        key = (key << 7) | (place << 2) | color;
    }
    key
}

impl Search<'_> {
    fn dfs(&mut self, state: &State) {
        self.nodes += 1;
        if state.is_complete() {
            if state.time_s < self.best_s - EPS_S || self.best.is_none() {
                self.best_s = state.time_s;
                self.best = Some(self.path.clone());
            }
            return;
        }
        if self.nodes > self.max_nodes {
            self.truncated = true;
            return;
        }
        if self.bound.finish_s(self.model, state) >= self.best_s - EPS_S || self.dominated(state) {
            return;
        }
        let mut children: Vec<(State, TimedAction)> = self
            .model
            .actions(state)
            .into_iter()
            .filter_map(|a: Action| self.model.apply(state, a).ok())
            .collect();
        children.sort_by(|a, b| a.1.done_s.total_cmp(&b.1.done_s));
        for (child, timed) in children {
            self.path.push(timed);
            self.dfs(&child);
            self.path.pop();
        }
    }

    /// Whether an explored state dominates `state`; records `state` otherwise.
    fn dominated(&mut self, state: &State) -> bool {
        let mut ready_s = [0.0; MAX_PARTS];
        for (r, p) in ready_s.iter_mut().zip(&state.parts) {
            *r = p.ready_s.max(state.time_s);
        }
        let key = key(state);
        if let Some(seen) = self.seen.get(&key) {
            let no_better = state.time_s >= seen.time_s - EPS_S
                && ready_s
                    .iter()
                    .zip(&seen.ready_s)
                    .all(|(a, b)| *a >= *b - EPS_S);
            if no_better {
                return true;
            }
            let better = state.time_s <= seen.time_s
                && ready_s.iter().zip(&seen.ready_s).all(|(a, b)| *a <= *b);
            if !better {
                return false;
            }
        }
        self.seen.insert(
            key,
            Seen {
                time_s: state.time_s,
                ready_s,
            },
        );
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Field;
    use crate::planning::tasks::model::{Rules, Timing};
    use crate::planning::tasks::travel::{StraightLineTimes, TravelMatrix};
    use crate::referee::protocol::{SlotLetters, letters_to_string, parse_letters};
    use proptest::prelude::*;
    use std::time::Instant;

    /// The fastest finish over every sequence of valid actions (no pruning at all).
    fn brute_force(model: &Model, state: &State) -> Option<f64> {
        if state.is_complete() {
            return Some(state.time_s);
        }
        model
            .actions(state)
            .into_iter()
            .filter_map(|a| model.apply(state, a).ok())
            .filter_map(|(next, _)| brute_force(model, &next))
            .min_by(f64::total_cmp)
    }

    /// Replay `plan` from `state`; the final state.
    fn replay(model: &Model, state: &State, plan: &Plan) -> State {
        let mut s = state.clone();
        for step in &plan.steps {
            let (next, timed) = model
                .apply(&s, step.action)
                .expect("plan actions are valid");
            assert!((timed.done_s - step.done_s).abs() < 1e-9);
            s = next;
        }
        s
    }

    fn timing(delay_s: f64) -> Timing {
        Timing {
            pick_s: 1.0,
            drop_s: 0.8,
            machine_delay_s: delay_s,
        }
    }

    fn field_model(round: u8, delay_s: f64) -> Model {
        let times = StraightLineTimes::new(
            &Field::competition(),
            StraightLineTimes::ORIGINAL_SPEED_M_S,
            StraightLineTimes::ORIGINAL_TURN_RATE_RAD_S,
        );
        Model::new(&times, timing(delay_s), Rules::for_round(round)).unwrap()
    }

    /// Every distinct arrangement of `letters` over the four slots.
    fn permutations(letters: &str) -> Vec<SlotLetters> {
        let chars: Vec<char> = letters.chars().collect();
        let mut out: Vec<String> = Vec::new();
        for a in 0..4 {
            for b in 0..4 {
                for c in 0..4 {
                    for d in 0..4 {
                        let idx = [a, b, c, d];
                        let mut sorted = idx;
                        sorted.sort_unstable();
                        if sorted != [0, 1, 2, 3] {
                            continue;
                        }
                        let s: String = idx.iter().map(|&i| chars[i]).collect();
                        if !out.contains(&s) {
                            out.push(s);
                        }
                    }
                }
            }
        }
        out.iter().map(|s| parse_letters(s).unwrap()).collect()
    }

    fn random_matrix(entries: &[f64]) -> TravelMatrix {
        let mut table = [[0.0; LOCATION_COUNT]; LOCATION_COUNT];
        for (k, v) in entries.iter().enumerate() {
            let (i, j) = (k / LOCATION_COUNT, k % LOCATION_COUNT);
            if i != j {
                table[i][j] = *v;
            }
        }
        TravelMatrix::from_table(table)
    }

    fn letter_strategy() -> impl Strategy<Value = Option<PartColor>> {
        prop_oneof![
            Just(None),
            Just(Some(PartColor::Red)),
            Just(Some(PartColor::Green)),
            Just(Some(PartColor::Blue)),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(40))]

        #[test]
        fn branch_and_bound_finds_the_brute_force_optimum(
            entries in proptest::collection::vec(0.2f64..6.0, LOCATION_COUNT * LOCATION_COUNT),
            incoming in proptest::array::uniform4(letter_strategy()),
            delay_s in prop_oneof![Just(0.0), 0.0f64..15.0],
            green_at_a in any::<bool>(),
            pick_s in 0.0f64..2.0,
        ) {
            let parts = incoming.iter().flatten().count();
            prop_assume!(parts <= 3);
            let model = Model {
                travel: random_matrix(&entries),
                timing: Timing { pick_s, drop_s: 0.5, machine_delay_s: delay_s },
                rules: Rules { green_at_a },
            };
            let state = State::from_incoming(&incoming, Location::Start, 0.0);
            let plan = BranchAndBound::default().plan(&model, &state).unwrap();
            let best = brute_force(&model, &state).unwrap();
            prop_assert!(plan.optimal);
            prop_assert!((plan.finish_s - best).abs() < 1e-9, "bnb {} vs brute {}", plan.finish_s, best);
            let end = replay(&model, &state, &plan);
            prop_assert!(end.is_complete());
            prop_assert!((end.time_s - plan.finish_s).abs() < 1e-9);
        }
    }

    #[test]
    fn every_round_and_permutation_gets_a_complete_optimal_plan_with_empty_slots_too() {
        let cases = [
            (1, "BBBB"),
            (2, "BBGG"),
            (3, "RGGB"),
            (1, "BBBX"),
            (2, "XBGG"),
            (3, "RGXB"),
            (3, "RXXX"),
            (3, "XXXX"),
        ];
        for (round, multiset) in cases {
            for delay_s in [0.0, 10.0] {
                let model = field_model(round, delay_s);
                for incoming in permutations(multiset) {
                    let state = State::from_incoming(&incoming, Location::Start, 0.0);
                    let plan = BranchAndBound::default().plan(&model, &state).unwrap();
                    let name = letters_to_string(&incoming);
                    assert!(plan.optimal, "{name}");
                    let end = replay(&model, &state, &plan);
                    assert!(end.is_complete(), "round {round} {name}");
                    let legs = incoming
                        .iter()
                        .flatten()
                        .map(|c| match c {
                            PartColor::Blue => 1,
                            PartColor::Green => 2,
                            PartColor::Red => 3,
                        })
                        .sum::<usize>();
                    assert_eq!(plan.steps.len(), legs, "round {round} {name}");
                }
            }
        }
    }

    #[test]
    fn replanning_mid_round_keeps_the_optimal_finish() {
        for delay_s in [0.0, 8.0] {
            let model = field_model(3, delay_s);
            let incoming = parse_letters("BGGR").unwrap();
            let start = State::from_incoming(&incoming, Location::Start, 0.0);
            let plan = BranchAndBound::default().plan(&model, &start).unwrap();
            let mut state = start.clone();
            for (k, step) in plan.steps.iter().enumerate() {
                let again = BranchAndBound::default().plan(&model, &state).unwrap();
                assert!(
                    (again.finish_s - plan.finish_s).abs() < 1e-9,
                    "after {k} actions: {} vs {}",
                    again.finish_s,
                    plan.finish_s
                );
                state = model.apply(&state, step.action).unwrap().0;
            }
            assert!(state.is_complete());
            let done = BranchAndBound::default().plan(&model, &state).unwrap();
            assert!(done.steps.is_empty() && done.finish_s == state.time_s);
        }
    }

    #[test]
    fn a_carried_part_is_dropped_first() {
        let model = field_model(3, 0.0);
        let incoming = parse_letters("BGGR").unwrap();
        let mut state = State::from_incoming(&incoming, Location::Incoming(0), 3.0);
        state.parts[0].place = Place::Carried;
        let plan = BranchAndBound::default().plan(&model, &state).unwrap();
        let first = plan.next().unwrap();
        assert_eq!((first.part, first.from), (0, Place::Carried));
        assert!(matches!(first.to, Location::Outgoing(_)));
        assert!(replay(&model, &state, &plan).is_complete());
    }

    #[test]
    fn greens_use_machine_a_only_when_the_rules_allow_and_it_pays() {
        // A fast field where machine A is next to everything and B is far away.
        let far = |l: Location| {
            matches!(
                l,
                Location::MachineInput(MachineKind::B, _)
                    | Location::MachineOutput(MachineKind::B, _)
            )
        };
        let mut table = [[0.0; LOCATION_COUNT]; LOCATION_COUNT];
        for (i, &a) in Location::ALL.iter().enumerate() {
            for (j, &b) in Location::ALL.iter().enumerate() {
                if i != j {
                    table[i][j] = if far(a) || far(b) { 10.0 } else { 1.0 };
                }
            }
        }
        let incoming = parse_letters("GXXX").unwrap();
        let state = State::from_incoming(&incoming, Location::Start, 0.0);
        for (green_at_a, want) in [(true, MachineKind::A), (false, MachineKind::B)] {
            let model = Model {
                travel: TravelMatrix::from_table(table),
                timing: timing(0.0),
                rules: Rules { green_at_a },
            };
            let plan = BranchAndBound::default().plan(&model, &state).unwrap();
            assert!(matches!(plan.steps[0].action.to, Location::MachineInput(k, _) if k == want));
        }
    }

    #[test]
    fn a_red_left_in_the_outgoing_warehouse_is_fixed_and_a_full_one_is_no_plan() {
        let model = field_model(1, 0.0);
        let (red, blue) = (Some(PartColor::Red), Some(PartColor::Blue));
        let areas = |incoming, outgoing| [incoming, outgoing, [None; 4], [None; 4]];
        let state = State::from_server(
            areas([None; 4], [red, blue, blue, blue]),
            Location::Start,
            0.0,
            timing(0.0),
            Rules::for_round(1),
        );
        let plan = BranchAndBound::default().plan(&model, &state).unwrap();
        assert_eq!(plan.steps.len(), 3, "red: A, then a machine, then back");
        assert!(replay(&model, &state, &plan).is_complete());
        let full = State::from_server(
            areas([blue, None, None, None], [blue; 4]),
            Location::Start,
            0.0,
            timing(0.0),
            Rules::for_round(1),
        );
        assert_eq!(
            BranchAndBound::default().plan(&model, &full),
            Err(TaskError::NoPlan)
        );
    }

    /// Prints the search effort for every round-3 arrangement (run with `--nocapture`).
    #[test]
    fn planner_effort_round_3() {
        for delay_s in [0.0, 10.0] {
            let model = field_model(3, delay_s);
            let (mut worst_nodes, mut worst_ms) = (0, 0.0f64);
            for incoming in permutations("RGGB") {
                let state = State::from_incoming(&incoming, Location::Start, 0.0);
                let started = Instant::now();
                let plan = BranchAndBound::default().plan(&model, &state).unwrap();
                let ms = started.elapsed().as_secs_f64() * 1e3;
                assert!(plan.optimal);
                worst_nodes = worst_nodes.max(plan.nodes);
                worst_ms = worst_ms.max(ms);
            }
            println!(
                "round 3, machine delay {delay_s} s: worst of 12 arrangements {worst_nodes} nodes, {worst_ms:.2} ms"
            );
        }
    }
}
