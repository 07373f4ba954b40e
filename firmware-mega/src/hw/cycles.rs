//! A CPU cycle counter for the `bench-pi` benchmark: Timer4 free-running at clk/1.
//!
//! The counter is 16 bits, so it measures spans up to 65 535 cycles (4 ms), enough for one
//! PI step (about 1 000–6 000 cycles).

use avr_device::atmega2560::TC4;

/// Timer4 counting CPU cycles.
pub struct CycleCounter<'a> {
    tc4: &'a TC4,
}

impl<'a> CycleCounter<'a> {
    /// Start Timer4 in normal mode at clk/1.
    pub fn start(tc4: &'a TC4) -> Self {
        tc4.tccr4a().reset();
        tc4.tccr4b().write(|w| w.cs4().direct());
        Self { tc4 }
    }

    /// The counter now (wrapping), cycles.
    pub fn now(&self) -> u16 {
        self.tc4.tcnt4().read().bits()
    }
}
