//! The shop floor of Robot@Factory 4.0: one source of truth for the simulator, the
//! planners, localisation and the plots.
//!
//! Frame (competition.md §1.1, architecture.md): origin at the floor's centre, +x right
//! towards the outgoing warehouse, +y up towards the incoming warehouse, metres, yaw
//! counter-clockwise in radians. Everything here is built from the organisers' drawing and
//! rules (competition.md §1) and the original's graph (original-system.md §6.1).

pub mod geometry;
pub mod markers;
pub mod oriented_rect;
pub mod stations;
pub mod waypoints;

use std::f64::consts::FRAC_PI_2;

pub use geometry::{Circle, Pose2, Rect, Segment, Vec2, wrap_angle};
pub use markers::{Beacon, FloorMarker, WallMarker};
pub use oriented_rect::OrientedRect;
pub use stations::{
    Machine, MachineBlock, MachineKind, Obstacle, ObstacleKind, PART_DEPTH_M, PART_HEIGHT_M,
    PART_PLATE_SIZE_M, PART_WIDTH_M, PICK_STANDOFF_M, PartColor, Slot, SlotKind, Warehouse,
    WarehouseKind,
};
pub use waypoints::{Edge, Waypoint, WaypointGraph, WaypointId};

/// Printed floor: two A0 sheets, 1682 × 1189 mm (competition.md §1.1).
pub const PRINTED_SIZE_M: (f64, f64) = (1.682, 1.189);

/// The whole shop floor.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    printed_area: Rect,
    incoming: Warehouse,
    outgoing: Warehouse,
    machine_a: MachineBlock,
    machine_b: MachineBlock,
    floor_markers: Vec<FloorMarker>,
    wall_markers: Vec<WallMarker>,
    beacons: [Beacon; 4],
    start_area: Rect,
    start_pose: Pose2,
    graph: WaypointGraph,
}

impl Field {
    /// The competition floor (2022–2026 layout).
    pub fn competition() -> Self {
        Self {
            printed_area: Rect::centered(Vec2::ZERO, PRINTED_SIZE_M.0, PRINTED_SIZE_M.1),
            incoming: Warehouse::incoming(),
            outgoing: Warehouse::outgoing(),
            machine_a: MachineBlock::a(),
            machine_b: MachineBlock::b(),
            floor_markers: markers::floor_markers(),
            wall_markers: markers::wall_markers(),
            beacons: markers::beacons(),
            // competition.md §1.6: ≈ 350 × 350 mm in the bottom-left corner, scaled from a
            // schematic that is not to scale (approximate).
            start_area: Rect::from_spans(-0.841, -0.490, -0.594, -0.245),
            // The original EKF's initial pose: floor marker 21, facing +y (original §5).
            start_pose: Pose2::new(-0.695, -0.355, FRAC_PI_2),
            graph: WaypointGraph::original(),
        }
    }

    /// This floor for a robot whose magnet's face stands `standoff_m` ahead of its wheels'
    /// centre: every slot's pick and drop pose that far from its plate
    /// (`config::RobotConfig::pick_standoff_m`).
    pub fn with_pick_standoff(mut self, standoff_m: f64) -> Self {
        let machines = [&mut self.machine_a, &mut self.machine_b]
            .into_iter()
            .flat_map(|b| b.machines.iter_mut())
            .flat_map(|m| [&mut m.input, &mut m.output]);
        let slots = self
            .incoming
            .slots
            .iter_mut()
            .chain(self.outgoing.slots.iter_mut())
            .chain(machines);
        for slot in slots {
            slot.pick_pose = slot.pose_at_standoff(standoff_m);
        }
        self
    }

    /// The printed area, x ∈ [−0.841, 0.841], y ∈ [−0.5945, 0.5945] m. No perimeter wall.
    pub fn printed_area(&self) -> Rect {
        self.printed_area
    }

    /// A warehouse.
    pub fn warehouse(&self, kind: WarehouseKind) -> &Warehouse {
        match kind {
            WarehouseKind::Incoming => &self.incoming,
            WarehouseKind::Outgoing => &self.outgoing,
        }
    }

    /// Incoming-warehouse slot `index` (0..3, increasing x; server letter `index`).
    pub fn incoming_slot(&self, index: usize) -> Option<&Slot> {
        self.incoming.slots.get(index)
    }

    /// Outgoing-warehouse slot `index` (0..3, increasing x; server letter `index`).
    pub fn outgoing_slot(&self, index: usize) -> Option<&Slot> {
        self.outgoing.slots.get(index)
    }

    /// A machine block.
    pub fn machine_block(&self, kind: MachineKind) -> &MachineBlock {
        match kind {
            MachineKind::A => &self.machine_a,
            MachineKind::B => &self.machine_b,
        }
    }

    /// The machine of type `kind` in row `row` (0 = upper, 1 = lower), or `None`.
    pub fn machine(&self, kind: MachineKind, row: usize) -> Option<&Machine> {
        self.machine_block(kind).machines.get(row)
    }

    /// Every slot: incoming 0..3, outgoing 0..3, then A rows (input, output), B rows.
    pub fn slots(&self) -> impl Iterator<Item = &Slot> + '_ {
        let machines = [&self.machine_a, &self.machine_b]
            .into_iter()
            .flat_map(|b| b.machines.iter())
            .flat_map(|m| [&m.input, &m.output]);
        self.incoming
            .slots
            .iter()
            .chain(self.outgoing.slots.iter())
            .chain(machines)
    }

    /// The slot served by a task waypoint (50–65), or `None`.
    pub fn slot_for_waypoint(&self, id: WaypointId) -> Option<&Slot> {
        self.slots().find(|s| s.waypoint == id)
    }

    /// All walls and dividers (the only obstacles on the floor; competition.md §1.1).
    pub fn obstacles(&self) -> Vec<Obstacle> {
        self.incoming
            .obstacles()
            .chain(self.outgoing.obstacles())
            .chain(self.machine_a.obstacles())
            .chain(self.machine_b.obstacles())
            .collect()
    }

    /// Floor markers (table A).
    pub fn floor_markers(&self) -> &[FloorMarker] {
        &self.floor_markers
    }

    /// Wall markers (table B).
    pub fn wall_markers(&self) -> &[WallMarker] {
        &self.wall_markers
    }

    /// The four lidar beacons B0..B3.
    pub fn beacons(&self) -> &[Beacon; 4] {
        &self.beacons
    }

    /// This floor with the beacons' centres at `centres_m` (world frame, m, B0..B3): the
    /// positions a team measured on the day.
    pub fn with_beacon_centres(mut self, centres_m: [[f64; 2]; 4]) -> Self {
        for (beacon, [x, y]) in self.beacons.iter_mut().zip(centres_m) {
            beacon.circle = Circle::new(Vec2::new(x, y), beacon.circle.radius_m);
        }
        self
    }

    /// The start area (approximate, competition.md §1.6).
    pub fn start_area(&self) -> Rect {
        self.start_area
    }

    /// The default start pose (−0.695, −0.355) m, facing +y.
    pub fn start_pose(&self) -> Pose2 {
        self.start_pose
    }

    /// The waypoint graph.
    pub fn waypoints(&self) -> &WaypointGraph {
        &self.graph
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn beacons_at_the_original_positions() {
        let f = Field::competition();
        let want = [
            (0.888, 0.538),
            (-0.888, 0.538),
            (0.888, -0.538),
            (-0.888, -0.538),
        ];
        for (b, (x, y)) in f.beacons().iter().zip(want) {
            assert_eq!(b.circle.center, Vec2::new(x, y));
            assert_eq!(b.circle.radius_m, 0.045);
            assert!(b.height_m <= 0.5);
            assert!(
                !f.printed_area().contains(b.circle.center),
                "beacons stand outside the print"
            );
        }
    }

    #[test]
    fn no_waypoint_inside_an_obstacle_and_none_off_the_floor() {
        let f = Field::competition();
        let obstacles = f.obstacles();
        assert_eq!(obstacles.len(), 2 * 6 + 2 * 4);
        for w in f.waypoints().waypoints() {
            for o in &obstacles {
                assert!(
                    !o.rect.contains(w.position),
                    "waypoint {} inside {:?}",
                    w.id,
                    o
                );
            }
            assert!(
                f.printed_area().contains(w.position),
                "waypoint {} off the floor",
                w.id
            );
        }
    }

    #[test]
    fn no_edge_crosses_a_wall() {
        let f = Field::competition();
        let g = f.waypoints();
        for e in g.edges() {
            let s = Segment::new(g.position(e.a).unwrap(), g.position(e.b).unwrap());
            for o in f.obstacles() {
                assert!(
                    !o.rect.intersects_segment(s),
                    "edge {}-{} crosses {:?}",
                    e.a,
                    e.b,
                    o
                );
            }
        }
    }

    #[test]
    fn pick_poses_are_square_to_their_face_and_match_the_graph_roles() {
        let f = Field::competition();
        let slots: Vec<&Slot> = f.slots().collect();
        assert_eq!(slots.len(), 16);
        for s in slots {
            let p = s.pick_pose;
            let normal = Vec2::from_angle(s.face_normal_rad);
            // Facing the plate.
            assert!(
                wrap_angle(p.yaw_rad - s.face_normal_rad - PI).abs() < 1e-12,
                "{s:?}"
            );
            // On the face normal through the plate centre, at the stand-off.
            let offset = p.position() - s.plate_face_center;
            assert!(offset.cross(normal).abs() < 1e-12, "{s:?}");
            assert!((offset.dot(normal) - stations::PICK_STANDOFF_M).abs() < 1e-12);
            // The task leaf's only neighbour lies on the same side of the face (approach).
            let (n, _) = f.waypoints().neighbours(s.waypoint)[0];
            let from = f.waypoints().position(n).unwrap() - s.plate_face_center;
            assert!(
                from.dot(normal) > 0.0,
                "slot {} approached from behind",
                s.waypoint
            );
            assert_eq!(s.marker_id, s.waypoint.0);
        }
        assert_eq!(f.incoming_slot(0).unwrap().waypoint, WaypointId(50));
        assert_eq!(f.outgoing_slot(3).unwrap().waypoint, WaypointId(65));
        assert!(f.incoming_slot(4).is_none());
        let a = f.machine(MachineKind::A, 1).unwrap();
        assert_eq!((a.input.waypoint.0, a.output.waypoint.0), (60, 61));
        let b = f.machine(MachineKind::B, 0).unwrap();
        assert_eq!((b.input.waypoint.0, b.output.waypoint.0), (54, 55));
        assert!(f.machine(MachineKind::B, 2).is_none());
        assert_eq!(
            f.slot_for_waypoint(WaypointId(57)).unwrap().kind,
            SlotKind::MachineOutput
        );
    }

    #[test]
    fn a_robot_with_its_own_standoff_gets_every_pick_pose_moved_along_its_normal() {
        let nominal = Field::competition();
        let own = Field::competition().with_pick_standoff(0.18);
        assert_eq!(own.slots().count(), 16);
        for (a, b) in nominal.slots().zip(own.slots()) {
            let moved = b.pick_pose.position() - a.pick_pose.position();
            let normal = Vec2::from_angle(a.face_normal_rad);
            assert!(
                (moved - normal * (0.18 - PICK_STANDOFF_M)).norm() < 1e-12,
                "{b:?}"
            );
            assert_eq!(a.pick_pose.yaw_rad, b.pick_pose.yaw_rad);
            assert_eq!(a.box_center, b.box_center);
        }
        // The default standoff leaves the floor as it was, to the bit.
        assert_eq!(
            Field::competition().with_pick_standoff(PICK_STANDOFF_M),
            nominal
        );
    }

    #[test]
    fn pick_pose_footprint_clears_every_obstacle() {
        let f = Field::competition();
        for s in f.slots() {
            let p = s.pick_pose;
            // 0.30 m square footprint, axis-aligned at these yaws (multiples of 90°).
            let r = Rect::centered(p.position(), 0.30, 0.30).inflated(-1e-9);
            for o in f.obstacles() {
                assert!(
                    !o.rect.overlaps(r),
                    "slot {} pick pose hits {:?}",
                    s.waypoint,
                    o
                );
            }
        }
    }

    #[test]
    fn markers_tables_and_start() {
        let f = Field::competition();
        assert_eq!(f.floor_markers().len(), 33);
        assert_eq!(f.wall_markers().len(), 16);
        let m21 = f.floor_markers().iter().find(|m| m.id == 21).unwrap();
        assert_eq!(m21.position, f.start_pose().position());
        assert!(f.start_area().contains(f.start_pose().position()));
        for s in f.slots() {
            let m = f
                .wall_markers()
                .iter()
                .find(|m| m.id == s.marker_id)
                .unwrap();
            assert!(wrap_angle(m.facing_rad - s.face_normal_rad).abs() < 1e-12);
            assert!(
                m.position.distance(s.box_center) < 0.045,
                "marker {} above its box",
                m.id
            );
        }
    }
}
