//! The ratf robot's pure core: everything the robot decides, as a fold over timestamped
//! inputs with no clock and no I/O (architecture.md, "The runtime").
//!
//! Device parsers (the Mega link, the YDLIDAR X4, the MPU9255 driver over `embedded-hal`)
//! are sans-I/O: bytes and their arrival time in, typed data out. Estimation, planning,
//! control, the mission and the organisers' server logic take the time as an argument. The
//! crate opens no socket, file or thread and knows nothing of the simulator: `ratf-sim`
//! builds the world on these types, and `ratf-host` drives the core with real devices.
#![forbid(unsafe_code)]

pub mod calibration;
pub mod competition;
pub mod config;
pub mod control;
pub mod drivers;
pub mod field;
pub mod identification;
pub mod kinematics;
pub mod localisation;
pub mod mission;
pub mod odometry;
pub mod planning;
pub mod referee;
pub mod rng;
pub mod robot;
pub mod runtime;
