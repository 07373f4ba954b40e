//! The bound's exact search over every legal order of picks and drops: a shortest path
//! (Dijkstra) over states "where the robot stands and which of its magnet faces it turns
//! to the plate there, where each part is (on which face if carried) and what colour it
//! has", each step one leg and one pick or drop. The robot carries one part per magnet face
//! at once; with one face that is the competition robot's one part.

use std::collections::{BinaryHeap, HashMap};
use std::fmt;

use crate::field::{MachineKind, PartColor};
use crate::planning::cheapest_first::Cheapest;
use crate::planning::tasks::model::Rules;
use crate::referee::protocol::SlotLetters;

use super::MotionLimits;

/// Machine rows in the bound's order: A upper, A lower, B upper, B lower.
const ROWS: [MachineKind; 4] = [
    MachineKind::A,
    MachineKind::A,
    MachineKind::B,
    MachineKind::B,
];

/// A place the robot stops at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Station {
    /// The start pose.
    Start,
    /// Facing incoming slot `i` (0..3, increasing x).
    Incoming(usize),
    /// Facing outgoing slot `i`.
    Outgoing(usize),
    /// Facing machine row `r`'s input (0 = A upper, 1 = A lower, 2 = B upper, 3 = B lower).
    MachineInput(usize),
    /// Facing machine row `r`'s output.
    MachineOutput(usize),
}

impl fmt::Display for Station {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let row = |r: usize| {
            let kind = if ROWS[r] == MachineKind::A { 'A' } else { 'B' };
            let level = if r.is_multiple_of(2) {
                "upper"
            } else {
                "lower"
            };
            format!("machine {kind} {level} row")
        };
        match *self {
            Self::Start => f.write_str("start pose"),
            Self::Incoming(i) => write!(f, "incoming slot {}", i + 1),
            Self::Outgoing(i) => write!(f, "outgoing slot {}", i + 1),
            Self::MachineInput(r) => write!(f, "{} input", row(r)),
            Self::MachineOutput(r) => write!(f, "{} output", row(r)),
        }
    }
}

/// The stations, indexed as the leg-time matrix is.
#[derive(Clone, Debug)]
pub struct Places {
    stations: Vec<Station>,
}

impl Places {
    /// Stations in matrix order.
    pub fn new(stations: Vec<Station>) -> Self {
        Self { stations }
    }

    /// The stations in matrix order.
    pub fn stations(&self) -> &[Station] {
        &self.stations
    }

    fn index(&self, station: Station) -> Option<usize> {
        self.stations.iter().position(|s| *s == station)
    }
}

/// Where the robot stops: a station with one of its magnet faces turned to the plate, as
/// the index of its row and column in the leg-time matrix (`station × faces + face`).
fn stop(station: usize, face: u8, faces: u8) -> u8 {
    (station * usize::from(faces) + usize::from(face)) as u8
}

/// Where a part is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Where {
    Incoming(u8),
    /// On the robot's magnet face `f` (an index into the faces the search was given).
    Carried(u8),
    /// On machine row `r`'s output, already turned.
    Output(u8),
    Delivered(u8),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
struct Part {
    at: Where,
    color: PartColor,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
struct State {
    /// The stop the robot is at ([`stop`]).
    robot: u8,
    parts: Vec<Part>,
}

impl State {
    fn occupied(&self, at: Where) -> bool {
        self.parts.iter().any(|p| p.at == at)
    }

    fn done(&self) -> bool {
        self.parts
            .iter()
            .all(|p| matches!(p.at, Where::Delivered(_)))
    }
}

/// The least time from the start to every part delivered, s (`None` when no legal order
/// exists or a station is missing): legs from `legs_s` (row-major over the stops, each
/// station of `places` with each of the robot's `faces` magnet faces, `station × faces +
/// face`), a settle at each pick and drop but the last.
pub fn search(
    places: &Places,
    faces: u8,
    legs_s: &[f64],
    limits: &MotionLimits,
    rules: Rules,
    parts: SlotLetters,
) -> Option<f64> {
    let stops = places.stations.len() * usize::from(faces);
    let start = State {
        robot: stop(places.index(Station::Start)?, 0, faces),
        parts: parts
            .iter()
            .enumerate()
            .filter_map(|(i, color)| {
                color.map(|color| Part {
                    at: Where::Incoming(i as u8),
                    color,
                })
            })
            .collect(),
    };
    let mut best: HashMap<State, f64> = HashMap::from([(start.clone(), 0.0)]);
    let mut queue = BinaryHeap::from([Cheapest {
        cost: 0.0,
        item: start,
    }]);
    while let Some(Cheapest {
        cost: time,
        item: state,
    }) = queue.pop()
    {
        if best.get(&state).is_some_and(|&b| time > b) {
            continue;
        }
        if state.done() {
            return Some(if state.parts.is_empty() {
                0.0
            } else {
                time - limits.release_settle_s
            });
        }
        for (station, face, next, settle) in moves(rules, faces, &state) {
            let Some(to) = places.index(station) else {
                continue;
            };
            let to = stop(to, face, faces);
            let leg = legs_s[usize::from(state.robot) * stops + usize::from(to)];
            let candidate = time + leg + settle(limits);
            let next = State { robot: to, ..next };
            if best.get(&next).is_none_or(|&b| candidate < b) {
                best.insert(next.clone(), candidate);
                queue.push(Cheapest {
                    cost: candidate,
                    item: next,
                });
            }
        }
    }
    None
}

type Settle = fn(&MotionLimits) -> f64;

/// Every pick or drop possible from `state` for a robot with `faces` magnet faces: where
/// the robot goes, which face it turns to the plate there, the state after (robot not yet
/// moved) and the dwell there. A free face may pick any part in reach; a face holding a
/// part may drop it wherever that part may go.
fn moves(rules: Rules, faces: u8, state: &State) -> Vec<(Station, u8, State, Settle)> {
    let mut moves = Vec::new();
    let with = |part: usize, at: Where, color: PartColor| {
        let mut next = state.clone();
        next.parts[part] = Part { at, color };
        next
    };
    for face in 0..faces {
        match state
            .parts
            .iter()
            .position(|p| p.at == Where::Carried(face))
        {
            None => {
                for (i, part) in state.parts.iter().enumerate() {
                    let station = match part.at {
                        Where::Incoming(slot) => Station::Incoming(usize::from(slot)),
                        Where::Output(row) => Station::MachineOutput(usize::from(row)),
                        Where::Carried(_) | Where::Delivered(_) => continue,
                    };
                    moves.push((
                        station,
                        face,
                        with(i, Where::Carried(face), part.color),
                        (|l| l.grip_settle_s) as Settle,
                    ));
                }
            }
            Some(i) => {
                let color = state.parts[i].color;
                if color == PartColor::Blue {
                    for slot in 0..4u8 {
                        if !state.occupied(Where::Delivered(slot)) {
                            moves.push((
                                Station::Outgoing(usize::from(slot)),
                                face,
                                with(i, Where::Delivered(slot), color),
                                (|l| l.release_settle_s) as Settle,
                            ));
                        }
                    }
                }
                for (row, kind) in ROWS.iter().enumerate() {
                    let row = row as u8;
                    if let Some(turned) = rules.transform(*kind, color)
                        && !state.occupied(Where::Output(row))
                    {
                        moves.push((
                            Station::MachineInput(usize::from(row)),
                            face,
                            with(i, Where::Output(row), turned),
                            (|l| l.release_settle_s) as Settle,
                        ));
                    }
                }
            }
        }
    }
    moves
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `stations` on a line, one second apart per index step (one magnet face): the
    /// search's answer can be worked out by hand.
    fn stations_on_a_line(stations: Vec<Station>) -> (Places, Vec<f64>) {
        let n = stations.len();
        let legs = (0..n * n).map(|k| (k / n).abs_diff(k % n) as f64).collect();
        (Places::new(stations), legs)
    }

    /// The start, incoming 1, outgoing 1 and machine B's input and output on a line.
    fn line() -> (Places, Vec<f64>) {
        stations_on_a_line(vec![
            Station::Start,
            Station::Incoming(0),
            Station::Outgoing(0),
            Station::MachineInput(2),
            Station::MachineOutput(2),
        ])
    }

    fn no_dwell() -> MotionLimits {
        MotionLimits {
            max_rim_speed_m_s: 1.0,
            yaw_arm_m: 0.0,
            max_accel_m_s2: 1.0,
            grip_settle_s: 0.0,
            release_settle_s: 0.0,
        }
    }

    #[test]
    fn a_blue_part_goes_straight_out() {
        let (places, legs) = line();
        let parts = [Some(PartColor::Blue), None, None, None];
        let t = search(&places, 1, &legs, &no_dwell(), Rules::for_round(1), parts);
        // Start → incoming (1 s) → outgoing (1 s).
        assert_eq!(t, Some(2.0));
    }

    #[test]
    fn a_green_part_visits_machine_b_first() {
        let (places, legs) = line();
        let parts = [Some(PartColor::Green), None, None, None];
        let t = search(&places, 1, &legs, &no_dwell(), Rules::for_round(3), parts);
        // Start → incoming 1 → B input 2 → B output 1 → outgoing 2.
        assert_eq!(t, Some(6.0));
    }

    #[test]
    fn settles_count_at_every_pick_and_drop_but_the_last() {
        let (places, legs) = line();
        let limits = MotionLimits {
            grip_settle_s: 0.25,
            release_settle_s: 0.5,
            ..no_dwell()
        };
        let parts = [Some(PartColor::Green), None, None, None];
        let t = search(&places, 1, &legs, &limits, Rules::for_round(3), parts);
        // Two picks and one timed drop.
        assert_eq!(t, Some(6.0 + 0.25 + 0.25 + 0.5));
    }

    /// Two blue parts on a line of stations, one second apart per step, no turn cost: one
    /// face carries them out one at a time (start → I1 → O1 → I2 → O2: 1 + 2 + 1 + 2 s), two
    /// faces collect both first (start → I1 → I2 → O1 → O2: 1 + 1 + 1 + 1 s).
    #[test]
    fn a_second_face_carries_two_parts_at_once() {
        let (places, one) = stations_on_a_line(vec![
            Station::Start,
            Station::Incoming(0),
            Station::Incoming(1),
            Station::Outgoing(0),
            Station::Outgoing(1),
        ]);
        let n = places.stations().len();
        let parts = [Some(PartColor::Blue), Some(PartColor::Blue), None, None];
        let rules = Rules::for_round(1);
        assert_eq!(
            search(&places, 1, &one, &no_dwell(), rules, parts),
            Some(6.0)
        );
        let stops = 2 * n;
        let two: Vec<f64> = (0..stops * stops)
            .map(|k| (k / stops / 2).abs_diff(k % stops / 2) as f64)
            .collect();
        assert_eq!(
            search(&places, 2, &two, &no_dwell(), rules, parts),
            Some(4.0)
        );
    }

    #[test]
    fn a_red_part_without_machine_a_has_no_order() {
        let (places, legs) = line();
        let parts = [Some(PartColor::Red), None, None, None];
        let t = search(&places, 1, &legs, &no_dwell(), Rules::for_round(3), parts);
        assert_eq!(t, None);
    }
}
