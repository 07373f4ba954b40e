//! The 5dpo line follower, reproduced as the "original" preset (original-system.md §6.3),
//! with every number of the deployed code.
//!
//! Per tick on the current segment: the foot p⊥ of the perpendicular from the robot onto
//! the segment's line; the segment direction r̂ (flipped when r̂·(unit robot→end) < −0.9);
//! per-axis PI cross-track terms u = PI(p⊥ − p) in the map frame; the command direction
//! 0.8·k_speed·r̂ + u scaled to exactly k_speed = 0.4 m/s; rotated into the robot frame; the
//! heading PI on wrap(θ_ref − θ) only once the robot is 0.15 m from where the route started.
//! Segments switch within 0.04 m of their end. On the last segment within 0.2 m of its end:
//! if more than 0.2 rad off, the linear speed is zero (turn in place), otherwise it is
//! divided by 2.512. The PIs are never reset, and ω keeps its last value while rotation is
//! not allowed, as in the original.
//!
//! Deviation (stated): after the last segment the original kept publishing its last
//! velocity until the switch closed at a pick; here it stops (zero twist) and reports
//! `Arrived`, so a trip's end is defined the same way for both presets.

use crate::control::follower::{FollowerCommand, PathFollower, Status, to_body};
use crate::control::route::Route;
use crate::field::geometry::{Pose2, Vec2, wrap_angle};
use crate::kinematics::BodyTwist;

/// The original's constants (original-system.md §6.3, `pid.yaml` and `path_planning.cpp`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OriginalParams {
    /// `k_speed`, m/s: 0.4.
    pub speed_m_s: f64,
    /// `k_correction` (PI_x, PI_y kp): 4.
    pub correction_kp: f64,
    /// `kd_v` (used as the PI_x, PI_y ki): 0.4.
    pub correction_ki: f64,
    /// PI_x, PI_y saturation, m/s: k_speed = 0.4.
    pub correction_saturation_m_s: f64,
    /// `k_w` (PI_θ kp): 4.
    pub heading_kp: f64,
    /// `kd_w` (used as the PI_θ ki): 0.202347.
    pub heading_ki: f64,
    /// PI_θ saturation, rad/s: 0.8 (hard-coded).
    pub heading_saturation_rad_s: f64,
    /// `dist_tresh`, m: 0.04.
    pub switch_distance_m: f64,
    /// `slow_zone`, m: 0.2.
    pub slow_zone_m: f64,
    /// `speed_divisor`: 2.512.
    pub slow_divisor: f64,
    /// Heading error above which the robot turns in place in the slow zone, rad: 0.2.
    pub turn_in_place_rad: f64,
    /// `rotate_dist`, m: 0.15.
    pub rotate_distance_m: f64,
    /// Overshoot test: r̂·(unit robot→end) below this flips r̂: −0.9.
    pub flip_dot: f64,
    /// Weight of r̂ in the command direction: 0.8 (× k_speed).
    pub along_weight: f64,
}

impl Default for OriginalParams {
    fn default() -> Self {
        Self {
            speed_m_s: 0.4,
            correction_kp: 4.0,
            correction_ki: 0.4,
            correction_saturation_m_s: 0.4,
            heading_kp: 4.0,
            heading_ki: 0.202347,
            heading_saturation_rad_s: 0.8,
            switch_distance_m: 0.04,
            slow_zone_m: 0.2,
            slow_divisor: 2.512,
            turn_in_place_rad: 0.2,
            rotate_distance_m: 0.15,
            flip_dot: -0.9,
            along_weight: 0.8,
        }
    }
}

/// The original's PI block (`Pid.cpp` with kd = 0): u = kp·e + ki·∫e dt, dt from the clock;
/// the first call returns kp·e; on saturation the last integration step is undone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OriginalPi {
    kp: f64,
    ki: f64,
    saturation: f64,
    integral: f64,
    last_us: Option<u64>,
}

impl OriginalPi {
    /// A PI with gains `kp`, `ki` and output limit ±`saturation`.
    pub fn new(kp: f64, ki: f64, saturation: f64) -> Self {
        Self {
            kp,
            ki,
            saturation,
            integral: 0.0,
            last_us: None,
        }
    }

    /// The time since the last step passed with the loop stopped: the next step integrates
    /// nothing over it.
    pub fn pause(&mut self) {
        self.last_us = None;
    }

    /// One step with error `error` at `now_us`.
    pub fn update(&mut self, error: f64, now_us: u64) -> f64 {
        let Some(last) = self.last_us.replace(now_us) else {
            return (self.kp * error).clamp(-self.saturation, self.saturation);
        };
        let dt_s = now_us.saturating_sub(last) as f64 * 1e-6;
        let step = error * dt_s;
        self.integral += step;
        let u = self.kp * error + self.ki * self.integral;
        if u.abs() > self.saturation {
            self.integral -= step;
            u.clamp(-self.saturation, self.saturation)
        } else {
            u
        }
    }
}

/// The original follower.
#[derive(Clone, Debug)]
pub struct OriginalFollower {
    params: OriginalParams,
    route: Option<Route>,
    segment: usize,
    theta_ref_rad: f64,
    can_rotate: bool,
    last_location: Vec2,
    following: bool,
    pi_x: OriginalPi,
    pi_y: OriginalPi,
    pi_theta: OriginalPi,
    omega_rad_s: f64,
    start_location: Option<Vec2>,
}

impl OriginalFollower {
    /// Gate rotation on the distance from `location` instead of the route's first point:
    /// the original's `last_loc` is the task vertex it just left (original-system.md §6.3),
    /// which need not be the first point of the new route.
    pub fn with_start_location(mut self, location: Option<Vec2>) -> Self {
        self.start_location = location;
        self
    }

    /// A follower with the original's numbers.
    pub fn new(params: OriginalParams) -> Self {
        Self {
            params,
            route: None,
            segment: 0,
            theta_ref_rad: 0.0,
            can_rotate: false,
            last_location: Vec2::ZERO,
            following: false,
            pi_x: OriginalPi::new(
                params.correction_kp,
                params.correction_ki,
                params.correction_saturation_m_s,
            ),
            pi_y: OriginalPi::new(
                params.correction_kp,
                params.correction_ki,
                params.correction_saturation_m_s,
            ),
            pi_theta: OriginalPi::new(
                params.heading_kp,
                params.heading_ki,
                params.heading_saturation_rad_s,
            ),
            omega_rad_s: 0.0,
            start_location: None,
        }
    }
}

impl PathFollower for OriginalFollower {
    /// θ_ref is the heading of the route's last segment; rotation is gated until the robot
    /// is 0.15 m from its first point (`last_loc`, the vertex just left).
    fn start(&mut self, route: Route) {
        let n = route.points().len();
        self.theta_ref_rad = (route.points()[n - 1] - route.points()[n - 2]).angle();
        self.last_location = self.start_location.unwrap_or(route.points()[0]);
        self.route = Some(route);
        self.segment = 0;
        self.can_rotate = false;
        self.following = true;
    }

    fn halted(&mut self) {
        self.pi_x.pause();
        self.pi_y.pause();
        self.pi_theta.pause();
    }

    fn update(&mut self, now_us: u64, pose: Pose2, _switch_pressed: bool) -> FollowerCommand {
        let p = self.params;
        let stopped = |status| FollowerCommand {
            twist: BodyTwist::default(),
            status,
            cross_track_m: 0.0,
        };
        let Some(route) = &self.route else {
            return stopped(Status::Idle);
        };
        if !self.following {
            return stopped(Status::Arrived);
        }
        let position = pose.position();
        let points = route.points();
        let end = points[self.segment + 1];
        if position.distance(end) < p.switch_distance_m {
            self.segment += 1;
            if self.segment + 1 >= points.len() {
                self.following = false;
                return stopped(Status::Arrived);
            }
        }
        let (start, end) = (points[self.segment], points[self.segment + 1]);
        let mut r = (end - start) * (1.0 / (end - start).norm());
        let to_end = end - position;
        if to_end.norm() > 0.0 && r.dot(to_end * (1.0 / to_end.norm())) < p.flip_dot {
            r = -r;
        }
        let foot = start + r * (position - start).dot(r);
        let u = Vec2::new(
            self.pi_x.update(foot.x - position.x, now_us),
            self.pi_y.update(foot.y - position.y, now_us),
        );
        let d = r * (p.along_weight * p.speed_m_s) + u;
        let world = if d.norm() > 0.0 {
            d * (p.speed_m_s / d.norm())
        } else {
            Vec2::ZERO
        };
        let mut body = to_body(world, pose.yaw_rad);
        if !self.can_rotate && position.distance(self.last_location) > p.rotate_distance_m {
            self.can_rotate = true;
        }
        let heading_error = wrap_angle(self.theta_ref_rad - pose.yaw_rad);
        if self.can_rotate {
            self.omega_rad_s = self.pi_theta.update(heading_error, now_us);
        }
        let last_segment = self.segment + 2 == points.len();
        if last_segment && position.distance(end) < p.slow_zone_m {
            if heading_error.abs() > p.turn_in_place_rad {
                body = Vec2::ZERO;
            } else {
                body = body * (1.0 / p.slow_divisor);
            }
        }
        FollowerCommand {
            twist: BodyTwist::new(body.x, body.y, self.omega_rad_s),
            status: Status::Following,
            cross_track_m: position.distance(foot),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pi_saturates_and_undoes_the_step() {
        let mut pi = OriginalPi::new(4.0, 0.4, 0.4);
        assert_eq!(pi.update(0.05, 0), 0.2);
        let u = pi.update(0.05, 20_000);
        assert!((u - (0.2 + 0.4 * 0.05 * 0.02)).abs() < 1e-12);
        assert_eq!(pi.update(1.0, 40_000), 0.4);
        let u = pi.update(0.0, 60_000);
        assert!(
            (u - 0.4 * 0.05 * 0.02).abs() < 1e-12,
            "the saturated step was undone"
        );
    }

    #[test]
    fn constant_speed_slow_zone_and_turn_in_place() {
        let mut f = OriginalFollower::new(OriginalParams::default());
        let route = Route::new(
            vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0)],
            0.0,
            0.0,
            0.0,
        )
        .unwrap();
        f.start(route);
        let out = f.update(0, Pose2::new(0.3, 0.0, 0.0), false);
        assert!((out.twist.vx_m_s - 0.4).abs() < 1e-12 && out.twist.omega_rad_s == 0.0);
        let out = f.update(20_000, Pose2::new(0.9, 0.0, 0.0), false);
        assert!((out.twist.vx_m_s - 0.4 / 2.512).abs() < 1e-9, "{out:?}");
        let out = f.update(40_000, Pose2::new(0.9, 0.0, 0.5), false);
        assert_eq!((out.twist.vx_m_s, out.twist.vy_m_s), (0.0, 0.0));
        assert!(out.twist.omega_rad_s < 0.0, "turns back towards θ_ref");
        let out = f.update(60_000, Pose2::new(0.97, 0.0, 0.0), false);
        assert_eq!(out.status, Status::Arrived);
    }
}
