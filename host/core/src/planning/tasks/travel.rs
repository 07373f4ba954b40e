//! Where things are and how long the robot takes between them: the planner's
//! [`Location`]s (the field's slots and the start) and travel-time tables.
//!
//! Travel times come from the caller through [`TravelTimes`] (the navigation stack knows the
//! real paths and speeds); [`StraightLineTimes`] is a crude stand-in for tests and for use
//! before the navigation stack is wired in.

use std::fmt;

use crate::field::{Field, MachineKind, Pose2, Slot, WaypointId, wrap_angle};

/// Where the robot or a part can be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// The robot's start pose, or wherever it is when it is not docked at a slot (the
    /// caller's travel times from `Start` then measure from its current pose). Never a
    /// part's place.
    Start,
    /// Incoming-warehouse slot 0..3 (increasing x).
    Incoming(usize),
    /// Outgoing-warehouse slot 0..3 (increasing x).
    Outgoing(usize),
    /// A machine's input: type and row (0 = upper, 1 = lower).
    MachineInput(MachineKind, usize),
    /// A machine's output: type and row.
    MachineOutput(MachineKind, usize),
}

/// Number of distinct [`Location`]s (1 start + 4 + 4 + 2 × 2 × 2).
pub const LOCATION_COUNT: usize = 17;

impl Location {
    /// Every location, in [`Location::index`] order.
    pub const ALL: [Self; LOCATION_COUNT] = {
        use MachineKind::{A, B};
        [
            Self::Start,
            Self::Incoming(0),
            Self::Incoming(1),
            Self::Incoming(2),
            Self::Incoming(3),
            Self::Outgoing(0),
            Self::Outgoing(1),
            Self::Outgoing(2),
            Self::Outgoing(3),
            Self::MachineInput(A, 0),
            Self::MachineInput(A, 1),
            Self::MachineOutput(A, 0),
            Self::MachineOutput(A, 1),
            Self::MachineInput(B, 0),
            Self::MachineInput(B, 1),
            Self::MachineOutput(B, 0),
            Self::MachineOutput(B, 1),
        ]
    };

    /// A dense index 0..17 (`None` if a slot or row number is out of range).
    pub fn index(self) -> Option<usize> {
        let machine = |kind: MachineKind| match kind {
            MachineKind::A => 0,
            MachineKind::B => 4,
        };
        match self {
            Self::Start => Some(0),
            Self::Incoming(i) if i < 4 => Some(1 + i),
            Self::Outgoing(i) if i < 4 => Some(5 + i),
            Self::MachineInput(k, r) if r < 2 => Some(9 + machine(k) + r),
            Self::MachineOutput(k, r) if r < 2 => Some(11 + machine(k) + r),
            _ => None,
        }
    }

    /// Whether the robot only ever picks here (the incoming warehouse, a machine's output),
    /// so it arrives empty; it arrives carrying a part at every other slot.
    pub fn is_pick(self) -> bool {
        matches!(self, Self::Incoming(_) | Self::MachineOutput(..))
    }

    /// The field's slot at this location (`None` for the start or an out-of-range index).
    pub fn slot(self, field: &Field) -> Option<&Slot> {
        match self {
            Self::Start => None,
            Self::Incoming(i) => field.incoming_slot(i),
            Self::Outgoing(i) => field.outgoing_slot(i),
            Self::MachineInput(k, r) => field.machine(k, r).map(|m| &m.input),
            Self::MachineOutput(k, r) => field.machine(k, r).map(|m| &m.output),
        }
    }

    /// The original's task waypoint (50–65) of this location, if it is a slot.
    pub fn waypoint(self, field: &Field) -> Option<WaypointId> {
        self.slot(field).map(|s| s.waypoint)
    }

    /// The robot pose for this location: the slot's pick pose, or the field's start pose.
    pub fn robot_pose(self, field: &Field) -> Option<Pose2> {
        match self {
            Self::Start => Some(field.start_pose()),
            other => other.slot(field).map(|s| s.pick_pose),
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Start => write!(f, "start"),
            Self::Incoming(i) => write!(f, "IW{i}"),
            Self::Outgoing(i) => write!(f, "OW{i}"),
            Self::MachineInput(k, r) => write!(f, "{k:?}{r}in"),
            Self::MachineOutput(k, r) => write!(f, "{k:?}{r}out"),
        }
    }
}

/// Travel-time estimates between locations, supplied by the caller (e.g. from the navigation
/// stack's planned paths and speed limits).
pub trait TravelTimes {
    /// Seconds to drive from the pose at `from` to the pose at `to`, docked and ready to
    /// pick or drop (finite, ≥ 0; 0 when `from == to`).
    fn travel_s(&self, from: Location, to: Location) -> f64;
}

/// A full table of travel times, s, indexed by [`Location::index`].
#[derive(Clone, Debug, PartialEq)]
pub struct TravelMatrix {
    seconds: [[f64; LOCATION_COUNT]; LOCATION_COUNT],
}

impl TravelMatrix {
    /// Tabulate `times` (each pair asked once).
    pub fn from_times(times: &(impl TravelTimes + ?Sized)) -> Self {
        let mut seconds = [[0.0; LOCATION_COUNT]; LOCATION_COUNT];
        for (i, &a) in Location::ALL.iter().enumerate() {
            for (j, &b) in Location::ALL.iter().enumerate() {
                seconds[i][j] = if i == j { 0.0 } else { times.travel_s(a, b) };
            }
        }
        Self { seconds }
    }

    /// From a raw table indexed by [`Location::index`].
    pub fn from_table(seconds: [[f64; LOCATION_COUNT]; LOCATION_COUNT]) -> Self {
        Self { seconds }
    }

    /// Seconds from location index `from` to `to`.
    pub fn between(&self, from: usize, to: usize) -> f64 {
        self.seconds[from][to]
    }

    /// Add `extra_s` to every trip that ends at location index `to` (out of range: no
    /// change): a slot the robot could not reach is then planned only when nothing else
    /// will do.
    pub fn penalise_arrivals_at(&mut self, to: usize, extra_s: f64) {
        for (from, row) in self.seconds.iter_mut().enumerate() {
            if let Some(s) = row.get_mut(to)
                && from != to
            {
                *s += extra_s;
            }
        }
    }

    /// Whether every entry is finite and ≥ 0.
    pub fn is_valid(&self) -> bool {
        self.seconds
            .iter()
            .flatten()
            .all(|s| s.is_finite() && *s >= 0.0)
    }
}

impl TravelTimes for TravelMatrix {
    fn travel_s(&self, from: Location, to: Location) -> f64 {
        match (from.index(), to.index()) {
            (Some(i), Some(j)) => self.seconds[i][j],
            _ => f64::INFINITY,
        }
    }
}

/// A crude estimate for when no navigation stack is at hand: the longer of the straight line
/// between the robot poses at a constant speed and the heading change at a constant turn rate
/// (a mecanum robot turns while it drives, as the original did). It ignores walls,
/// acceleration and docking, so it underestimates, most around a machine block.
#[derive(Clone, Debug, PartialEq)]
pub struct StraightLineTimes {
    poses: [Pose2; LOCATION_COUNT],
    speed_m_s: f64,
    turn_rate_rad_s: f64,
}

impl StraightLineTimes {
    /// The original's limits: 0.4 m/s and 0.8 rad/s (original-system.md §6.3).
    pub const ORIGINAL_SPEED_M_S: f64 = 0.4;
    /// See [`Self::ORIGINAL_SPEED_M_S`].
    pub const ORIGINAL_TURN_RATE_RAD_S: f64 = 0.8;

    /// Estimates on `field` at `speed_m_s` and `turn_rate_rad_s`.
    pub fn new(field: &Field, speed_m_s: f64, turn_rate_rad_s: f64) -> Self {
        let poses = Location::ALL.map(|l| l.robot_pose(field).unwrap_or_default());
        Self {
            poses,
            speed_m_s,
            turn_rate_rad_s,
        }
    }
}

impl TravelTimes for StraightLineTimes {
    fn travel_s(&self, from: Location, to: Location) -> f64 {
        let (Some(i), Some(j)) = (from.index(), to.index()) else {
            return f64::INFINITY;
        };
        let (a, b) = (self.poses[i], self.poses[j]);
        let turn = wrap_angle(b.yaw_rad - a.yaw_rad).abs();
        f64::max(
            a.position().distance(b.position()) / self.speed_m_s,
            turn / self.turn_rate_rad_s,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_index_densely_and_name_the_original_waypoints() {
        let field = Field::competition();
        for (i, l) in Location::ALL.iter().enumerate() {
            assert_eq!(l.index(), Some(i));
            assert!(l.robot_pose(&field).is_some());
        }
        assert_eq!(Location::Incoming(4).index(), None);
        let ids: Vec<u8> = Location::ALL[1..]
            .iter()
            .map(|l| l.waypoint(&field).unwrap().0)
            .collect();
        assert_eq!(
            ids,
            [
                50, 51, 52, 53, 62, 63, 64, 65, 56, 60, 57, 61, 54, 58, 55, 59
            ]
        );
    }

    #[test]
    fn straight_line_times_take_the_longer_of_driving_and_turning() {
        let field = Field::competition();
        let t = StraightLineTimes::new(&field, 0.4, 0.8);
        let (a, b) = (Location::Incoming(0), Location::Incoming(1));
        assert!(
            (t.travel_s(a, b) - 0.150 / 0.4).abs() < 1e-9,
            "same heading, 150 mm"
        );
        let (a, b) = (Location::Incoming(3), Location::Outgoing(0));
        let turn_s = std::f64::consts::PI / 0.8;
        let drive_s = a
            .robot_pose(&field)
            .unwrap()
            .position()
            .distance(b.robot_pose(&field).unwrap().position())
            / 0.4;
        assert!((t.travel_s(a, b) - drive_s.max(turn_s)).abs() < 1e-9);
        let m = TravelMatrix::from_times(&t);
        assert!(m.is_valid());
        assert_eq!(m.travel_s(a, a), 0.0);
        assert_eq!(m.travel_s(Location::Outgoing(7), a), f64::INFINITY);
    }
}
