//! Contact between rigid shapes on the floor: how far, and which way, one must move to stop
//! overlapping another (the minimum translation).
//!
//! The world keeps bodies apart by projection after each step (see `World::step`): an
//! overlapping body is moved out along the minimum translation and loses its velocity into
//! the obstacle. That is a rigid-body projection, not dynamics: no impulses, no friction
//! between the bodies, no rotation from an off-centre push.

use ratf_core::field::OrientedRect;
use ratf_core::field::geometry::Vec2;

/// A solid on the floor that bodies cannot enter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A rectangle (a wall, a divider, a part, the robot's body).
    Rect(OrientedRect),
    /// A circle: centre and radius, m (a beacon pole).
    Circle(Vec2, f64),
}

/// Overlap (m) that counts as touching, not entering: a nanometre, the rounding left by the
/// previous step's push (without it a robot pushing a part would be stopped by it).
pub const TOUCHING_M: f64 = 1e-9;

/// The translation (m, world frame) that moves `rect` out of `shape`, or `None` when they do
/// not overlap by more than [`TOUCHING_M`].
pub fn push_out(rect: &OrientedRect, shape: &Shape) -> Option<Vec2> {
    match shape {
        Shape::Rect(other) => rect_out_of_rect(rect, other),
        Shape::Circle(center, radius_m) => rect_out_of_circle(rect, *center, *radius_m),
    }
}

/// Separating axis theorem: the axis of least overlap among the four edge normals.
fn rect_out_of_rect(a: &OrientedRect, b: &OrientedRect) -> Option<Vec2> {
    // Far apart (beyond both half-diagonals): no need for the axes.
    let reach = a.half_x_m.hypot(a.half_y_m) + b.half_x_m.hypot(b.half_y_m);
    if a.pose.position().distance(b.pose.position()) >= reach {
        return None;
    }
    let mut best: Option<(f64, Vec2)> = None;
    for axis in axes(a).into_iter().chain(axes(b)) {
        let (a_lo, a_hi) = projection(a, axis);
        let (b_lo, b_hi) = projection(b, axis);
        let forward = b_hi - a_lo; // moving a along +axis by this clears b
        let backward = a_hi - b_lo; // moving a along −axis by this clears b
        if forward <= TOUCHING_M || backward <= TOUCHING_M {
            return None;
        }
        let candidate = if forward < backward {
            (forward, axis)
        } else {
            (backward, axis * -1.0)
        };
        if best.is_none_or(|(depth, _)| candidate.0 < depth) {
            best = Some(candidate);
        }
    }
    best.map(|(depth, direction)| direction * depth)
}

fn rect_out_of_circle(rect: &OrientedRect, center: Vec2, radius_m: f64) -> Option<Vec2> {
    let local = rect.pose.inverse_transform_point(center);
    let (hx, hy) = (rect.half_x_m, rect.half_y_m);
    let inside = local.x.abs() < hx && local.y.abs() < hy;
    let local_push = if inside {
        // The centre is inside the rectangle: out through the nearest side.
        let to_x_side = hx - local.x.abs();
        let to_y_side = hy - local.y.abs();
        if to_x_side < to_y_side {
            Vec2::new(-local.x.signum() * (to_x_side + radius_m), 0.0)
        } else {
            Vec2::new(0.0, -local.y.signum() * (to_y_side + radius_m))
        }
    } else {
        let nearest = Vec2::new(local.x.clamp(-hx, hx), local.y.clamp(-hy, hy));
        let away = nearest - local;
        let distance = away.norm();
        if distance >= radius_m - TOUCHING_M || distance == 0.0 {
            return None;
        }
        away * ((radius_m - distance) / distance)
    };
    Some(local_push.rotated(rect.pose.yaw_rad))
}

fn axes(rect: &OrientedRect) -> [Vec2; 2] {
    let u = Vec2::from_angle(rect.pose.yaw_rad);
    [u, Vec2::new(-u.y, u.x)]
}

fn projection(rect: &OrientedRect, axis: Vec2) -> (f64, f64) {
    let center = rect.pose.position().dot(axis);
    let u = Vec2::from_angle(rect.pose.yaw_rad);
    let reach = rect.half_x_m * u.dot(axis).abs() + rect.half_y_m * u.cross(axis).abs();
    (center - reach, center + reach)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_core::field::geometry::Pose2;

    fn square(x: f64, y: f64, yaw: f64) -> OrientedRect {
        OrientedRect::new(Pose2::new(x, y, yaw), 0.30, 0.30)
    }

    fn moved(rect: &OrientedRect, by: Vec2) -> OrientedRect {
        let mut out = *rect;
        out.pose.x += by.x;
        out.pose.y += by.y;
        out
    }

    #[test]
    fn a_square_into_a_wall_goes_back_the_way_it_came() {
        let wall = Shape::Rect(OrientedRect::new(Pose2::new(0.3, 0.0, 0.0), 0.2, 2.0));
        // Front face at 0.16, the wall's at 0.2: no contact.
        assert_eq!(push_out(&square(0.01, 0.0, 0.0), &wall), None);
        // 7 mm in: out by 7 mm along −x.
        let robot = square(0.057, 0.3, 0.0);
        let push = push_out(&robot, &wall).unwrap();
        assert!(
            (push.x + 0.007).abs() < 1e-12 && push.y.abs() < 1e-12,
            "{push:?}"
        );
        assert_eq!(push_out(&moved(&robot, push), &wall), None);
    }

    #[test]
    fn a_turned_square_is_pushed_out_by_its_corner_depth() {
        let wall = Shape::Rect(OrientedRect::new(Pose2::new(0.3, 0.0, 0.0), 0.2, 2.0));
        // At 45° the corner reaches 0.212 m: 12 mm into a wall face at 0.2.
        let robot = square(0.0, 0.0, std::f64::consts::FRAC_PI_4);
        let push = push_out(&robot, &wall).unwrap();
        assert!(
            (push.x + (0.15 * 2f64.sqrt() - 0.2)).abs() < 1e-12,
            "{push:?}"
        );
        assert_eq!(push_out(&moved(&robot, push), &wall), None);
    }

    #[test]
    fn a_pole_pushes_a_rectangle_away_from_its_centre() {
        let robot = square(0.0, 0.0, 0.0);
        // Facing a face: straight back.
        let push = push_out(&robot, &Shape::Circle(Vec2::new(0.18, 0.0), 0.045)).unwrap();
        assert!((push.x + 0.015).abs() < 1e-12 && push.y.abs() < 1e-12);
        // At a corner: along the diagonal, just clear.
        let pole = Shape::Circle(Vec2::new(0.18, 0.18), 0.045);
        let push = push_out(&robot, &pole).unwrap();
        assert!(push.x < 0.0 && (push.x - push.y).abs() < 1e-12);
        let after = moved(&robot, push);
        assert!(push_out(&after, &pole).is_none_or(|p| p.norm() < 1e-12));
        // Clear of the corner: nothing.
        assert_eq!(
            push_out(&robot, &Shape::Circle(Vec2::new(0.19, 0.19), 0.045)),
            None
        );
        // The pole's centre inside the body: out through the nearest side, fully.
        let pole = Shape::Circle(Vec2::new(0.0, 0.14), 0.045);
        let push = push_out(&robot, &pole).unwrap();
        assert!((push.y + 0.055).abs() < 1e-12 && push.x.abs() < 1e-12);
    }
}
