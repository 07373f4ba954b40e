//! The original's waypoint graph (original-system.md §6.1, runtime `map.yaml`).
//!
//! 49 vertices (ids 0–26, 30–35, 50–65) at the runtime coordinates (mm in the file,
//! metres here) and 50 unique undirected edges weighted by Euclidean length. Task vertices
//! 50–65 are leaves; the slot they serve is in [`super::stations`].

use std::collections::BTreeMap;
use std::fmt;

use super::geometry::Vec2;

/// A vertex id: the ArUco id the original named it after.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
pub struct WaypointId(pub u8);

impl fmt::Display for WaypointId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// A vertex and its position in the world frame, m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Waypoint {
    /// Id.
    pub id: WaypointId,
    /// Position, m.
    pub position: Vec2,
}

/// An undirected edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edge {
    /// One end.
    pub a: WaypointId,
    /// The other end.
    pub b: WaypointId,
    /// Euclidean length between the ends, m.
    pub length_m: f64,
}

/// Runtime vertex coordinates, mm (original-system.md §6.1, "runtime" column).
const VERTICES_MM: [(u8, f64, f64); 49] = [
    (0, -695.0, 255.0),
    (1, -545.0, 255.0),
    (2, -395.0, 255.0),
    (3, -245.0, 255.0),
    (4, 0.0, 255.0),
    (5, 695.0, 355.0),
    (6, 0.0, 150.0),
    (7, 100.0, 150.0),
    (8, 568.0, 150.0),
    (9, 695.0, 150.0),
    (10, -695.0, 0.0),
    (11, -568.0, 0.0),
    (12, -80.0, 0.0),
    (13, 0.0, 0.0),
    (14, 100.0, 0.0),
    (15, 568.0, 0.0),
    (16, 695.0, 0.0),
    (17, -695.0, -150.0),
    (18, -568.0, -150.0),
    (19, -100.0, -150.0),
    (20, 0.0, -150.0),
    (21, -695.0, -355.0),
    (22, 0.0, -255.0),
    (23, 245.0, -245.0),
    (24, 395.0, -245.0),
    (25, 545.0, -245.0),
    (26, 700.0, -245.0),
    (30, 227.0, 455.0),
    (31, 468.0, 455.0),
    (32, -468.0, -455.0),
    (33, -227.0, -455.0),
    (34, -695.0, 150.0),
    (35, 695.0, -150.0),
    (50, -700.0, 360.0),
    (51, -545.0, 360.0),
    (52, -395.0, 360.0),
    (53, -245.0, 360.0),
    (54, 150.0, 150.0),
    (55, 565.0, 150.0),
    (56, -550.0, 0.0),
    (57, -150.5, 0.0),
    (58, 150.0, 0.0),
    (59, 565.0, 0.0),
    (60, -550.0, -150.0),
    (61, -150.5, -150.0),
    (62, 245.0, -385.0),
    (63, 395.0, -385.0),
    (64, 545.0, -385.0),
    (65, 700.0, -385.0),
];

/// The 50 unique undirected edges (original-system.md §6.1; the file's 5 duplicates removed).
const EDGES: [(u8, u8); 50] = [
    (0, 50),
    (0, 1),
    (1, 51),
    (1, 2),
    (2, 52),
    (2, 3),
    (3, 53),
    (3, 4),
    (4, 30),
    (30, 31),
    (31, 5),
    (5, 9),
    (9, 8),
    (8, 55),
    (9, 16),
    (16, 15),
    (15, 59),
    (16, 35),
    (35, 26),
    (26, 65),
    (26, 25),
    (25, 64),
    (25, 24),
    (24, 63),
    (24, 23),
    (23, 62),
    (23, 22),
    (22, 33),
    (33, 32),
    (32, 21),
    (21, 17),
    (17, 18),
    (18, 60),
    (17, 10),
    (10, 11),
    (11, 56),
    (10, 34),
    (34, 0),
    (22, 20),
    (20, 19),
    (19, 61),
    (20, 13),
    (13, 12),
    (12, 57),
    (13, 14),
    (14, 58),
    (13, 6),
    (6, 7),
    (7, 54),
    (6, 4),
];

/// The waypoint graph: vertices, edges and an adjacency list.
#[derive(Clone, Debug, PartialEq)]
pub struct WaypointGraph {
    waypoints: Vec<Waypoint>,
    edges: Vec<Edge>,
    adjacency: BTreeMap<WaypointId, Vec<(WaypointId, f64)>>,
}

impl WaypointGraph {
    /// The original's runtime graph.
    pub fn original() -> Self {
        let waypoints: Vec<Waypoint> = VERTICES_MM
            .iter()
            .map(|&(id, x, y)| Waypoint {
                id: WaypointId(id),
                position: Vec2::new(x / 1000.0, y / 1000.0),
            })
            .collect();
        let pairs: Vec<(WaypointId, WaypointId)> = EDGES
            .iter()
            .map(|&(a, b)| (WaypointId(a), WaypointId(b)))
            .collect();
        Self::from_parts(waypoints, &pairs)
    }

    /// The same edges with the vertices of `moved` at new positions (m), the edge lengths
    /// measured again; ids not in the graph are ignored.
    pub fn with_moved(&self, moved: &[(WaypointId, Vec2)]) -> Self {
        let waypoints = self
            .waypoints
            .iter()
            .map(|w| Waypoint {
                id: w.id,
                position: moved
                    .iter()
                    .find(|(id, _)| *id == w.id)
                    .map_or(w.position, |(_, p)| *p),
            })
            .collect();
        let pairs: Vec<(WaypointId, WaypointId)> = self.edges.iter().map(|e| (e.a, e.b)).collect();
        Self::from_parts(waypoints, &pairs)
    }

    fn from_parts(waypoints: Vec<Waypoint>, pairs: &[(WaypointId, WaypointId)]) -> Self {
        let position = |id: WaypointId| {
            waypoints
                .iter()
                .find(|w| w.id == id)
                .map(|w| w.position)
                .unwrap_or(Vec2::ZERO)
        };
        let edges: Vec<Edge> = pairs
            .iter()
            .map(|&(a, b)| Edge {
                a,
                b,
                length_m: position(a).distance(position(b)),
            })
            .collect();
        let mut adjacency: BTreeMap<WaypointId, Vec<(WaypointId, f64)>> =
            waypoints.iter().map(|w| (w.id, Vec::new())).collect();
        for e in &edges {
            adjacency.entry(e.a).or_default().push((e.b, e.length_m));
            adjacency.entry(e.b).or_default().push((e.a, e.length_m));
        }
        Self {
            waypoints,
            edges,
            adjacency,
        }
    }

    /// All vertices, in increasing id order.
    pub fn waypoints(&self) -> &[Waypoint] {
        &self.waypoints
    }

    /// All undirected edges, each once.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// Position of a vertex, m, or `None` for an unknown id.
    pub fn position(&self, id: WaypointId) -> Option<Vec2> {
        self.waypoints
            .iter()
            .find(|w| w.id == id)
            .map(|w| w.position)
    }

    /// Neighbours of a vertex with the edge lengths (m); empty for an unknown id.
    pub fn neighbours(&self, id: WaypointId) -> &[(WaypointId, f64)] {
        self.adjacency.get(&id).map(Vec::as_slice).unwrap_or(&[])
    }

    /// The vertex nearest to `point` (Euclidean, all vertices, as the original's planner
    /// picks its start vertex; original-system.md §6.2).
    pub fn nearest(&self, point: Vec2) -> Option<WaypointId> {
        self.waypoints
            .iter()
            .min_by(|a, b| {
                a.position
                    .distance(point)
                    .total_cmp(&b.position.distance(point))
            })
            .map(|w| w.id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    #[test]
    fn counts_ids_and_uniqueness() {
        let g = WaypointGraph::original();
        assert_eq!(g.waypoints().len(), 49);
        assert_eq!(g.edges().len(), 50);
        let ids: BTreeSet<u8> = g.waypoints().iter().map(|w| w.id.0).collect();
        let want: BTreeSet<u8> = (0..=26).chain(30..=35).chain(50..=65).collect();
        assert_eq!(ids, want);
        let undirected: BTreeSet<(u8, u8)> = g
            .edges()
            .iter()
            .map(|e| (e.a.0.min(e.b.0), e.a.0.max(e.b.0)))
            .collect();
        assert_eq!(undirected.len(), 50, "duplicate edge");
        assert!(
            g.edges()
                .iter()
                .all(|e| ids.contains(&e.a.0) && ids.contains(&e.b.0) && e.a != e.b)
        );
    }

    #[test]
    fn task_vertices_are_leaves_with_the_listed_neighbour() {
        let g = WaypointGraph::original();
        let expected = [
            (50, 0),
            (51, 1),
            (52, 2),
            (53, 3),
            (54, 7),
            (55, 8),
            (56, 11),
            (57, 12),
            (58, 14),
            (59, 15),
            (60, 18),
            (61, 19),
            (62, 23),
            (63, 24),
            (64, 25),
            (65, 26),
        ];
        for (task, neighbour) in expected {
            let n = g.neighbours(WaypointId(task));
            assert_eq!(n.len(), 1, "task vertex {task}");
            assert_eq!(n[0].0, WaypointId(neighbour), "task vertex {task}");
        }
    }

    #[test]
    fn edges_are_euclidean_and_graph_is_connected() {
        let g = WaypointGraph::original();
        let e = g.edges().iter().find(|e| e.a.0 == 9 && e.b.0 == 8).copied();
        let e = e.expect("edge 9-8");
        assert!((e.length_m - 0.127).abs() < 1e-12);
        for e in g.edges() {
            let d = g.position(e.a).unwrap().distance(g.position(e.b).unwrap());
            assert!((e.length_m - d).abs() < 1e-12 && e.length_m > 0.0);
        }
        let mut seen = BTreeSet::from([WaypointId(13)]);
        let mut stack = vec![WaypointId(13)];
        while let Some(v) = stack.pop() {
            for (n, _) in g.neighbours(v) {
                if seen.insert(*n) {
                    stack.push(*n);
                }
            }
        }
        assert_eq!(seen.len(), 49);
    }

    #[test]
    fn nearest_and_unknown_ids() {
        let g = WaypointGraph::original();
        assert_eq!(g.nearest(Vec2::new(-0.69, -0.35)), Some(WaypointId(21)));
        assert_eq!(g.position(WaypointId(40)), None);
        assert!(g.neighbours(WaypointId(40)).is_empty());
    }
}
