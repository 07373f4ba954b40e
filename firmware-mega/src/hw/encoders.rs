//! The 50 kHz encoder interrupt (Timer1 compare A, `__vector_17`) and the 1 kHz time base
//! (Timer3 compare A, `__vector_32`).
//!
//! # Encoder interrupt
//!
//! Every 20 µs it reads `PINA` once (the four encoders on Arduino pins 22–29) and, for each
//! encoder, adds the table increment of its transition to an 8-bit wrapping position
//! counter ([`POSITIONS`]) and its skipped transitions to a 4-bit counter packed two per
//! byte ([`SKIPS`]). The tables (`crate::quadrature_tables`, generated from
//! `ratf_protocol::quadrature`) are indexed by `previous_nibble << 4 | current_nibble`, one
//! lookup per encoder pair and value.
//!
//! It is written in assembly (a naked function) so that its cost is known exactly and is
//! the same on every path (no branches): **99 cycles per invocation**, counted from the
//! listing below, hardware entry and `reti` included:
//!
//! | part | cycles |
//! |---|---|
//! | hardware entry (3-byte PC) + `jmp` in the vector table | 5 + 3 |
//! | save r24 and SREG in `GPIOR1`/`GPIOR2` (1 each), push r25, r30, r31 | 3 + 6 |
//! | read `PINA`, previous sample from `GPIOR0`, store the new one | 3 |
//! | the two pair indices | 10 |
//! | 6 × (`ldi`, `lpm`, `lds`, `add`, `sts`) = 6 × 9, plus one `mov` | 55 |
//! | pop r31, r30, r25, restore SREG and r24 | 6 + 3 |
//! | `reti` | 5 |
//!
//! State kept by the interrupt: the previous sample in `GPIOR0` (1-cycle `in`/`out`), the
//! 6 counter bytes in SRAM, the 768 B of tables in flash (256-byte aligned, so the index is
//! the low byte of the `lpm` address). `GPIOR1`/`GPIOR2` are its scratch save slots: no
//! other code may use the three `GPIOR` registers.
//!
//! # Time base
//!
//! Timer3 interrupts every millisecond (CTC, clk/8, `OCR3A` = 1999). Its handler advances
//! the clock and folds the encoder bytes into 16-bit control-window totals
//! (`crate::encoder_fold`), with interrupts enabled. The encoder interrupt has the higher
//! priority (lower vector) and pre-empts it, so a sample is at most delayed, never lost.
//!
//! # Hand-over to the main loop, with interrupts on
//!
//! The clock and each closed window's totals reach the main loop through a [`SeqCell`]: the
//! time-base handler writes the value and then bumps a one-byte sequence number; the main
//! loop reads the sequence number, copies the value, and keeps the copy only if the
//! sequence number has not moved meanwhile, else reads again. No critical section is
//! needed, so the hand-over never holds back the encoder interrupt (it used to take the
//! window out of a `Mutex<RefCell>` with interrupts off for 51 cycles).

use crate::board::{ENCODER_TIMER_TOP, TIME_BASE_TIMER_TOP};
use crate::encoder_fold::{ControlSample, ENCODERS, Fold, SampleTaker, WindowTotals};
use crate::quadrature_tables::{PairTable, TABLE_LEN, pair_table};
use avr_device::atmega2560::{CPU, TC1, TC3};
use avr_device::interrupt::{self, Mutex};
use core::cell::{RefCell, UnsafeCell};

/// A table in flash, aligned so that its address's low byte is 0.
#[repr(C, align(256))]
pub struct FlashTable([u8; TABLE_LEN]);

/// Bytes written by the encoder interrupt and read with interrupts disabled.
#[repr(transparent)]
pub struct IsrBytes<const N: usize>(UnsafeCell<[u8; N]>);

// SAFETY: the bytes are written only by the encoder interrupt, one store per byte, and read
// either with interrupts disabled (`start`, before the encoder interrupt is enabled) or one
// byte at a time (the time-base interrupt), so no read ever sees a half-written value on
// this single-core MCU.
unsafe impl<const N: usize> Sync for IsrBytes<N> {}

impl<const N: usize> IsrBytes<N> {
    const fn zeroed() -> Self {
        Self(UnsafeCell::new([0; N]))
    }

    /// Read the bytes. Call only with interrupts disabled (see the `Sync` impl).
    fn read(&self, _cs: interrupt::CriticalSection<'_>) -> [u8; N] {
        // SAFETY: the pointer is valid and aligned (it comes from the cell), and the
        // critical section guarantees the encoder interrupt is not writing meanwhile.
        unsafe { core::ptr::read_volatile(self.0.get()) }
    }

    /// Read the bytes one at a time, interrupts allowed: each byte is read whole (a single
    /// load), but an encoder interrupt may update later bytes between two reads.
    fn read_bytewise(&self) -> [u8; N] {
        let base = self.0.get().cast::<u8>();
        core::array::from_fn(|k| {
            // SAFETY: `k < N`, so the pointer stays inside the array; a one-byte volatile
            // load cannot tear, and the encoder interrupt writes each byte with one store.
            unsafe { core::ptr::read_volatile(base.add(k)) }
        })
    }
}

/// The pair tables, in flash (`.progmem`, placed by avr-gcc's linker script in the first
/// 64 KiB, where `lpm` reaches). Only the assembly below reads them; Rust code must not,
/// since a normal load would read SRAM at the same address.
#[unsafe(link_section = ".progmem.data.ratf_quadrature_first")]
static FIRST_DELTA: FlashTable = FlashTable(pair_table(PairTable::FirstDelta));
#[unsafe(link_section = ".progmem.data.ratf_quadrature_second")]
static SECOND_DELTA: FlashTable = FlashTable(pair_table(PairTable::SecondDelta));
#[unsafe(link_section = ".progmem.data.ratf_quadrature_skips")]
static SKIP_COUNTS: FlashTable = FlashTable(pair_table(PairTable::Skips));

/// Net counts mod 256 per encoder, written by the encoder interrupt.
static POSITIONS: IsrBytes<ENCODERS> = IsrBytes::zeroed();
/// Skipped transitions, two 4-bit wrapping counts per byte (encoders 0/1, 2/3; the first
/// of a pair in the low nibble), written by the encoder interrupt.
static SKIPS: IsrBytes<{ ENCODERS / 2 }> = IsrBytes::zeroed();

/// The time-base state: used only by the time-base interrupt (and by [`Encoders::start`]
/// before interrupts are enabled).
static FOLD: Mutex<RefCell<Fold>> = Mutex::new(RefCell::new(Fold::new([0; 4], [0; 2])));

/// A value written by one interrupt handler and read by the main loop without a critical
/// section: a sequence lock with a one-byte sequence number (see the module documentation).
struct SeqCell<T> {
    sequence: UnsafeCell<u8>,
    value: UnsafeCell<T>,
}

// SAFETY: only one interrupt handler writes (`publish`, which cannot nest inside itself and
// which the main loop cannot interrupt), and only the main loop reads (`read`), which
// discards any copy that a `publish` may have overlapped (the sequence number moved). All
// accesses are volatile, so they happen in program order; the MCU has a single core.
unsafe impl<T: Copy> Sync for SeqCell<T> {}

impl<T: Copy> SeqCell<T> {
    const fn new(value: T) -> Self {
        Self {
            sequence: UnsafeCell::new(0),
            value: UnsafeCell::new(value),
        }
    }

    /// Store `value`. Call only from the one interrupt handler that owns this cell.
    fn publish(&self, value: T) {
        // SAFETY: the pointers come from the cells (valid, aligned). Only this handler
        // writes, and nothing can interrupt it and read meanwhile (the main loop is the only
        // reader); the value is written before the sequence number moves.
        unsafe {
            core::ptr::write_volatile(self.value.get(), value);
            let sequence = core::ptr::read_volatile(self.sequence.get());
            core::ptr::write_volatile(self.sequence.get(), sequence.wrapping_add(1));
        }
    }

    /// A consistent copy of the value. Call only from the main loop. It reads again when the
    /// handler published during the copy, which at most once a millisecond can happen.
    fn read(&self) -> T {
        loop {
            // SAFETY: the pointers come from the cells (valid, aligned, `T: Copy`). A
            // `publish` may interrupt the copy and tear it; then the sequence number read
            // after the copy differs (the handler bumps it after writing, and 256 publishes
            // cannot fit into one copy), and the torn copy is discarded.
            let (before, value, after) = unsafe {
                let before = core::ptr::read_volatile(self.sequence.get());
                let value = core::ptr::read_volatile(self.value.get());
                let after = core::ptr::read_volatile(self.sequence.get());
                (before, value, after)
            };
            if before == after {
                return value;
            }
        }
    }
}

/// The latest closed window's totals, from the time-base interrupt to the main loop.
static WINDOW: SeqCell<WindowTotals> = SeqCell::new(WindowTotals {
    windows: 0,
    end_us: 0,
    counts: [0; ENCODERS],
    quadrature_errors: [0; ENCODERS],
});
/// Time since boot at the latest millisecond, µs (wrapping), from the time-base interrupt.
static CLOCK_US: SeqCell<u32> = SeqCell::new(0);

/// Timer1 compare A: the encoder interrupt. See the module documentation for the cycle
/// count; the instruction comments give each one's cycles.
///
/// # Safety
///
/// Only the hardware calls it, as the `TIMER1_COMPA` vector. It preserves every register
/// it uses and SREG, and touches only `PINA`, `GPIOR0..2`, the flash tables, [`POSITIONS`]
/// and [`SKIPS`].
#[unsafe(no_mangle)]
#[unsafe(naked)]
pub unsafe extern "C" fn __vector_17() {
    core::arch::naked_asm!(
        "out 0x2a, r24", // 1  GPIOR1 <- r24
        "in r24, 0x3f",  // 1  SREG
        "out 0x2b, r24", // 1  GPIOR2 <- SREG
        "push r25",      // 2
        "push r30",      // 2
        "push r31",      // 2
        "in r24, 0x00",  // 1  r24 = PINA (current)
        "in r25, 0x1e",  // 1  r25 = GPIOR0 (previous)
        "out 0x1e, r24", // 1  GPIOR0 <- current
        // Pair 0 index in r30: previous low nibble << 4 | current low nibble.
        "mov r30, r25",   // 1
        "swap r30",       // 1
        "andi r30, 0xf0", // 1
        "mov r31, r24",   // 1
        "andi r31, 0x0f", // 1
        "or r30, r31",    // 1
        // Pair 1 index in r25: previous high nibble << 4 | current high nibble.
        "andi r25, 0xf0", // 1
        "swap r24",       // 1
        "andi r24, 0x0f", // 1
        "or r25, r24",    // 1
        // Encoder 0.
        "ldi r31, hi8({first})", // 1
        "lpm r24, Z",            // 3
        "lds r31, {pos}",        // 2
        "add r31, r24",          // 1
        "sts {pos}, r31",        // 2
        // Encoder 1.
        "ldi r31, hi8({second})",
        "lpm r24, Z",
        "lds r31, {pos}+1",
        "add r31, r24",
        "sts {pos}+1, r31",
        // Skips of encoders 0 and 1.
        "ldi r31, hi8({skips})",
        "lpm r24, Z",
        "lds r31, {skip}",
        "add r31, r24",
        "sts {skip}, r31",
        // Pair 1.
        "mov r30, r25", // 1
        "ldi r31, hi8({first})",
        "lpm r24, Z",
        "lds r31, {pos}+2",
        "add r31, r24",
        "sts {pos}+2, r31",
        "ldi r31, hi8({second})",
        "lpm r24, Z",
        "lds r31, {pos}+3",
        "add r31, r24",
        "sts {pos}+3, r31",
        "ldi r31, hi8({skips})",
        "lpm r24, Z",
        "lds r31, {skip}+1",
        "add r31, r24",
        "sts {skip}+1, r31",
        "pop r31",       // 2
        "pop r30",       // 2
        "pop r25",       // 2
        "in r24, 0x2b",  // 1  GPIOR2
        "out 0x3f, r24", // 1  SREG
        "in r24, 0x2a",  // 1  GPIOR1
        "reti",          // 5
        first = sym FIRST_DELTA,
        second = sym SECOND_DELTA,
        skips = sym SKIP_COUNTS,
        pos = sym POSITIONS,
        skip = sym SKIPS,
    );
}

/// Timer3 compare A (vector 32), every millisecond: advance the clock, fold the encoder
/// counters and publish the clock and any closed window ([`CLOCK_US`], [`WINDOW`]). A
/// non-blocking handler: its first instruction is `sei`, so interrupts are off only for the
/// hardware entry, the vector's `jmp` and that `sei`. The encoder bytes are then read one at
/// a time with interrupts on: each byte is read whole (one `lds`), and the fold works on
/// each counter's own change since its previous read, so an encoder interrupt between two
/// reads only moves that sample's later counters into the next millisecond.
///
/// # Safety
///
/// Only the hardware calls it, as the `TIMER3_COMPA` vector (the hardware clears its flag on
/// entry). Nothing else touches [`FOLD`] while it runs: the encoder and serial handlers that
/// may nest inside it do not, it cannot nest inside itself (it runs for far less than its
/// 1 ms period), and the main loop only reads the two [`SeqCell`]s this handler writes.
#[unsafe(no_mangle)]
pub unsafe extern "avr-non-blocking-interrupt" fn __vector_32() {
    let positions = POSITIONS.read_bytewise();
    let skips = SKIPS.read_bytewise();
    // SAFETY: as above, no other code can access FOLD until this handler returns, which is
    // the exclusivity a critical section would give.
    let cs = unsafe { interrupt::CriticalSection::new() };
    let mut fold = FOLD.borrow(cs).borrow_mut();
    if let Some(totals) = fold.on_millisecond(positions, skips) {
        WINDOW.publish(totals);
    }
    CLOCK_US.publish(fold.now_us());
}

/// Handle to the running encoder sampling and time base.
pub struct Encoders {
    _tc1: TC1,
    _tc3: TC3,
    taker: SampleTaker,
}

impl Encoders {
    /// Seed the previous sample with `pins` (the encoder pins' current state, `PINA`) and
    /// start both timers (their interrupts run once interrupts are enabled).
    pub fn start(tc1: TC1, tc3: TC3, cpu: &CPU, pins: u8) -> Self {
        interrupt::free(|cs| {
            // SAFETY: GPIOR0 is a plain storage register: every value is valid.
            cpu.gpior0().write(|w| unsafe { w.bits(pins) });
            *FOLD.borrow(cs).borrow_mut() = Fold::new(POSITIONS.read(cs), SKIPS.read(cs));
        });
        // Timer1: CTC with TOP = OCR1A (WGM1 = 0b0100), clk/1.
        tc1.tccr1a().reset();
        tc1.ocr1a().write(|w| w.set(ENCODER_TIMER_TOP));
        tc1.tcnt1().write(|w| w.set(0));
        tc1.tccr1b().write(|w| w.wgm1().set(0b01).cs1().direct());
        tc1.timsk1().write(|w| w.ocie1a().set_bit());
        // Timer3: CTC with TOP = OCR3A, clk/8.
        tc3.tccr3a().reset();
        tc3.ocr3a().write(|w| w.set(TIME_BASE_TIMER_TOP));
        tc3.tcnt3().write(|w| w.set(0));
        tc3.tccr3b()
            .write(|w| w.wgm3().set(0b01).cs3().prescale_8());
        tc3.timsk3().write(|w| w.ocie3a().set_bit());
        Self {
            _tc1: tc1,
            _tc3: tc3,
            taker: SampleTaker::new(),
        }
    }

    /// The sample of the control windows closed since the last call, if any (read with
    /// interrupts on, see [`SeqCell`]).
    pub fn take_sample(&mut self) -> Option<ControlSample> {
        self.taker.take(&WINDOW.read())
    }

    /// Time since boot, µs (wrapping), with millisecond resolution (read with interrupts on).
    pub fn now_us(&self) -> u32 {
        CLOCK_US.read()
    }
}
