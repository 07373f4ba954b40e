//! The code the robot's two computers share: the Arduino Mega firmware and the Raspberry Pi
//! host link this one crate, so the host's simulator runs exactly the logic the Mega runs.
//!
//! Boundary: `no_std`, no allocation, no `unsafe`, no I/O and no clock. Time is always passed
//! in (microseconds, wrapping `u32`, as the Mega's timer gives it). Wire integers are explicit
//! `u32`/`i32`, never `usize` (16 bits on AVR).
//!
//! - [`channels`]: the original 5dpo "channels" wire format, bit-exact (letter + 8 hex digits).
//! - [`integrity`]: the backward-compatible batch checksum extension (sequence + CRC).
//! - [`messages`]: typed frames both ways, units in the names.
//! - [`quadrature`]: the paper's Table I as a lookup table, plus skipped-state detection.
//! - [`pi`]: the wheel speed controller (PI + feed-forward + dead zone + anti-windup).
//! - [`settings`]: the controller settings the host sends the Mega, and their acknowledgement.
//! - [`mcu`]: the Mega's whole behaviour as a pure state machine.
//!
//! The wire format is specified with byte-exact examples in `protocol/README.md`.
#![no_std]
#![forbid(unsafe_code)]

#[cfg(test)]
extern crate std;

pub mod channels;
pub mod integrity;
pub mod mcu;
pub mod messages;
pub mod pi;
pub mod quadrature;
pub mod settings;
