//! Rectangles at any orientation, and overlap tests between them: the robot's footprint (and a
//! box it carries) against the things on the floor, for the simulator's collision detection
//! and the planners' clearance checks.
//!
//! Walls, dividers, machine blocks and boxes in their slots are axis-aligned rectangles or
//! oriented ones. Two convex polygons
//! are disjoint exactly when some edge normal of one of them separates their projections (the
//! separating axis theorem), so for two rectangles four axes suffice.

use super::geometry::{Pose2, Rect, Segment, Vec2, hypot};

/// A rectangle at any orientation, m and rad.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrientedRect {
    /// Centre and orientation (the rectangle's local x axis points along the yaw).
    pub pose: Pose2,
    /// Half the size along the local x axis, m.
    pub half_x_m: f64,
    /// Half the size along the local y axis, m.
    pub half_y_m: f64,
}

impl OrientedRect {
    /// A `size_x` × `size_y` rectangle centred on `pose`.
    pub fn new(pose: Pose2, size_x_m: f64, size_y_m: f64) -> Self {
        Self {
            pose,
            half_x_m: size_x_m / 2.0,
            half_y_m: size_y_m / 2.0,
        }
    }

    /// An axis-aligned rectangle as an oriented one.
    pub fn from_rect(rect: Rect) -> Self {
        let c = rect.center();
        Self::new(Pose2::new(c.x, c.y, 0.0), rect.size_x(), rect.size_y())
    }

    /// The four corners, counter-clockwise from local (+x, +y).
    pub fn corners(&self) -> [Vec2; 4] {
        let (hx, hy) = (self.half_x_m, self.half_y_m);
        [
            Vec2::new(hx, hy),
            Vec2::new(-hx, hy),
            Vec2::new(-hx, -hy),
            Vec2::new(hx, -hy),
        ]
        .map(|local| self.pose.transform_point(local))
    }

    fn axes(&self) -> [Vec2; 2] {
        let u = Vec2::from_angle(self.pose.yaw_rad);
        [u, Vec2::new(-u.y, u.x)]
    }

    /// The interval `corners` project onto `axis`.
    fn projection(corners: &[Vec2; 4], axis: Vec2) -> (f64, f64) {
        corners
            .iter()
            .map(|c| c.dot(axis))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p), hi.max(p))
            })
    }

    /// True when the two rectangles overlap with positive area. Touching edges do not count,
    /// so a robot pressing its front against a box is not a collision.
    pub fn overlaps(&self, other: &OrientedRect) -> bool {
        self.penetrates(other, 1e-9)
    }

    /// True when the two rectangles overlap by more than `depth_m` along every separating
    /// axis (the overlap's smallest extent exceeds `depth_m`).
    pub fn penetrates(&self, other: &OrientedRect, depth_m: f64) -> bool {
        Self::corners_penetrate(&self.corners(), &other.corners(), self, other, depth_m)
    }

    /// [`Self::penetrates`] with the corners of `a` and `b` computed once (each corner
    /// costs a sine and a cosine; the clearance grids test millions of pairs).
    fn corners_penetrate(
        a_corners: &[Vec2; 4],
        b_corners: &[Vec2; 4],
        a: &OrientedRect,
        b: &OrientedRect,
        depth_m: f64,
    ) -> bool {
        a.axes().into_iter().chain(b.axes()).all(|axis| {
            let (a_lo, a_hi) = Self::projection(a_corners, axis);
            let (b_lo, b_hi) = Self::projection(b_corners, axis);
            a_hi > b_lo + depth_m && b_hi > a_lo + depth_m
        })
    }

    /// True when this rectangle overlaps the axis-aligned `rect`.
    pub fn overlaps_rect(&self, rect: Rect) -> bool {
        self.overlaps(&Self::from_rect(rect))
    }

    /// The four edges joining `corners` (counter-clockwise) in turn.
    fn edges_of(corners: &[Vec2; 4]) -> [Segment; 4] {
        [0, 1, 2, 3].map(|i| Segment::new(corners[i], corners[(i + 1) % 4]))
    }

    /// Distance from `p` to the rectangle, m (0 inside it).
    pub fn distance_to_point(&self, p: Vec2) -> f64 {
        let local = self.pose.inverse_transform_point(p);
        let dx = (local.x.abs() - self.half_x_m).max(0.0);
        let dy = (local.y.abs() - self.half_y_m).max(0.0);
        hypot(dx, dy)
    }

    /// Radius of the circle about the centre that holds the rectangle, m.
    pub fn circumradius_m(&self) -> f64 {
        hypot(self.half_x_m, self.half_y_m)
    }

    /// The gap between the two rectangles, m: 0 when they overlap or touch, else the
    /// least distance between their outlines (for convex polygons apart, always between a
    /// corner of one and an edge of the other).
    pub fn distance_to(&self, other: &OrientedRect) -> f64 {
        let (ours, theirs) = (self.corners(), other.corners());
        if Self::corners_penetrate(&ours, &theirs, self, other, 0.0) {
            return 0.0;
        }
        let from_corners = |corners: &[Vec2; 4], edges: &[Segment; 4]| {
            corners
                .iter()
                .flat_map(|&corner| edges.map(|edge| edge.distance_to_point(corner)))
                .fold(f64::INFINITY, f64::min)
        };
        from_corners(&ours, &Self::edges_of(&theirs))
            .min(from_corners(&theirs, &Self::edges_of(&ours)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::FRAC_PI_4;

    fn robot(x: f64, y: f64, yaw: f64) -> OrientedRect {
        OrientedRect::new(Pose2::new(x, y, yaw), 0.30, 0.30)
    }

    #[test]
    fn separated_touching_and_overlapping() {
        let wall = Rect::from_spans(0.2, 0.4, -1.0, 1.0);
        assert!(!robot(0.0, 0.0, 0.0).overlaps_rect(wall));
        assert!(!robot(0.05, 0.0, 0.0).overlaps_rect(wall)); // front face exactly on the wall
        assert!(robot(0.06, 0.0, 0.0).overlaps_rect(wall));
    }

    #[test]
    fn a_rotated_robot_reaches_further() {
        let wall = Rect::from_spans(0.2, 0.4, -1.0, 1.0);
        // At 45° the half-diagonal is 0.212 m: the corner crosses x = 0.2 from x = 0.
        assert!(robot(0.0, 0.0, FRAC_PI_4).overlaps_rect(wall));
        assert!(!robot(-0.02, 0.0, FRAC_PI_4).overlaps_rect(wall));
    }

    #[test]
    fn distances_between_rectangles_and_to_points() {
        let wall = OrientedRect::from_rect(Rect::from_spans(0.2, 0.4, -1.0, 1.0));
        assert!((robot(0.0, 0.0, 0.0).distance_to(&wall) - 0.05).abs() < 1e-12);
        assert_eq!(robot(0.06, 0.0, 0.0).distance_to(&wall), 0.0);
        // At 45° the corner leads: 0.2 − 0.212.. from x = −0.05.
        let turned = robot(-0.05, 0.0, FRAC_PI_4).distance_to(&wall);
        assert!(
            (turned - (0.25 - 0.15 * 2f64.sqrt())).abs() < 1e-12,
            "{turned}"
        );
        // Corner to corner, diagonally apart.
        let post = OrientedRect::from_rect(Rect::from_spans(0.25, 0.35, 0.25, 0.35));
        let gap = robot(0.0, 0.0, 0.0).distance_to(&post);
        assert!((gap - 0.1 * 2f64.sqrt()).abs() < 1e-12, "{gap}");
        assert!((wall.distance_to_point(Vec2::new(0.0, 1.1)) - 0.2236).abs() < 1e-4);
        assert_eq!(wall.distance_to_point(Vec2::new(0.3, 0.0)), 0.0);
    }

    proptest! {
        /// The gap between two rectangles is the least distance between points of theirs:
        /// no pair of sampled outline points is closer, and a corner of one lies at the
        /// gap from the other.
        #[test]
        fn the_gap_is_the_least_distance_between_outlines(
            ax in -0.5f64..0.5, ay in -0.5f64..0.5, ayaw in -3.2f64..3.2,
            bx in -0.5f64..0.5, by in -0.5f64..0.5, byaw in -3.2f64..3.2,
        ) {
            let a = robot(ax, ay, ayaw);
            let b = OrientedRect::new(Pose2::new(bx, by, byaw), 0.09, 0.06);
            let gap = a.distance_to(&b);
            prop_assert!((gap - b.distance_to(&a)).abs() < 1e-12);
            prop_assert_eq!(gap == 0.0, a.penetrates(&b, 0.0));
            let outline = |r: &OrientedRect| -> Vec<Vec2> {
                OrientedRect::edges_of(&r.corners())
                    .iter()
                    .flat_map(|e| (0..=20).map(move |k| e.a + (e.b - e.a) * (k as f64 / 20.0)))
                    .collect()
            };
            if gap > 0.0 {
                let (pa, pb) = (outline(&a), outline(&b));
                for p in &pa {
                    for q in &pb {
                        prop_assert!(p.distance(*q) >= gap - 1e-9);
                    }
                }
                // A corner of one is the gap away from the other.
                let near = b.corners().iter().any(|c| a.distance_to_point(*c) <= gap + 1e-9)
                    || a.corners().iter().any(|c| b.distance_to_point(*c) <= gap + 1e-9);
                prop_assert!(near);
            }
        }

        /// Overlap is symmetric, and agrees with a dense point-sampling check whenever the
        /// sampled points clearly decide it.
        #[test]
        fn overlap_matches_point_sampling(
            ax in -0.5f64..0.5, ay in -0.5f64..0.5, ayaw in -3.2f64..3.2,
            bx in -0.5f64..0.5, by in -0.5f64..0.5, byaw in -3.2f64..3.2,
        ) {
            let a = robot(ax, ay, ayaw);
            let b = OrientedRect::new(Pose2::new(bx, by, byaw), 0.09, 0.06);
            prop_assert_eq!(a.overlaps(&b), b.overlaps(&a));
            let n = 24;
            let mut inside = false;
            for i in 0..=n {
                for j in 0..=n {
                    let local = Vec2::new(
                        b.half_x_m * (2.0 * i as f64 / n as f64 - 1.0) * 0.999,
                        b.half_y_m * (2.0 * j as f64 / n as f64 - 1.0) * 0.999,
                    );
                    let p = a.pose.inverse_transform_point(b.pose.transform_point(local));
                    if p.x.abs() < a.half_x_m && p.y.abs() < a.half_y_m {
                        inside = true;
                    }
                }
            }
            if inside {
                prop_assert!(a.overlaps(&b));
            }
        }
    }
}
