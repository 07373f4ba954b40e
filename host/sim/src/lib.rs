//! The ratf simulated world: a deterministic simulator of the robot's body, wheels and
//! motors, the Mega (which runs [`ratf_protocol::mcu`], the firmware's own code), the X4
//! lidar, the IMU, the parts, switch, magnet and machines, and a twin of the organisers'
//! server. It speaks to the robot's core only through the devices' bytes and the core's
//! types, never through the core's beliefs.
#![forbid(unsafe_code)]

pub mod body;
pub mod contact;
pub mod devices;
#[cfg(test)]
mod fault_tests;
pub mod faults;
pub mod harness;
pub mod imu;
pub mod lidar;
pub mod motor;
pub mod parts;
pub mod referee;
pub mod serial;
pub mod testkit;
pub mod truth;
pub mod world;
