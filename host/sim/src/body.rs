//! The robot's body on the floor: four mecanum wheels, driven by their motors, with a traction
//! limit.
//!
//! Model. The wheels' speeds ask for a body twist (the mecanum forward kinematics of the
//! wheel speeds, "no-slip twist"). Reaching it from the current twist within one step needs a
//! horizontal acceleration, which only friction can supply: at most μ·g for the centre of
//! mass and μ·g·r/k² for the yaw (r: the wheels' lever arm about the centre, k²: the body's
//! squared radius of gyration, a uniform square plate of the footprint). The two share the
//! same friction budget, so the demand is limited to the ellipse
//! `(a / a_max)² + (α / α_max)² ≤ 1`, direction kept. Within the limit the body moves exactly
//! as the wheels say (odometry is exact up to encoder quantisation); beyond it the wheels
//! slip: they keep the speed their motors give them while the body lags, so aggressive
//! driving costs odometry accuracy, as on the real robot. The acceleration counts the
//! centripetal term of a turning body, so a fast curve can slip too.
//!
//! Contact ([`Body::push`]): the world moves a body that ran into something back out, and
//! takes away its velocity into the obstacle. The wheels keep turning as their motors drive
//! them, so the encoders count on while the body stands against a wall: the next step's
//! no-slip twist again asks for more than the contact allows, and the difference is slip.
//!
//! Simplifications (stated, not hidden): the motors do not feel the body's load (a slipping
//! wheel spins at its free speed, a wheel against a wall too); the wheels have no inertia of
//! their own; the friction budget is isotropic although mecanum rollers grip less across than
//! along.

use ratf_core::config::{RobotConfig, TractionConfig};
use ratf_core::field::geometry::{Pose2, Vec2};
use ratf_core::kinematics::{BodyTwist, Mecanum};
use ratf_core::odometry::arc_displacement;

/// Standard gravity, m/s².
const GRAVITY_M_S2: f64 = 9.806_65;

/// The largest accelerations friction allows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TractionLimits {
    /// Linear acceleration of the centre of mass, m/s² (μ·g).
    pub linear_m_s2: f64,
    /// Yaw acceleration, rad/s² (μ·g·r/k²).
    pub angular_rad_s2: f64,
}

impl TractionLimits {
    /// The limits for a robot of this geometry on a floor of this friction.
    pub fn new(traction: &TractionConfig, robot: &RobotConfig) -> Self {
        let linear_m_s2 = traction.friction_coefficient * GRAVITY_M_S2;
        let lever_arm_m = (robot.front_back_wheel_distance_m / 2.0)
            .hypot(robot.left_right_wheel_distance_m / 2.0);
        let gyration_sq_m2 =
            (robot.footprint_length_m.powi(2) + robot.footprint_width_m.powi(2)) / 12.0;
        Self {
            linear_m_s2,
            angular_rad_s2: linear_m_s2 * lever_arm_m / gyration_sq_m2,
        }
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepReport {
    /// The wheels slipped: friction could not give the acceleration they asked for.
    pub slipped: bool,
    /// Difference between the no-slip speed and the body's speed after the step, m/s.
    pub slip_speed_m_s: f64,
}

/// The body's ground-truth state.
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    /// Pose of the robot frame in the world, m and rad.
    pub pose: Pose2,
    /// Velocity in the robot frame.
    pub twist: BodyTwist,
    /// Accumulated wheel angles, wire sign convention, rad (what the encoders measure).
    pub wheel_angles_rad: [f64; 4],
}

/// How the floor answers the wheels, beyond the kinematics' nominal geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground {
    /// Each wheel's radius over the kinematics' radius (motor index order).
    pub wheel_radius_spread: [f64; 4],
    /// Lateral (strafe) travel over the kinematics' (the mecanum rollers' slip).
    pub lateral_factor: f64,
}

impl Ground {
    /// Wheels exactly as the kinematics says.
    pub const NOMINAL: Self = Self {
        wheel_radius_spread: [1.0; 4],
        lateral_factor: 1.0,
    };
}

impl Body {
    /// A body at rest at `pose`.
    pub fn at_rest(pose: Pose2) -> Self {
        Self {
            pose,
            twist: BodyTwist::default(),
            wheel_angles_rad: [0.0; 4],
        }
    }

    /// Advance by `dt_s` with the wheels turning at `wheel_speeds_rad_s` (wire convention).
    /// `grip` (0..=1) is the fraction of the wheels' motion the floor passes on to the body:
    /// 1 normally; less during an injected slip burst (a slippery patch, a dusty floor), when
    /// the wheels turn further than the body moves whatever the acceleration.
    pub fn step(
        &mut self,
        wheel_speeds_rad_s: [f64; 4],
        mecanum: &Mecanum,
        limits: &TractionLimits,
        ground: &Ground,
        grip: f64,
        dt_s: f64,
    ) -> StepReport {
        for (angle, speed) in self.wheel_angles_rad.iter_mut().zip(wheel_speeds_rad_s) {
            *angle += speed * dt_s;
        }
        // The ground moves by each wheel's own radius; the rollers let the strafe fall short.
        let rim_speeds =
            std::array::from_fn(|k| wheel_speeds_rad_s[k] * ground.wheel_radius_spread[k]);
        let mut wanted = mecanum.forward(rim_speeds).scaled(grip.clamp(0.0, 1.0));
        wanted.vy_m_s *= ground.lateral_factor;
        let v = self.twist;
        // Acceleration in an inertial frame, written in robot-frame coordinates: the change
        // of the robot-frame velocity plus the centripetal term ω × v.
        let ax = (wanted.vx_m_s - v.vx_m_s) / dt_s - v.omega_rad_s * v.vy_m_s;
        let ay = (wanted.vy_m_s - v.vy_m_s) / dt_s + v.omega_rad_s * v.vx_m_s;
        let alpha = (wanted.omega_rad_s - v.omega_rad_s) / dt_s;
        let demand = (ax.hypot(ay) / limits.linear_m_s2).hypot(alpha / limits.angular_rad_s2);
        let (slipped, factor) = if demand > 1.0 {
            (true, 1.0 / demand)
        } else {
            (false, 1.0)
        };
        self.twist = if slipped {
            let (ax, ay, alpha) = (ax * factor, ay * factor, alpha * factor);
            BodyTwist::new(
                v.vx_m_s + (ax + v.omega_rad_s * v.vy_m_s) * dt_s,
                v.vy_m_s + (ay - v.omega_rad_s * v.vx_m_s) * dt_s,
                v.omega_rad_s + alpha * dt_s,
            )
        } else {
            wanted
        };
        let t = self.twist;
        let arc = arc_displacement(t.vx_m_s * dt_s, t.vy_m_s * dt_s, t.omega_rad_s * dt_s);
        self.pose = self.pose.compose(arc.as_pose());
        StepReport {
            slipped,
            slip_speed_m_s: (wanted.vx_m_s - self.twist.vx_m_s)
                .hypot(wanted.vy_m_s - self.twist.vy_m_s),
        }
    }

    /// Contact: move the body by `by` (m, world frame) out of an obstacle and take away the
    /// part of its velocity that points into it (against `by`); the velocity along the
    /// obstacle's face and the yaw rate are kept. The wheels' angles do not change.
    pub fn push(&mut self, by: Vec2) {
        let length = by.norm();
        if length == 0.0 || !length.is_finite() {
            return;
        }
        self.pose.x += by.x;
        self.pose.y += by.y;
        // The normal, in the robot frame.
        let normal = (by * (1.0 / length)).rotated(-self.pose.yaw_rad);
        let velocity = Vec2::new(self.twist.vx_m_s, self.twist.vy_m_s);
        let into = velocity.dot(normal);
        if into < 0.0 {
            let kept = velocity - normal * into;
            self.twist = BodyTwist::new(kept.x, kept.y, self.twist.omega_rad_s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> (Mecanum, TractionLimits) {
        let robot = RobotConfig::default();
        (
            Mecanum::rigid(&robot),
            TractionLimits::new(&TractionConfig::default(), &robot),
        )
    }

    #[test]
    fn default_limits_are_plausible() {
        let (_, limits) = setup();
        assert!((limits.linear_m_s2 - 0.7 * 9.80665).abs() < 1e-9);
        // r = 0.1228 m, k² = 0.015 m²: α_max ≈ 56 rad/s².
        assert!(
            (limits.angular_rad_s2 - 56.2).abs() < 0.5,
            "{}",
            limits.angular_rad_s2
        );
    }

    #[test]
    fn gentle_driving_does_not_slip_and_follows_the_wheels() {
        let (mecanum, limits) = setup();
        let mut body = Body::at_rest(Pose2::new(0.0, 0.0, 0.0));
        let target = BodyTwist::new(0.3, 0.1, 0.5);
        let dt = 0.0005;
        for i in 0..2000 {
            // Ramp the wheels up over 0.5 s: at most 0.6 m/s², well inside μg.
            let ramp = (i as f64 * dt / 0.5).min(1.0);
            let report = body.step(
                mecanum.inverse(target.scaled(ramp)),
                &mecanum,
                &limits,
                &Ground::NOMINAL,
                1.0,
                dt,
            );
            assert!(!report.slipped, "slipped at step {i}");
        }
        assert!((body.twist.vx_m_s - 0.3).abs() < 1e-9);
        assert!((body.twist.omega_rad_s - 0.5).abs() < 1e-9);
    }

    #[test]
    fn a_wheel_speed_step_slips_and_the_body_lags() {
        let (mecanum, limits) = setup();
        let mut body = Body::at_rest(Pose2::new(0.0, 0.0, 0.0));
        let wheels = mecanum.inverse(BodyTwist::new(0.6, 0.0, 0.0));
        let dt = 0.0005;
        let report = body.step(wheels, &mecanum, &limits, &Ground::NOMINAL, 1.0, dt);
        assert!(report.slipped);
        assert!((body.twist.vx_m_s - limits.linear_m_s2 * dt).abs() < 1e-12);
        // After enough time the body has caught up with the wheels.
        let mut t = dt;
        while t < 0.6 / limits.linear_m_s2 + 0.01 {
            body.step(wheels, &mecanum, &limits, &Ground::NOMINAL, 1.0, dt);
            t += dt;
        }
        assert!((body.twist.vx_m_s - 0.6).abs() < 1e-9);
        // The wheels turned further than the body moved: odometry would over-count.
        let rolled_m = body.wheel_angles_rad[0] * mecanum.wheel_radius_m();
        assert!(
            rolled_m > body.pose.x + 0.01,
            "{rolled_m} vs {}",
            body.pose.x
        );
    }

    #[test]
    fn a_larger_wheel_carries_further_and_the_rollers_shorten_a_strafe() {
        let (mecanum, limits) = setup();
        let drive = |twist: BodyTwist, ground: &Ground| {
            let mut body = Body::at_rest(Pose2::new(0.0, 0.0, 0.0));
            let dt = 0.001;
            for i in 0..2000 {
                let ramp = (i as f64 * dt / 0.5).min(1.0);
                body.step(
                    mecanum.inverse(twist.scaled(ramp)),
                    &mecanum,
                    &limits,
                    ground,
                    1.0,
                    dt,
                );
            }
            (body.pose, body.wheel_angles_rad)
        };
        let forward = BodyTwist::new(0.2, 0.0, 0.0);
        let (nominal, nominal_angles) = drive(forward, &Ground::NOMINAL);
        let bigger = Ground {
            wheel_radius_spread: [1.01; 4],
            lateral_factor: 1.0,
        };
        let (further, angles) = drive(forward, &bigger);
        assert!(
            (further.x / nominal.x - 1.01).abs() < 1e-9,
            "{further:?} {nominal:?}"
        );
        assert_eq!(angles, nominal_angles, "the encoders count the same turns");
        let sideways = BodyTwist::new(0.0, 0.2, 0.0);
        let (strafe, _) = drive(sideways, &Ground::NOMINAL);
        let rollers = Ground {
            wheel_radius_spread: [1.0; 4],
            lateral_factor: 0.93,
        };
        let (short, _) = drive(sideways, &rollers);
        assert!(
            (short.y / strafe.y - 0.93).abs() < 1e-9,
            "{short:?} {strafe:?}"
        );
    }

    #[test]
    fn a_push_stops_the_motion_into_the_obstacle_and_keeps_the_rest() {
        // Heading +y (yaw 90°), moving forward 0.3 m/s and left 0.1 m/s (world −x).
        let mut body = Body::at_rest(Pose2::new(1.0, 2.0, std::f64::consts::FRAC_PI_2));
        body.twist = BodyTwist::new(0.3, 0.1, 0.2);
        // A wall ahead (world +y) pushes back by 4 mm along world −y.
        body.push(Vec2::new(0.0, -0.004));
        assert!((body.pose.y - 1.996).abs() < 1e-12 && body.pose.x == 1.0);
        assert!(body.twist.vx_m_s.abs() < 1e-12, "{:?}", body.twist);
        assert!((body.twist.vy_m_s - 0.1).abs() < 1e-12);
        assert_eq!(body.twist.omega_rad_s, 0.2);
        // Moving away from the obstacle already: the velocity stays.
        body.twist = BodyTwist::new(-0.3, 0.0, 0.0);
        body.push(Vec2::new(0.0, -0.001));
        assert_eq!(body.twist.vx_m_s, -0.3);
    }

    #[test]
    fn a_steady_turn_follows_a_circle() {
        // 0.3 m/s forward at 1 rad/s: a circle of radius 0.3 m, back home after 2π s.
        let (mecanum, limits) = setup();
        let start = Pose2::new(-0.2, 0.1, 0.3);
        let mut body = Body::at_rest(start);
        let wheels = mecanum.inverse(BodyTwist::new(0.3, 0.0, 1.0));
        body.twist = mecanum.forward(wheels);
        let steps = 10_000;
        for _ in 0..steps {
            let report = body.step(
                wheels,
                &mecanum,
                &limits,
                &Ground::NOMINAL,
                1.0,
                std::f64::consts::TAU / steps as f64,
            );
            assert!(!report.slipped, "0.3 m/s² centripetal is within μg");
        }
        assert!((body.pose.x - start.x).abs() < 1e-9 && (body.pose.y - start.y).abs() < 1e-9);
    }
}
