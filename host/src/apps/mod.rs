//! Apps built on the core and the simulated world: a whole round ([`round`]), the velocity
//! scripts ([`drive`], [`scripts`]), the benchmarks ([`loc_bench`], [`nav_bench`],
//! [`fault_bench`]; where a round's time goes: [`time_split`]; what its collisions were:
//! [`collision_causes`]) and the replay of a recording ([`replay`]); operator commands
//! scripted through the runtime ([`operator_script`]).

pub mod calibrate;
pub mod check;
pub mod collision_causes;
pub mod drive;
pub mod fault_bench;
pub mod fault_round;
pub mod latency_histogram;
pub mod loc_bench;
pub mod nav_bench;
pub mod operator_script;
pub mod replay;
pub mod round;
pub mod run;
pub mod scripts;
pub mod serve_pty;
pub mod soak;
pub mod time_split;
pub mod tracked_script;
pub mod tune;
