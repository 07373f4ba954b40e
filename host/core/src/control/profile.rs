//! Speed and heading profiles along a route: trapezoidal in the path length remaining, with
//! slow-downs before corners (by turn angle, and the planner's cap where an overshoot would
//! touch an obstacle, `control::route`), in the docking approach to a part (not on the
//! way into a drop: [`Route::docks_on_switch`]) and where the heading must turn faster than
//! the yaw-rate limit allows at full speed, and wherever the wheels cannot give the top
//! speed with the heading's turn on top ([`WheelBudget`]).

use std::f64::consts::PI;

use crate::config::{NavigationConfig, RobotConfig};
use crate::control::route::Route;
use crate::field::geometry::wrap_angle;
use crate::kinematics::{BodyTwist, Mecanum};

/// Lowest cap of a turn window, m/s: enough to reach a window of zero length.
pub const MIN_TURN_SPEED_M_S: f64 = 0.03;

/// A stretch of the route with a speed cap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedZone {
    /// Arc length where the cap starts, m.
    pub from_m: f64,
    /// Arc length where it ends, m.
    pub to_m: f64,
    /// The cap, m/s.
    pub max_m_s: f64,
}

impl SpeedZone {
    /// The highest speed at arc length `s_m` from which a robot braking at `decel_m_s2`
    /// keeps this cap: the cap inside the zone, the braking curve before it, infinite
    /// beyond it.
    pub fn limit_at(&self, s_m: f64, decel_m_s2: f64) -> f64 {
        if s_m > self.to_m {
            f64::INFINITY
        } else if s_m >= self.from_m {
            self.max_m_s
        } else {
            (self.max_m_s * self.max_m_s + 2.0 * decel_m_s2 * (self.from_m - s_m)).sqrt()
        }
    }
}

/// The heading reference along the route: the start heading held for the first
/// `rotate_after_m`, then turned at a constant rate per metre so that the goal heading is
/// reached `align_before_m` before the end (the base rotates while it travels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingPlan {
    /// Arc length where the turn starts, m.
    pub from_m: f64,
    /// Arc length where it ends, m.
    pub to_m: f64,
    /// Heading before the turn, rad.
    pub start_yaw_rad: f64,
    /// Signed turn, rad, in (−π, π].
    pub turn_rad: f64,
}

impl HeadingPlan {
    /// The plan for `route`: its turn window if the planner gave one, otherwise between
    /// `rotate_after_m` from the start and `align_before_m` from the end (on a route too
    /// short for both, its middle third).
    pub fn new(route: &Route, config: &NavigationConfig) -> Self {
        let length = route.length_m();
        let (from_m, to_m) = route.turn_window_m().unwrap_or_else(|| {
            if length > config.rotate_after_m + config.align_before_m {
                (config.rotate_after_m, length - config.align_before_m)
            } else {
                (length / 3.0, 2.0 * length / 3.0)
            }
        });
        Self {
            from_m,
            to_m,
            start_yaw_rad: route.start_yaw_rad(),
            turn_rad: wrap_angle(route.goal().yaw_rad - route.start_yaw_rad()),
        }
    }

    /// Heading reference at arc length `s_m`, rad.
    pub fn yaw_at(&self, s_m: f64) -> f64 {
        let span = (self.to_m - self.from_m).max(1e-9);
        let f = ((s_m - self.from_m) / span).clamp(0.0, 1.0);
        wrap_angle(self.start_yaw_rad + self.turn_rad * f)
    }

    /// d(heading)/ds at `s_m`, rad/m (0 outside the turn).
    pub fn rate_rad_per_m(&self, s_m: f64) -> f64 {
        if s_m < self.from_m || s_m > self.to_m || self.to_m - self.from_m < 1e-9 {
            0.0
        } else {
            self.turn_rad / (self.to_m - self.from_m)
        }
    }
}

/// Length of the stretches over which the wheel budget's cap is taken as constant, m.
const WHEEL_ZONE_M: f64 = 0.01;

/// The wheels' speed limit, which the heading's turn shares with the translation: on a
/// mecanum base every wheel's rim speed is |vx| ± |vy| ± k·ω, so a body moving diagonally
/// in its own frame, or turning as it goes, has less along-track speed left than one
/// driving straight ahead.
#[derive(Clone, Debug)]
pub struct WheelBudget {
    mecanum: Mecanum,
    max_wheel_speed_rad_s: f64,
}

impl WheelBudget {
    /// The wheels of `robot` (`max_wheel_speed_rad_s` and the kinematics).
    pub fn new(robot: &RobotConfig) -> Self {
        Self {
            mecanum: Mecanum::new(robot),
            max_wheel_speed_rad_s: robot.max_wheel_speed_rad_s,
        }
    }

    /// The highest along-track speed at arc length `s_m` of `route` at which no wheel
    /// exceeds its limit, m/s: the route's direction in the planned heading's frame, with
    /// the heading's turn per metre (infinite where nothing moves).
    pub fn speed_limit_m_s(&self, route: &Route, heading: &HeadingPlan, s_m: f64) -> f64 {
        let direction = route.tangent_at_m(s_m).rotated(-heading.yaw_at(s_m));
        let per_unit_speed = self.mecanum.inverse(BodyTwist::new(
            direction.x,
            direction.y,
            heading.rate_rad_per_m(s_m),
        ));
        let peak = per_unit_speed.iter().fold(0.0f64, |m, w| m.max(w.abs()));
        if peak > 0.0 {
            self.max_wheel_speed_rad_s / peak
        } else {
            f64::INFINITY
        }
    }
}

/// Speed caps along one route.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    zones: Vec<SpeedZone>,
    /// The cap on the corner into a slot a carried part enters right after it
    /// ([`SLOT_CORNER_M_S`]), also among `zones`.
    slot_corner: Option<SpeedZone>,
    max_speed_m_s: f64,
    decel_m_s2: f64,
}

/// Speed at which a corner of `turn_rad` can be taken: the velocity changes by
/// 2·v·sin(φ/2) over about `blend_m` of path (taking `blend_m / v` s), which must stay
/// within `accel_m_s2`: v = √(a·ℓ / (2·sin(φ/2))).
pub fn corner_speed_m_s(turn_rad: f64, accel_m_s2: f64, blend_m: f64) -> f64 {
    let change = 2.0 * (turn_rad.abs().min(PI) / 2.0).sin();
    if change < 1e-9 {
        f64::INFINITY
    } else {
        (accel_m_s2 * blend_m / change).sqrt()
    }
}

/// Speed cap at the corner into a slot where a carried part goes in right after it, m/s.
/// The follower runs on past a corner by about its speed × 50 ms
/// ([`crate::control::route::CORNER_OVERSHOOT_S`]); along the outgoing row under machine B
/// the carried part's far face passes 17 mm above the outgoing dividers' tips, so it meets
/// them 2 cm after the corner into its slot, with the overshoot not yet taken back. At the
/// 90° corner's 0.27 m/s ([`corner_speed_m_s`]) the robot ran 7–10 mm past the line
/// (truth; realistic world, calibrated, round 2 of seeds 53 and 83) and the part touched a
/// divider. Chosen with the reach of the cap (`SLOT_CORNER_NEAR_M`) on the tuning seeds
/// 61–160 (README: worlds). The follower places itself by the estimate moved on by its last command over
/// the loop's lag, ahead of the truth, so it reaches this stretch in its own reckoning
/// while the robot is still short of it and faster than the cap (seed 58, round 1: 0.2 m/s
/// at the corner, 10 mm past the line).
pub const SLOT_CORNER_M_S: f64 = 0.08;
/// Length of the stretch before that corner held at [`SLOT_CORNER_M_S`], m. Braking at
/// 2 m/s², the wheels trail the command by about a·τ ≈ 0.2 m/s (the motors' 0.1 s time
/// constant) and come down to the cap some a·τ² + cap·τ ≈ 3 cm after the command does: a
/// 3 cm stretch was measured at `d89c760` (realistic world, calibrated): in seed 58's round
/// 1 the carried part touches a divider of outgoing slot 3 with 1 cm and not with 3 cm, but
/// the tuning seeds 61–110 took 35.4 / 37.9 / 48.8 → 35.8 / 38.5 / 49.4 s per round (0
/// collisions either way): not kept.
const SLOT_CORNER_ZONE_M: f64 = 0.01;
/// That corner is capped when the route's goal lies within this much of it, m: an outgoing
/// slot entered from the row under machine B (8 cm); a slot approached down a long free
/// stretch (an outgoing slot from above, the machines' inputs) leaves the robot the stretch
/// to come onto the line first.
const SLOT_CORNER_NEAR_M: f64 = 0.12;
/// Least turn at that corner for the cap, rad (40°): a corner that turns less is a bend
/// of the approach, not the turn into the slot.
const SLOT_CORNER_MIN_TURN_RAD: f64 = 0.7;

/// The cap on the corner where a route that carries a part into a slot turns into it, if
/// the part goes between the dividers right after it ([`SLOT_CORNER_M_S`]): the last corner
/// within [`SLOT_CORNER_NEAR_M`] of the goal that turns by more than
/// [`SLOT_CORNER_MIN_TURN_RAD`] (a drop aimed off the slot's line, `competition`, leaves a
/// bend of a few millimetres after it).
fn slot_corner_zone(route: &Route) -> Option<SpeedZone> {
    if !route.carries_part_in() {
        return None;
    }
    let length = route.length_m();
    let corner = (1..route.points().len().saturating_sub(1))
        .rev()
        .take_while(|&i| length - route.s_at_point_m(i) < SLOT_CORNER_NEAR_M)
        .find(|&i| route.turn_angle_rad(i).abs() > SLOT_CORNER_MIN_TURN_RAD)?;
    let corner_m = route.s_at_point_m(corner);
    Some(SpeedZone {
        from_m: corner_m - SLOT_CORNER_ZONE_M,
        to_m: corner_m,
        max_m_s: SLOT_CORNER_M_S,
    })
}

impl Profile {
    /// The caps for `route`: corners, the heading turn, the wheels' budget, the docking
    /// approach, the stop. The wheels' cap is their whole limit: the follower scales its
    /// feedback beyond it down with the twist (planning to 0.9 of it was 1–3 % slower per
    /// round on the realistic world's seeds 61–80, calibrated), and without it the robot
    /// reached a turn window at full speed and lost it to the turn all at once.
    pub fn new(
        route: &Route,
        heading: &HeadingPlan,
        config: &NavigationConfig,
        wheels: &WheelBudget,
    ) -> Self {
        let mut zones = Vec::new();
        let n = route.points().len();
        for i in 1..n.saturating_sub(1) {
            let s = route.s_at_point_m(i);
            let v = corner_speed_m_s(
                route.turn_angle_rad(i),
                config.max_accel_m_s2.min(config.max_decel_m_s2),
                config.corner_blend_m,
            )
            .min(route.corner_cap_m_s(i));
            zones.push(SpeedZone {
                from_m: s - config.corner_blend_m / 2.0,
                to_m: s + config.corner_blend_m / 2.0,
                max_m_s: v,
            });
        }
        let slot_corner = slot_corner_zone(route);
        zones.extend(slot_corner);
        if heading.turn_rad.abs() > 1e-9 {
            // Keep a fifth of the yaw-rate limit for the heading feedback. A (nearly) zero
            // window still lets the robot creep onto it; the follower then waits for the
            // heading (it slows down with the heading error).
            let v = (0.8 * config.max_yaw_rate_rad_s * (heading.to_m - heading.from_m)
                / heading.turn_rad.abs())
            .max(MIN_TURN_SPEED_M_S);
            zones.push(SpeedZone {
                from_m: heading.from_m,
                to_m: heading.to_m,
                max_m_s: v,
            });
        }
        let length = route.length_m();
        let stretches = (length / WHEEL_ZONE_M).ceil() as usize;
        // The wheels' limit at each stretch's ends, each boundary computed once.
        let boundary_m = |k: usize| (k as f64 * WHEEL_ZONE_M).min(length);
        let at_boundary: Vec<f64> = (0..=stretches)
            .map(|k| wheels.speed_limit_m_s(route, heading, boundary_m(k)))
            .collect();
        for k in 0..stretches {
            let (from_m, to_m) = (boundary_m(k), boundary_m(k + 1));
            // Never below the turn window's own floor: a window of a few millimetres asks
            // for a turn no speed can share the wheels with, and the robot crawled up to it
            // at millimetres a second (a 1.4 mm window for a quarter turn: 4 mm/s for 5 s);
            // the follower waits for the heading instead (it slows while the heading lags).
            let cap = at_boundary[k]
                .min(at_boundary[k + 1])
                .max(MIN_TURN_SPEED_M_S);
            if cap < config.max_speed_m_s {
                zones.push(SpeedZone {
                    from_m,
                    to_m,
                    max_m_s: cap,
                });
            }
        }
        if route.docks_on_switch() {
            zones.push(SpeedZone {
                from_m: length - route.dock_length_m(),
                to_m: length,
                max_m_s: config.dock_speed_m_s,
            });
        }
        zones.push(SpeedZone {
            from_m: length,
            to_m: f64::INFINITY,
            max_m_s: 0.0,
        });
        Self {
            zones,
            slot_corner,
            max_speed_m_s: config.max_speed_m_s,
            decel_m_s2: config.max_decel_m_s2,
        }
    }

    /// The cap on the corner into a slot a carried part enters right after it, if the
    /// route has one ([`SLOT_CORNER_M_S`]).
    pub fn slot_corner(&self) -> Option<SpeedZone> {
        self.slot_corner
    }

    /// The highest speed at arc length `s_m` from which the robot brakes to `zone`'s cap
    /// at the deceleration limit (its cap inside it, infinite beyond it).
    pub fn zone_limit_m_s(&self, zone: &SpeedZone, s_m: f64) -> f64 {
        zone.limit_at(s_m, self.decel_m_s2)
    }

    /// The zones (for inspection).
    pub fn zones(&self) -> &[SpeedZone] {
        &self.zones
    }

    /// The highest speed allowed at arc length `s_m`: the top speed, every cap in force, and
    /// every cap ahead reachable at the deceleration limit.
    pub fn speed_limit_m_s(&self, s_m: f64) -> f64 {
        self.zones
            .iter()
            .map(|z| z.limit_at(s_m, self.decel_m_s2))
            .fold(self.max_speed_m_s, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::geometry::Vec2;
    use std::f64::consts::FRAC_PI_2;

    fn wheels() -> WheelBudget {
        WheelBudget::new(&RobotConfig::default())
    }

    #[test]
    fn a_turn_window_of_millimetres_leaves_the_robot_its_turn_windows_floor() {
        // A quarter turn planned over 1.4 mm (a free-space route's window at a tight spot):
        // the wheels cannot share it with any speed, and the robot crawled up to it at
        // 4 mm/s; the floor keeps MIN_TURN_SPEED_M_S, the follower waiting for the heading.
        let config = NavigationConfig::default();
        let route = Route::new(
            vec![Vec2::new(0.0, 0.0), Vec2::new(0.5, 0.0)],
            0.0,
            FRAC_PI_2,
            0.0,
        )
        .unwrap()
        .with_turn_window(0.2, 0.2014);
        let heading = HeadingPlan::new(&route, &config);
        let profile = Profile::new(&route, &heading, &config, &wheels());
        let inside = profile.speed_limit_m_s(0.2007);
        assert!((inside - MIN_TURN_SPEED_M_S).abs() < 1e-12, "{inside}");
        // The wheels alone would allow about 4 mm/s there.
        assert!(wheels().speed_limit_m_s(&route, &heading, 0.2007) < 0.005);
    }

    #[test]
    fn trapezoid_corner_and_dock() {
        let config = NavigationConfig {
            max_accel_m_s2: 1.5,
            max_decel_m_s2: 1.5,
            corner_blend_m: 0.05,
            dock_length_m: 0.08,
            ..NavigationConfig::default()
        };
        let p = |x: f64, y: f64| Vec2::new(x, y);
        let route = Route::new(
            vec![p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)],
            0.0,
            0.0,
            config.dock_length_m,
        )
        .unwrap();
        let heading = HeadingPlan::new(&route, &config);
        let profile = Profile::new(&route, &heading, &config, &wheels());
        assert_eq!(profile.speed_limit_m_s(0.3), config.max_speed_m_s);
        let corner = corner_speed_m_s(FRAC_PI_2, 1.5, 0.05);
        assert!((corner - 0.2303).abs() < 1e-3, "{corner}");
        assert!((profile.speed_limit_m_s(1.0) - corner).abs() < 1e-12);
        // Before the corner zone the cap rises as √(v² + 2·a·d).
        let before = profile.speed_limit_m_s(0.9);
        let want = (corner * corner + 2.0 * 1.5 * 0.075).sqrt();
        assert!((before - want).abs() < 1e-12);
        assert_eq!(profile.speed_limit_m_s(1.95), config.dock_speed_m_s);
        assert_eq!(profile.speed_limit_m_s(2.0), 0.0);
        assert_eq!(profile.speed_limit_m_s(2.5), 0.0);
        // Straight on: no corner cap.
        assert_eq!(corner_speed_m_s(0.0, 1.5, 0.05), f64::INFINITY);
    }

    #[test]
    fn only_the_approach_to_a_part_is_capped_at_the_docking_speed() {
        let config = NavigationConfig::default();
        let route = Route::new(
            vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0)],
            0.0,
            0.0,
            config.dock_length_m,
        )
        .unwrap();
        let inside_dock = 1.0 - config.dock_length_m / 2.0;
        let cap_at = |route: &Route| {
            let heading = HeadingPlan::new(route, &config);
            Profile::new(route, &heading, &config, &wheels()).speed_limit_m_s(inside_dock)
        };
        assert_eq!(cap_at(&route), config.dock_speed_m_s);
        // Carrying a part in, only the braking curve onto the goal limits the speed.
        let braking = (2.0 * config.max_decel_m_s2 * config.dock_length_m / 2.0).sqrt();
        assert!(braking > config.dock_speed_m_s);
        assert!((cap_at(&route.carrying_part_in()) - braking).abs() < 1e-12);
    }

    #[test]
    fn a_carried_part_turns_slowly_into_a_slot_it_enters_right_after_the_corner() {
        // Along a row, then 8 cm down into a slot, with the few-millimetre bend of a drop
        // aimed off the slot's line 3 cm before the goal.
        let row_then_slot = |down_m: f64| {
            Route::new(
                vec![
                    Vec2::new(0.0, 0.0),
                    Vec2::new(0.5, 0.0),
                    Vec2::new(0.502, -(down_m - 0.03)),
                    Vec2::new(0.502, -down_m),
                ],
                -FRAC_PI_2,
                -FRAC_PI_2,
                0.0,
            )
            .unwrap()
        };
        let just_before_the_corner = 0.5 - SLOT_CORNER_ZONE_M / 2.0;
        let cap_at = |route: &Route| {
            Profile::new(
                route,
                &HeadingPlan::new(route, &NavigationConfig::default()),
                &NavigationConfig::default(),
                &wheels(),
            )
            .speed_limit_m_s(just_before_the_corner)
        };
        let near = row_then_slot(0.08);
        assert_eq!(cap_at(&near.clone().carrying_part_in()), SLOT_CORNER_M_S);
        // Empty-handed, or with room after the corner to come onto the line, the corner's
        // own cap.
        assert!(cap_at(&near) > 2.0 * SLOT_CORNER_M_S);
        let far = row_then_slot(SLOT_CORNER_NEAR_M + 0.01).carrying_part_in();
        assert!(cap_at(&far) > 2.0 * SLOT_CORNER_M_S);
    }

    #[test]
    fn a_turn_along_the_route_caps_the_speed_to_what_the_wheels_have_left() {
        let config = NavigationConfig::default();
        let robot = RobotConfig::default();
        let route = Route::new(vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0)], 0.0, PI, 0.0)
            .unwrap()
            .with_turn_window(0.1, 0.9);
        let heading = HeadingPlan::new(&route, &config);
        let profile = Profile::new(&route, &heading, &config, &wheels());
        // Rim speed per unit along-track speed: |vx| + |vy| in the turning body's frame,
        // plus k times the turn per metre.
        let rim_m_s = robot.max_wheel_speed_rad_s * robot.wheel_radius_m();
        let k = robot.half_wheelbase_sum_m();
        let per_m = PI / 0.8;
        // Just inside the window the body nearly faces along the route (each centimetre
        // is capped as at its worse end: here 1 cm in, turned by 0.04 rad).
        let turned = 0.01 * per_m;
        let ahead = rim_m_s / (turned.cos() + turned.sin() + k * per_m);
        assert!((profile.speed_limit_m_s(0.105) - ahead).abs() < 1e-9);
        // A quarter of the way round it moves diagonally in its own frame: less is left.
        let diagonal = rim_m_s / (2f64.sqrt() + k * per_m);
        assert!((profile.speed_limit_m_s(0.305) - diagonal).abs() < 1e-9);
        // Before the window, only the top speed and the braking onto the cap ahead.
        assert_eq!(profile.speed_limit_m_s(0.0), config.max_speed_m_s);
    }

    #[test]
    fn heading_turns_between_the_margins() {
        let config = NavigationConfig {
            rotate_after_m: 0.1,
            align_before_m: 0.1,
            ..NavigationConfig::default()
        };
        let route = Route::new(
            vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0)],
            0.0,
            FRAC_PI_2,
            0.0,
        )
        .unwrap();
        let h = HeadingPlan::new(&route, &config);
        assert_eq!(h.yaw_at(0.05), 0.0);
        assert!((h.yaw_at(0.95) - FRAC_PI_2).abs() < 1e-12);
        assert!((h.yaw_at(0.5) - FRAC_PI_2 / 2.0).abs() < 1e-12);
        assert!(h.rate_rad_per_m(0.5) > 0.0 && h.rate_rad_per_m(0.05) == 0.0);
    }
}
