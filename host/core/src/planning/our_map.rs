//! Our road map: the original's waypoint graph with the row in front of the outgoing
//! warehouse moved to the middle of its corridor.
//!
//! The original's row (waypoints 23–26, the outgoing slots' graph neighbours, at y =
//! −0.245 m) runs between machine B's lower end (y = −0.085 m) and the outgoing dividers'
//! tips (y = −0.495 m). A robot carrying a part there faces the warehouse (heading −90°):
//! its 30 cm body reaches 0.15 m behind its centre, the part
//! [`PICK_STANDOFF_M`] + [`PART_DEPTH_M`] = 0.225 m ahead. On the original's row that
//! leaves the body's back edge 10 mm from machine B and the part's front 25 mm from the
//! dividers: in the realistic world (the true outline, the follower's and the estimate's few
//! millimetres) the body grazed machine B there in 9 of 13 collisions over the tuning seeds
//! 1–10. Moved to where both gaps are equal, each is 17.5 mm. The original preset keeps the
//! original's graph.

use crate::field::geometry::Vec2;
use crate::field::{Field, PART_DEPTH_M, PICK_STANDOFF_M, WaypointGraph, WaypointId};

/// How far the carried part reaches ahead of the robot's centre, m.
const PART_REACH_M: f64 = PICK_STANDOFF_M + PART_DEPTH_M;

/// The outgoing row's vertices (each outgoing slot's neighbour in the graph) and the y (m)
/// that centres the robot carrying a part towards the warehouse, `body_length_m` long,
/// between the obstacles above and below the row's reach. `None` when the field has no
/// obstacle on either side.
pub fn centred_outgoing_row(
    field: &Field,
    graph: &WaypointGraph,
    body_length_m: f64,
) -> Option<(Vec<WaypointId>, f64)> {
    let half = body_length_m / 2.0;
    let row: Vec<(WaypointId, Vec2)> = (0..4)
        .filter_map(|k| field.outgoing_slot(k))
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
    // Back edge at y + half, the part's front at y − reach: equal gaps to `above` and
    // `below`.
    let y = (above + below + PART_REACH_M - half) / 2.0;
    Some((row.into_iter().map(|(id, _)| id).collect(), y))
}

/// Our graph for a body `body_length_m` long: the original's with the outgoing row centred
/// ([`centred_outgoing_row`]).
pub fn our_graph(field: &Field, body_length_m: f64) -> WaypointGraph {
    let graph = field.waypoints().clone();
    let Some((row, y)) = centred_outgoing_row(field, &graph, body_length_m) else {
        return graph;
    };
    let moved: Vec<(WaypointId, Vec2)> = row
        .iter()
        .filter_map(|&id| graph.position(id).map(|p| (id, Vec2::new(p.x, y))))
        .collect();
    graph.with_moved(&moved)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::geometry::Pose2;
    use crate::planning::shortcuts::{Footprint, FreeSpace};

    const BODY_M: f64 = 0.30;

    /// The least margin at which the body carrying a part, facing the outgoing warehouse,
    /// is free all along the row of `graph`, m (to 0.5 mm).
    fn row_margin_m(field: &Field, graph: &WaypointGraph) -> f64 {
        let (row, _) = centred_outgoing_row(field, graph, BODY_M).unwrap();
        let ends = [row[0], row[row.len() - 1]].map(|id| graph.position(id).unwrap());
        let footprint = Footprint {
            length_m: BODY_M,
            width_m: BODY_M,
            carrying: true,
        };
        let mut margin_m = 0.0;
        loop {
            let space = FreeSpace::new(field, &[], footprint, margin_m + 0.0005);
            let free = (0..=100).all(|k| {
                let p = ends[0] + (ends[1] - ends[0]) * (f64::from(k) / 100.0);
                space.pose_is_free(Pose2::new(p.x, p.y, -std::f64::consts::FRAC_PI_2))
            });
            if !free {
                return margin_m;
            }
            margin_m += 0.0005;
        }
    }

    #[test]
    fn the_original_row_leaves_10_mm_and_ours_centres_the_carrying_body_with_17_mm_each_side() {
        let field = Field::competition();
        let original = field.waypoints();
        let (row, y) = centred_outgoing_row(&field, original, BODY_M).unwrap();
        assert_eq!(row, [23, 24, 25, 26].map(WaypointId));
        assert!((y - -0.2525).abs() < 1e-9, "{y}");
        let before = row_margin_m(&field, original);
        let ours = our_graph(&field, BODY_M);
        let after = row_margin_m(&field, &ours);
        assert!((0.0095..=0.0105).contains(&before), "{before}");
        assert!((0.017..=0.018).contains(&after), "{after}");
    }

    #[test]
    fn only_the_outgoing_row_moves_and_the_edges_follow() {
        let field = Field::competition();
        let original = field.waypoints();
        let ours = our_graph(&field, BODY_M);
        for (a, b) in original.waypoints().iter().zip(ours.waypoints()) {
            assert_eq!(a.id, b.id);
            let moved = (23..=26).contains(&a.id.0);
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
