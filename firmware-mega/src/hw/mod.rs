//! The hardware layer: the only modules that touch registers, interrupts or `unsafe`.
//!
//! Each submodule owns one peripheral and exposes a safe API; the rest of the crate is
//! plain logic. Interrupt handlers share state with the main loop only inside critical
//! sections (`interrupt::free`): through `avr_device::interrupt::Mutex`, or for the serial
//! rings a `CsCell` without a borrow flag ([`usart`]); the exception is the encoder
//! interrupt, whose few bytes are documented in [`encoders`].
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
