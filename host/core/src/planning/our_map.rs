//! Our road map: the original's waypoint graph with the rows in front of both warehouses
//! moved to the middle of their corridors, for the robot's own outline.
//!
//! The original's outgoing row (waypoints 23–26, the outgoing slots' graph neighbours, at
//! y = −0.245 m) runs between machine B's lower end (y = −0.085 m) and the outgoing
//! dividers' tips (y = −0.495 m). A robot carrying a part there faces the warehouse
//! (heading −90°): its 30 cm body reaches 0.15 m behind its centre, the part
//! [`PICK_STANDOFF_M`] + [`PART_DEPTH_M`] = 0.225 m ahead. On the original's row that
//! leaves the body's back edge 10 mm from machine B and the part's front 25 mm from the
//! dividers: in the realistic world (the true outline, the follower's and the estimate's few
//! millimetres) the body grazed machine B there in 9 of 13 collisions over the tuning seeds
//! 1–10. Moved to where both gaps are equal, each is 17.5 mm. The incoming row (waypoints
//! 0–3, y = 0.255 m, between machine A's upper end and the incoming dividers' tips) is the
//! same corridor turned over, and the original's row leaves 15 and 20 mm there: centred too,
//! 17.5 mm each (at 0.2525 m). A body off its wheels' centre (`robot.body_center_x_m`)
//! reaches its own distances behind and ahead, and its rows move with them: a body 2 cm
//! ahead of its wheels carried its part's front into the incoming dividers on the 30 cm
//! square's row. The original preset keeps the original's graph.

use crate::field::geometry::Vec2;
use crate::field::{Field, WarehouseKind, WaypointGraph, WaypointId};
#[cfg(doc)]
use crate::field::{PART_DEPTH_M, PICK_STANDOFF_M};
use crate::planning::shortcuts::Footprint;

/// A warehouse's row: its vertices (each of the warehouse's slots' neighbour in the graph)
/// and the y (m) that centres the robot with outline `body` carrying a part towards the
/// warehouse (its back face [`Footprint::back_m`] behind its centre, the part's far face
/// [`Footprint::part_reach_m`] ahead), between the obstacles above and below the row's
/// reach. `None` when the field has no obstacle on either side.
pub fn centred_row(
    field: &Field,
    graph: &WaypointGraph,
    body: &Footprint,
    warehouse: WarehouseKind,
) -> Option<(Vec<WaypointId>, f64)> {
    let half = body.width_m / 2.0 + body.center_m.y.abs();
    let row: Vec<(WaypointId, Vec2)> = field
        .warehouse(warehouse)
        .slots
        .iter()
        .filter_map(|slot| graph.neighbours(slot.waypoint).first())
        .filter_map(|&(id, _)| graph.position(id).map(|p| (id, p)))
        .collect();
    let (first, last) = (row.first()?.1, row.last()?.1);
    let (x_lo, x_hi) = (first.x.min(last.x) - half, first.x.max(last.x) + half);
    let row_y = row.iter().map(|(_, p)| p.y).sum::<f64>() / row.len() as f64;
    let beside = field
        .obstacles()
        .into_iter()
        .map(|o| o.rect)
        .filter(|r| r.max.x > x_lo && r.min.x < x_hi);
    let (mut above, mut below) = (f64::INFINITY, f64::NEG_INFINITY);
    for rect in beside {
        if rect.min.y > row_y {
            above = above.min(rect.min.y);
        } else if rect.max.y < row_y {
            below = below.max(rect.max.y);
        }
    }
    if !above.is_finite() || !below.is_finite() {
        return None;
    }
    // Facing the warehouse (above the row for the incoming one, below for the outgoing):
    // the part's front at y + reach and the back edge at y − back, or the other way round;
    // equal gaps to `above` and `below`.
    let towards_warehouse = match warehouse {
        WarehouseKind::Incoming => 1.0,
        WarehouseKind::Outgoing => -1.0,
    };
    let y = (above + below - towards_warehouse * (body.part_reach_m() - body.back_m())) / 2.0;
    Some((row.into_iter().map(|(id, _)| id).collect(), y))
}

/// Our graph for a robot with outline `body`: the original's with both warehouses' rows
/// centred ([`centred_row`]).
pub fn our_graph(field: &Field, body: &Footprint) -> WaypointGraph {
    let graph = field.waypoints().clone();
    let moved: Vec<(WaypointId, Vec2)> = [WarehouseKind::Incoming, WarehouseKind::Outgoing]
        .into_iter()
        .filter_map(|warehouse| centred_row(field, &graph, body, warehouse))
        .flat_map(|(row, y)| {
            row.into_iter()
                .filter_map(|id| graph.position(id).map(|p| (id, Vec2::new(p.x, y))))
                .collect::<Vec<_>>()
        })
        .collect();
    graph.with_moved(&moved)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::RobotConfig;
    use crate::field::geometry::Pose2;
    use crate::planning::shortcuts::FreeSpace;

    const BODY: Footprint = Footprint {
        length_m: 0.30,
        width_m: 0.30,
        center_m: Vec2::ZERO,
        magnet_m: crate::field::PICK_STANDOFF_M,
        carrying: true,
    };

    /// The least margin at which `body` carrying a part, facing `warehouse`, is free all
    /// along that warehouse's row of `graph`, m (to 0.5 mm).
    fn row_margin_m(
        field: &Field,
        graph: &WaypointGraph,
        body: Footprint,
        warehouse: WarehouseKind,
    ) -> f64 {
        let (row, _) = centred_row(field, graph, &body, warehouse).unwrap();
        let ends = [row[0], row[row.len() - 1]].map(|id| graph.position(id).unwrap());
        let heading = match warehouse {
            WarehouseKind::Incoming => std::f64::consts::FRAC_PI_2,
            WarehouseKind::Outgoing => -std::f64::consts::FRAC_PI_2,
        };
        let mut margin_m = 0.0;
        loop {
            let space = FreeSpace::new(field, &[], body, margin_m + 0.0005);
            let free = (0..=100).all(|k| {
                let p = ends[0] + (ends[1] - ends[0]) * (f64::from(k) / 100.0);
                space.pose_is_free(Pose2::new(p.x, p.y, heading))
            });
            if !free {
                return margin_m;
            }
            margin_m += 0.0005;
        }
    }

    #[test]
    fn the_original_rows_leave_10_and_15_mm_and_ours_centre_the_carrying_body_with_17_mm() {
        let field = Field::competition();
        let original = field.waypoints();
        let ours = our_graph(&field, &BODY);
        for (warehouse, ids, y_m, original_m) in [
            (WarehouseKind::Outgoing, [23, 24, 25, 26], -0.2525, 0.010),
            (WarehouseKind::Incoming, [0, 1, 2, 3], 0.2525, 0.015),
        ] {
            let (row, y) = centred_row(&field, original, &BODY, warehouse).unwrap();
            assert_eq!(row, ids.map(WaypointId));
            assert!((y - y_m).abs() < 1e-9, "{warehouse:?}: {y}");
            let before = row_margin_m(&field, original, BODY, warehouse);
            let after = row_margin_m(&field, &ours, BODY, warehouse);
            assert!(
                (before - original_m).abs() <= 0.0005,
                "{warehouse:?}: {before}"
            );
            assert!((0.017..=0.018).contains(&after), "{warehouse:?}: {after}");
        }
    }

    #[test]
    fn a_body_ahead_of_its_wheels_is_centred_by_its_own_faces() {
        let field = Field::competition();
        let robot = RobotConfig {
            body_center_x_m: 0.010,
            ..RobotConfig::default()
        };
        let body = Footprint::of_robot(&robot, true);
        let ours = our_graph(&field, &body);
        // Reaching 10 mm further ahead and 10 mm less behind: each row 10 mm further from
        // its warehouse, with the same gaps; the centred body's rows would leave it 7.5 mm.
        for (warehouse, y_m) in [
            (WarehouseKind::Outgoing, -0.2425),
            (WarehouseKind::Incoming, 0.2425),
        ] {
            let (_, y) = centred_row(&field, field.waypoints(), &body, warehouse).unwrap();
            assert!((y - y_m).abs() < 1e-9, "{warehouse:?}: {y}");
            let after = row_margin_m(&field, &ours, body, warehouse);
            assert!((0.017..=0.018).contains(&after), "{warehouse:?}: {after}");
            let centred = row_margin_m(&field, &our_graph(&field, &BODY), body, warehouse);
            assert!(
                (0.007..=0.008).contains(&centred),
                "{warehouse:?}: {centred}"
            );
        }
    }

    #[test]
    fn only_the_two_rows_move_and_the_edges_follow() {
        let field = Field::competition();
        let original = field.waypoints();
        let ours = our_graph(&field, &BODY);
        for (a, b) in original.waypoints().iter().zip(ours.waypoints()) {
            assert_eq!(a.id, b.id);
            let moved = (23..=26).contains(&a.id.0) || (0..=3).contains(&a.id.0);
            assert_eq!(a.position != b.position, moved, "{a:?} {b:?}");
            assert_eq!(a.position.x, b.position.x);
        }
        for (a, b) in original.edges().iter().zip(ours.edges()) {
            assert_eq!((a.a, a.b), (b.a, b.b));
            let (pa, pb) = (ours.position(b.a).unwrap(), ours.position(b.b).unwrap());
            assert!((b.length_m - pa.distance(pb)).abs() < 1e-12);
        }
    }
}
