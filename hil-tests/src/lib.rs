//! Hardware-in-the-loop tests for the Mega firmware: the release ELF, exactly as it will be
//! flashed, run in simavr (through avr-tester) with simulated peripherals around it.
//!
//! - [`firmware`]: where the ELF is (with a clear error when it is not built) and its size.
//! - [`sim`]: [`sim::Hil`], the simulator with the robot's pins, UART and motor shield.
//! - [`telemetry`]: the firmware's UART output as timestamped frames and batches.
//! - [`host_link`]: command batches as the Pi encodes them.
//! - [`encoder_lines`]: quadrature lines the tests drive onto `PINA`; [`edge_rate`]: edge-rate
//!   trials and the search for the highest lossless rate; [`edge_load`]: the same under full
//!   host traffic at random phases.
//! - [`pca9685`] and [`shield`]: the motor shield's PWM chip on the TWI bus, decoded into
//!   per-motor PWM and voltage.
//! - [`isr_cycles`]: static cycle bounds of the encoder ISR from `avr-objdump -d`.
//! - [`plant`]: a first-order DC motor with encoder; [`closed_loop`]: four of them driven
//!   by the simulated shield, closing the firmware's speed loop.
//! - [`latency`]: how long before a batch's first byte its control window closed.
//! - [`watchdog`]: measuring how long after the last `G`/`K` the motors stop.
//! - [`report`]: the figures of `target/hil-report.json` (written by the `hil_report` test).
//!
//! The tests in `tests/` need the firmware built first (`cd firmware-mega && cargo build
//! --release`) and run with `cargo test -p ratf-hil-tests --release`; a missing ELF fails
//! each test with that command in the message (`RATF_HIL_ELF` points them at another ELF).
//! The `hil_report` test binary prints every figure and writes `target/hil-report.json`:
//! `cargo test -p ratf-hil-tests --release --test hil_report`.
#![forbid(unsafe_code)]

pub mod closed_loop;
pub mod edge_load;
pub mod edge_rate;
pub mod encoder_lines;
pub mod firmware;
pub mod host_link;
pub mod isr_cycles;
pub mod latency;
pub mod pca9685;
pub mod plant;
pub mod report;
pub mod shield;
pub mod sim;
pub mod telemetry;
pub mod watchdog;
