//! Planning: a lower bound on a round's time ([`bound`]); paths on the waypoint graph with free-space shortcuts ([`graph`],
//! [`shortcuts`]) and the order of the competition's actions ([`tasks`]).

pub mod bound;
pub mod graph;
pub mod shortcuts;
pub mod tasks;
