//! Shortest paths for a disc among rectangles (walls, dividers, parts, poles): the disc's
//! centre around each obstacle grown by the disc's radius, on a visibility graph.
//!
//! The grown obstacle (a rectangle's Minkowski sum with the disc: a rounded rectangle) is
//! replaced by a convex polygon, in one of two ways ([`Fit`]):
//! - **inscribed** (the rounded corners by chords whose ends lie on the arcs): the polygon
//!   lies inside the true grown obstacle, so every path the true obstacles allow the
//!   polygons allow too and lengths are never longer than the true ones, which is what a
//!   lower bound needs ([`super::bound`]); with [`ARC_SEGMENTS`] chords per corner of a
//!   0.15 m disc a path round a corner is at most about a millimetre short;
//! - **circumscribed** (the corners by tangents): the polygon contains the grown obstacle,
//!   so every path found keeps the whole disc off every obstacle, which is what a route
//!   needs ([`crate::control::route`]).

use std::collections::BinaryHeap;
use std::f64::consts::FRAC_PI_2;

use crate::field::geometry::{Rect, Vec2};
use crate::planning::cheapest_first::Cheapest;

/// Chords per rounded corner.
pub const ARC_SEGMENTS: usize = 8;

/// How a grown obstacle's rounded corners become polygon edges (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fit {
    /// Chords inside the arcs: lengths never longer than the true ones.
    Inscribed,
    /// Tangents outside the arcs: paths never closer than the radius.
    Circumscribed,
}

/// Free space for a disc of a given radius among axis-aligned rectangles.
#[derive(Clone, Debug)]
pub struct DiscPaths {
    /// The grown obstacles, each convex and counter-clockwise.
    polygons: Vec<Vec<Vec2>>,
}

impl DiscPaths {
    /// Free space for a disc of `radius_m` among `obstacles`, for lower bounds (inscribed,
    /// [`ARC_SEGMENTS`] per corner).
    pub fn around(obstacles: &[Rect], radius_m: f64) -> Self {
        Self::fitted(obstacles, radius_m, Fit::Inscribed, ARC_SEGMENTS)
    }

    /// Free space for a disc of `radius_m` among `obstacles`, each corner fitted by
    /// `segments` edges the `fit` way.
    pub fn fitted(obstacles: &[Rect], radius_m: f64, fit: Fit, segments: usize) -> Self {
        Self {
            polygons: obstacles
                .iter()
                .map(|rect| rounded_rect(*rect, radius_m, fit, segments.max(1)))
                .collect(),
        }
    }

    /// Whether the disc's centre at `point` is clear of every grown obstacle (on a boundary
    /// counts as clear).
    pub fn is_clear(&self, point: Vec2) -> bool {
        self.polygons
            .iter()
            .all(|polygon| !strictly_inside(polygon, point))
    }

    /// Whether the centre may move straight from `a` to `b`.
    pub fn is_visible(&self, a: Vec2, b: Vec2) -> bool {
        self.polygons
            .iter()
            .all(|polygon| !crosses_interior(polygon, a, b))
    }

    /// The visibility graph over `points` and the grown obstacles' corners, for shortest
    /// paths from a point or a region to each of `points`.
    pub fn graph(&self, points: &[Vec2]) -> VisibilityGraph<'_> {
        let nodes: Vec<Vec2> = points
            .iter()
            .copied()
            .chain(
                self.polygons
                    .iter()
                    .flatten()
                    .copied()
                    .filter(|v| self.is_clear(*v)),
            )
            .collect();
        let n = nodes.len();
        let mut edges = vec![Vec::new(); n];
        for i in 0..n {
            for j in i + 1..n {
                if self.is_visible(nodes[i], nodes[j]) {
                    let length = nodes[i].distance(nodes[j]);
                    edges[i].push((j, length));
                    edges[j].push((i, length));
                }
            }
        }
        VisibilityGraph {
            space: self,
            nodes,
            edges,
            points: points.len(),
        }
    }

    /// The shortest path lengths between every pair of `points` (m; infinite where a point
    /// is walled in), as a row-major `points.len()²` matrix.
    pub fn distances(&self, points: &[Vec2]) -> Vec<f64> {
        let graph = self.graph(points);
        (0..points.len())
            .flat_map(|source| graph.from_point(source))
            .collect()
    }
}

/// A visibility graph: the first nodes are the points it was built for.
#[derive(Clone, Debug)]
pub struct VisibilityGraph<'a> {
    space: &'a DiscPaths,
    nodes: Vec<Vec2>,
    edges: Vec<Vec<(usize, f64)>>,
    points: usize,
}

impl VisibilityGraph<'_> {
    /// Shortest lengths from point `source` to every point, m.
    pub fn from_point(&self, source: usize) -> Vec<f64> {
        let mut start = vec![f64::INFINITY; self.nodes.len()];
        start[source] = 0.0;
        self.shortest(start)
    }

    /// Shortest lengths from anywhere in `region` to every point, m: each node is entered
    /// from its nearest point of the region when the straight line from there is clear,
    /// and from the other nodes as usual.
    pub fn from_region(&self, region: Rect) -> Vec<f64> {
        let start = self
            .nodes
            .iter()
            .map(|&node| {
                let nearest = Vec2::new(
                    node.x.clamp(region.min.x, region.max.x),
                    node.y.clamp(region.min.y, region.max.y),
                );
                if self.space.is_clear(nearest) && self.space.is_visible(nearest, node) {
                    nearest.distance(node)
                } else {
                    f64::INFINITY
                }
            })
            .collect();
        self.shortest(start)
    }

    /// Dijkstra from the initial lengths `start`, truncated to the points.
    fn shortest(&self, start: Vec<f64>) -> Vec<f64> {
        let (mut lengths, _) = dijkstra(&self.edges, start);
        lengths.truncate(self.points);
        lengths
    }

    /// The shortest path for the disc's centre from `a` to `b` (both ends included) through
    /// the graph's nodes; `None` when `a` or `b` is not clear or no path exists. Build the
    /// graph once without points ([`DiscPaths::graph`] of `&[]`) and ask for many paths.
    pub fn path(&self, a: Vec2, b: Vec2) -> Option<Vec<Vec2>> {
        if !self.space.is_clear(a) || !self.space.is_clear(b) {
            return None;
        }
        if self.space.is_visible(a, b) {
            return Some(vec![a, b]);
        }
        let seen_from = |end: Vec2| -> Vec<f64> {
            self.nodes
                .iter()
                .map(|&node| {
                    if self.space.is_visible(end, node) {
                        end.distance(node)
                    } else {
                        f64::INFINITY
                    }
                })
                .collect()
        };
        let (from_a, previous) = dijkstra(&self.edges, seen_from(a));
        let to_b = seen_from(b);
        let (last, _) = from_a
            .iter()
            .zip(&to_b)
            .map(|(x, y)| x + y)
            .enumerate()
            .filter(|(_, total)| total.is_finite())
            .min_by(|x, y| x.1.total_cmp(&y.1))?;
        let mut reversed = vec![b, self.nodes[last]];
        let mut node = last;
        while previous[node] != usize::MAX {
            node = previous[node];
            reversed.push(self.nodes[node]);
        }
        reversed.push(a);
        reversed.reverse();
        Some(reversed)
    }
}

/// The polygon fitted to `rect` grown by `radius_m`, `segments` edges per corner, counter-
/// clockwise (module documentation).
fn rounded_rect(rect: Rect, radius_m: f64, fit: Fit, segments: usize) -> Vec<Vec2> {
    let corners = [
        (Vec2::new(rect.max.x, rect.min.y), -FRAC_PI_2),
        (Vec2::new(rect.max.x, rect.max.y), 0.0),
        (Vec2::new(rect.min.x, rect.max.y), FRAC_PI_2),
        (Vec2::new(rect.min.x, rect.min.y), 2.0 * FRAC_PI_2),
    ];
    let step = FRAC_PI_2 / segments as f64;
    let mut polygon = Vec::with_capacity(4 * (segments + 2));
    for (corner, start_rad) in corners {
        let at = |angle: f64, radius: f64| corner + Vec2::from_angle(angle) * radius;
        match fit {
            Fit::Inscribed => {
                polygon.extend((0..=segments).map(|k| at(start_rad + step * k as f64, radius_m)));
            }
            Fit::Circumscribed => {
                // The tangents at the arc's ends and at every step meet half a step on, at
                // radius r / cos(step / 2).
                let outer = radius_m / (step / 2.0).cos();
                polygon.push(at(start_rad, radius_m));
                polygon
                    .extend((0..segments).map(|k| at(start_rad + step * (k as f64 + 0.5), outer)));
                polygon.push(at(start_rad + FRAC_PI_2, radius_m));
            }
        }
    }
    polygon
}

/// Lengths below this are a touch, not a crossing, m.
const TOUCH_M: f64 = 1e-9;

/// Whether `point` is inside the convex counter-clockwise `polygon`, off its boundary.
fn strictly_inside(polygon: &[Vec2], point: Vec2) -> bool {
    edges(polygon).all(|(p, q)| (q - p).cross(point - p) > TOUCH_M)
}

/// Whether the segment `a`–`b` runs through the interior of the convex counter-clockwise
/// `polygon` (touching a vertex or running along an edge does not count): Cyrus–Beck
/// clipping of the segment to the polygon.
fn crosses_interior(polygon: &[Vec2], a: Vec2, b: Vec2) -> bool {
    let direction = b - a;
    let (mut enter, mut exit) = (0.0_f64, 1.0_f64);
    for (p, q) in edges(polygon) {
        let edge = q - p;
        // Positive on the inner side of this edge.
        let start = edge.cross(a - p);
        let rate = edge.cross(direction);
        if rate.abs() < 1e-15 {
            if start <= TOUCH_M {
                return false;
            }
            continue;
        }
        let t = -start / rate;
        if rate > 0.0 {
            enter = enter.max(t);
        } else {
            exit = exit.min(t);
        }
        if enter >= exit {
            return false;
        }
    }
    (exit - enter) * direction.norm() > TOUCH_M
        && strictly_inside(polygon, a + direction * ((enter + exit) / 2.0))
}

fn edges(polygon: &[Vec2]) -> impl Iterator<Item = (Vec2, Vec2)> + '_ {
    polygon
        .iter()
        .copied()
        .zip(polygon.iter().copied().cycle().skip(1))
}

/// Shortest lengths over an undirected graph's adjacency lists from initial lengths
/// `start` (zero at a single source, or a region's entry lengths), with each node's
/// predecessor on its shortest path (`usize::MAX` for a start node or an unreached one).
fn dijkstra(edges: &[Vec<(usize, f64)>], start: Vec<f64>) -> (Vec<f64>, Vec<usize>) {
    let mut queue: BinaryHeap<Cheapest<usize>> = start
        .iter()
        .enumerate()
        .filter(|(_, length)| length.is_finite())
        .map(|(node, length)| Cheapest {
            cost: *length,
            item: node,
        })
        .collect();
    let mut previous = vec![usize::MAX; start.len()];
    let mut best = start;
    while let Some(Cheapest {
        cost: length,
        item: node,
    }) = queue.pop()
    {
        if length > best[node] {
            continue;
        }
        for &(next, step) in &edges[node] {
            let candidate = length + step;
            if candidate < best[next] {
                best[next] = candidate;
                previous[next] = node;
                queue.push(Cheapest {
                    cost: candidate,
                    item: next,
                });
            }
        }
    }
    (best, previous)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn wall() -> Rect {
        Rect::from_spans(-0.5, 0.5, -0.01, 0.01)
    }

    #[test]
    fn an_open_floor_gives_straight_lines() {
        let space = DiscPaths::around(&[], 0.15);
        let d = space.distances(&[Vec2::new(0.0, 0.0), Vec2::new(3.0, 4.0)]);
        assert_eq!(d, vec![0.0, 5.0, 5.0, 0.0]);
    }

    #[test]
    fn a_wall_is_passed_round_its_grown_end() {
        let space = DiscPaths::around(&[wall()], 0.15);
        let (a, b) = (Vec2::new(0.0, -0.5), Vec2::new(0.0, 0.5));
        assert!(!space.is_visible(a, b));
        let d = space.distances(&[a, b])[1];
        // The exact way round the rounded end: a tangent from each point to the corner
        // circle (centre (0.5, ∓0.01), radius 0.15), an arc to x = 0.65 on each, and the
        // 0.02 m flat between. The inscribed chords are never longer and only a little shorter.
        let centre_distance = (0.5f64.powi(2) + 0.49f64.powi(2)).sqrt();
        let tangent = (centre_distance.powi(2) - 0.15f64.powi(2)).sqrt();
        let towards_point = (-0.49f64).atan2(-0.5);
        let tangent_angle = towards_point + (0.15 / centre_distance).acos();
        let exact = 2.0 * (tangent + 0.15 * -tangent_angle) + 0.02;
        assert!(
            d <= exact + 1e-9 && d > exact - 0.002,
            "{d} against {exact}"
        );
    }

    #[test]
    fn a_region_is_left_from_its_nearest_clear_point() {
        let space = DiscPaths::around(&[wall()], 0.15);
        let region = Rect::from_spans(-0.2, 0.2, -1.0, -0.8);
        let graph = space.graph(&[Vec2::new(0.0, -0.5), Vec2::new(0.0, 0.5)]);
        let lengths = graph.from_region(region);
        assert!((lengths[0] - 0.3).abs() < 1e-12);
        // Behind the wall: from the region's corner nearest the way round.
        let via_point = space.distances(&[Vec2::new(0.0, -0.8), Vec2::new(0.0, 0.5)])[1];
        assert!(lengths[1] < via_point && lengths[1] > 1.0, "{}", lengths[1]);
    }

    #[test]
    fn a_path_goes_round_and_keeps_the_disc_off_the_wall() {
        let space = DiscPaths::fitted(&[wall()], 0.15, Fit::Circumscribed, 4);
        let graph = space.graph(&[]);
        let (a, b) = (Vec2::new(0.0, -0.5), Vec2::new(0.1, 0.5));
        let path = graph.path(a, b).expect("a way round");
        assert_eq!((path[0], path[path.len() - 1]), (a, b));
        for pair in path.windows(2) {
            assert!(space.is_visible(pair[0], pair[1]));
            // Sampled, every point keeps at least the radius from the wall.
            for k in 0..=20 {
                let p = pair[0] + (pair[1] - pair[0]) * (k as f64 / 20.0);
                let dx = (wall().min.x - p.x).max(p.x - wall().max.x).max(0.0);
                let dy = (wall().min.y - p.y).max(p.y - wall().max.y).max(0.0);
                assert!(
                    crate::field::geometry::hypot(dx, dy) >= 0.15 - 1e-9,
                    "{p:?}"
                );
            }
        }
        let length: f64 = path.windows(2).map(|w| w[0].distance(w[1])).sum();
        let exact = space.distances(&[a, b])[1];
        assert!((length - exact).abs() < 1e-9, "{length} against {exact}");
        assert!(
            graph.path(a, Vec2::new(0.0, 0.0)).is_none(),
            "inside the grown wall"
        );
    }

    #[test]
    fn touching_a_grown_corner_does_not_block() {
        let polygon = rounded_rect(wall(), 0.15, Fit::Inscribed, ARC_SEGMENTS);
        let vertex = polygon[0];
        assert!(!crosses_interior(
            &polygon,
            vertex + Vec2::new(0.0, -1.0),
            vertex
        ));
        assert!(!strictly_inside(&polygon, vertex));
        assert!(strictly_inside(&polygon, Vec2::new(0.0, 0.1)));
    }

    proptest! {
        /// The inscribed polygon is inside the true grown rectangle (so lengths never
        /// exceed the true ones) and no vertex is more than the chord's sag inside it.
        #[test]
        fn the_polygon_is_inscribed(
            x in -1.0..1.0f64, y in -1.0..1.0f64, w in 0.01..0.7f64, h in 0.01..0.7f64,
            r in 0.05..0.3f64,
        ) {
            let rect = Rect::from_spans(x, x + w, y, y + h);
            for v in rounded_rect(rect, r, Fit::Inscribed, ARC_SEGMENTS) {
                let dx = (rect.min.x - v.x).max(v.x - rect.max.x).max(0.0);
                let dy = (rect.min.y - v.y).max(v.y - rect.max.y).max(0.0);
                prop_assert!((crate::field::geometry::hypot(dx, dy) - r).abs() < 1e-9);
            }
        }

        /// Shortest lengths obey the triangle inequality and are never below the straight
        /// line.
        #[test]
        fn lengths_are_metric(
            ax in -1.5..1.5f64, ay in -1.5..1.5f64, bx in -1.5..1.5f64, by in -1.5..1.5f64,
        ) {
            let space = DiscPaths::around(&[wall()], 0.15);
            let points = [Vec2::new(ax, ay), Vec2::new(bx, by), Vec2::new(1.0, 1.0)];
            prop_assume!(points.iter().all(|p| space.is_clear(*p)));
            let d = space.distances(&points);
            prop_assert!(d[1] + 1e-9 >= points[0].distance(points[1]));
            prop_assert!(d[1] <= d[2] + d[5] + 1e-9);
            prop_assert!((d[1] - d[3]).abs() < 1e-9);
        }
    }
}
