//! Planning: a lower bound on a round's time ([`bound`]); shortest paths for a disc in free
//! space ([`disc_paths`]); paths on the waypoint graph with free-space shortcuts ([`graph`],
//! [`shortcuts`]; our road map: [`our_map`]) and the order of the competition's actions
//! ([`tasks`]).

pub mod bound;
mod cheapest_first;
pub mod disc_paths;
pub mod free_routes;
pub mod graph;
pub mod our_map;
pub mod shortcuts;
pub mod tasks;
