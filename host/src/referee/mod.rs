//! The organisers' server: its UDP protocol ([`protocol`]), a client for it ([`client`]),
//! and a compatible mock server for practice and simulation ([`mock`] is the pure state
//! machine, [`server`] puts it on a UDP socket).

pub mod client;
pub mod mock;
pub mod practice;
pub mod protocol;
pub mod server;
pub mod snapshot;
