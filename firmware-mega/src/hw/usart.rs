//! USART0 (Arduino pins 0/1, the USB-serial bridge to the Raspberry Pi) at 115200 8N1 with
//! interrupt-driven receive and transmit rings.
//!
//! - Receive: the `USART0_RX` interrupt moves each byte into a 128-byte ring (about 11 ms of
//!   bytes at line rate; the main loop drains it every pass).
//! - Transmit: [`Usart::write`] appends to a 256-byte ring and enables the data-register-
//!   empty interrupt (`USART0_UDRE`), which sends one byte per interrupt and disables itself
//!   when the ring is empty. `write` never waits: bytes that do not fit are dropped and
//!   counted. One telemetry batch is 81 bytes per 20 ms, 35 % of the line rate.

use crate::board::LINK_UBRR;
use crate::ring::Ring;
use avr_device::atmega2560::USART0;
use avr_device::interrupt::{self, Mutex};
use core::cell::RefCell;

/// Receive ring capacity, bytes.
pub const RX_CAPACITY: usize = 128;
/// Transmit ring capacity, bytes: three telemetry batches.
pub const TX_CAPACITY: usize = 256;

static RX: Mutex<RefCell<Ring<RX_CAPACITY>>> = Mutex::new(RefCell::new(Ring::new()));
static TX: Mutex<RefCell<Ring<TX_CAPACITY>>> = Mutex::new(RefCell::new(Ring::new()));

#[avr_device::interrupt(atmega2560)]
fn USART0_RX() {
    // SAFETY: inside this handler only USART0's data register is read; the main loop never
    // reads UDR0, so the stolen handle does not race with another user of that register.
    let usart = unsafe { avr_device::atmega2560::Peripherals::steal() }.USART0;
    let byte = usart.udr0().read().bits();
    interrupt::free(|cs| RX.borrow(cs).borrow_mut().push(byte));
}

#[avr_device::interrupt(atmega2560)]
fn USART0_UDRE() {
    // SAFETY: this handler is the only writer of UDR0, and it clears UDRIE0 with a single
    // read-modify-write while interrupts are disabled (handlers do not nest), so it cannot
    // interleave with `Usart::write`, which sets UDRIE0 inside a critical section.
    let usart = unsafe { avr_device::atmega2560::Peripherals::steal() }.USART0;
    match interrupt::free(|cs| TX.borrow(cs).borrow_mut().pop()) {
        Some(byte) => {
            usart.udr0().write(|w| w.set(byte));
        }
        None => {
            usart.ucsr0b().modify(|_, w| w.udrie0().clear_bit());
        }
    }
}

/// The serial link.
pub struct Usart {
    usart: USART0,
}

impl Usart {
    /// Configure 115200 baud with U2X (`board::LINK_UBRR`), 8N1, receiver and transmitter
    /// on, receive interrupt on.
    pub fn new(usart: USART0) -> Self {
        usart.ucsr0a().write(|w| w.u2x0().set_bit());
        usart.ubrr0().write(|w| w.set(LINK_UBRR));
        usart.ucsr0c().write(|w| w.ucsz0().chr8());
        usart
            .ucsr0b()
            .write(|w| w.rxen0().set_bit().txen0().set_bit().rxcie0().set_bit());
        Self { usart }
    }

    /// Queue `bytes` for transmission without waiting. Returns how many were queued; the
    /// rest were dropped (and counted, see [`Usart::bytes_dropped`]).
    pub fn write(&mut self, bytes: &[u8]) -> usize {
        // One byte per critical section, so interrupts are never off for more than a few
        // dozen cycles (the encoder interrupt must start within 320 cycles).
        let queued = bytes
            .iter()
            .filter(|&&byte| interrupt::free(|cs| TX.borrow(cs).borrow_mut().push(byte)))
            .count();
        interrupt::free(|_| {
            self.usart.ucsr0b().modify(|_, w| w.udrie0().set_bit());
        });
        queued
    }

    /// Move received bytes into `buffer`; returns how many.
    pub fn read(&mut self, buffer: &mut [u8]) -> usize {
        let mut n = 0;
        while n < buffer.len() {
            match interrupt::free(|cs| RX.borrow(cs).borrow_mut().pop()) {
                Some(byte) => {
                    buffer[n] = byte;
                    n += 1;
                }
                None => break,
            }
        }
        n
    }

    /// Bytes lost since boot (wrapping): received bytes that found the receive ring full plus
    /// bytes to send that found the transmit ring full. Reported on telemetry channel `x`.
    pub fn bytes_dropped(&self) -> u16 {
        interrupt::free(|cs| {
            let rx = RX.borrow(cs).borrow().dropped();
            let tx = TX.borrow(cs).borrow().dropped();
            rx.wrapping_add(tx)
        })
    }
}
