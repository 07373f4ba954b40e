//! Motion control: routes ([`route`]), speed and heading profiles ([`profile`]), a route's
//! time for the task planner ([`route_time`]), our path
//! follower with docking ([`follower`]), the creep to contact that ends a docking approach
//! ([`creep`]) and the original 5dpo follower as a preset
//! ([`original`]). Everything here is pure: time and the pose estimate come in as arguments,
//! a body twist goes out.

pub mod creep;
pub mod follower;
pub mod original;
pub mod profile;
pub mod route;
pub mod route_time;
