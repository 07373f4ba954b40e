//! The "original" preset: the 5dpo task manager's priority rules and machine choices
//! (original-system.md §6.4, `Manager.cpp`), as a policy over the same model.
//!
//! Priorities (lower first; ties go to the lower part index, i.e. the incoming slot):
//! red in the incoming warehouse 0, green there 1, a processed green (now blue) 2, a red
//! after machine A (now green) 3, blue in the incoming warehouse 4, a red after machine B
//! (now blue) 5. Destinations, chosen when the part is picked, first free in order:
//! an originally blue part → outgoing 0, 1, 2, 3 (waypoints 62–65); a finished green or red
//! → outgoing 3, 2, 1, 0; a green → machine B row 0 then row 1 (inputs 54, 58) when `mach_b`
//! (deployed: true), else machine A row 0 then row 1 (56, 60); a red → machine A row 0 then
//! row 1; a red after A → machine B row 0 then row 1. The original ignored machine delays
//! (it drove to the output and pushed until the part was there); here the pick waits for the
//! part like every plan. Its final trip to park at vertex 5 is not an action.

use super::model::{Model, PartState, State, TaskError, TimedAction};
use super::travel::Location;
use super::{Plan, Policy};
use crate::field::MachineKind;
use crate::field::PartColor;

/// The 5dpo priority planner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Original {
    /// Whether greens go to machine B (`mach_b`; the deployed configuration set it true,
    /// original-system.md §1.3) rather than A.
    pub mach_b: bool,
}

impl Default for Original {
    /// The deployed configuration: `mach_b = true`.
    fn default() -> Self {
        Self { mach_b: true }
    }
}

/// The original's priority of a part (`None` when finished; 9 for a state the original
/// never produced, such as a red left in the outgoing warehouse).
fn priority(part: &PartState) -> Option<u8> {
    if part.is_done() {
        return None;
    }
    use PartColor::{Blue, Green, Red};
    Some(match (part.initial, part.color) {
        (Red, Red) => 0,
        (Green, Green) => 1,
        (Green, Blue) => 2,
        (Red, Green) => 3,
        (Blue, Blue) => 4,
        (Red, Blue) => 5,
        _ => 9,
    })
}

impl Original {
    /// The candidate destinations of `part`, in the original's order.
    fn candidates(&self, part: &PartState) -> Vec<Location> {
        use PartColor::{Blue, Green, Red};
        let machine = |kind| {
            vec![
                Location::MachineInput(kind, 0),
                Location::MachineInput(kind, 1),
            ]
        };
        match (part.initial, part.color) {
            (Blue, _) => (0..4).map(Location::Outgoing).collect(),
            (_, Blue) => (0..4).rev().map(Location::Outgoing).collect(),
            (Red, Red) => machine(MachineKind::A),
            (Red, Green) => machine(MachineKind::B),
            (_, Green) if self.mach_b => machine(MachineKind::B),
            (_, Green) => machine(MachineKind::A),
            (_, Red) => machine(MachineKind::A),
        }
    }

    /// The original's next action in `state`, or `None` when every part is finished.
    pub fn next_action(
        &self,
        model: &Model,
        state: &State,
    ) -> Result<Option<super::Action>, TaskError> {
        let part = match state.carried() {
            Some(p) => p,
            None => {
                let best = (0..state.parts.len())
                    .filter(|&i| state.pickable(i))
                    .filter_map(|i| priority(&state.parts[i]).map(|p| (p, i)))
                    .min();
                match best {
                    Some((_, i)) => i,
                    None if state.is_complete() => return Ok(None),
                    None => return Err(TaskError::NoPlan),
                }
            }
        };
        let p = &state.parts[part];
        let to = self
            .candidates(p)
            .into_iter()
            .find(|&to| state.can_drop(part, to, model.rules))
            .ok_or(TaskError::NoPlan)?;
        Ok(Some(super::Action {
            part,
            from: p.place,
            to,
        }))
    }
}

impl Policy for Original {
    fn name(&self) -> &'static str {
        "original"
    }

    fn plan(&self, model: &Model, state: &State) -> Result<Plan, TaskError> {
        model.check()?;
        let mut state = state.clone();
        let mut steps: Vec<TimedAction> = Vec::new();
        while let Some(action) = self.next_action(model, &state)? {
            let (next, timed) = model.apply(&state, action)?;
            state = next;
            steps.push(timed);
        }
        Ok(Plan {
            finish_s: state.time_s,
            nodes: steps.len() as u64,
            steps,
            optimal: false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Field;
    use crate::planning::tasks::model::{Place, Rules, Timing};
    use crate::planning::tasks::search::BranchAndBound;
    use crate::planning::tasks::travel::StraightLineTimes;
    use crate::referee::protocol::parse_letters;

    fn model(round: u8, delay_s: f64) -> Model {
        let times = StraightLineTimes::new(
            &Field::competition(),
            StraightLineTimes::ORIGINAL_SPEED_M_S,
            StraightLineTimes::ORIGINAL_TURN_RATE_RAD_S,
        );
        let timing = Timing {
            pick_s: 1.0,
            drop_s: 0.8,
            machine_delay_s: delay_s,
        };
        Model::new(&times, timing, Rules::for_round(round)).unwrap()
    }

    /// (part, pick waypoint, drop waypoint) of every step.
    fn route(plan: &Plan) -> Vec<(usize, u8, u8)> {
        let field = Field::competition();
        plan.steps
            .iter()
            .map(|s| {
                let Place::At(from) = s.action.from else {
                    panic!("the original never starts carrying");
                };
                let id = |l: Location| l.waypoint(&field).unwrap().0;
                (s.action.part, id(from), id(s.action.to))
            })
            .collect()
    }

    #[test]
    fn bggr_reproduces_the_order_of_original_system_6_4() {
        let state = State::from_incoming(&parse_letters("BGGR").unwrap(), Location::Start, 0.0);
        let plan = Original::default().plan(&model(3, 0.0), &state).unwrap();
        // §6.4: R → A (56); G1 → B (54); G2 → B (58); G1 (55) → 65; G2 (59) → 64;
        // R (57) → B (54); B → 62; R (55) → 63.
        let want = [
            (3, 53, 56),
            (1, 51, 54),
            (2, 52, 58),
            (1, 55, 65),
            (2, 59, 64),
            (3, 57, 54),
            (0, 50, 62),
            (3, 55, 63),
        ];
        assert_eq!(route(&plan), want);
    }

    #[test]
    fn rounds_one_and_two_follow_the_same_rules() {
        let m2 = model(2, 0.0);
        let state = State::from_incoming(&parse_letters("GBBG").unwrap(), Location::Start, 0.0);
        let plan = Original::default().plan(&m2, &state).unwrap();
        // Greens first (slot order), both to B although round 2 allows A (mach_b = true),
        // then finished greens descending, then blues ascending.
        let want = [
            (0, 50, 54),
            (3, 53, 58),
            (0, 55, 65),
            (3, 59, 64),
            (1, 51, 62),
            (2, 52, 63),
        ];
        assert_eq!(route(&plan), want);
        let to_a = Original { mach_b: false }.plan(&m2, &state).unwrap();
        assert_eq!(route(&to_a)[..2], [(0, 50, 56), (3, 53, 60)]);
        let m1 = model(1, 0.0);
        let state = State::from_incoming(&parse_letters("BXBB").unwrap(), Location::Start, 0.0);
        let plan = Original::default().plan(&m1, &state).unwrap();
        assert_eq!(route(&plan), [(0, 50, 62), (1, 52, 63), (2, 53, 64)]);
    }

    #[test]
    fn every_arrangement_is_completed_and_never_beats_the_optimum() {
        let cases = [
            (1, "BBBB"),
            (2, "BBGG"),
            (2, "BGGX"),
            (3, "RGGB"),
            (3, "RXGB"),
        ];
        for (round, letters) in cases {
            for delay_s in [0.0, 12.0] {
                let m = model(round, delay_s);
                let chars: Vec<char> = letters.chars().collect();
                for rot in 0..4 {
                    let text: String = (0..4).map(|i| chars[(i + rot) % 4]).collect();
                    let state =
                        State::from_incoming(&parse_letters(&text).unwrap(), Location::Start, 0.0);
                    let original = Original::default().plan(&m, &state).unwrap();
                    let mut end = state.clone();
                    for s in &original.steps {
                        end = m.apply(&end, s.action).unwrap().0;
                    }
                    assert!(end.is_complete(), "{text}");
                    let ours = BranchAndBound::default().plan(&m, &state).unwrap();
                    assert!(ours.finish_s <= original.finish_s + 1e-9, "{text}");
                }
            }
        }
    }

    /// Prints each policy's mean estimated round time over every arrangement (straight-line
    /// travel at the original's 0.4 m/s and 0.8 rad/s; pick 1 s and drop 0.8 s are
    /// assumptions). Run with `--nocapture`.
    #[test]
    fn prints_estimated_round_times_per_policy() {
        let cases = [(1, "BBBB"), (2, "BBGG"), (3, "RGGB")];
        for ((round, letters), delay_s) in cases.into_iter().flat_map(|c| [(c, 0.0), (c, 10.0)]) {
            let m = model(round, delay_s);
            let chars: Vec<char> = letters.chars().collect();
            let mut seen = Vec::new();
            let (mut ours_s, mut original_s) = (0.0, 0.0);
            for code in 0..256usize {
                let idx: Vec<usize> = (0..4).map(|k| (code >> (2 * k)) & 3).collect();
                let mut sorted = idx.clone();
                sorted.sort_unstable();
                let text: String = idx.iter().map(|&i| chars[i]).collect();
                if sorted != [0, 1, 2, 3] || seen.contains(&text) {
                    continue;
                }
                let state =
                    State::from_incoming(&parse_letters(&text).unwrap(), Location::Start, 0.0);
                let ours = BranchAndBound::default().plan(&m, &state).unwrap().finish_s;
                let original = Original::default().plan(&m, &state).unwrap().finish_s;
                assert!(ours <= original + 1e-9, "{text}");
                ours_s += ours;
                original_s += original;
                seen.push(text);
            }
            let n = seen.len() as f64;
            println!(
                "round {round}, machine delay {delay_s} s ({} arrangements): ours {:.1} s, original {:.1} s, ratio {:.2}",
                seen.len(),
                ours_s / n,
                original_s / n,
                ours_s / original_s
            );
        }
    }

    #[test]
    fn resumes_from_a_mid_round_state_with_the_original_priorities() {
        let m = model(3, 0.0);
        let state = State::from_incoming(&parse_letters("BGGR").unwrap(), Location::Start, 0.0);
        let full = Original::default().plan(&m, &state).unwrap();
        let mut mid = state;
        for s in &full.steps[..4] {
            mid = m.apply(&mid, s.action).unwrap().0;
        }
        let rest = Original::default().plan(&m, &mid).unwrap();
        assert_eq!(route(&rest), route(&full)[4..]);
        assert!((rest.finish_s - full.finish_s).abs() < 1e-9);
    }
}
