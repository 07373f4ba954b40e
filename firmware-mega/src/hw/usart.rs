//! USART0 (Arduino pins 0/1, the USB-serial bridge to the Raspberry Pi) at 115200 8N1 with
//! interrupt-driven receive and transmit rings.
//!
//! - Receive: the `USART0_RX` interrupt moves each byte into a 128-byte ring (about 11 ms of
//!   bytes at line rate; the main loop drains it every pass). The receiver is enabled only
//!   once interrupts are ([`Usart::start_receiving`]).
//! - Both interrupts turn themselves off and re-enable interrupts within a few cycles of
//!   entry (naked stubs, `__vector_25` and `__vector_26`), so the 50 kHz encoder interrupt
//!   pre-empts them instead of waiting for them to finish.
//! - Transmit: [`Usart::write`] appends to a 256-byte ring and enables the data-register-
//!   empty interrupt (`USART0_UDRE`), which sends one byte per interrupt and disables itself
//!   when the ring is empty. `write` never waits: bytes that do not fit are dropped and
//!   counted. One telemetry batch is 81 bytes per 20 ms, 35 % of the line rate.

use crate::board::LINK_UBRR;
use crate::ring::Ring;
use avr_device::atmega2560::USART0;
use avr_device::interrupt::{self, CriticalSection};
use core::cell::UnsafeCell;

/// Receive ring capacity, bytes.
pub const RX_CAPACITY: usize = 128;
/// Transmit ring capacity, bytes: three telemetry batches.
pub const TX_CAPACITY: usize = 256;

static RX: CsCell<Ring<RX_CAPACITY>> = CsCell::new(Ring::new());
static TX: CsCell<Ring<TX_CAPACITY>> = CsCell::new(Ring::new());

/// A ring shared by an interrupt handler and the main loop, reached only inside critical
/// sections. Unlike `Mutex<RefCell<_>>` it keeps no borrow flag: each access is a short
/// closure that cannot reach the same cell again, so the flag's 16 or so cycles per access
/// (with interrupts off, holding back the encoder interrupt) bought nothing.
struct CsCell<T>(UnsafeCell<T>);

// SAFETY: the value is reached only through `with`, which needs a critical section: on this
// single-core MCU no other code runs meanwhile, so accesses never overlap.
unsafe impl<T> Sync for CsCell<T> {}

impl<T> CsCell<T> {
    const fn new(value: T) -> Self {
        Self(UnsafeCell::new(value))
    }

    /// Run `f` on the value. Every `f` in this module is a leaf (a ring push, pop or count)
    /// that never calls `with` again, so the `&mut` is the only reference while it lives.
    fn with<R>(&self, _cs: CriticalSection<'_>, f: impl FnOnce(&mut T) -> R) -> R {
        // SAFETY: interrupts are off for the token's lifetime and `f` does not re-enter
        // (above), so nothing else reads or writes the value during `f`.
        f(unsafe { &mut *self.0.get() })
    }
}

/// `UCSR0B` with the receiver, its interrupt and the transmitter on, and the data-register-
/// empty interrupt off.
const UCSR0B_IDLE: u8 = (1 << 7) | (1 << 4) | (1 << 3);
/// `UCSR0B` as [`UCSR0B_IDLE`] with the data-register-empty interrupt on (`UDRIE0`, bit 5).
const UCSR0B_SENDING: u8 = UCSR0B_IDLE | (1 << 5);

/// Saves every register an `extern "C"` Rust function may clobber (r0, r1, r18–r27, r30,
/// r31; r24 is already saved) and SREG (on the stack: r25 is clobbered by the call), calls `{body}` with r24 as its first argument,
/// restores everything and returns from the interrupt. Runs with interrupts enabled: the
/// stubs below `sei` before it, so the encoder interrupt can pre-empt all of this.
macro_rules! nested_isr_tail {
    () => {
        concat!(
            "push r25\n",
            "in r25, 0x3f\n",
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
/// The byte stays in the hardware's buffer until [`rx_bytes`] reads it, and each read is
/// queued in the same critical section, so bytes are queued in arrival order even when a
/// long handler (the 1 kHz fold) pre-empts this one; the hardware holds two bytes more.
///
/// # Safety
///
/// Only the hardware calls it, as the `USART0_RX` vector. It preserves every register and
/// SREG. Its read-modify-write of `UCSR0B` runs with interrupts off; the main loop changes
/// `UCSR0B` only in critical sections and is suspended meanwhile.
#[unsafe(no_mangle)]
#[unsafe(naked)]
pub unsafe extern "C" fn __vector_25() {
    core::arch::naked_asm!(
        "push r24",       // 2
        "in r24, 0x3f",   // 1
        "push r24",       // 2
        "lds r24, 0xC1",  // 2  UCSR0B
        "andi r24, 0x7F", // 1  RXCIE0 off
        "sts 0xC1, r24",  // 2
        "pop r24",        // 2
        "out 0x3f, r24",  // 1
        "sei",            // 1
        nested_isr_tail!(),
        body = sym rx_bytes,
    );
}

/// `USART0_UDRE` (vector 26): turns its own interrupt off (a constant write of `UCSR0B`,
/// which changes no flag), re-enables interrupts, then sends the next byte ([`tx_next`]).
/// Interrupts are off for the hardware entry, the `jmp` and 6 cycles.
///
/// # Safety
///
/// Only the hardware calls it, as the `USART0_UDRE` vector. It preserves every register and
/// SREG. `UCSR0B` is otherwise written only by [`Usart::write`] and [`Usart::start_receiving`]
/// inside critical sections, and while this handler runs the main loop is suspended. It may
/// nest inside itself once, after [`tx_next`] re-enabled the interrupt and the transmitter
/// moved its byte on at once; the nested one fills the data register, so no third level.
#[unsafe(no_mangle)]
#[unsafe(naked)]
pub unsafe extern "C" fn __vector_26() {
    core::arch::naked_asm!(
        "push r24",        // 2
        "ldi r24, {idle}", // 1
        "sts 0xC1, r24",   // 2  UCSR0B: UDRIE0 off
        "sei",             // 1
        nested_isr_tail!(),
        idle = const UCSR0B_IDLE,
        body = sym tx_next,
    );
}

/// The receive interrupt's body: queue the received byte (read and queued in one critical
/// section; a full ring drops and counts it), then turn the receive interrupt back on. One
/// byte per interrupt: if the hardware holds another, the interrupt fires again at once.
/// (Reading on while `RXC0` is set would also be correct on the chip, but simavr then
/// delivers a backlog at up to twice the line rate.)
extern "C" fn rx_bytes() {
    // SAFETY: UDR0 is read only here (nested instances of this handler each read inside a
    // critical section); UCSR0B is changed here only inside a critical section.
    let usart = unsafe { avr_device::atmega2560::Peripherals::steal() }.USART0;
    interrupt::free(|cs| {
        if usart.ucsr0a().read().rxc0().bit_is_set() {
            let byte = usart.udr0().read().bits();
            RX.with(cs, |ring| ring.push(byte));
        }
    });
    interrupt::free(|_| usart.ucsr0b().modify(|_, w| w.rxcie0().set_bit()));
}

/// The transmit interrupt's body: send the next queued byte and re-enable the interrupt, or
/// leave it off when the ring is empty.
extern "C" fn tx_next() {
    if let Some(byte) = interrupt::free(|cs| TX.with(cs, |ring| ring.pop())) {
        // SAFETY: UDR0 and UCSR0B are written here only with the interrupt off (the stub
        // cleared UDRIE0), and by the main loop only in critical sections, while it is
        // suspended under this handler.
        let usart = unsafe { avr_device::atmega2560::Peripherals::steal() }.USART0;
        usart.udr0().write(|w| w.set(byte));
        // SAFETY: a valid UCSR0B value: receiver, transmitter and both interrupts on.
        usart.ucsr0b().write(|w| unsafe { w.bits(UCSR0B_SENDING) });
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
        // One byte per critical section, so interrupts are never off for more than a few
        // dozen cycles (the encoder interrupt must start within 320 cycles).
        let queued = bytes
            .iter()
            .filter(|&&byte| interrupt::free(|cs| TX.with(cs, |ring| ring.push(byte))))
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
            match interrupt::free(|cs| RX.with(cs, |ring| ring.pop())) {
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
            let rx = RX.with(cs, |ring| ring.dropped());
            let tx = TX.with(cs, |ring| ring.dropped());
            rx.wrapping_add(tx)
        })
    }
}
