//! ArUco markers (competition.md §1.4, tables A and B) and the lidar beacons (§1.5).

use std::f64::consts::{FRAC_PI_2, PI};

use super::geometry::{Circle, Vec2};

/// Side of a floor marker, m: 60 mm (competition.md §1.4).
pub const FLOOR_MARKER_SIDE_M: f64 = 0.060;
/// Side of a wall marker, m: 40 mm, stated from 2023 on (competition.md §1.4).
pub const WALL_MARKER_SIDE_M: f64 = 0.040;
/// Height of a wall marker's centre above the floor, m: 100 mm (competition.md table B).
pub const WALL_MARKER_HEIGHT_M: f64 = 0.100;

/// A marker lying flat on the floor, axis-aligned (competition.md table A).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloorMarker {
    /// ArUco id (DICT_5X5_100 or larger).
    pub id: u8,
    /// Centre in the world frame, m.
    pub position: Vec2,
}

/// A marker on a warehouse or machine wall, above the boxes (competition.md table B).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WallMarker {
    /// ArUco id, 50–65.
    pub id: u8,
    /// Centre projected on the floor, world frame, m.
    pub position: Vec2,
    /// Height of the centre above the floor, m.
    pub height_m: f64,
    /// Direction the printed side faces, rad (world yaw of its outward normal). Derived
    /// from the geometry (competition.md table B, "Where / faces" column).
    pub facing_rad: f64,
}

/// A cylindrical beacon pole seen by the lidar (competition.md §1.5, original-system.md §5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beacon {
    /// Index in the original's order B0..B3 (`sdpo_ratf_ros_localization.yaml`).
    pub index: usize,
    /// Pole cross-section in the world frame (centre and radius), m.
    pub circle: Circle,
    /// Pole height, m. 0.5 m: the rules' maximum; assumption that the poles use it
    /// (the original's rviz model draws 0.5 m).
    pub height_m: f64,
}

/// Floor markers, table A (rules table 3.1), mm.
const FLOOR_TABLE_MM: [(u8, f64, f64); 33] = [
    (0, -695.0, 355.0),
    (1, -545.0, 355.0),
    (2, -395.0, 355.0),
    (3, -245.0, 355.0),
    (4, 0.0, 355.0),
    (5, 695.0, 355.0),
    (6, 0.0, 150.0),
    (7, 227.0, 150.0),
    (8, 468.0, 150.0),
    (9, 695.0, 150.0),
    (10, -695.0, 0.0),
    (11, -468.0, 0.0),
    (12, -227.0, 0.0),
    (13, 0.0, 0.0),
    (14, 227.0, 0.0),
    (15, 468.0, 0.0),
    (16, 695.0, 0.0),
    (17, -695.0, -150.0),
    (18, -468.0, -150.0),
    (19, -227.0, -150.0),
    (20, 0.0, -150.0),
    (21, -695.0, -355.0),
    (22, 0.0, -355.0),
    (23, 245.0, -355.0),
    (24, 395.0, -355.0),
    (25, 545.0, -355.0),
    (26, 695.0, -355.0),
    (30, 227.0, 355.0),
    (31, 468.0, 355.0),
    (32, -468.0, -355.0),
    (33, -227.0, -355.0),
    (34, -695.0, 150.0),
    (35, 695.0, -150.0),
];

/// Wall markers, table B (rules table 3.2, 2024 v1.4 = 2026 v2.0): id, x, y (mm), facing.
const WALL_TABLE_MM: [(u8, f64, f64, f64); 16] = [
    (50, -695.0, 565.0, -FRAC_PI_2),
    (51, -545.0, 565.0, -FRAC_PI_2),
    (52, -395.0, 565.0, -FRAC_PI_2),
    (53, -245.0, 565.0, -FRAC_PI_2),
    (54, 338.0, 150.0, PI),
    (55, 358.0, 150.0, 0.0),
    (56, -357.5, 0.0, PI),
    (57, -337.5, 0.0, 0.0),
    (58, 337.5, 0.0, PI),
    (59, 357.5, 0.0, 0.0),
    (60, -357.5, -150.0, PI),
    (61, -337.5, -150.0, 0.0),
    (62, 245.0, -565.0, FRAC_PI_2),
    (63, 395.0, -565.0, FRAC_PI_2),
    (64, 545.0, -565.0, FRAC_PI_2),
    (65, 695.0, -565.0, FRAC_PI_2),
];

/// Beacon centres, m, in the original's order (`sdpo_ratf_ros_localization.yaml`, their
/// own measurement; competition.md §1.5).
const BEACON_CENTRES_M: [(f64, f64); 4] = [
    (0.888, 0.538),
    (-0.888, 0.538),
    (0.888, -0.538),
    (-0.888, -0.538),
];

/// Beacon diameter, m: 90 mm poles (original `beacons_diam: 0.09`, paper §VI).
pub const BEACON_DIAMETER_M: f64 = 0.09;

/// The 33 floor markers of table A.
pub fn floor_markers() -> Vec<FloorMarker> {
    FLOOR_TABLE_MM
        .iter()
        .map(|&(id, x, y)| FloorMarker {
            id,
            position: Vec2::new(x / 1000.0, y / 1000.0),
        })
        .collect()
}

/// The 16 wall markers of table B.
pub fn wall_markers() -> Vec<WallMarker> {
    WALL_TABLE_MM
        .iter()
        .map(|&(id, x, y, facing_rad)| WallMarker {
            id,
            position: Vec2::new(x / 1000.0, y / 1000.0),
            height_m: WALL_MARKER_HEIGHT_M,
            facing_rad,
        })
        .collect()
}

/// The four beacons B0..B3.
pub fn beacons() -> [Beacon; 4] {
    std::array::from_fn(|index| {
        let (x, y) = BEACON_CENTRES_M[index];
        Beacon {
            index,
            circle: Circle::new(Vec2::new(x, y), BEACON_DIAMETER_M / 2.0),
            height_m: 0.5,
        }
    })
}
