//! Rectangles at any orientation, and overlap tests between them: the robot's footprint (and a
//! box it carries) against the things on the floor, for the simulator's collision detection
//! and the planners' clearance checks.
//!
//! Walls, dividers, machine blocks and boxes in their slots are axis-aligned rectangles or
//! oriented ones. Two convex polygons
//! are disjoint exactly when some edge normal of one of them separates their projections (the
//! separating axis theorem), so for two rectangles four axes suffice.

use super::geometry::{Pose2, Rect, Vec2};

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

    fn projection(&self, axis: Vec2) -> (f64, f64) {
        self.corners()
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
        self.axes().into_iter().chain(other.axes()).all(|axis| {
            let (a_lo, a_hi) = self.projection(axis);
            let (b_lo, b_hi) = other.projection(axis);
            a_hi > b_lo + depth_m && b_hi > a_lo + depth_m
        })
    }

    /// True when this rectangle overlaps the axis-aligned `rect`.
    pub fn overlaps_rect(&self, rect: Rect) -> bool {
        self.overlaps(&Self::from_rect(rect))
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

    proptest! {
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
