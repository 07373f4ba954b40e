//! Shortest paths on the waypoint graph (original-system.md §6.1–6.2), with edges that can be
//! blocked or penalised at run time and collinear points merged.
//!
//! Differences from the original, on purpose: the start vertex is the nearest *non-task*
//! vertex whose straight line from the robot crosses no wall (the original took the nearest
//! of all vertices, task leaves included, which can be behind a wall), and collinear segments
//! are merged with a distance tolerance instead of exact floating-point equality of unit
//! vectors.

use std::collections::{BTreeMap, BinaryHeap};

use crate::field::geometry::{Segment, Vec2};
use crate::field::{Field, WaypointGraph, WaypointId};
use crate::planning::cheapest_first::Cheapest;

/// Run-time state of one undirected edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EdgeState {
    /// Usable at its length.
    Open,
    /// Not usable (e.g. a part lies on it).
    Blocked,
    /// Usable, its cost increased by `extra_m` (metres of equivalent length).
    Penalised {
        /// Added cost, m (finite, ≥ 0).
        extra_m: f64,
    },
}

/// Why a plan could not be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// The id is not a vertex of the graph.
    #[error("waypoint {0} is not in the graph")]
    UnknownVertex(WaypointId),
    /// The two ids are not joined by an edge.
    #[error("there is no edge {0}-{1}")]
    UnknownEdge(WaypointId, WaypointId),
    /// A penalty that is negative or not finite.
    #[error("edge penalty must be a finite number >= 0 m (got {0})")]
    BadPenalty(f64),
    /// Every path is blocked.
    #[error("no open path from waypoint {from} to waypoint {to}")]
    Unreachable {
        /// Start vertex.
        from: WaypointId,
        /// Goal vertex.
        to: WaypointId,
    },
    /// No vertex can be reached in a straight line from the robot.
    #[error("no waypoint is reachable in a straight line from ({0:.3}, {1:.3}) m")]
    NoStartVertex(f64, f64),
}

/// A shortest path: the vertices in order and its total cost (m, penalties included).
#[derive(Clone, Debug, PartialEq)]
pub struct GraphPath {
    /// Vertices from start to goal, both included.
    pub vertices: Vec<WaypointId>,
    /// Sum of the edge costs, m.
    pub cost_m: f64,
}

/// The waypoint graph with the run-time state of its edges.
#[derive(Clone, Debug, PartialEq)]
pub struct RoadMap {
    graph: WaypointGraph,
    states: BTreeMap<(WaypointId, WaypointId), EdgeState>,
}

/// Canonical key of an undirected edge.
fn key(a: WaypointId, b: WaypointId) -> (WaypointId, WaypointId) {
    (a.min(b), a.max(b))
}

impl RoadMap {
    /// Every edge open.
    pub fn new(graph: WaypointGraph) -> Self {
        let states = graph
            .edges()
            .iter()
            .map(|e| (key(e.a, e.b), EdgeState::Open))
            .collect();
        Self { graph, states }
    }

    /// The underlying graph.
    pub fn graph(&self) -> &WaypointGraph {
        &self.graph
    }

    /// Set the state of edge `a`–`b` (either order).
    pub fn set_edge(
        &mut self,
        a: WaypointId,
        b: WaypointId,
        state: EdgeState,
    ) -> Result<(), PlanError> {
        if let EdgeState::Penalised { extra_m } = state
            && !(extra_m.is_finite() && extra_m >= 0.0)
        {
            return Err(PlanError::BadPenalty(extra_m));
        }
        match self.states.get_mut(&key(a, b)) {
            Some(s) => {
                *s = state;
                Ok(())
            }
            None => Err(PlanError::UnknownEdge(a, b)),
        }
    }

    /// Open every edge again.
    pub fn reset_edges(&mut self) {
        self.states.values_mut().for_each(|s| *s = EdgeState::Open);
    }

    /// The cost of travelling edge `a`–`b`, m, or `None` when it is blocked or not an edge.
    pub fn edge_cost_m(&self, a: WaypointId, b: WaypointId) -> Option<f64> {
        let length = self
            .graph
            .neighbours(a)
            .iter()
            .find(|(n, _)| *n == b)
            .map(|(_, l)| *l)?;
        match self.states.get(&key(a, b))? {
            EdgeState::Open => Some(length),
            EdgeState::Blocked => None,
            EdgeState::Penalised { extra_m } => Some(length + extra_m),
        }
    }

    /// Dijkstra from `from` to `to`, stopping when the goal is settled. Ties between equal
    /// costs go to the smaller vertex id, and a vertex keeps the first predecessor that
    /// reached it at its final cost, so the result depends only on the graph and its state.
    pub fn shortest_path(&self, from: WaypointId, to: WaypointId) -> Result<GraphPath, PlanError> {
        for id in [from, to] {
            if self.graph.position(id).is_none() {
                return Err(PlanError::UnknownVertex(id));
            }
        }
        let mut best: BTreeMap<WaypointId, (f64, Option<WaypointId>)> = BTreeMap::new();
        let mut settled = std::collections::BTreeSet::new();
        let mut heap = BinaryHeap::new();
        best.insert(from, (0.0, None));
        heap.push(Cheapest {
            cost: 0.0,
            item: from,
        });
        while let Some(Cheapest {
            cost: cost_m,
            item: vertex,
        }) = heap.pop()
        {
            if !settled.insert(vertex) {
                continue;
            }
            if vertex == to {
                break;
            }
            for &(next, _) in self.graph.neighbours(vertex) {
                let Some(edge) = self.edge_cost_m(vertex, next) else {
                    continue;
                };
                let candidate = cost_m + edge;
                let better = best.get(&next).is_none_or(|(c, _)| candidate < *c);
                if better && !settled.contains(&next) {
                    best.insert(next, (candidate, Some(vertex)));
                    heap.push(Cheapest {
                        cost: candidate,
                        item: next,
                    });
                }
            }
        }
        if !settled.contains(&to) {
            return Err(PlanError::Unreachable { from, to });
        }
        let cost_m = best.get(&to).map_or(0.0, |(c, _)| *c);
        let mut vertices = vec![to];
        let mut at = to;
        while let Some(&(_, Some(previous))) = best.get(&at) {
            vertices.push(previous);
            at = previous;
        }
        vertices.reverse();
        Ok(GraphPath { vertices, cost_m })
    }

    /// The vertex to start from at `position`: the nearest vertex that does not serve a slot
    /// and whose straight line from `position` crosses no wall or divider grown by
    /// `clearance_m` (a point robot's check; the follower's shortcuts do the footprint).
    /// Ties go to the smaller id.
    pub fn start_vertex(
        &self,
        field: &Field,
        position: Vec2,
        clearance_m: f64,
    ) -> Result<WaypointId, PlanError> {
        let obstacles = field.obstacles();
        let mut candidates: Vec<(f64, WaypointId, Vec2)> = self
            .graph
            .waypoints()
            .iter()
            .filter(|w| field.slot_for_waypoint(w.id).is_none())
            .map(|w| (w.position.distance(position), w.id, w.position))
            .collect();
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        candidates
            .into_iter()
            .find(|&(_, _, p)| {
                let line = Segment::new(position, p);
                obstacles
                    .iter()
                    .all(|o| !o.rect.inflated(clearance_m).intersects_segment(line))
            })
            .map(|(_, id, _)| id)
            .ok_or(PlanError::NoStartVertex(position.x, position.y))
    }

    /// The positions of a path's vertices, m.
    pub fn positions(&self, path: &GraphPath) -> Vec<Vec2> {
        path.vertices
            .iter()
            .filter_map(|&id| self.graph.position(id))
            .collect()
    }
}

/// Drop every interior point that lies within `tolerance_m` of the straight line that
/// replaces it, in order along that line (so a reversal is never merged). Points closer
/// than `tolerance_m` to the previous kept one are dropped first. The first and last points
/// are always kept exactly. Every input point ends within `tolerance_m` of the result.
pub fn merge_collinear(points: &[Vec2], tolerance_m: f64) -> Vec<Vec2> {
    let (Some(&first), Some(&last)) = (points.first(), points.last()) else {
        return Vec::new();
    };
    let mut distinct: Vec<Vec2> = vec![first];
    for &p in &points[1..] {
        if distinct.last().is_some_and(|q| q.distance(p) > tolerance_m) {
            distinct.push(p);
        }
    }
    if points.len() > 1 {
        if distinct.len() > 1 {
            distinct.pop();
        }
        distinct.push(last);
    }
    let fits = |from: usize, to: usize| {
        let line = Segment::new(distinct[from], distinct[to]);
        let direction = distinct[to] - distinct[from];
        let mut previous = 0.0;
        distinct[from + 1..to].iter().all(|&p| {
            let t = (p - distinct[from]).dot(direction);
            let ok = t > previous
                && t < direction.dot(direction)
                && line.distance_to_point(p) <= tolerance_m;
            previous = t;
            ok
        })
    };
    let mut kept = vec![distinct[0]];
    let mut anchor = 0;
    for j in 2..distinct.len() {
        if !fits(anchor, j) {
            anchor = j - 1;
            kept.push(distinct[anchor]);
        }
    }
    if distinct.len() > 1 {
        kept.push(last);
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use petgraph::graph::{NodeIndex, UnGraph};
    use proptest::prelude::*;

    fn road_map() -> RoadMap {
        RoadMap::new(WaypointGraph::original())
    }

    #[test]
    fn known_path_and_its_cost() {
        let map = road_map();
        let path = map
            .shortest_path(WaypointId(21), WaypointId(50))
            .expect("start to incoming slot 0");
        let ids: Vec<u8> = path.vertices.iter().map(|v| v.0).collect();
        assert_eq!(ids, [21, 17, 10, 34, 0, 50]);
        let want = 0.205 + 0.150 + 0.150 + 0.105 + 0.105_118_980_208_143;
        assert!((path.cost_m - want).abs() < 1e-9, "{}", path.cost_m);
    }

    #[test]
    fn blocking_and_penalising_reroute_and_bad_input_is_an_error() {
        let mut map = road_map();
        let direct = map.shortest_path(WaypointId(13), WaypointId(4)).unwrap();
        assert_eq!(direct.vertices.len(), 3);
        map.set_edge(WaypointId(6), WaypointId(4), EdgeState::Blocked)
            .unwrap();
        let around = map.shortest_path(WaypointId(13), WaypointId(4)).unwrap();
        assert!(around.cost_m > direct.cost_m + 1.0, "{around:?}");
        map.reset_edges();
        map.set_edge(
            WaypointId(4),
            WaypointId(6),
            EdgeState::Penalised { extra_m: 0.5 },
        )
        .unwrap();
        let penalised = map.shortest_path(WaypointId(13), WaypointId(4)).unwrap();
        assert!((penalised.cost_m - direct.cost_m - 0.5).abs() < 1e-9);
        assert_eq!(
            map.set_edge(WaypointId(4), WaypointId(13), EdgeState::Blocked),
            Err(PlanError::UnknownEdge(WaypointId(4), WaypointId(13)))
        );
        assert_eq!(
            map.set_edge(
                WaypointId(4),
                WaypointId(6),
                EdgeState::Penalised { extra_m: -1.0 }
            ),
            Err(PlanError::BadPenalty(-1.0))
        );
        assert_eq!(
            map.shortest_path(WaypointId(40), WaypointId(4)),
            Err(PlanError::UnknownVertex(WaypointId(40)))
        );
        map.set_edge(WaypointId(0), WaypointId(50), EdgeState::Blocked)
            .unwrap();
        assert!(matches!(
            map.shortest_path(WaypointId(13), WaypointId(50)),
            Err(PlanError::Unreachable { .. })
        ));
    }

    #[test]
    fn every_task_vertex_is_reachable_from_the_start_area() {
        let field = Field::competition();
        let map = road_map();
        let area = field.start_area();
        let probes = [
            field.start_pose().position(),
            area.center(),
            area.min + Vec2::new(0.05, 0.05),
            area.max - Vec2::new(0.05, 0.05),
        ];
        for position in probes {
            let start = map.start_vertex(&field, position, 0.0).unwrap();
            assert!(field.slot_for_waypoint(start).is_none());
            for slot in field.slots() {
                let path = map.shortest_path(start, slot.waypoint).unwrap();
                assert_eq!(path.vertices.last(), Some(&slot.waypoint));
            }
        }
    }

    #[test]
    fn the_start_vertex_is_never_behind_a_wall() {
        let field = Field::competition();
        let map = road_map();
        // Just below the incoming warehouse's back wall, between dividers: task vertex 51 is
        // the nearest, but a task leaf is never a start vertex.
        let start = map
            .start_vertex(&field, Vec2::new(-0.545, 0.40), 0.0)
            .unwrap();
        assert_eq!(start, WaypointId(1));
        // Right of machine block A's wall: 57 (task) and 12 are nearer than 11 or 56, and
        // the wall hides 56.
        let start = map
            .start_vertex(&field, Vec2::new(-0.30, 0.0), 0.0)
            .unwrap();
        assert_eq!(start, WaypointId(12));
    }

    #[test]
    fn merging_keeps_corners_and_u_turns() {
        let p = |x: f64, y: f64| Vec2::new(x, y);
        let merged = merge_collinear(
            &[p(0.0, 0.0), p(0.1, 0.0005), p(0.2, 0.0), p(0.2, 0.2)],
            0.001,
        );
        assert_eq!(merged, [p(0.0, 0.0), p(0.2, 0.0), p(0.2, 0.2)]);
        let u = merge_collinear(&[p(0.0, 0.0), p(0.3, 0.0), p(0.1, 0.0)], 0.001);
        assert_eq!(u.len(), 3, "a reversal is not collinear continuation");
        let dup = merge_collinear(&[p(0.0, 0.0), p(0.0, 0.0), p(0.1, 0.0)], 0.001);
        assert_eq!(dup, [p(0.0, 0.0), p(0.1, 0.0)]);
        assert_eq!(merge_collinear(&[p(1.0, 1.0)], 0.001), [p(1.0, 1.0)]);
        // The original's example: 9 -> 8 -> 55 becomes 9 -> 55.
        let g = WaypointGraph::original();
        let pts: Vec<Vec2> = [9, 8, 55]
            .iter()
            .map(|&i| g.position(WaypointId(i)).unwrap())
            .collect();
        assert_eq!(merge_collinear(&pts, 0.001), [pts[0], pts[2]]);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Dijkstra's costs equal petgraph's for random penalties and blocked edges, and the
        /// returned vertex sequence is a walk along open edges whose cost is that total.
        #[test]
        fn dijkstra_matches_petgraph(
            extras in proptest::collection::vec(0.0f64..1.0, 50),
            blocked in proptest::collection::vec(proptest::bool::weighted(0.15), 50),
            from_index in 0usize..49,
            to_index in 0usize..49,
        ) {
            let mut map = road_map();
            let edges = map.graph().edges().to_vec();
            let ids: Vec<WaypointId> = map.graph().waypoints().iter().map(|w| w.id).collect();
            let mut oracle = UnGraph::<WaypointId, f64>::new_undirected();
            let nodes: BTreeMap<WaypointId, NodeIndex> =
                ids.iter().map(|&id| (id, oracle.add_node(id))).collect();
            for (k, e) in edges.iter().enumerate() {
                let state = if blocked[k] {
                    EdgeState::Blocked
                } else {
                    EdgeState::Penalised { extra_m: extras[k] }
                };
                map.set_edge(e.a, e.b, state).unwrap();
                if !blocked[k] {
                    oracle.add_edge(nodes[&e.a], nodes[&e.b], e.length_m + extras[k]);
                }
            }
            let (from, to) = (ids[from_index], ids[to_index]);
            let costs = petgraph::algo::dijkstra(&oracle, nodes[&from], Some(nodes[&to]), |e| *e.weight());
            match (map.shortest_path(from, to), costs.get(&nodes[&to])) {
                (Ok(path), Some(&want)) => {
                    prop_assert!((path.cost_m - want).abs() < 1e-9, "{} vs {}", path.cost_m, want);
                    prop_assert_eq!(path.vertices.first(), Some(&from));
                    prop_assert_eq!(path.vertices.last(), Some(&to));
                    let walked: f64 = path
                        .vertices
                        .windows(2)
                        .map(|w| map.edge_cost_m(w[0], w[1]).expect("open edge"))
                        .sum();
                    prop_assert!((walked - path.cost_m).abs() < 1e-9);
                }
                (Err(PlanError::Unreachable { .. }), None) => {}
                (ours, theirs) => prop_assert!(false, "ours {:?}, petgraph {:?}", ours, theirs),
            }
        }

        /// Merging never moves the path by more than the tolerance: every input point lies
        /// within it of the merged polyline.
        #[test]
        fn merged_paths_stay_within_tolerance(
            coords in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 2..8),
        ) {
            let points: Vec<Vec2> = coords.iter().map(|&(x, y)| Vec2::new(x, y)).collect();
            let merged = merge_collinear(&points, 0.001);
            prop_assert_eq!(merged.first(), points.first());
            prop_assert_eq!(merged.last(), points.last());
            for p in &points {
                let d = merged
                    .windows(2)
                    .map(|w| Segment::new(w[0], w[1]).distance_to_point(*p))
                    .fold(f64::INFINITY, f64::min);
                prop_assert!(merged.len() < 2 || d <= 0.001 + 1e-12, "{:?} off by {}", p, d);
            }
        }
    }
}
