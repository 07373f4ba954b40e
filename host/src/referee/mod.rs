//! The organisers' server on UDP: a client for it ([`client`]), and a compatible mock server
//! for practice and simulation ([`server`] puts `ratf_sim::referee`'s pure state machine on
//! a socket; [`practice`] is the console `ratf referee`). The protocol and the request logic
//! are the core's (`ratf_core::referee`).

pub mod client;
pub mod practice;
pub mod server;
