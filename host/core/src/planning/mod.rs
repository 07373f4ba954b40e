//! Planning: paths on the waypoint graph with free-space shortcuts ([`graph`],
//! [`shortcuts`]) and the order of the competition's actions ([`tasks`]).

pub mod graph;
pub mod shortcuts;
pub mod tasks;
