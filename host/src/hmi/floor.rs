//! The shop floor as the page draws it (`GET /api/floor`): every shape in world
//! coordinates (m, +y up; architecture.md, "Conventions"), with the labels a team uses.

use serde::Serialize;

use ratf_core::config::Config;
use ratf_core::field::geometry::{Rect, Vec2};
use ratf_core::field::stations::SlotKind;
use ratf_core::field::{Field, MachineKind, WarehouseKind};
use ratf_core::runtime::slot_name;

/// An axis-aligned rectangle, m: `[x_min, y_min, x_max, y_max]`.
pub type Box4 = [f64; 4];

fn box4(rect: Rect) -> Box4 {
    [rect.min.x, rect.min.y, rect.max.x, rect.max.y]
}

fn xy(v: Vec2) -> [f64; 2] {
    [v.x, v.y]
}

/// A labelled area (a warehouse, a machine block).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Area {
    /// Its outline.
    pub rect: Box4,
    /// What a team calls it.
    pub label: String,
}

/// A slot where a part stands.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SlotView {
    /// The slot's waypoint number (events name slots by it).
    pub waypoint: u8,
    /// The box on the floor.
    pub rect: Box4,
    /// Short label drawn on the map (`I1`, `O4`, `A1 in`, `B2 out`).
    pub label: String,
    /// Full name (`incoming slot 1`, `machine A (upper) input`).
    pub name: String,
}

/// A numbered point.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Point {
    /// Its number.
    pub id: u8,
    /// Where, m.
    pub at: [f64; 2],
}

/// A beacon pole.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BeaconView {
    /// B0..B3 in the original's order.
    pub index: usize,
    /// Centre, m.
    pub at: [f64; 2],
    /// Radius, m.
    pub radius_m: f64,
}

/// Everything the page draws that does not move.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Floor {
    /// The printed floor.
    pub printed: Box4,
    /// The start area.
    pub start: Box4,
    /// Walls and dividers.
    pub obstacles: Vec<Box4>,
    /// Warehouses and machine blocks with their names.
    pub areas: Vec<Area>,
    /// Every slot.
    pub slots: Vec<SlotView>,
    /// The floor markers.
    pub markers: Vec<Point>,
    /// The beacon poles.
    pub beacons: Vec<BeaconView>,
    /// The waypoint graph's nodes.
    pub waypoints: Vec<Point>,
    /// Its edges, as pairs of waypoint numbers.
    pub edges: Vec<[u8; 2]>,
    /// The robot's footprint (length along x, width along y), m.
    pub footprint_m: [f64; 2],
    /// The lidar's mount on the robot (x, y m, yaw rad).
    pub lidar_mount: [f64; 3],
}

/// A slot's short label: `incoming slot 1` → `I1`, `machine A (upper) input` → `A1 in`.
fn short_label(name: &str, kind: SlotKind) -> String {
    let last = name.chars().last().unwrap_or('?');
    match kind {
        SlotKind::Incoming => format!("I{last}"),
        SlotKind::Outgoing => format!("O{last}"),
        SlotKind::MachineInput | SlotKind::MachineOutput => {
            let letter = if name.contains("machine A") { 'A' } else { 'B' };
            let row = if name.contains("upper") { 1 } else { 2 };
            let side = if kind == SlotKind::MachineInput {
                "in"
            } else {
                "out"
            };
            format!("{letter}{row} {side}")
        }
    }
}

impl Floor {
    /// The floor the robot believes (`config`'s measured field) with its footprint.
    pub fn new(config: &Config) -> Self {
        let field: Field = config.field.field();
        let mut areas = vec![
            Area {
                rect: box4(field.warehouse(WarehouseKind::Incoming).wall.rect),
                label: "incoming warehouse".into(),
            },
            Area {
                rect: box4(field.warehouse(WarehouseKind::Outgoing).wall.rect),
                label: "outgoing warehouse".into(),
            },
        ];
        for (kind, label) in [(MachineKind::A, "machine A"), (MachineKind::B, "machine B")] {
            areas.push(Area {
                rect: box4(field.machine_block(kind).wall.rect),
                label: label.into(),
            });
        }
        let slots = field
            .slots()
            .map(|slot| {
                let name = slot_name(&field, slot.waypoint);
                SlotView {
                    waypoint: slot.waypoint.0,
                    rect: box4(slot.box_rect()),
                    label: short_label(&name, slot.kind),
                    name,
                }
            })
            .collect();
        let graph = field.waypoints();
        let mount = config.robot.lidar_mount();
        Self {
            printed: box4(field.printed_area()),
            start: box4(field.start_area()),
            obstacles: field.obstacles().iter().map(|o| box4(o.rect)).collect(),
            areas,
            slots,
            markers: field
                .floor_markers()
                .iter()
                .map(|m| Point {
                    id: m.id,
                    at: xy(m.position),
                })
                .collect(),
            beacons: field
                .beacons()
                .iter()
                .map(|b| BeaconView {
                    index: b.index,
                    at: xy(b.circle.center),
                    radius_m: b.circle.radius_m,
                })
                .collect(),
            waypoints: graph
                .waypoints()
                .iter()
                .map(|w| Point {
                    id: w.id.0,
                    at: xy(w.position),
                })
                .collect(),
            edges: graph.edges().iter().map(|e| [e.a.0, e.b.0]).collect(),
            footprint_m: [
                config.robot.footprint_length_m,
                config.robot.footprint_width_m,
            ],
            lidar_mount: [mount.x, mount.y, mount.yaw_rad],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_floor_names_every_slot_warehouse_and_machine() {
        let floor = Floor::new(&Config::default());
        let labels: Vec<&str> = floor.slots.iter().map(|s| s.label.as_str()).collect();
        for expected in ["I1", "I4", "O1", "O4", "A1 in", "A2 out", "B1 in", "B2 out"] {
            assert!(labels.contains(&expected), "{expected} in {labels:?}");
        }
        assert_eq!(floor.areas.len(), 4);
        assert_eq!(floor.beacons.len(), 4);
        assert!(!floor.edges.is_empty() && !floor.waypoints.is_empty());
    }
}
