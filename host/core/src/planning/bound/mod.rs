//! A lower bound on a round's time for this robot, computed independently of our planners,
//! to say how far from the physical limit a round is (issue 14).
//!
//! The method relaxes every constraint it can and keeps only what physics and the rules
//! impose, so no run of any planner can beat it:
//!
//! - **Order:** exact over every legal sequence of picks and drops with one part carried per
//!   magnet face (one on the competition robot),
//!   every machine and row a colour may use ([`Rules`]: red to A, green to B, or to A as well
//!   in rounds 1–2), every free outgoing slot, machines that turn a part at once (zero delay),
//!   a row loaded again only once its output is empty ([`mod@search`]).
//! - **Poses:** a magnet face (`robot.magnet_faces`: the front, and the back too on a robot
//!   with two magnets) touches each plate: the robot's centre half the body length
//!   (`robot.footprint_length_m / 2`) in front of the plate face, that face turned to it; the
//!   robot carries one part per face at once. The
//!   run starts at rest with the centre anywhere in the start area and any heading (the
//!   rules let a team place the robot anywhere in it; the area is approximate).
//! - **Paths:** the shortest path of the robot's centre around the walls and dividers grown
//!   by half the body width (a disc inside the square body: a relaxation), not the waypoint
//!   graph ([`crate::planning::disc_paths`]); parts standing on the floor are ignored.
//! - **Motion:** the wheel-speed limit in the robot frame, `|vx| + |vy| + k·|ω| ≤ v_max` with
//!   `k = lx + ly` and `v_max` the rim speed at `robot.max_wheel_speed_rad_s`, relaxed to
//!   `|v| + k·|ω| ≤ v_max`, whose left side is the fastest wheel's rim speed. Over a leg of
//!   path length `d` turning by `Δθ` its integral is at least `L = d + k·|Δθ|`, and a wheel
//!   accelerates at most at `navigation.max_accel_m_s2`, so a leg from rest to rest takes at
//!   least the trapezoid (or triangle) time of `L` ([`leg_time_s`]).
//! - **Handling:** a full stop at every pick and drop and the magnet's settle there
//!   (`mission.grip_settle_s`, `mission.release_settle_s`), except the last release, which
//!   the clock does not wait for.

pub mod search;

use crate::config::Config;
use crate::field::geometry::{Vec2, wrap_angle};
use crate::field::{Field, MachineKind, PartColor, Slot};
use crate::planning::tasks::model::Rules;
use crate::referee::protocol::SlotLetters;

use self::search::{Places, Station, search};
use crate::planning::disc_paths::DiscPaths;

/// The motion limits the bound keeps (module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionLimits {
    /// Fastest wheel's rim speed, m/s (`v_max`).
    pub max_rim_speed_m_s: f64,
    /// Rim speed per rad/s of turn, m (`k = lx + ly`).
    pub yaw_arm_m: f64,
    /// Fastest wheel's rim acceleration, m/s².
    pub max_accel_m_s2: f64,
    /// Dwell at a pick, s.
    pub grip_settle_s: f64,
    /// Dwell at a drop, s.
    pub release_settle_s: f64,
}

impl MotionLimits {
    /// The limits of the robot `config` describes.
    pub fn of(config: &Config) -> Self {
        Self {
            max_rim_speed_m_s: config.robot.max_wheel_speed_rad_s * config.robot.wheel_radius_m(),
            yaw_arm_m: config.robot.half_wheelbase_sum_m(),
            max_accel_m_s2: config.navigation.max_accel_m_s2,
            grip_settle_s: config.mission.grip_settle_s,
            release_settle_s: config.mission.release_settle_s,
        }
    }
}

/// The shortest time of a leg from rest to rest whose path is `path_m` long and turns by
/// `turn_rad` (module documentation), s.
pub fn leg_time_s(limits: &MotionLimits, path_m: f64, turn_rad: f64) -> f64 {
    let length = path_m + limits.yaw_arm_m * wrap_angle(turn_rad).abs();
    let (v, a) = (limits.max_rim_speed_m_s, limits.max_accel_m_s2);
    if length >= v * v / a {
        length / v + v / a
    } else {
        2.0 * (length / a).sqrt()
    }
}

/// Why no bound could be computed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BoundError {
    /// The round number is not 1, 2 or 3.
    #[error("no round {0}: rounds are 1, 2 and 3")]
    NoSuchRound(u8),
    /// A pick or drop pose, or the start, lies inside a grown obstacle or is walled in.
    #[error("the {0} cannot be reached by the robot's centre among the grown obstacles")]
    Unreachable(String),
    /// No sequence delivers every part (a colour no machine accepts).
    #[error("no legal order delivers every part")]
    NoOrder,
}

/// The field's stations and the leg times between them, for one robot; build once, then
/// ask [`RoundBound::seconds`] per colour arrangement.
#[derive(Clone, Debug)]
pub struct RoundBound {
    places: Places,
    /// How many magnet faces the robot has (`robot.magnet_faces`): parts it carries at once.
    faces: u8,
    /// Leg times between stops, row-major: each of [`Places::stations`] with each magnet
    /// face turned to its plate (`station × faces + face`).
    legs_s: Vec<f64>,
    limits: MotionLimits,
}

impl RoundBound {
    /// The bound's model of `field` for the robot `config` describes.
    pub fn new(config: &Config, field: &Field) -> Result<Self, BoundError> {
        let limits = MotionLimits::of(config);
        let standoff_m = config.robot.footprint_length_m / 2.0;
        let radius_m = config.robot.footprint_width_m / 2.0;
        let pose = |slot: &Slot| slot.pose_at_standoff(standoff_m);
        let machine = |kind: MachineKind, row: usize| {
            field
                .machine(kind, row)
                .map(|m| (pose(&m.input), pose(&m.output)))
        };
        let mut stations = vec![(Station::Start, field.start_pose())];
        for i in 0..4 {
            if let Some(slot) = field.incoming_slot(i) {
                stations.push((Station::Incoming(i), pose(slot)));
            }
            if let Some(slot) = field.outgoing_slot(i) {
                stations.push((Station::Outgoing(i), pose(slot)));
            }
        }
        for (row, (kind, index)) in [
            (MachineKind::A, 0),
            (MachineKind::A, 1),
            (MachineKind::B, 0),
            (MachineKind::B, 1),
        ]
        .into_iter()
        .enumerate()
        {
            if let Some((input, output)) = machine(kind, index) {
                stations.push((Station::MachineInput(row), input));
                stations.push((Station::MachineOutput(row), output));
            }
        }
        let obstacles: Vec<_> = field.obstacles().iter().map(|o| o.rect).collect();
        let space = DiscPaths::around(&obstacles, radius_m);
        for (station, pose) in &stations[1..] {
            if !space.is_clear(pose.position()) {
                return Err(BoundError::Unreachable(station.to_string()));
            }
        }
        let points: Vec<Vec2> = stations.iter().map(|(_, p)| p.position()).collect();
        let graph = space.graph(&points);
        let faces = &config.robot.magnet_faces;
        let stops = stations.len() * faces.len();
        let mut legs_s = Vec::with_capacity(stops * stops);
        // From the start: anywhere in the start area, any heading, at rest (each face's
        // stop there the same).
        let from_start: Vec<f64> = graph
            .from_region(field.start_area())
            .into_iter()
            .flat_map(|path| faces.iter().map(move |_| leg_time_s(&limits, path, 0.0)))
            .collect();
        for _ in faces {
            legs_s.extend_from_slice(&from_start);
        }
        for (i, (_, from)) in stations.iter().enumerate().skip(1) {
            let paths = graph.from_point(i);
            for from_face in faces {
                let from_yaw = from.yaw_rad + from_face.heading_offset_rad();
                for ((to_station, to), path) in stations.iter().zip(&paths) {
                    for to_face in faces {
                        if *to_station == Station::Start {
                            legs_s.push(f64::INFINITY);
                        } else if path.is_finite() {
                            let to_yaw = to.yaw_rad + to_face.heading_offset_rad();
                            legs_s.push(leg_time_s(&limits, *path, to_yaw - from_yaw));
                        } else {
                            return Err(BoundError::Unreachable(to_station.to_string()));
                        }
                    }
                }
            }
        }
        Ok(Self {
            places: Places::new(stations.into_iter().map(|(s, _)| s).collect()),
            faces: faces.len() as u8,
            legs_s,
            limits,
        })
    }

    /// The bound for round `round` with `parts` in the incoming slots, s from the part list
    /// to the last part placed.
    pub fn seconds(&self, round: u8, parts: SlotLetters) -> Result<f64, BoundError> {
        if !(1..=3).contains(&round) {
            return Err(BoundError::NoSuchRound(round));
        }
        let total = search(
            &self.places,
            self.faces,
            &self.legs_s,
            &self.limits,
            Rules::for_round(round),
            parts,
        )
        .ok_or(BoundError::NoOrder)?;
        Ok(total)
    }

    /// The bound of every arrangement of round `round`'s preset colours (round 1 `BBBB`,
    /// round 2 `BBGG`, round 3 `RGGB`): (mean, least, greatest), s.
    pub fn over_arrangements(&self, round: u8) -> Result<(f64, f64, f64), BoundError> {
        let arrangements = arrangements(round)?;
        let mut times = Vec::with_capacity(arrangements.len());
        for arrangement in arrangements {
            times.push(self.seconds(round, arrangement)?);
        }
        let mean = times.iter().sum::<f64>() / times.len() as f64;
        let least = times.iter().copied().fold(f64::INFINITY, f64::min);
        let greatest = times.iter().copied().fold(0.0, f64::max);
        Ok((mean, least, greatest))
    }
}

/// Every distinct arrangement of round `round`'s preset colours in the incoming slots
/// (round 1 `BBBB`, round 2 `BBGG`, round 3 `RGGB`).
fn arrangements(round: u8) -> Result<Vec<SlotLetters>, BoundError> {
    use PartColor::{Blue, Green, Red};
    let colours = match round {
        1 => [Blue; 4],
        2 => [Blue, Blue, Green, Green],
        3 => [Red, Green, Green, Blue],
        other => return Err(BoundError::NoSuchRound(other)),
    };
    let mut arrangements: Vec<SlotLetters> = Vec::new();
    for order in permutations4() {
        let arrangement = order.map(|i| Some(colours[i]));
        if !arrangements.contains(&arrangement) {
            arrangements.push(arrangement);
        }
    }
    Ok(arrangements)
}

/// The 24 orders of four things.
fn permutations4() -> Vec<[usize; 4]> {
    let mut all = Vec::with_capacity(24);
    for a in 0..4 {
        for b in (0..4).filter(|&b| b != a) {
            for c in (0..4).filter(|&c| c != a && c != b) {
                let d = 6 - a - b - c;
                all.push([a, b, c, d]);
            }
        }
    }
    all
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::MagnetFace;

    fn limits() -> MotionLimits {
        MotionLimits::of(&Config::default())
    }

    #[test]
    fn the_default_robot_has_the_issues_limits() {
        let l = limits();
        assert!((l.max_rim_speed_m_s - 0.729).abs() < 1e-9);
        assert!((l.yaw_arm_m - 0.1725).abs() < 1e-9);
        assert_eq!(l.max_accel_m_s2, 2.0);
    }

    #[test]
    fn a_leg_is_a_trapezoid_or_a_triangle_of_its_effort_length() {
        let l = limits();
        // Long: cruise at v_max with a ramp at each end (v/a = 0.3645 s in all).
        assert!((leg_time_s(&l, 1.0, 0.0) - (1.0 / 0.729 + 0.3645)).abs() < 1e-9);
        // A half turn on the spot costs k·π of rim travel.
        let spin = leg_time_s(&l, 0.0, std::f64::consts::PI);
        assert!((spin - (0.1725 * std::f64::consts::PI / 0.729 + 0.3645)).abs() < 1e-9);
        // Short: never reaches v_max.
        assert!((leg_time_s(&l, 0.1, 0.0) - 2.0 * (0.1f64 / 2.0).sqrt()).abs() < 1e-12);
        // Continuous where the two meet (L = v²/a).
        let knee = 0.729 * 0.729 / 2.0;
        assert!((leg_time_s(&l, knee, 0.0) - leg_time_s(&l, knee - 1e-12, 0.0)).abs() < 1e-6);
    }

    /// Issue 14 states the bound computed independently by the same method: round 1
    /// 21.9 s; round 2 22.8 s (22.7–23.1); round 3 27.3 s (26.7–28.1). Round 1, which uses
    /// no machine, agrees to 0.05 s. Rounds 2 and 3 come out higher here (22.94 s and
    /// 28.36 s); letting greens use machine A in round 3, which the rules do not, gives
    /// 27.16 s (26.79–27.56), so the two computations model the machines' legs differently.
    /// This pins today's figures so a change to the method shows.
    #[test]
    fn the_bound_matches_the_independent_round_1_figure_and_pins_rounds_2_and_3() {
        let bound = RoundBound::new(&Config::default(), &Field::competition()).unwrap();
        let close = |(mean, least, most): (f64, f64, f64), expected: (f64, f64, f64)| {
            (mean - expected.0).abs() < 0.005
                && (least - expected.1).abs() < 0.005
                && (most - expected.2).abs() < 0.005
        };
        let r1 = bound.over_arrangements(1).unwrap();
        assert!((r1.0 - 21.9).abs() < 0.05, "round 1: {r1:?}");
        let r2 = bound.over_arrangements(2).unwrap();
        assert!(close(r2, (22.936, 22.797, 23.232)), "round 2: {r2:?}");
        let r3 = bound.over_arrangements(3).unwrap();
        assert!(close(r3, (28.363, 27.947, 28.759)), "round 3: {r3:?}");
    }

    #[test]
    fn round_1_lies_between_its_straight_lines_and_straight_lines_with_its_half_turns() {
        // Every leg costs at least its straight-line time at v_max plus the ramps: the
        // bound of round 1 is at least that over the best order's straight lines (8.5 m,
        // issue 14) and eight legs' ramps, and at most the same plus the seven half turns.
        let bound = RoundBound::new(&Config::default(), &Field::competition()).unwrap();
        let (r1, _, _) = bound.over_arrangements(1).unwrap();
        let ramps = 8.0 * 0.3645 + 7.0 * 0.25;
        assert!(r1 > 8.5 / 0.729 + ramps, "{r1}");
        let half_turns = 7.0 * 0.1725 * std::f64::consts::PI / 0.729;
        assert!(r1 < 9.0 / 0.729 + ramps + half_turns, "{r1}");
    }

    fn two_magnets() -> Config {
        let mut config = Config::default();
        config.robot.magnet_faces = vec![MagnetFace::Front, MagnetFace::Back];
        config
    }

    /// Issue 14 gives 14.6 / 19.0 / 24.5 s for magnets on the front and back faces, by a
    /// computation of its own. This one, the same method with a part per face: 13.78 /
    /// 18.44 / 25.04 s. Round 1 in hand: four 180° legs between neighbouring slots (each
    /// 0.15 m and k·π, 1.32 s), three long legs that need no turn (picked with the front
    /// facing the incoming wall, the robot drops with its back facing the outgoing one;
    /// 1.83–1.87 s), the start leg (1.19 s) and seven settles (1.75 s). Pinned so a change
    /// to the method shows.
    #[test]
    fn magnets_front_and_back_carry_two_parts_and_pin_the_bound() {
        let bound = RoundBound::new(&two_magnets(), &Field::competition()).unwrap();
        let expected = [
            (1, 13.780, 13.780, 13.780),
            (2, 18.438, 18.158, 18.832),
            (3, 25.041, 24.693, 25.465),
        ];
        for (round, mean, least, most) in expected {
            let got = bound.over_arrangements(round).unwrap();
            let close = (got.0 - mean).abs() < 0.005
                && (got.1 - least).abs() < 0.005
                && (got.2 - most).abs() < 0.005;
            assert!(close, "round {round}: {got:?}");
        }
    }

    /// A robot that may carry a second part may also carry just one: never slower, for
    /// every arrangement of every round.
    #[test]
    fn a_second_magnet_never_makes_a_round_slower() {
        let field = Field::competition();
        let one = RoundBound::new(&Config::default(), &field).unwrap();
        let two = RoundBound::new(&two_magnets(), &field).unwrap();
        let back_only = {
            let mut config = Config::default();
            config.robot.magnet_faces = vec![MagnetFace::Back];
            RoundBound::new(&config, &field).unwrap()
        };
        for round in 1..=3u8 {
            for parts in arrangements(round).unwrap() {
                let single = one.seconds(round, parts).unwrap();
                assert!(two.seconds(round, parts).unwrap() <= single + 1e-9);
                // One magnet on the back instead: the same body turned round, the same bound.
                assert!((back_only.seconds(round, parts).unwrap() - single).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn a_round_that_does_not_exist_is_an_error() {
        let bound = RoundBound::new(&Config::default(), &Field::competition()).unwrap();
        assert_eq!(bound.seconds(4, [None; 4]), Err(BoundError::NoSuchRound(4)));
    }
}
