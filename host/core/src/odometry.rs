//! Wheel odometry: cumulative encoder ticks → wheel angles → body increments → pose.
//!
//! Per update (one telemetry batch, 50 Hz): tick deltas (wrapping i32 arithmetic, so the
//! Mega's cumulative counters may overflow), wheel angle deltas Δφ = Δticks·2π/ticks_per_rev,
//! the body's arc increment (du, dv, dθ) by the robot's mecanum model (whose forward
//! scales dv by `robot.strafe_factor`: the rollers' sideways slip), then the exact
//! constant-curvature integration (the SE(2) exponential). The original (original-system.md
//! §4.3) uses the same arc but rotates the chord by θ + dθ/2 although the chord formula is
//! already in the start frame, so it over-rotates each step by dθ/2; here the chord is
//! rotated by θ. Yaw is wrapped into (−π, π] (the original does not wrap).

use std::f64::consts::TAU;

use crate::config::RobotConfig;
use crate::field::geometry::{Pose2, wrap_angle};
use crate::kinematics::{BodyTwist, Mecanum};

/// A rigid displacement in the robot frame at the start of a step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BodyIncrement {
    /// Forward displacement, m.
    pub dx_m: f64,
    /// Leftward displacement, m.
    pub dy_m: f64,
    /// Yaw change, rad (counter-clockwise).
    pub dtheta_rad: f64,
}

impl BodyIncrement {
    /// As a pose of the end frame in the start frame.
    pub fn as_pose(self) -> Pose2 {
        Pose2::new(self.dx_m, self.dy_m, self.dtheta_rad)
    }
}

/// The displacement after moving along the arc increment (du, dv, dθ) — forward and left
/// distances and yaw change at constant curvature — expressed in the start frame:
/// dx = (du·sin dθ + dv·(cos dθ − 1))/dθ, dy = (du·(1 − cos dθ) + dv·sin dθ)/dθ
/// (Taylor series near dθ = 0).
pub fn arc_displacement(du_m: f64, dv_m: f64, dtheta_rad: f64) -> BodyIncrement {
    let t = dtheta_rad;
    // sin(t)/t and (1 − cos t)/t, series for small t (error < 1e-20 below 1e-4).
    let (sin_over_t, one_minus_cos_over_t) = if t.abs() < 1e-4 {
        let t2 = t * t;
        (1.0 - t2 / 6.0, t / 2.0 - t * t2 / 24.0)
    } else {
        (t.sin() / t, (1.0 - t.cos()) / t)
    };
    BodyIncrement {
        dx_m: du_m * sin_over_t - dv_m * one_minus_cos_over_t,
        dy_m: du_m * one_minus_cos_over_t + dv_m * sin_over_t,
        dtheta_rad: t,
    }
}

/// What one odometry update produced.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OdometryStep {
    /// True for the first update, which only stores the totals (everything else is zero).
    pub is_first: bool,
    /// Ticks since the previous update, per wheel (motor index order).
    pub tick_deltas: [i32; 4],
    /// Wheel angle increments, rad (wire sign convention).
    pub wheel_angle_deltas_rad: [f64; 4],
    /// Wheel speeds over the measured period, rad/s; zero when the period is 0.
    pub wheel_speeds_rad_s: [f64; 4],
    /// Displacement in the robot frame at the start of the step.
    pub body_increment: BodyIncrement,
    /// Mean body twist over the step (the arc increment divided by the period); zero when
    /// the period is 0.
    pub twist: BodyTwist,
    /// Pose after the step, in the odometry frame.
    pub pose: Pose2,
}

/// Dead-reckoning from the Mega's cumulative tick counters.
#[derive(Clone, Debug, PartialEq)]
pub struct Odometry {
    kinematics: Mecanum,
    ticks_per_wheel_rev: f64,
    last_totals: Option<[i32; 4]>,
    pose: Pose2,
}

impl Odometry {
    /// Odometry for the robot's geometry and encoder resolution, at the origin.
    pub fn new(robot: &RobotConfig) -> Self {
        Self {
            kinematics: Mecanum::new(robot),
            ticks_per_wheel_rev: robot.ticks_per_wheel_rev,
            last_totals: None,
            pose: Pose2::default(),
        }
    }

    /// The current pose in the odometry frame.
    pub fn pose(&self) -> Pose2 {
        self.pose
    }

    /// Set the pose (the yaw is wrapped). The tick totals are kept.
    pub fn reset(&mut self, pose: Pose2) {
        self.pose = Pose2::new(pose.x, pose.y, wrap_angle(pose.yaw_rad));
    }

    /// Forget the last tick totals, so the next update only initialises them: after the
    /// Mega reboots (`r`) its counters restart from zero, which must not read as motion.
    pub fn forget_totals(&mut self) {
        self.last_totals = None;
    }

    /// Advance with the cumulative tick totals (motor index order) and the period the
    /// Mega measured for them (channel `k`), µs.
    pub fn update(&mut self, totals: [i32; 4], period_us: u32) -> OdometryStep {
        let Some(last) = self.last_totals.replace(totals) else {
            return OdometryStep {
                is_first: true,
                pose: self.pose,
                ..OdometryStep::default()
            };
        };
        let tick_deltas: [i32; 4] = std::array::from_fn(|i| totals[i].wrapping_sub(last[i]));
        let wheel_angle_deltas_rad =
            tick_deltas.map(|d| f64::from(d) * TAU / self.ticks_per_wheel_rev);
        let arc = self.kinematics.forward(wheel_angle_deltas_rad);
        let body_increment = arc_displacement(arc.vx_m_s, arc.vy_m_s, arc.omega_rad_s);
        self.pose = self.pose.compose(body_increment.as_pose());
        let period_s = f64::from(period_us) * 1e-6;
        let (wheel_speeds_rad_s, twist) = if period_us == 0 {
            ([0.0; 4], BodyTwist::default())
        } else {
            (
                wheel_angle_deltas_rad.map(|a| a / period_s),
                arc.scaled(1.0 / period_s),
            )
        };
        OdometryStep {
            is_first: false,
            tick_deltas,
            wheel_angle_deltas_rad,
            wheel_speeds_rad_s,
            body_increment,
            twist,
            pose: self.pose,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::geometry::Vec2;
    use proptest::prelude::*;
    use std::f64::consts::FRAC_PI_2;

    const PERIOD_US: u32 = 20_000;

    fn robot() -> RobotConfig {
        RobotConfig::default()
    }

    /// Cumulative tick totals after driving `twist` for `t_s` from zero (rounded).
    fn ticks_for(twist: BodyTwist, t_s: f64) -> [i32; 4] {
        let r = robot();
        Mecanum::new(&r)
            .inverse(twist)
            .map(|w| (w * t_s * r.ticks_per_wheel_rev / TAU).round() as i32)
    }

    /// Closed form: constant twist for `t_s` from `start`, by rotation about the
    /// instantaneous centre (independent of [`arc_displacement`]).
    fn closed_form(start: Pose2, twist: BodyTwist, t_s: f64) -> Pose2 {
        let w = twist.omega_rad_s;
        if w == 0.0 {
            let d = Vec2::new(twist.vx_m_s, twist.vy_m_s).rotated(start.yaw_rad) * t_s;
            return Pose2::new(start.x + d.x, start.y + d.y, start.yaw_rad);
        }
        let centre = start.transform_point(Vec2::new(-twist.vy_m_s / w, twist.vx_m_s / w));
        let p = centre + (start.position() - centre).rotated(w * t_s);
        Pose2::new(p.x, p.y, wrap_angle(start.yaw_rad + w * t_s))
    }

    fn drive(odo: &mut Odometry, twist: BodyTwist, steps: u32) -> Pose2 {
        odo.update([0; 4], PERIOD_US);
        for k in 1..=steps {
            odo.update(ticks_for(twist, f64::from(k) * 0.02), PERIOD_US);
        }
        odo.pose()
    }

    fn assert_near(got: Pose2, want: Pose2, tol_m: f64, tol_rad: f64) {
        assert!(
            got.position().distance(want.position()) < tol_m,
            "{got:?} vs {want:?}"
        );
        assert!(
            wrap_angle(got.yaw_rad - want.yaw_rad).abs() < tol_rad,
            "{got:?} vs {want:?}"
        );
    }

    #[test]
    fn first_update_only_initialises() {
        let mut odo = Odometry::new(&robot());
        let s = odo.update([100, -5, 7, 1_000_000], PERIOD_US);
        assert!(s.is_first && s.pose == Pose2::default() && s.tick_deltas == [0; 4]);
        let s = odo.update([100, -5, 7, 1_000_000], PERIOD_US);
        assert!(!s.is_first && s.pose == Pose2::default());
    }

    #[test]
    fn straight_sideways_and_rotation_in_place() {
        // 1 m forward in 5 s.
        let mut odo = Odometry::new(&robot());
        let p = drive(&mut odo, BodyTwist::new(0.2, 0.0, 0.0), 250);
        assert_near(p, Pose2::new(1.0, 0.0, 0.0), 1e-4, 1e-4);
        // 0.5 m to the left, starting at yaw 90°: moves along −x.
        let mut odo = Odometry::new(&robot());
        odo.reset(Pose2::new(0.0, 0.0, FRAC_PI_2));
        let p = drive(&mut odo, BodyTwist::new(0.0, 0.25, 0.0), 100);
        assert_near(p, Pose2::new(-0.5, 0.0, FRAC_PI_2), 1e-4, 1e-4);
        // A quarter turn in place. One tick on all four wheels is 3.9e-4 rad of yaw; the
        // totals are rounded to the nearest tick, so allow half of that.
        let mut odo = Odometry::new(&robot());
        let p = drive(&mut odo, BodyTwist::new(0.0, 0.0, FRAC_PI_2), 50);
        assert_near(p, Pose2::new(0.0, 0.0, FRAC_PI_2), 1e-6, 2e-4);
    }

    #[test]
    fn a_strafe_counts_only_the_sideways_travel_the_rollers_give() {
        let robot = RobotConfig {
            strafe_factor: 0.93,
            ..robot()
        };
        // 0.5 m of wheel travel to the left: 0.465 m on the floor; forward travel and
        // turns keep the kinematics'.
        let mut odo = Odometry::new(&robot);
        let p = drive(&mut odo, BodyTwist::new(0.0, 0.25, 0.0), 100);
        assert_near(p, Pose2::new(0.0, 0.465, 0.0), 1e-4, 1e-4);
        let mut odo = Odometry::new(&robot);
        let p = drive(&mut odo, BodyTwist::new(0.2, 0.0, 0.0), 250);
        assert_near(p, Pose2::new(1.0, 0.0, 0.0), 1e-4, 1e-4);
        let mut odo = Odometry::new(&robot);
        let p = drive(&mut odo, BodyTwist::new(0.0, 0.0, FRAC_PI_2), 50);
        assert_near(p, Pose2::new(0.0, 0.0, FRAC_PI_2), 1e-6, 2e-4);
    }

    #[test]
    fn speeds_use_the_measured_period() {
        let mut odo = Odometry::new(&robot());
        odo.update([0; 4], PERIOD_US);
        let s = odo.update([2803, -2803, 2803, -2803], 25_000);
        let w = 2803.0 * TAU / 2803.2 / 0.025;
        assert!(
            (s.wheel_speeds_rad_s[0] - w).abs() < 1e-9
                && (s.wheel_speeds_rad_s[1] + w).abs() < 1e-9
        );
        assert!((s.twist.vx_m_s - w * 0.03).abs() < 1e-9 && s.twist.omega_rad_s.abs() < 1e-12);
        let s = odo.update([2803; 4], 0);
        assert_eq!(s.wheel_speeds_rad_s, [0.0; 4]);
        assert!(s.body_increment.dtheta_rad > 0.0);
    }

    #[test]
    fn arc_is_exact_in_one_step_or_many() {
        // Constant per-step tick deltas = a constant twist, exactly. One big step must land
        // where 100 small ones do, and both on the closed form.
        let per_step = [40, 10, 60, 30];
        let mut many = Odometry::new(&robot());
        many.update([0; 4], PERIOD_US);
        for k in 1..=100 {
            many.update(per_step.map(|d| d * k), PERIOD_US);
        }
        let mut one = Odometry::new(&robot());
        one.update([0; 4], PERIOD_US);
        let step = one.update(per_step.map(|d| d * 100), 100 * PERIOD_US);
        assert!(
            step.body_increment.dtheta_rad.abs() > 1.0,
            "a real arc: {step:?}"
        );
        assert_near(one.pose(), many.pose(), 1e-12, 1e-12);
        assert_near(
            one.pose(),
            closed_form(Pose2::default(), step.twist, 2.0),
            1e-12,
            1e-12,
        );
    }

    #[test]
    fn arc_displacement_matches_fine_numerical_integration() {
        let (du, dv, dth) = (0.3, -0.1, 1.3);
        let n = 100_000;
        let (mut x, mut y) = (0.0f64, 0.0f64);
        for k in 0..n {
            let th = dth * (f64::from(k) + 0.5) / f64::from(n);
            let v = Vec2::new(du, dv).rotated(th) * (1.0 / f64::from(n));
            x += v.x;
            y += v.y;
        }
        let d = arc_displacement(du, dv, dth);
        assert!(
            (d.dx_m - x).abs() < 1e-9 && (d.dy_m - y).abs() < 1e-9,
            "{d:?} vs {x}, {y}"
        );
        let small = arc_displacement(du, dv, 1e-6);
        assert!((small.dx_m - du).abs() < 1e-6 && (small.dy_m - dv).abs() < 1e-6);
    }

    #[test]
    fn tick_counters_wrap_around() {
        let mut odo = Odometry::new(&robot());
        let start = [i32::MAX - 5, i32::MIN + 5, i32::MAX, i32::MIN];
        odo.update(start, PERIOD_US);
        let next = [
            start[0].wrapping_add(10),
            start[1].wrapping_sub(10),
            start[2].wrapping_add(10),
            start[3].wrapping_sub(10),
        ];
        let s = odo.update(next, PERIOD_US);
        assert_eq!(s.tick_deltas, [10, -10, 10, -10]);
        assert!(s.body_increment.dx_m > 0.0 && s.body_increment.dy_m.abs() < 1e-15);
    }

    proptest! {
        #[test]
        fn constant_twist_reproduces_the_pose(
            vx in -0.5..0.5f64, vy in -0.5..0.5f64, w in -3.0..3.0f64, steps in 1u32..200,
            x0 in -0.5..0.5f64, y0 in -0.5..0.5f64, th0 in -3.0..3.0f64,
        ) {
            let twist = BodyTwist::new(vx, vy, w);
            let start = Pose2::new(x0, y0, th0);
            let mut odo = Odometry::new(&robot());
            odo.reset(start);
            let got = drive(&mut odo, twist, steps);
            let want = closed_form(start, twist, f64::from(steps) * 0.02);
            // Quantisation: ±½ tick per wheel = ±34 µm of rim; it does not accumulate in
            // the totals, only through the path's heading.
            let path_m = Vec2::new(vx, vy).norm() * f64::from(steps) * 0.02;
            prop_assert!(got.position().distance(want.position()) < 2e-4 + 1e-3 * path_m,
                "{:?} vs {:?}", got, want);
            prop_assert!(wrap_angle(got.yaw_rad - want.yaw_rad).abs() < 5e-4);
        }
    }
}
