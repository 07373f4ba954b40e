//! What the page shows, one message of the stream (`GET /api/stream`, Server-Sent Events,
//! each `data:` line one [`Snapshot`] as JSON). Units in the names; world frame, metres.

use serde::Serialize;

use ratf_core::field::PartColor;
use ratf_core::field::geometry::Pose2;
use ratf_core::runtime::{Event, Phase};

/// A pose: x, y (m), yaw (rad).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PoseView {
    /// m.
    pub x: f64,
    /// m.
    pub y: f64,
    /// rad, counter-clockwise.
    pub yaw_rad: f64,
}

impl From<Pose2> for PoseView {
    fn from(p: Pose2) -> Self {
        Self {
            x: p.x,
            y: p.y,
            yaw_rad: p.yaw_rad,
        }
    }
}

/// One line of the timeline.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EventLine {
    /// Robot time, s.
    pub t_s: f64,
    /// What kind (the page colours by it): `start`, `action`, `retry`, `pick`, `drop`,
    /// `points`, `skip`, `collision`, `operator`, `server`, `fault`, `finished`, `info`.
    pub kind: &'static str,
    /// In a team's words.
    pub text: String,
}

/// The timeline kind of a core event.
pub fn event_kind(event: &Event) -> &'static str {
    match event {
        Event::PartList { .. } => "start",
        Event::ActionStarted { attempt, .. } if *attempt > 1 => "retry",
        Event::ActionStarted { .. } => "action",
        Event::Picked { .. } | Event::Regripped { .. } => "pick",
        Event::PartSlipped { .. }
        | Event::PartJammed { .. }
        | Event::PartLetGoInHold { .. }
        | Event::PartLetGoNearDrop { .. } => "fault",
        Event::Placed { .. } => "drop",
        Event::Skipped { .. } => "skip",
        Event::Finished => "finished",
        Event::ServerDisagrees { .. } | Event::RefereeFailed { .. } => "server",
        Event::Stopped | Event::Resumed | Event::ManualDrive | Event::PoseSet { .. } => "operator",
        Event::GyroBiasMeasured { .. } | Event::GyroBiasRefused { .. } => "info",
        Event::DeviceSilent { .. } | Event::DeviceFault { .. } => "fault",
        Event::DeviceBack { .. } => "info",
    }
}

/// Where the robot is going.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Target {
    /// The slot's waypoint number.
    pub waypoint: u8,
    /// Where, m.
    pub at: [f64; 2],
    /// `pick` or `drop`.
    pub what: &'static str,
    /// The slot's name.
    pub name: String,
}

/// A part as the robot's events place it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PartView {
    /// The slot's waypoint number.
    pub waypoint: u8,
    /// The slot's centre, m.
    pub at: [f64; 2],
    /// `R`, `G`, `B`, or `?` when unknown.
    pub color: char,
}

/// A colour letter, `?` when unknown.
pub fn color_letter(color: Option<PartColor>) -> char {
    color.map_or('?', PartColor::letter)
}

/// The last lidar revolution's beacons.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct BeaconsView {
    /// Observations applied.
    pub used: u32,
    /// Observations refused by the χ² gate.
    pub gated: u32,
    /// Clusters near a beacon refused for their shape.
    pub rejected: u32,
    /// Beacons with no candidate.
    pub unseen: u32,
    /// Per beacon B0..B3: an observation was offered.
    pub seen: [bool; 4],
}

/// Wheel references against measured speeds, wheel rad/s, motor index order (0 back-right,
/// 1 back-left, 2 front-right, 3 front-left).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct WheelsView {
    /// What the core commanded at the last host tick.
    pub reference_rad_s: [f32; 4],
    /// What the last telemetry batch measured.
    pub measured_rad_s: [f64; 4],
}

/// Link and device health.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct HealthView {
    /// Mega telemetry batches per second of robot time.
    pub wheel_hz: f64,
    /// Lidar revolutions per second.
    pub scan_hz: f64,
    /// IMU samples per second.
    pub imu_hz: f64,
    /// Mega resets so far.
    pub mega_resets: u64,
    /// Lidar revolutions whose packets failed their check code (integrity errors).
    pub scans_with_dropped_packets: u64,
    /// Lidar scans in a row with no beacon used (the localiser relocks at its
    /// `relock_after_scans`, and counts from 0 again).
    pub scans_without_beacons: u32,
    /// The localiser is lost: it relocked and no scan since has fixed the pose with three or
    /// more beacons that agree (`localisation::Health::relocking`).
    pub lost: bool,
    /// Device faults so far, in the core's words.
    pub faults: Vec<String>,
}

/// The replay player's state (only in `ratf replay --hmi`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ReplayView {
    /// The recording's length, s of robot time.
    pub duration_s: f64,
    /// Playing (else paused).
    pub playing: bool,
    /// Robot seconds per wall second.
    pub speed: f64,
}

/// One message of the stream: everything the page shows that changes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Snapshot {
    /// `sim`, `robot` or `replay`.
    pub mode: &'static str,
    /// The simulated round and seed (the simulator only).
    pub round: Option<(u8, u64)>,
    /// Robot time of the last input, s.
    pub time_s: f64,
    /// Round clock: s since the part list, when it is known.
    pub clock_s: Option<f64>,
    /// Where the round is.
    pub phase: Phase,
    /// The operator stopped the robot.
    pub stopped: bool,
    /// The operator drives.
    pub manual: bool,
    /// Parts placed (the robot's own count).
    pub placed: u32,
    /// Points as the referee scores them (the simulator knows; on the robot, `None`).
    pub points: Option<u32>,
    /// The pose estimate.
    pub pose: PoseView,
    /// Position covariance `[xx, xy, yy]`, m².
    pub covariance_m2: [f64; 3],
    /// Heading standard deviation, rad.
    pub heading_std_rad: f64,
    /// The true pose (simulator, or a simulated recording).
    pub truth: Option<PoseView>,
    /// The last lidar revolution, world frame through the estimate, m (rounded to mm).
    pub scan: Vec<[f32; 2]>,
    /// Beacons of the last revolution.
    pub beacons: BeaconsView,
    /// The slot the robot is heading for.
    pub target: Option<Target>,
    /// The route it follows there, world points, m (empty when none).
    pub path: Vec<[f64; 2]>,
    /// Parts where the robot's events put them.
    pub parts: Vec<PartView>,
    /// The part on the magnet.
    pub carrying: Option<char>,
    /// The magnet's level.
    pub magnet: bool,
    /// The box switch.
    pub switch_pressed: bool,
    /// Wheel references and measured speeds.
    pub wheels: WheelsView,
    /// Link and device health.
    pub health: HealthView,
    /// The timeline so far (the latest [`super::tap::TIMELINE_LINES`]).
    pub events: Vec<EventLine>,
    /// The replay player.
    pub replay: Option<ReplayView>,
}
