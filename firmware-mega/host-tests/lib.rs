//! The firmware's hardware-independent modules, compiled for the host so that their unit tests
//! run with `cargo test` (the firmware crate builds only for the ATmega2560). The modules are the
//! firmware's own source files; nothing here is a copy.
#![forbid(unsafe_code)]

#[path = "../src/board.rs"]
pub mod board;
#[path = "../src/encoder_fold.rs"]
pub mod encoder_fold;
#[path = "../src/motor_shield.rs"]
pub mod motor_shield;
#[path = "../src/quadrature_tables.rs"]
pub mod quadrature_tables;
#[path = "../src/ring.rs"]
pub mod ring;
