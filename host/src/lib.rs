//! The ratf robot host (Raspberry Pi 4): what does I/O. The organisers' server client and
//! the mock server on UDP sockets, the SVG plots, and the apps built on the core
//! (`ratf-core`) and the simulated world (`ratf-sim`): whole simulated rounds, the
//! benchmarks, the drive scripts. The `ratf` binary is the CLI over them.
#![forbid(unsafe_code)]

pub mod apps;
pub mod devices;
pub mod hmi;
pub mod mcap_read;
pub mod plot;
pub mod pty;
pub mod recording;
pub mod referee;
pub mod ros2;
