//! The ratf robot host (Raspberry Pi 4): drivers, estimation, planning, control, the
//! competition mission, the organisers' server client, the operator interface, and a
//! deterministic simulator of the whole robot.
//!
//! Boundary: everything here except `drivers`' real ports and the `ratf` binary is pure logic
//! that reads no clock and does no I/O; time is passed in. The Mega's wheel-level behaviour
//! is not re-implemented here: the simulator runs [`ratf_protocol::mcu`], the firmware's own
//! code.
#![forbid(unsafe_code)]

pub mod competition;
pub mod config;
pub mod control;
pub mod drivers;
pub mod field;
pub mod kinematics;
pub mod localisation;
pub mod mission;
pub mod odometry;
pub mod planning;
pub mod plot;
pub mod referee;
pub mod robot;
pub mod sim;
