//! Plane geometry shared by the whole host: points, poses, rectangles, segments, circles.
//!
//! Units: metres and radians. Angles are counter-clockwise; [`wrap_angle`] maps them into
//! (−π, π]. A [`Pose2`] is a rigid transform from a local frame (e.g. the robot frame:
//! x forward, y left) into its parent frame (e.g. the world frame of `architecture.md`).

use std::f64::consts::PI;
use std::ops::{Add, AddAssign, Mul, Neg, Sub};

use serde::{Deserialize, Serialize};

/// √(x² + y²), computed the same on every machine: `f64::hypot` calls the platform's libm,
/// whose last bit differs between the Pi (aarch64) and a PC (x86-64) for about one input in
/// eight, and a recording made on the robot must replay bit for bit on a PC. Squares and an
/// IEEE square root are exact everywhere; the lengths here (metres, m/s) cannot overflow.
pub fn hypot(x: f64, y: f64) -> f64 {
    (x * x + y * y).sqrt()
}

/// Wrap an angle into (−π, π], radians. Non-finite input is returned unchanged.
pub fn wrap_angle(angle_rad: f64) -> f64 {
    if !angle_rad.is_finite() {
        return angle_rad;
    }
    let wrapped = (angle_rad + PI).rem_euclid(2.0 * PI) - PI;
    if wrapped <= -PI {
        wrapped + 2.0 * PI
    } else {
        wrapped
    }
}

/// A point or vector in the plane, metres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vec2 {
    /// x component, m.
    pub x: f64,
    /// y component, m.
    pub y: f64,
}

impl Vec2 {
    /// The zero vector.
    pub const ZERO: Self = Self { x: 0.0, y: 0.0 };

    /// A vector from its components, m.
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }

    /// The unit vector at `angle_rad` from +x, counter-clockwise.
    pub fn from_angle(angle_rad: f64) -> Self {
        Self::new(angle_rad.cos(), angle_rad.sin())
    }

    /// Dot product.
    pub fn dot(self, other: Self) -> f64 {
        self.x * other.x + self.y * other.y
    }

    /// z component of the 3D cross product (positive when `other` is counter-clockwise).
    pub fn cross(self, other: Self) -> f64 {
        self.x * other.y - self.y * other.x
    }

    /// Euclidean length.
    pub fn norm(self) -> f64 {
        hypot(self.x, self.y)
    }

    /// Euclidean distance to `other`.
    pub fn distance(self, other: Self) -> f64 {
        (self - other).norm()
    }

    /// Angle from +x, radians in (−π, π].
    pub fn angle(self) -> f64 {
        self.y.atan2(self.x)
    }

    /// This vector rotated counter-clockwise by `angle_rad`.
    pub fn rotated(self, angle_rad: f64) -> Self {
        let (s, c) = angle_rad.sin_cos();
        Self::new(c * self.x - s * self.y, s * self.x + c * self.y)
    }

    /// True when both components are finite.
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite()
    }
}

impl Add for Vec2 {
    type Output = Self;
    fn add(self, rhs: Self) -> Self {
        Self::new(self.x + rhs.x, self.y + rhs.y)
    }
}

impl AddAssign for Vec2 {
    fn add_assign(&mut self, rhs: Self) {
        *self = *self + rhs;
    }
}

impl Sub for Vec2 {
    type Output = Self;
    fn sub(self, rhs: Self) -> Self {
        Self::new(self.x - rhs.x, self.y - rhs.y)
    }
}

impl Neg for Vec2 {
    type Output = Self;
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y)
    }
}

impl Mul<f64> for Vec2 {
    type Output = Self;
    fn mul(self, rhs: f64) -> Self {
        Self::new(self.x * rhs, self.y * rhs)
    }
}

/// A pose in the plane: position (m) and yaw (rad, counter-clockwise from the parent's +x).
///
/// Read as the transform that maps coordinates in the local frame into the parent frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose2 {
    /// x of the local origin in the parent frame, m.
    pub x: f64,
    /// y of the local origin in the parent frame, m.
    pub y: f64,
    /// Yaw of the local x axis in the parent frame, rad (not necessarily wrapped).
    pub yaw_rad: f64,
}

impl Pose2 {
    /// A pose from position (m) and yaw (rad).
    pub const fn new(x: f64, y: f64, yaw_rad: f64) -> Self {
        Self { x, y, yaw_rad }
    }

    /// The position as a vector, m.
    pub fn position(self) -> Vec2 {
        Vec2::new(self.x, self.y)
    }

    /// The unit vector of the local +x axis (the robot's forward direction).
    pub fn heading(self) -> Vec2 {
        Vec2::from_angle(self.yaw_rad)
    }

    /// `self ∘ other`: `other` is expressed in this pose's local frame; the result is in
    /// the parent frame. The yaw is wrapped.
    pub fn compose(self, other: Self) -> Self {
        let p = self.transform_point(other.position());
        Self::new(p.x, p.y, wrap_angle(self.yaw_rad + other.yaw_rad))
    }

    /// The inverse transform (parent expressed in the local frame). The yaw is wrapped.
    pub fn inverse(self) -> Self {
        let p = (-self.position()).rotated(-self.yaw_rad);
        Self::new(p.x, p.y, wrap_angle(-self.yaw_rad))
    }

    /// `other` expressed in this pose's local frame: `self.inverse() ∘ other`.
    pub fn relative(self, other: Self) -> Self {
        self.inverse().compose(other)
    }

    /// A point given in the local frame, expressed in the parent frame.
    pub fn transform_point(self, local: Vec2) -> Vec2 {
        self.position() + local.rotated(self.yaw_rad)
    }

    /// A point given in the parent frame, expressed in the local frame.
    pub fn inverse_transform_point(self, parent: Vec2) -> Vec2 {
        (parent - self.position()).rotated(-self.yaw_rad)
    }

    /// True when all three fields are finite.
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.yaw_rad.is_finite()
    }
}

/// A straight segment between two points, m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// One end.
    pub a: Vec2,
    /// The other end.
    pub b: Vec2,
}

impl Segment {
    /// A segment from its ends.
    pub const fn new(a: Vec2, b: Vec2) -> Self {
        Self { a, b }
    }

    /// Length, m.
    pub fn length(self) -> f64 {
        self.a.distance(self.b)
    }

    /// The point of the segment nearest to `p`.
    pub fn closest_point(self, p: Vec2) -> Vec2 {
        let d = self.b - self.a;
        let len2 = d.dot(d);
        if len2 == 0.0 {
            return self.a;
        }
        let t = ((p - self.a).dot(d) / len2).clamp(0.0, 1.0);
        self.a + d * t
    }

    /// Distance from `p` to the segment, m.
    pub fn distance_to_point(self, p: Vec2) -> f64 {
        self.closest_point(p).distance(p)
    }

    /// Parameter `t` ≥ 0 at which the ray `origin + t·direction` first meets this segment,
    /// or `None`. With a unit `direction`, `t` is a distance in metres. A ray parallel to the
    /// segment never meets it (grazing contact is ignored).
    pub fn ray_intersection(self, origin: Vec2, direction: Vec2) -> Option<f64> {
        let e = self.b - self.a;
        let denom = direction.cross(e);
        if denom == 0.0 {
            return None;
        }
        let w = self.a - origin;
        let t = w.cross(e) / denom;
        let u = w.cross(direction) / denom;
        (t >= 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
    }

    /// True when this segment and `other` share at least one point (collinear overlaps
    /// included).
    pub fn intersects(self, other: Self) -> bool {
        let d1 = (other.b - other.a).cross(self.a - other.a);
        let d2 = (other.b - other.a).cross(self.b - other.a);
        let d3 = (self.b - self.a).cross(other.a - self.a);
        let d4 = (self.b - self.a).cross(other.b - self.a);
        if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
            && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
        {
            return true;
        }
        let on = |s: Segment, p: Vec2, d: f64| {
            d == 0.0
                && p.x >= s.a.x.min(s.b.x)
                && p.x <= s.a.x.max(s.b.x)
                && p.y >= s.a.y.min(s.b.y)
                && p.y <= s.a.y.max(s.b.y)
        };
        on(other, self.a, d1)
            || on(other, self.b, d2)
            || on(self, other.a, d3)
            || on(self, other.b, d4)
    }
}

/// An axis-aligned rectangle, m. Invariant: `min.x ≤ max.x` and `min.y ≤ max.y`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rect {
    /// Lower-left corner.
    pub min: Vec2,
    /// Upper-right corner.
    pub max: Vec2,
}

impl Rect {
    /// The rectangle spanning x ∈ [x0, x1], y ∈ [y0, y1] (the ends may come in any order).
    pub fn from_spans(x0: f64, x1: f64, y0: f64, y1: f64) -> Self {
        Self {
            min: Vec2::new(x0.min(x1), y0.min(y1)),
            max: Vec2::new(x0.max(x1), y0.max(y1)),
        }
    }

    /// The rectangle of size `size_x` × `size_y` centred on `center`.
    pub fn centered(center: Vec2, size_x: f64, size_y: f64) -> Self {
        let half = Vec2::new(size_x.abs() / 2.0, size_y.abs() / 2.0);
        Self {
            min: center - half,
            max: center + half,
        }
    }

    /// Centre point.
    pub fn center(self) -> Vec2 {
        (self.min + self.max) * 0.5
    }

    /// Width along x, m.
    pub fn size_x(self) -> f64 {
        self.max.x - self.min.x
    }

    /// Height along y, m.
    pub fn size_y(self) -> f64 {
        self.max.y - self.min.y
    }

    /// True when `p` is inside or on the boundary.
    pub fn contains(self, p: Vec2) -> bool {
        p.x >= self.min.x && p.x <= self.max.x && p.y >= self.min.y && p.y <= self.max.y
    }

    /// This rectangle grown by `margin_m` on every side (shrunk when negative).
    pub fn inflated(self, margin_m: f64) -> Self {
        let m = Vec2::new(margin_m, margin_m);
        Self::from_spans(
            self.min.x - m.x,
            self.max.x + m.x,
            self.min.y - m.y,
            self.max.y + m.y,
        )
    }

    /// True when the two rectangles share at least one point.
    pub fn overlaps(self, other: Self) -> bool {
        self.min.x <= other.max.x
            && other.min.x <= self.max.x
            && self.min.y <= other.max.y
            && other.min.y <= self.max.y
    }

    /// The four corners, counter-clockwise from `min`.
    pub fn corners(self) -> [Vec2; 4] {
        [
            self.min,
            Vec2::new(self.max.x, self.min.y),
            self.max,
            Vec2::new(self.min.x, self.max.y),
        ]
    }

    /// The four edges, counter-clockwise from the bottom one.
    pub fn edges(self) -> [Segment; 4] {
        let c = self.corners();
        [
            Segment::new(c[0], c[1]),
            Segment::new(c[1], c[2]),
            Segment::new(c[2], c[3]),
            Segment::new(c[3], c[0]),
        ]
    }

    /// Distance from `p` to the rectangle, m (0 inside).
    pub fn distance_to_point(self, p: Vec2) -> f64 {
        let dx = (self.min.x - p.x).max(0.0).max(p.x - self.max.x);
        let dy = (self.min.y - p.y).max(0.0).max(p.y - self.max.y);
        hypot(dx, dy)
    }

    /// True when the segment touches or crosses the rectangle.
    pub fn intersects_segment(self, segment: Segment) -> bool {
        self.contains(segment.a)
            || self.contains(segment.b)
            || self.edges().iter().any(|e| e.intersects(segment))
    }

    /// Smallest `t` ≥ 0 at which the ray `origin + t·direction` meets the boundary, or
    /// `None`. A ray starting inside returns its exit distance.
    pub fn ray_intersection(self, origin: Vec2, direction: Vec2) -> Option<f64> {
        self.edges()
            .iter()
            .filter_map(|e| e.ray_intersection(origin, direction))
            .min_by(f64::total_cmp)
    }
}

/// A circle (a beacon pole's cross-section), m.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Circle {
    /// Centre.
    pub center: Vec2,
    /// Radius, m.
    pub radius_m: f64,
}

impl Circle {
    /// A circle from centre and radius.
    pub const fn new(center: Vec2, radius_m: f64) -> Self {
        Self { center, radius_m }
    }

    /// True when `p` is inside or on the circle.
    pub fn contains(self, p: Vec2) -> bool {
        p.distance(self.center) <= self.radius_m
    }

    /// Smallest `t` ≥ 0 at which the ray `origin + t·direction` meets the circle, or
    /// `None`. A ray starting inside returns its exit distance.
    pub fn ray_intersection(self, origin: Vec2, direction: Vec2) -> Option<f64> {
        let a = direction.dot(direction);
        if a == 0.0 {
            return None;
        }
        let w = origin - self.center;
        let half_b = w.dot(direction);
        let c = w.dot(w) - self.radius_m * self.radius_m;
        let disc = half_b * half_b - a * c;
        if disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        let t0 = (-half_b - root) / a;
        let t1 = (-half_b + root) / a;
        if t0 >= 0.0 {
            Some(t0)
        } else if t1 >= 0.0 {
            Some(t1)
        } else {
            None
        }
    }

    /// True when the segment touches or crosses the circle.
    pub fn intersects_segment(self, segment: Segment) -> bool {
        segment.distance_to_point(self.center) <= self.radius_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const EPS: f64 = 1e-9;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < EPS
    }

    #[test]
    fn wrap_angle_range_and_edges() {
        assert!(close(wrap_angle(PI), PI));
        assert!(close(wrap_angle(-PI), PI));
        assert!(close(wrap_angle(3.0 * PI / 2.0), -PI / 2.0));
        assert!(close(wrap_angle(-7.0), -7.0 + 2.0 * PI));
        assert!(wrap_angle(f64::NAN).is_nan());
    }

    #[test]
    fn compose_known_values() {
        let a = Pose2::new(1.0, 2.0, PI / 2.0);
        let b = Pose2::new(1.0, 0.0, PI / 2.0);
        let c = a.compose(b);
        assert!(close(c.x, 1.0) && close(c.y, 3.0) && close(c.yaw_rad, PI));
    }

    #[test]
    fn ray_hits_rect_and_circle() {
        let r = Rect::from_spans(1.0, 2.0, -1.0, 1.0);
        let t = r.ray_intersection(Vec2::ZERO, Vec2::new(1.0, 0.0));
        assert_eq!(t, Some(1.0));
        assert_eq!(r.ray_intersection(Vec2::ZERO, Vec2::new(-1.0, 0.0)), None);
        let c = Circle::new(Vec2::new(3.0, 0.0), 0.5);
        assert!(close(
            c.ray_intersection(Vec2::ZERO, Vec2::new(1.0, 0.0)).unwrap(),
            2.5
        ));
        assert!(close(
            c.ray_intersection(Vec2::new(3.0, 0.0), Vec2::new(0.0, 1.0))
                .unwrap(),
            0.5
        ));
        assert_eq!(c.ray_intersection(Vec2::ZERO, Vec2::new(0.0, 1.0)), None);
    }

    #[test]
    fn segment_rect_intersection() {
        let r = Rect::from_spans(0.0, 1.0, 0.0, 1.0);
        assert!(r.intersects_segment(Segment::new(Vec2::new(-1.0, 0.5), Vec2::new(2.0, 0.5))));
        assert!(!r.intersects_segment(Segment::new(Vec2::new(-1.0, 1.5), Vec2::new(2.0, 1.5))));
        assert!(r.intersects_segment(Segment::new(Vec2::new(0.5, 0.5), Vec2::new(0.6, 0.6))));
        assert!(r.intersects_segment(Segment::new(Vec2::new(-1.0, 1.0), Vec2::new(2.0, 1.0))));
        assert!(close(r.distance_to_point(Vec2::new(4.0, 5.0)), 5.0));
    }

    fn pose() -> impl Strategy<Value = Pose2> {
        (-10.0..10.0f64, -10.0..10.0f64, -4.0..4.0f64).prop_map(|(x, y, t)| Pose2::new(x, y, t))
    }

    proptest! {
        #[test]
        fn wrap_is_in_range_and_equivalent(a in -100.0..100.0f64) {
            let w = wrap_angle(a);
            prop_assert!(w > -PI && w <= PI);
            prop_assert!(((a - w) / (2.0 * PI)).round().mul_add(-2.0 * PI, a - w).abs() < 1e-9);
        }

        #[test]
        fn compose_with_inverse_is_identity(p in pose(), q in pose()) {
            let id = p.compose(p.inverse());
            prop_assert!(id.x.abs() < 1e-9 && id.y.abs() < 1e-9 && wrap_angle(id.yaw_rad).abs() < 1e-9);
            let back = p.compose(p.relative(q));
            prop_assert!((back.x - q.x).abs() < 1e-9 && (back.y - q.y).abs() < 1e-9);
            prop_assert!(wrap_angle(back.yaw_rad - q.yaw_rad).abs() < 1e-9);
        }

        #[test]
        fn point_transform_round_trips(p in pose(), x in -5.0..5.0f64, y in -5.0..5.0f64) {
            let v = Vec2::new(x, y);
            let back = p.inverse_transform_point(p.transform_point(v));
            prop_assert!(back.distance(v) < 1e-9);
            prop_assert!((p.transform_point(v).distance(p.position()) - v.norm()).abs() < 1e-9);
        }

        #[test]
        fn ray_hit_point_lies_on_circle(
            ox in -3.0..3.0f64, oy in -3.0..3.0f64, a in -4.0..4.0f64, r in 0.01..1.0f64,
        ) {
            let c = Circle::new(Vec2::new(0.5, -0.2), r);
            let d = Vec2::from_angle(a);
            let o = Vec2::new(ox, oy);
            if let Some(t) = c.ray_intersection(o, d) {
                prop_assert!(t >= 0.0);
                prop_assert!(((o + d * t).distance(c.center) - r).abs() < 1e-9);
            } else {
                // Missed: the ray's closest approach is outside the circle, or it points away.
                let t_close = (c.center - o).dot(d).max(0.0);
                prop_assert!((o + d * t_close).distance(c.center) > r - 1e-12);
            }
        }

        #[test]
        fn ray_hit_point_lies_on_rect_boundary(
            ox in -3.0..3.0f64, oy in -3.0..3.0f64, a in -4.0..4.0f64,
        ) {
            let r = Rect::from_spans(-0.5, 1.0, -0.25, 0.75);
            let d = Vec2::from_angle(a);
            let o = Vec2::new(ox, oy);
            if let Some(t) = r.ray_intersection(o, d) {
                let p = o + d * t;
                prop_assert!(r.inflated(1e-9).contains(p) && !r.inflated(-1e-9).contains(p));
            } else {
                prop_assert!(!r.contains(o));
            }
        }
    }
}
