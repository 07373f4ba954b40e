//! The planned path the page draws: the robot's own route planner (`plan_route`, or the
//! original's for that policy) run with the inputs the robot's navigator had when it set off
//! (the pose, the goal slot, whether it docks), so the line is the route the robot follows
//! without the core exposing its navigator.

use ratf_core::config::{Config, Policy};
use ratf_core::control::route::{ORIGINAL_APPROACH_M, plan_original_route, plan_route};
use ratf_core::field::geometry::Pose2;
use ratf_core::field::{Field, WaypointId};
use ratf_core::planning::graph::RoadMap;
use ratf_core::planning::shortcuts::{Footprint, FreeSpace};

/// Plans routes as the robot's navigator does.
#[derive(Debug)]
pub struct PathPlanner {
    config: Config,
    field: Field,
    map: RoadMap,
}

impl PathPlanner {
    /// A planner for the robot `config` describes (the navigator plans on the competition
    /// floor).
    pub fn new(config: &Config) -> Self {
        let field = Field::competition();
        Self {
            map: RoadMap::new(field.waypoints().clone()),
            config: config.clone(),
            field,
        }
    }

    /// The route from `pose` to the slot at `goal` (docking when `dock`, i.e. to pick), as
    /// world points, m; empty when there is none.
    pub fn route(&self, pose: Pose2, goal: WaypointId, dock: bool) -> Vec<[f64; 2]> {
        let Some(slot) = self.field.slot_for_waypoint(goal).copied() else {
            return Vec::new();
        };
        let route = match self.config.competition.policy {
            Policy::Ours => {
                let footprint = Footprint {
                    length_m: self.config.robot.footprint_length_m,
                    width_m: self.config.robot.footprint_width_m,
                    carrying: !dock,
                };
                let space = FreeSpace::new(
                    &self.field,
                    &[],
                    footprint,
                    self.config.navigation.shortcut_margin_m,
                );
                plan_route(
                    &self.field,
                    &self.map,
                    &space,
                    pose,
                    &slot,
                    &self.config.navigation,
                )
            }
            Policy::Original => plan_original_route(&self.map, pose, &slot, ORIGINAL_APPROACH_M),
        };
        route.map_or_else(
            |_| Vec::new(),
            |route| route.points().iter().map(|p| [p.x, p.y]).collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_route_from_the_start_ends_at_the_first_incoming_slot() {
        let config = Config::default();
        let field = Field::competition();
        let slot = field.incoming_slot(0).unwrap();
        let route = PathPlanner::new(&config).route(field.start_pose(), slot.waypoint, true);
        assert!(route.len() >= 2, "{route:?}");
        let start = field.start_pose();
        assert!((route[0][0] - start.x).abs() < 1e-9 && (route[0][1] - start.y).abs() < 1e-9);
        let end = route[route.len() - 1];
        let pick = slot.pick_pose;
        assert!(((end[0] - pick.x).powi(2) + (end[1] - pick.y).powi(2)).sqrt() < 0.01);
    }
}
