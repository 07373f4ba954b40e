//! A busy-wait delay (embedded-hal 1.0 `DelayNs`), used only at motor-shield
//! initialisation (the PCA9685's oscillator needs 500 µs after leaving sleep).

use crate::board::F_CPU_HZ;
use embedded_hal::delay::DelayNs;

/// Busy-waits by counting CPU cycles (at least the requested time; interrupts lengthen it).
pub struct BusyDelay;

impl DelayNs for BusyDelay {
    fn delay_ns(&mut self, ns: u32) {
        let cycles = (u64::from(ns) * u64::from(F_CPU_HZ)).div_ceil(1_000_000_000);
        avr_device::asm::delay_cycles(cycles as u32);
    }
}
