//! How long our follower takes along a route, and the task planner's travel times from it
//! (issue 14: the order the planner chooses is the fastest in driving time, not in straight
//! metres).
//!
//! A route's time is the minimum-time speed profile along its arc length under the
//! follower's [`Profile`] at every point (top speed, corners, the heading turn's yaw-rate
//! cap, the wheel-speed budget the heading turn shares with the translation, the docking
//! approach, the stop), with the acceleration and deceleration limits between them (a
//! forward and a backward pass). It leaves out what every leg has alike (the follower's
//! final hold on the goal, the lag), so it ranks legs rather than predicting them to the
//! tenth of a second.
use crate::config::{Config, NavigationConfig};
use crate::control::profile::{HeadingPlan, Profile, WheelBudget};
use crate::control::route::{LegPlanner, Route};
use crate::field::Slot;
use crate::planning::tasks::{LOCATION_COUNT, Location, StraightLineTimes, TravelTimes};

/// Arc-length step of the speed profile, m (5 mm: well under the shortest corner blend).
const STEP_M: f64 = 0.005;

/// Lowest speed counted on a step, m/s: the profile's last step ends at rest, where the
/// follower still creeps on (`control::follower`'s creep).
const MIN_SPEED_M_S: f64 = 0.015;

/// The robot's limits a route's time depends on.
#[derive(Clone, Debug)]
pub struct RouteTimer {
    navigation: NavigationConfig,
    wheels: WheelBudget,
}

impl RouteTimer {
    /// A timer for the robot of `config` (`[navigation]` and the wheels of `[robot]`).
    pub fn new(config: &Config) -> Self {
        Self {
            navigation: config.navigation.clone(),
            wheels: WheelBudget::new(&config.robot),
        }
    }

    /// Seconds from rest at the start of `route` to rest at its end.
    pub fn seconds(&self, route: &Route) -> f64 {
        let heading = HeadingPlan::new(route, &self.navigation);
        let profile = Profile::new(route, &heading, &self.navigation, &self.wheels);
        let length = route.length_m();
        let steps = ((length / STEP_M).ceil() as usize).max(1);
        let ds = length / steps as f64;
        let mut speed: Vec<f64> = (0..=steps)
            .map(|k| profile.speed_limit_m_s(k as f64 * ds))
            .collect();
        speed[0] = 0.0;
        speed[steps] = 0.0;
        let accel = self.navigation.max_accel_m_s2;
        for k in 1..=steps {
            speed[k] = speed[k].min((speed[k - 1].powi(2) + 2.0 * accel * ds).sqrt());
        }
        let decel = self.navigation.max_decel_m_s2;
        for k in (0..steps).rev() {
            speed[k] = speed[k].min((speed[k + 1].powi(2) + 2.0 * decel * ds).sqrt());
        }
        speed
            .windows(2)
            .map(|pair| ds / ((pair[0] + pair[1]) / 2.0).max(MIN_SPEED_M_S))
            .sum()
    }
}

/// The task planner's travel times from our routes: for every pair of locations, the route
/// our navigator would plan from the first's pick pose to the second's (carrying a part to a
/// drop, empty to a pick), timed by [`RouteTimer`]. Where no route can be planned (the
/// start as a destination, which no action has), the straight-line estimate at the
/// navigation's top speed and yaw rate stands in.
#[derive(Clone, Debug)]
pub struct RouteTimes {
    seconds: [[f64; LOCATION_COUNT]; LOCATION_COUNT],
    unplanned: Vec<(Location, Location)>,
}

impl RouteTimes {
    /// The times for the robot of `config` on the competition field.
    pub fn new(config: &Config) -> Self {
        Self::with_planner(&LegPlanner::new(config), config)
    }

    /// The times of the routes `legs` plans for the robot of `config` (one planner for
    /// these times and the navigator: [`LegPlanner::new`] builds the free-space grids).
    pub fn with_planner(legs: &LegPlanner, config: &Config) -> Self {
        let field = legs.field().clone();
        let timer = RouteTimer::new(config);
        let fallback = StraightLineTimes::new(
            &field,
            config.navigation.max_speed_m_s,
            config.navigation.max_yaw_rate_rad_s,
        );
        let mut seconds = [[0.0; LOCATION_COUNT]; LOCATION_COUNT];
        let mut unplanned = Vec::new();
        for (i, &from) in Location::ALL.iter().enumerate() {
            let Some(start) = from.robot_pose(&field) else {
                continue;
            };
            // Empty to the picks, carrying a part to the drops: one search each.
            for carrying in [false, true] {
                let to: Vec<(usize, Location)> = Location::ALL
                    .iter()
                    .copied()
                    .enumerate()
                    .filter(|&(j, to)| j != i && to.is_pick() != carrying)
                    .collect();
                let slots: Vec<Slot> = to
                    .iter()
                    .filter_map(|(_, to)| to.slot(&field).copied())
                    .collect();
                let routes = legs.plan_many(start, &slots, carrying);
                let mut routes = routes.into_iter();
                for &(j, to) in &to {
                    let route = to
                        .slot(&field)
                        .and_then(|_| routes.next())
                        .and_then(Result::ok);
                    seconds[i][j] = match route {
                        Some(route) => timer.seconds(&route),
                        None => {
                            unplanned.push((from, to));
                            fallback.travel_s(from, to)
                        }
                    };
                }
            }
        }
        Self { seconds, unplanned }
    }

    /// The pairs timed by the straight-line stand-in because no route was planned.
    pub fn unplanned(&self) -> &[(Location, Location)] {
        &self.unplanned
    }
}

impl TravelTimes for RouteTimes {
    fn travel_s(&self, from: Location, to: Location) -> f64 {
        match (from.index(), to.index()) {
            (Some(i), Some(j)) => self.seconds[i][j],
            _ => f64::INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Field;
    use crate::field::geometry::Vec2;

    fn straight(length_m: f64, turn_rad: f64) -> Route {
        Route::new(
            vec![Vec2::new(0.0, 0.0), Vec2::new(length_m, 0.0)],
            0.0,
            turn_rad,
            0.0,
        )
        .unwrap()
    }

    #[test]
    fn a_straight_leg_takes_its_trapezoid_and_a_turn_on_it_costs_time() {
        let config = Config::default();
        let nav = &config.navigation;
        let timer = RouteTimer::new(&config);
        // 1 m straight on, no turn: the trapezoid under the top speed (the wheels allow more
        // along x), up to the last step's creep floor.
        let v = nav.max_speed_m_s;
        let trapezoid = 1.0 / v + v / (2.0 * nav.max_accel_m_s2) + v / (2.0 * nav.max_decel_m_s2);
        let t = timer.seconds(&straight(1.0, 0.0));
        assert!((t - trapezoid).abs() < 0.02, "{t} s against {trapezoid} s");
        // Turning half a turn on the way shares the wheels' budget: slower.
        let turning = timer.seconds(&straight(1.0, std::f64::consts::PI));
        assert!(turning > t + 0.1, "{turning} s against {t} s");
    }

    #[test]
    fn every_pair_of_slots_has_a_planned_route_and_a_time_above_the_straight_line() {
        let config = Config::default();
        let times = RouteTimes::new(&config);
        assert!(
            times
                .unplanned()
                .iter()
                .all(|(_, to)| *to == Location::Start),
            "{:?}",
            times.unplanned()
        );
        let field = Field::competition();
        let top_speed = StraightLineTimes::new(&field, config.navigation.max_speed_m_s, 1e9);
        let slots = Location::ALL.iter().filter(|l| **l != Location::Start);
        for &from in Location::ALL.iter() {
            for &to in slots.clone() {
                if from == to {
                    continue;
                }
                let t = times.travel_s(from, to);
                // Never below the straight line at the top speed: a route is at least as
                // long and starts and ends at rest.
                assert!(
                    t.is_finite() && t > top_speed.travel_s(from, to),
                    "{from} → {to}: {t} s"
                );
            }
        }
        // Round the machine block costs more than the straight line says: from incoming
        // slot 1 to machine A's lower input (behind the block's upper row).
        let (from, to) = (
            Location::Incoming(0),
            Location::MachineInput(crate::field::MachineKind::A, 1),
        );
        assert!(times.travel_s(from, to) > 1.5 * top_speed.travel_s(from, to));
    }
}
