//! USART0 (Arduino pins 0/1, the USB-serial bridge to the Raspberry Pi) at 115200 8N1 with
//! interrupt-driven receive and transmit rings.
//!
//! - Receive: the `USART0_RX` interrupt moves each byte into a 128-byte ring (about 11 ms of
//!   bytes at line rate; the main loop drains it every pass). The receiver is enabled only
//!   once interrupts are ([`Usart::start_receiving`]).
//! - Both interrupts turn themselves off and re-enable interrupts within a few cycles of
//!   entry (naked stubs, `__vector_25` and `__vector_26`), so the 50 kHz encoder interrupt
//!   pre-empts them instead of waiting for them to finish.
//! - Transmit: [`Usart::write`] appends to a 256-slot ring (255 bytes) and enables the
//!   data-register-empty interrupt (`USART0_UDRE`), which sends one byte per interrupt and
//!   leaves itself off when the ring is empty. `write` never waits: bytes that do not fit
//!   are dropped and counted. One telemetry batch is 90 bytes per 20 ms, 39 % of the line.
//! - The rings need no critical section: each has one producer and one consumer
//!   (`crate::ring`), and each handler is the only instance of itself while it touches its
//!   ring, because it keeps its own interrupt off until it is done, and every other writer
//!   of `UCSR0B` changes only its own bit (a read-modify-write with interrupts off). Those
//!   read-modify-writes of `UCSR0B` are the only critical sections here.

use crate::board::LINK_UBRR;
use crate::ring::{Ring, SharedByte};
use avr_device::atmega2560::USART0;
use avr_device::interrupt;
use core::cell::UnsafeCell;

/// Receive ring slots (and bytes held): about 11 ms of bytes at line rate.
pub const RX_CAPACITY: usize = 128;
/// Transmit ring slots: 255 bytes, almost three telemetry batches.
pub const TX_CAPACITY: usize = 256;

/// Producer [`rx_bytes`] (the receive interrupt), consumer [`Usart::read`] (the main loop).
static RX: Ring<VolatileByte, RX_CAPACITY> = Ring::new(
    [const { VolatileByte::new() }; RX_CAPACITY],
    VolatileByte::new(),
    VolatileByte::new(),
    VolatileByte::new(),
);
/// Producer [`Usart::write`] (the main loop), consumer [`tx_next`] (the transmit interrupt).
static TX: Ring<VolatileByte, TX_CAPACITY> = Ring::new(
    [const { VolatileByte::new() }; TX_CAPACITY],
    VolatileByte::new(),
    VolatileByte::new(),
    VolatileByte::new(),
);

/// A byte of a ring shared by an interrupt handler and the main loop, read and written with
/// one volatile load or store each (one `lds`/`sts` or `ld`/`st`, which cannot tear).
struct VolatileByte(UnsafeCell<u8>);

// SAFETY: every access is a single volatile one-byte load or store, which this single-core
// MCU performs as one instruction, and no reference to the byte is ever handed out; which
// side may write which byte is the ring's protocol (`crate::ring`).
unsafe impl Sync for VolatileByte {}

impl VolatileByte {
    const fn new() -> Self {
        Self(UnsafeCell::new(0))
    }
}

impl SharedByte for VolatileByte {
    fn get(&self) -> u8 {
        // SAFETY: the pointer comes from the cell (valid, aligned); see the `Sync` impl.
        unsafe { core::ptr::read_volatile(self.0.get()) }
    }

    fn set(&self, value: u8) {
        // SAFETY: as in `get`.
        unsafe { core::ptr::write_volatile(self.0.get(), value) }
    }
}

/// `UDRIE0`, the data-register-empty interrupt's enable bit in `UCSR0B`.
const UDRIE0: u8 = 1 << 5;

/// The end of both handlers' stubs, entered with r24 and r25 pushed, SREG in r25 and
/// interrupts enabled: pushes SREG and every other register an `extern "C"` Rust function
/// may clobber (r0, r1, r18–r23, r26, r27, r30, r31), calls `{body}`, restores everything
/// and returns from the interrupt. The encoder interrupt can pre-empt all of this.
macro_rules! nested_isr_tail {
    () => {
        concat!(
            "push r25\n",
            "push r0\n",
            "push r1\n",
            "clr r1\n",
            "push r18\n push r19\n push r20\n push r21\n push r22\n push r23\n",
            "push r26\n push r27\n push r30\n push r31\n",
            "call {body}\n",
            "pop r31\n pop r30\n pop r27\n pop r26\n",
            "pop r23\n pop r22\n pop r21\n pop r20\n pop r19\n pop r18\n",
            "pop r1\n",
            "pop r0\n",
            "pop r25\n",
            "out 0x3f, r25\n",
            "pop r25\n",
            "pop r24\n",
            "reti\n",
        )
    };
}

/// `USART0_RX` (vector 25): turns its own interrupt off (`RXCIE0`, a read-modify-write of
/// `UCSR0B`), re-enables interrupts, then moves the received byte to the ring and turns
/// the interrupt back on ([`rx_bytes`]). Interrupts are off for the hardware entry, the
/// vector's `jmp` and 11 cycles.
///
/// No other instance of this handler can run until [`rx_bytes`] turns the interrupt back
/// on: the transmit handler and the main loop change only `UDRIE0` in `UCSR0B`. So the
/// bytes are read and queued in arrival order, one handler at a time, even when a long
/// handler (the 1 kHz fold) pre-empts this one; the hardware holds two bytes more.
///
/// # Safety
///
/// Only the hardware calls it, as the `USART0_RX` vector. It preserves every register and
/// SREG. Its read-modify-write of `UCSR0B` runs with interrupts off, and so do all others.
#[unsafe(no_mangle)]
#[unsafe(naked)]
pub unsafe extern "C" fn __vector_25() {
    core::arch::naked_asm!(
        "push r24",       // 2
        "push r25",       // 2
        "in r25, 0x3f",   // 1  SREG, pushed by the tail
        "lds r24, 0xC1",  // 2  UCSR0B
        "andi r24, 0x7F", // 1  RXCIE0 off
        "sts 0xC1, r24",  // 2
        "sei",            // 1
        nested_isr_tail!(),
        body = sym rx_bytes,
    );
}

/// `USART0_UDRE` (vector 26): turns its own interrupt off (`UDRIE0`, a read-modify-write
/// of `UCSR0B` that leaves `RXCIE0` as it is), re-enables interrupts, then sends the next
/// byte ([`tx_next`]). Interrupts are off for the hardware entry, the `jmp` and 11 cycles.
///
/// # Safety
///
/// Only the hardware calls it, as the `USART0_UDRE` vector. It preserves every register and
/// SREG. Its read-modify-write of `UCSR0B` runs with interrupts off, and so do all others.
/// It may nest inside itself once, after [`tx_next`] took its byte, re-enabled the
/// interrupt and the transmitter moved the byte on at once; the nested one fills the data
/// register, so no third level, and the two never take from the ring at the same time.
#[unsafe(no_mangle)]
#[unsafe(naked)]
pub unsafe extern "C" fn __vector_26() {
    core::arch::naked_asm!(
        "push r24",         // 2
        "push r25",         // 2
        "in r25, 0x3f",     // 1  SREG, pushed by the tail
        "lds r24, 0xC1",    // 2  UCSR0B
        "andi r24, {mask}", // 1  UDRIE0 off
        "sts 0xC1, r24",    // 2
        "sei",              // 1
        nested_isr_tail!(),
        mask = const !UDRIE0,
        body = sym tx_next,
    );
}

/// The receive interrupt's body: queue the received byte (a full ring drops and counts
/// it), then turn the receive interrupt back on. It is the ring's only producer, and the
/// only instance of itself until that last step (see [`__vector_25`]), so it needs no
/// critical section but the read-modify-write of `UCSR0B`. One byte per interrupt: if the
/// hardware holds another, the interrupt fires again at once. (Reading on while `RXC0` is
/// set would also be correct on the chip, but simavr then delivers a backlog at up to twice
/// the line rate.)
extern "C" fn rx_bytes() {
    // SAFETY: UDR0 is read only here, by one instance at a time (above); UCSR0B is changed
    // here only inside a critical section.
    let usart = unsafe { avr_device::atmega2560::Peripherals::steal() }.USART0;
    if usart.ucsr0a().read().rxc0().bit_is_set() {
        RX.push(usart.udr0().read().bits());
    }
    interrupt::free(|_| usart.ucsr0b().modify(|_, w| w.rxcie0().set_bit()));
}

/// The transmit interrupt's body: send the next queued byte and re-enable the interrupt, or
/// leave it off when the ring is empty. It is the ring's only consumer, and the only
/// instance of itself until it re-enables the interrupt (see [`__vector_26`]).
extern "C" fn tx_next() {
    if let Some(byte) = TX.pop() {
        // SAFETY: UDR0 is written only here, with the interrupt off (the stub cleared
        // UDRIE0); UCSR0B is changed here only inside a critical section.
        let usart = unsafe { avr_device::atmega2560::Peripherals::steal() }.USART0;
        usart.udr0().write(|w| w.set(byte));
        interrupt::free(|_| usart.ucsr0b().modify(|_, w| w.udrie0().set_bit()));
    }
}

/// The serial link.
pub struct Usart {
    usart: USART0,
}

impl Usart {
    /// Configure 115200 baud with U2X (`board::LINK_UBRR`), 8N1, transmitter on. The
    /// receiver stays off until [`Usart::start_receiving`]: a byte arriving before its
    /// interrupt can run would overrun the two-byte hardware buffer.
    pub fn new(usart: USART0) -> Self {
        usart.ucsr0a().write(|w| w.u2x0().set_bit());
        usart.ubrr0().write(|w| w.set(LINK_UBRR));
        usart.ucsr0c().write(|w| w.ucsz0().chr8());
        usart.ucsr0b().write(|w| w.txen0().set_bit());
        Self { usart }
    }

    /// Turn the receiver and its interrupt on; call once interrupts are enabled.
    pub fn start_receiving(&mut self) {
        interrupt::free(|_| {
            self.usart
                .ucsr0b()
                .modify(|_, w| w.rxen0().set_bit().rxcie0().set_bit());
        });
    }

    /// Queue `bytes` for transmission without waiting. Returns how many were queued; the
    /// rest were dropped (and counted, see [`Usart::bytes_dropped`]).
    pub fn write(&mut self, bytes: &[u8]) -> usize {
        // The main loop is the transmit ring's only producer: no critical section.
        let queued = bytes.iter().filter(|&&byte| TX.push(byte)).count();
        interrupt::free(|_| {
            self.usart.ucsr0b().modify(|_, w| w.udrie0().set_bit());
        });
        queued
    }

    /// Move received bytes into `buffer`; returns how many.
    pub fn read(&mut self, buffer: &mut [u8]) -> usize {
        // The main loop is the receive ring's only consumer: no critical section.
        let mut n = 0;
        while n < buffer.len() {
            match RX.pop() {
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
    pub fn bytes_dropped(&self) -> u8 {
        RX.dropped().wrapping_add(TX.dropped())
    }
}
