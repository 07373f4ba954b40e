//! Where a round's time goes: every host tick's 20 ms attributed to what the robot was doing,
//! so the gap to the lower bound ([`ratf_core::planning::bound`]) can be read by cause.
//!
//! The classes, from the mission's [`Activity`] and the twist the core commanded:
//!
//! | class | when |
//! |---|---|
//! | driving | going to a slot with the heading held (`|ω| ≤` [`TURNING_RAD_S`]) |
//! | turning | going to a slot while the heading turns (`|ω| >` [`TURNING_RAD_S`]), on the spot or moving on |
//! | docking | going to a slot within `dock_length_m + dock_creep_m` of its pick or drop pose, and reversing out of a slot |
//! | settling | the magnet's grip or release dwell |
//! | waiting | asking the planner or waiting for a machine |

use ratf_core::config::Config;
use ratf_core::field::Field;
use ratf_core::field::waypoints::WaypointId;
use ratf_core::kinematics::Mecanum;
use ratf_core::mission::Activity;
use ratf_core::runtime::{Input, StepView, Tap};
use serde::Serialize;

/// Seconds per class (module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct TimeSplit {
    /// Going to a slot with the heading held, s.
    pub driving_s: f64,
    /// Going to a slot while the heading turns, s (a half turn per carry with one magnet:
    /// the bound charges each `k·π` of the fastest wheel's travel, `planning::bound`).
    pub turning_s: f64,
    /// The last stretch into a slot and the reverse out of it, s.
    pub docking_s: f64,
    /// Grip and release dwells, s.
    pub settling_s: f64,
    /// Planning or waiting for a machine, s.
    pub waiting_s: f64,
}

impl TimeSplit {
    /// The sum of the classes, s.
    pub fn total_s(&self) -> f64 {
        self.driving_s + self.turning_s + self.docking_s + self.settling_s + self.waiting_s
    }

    /// Every class times `factor` (a sum into a mean).
    pub fn scaled(self, factor: f64) -> Self {
        Self {
            driving_s: self.driving_s * factor,
            turning_s: self.turning_s * factor,
            docking_s: self.docking_s * factor,
            settling_s: self.settling_s * factor,
            waiting_s: self.waiting_s * factor,
        }
    }

    fn slot_mut(&mut self, class: Class) -> &mut f64 {
        match class {
            Class::Driving => &mut self.driving_s,
            Class::Turning => &mut self.turning_s,
            Class::Docking => &mut self.docking_s,
            Class::Settling => &mut self.settling_s,
            Class::Waiting => &mut self.waiting_s,
        }
    }
}

impl std::ops::AddAssign for TimeSplit {
    fn add_assign(&mut self, other: Self) {
        self.driving_s += other.driving_s;
        self.turning_s += other.turning_s;
        self.docking_s += other.docking_s;
        self.settling_s += other.settling_s;
        self.waiting_s += other.waiting_s;
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Class {
    Driving,
    Turning,
    Docking,
    Settling,
    Waiting,
}

/// Commanded yaw rate above which a tick counts as turning, rad/s. 0.3: the heading
/// feedback (`navigation.heading_gain_per_s`, 6/s) holding a heading within 3° asks for
/// less; a half turn spread over a 0.6 m turn window at 0.3 m/s asks for 1.6 rad/s.
pub const TURNING_RAD_S: f64 = 0.3;

/// A tap noting each host tick's class; [`TimeSplitTap::split`] sums them over a span.
#[derive(Debug)]
pub struct TimeSplitTap {
    kinematics: Mecanum,
    dock_zone_m: f64,
    field: Field,
    ticks: Vec<(u64, Class)>,
}

impl TimeSplitTap {
    /// A tap for the robot `config` describes.
    pub fn new(config: &Config) -> Self {
        Self {
            kinematics: Mecanum::new(&config.robot),
            dock_zone_m: config.navigation.dock_length_m + config.navigation.dock_creep_m,
            field: Field::competition(),
            ticks: Vec::new(),
        }
    }

    /// The classes' seconds between `from_us` and `to_us` (each tick counts until the next).
    pub fn split(&self, from_us: u64, to_us: u64) -> TimeSplit {
        let mut split = TimeSplit::default();
        let ends = self.ticks.iter().skip(1).map(|(t, _)| *t).chain([to_us]);
        for (&(start, class), end) in self.ticks.iter().zip(ends) {
            let (start, end) = (start.max(from_us), end.min(to_us));
            if end > start {
                *split.slot_mut(class) += (end - start) as f64 * 1e-6;
            }
        }
        split
    }

    fn near_goal(&self, slot: WaypointId, step: &StepView<'_>) -> bool {
        self.field.slot_for_waypoint(slot).is_some_and(|s| {
            s.pick_pose.position().distance(step.core.pose().position()) <= self.dock_zone_m
        })
    }
}

impl Tap for TimeSplitTap {
    fn on_step(&mut self, step: &StepView<'_>) {
        let (Input::HostTick, Some(wheels)) = (&step.input.input, step.outputs.wheels) else {
            return;
        };
        let Some(activity) = step.core.brain().activity() else {
            return;
        };
        let class = match activity {
            Activity::Planning | Activity::AwaitingServer | Activity::Finished => Class::Waiting,
            Activity::Gripping | Activity::ConfirmingDrop | Activity::Releasing => Class::Settling,
            Activity::BackingOut | Activity::Regripping => Class::Docking,
            Activity::ToPick { slot } | Activity::ToDrop { slot } => {
                if self.near_goal(slot, step) {
                    Class::Docking
                } else {
                    let twist = self
                        .kinematics
                        .forward(wheels.wheel_speeds_rad_s.map(f64::from));
                    if twist.omega_rad_s.abs() > TURNING_RAD_S {
                        Class::Turning
                    } else {
                        Class::Driving
                    }
                }
            }
        };
        self.ticks.push((step.input.time.as_us(), class));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_span_sums_each_tick_until_the_next() {
        let mut tap = TimeSplitTap::new(&Config::default());
        tap.ticks = vec![
            (0, Class::Waiting),
            (20_000, Class::Driving),
            (40_000, Class::Turning),
            (60_000, Class::Settling),
        ];
        let split = tap.split(10_000, 70_000);
        assert!((split.waiting_s - 0.010).abs() < 1e-12);
        assert!((split.driving_s - 0.020).abs() < 1e-12);
        assert!((split.turning_s - 0.020).abs() < 1e-12);
        assert!((split.settling_s - 0.010).abs() < 1e-12);
        assert!((split.total_s() - 0.060).abs() < 1e-12);
    }
}
