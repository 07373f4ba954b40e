//! Warehouses and machine blocks: their walls (as obstacles) and their box slots.
//!
//! Numbers: competition.md §1.2 (warehouses) and §1.3 (machines), from the organisers'
//! `ratf_machine.scad`; mm in the comments, metres in the code.

use std::f64::consts::{FRAC_PI_2, PI};
use std::fmt;

use super::geometry::{Pose2, Rect, Vec2, wrap_angle};
use super::waypoints::WaypointId;

/// Warehouse back wall and machine central wall height, m: 130 mm (§1.2, §1.3).
pub const WALL_HEIGHT_M: f64 = 0.130;
/// Divider height, m: 65 mm (§1.2, §1.3).
pub const DIVIDER_HEIGHT_M: f64 = 0.065;
/// Wall and divider thickness, m: 20 mm (§1.2, §1.3).
pub const WALL_THICKNESS_M: f64 = 0.020;
/// Part footprint across its plate face, m: 90 mm (§1.7).
pub const PART_WIDTH_M: f64 = 0.090;
/// Part footprint along its plate normal (its depth), m: 60 mm (§1.7).
pub const PART_DEPTH_M: f64 = 0.060;
/// Part height including its 5 mm feet, m: 65 mm (§1.7).
pub const PART_HEIGHT_M: f64 = 0.065;
/// Metal plate on the part's front face, width × height, m: 80 × 20 mm (§1.7).
pub const PART_PLATE_SIZE_M: (f64, f64) = (0.080, 0.020);

/// Distance from a slot's plate face to the robot centre at the pick/drop pose of the
/// default robot, m.
///
/// 0.165 = 0.150 (its front face, [`DEFAULT_FRONT_FACE_M`]) + 0.010 (the dividers stick
/// out 70 mm, 10 mm beyond a 60 mm deep box, so a flat-fronted robot stops at the divider
/// tips) + 0.005 clearance. Assumption: the magnet/switch reaches the plate across those
/// 15 mm, standing that far proud of the front face. A robot whose outline differs docks at
/// its own ([`pick_standoff_m`]). The original stopped 127–177 mm from the plate
/// (original-system.md §6.1), so its robot centre was not at its geometric centre or it
/// stopped short.
pub const PICK_STANDOFF_M: f64 = 0.165;

/// The default robot's front face ahead of its wheels' centre, m: half of its centred
/// 0.30 m body (`robot.footprint_length_m`).
pub const DEFAULT_FRONT_FACE_M: f64 = 0.150;

/// The pick standoff of a robot whose front face stands `front_face_m` ahead of its
/// wheels' centre, m: its magnet's face as far proud of that face as the default robot's
/// (15 mm), so [`PICK_STANDOFF_M`] to the bit on the default body.
pub fn pick_standoff_m(front_face_m: f64) -> f64 {
    PICK_STANDOFF_M + (front_face_m - DEFAULT_FRONT_FACE_M)
}

/// A part's type (competition.md §1.7).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub enum PartColor {
    /// Raw: machine A, then B, then the outgoing warehouse.
    Red,
    /// Intermediate: machine B (or A in round 2), then the outgoing warehouse.
    Green,
    /// Final: the outgoing warehouse.
    Blue,
}

impl PartColor {
    /// The organisers' server letter.
    pub const fn letter(self) -> char {
        match self {
            Self::Red => 'R',
            Self::Green => 'G',
            Self::Blue => 'B',
        }
    }

    /// The colour for a server letter (`None` for `X` and anything else).
    pub const fn from_letter(letter: char) -> Option<Self> {
        match letter {
            'R' => Some(Self::Red),
            'G' => Some(Self::Green),
            'B' => Some(Self::Blue),
            _ => None,
        }
    }
}

impl fmt::Display for PartColor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            Self::Red => "red",
            Self::Green => "green",
            Self::Blue => "blue",
        };
        f.write_str(name)
    }
}

/// What an obstacle is part of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObstacleKind {
    /// A warehouse back wall (130 mm high).
    WarehouseWall,
    /// A warehouse divider (65 mm high).
    WarehouseDivider,
    /// A machine block's central wall (130 mm high).
    MachineWall,
    /// A machine block's divider (65 mm high).
    MachineDivider,
}

/// An axis-aligned box standing on the floor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Obstacle {
    /// Footprint in the world frame, m.
    pub rect: Rect,
    /// Height above the floor, m.
    pub height_m: f64,
    /// What it is.
    pub kind: ObstacleKind,
}

/// The two warehouses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WarehouseKind {
    /// Top-left; raw parts wait here (slots = wall markers 50–53).
    Incoming,
    /// Bottom-right; finished parts go here (slots = wall markers 62–65).
    Outgoing,
}

/// The two machine types (two blocks, one per type, two rows each; §1.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MachineKind {
    /// Left block, x ≈ −0.35 m; rows y = 0 (markers 56/57) and y = −0.15 (60/61).
    A,
    /// Right block, x ≈ +0.35 m; rows y = 0.15 (markers 54/55) and y = 0 (58/59).
    B,
}

/// What kind of place a slot is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlotKind {
    /// An incoming-warehouse slot (pick).
    Incoming,
    /// An outgoing-warehouse slot (drop).
    Outgoing,
    /// A machine's input side (−x of its wall; drop).
    MachineInput,
    /// A machine's output side (+x of its wall; pick).
    MachineOutput,
}

/// A place where one part stands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slot {
    /// What kind of place.
    pub kind: SlotKind,
    /// Centre of the part's footprint, world frame, m.
    pub box_center: Vec2,
    /// Centre of the part's front face (the one carrying the plate), on the floor, m.
    pub plate_face_center: Vec2,
    /// Direction the plate faces (outward normal), world yaw, rad.
    pub face_normal_rad: f64,
    /// The wall marker above this slot (table B).
    pub marker_id: u8,
    /// The waypoint-graph leaf serving this slot (original-system.md §6.1).
    pub waypoint: WaypointId,
    /// Robot pose to pick or drop the part: facing the plate, centred on it,
    /// [`PICK_STANDOFF_M`] from it.
    pub pick_pose: Pose2,
}

impl Slot {
    fn new(kind: SlotKind, box_center: Vec2, face_normal_rad: f64, id: u8) -> Self {
        let plate_face_center =
            box_center + Vec2::from_angle(face_normal_rad) * (PART_DEPTH_M / 2.0);
        let mut slot = Self {
            kind,
            box_center,
            plate_face_center,
            face_normal_rad,
            marker_id: id,
            waypoint: WaypointId(id),
            pick_pose: Pose2::default(),
        };
        slot.pick_pose = slot.pose_at_standoff(PICK_STANDOFF_M);
        slot
    }

    /// The robot pose that faces the plate squarely with its centre `standoff_m` from it.
    pub fn pose_at_standoff(&self, standoff_m: f64) -> Pose2 {
        let p = self.plate_face_center + Vec2::from_angle(self.face_normal_rad) * standoff_m;
        Pose2::new(p.x, p.y, wrap_angle(self.face_normal_rad + PI))
    }

    /// The part's footprint when it stands in this slot, m.
    pub fn box_rect(&self) -> Rect {
        let along_x = self.face_normal_rad.cos().abs() > 0.5;
        let (sx, sy) = if along_x {
            (PART_DEPTH_M, PART_WIDTH_M)
        } else {
            (PART_WIDTH_M, PART_DEPTH_M)
        };
        Rect::centered(self.box_center, sx, sy)
    }
}

/// A warehouse: back wall, five dividers, four slots (index 0..3 = increasing x, the
/// order 5dpo maps the server's letters to; competition.md §3).
#[derive(Clone, Debug, PartialEq)]
pub struct Warehouse {
    /// Which one.
    pub kind: WarehouseKind,
    /// Back wall 620 × 20 mm, 130 mm high.
    pub wall: Obstacle,
    /// Five dividers 20 × 70 mm, 65 mm high, every 150 mm.
    pub dividers: [Obstacle; 5],
    /// Four slots, increasing x.
    pub slots: [Slot; 4],
}

impl Warehouse {
    /// Build one. `wall_x_min_m`: the wall's left end (−0.780 incoming, 0.160 outgoing);
    /// `side`: +1 for the top (incoming), −1 for the bottom (outgoing).
    fn new(kind: WarehouseKind, wall_x_min_m: f64, side: f64, first_id: u8) -> Self {
        let wall = Obstacle {
            rect: Rect::from_spans(
                wall_x_min_m,
                wall_x_min_m + 0.620,
                side * 0.565,
                side * 0.585,
            ),
            height_m: WALL_HEIGHT_M,
            kind: ObstacleKind::WarehouseWall,
        };
        let dividers = std::array::from_fn(|k| {
            let x = wall_x_min_m + 0.010 + 0.150 * k as f64;
            Obstacle {
                rect: Rect::from_spans(x - 0.010, x + 0.010, side * 0.495, side * 0.565),
                height_m: DIVIDER_HEIGHT_M,
                kind: ObstacleKind::WarehouseDivider,
            }
        });
        let slot_kind = match kind {
            WarehouseKind::Incoming => SlotKind::Incoming,
            WarehouseKind::Outgoing => SlotKind::Outgoing,
        };
        let slots = std::array::from_fn(|k| {
            let center = Vec2::new(wall_x_min_m + 0.085 + 0.150 * k as f64, side * 0.535);
            Slot::new(slot_kind, center, -side * FRAC_PI_2, first_id + k as u8)
        });
        Self {
            kind,
            wall,
            dividers,
            slots,
        }
    }

    /// The incoming warehouse (competition.md §1.2).
    pub fn incoming() -> Self {
        Self::new(WarehouseKind::Incoming, -0.780, 1.0, 50)
    }

    /// The outgoing warehouse: the incoming one rotated 180° (competition.md §1.2).
    pub fn outgoing() -> Self {
        Self::new(WarehouseKind::Outgoing, 0.160, -1.0, 62)
    }
}

/// One machine: a row of a machine block, input on −x, output on +x.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Machine {
    /// Machine type.
    pub kind: MachineKind,
    /// Row index within the block: 0 = upper (larger y), 1 = lower.
    pub row: usize,
    /// Input slot (−x side of the wall; the robot drops here).
    pub input: Slot,
    /// Output slot (+x side; the robot picks the processed part here).
    pub output: Slot,
}

/// A machine block: central wall 320 × 20 mm along y, three dividers 160 × 20 mm, two rows.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineBlock {
    /// Machine type of both rows.
    pub kind: MachineKind,
    /// Central wall.
    pub wall: Obstacle,
    /// Dividers at the wall's ends and centre.
    pub dividers: [Obstacle; 3],
    /// Rows 0 (upper) and 1 (lower).
    pub machines: [Machine; 2],
}

impl MachineBlock {
    fn new(kind: MachineKind, wall_x_m: f64, upper_row_y_m: f64, ids: [(u8, u8); 2]) -> Self {
        let lower_row_y_m = upper_row_y_m - 0.150;
        let wall = Obstacle {
            rect: Rect::from_spans(
                wall_x_m - 0.010,
                wall_x_m + 0.010,
                lower_row_y_m - 0.085,
                upper_row_y_m + 0.085,
            ),
            height_m: WALL_HEIGHT_M,
            kind: ObstacleKind::MachineWall,
        };
        let dividers = std::array::from_fn(|k| {
            let y = upper_row_y_m + 0.075 - 0.150 * k as f64;
            Obstacle {
                rect: Rect::from_spans(wall_x_m - 0.080, wall_x_m + 0.080, y - 0.010, y + 0.010),
                height_m: DIVIDER_HEIGHT_M,
                kind: ObstacleKind::MachineDivider,
            }
        });
        let box_offset_m = WALL_THICKNESS_M / 2.0 + PART_DEPTH_M / 2.0;
        let machines = std::array::from_fn(|row| {
            let y = upper_row_y_m - 0.150 * row as f64;
            let (input_id, output_id) = ids[row];
            Machine {
                kind,
                row,
                input: Slot::new(
                    SlotKind::MachineInput,
                    Vec2::new(wall_x_m - box_offset_m, y),
                    PI,
                    input_id,
                ),
                output: Slot::new(
                    SlotKind::MachineOutput,
                    Vec2::new(wall_x_m + box_offset_m, y),
                    0.0,
                    output_id,
                ),
            }
        });
        Self {
            kind,
            wall,
            dividers,
            machines,
        }
    }

    /// Machine block A (left; competition.md §1.3; markers 56/57, 60/61).
    pub fn a() -> Self {
        Self::new(MachineKind::A, -0.3475, 0.0, [(56, 57), (60, 61)])
    }

    /// Machine block B (right; competition.md §1.3; markers 54/55, 58/59).
    pub fn b() -> Self {
        Self::new(MachineKind::B, 0.3475, 0.150, [(54, 55), (58, 59)])
    }

    /// The wall and the dividers.
    pub fn obstacles(&self) -> impl Iterator<Item = Obstacle> + '_ {
        std::iter::once(self.wall).chain(self.dividers.iter().copied())
    }
}

impl Warehouse {
    /// The wall and the dividers.
    pub fn obstacles(&self) -> impl Iterator<Item = Obstacle> + '_ {
        std::iter::once(self.wall).chain(self.dividers.iter().copied())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn warehouse_numbers_match_competition_md() {
        let w = Warehouse::incoming();
        assert!(close(w.wall.rect.min.x, -0.780) && close(w.wall.rect.max.x, -0.160));
        let xs: Vec<f64> = w.dividers.iter().map(|d| d.rect.center().x).collect();
        for (x, want) in xs.iter().zip([-0.770, -0.620, -0.470, -0.320, -0.170]) {
            assert!(close(*x, want), "{x} vs {want}");
        }
        for (s, want) in w.slots.iter().zip([-0.695, -0.545, -0.395, -0.245]) {
            assert!(close(s.box_center.x, want) && close(s.box_center.y, 0.535));
            assert!(close(s.plate_face_center.y, 0.505));
        }
        let o = Warehouse::outgoing();
        assert!(close(o.wall.rect.min.y, -0.585) && close(o.wall.rect.max.y, -0.565));
        for (s, want) in o.slots.iter().zip([0.245, 0.395, 0.545, 0.695]) {
            assert!(close(s.box_center.x, want) && close(s.plate_face_center.y, -0.505));
            assert!(close(s.face_normal_rad, FRAC_PI_2));
        }
    }

    #[test]
    fn machine_numbers_match_competition_md() {
        let a = MachineBlock::a();
        assert!(close(a.wall.rect.min.x, -0.3575) && close(a.wall.rect.max.y, 0.085));
        assert!(close(a.wall.rect.min.y, -0.235));
        assert!(close(a.machines[0].input.box_center.x, -0.3875));
        assert!(close(a.machines[0].input.plate_face_center.x, -0.4175));
        assert!(close(a.machines[1].output.plate_face_center.x, -0.2775));
        assert!(close(a.dividers[2].rect.center().y, -0.225));
        let b = MachineBlock::b();
        assert!(close(b.wall.rect.min.y, -0.085) && close(b.wall.rect.max.y, 0.235));
        assert!(close(b.machines[0].input.box_center.x, 0.3075));
        assert!(close(b.machines[0].output.plate_face_center.x, 0.4175));
        assert!(close(b.machines[1].input.box_center.y, 0.0));
        assert_eq!(b.machines[0].input.marker_id, 54);
        assert_eq!(b.machines[1].output.marker_id, 59);
    }

    #[test]
    fn boxes_fit_between_dividers_and_touch_their_wall() {
        let blocks = [MachineBlock::a(), MachineBlock::b()];
        let houses = [Warehouse::incoming(), Warehouse::outgoing()];
        let mut slots: Vec<(Slot, Vec<Obstacle>)> = Vec::new();
        for b in &blocks {
            for m in &b.machines {
                slots.push((m.input, b.obstacles().collect()));
                slots.push((m.output, b.obstacles().collect()));
            }
        }
        for h in &houses {
            for s in &h.slots {
                slots.push((*s, h.obstacles().collect()));
            }
        }
        for (slot, obstacles) in slots {
            let r = slot.box_rect().inflated(-1e-6);
            assert!(obstacles.iter().all(|o| !o.rect.overlaps(r)), "{slot:?}");
            let touching = slot.box_rect().inflated(1e-6);
            assert_eq!(
                obstacles
                    .iter()
                    .filter(|o| o.rect.overlaps(touching))
                    .count(),
                1,
                "box must touch its wall only: {slot:?}"
            );
        }
    }
}
