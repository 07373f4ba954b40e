//! What the core reports, in words a team uses.

use serde::{Deserialize, Serialize};

use crate::field::geometry::Pose2;
use crate::field::stations::SlotKind;
use crate::field::waypoints::WaypointId;
use crate::field::{Field, MachineKind, PartColor};
use crate::mission::SkipReason;

use super::input::DeviceKind;

/// Something that happened in the core.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum Event {
    /// The part list is known (from the server's first `IWP`, or forced by the operator):
    /// the round's clock starts.
    PartList {
        /// Incoming slots 1–4 (`None` = empty).
        parts: [Option<PartColor>; 4],
        /// The operator forced the start (no answer from the server needed).
        forced: bool,
    },
    /// The mission began an action: fetch the part at `pick`, put it at `drop`.
    ActionStarted {
        /// Where the part stands (slot waypoint).
        pick: WaypointId,
        /// Where it goes.
        drop: WaypointId,
        /// Its colour as the planner knows it.
        color: Option<PartColor>,
        /// Attempt number, from 1.
        attempt: u32,
    },
    /// The magnet holds the part.
    Picked {
        /// Where it was.
        slot: WaypointId,
        /// Its colour as the planner knows it.
        color: Option<PartColor>,
    },
    /// The part was released at its drop slot and the switch opened.
    Placed {
        /// Where it is now.
        slot: WaypointId,
        /// Its colour as the planner knew it when picked.
        color: Option<PartColor>,
    },
    /// The switch opened while carrying: the part fell off the magnet; the robot stops and
    /// looks for it where it was last held (`mission::search`).
    PartSlipped {
        /// Its colour as the planner knows it.
        color: Option<PartColor>,
    },
    /// The carried part stopped getting closer to its drop (`mission::jam`): the robot
    /// backs off, lets it go and grips it again centred on its plate.
    PartJammed {
        /// Its colour as the planner knows it.
        color: Option<PartColor>,
    },
    /// The core's hold let the carried part go away from its drop (`mission`, "Held"): the
    /// robot moved on a little after the magnet went off, so the part may stand off the
    /// magnet's centre; the robot grips it again centred on its plate (`mission::search`).
    PartLetGoInHold {
        /// Its colour as the planner knows it.
        color: Option<PartColor>,
    },
    /// The core's hold let the carried part go near its drop but off its drop pose
    /// (`mission`, "Held"): the robot stands until the server says whether the part lies in
    /// its slot, and looks for it if not.
    PartLetGoNearDrop {
        /// Its colour as the planner knows it.
        color: Option<PartColor>,
    },
    /// The part that fell off is held again.
    Regripped {
        /// Its colour as the planner knows it.
        color: Option<PartColor>,
    },
    /// An action failed for good; the planner carries on with the other parts.
    Skipped {
        /// Where the part stood.
        pick: WaypointId,
        /// Where it was to go.
        drop: WaypointId,
        /// Why.
        reason: SkipReason,
    },
    /// Nothing left to do: the robot parks.
    Finished,
    /// The server's strings disagreed with what the robot knew; it re-plans from them.
    ServerDisagrees {
        /// Parts that vanished, appeared, moved or changed colour.
        parts: usize,
        /// The four strings, `IWP OWP MAP MBP`.
        areas: String,
    },
    /// A request to the server got no valid answer in all its tries.
    RefereeFailed {
        /// Why (the tracker's words).
        message: String,
    },
    /// The operator stopped the robot.
    Stopped,
    /// The operator let it go on (or handed the wheels back to the mission).
    Resumed,
    /// The operator took the wheels ([`super::OperatorCommand::Drive`] or
    /// [`super::OperatorCommand::OpenLoop`]): the mission pauses.
    ManualDrive,
    /// The operator placed the robot: the pose estimate restarted here.
    PoseSet {
        /// The pose, world frame.
        pose: Pose2,
    },
    /// The gyro's bias, measured while the robot stood still before the round, went to the
    /// pose estimator.
    GyroBiasMeasured {
        /// The z bias, rad/s.
        bias_rad_s: f64,
    },
    /// No start-up gyro bias (the robot moved, or too few samples): the estimator learns it
    /// on its own.
    GyroBiasRefused {
        /// Why.
        reason: String,
    },
    /// A device that had spoken fell silent: the robot holds still until it speaks again,
    /// the magnet off (a lidar that still streams keeps a held part for a while,
    /// [`super::BLIND_MAGNET_HOLD_US`]; [`super::SilenceGuard`]).
    DeviceSilent {
        /// Which device.
        device: DeviceKind,
        /// The silence that triggered the hold, ms.
        silent_ms: u64,
    },
    /// A silent device speaks again: the hold is over.
    DeviceBack {
        /// Which device.
        device: DeviceKind,
    },
    /// A device failed; the robot stopped.
    DeviceFault {
        /// Which device.
        device: DeviceKind,
        /// What happened.
        message: String,
        /// Its thread is reopening the port: the robot holds still until the device speaks
        /// again ([`DeviceBack`](Self::DeviceBack)) instead of stopping for good.
        #[serde(default)]
        reconnecting: bool,
    },
}

fn color_word(color: Option<PartColor>) -> &'static str {
    match color {
        Some(PartColor::Red) => "red",
        Some(PartColor::Green) => "green",
        Some(PartColor::Blue) => "blue",
        None => "unknown",
    }
}

fn letters(parts: &[Option<PartColor>; 4]) -> String {
    parts
        .iter()
        .map(|c| c.map_or('X', PartColor::letter))
        .collect()
}

/// A slot as a team names it: "incoming slot 2", "machine A (upper) input",
/// "outgoing slot 4"; slots are numbered 1–4 in the field's order (competition.md §1).
pub fn slot_name(field: &Field, id: WaypointId) -> String {
    let Some(slot) = field.slot_for_waypoint(id) else {
        return format!("waypoint {}", id.0);
    };
    let numbered = |kind: SlotKind, name: &str| {
        let index = field
            .slots()
            .filter(|s| s.kind == kind)
            .position(|s| s.waypoint == id)
            .map_or(0, |i| i + 1);
        format!("{name} slot {index}")
    };
    match slot.kind {
        SlotKind::Incoming => numbered(SlotKind::Incoming, "incoming"),
        SlotKind::Outgoing => numbered(SlotKind::Outgoing, "outgoing"),
        SlotKind::MachineInput | SlotKind::MachineOutput => {
            let side = if slot.kind == SlotKind::MachineInput {
                "input"
            } else {
                "output"
            };
            for kind in [MachineKind::A, MachineKind::B] {
                for machine in &field.machine_block(kind).machines {
                    if machine.input.waypoint == id || machine.output.waypoint == id {
                        let row = if machine.row == 0 { "upper" } else { "lower" };
                        let letter = if kind == MachineKind::A { 'A' } else { 'B' };
                        return format!("machine {letter} ({row}) {side}");
                    }
                }
            }
            format!("machine {side} {}", id.0)
        }
    }
}

impl Event {
    /// The event in a team's words, e.g. `picked red from incoming slot 1`.
    pub fn describe(&self, field: &Field) -> String {
        let slot = |id: &WaypointId| slot_name(field, *id);
        match self {
            Self::PartList { parts, forced } => {
                let how = if *forced {
                    ", forced by the operator"
                } else {
                    " from the server"
                };
                format!("part list {}{how}: the clock starts", letters(parts))
            }
            Self::ActionStarted {
                pick,
                drop,
                color,
                attempt,
            } => {
                let again = if *attempt > 1 {
                    format!(" (attempt {attempt})")
                } else {
                    String::new()
                };
                format!(
                    "going for the {} part at {}, for {}{again}",
                    color_word(*color),
                    slot(pick),
                    slot(drop)
                )
            }
            Self::Picked { slot: at, color } => {
                format!("picked {} from {}", color_word(*color), slot(at))
            }
            Self::Placed { slot: at, color } => {
                format!("placed {} on {}", color_word(*color), slot(at))
            }
            Self::PartSlipped { color } => format!(
                "the {} part fell off the magnet: stopped, looking for it where it was last held",
                color_word(*color)
            ),
            Self::PartJammed { color } => format!(
                "the {} part stopped short of its drop: backing off to grip it again centred",
                color_word(*color)
            ),
            Self::PartLetGoInHold { color } => format!(
                "the hold let the {} part go on the way: gripping it again centred",
                color_word(*color)
            ),
            Self::PartLetGoNearDrop { color } => format!(
                "the hold let the {} part go near its drop: asking the server whether it lies there",
                color_word(*color)
            ),
            Self::Regripped { color } => {
                format!("picked the {} part up again", color_word(*color))
            }
            Self::Skipped { pick, drop, reason } => {
                let why = match reason {
                    SkipReason::NoContact => "the switch never closed on it",
                    SkipReason::NotHeld => "the magnet did not hold it",
                    SkipReason::Unreachable => "no way there in time",
                    SkipReason::Stuck => "it stayed on the magnet",
                    SkipReason::Dropped => {
                        "it fell off the magnet and was not found where it was last held"
                    }
                };
                format!(
                    "gave up the part at {} for {}: {why}",
                    slot(pick),
                    slot(drop)
                )
            }
            Self::Finished => "finished: nothing left to do, parked".to_owned(),
            Self::ServerDisagrees { parts, areas } => {
                format!("the server disagrees on {parts} part(s) ({areas}): re-planning")
            }
            Self::RefereeFailed { message } => format!("server: {message}"),
            Self::Stopped => "stopped by the operator".to_owned(),
            Self::Resumed => "resumed by the operator".to_owned(),
            Self::ManualDrive => "driven by the operator; the mission waits".to_owned(),
            Self::PoseSet { pose } => format!(
                "pose set by the operator: ({:.3}, {:.3}) m, {:.1}°",
                pose.x,
                pose.y,
                pose.yaw_rad.to_degrees()
            ),
            Self::GyroBiasMeasured { bias_rad_s } => format!(
                "gyro bias {:.3} °/s measured while still",
                bias_rad_s.to_degrees()
            ),
            Self::GyroBiasRefused { reason } => {
                format!("no start-up gyro bias ({reason}); the localiser learns it")
            }
            Self::DeviceSilent { device, silent_ms } => {
                let magnet = match device {
                    DeviceKind::Lidar => format!(
                        "a part on the magnet held for up to {} s",
                        super::BLIND_MAGNET_HOLD_US / 1_000_000
                    ),
                    _ => "magnet off".to_owned(),
                };
                format!(
                    "{device} silent for {silent_ms} ms: holding still, {magnet}, until it \
                     speaks again (check its cable and power if this lasts)"
                )
            }
            Self::DeviceBack { device } => format!("{device} speaks again: going on"),
            Self::DeviceFault {
                device,
                message,
                reconnecting: true,
            } => format!(
                "{device} lost: {message}; holding still, magnet off, until it speaks again"
            ),
            Self::DeviceFault {
                device,
                message,
                reconnecting: false,
            } => format!("{device} failed: {message}; stopped"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_read_as_a_team_names_them() {
        let field = Field::competition();
        let names: Vec<String> = field
            .slots()
            .map(|s| slot_name(&field, s.waypoint))
            .collect();
        for expected in [
            "incoming slot 1",
            "incoming slot 4",
            "outgoing slot 1",
            "outgoing slot 4",
            "machine A (upper) input",
            "machine B (lower) output",
        ] {
            assert!(names.iter().any(|n| n == expected), "{expected}: {names:?}");
        }
        // Every slot has its own name.
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "{names:?}");
    }

    #[test]
    fn events_read_as_sentences() {
        let field = Field::competition();
        let incoming = field
            .slots()
            .find(|s| s.kind == SlotKind::Incoming)
            .unwrap()
            .waypoint;
        let picked = Event::Picked {
            slot: incoming,
            color: Some(PartColor::Red),
        };
        assert_eq!(picked.describe(&field), "picked red from incoming slot 1");
        let list = Event::PartList {
            parts: [Some(PartColor::Red), None, Some(PartColor::Green), None],
            forced: true,
        };
        assert_eq!(
            list.describe(&field),
            "part list RXGX, forced by the operator: the clock starts"
        );
    }
}
