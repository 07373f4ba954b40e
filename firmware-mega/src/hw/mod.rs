//! The hardware layer: the only modules that touch registers, interrupts or `unsafe`.
//!
//! Each submodule owns one peripheral and exposes a safe API; the rest of the crate is
//! plain logic. Interrupt handlers share state with the main loop without holding
//! interrupts off for long: the serial rings are single-producer single-consumer rings of
//! volatile bytes ([`usart`], `crate::ring`), the time base hands the clock and the closed
//! control windows over through a sequence lock ([`encoders`]), and the encoder interrupt's
//! few bytes are read one at a time ([`encoders`]). The critical sections left
//! (`interrupt::free`) are read-modify-writes of `UCSR0B` and the boot's set-up.
//!
//! Reserved for the encoder interrupt, never to be used elsewhere: `GPIOR0` (the previous
//! `PINA` sample), `GPIOR1` and `GPIOR2` (its register save slots).

pub mod delay;
pub mod encoders;
pub mod float;
pub mod gpio;
pub mod panic;
pub mod twi;
pub mod usart;

#[cfg(feature = "bench-pi")]
pub mod cycles;

use avr_device::atmega2560::Peripherals;

/// Enable interrupts, once every peripheral is configured.
pub fn enable_interrupts() {
    // SAFETY: called once from `main` after all interrupt state is initialised
    // (`encoders::start`, `usart::Usart::new`); no critical section is active.
    unsafe { avr_device::interrupt::enable() };
}

/// The device's peripherals, taken once at boot.
pub fn take_peripherals() -> Peripherals {
    // `take` returns None only on a second call; `main` calls this exactly once.
    match Peripherals::take() {
        Some(peripherals) => peripherals,
        None => panic!(),
    }
}
