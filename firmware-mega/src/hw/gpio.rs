//! The digital pins the firmware uses besides the encoders: the box switch and the solenoid.
//! Pins and levels: `board.rs` and `hardware/pinmap.md`.

use crate::board::{ENCODER_PORT_MASK, SOLENOID_PORTC_BIT, SWITCH_PORTB_BIT};
use avr_device::atmega2560::{PORTA, PORTB, PORTC};

/// Set (`high`) or clear the bits `mask` of a port register with a read-modify-write.
/// No interrupt handler writes the port registers used here, so it need not be atomic.
macro_rules! update_bits {
    ($register:expr, $mask:expr, $high:expr) => {{
        let (mask, high): (u8, bool) = ($mask, $high);
        // SAFETY: DDRx and PORTx are plain per-pin bit registers: every value is valid.
        $register.modify(|r, w| unsafe {
            w.bits(if high {
                r.bits() | mask
            } else {
                r.bits() & !mask
            })
        });
    }};
}

/// The encoder pins (read once at start), the switch input and the solenoid output.
pub struct Gpio {
    porta: PORTA,
    portb: PORTB,
    portc: PORTC,
}

impl Gpio {
    /// Configure the pins: encoder pins (PORTA) inputs with pull-ups, switch (PB0) input
    /// with pull-up, solenoid (PC7) output driven low.
    pub fn new(porta: PORTA, portb: PORTB, portc: PORTC) -> Self {
        update_bits!(porta.ddra(), ENCODER_PORT_MASK, false);
        update_bits!(porta.porta(), ENCODER_PORT_MASK, true);
        update_bits!(portb.ddrb(), 1 << SWITCH_PORTB_BIT, false);
        update_bits!(portb.portb(), 1 << SWITCH_PORTB_BIT, true);
        update_bits!(portc.portc(), 1 << SOLENOID_PORTC_BIT, false);
        update_bits!(portc.ddrc(), 1 << SOLENOID_PORTC_BIT, true);
        Self {
            porta,
            portb,
            portc,
        }
    }

    /// The encoder pins now (`PINA`: encoder `k` has A on bit `2k`, B on bit `2k + 1`).
    pub fn encoder_pins(&self) -> u8 {
        self.porta.pina().read().bits()
    }

    /// The box switch is pressed (pin 53 reads 0).
    pub fn switch_pressed(&self) -> bool {
        self.portb.pinb().read().bits() & (1 << SWITCH_PORTB_BIT) == 0
    }

    /// Drive the solenoid (pin 30) high (`true`) or low.
    pub fn set_solenoid(&mut self, on: bool) {
        update_bits!(self.portc.portc(), 1 << SOLENOID_PORTC_BIT, on);
    }
}
