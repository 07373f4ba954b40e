//! A deterministic simulator of the whole robot, in simulated time, as fast as the CPU allows.
//!
//! The simulated devices speak the same bytes as the real ones: the Mega is
//! [`ratf_protocol::mcu::Mcu`] (the firmware's own logic) behind a 115 200 baud line, the
//! lidar emits real YDLIDAR X4 packets, and the IMU answers the real driver's register reads.
//! So every simulation runs the host's real parsers and the Mega's real logic.

pub mod body;
pub mod drive;
pub mod harness;
pub mod lidar;
pub mod loc_bench;
pub mod motor;
pub mod nav_bench;
pub mod parts;
pub mod rng;
pub mod round;
pub mod scripts;
pub mod serial;
pub mod world;
