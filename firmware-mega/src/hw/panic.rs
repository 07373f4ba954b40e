//! The panic handler: make the robot safe without formatting anything.
//!
//! It disables interrupts (the encoder and serial handlers stop) and drives the solenoid
//! pin low. The motors cannot be stopped here, because that needs a working I2C transfer;
//! the PCA9685 keeps its last outputs. No code path of the firmware is expected to panic:
//! it exists because `core` requires one.

use crate::board::SOLENOID_PORTC_BIT;

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo<'_>) -> ! {
    avr_device::interrupt::disable();
    // SAFETY: interrupts are off and the main loop never resumes, so nothing else accesses
    // PORTC; stealing the peripherals cannot create a conflicting live access.
    let dp = unsafe { avr_device::atmega2560::Peripherals::steal() };
    // SAFETY: PORTC is a plain per-pin bit register: every value is valid.
    dp.PORTC
        .portc()
        .modify(|r, w| unsafe { w.bits(r.bits() & !(1 << SOLENOID_PORTC_BIT)) });
    loop {
        core::hint::spin_loop();
    }
}
