//! [`Hil`]: the release ELF running in simavr (through avr-tester) with the robot's
//! peripherals around it — the host's UART, the four encoders on `PINA`, the box switch,
//! the solenoid pin and the motor shield's PCA9685 on the TWI bus.
//!
//! Time is simulated CPU cycles at 16 MHz, counted from reset; nothing here reads a
//! wall clock. The simulator advances one instruction per [`Hil::step`], and every byte the
//! firmware transmits is recorded with the cycle it left.
//!
//! Pins (original-system.md §2.1): encoders on PA0..PA7 (Arduino 22–29), switch on PB0
//! (pin 53, pull-up, low = pressed), solenoid on PC7 (pin 30).

use crate::encoder_lines::EncoderLines;
use crate::firmware::{FirmwareError, elf_path};
use crate::pca9685::{Pca9685, Pca9685Slave};
use crate::telemetry::{RxByte, TelemetryBatch, TimedBatch, TimedFrame, batches, timed_frames};
use avr_tester::{AvrTester, Reader};
use std::cell::{Ref, RefCell};
use std::rc::Rc;

/// CPU clock, Hz (Arduino Mega 2560 crystal).
pub const CLOCK_HZ: u64 = 16_000_000;
/// Cycles per microsecond.
pub const CYCLES_PER_US: u64 = CLOCK_HZ / 1_000_000;
/// Cycles per millisecond.
pub const CYCLES_PER_MS: u64 = CLOCK_HZ / 1_000;

/// Cycles simavr takes to deliver one UART byte to the firmware at 115 200 baud with U2X
/// (UBRR = 16, so one bit is 8 · 17 = 136 cycles): simavr counts 11 bit times per byte
/// (avr-toolchain.md, "Simulation notes"), so 1496 cycles ≈ 93.5 µs.
pub const UART_BYTE_CYCLES: u64 = 11 * 8 * 17;

/// The firmware in the simulator with its peripherals.
pub struct Hil {
    avr: AvrTester,
    cycle: u64,
    rx: Vec<RxByte>,
    lines: EncoderLines,
    driven_pina: u8,
    shield: Rc<RefCell<Pca9685>>,
}

impl Hil {
    /// Load the release ELF (see [`crate::firmware::elf_path`]) into a fresh ATmega2560 at
    /// 16 MHz, attach a PCA9685 at 0x60, and drive every encoder line and the switch high
    /// (idle, not pressed) before the first instruction.
    pub fn boot() -> Result<Self, FirmwareError> {
        let path = elf_path()?;
        let mut avr = AvrTester::atmega2560().with_clock_of_16_mhz().load(path);
        let shield = Rc::new(RefCell::new(Pca9685::new()));
        avr.twi0().attach_slave(Pca9685Slave::new(shield.clone()));
        let mut hil = Self {
            avr,
            cycle: 0,
            rx: Vec::new(),
            lines: EncoderLines::new(),
            driven_pina: 0,
            shield,
        };
        for bit in 0..8 {
            hil.set_pa(bit, true);
        }
        hil.driven_pina = 0xFF;
        hil.set_switch_pressed(false);
        Ok(hil)
    }

    /// Like [`Self::boot`], panicking with the build instructions if the ELF is missing.
    pub fn boot_or_panic() -> Self {
        Self::boot().unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Hil::boot_or_panic`], then run until the first telemetry batch (at most 60 ms):
    /// the firmware is up and its control loop is running.
    pub fn booted() -> Self {
        let mut hil = Self::boot_or_panic();
        assert!(
            hil.run_until_telemetry_batches(1, 60 * CYCLES_PER_MS),
            "no telemetry within 60 ms of boot"
        );
        hil
    }

    /// Cycles since reset.
    pub fn cycle(&self) -> u64 {
        self.cycle
    }

    /// Execute one instruction (and any interrupt entry simavr performs with it).
    pub fn step(&mut self) {
        self.cycle += self.avr.run().as_cycles();
        while let Some(byte) = self.avr.uart0().try_read_byte() {
            self.rx.push(RxByte {
                cycle: self.cycle,
                byte,
            });
        }
    }

    /// Run until at least cycle `cycle`.
    pub fn run_until(&mut self, cycle: u64) {
        while self.cycle < cycle {
            self.step();
        }
    }

    /// Run for `us` microseconds.
    pub fn run_for_us(&mut self, us: u64) {
        self.run_until(self.cycle + us * CYCLES_PER_US);
    }

    /// Run for `ms` milliseconds.
    pub fn run_for_ms(&mut self, ms: u64) {
        self.run_until(self.cycle + ms * CYCLES_PER_MS);
    }

    /// Run until `done` holds for the received bytes, at most `limit_cycles` more cycles.
    /// Returns whether it held.
    pub fn run_until_rx(
        &mut self,
        limit_cycles: u64,
        mut done: impl FnMut(&[RxByte]) -> bool,
    ) -> bool {
        let end = self.cycle + limit_cycles;
        while !done(&self.rx) {
            if self.cycle >= end {
                return false;
            }
            self.step();
        }
        true
    }

    /// Run until the firmware has completed `count` telemetry batches in all, at most
    /// `limit_cycles` more cycles. Returns whether it did.
    pub fn run_until_telemetry_batches(&mut self, count: usize, limit_cycles: u64) -> bool {
        let end = self.cycle + limit_cycles;
        loop {
            // Decoding everything is linear in the bytes received; do it only when the last
            // byte may have completed a checksum frame (a `z` eight bytes earlier).
            let closes_batch = self.rx.len() >= 9 && self.rx[self.rx.len() - 9].byte == b'z';
            if closes_batch && self.telemetry_batches().len() >= count {
                return true;
            }
            if self.cycle >= end {
                return false;
            }
            let before = self.rx.len();
            while self.rx.len() == before && self.cycle < end {
                self.step();
            }
        }
    }

    /// Queue bytes for the firmware's receiver; simavr delivers them at the line rate.
    pub fn send(&mut self, bytes: &[u8]) {
        self.avr.uart0().write(bytes);
    }

    /// Every byte received so far.
    pub fn rx(&self) -> &[RxByte] {
        &self.rx
    }

    /// Every complete frame received so far.
    pub fn frames(&self) -> Vec<TimedFrame> {
        timed_frames(&self.rx)
    }

    /// Every batch (closed by `z`) received so far.
    pub fn batches(&self) -> Vec<TimedBatch> {
        batches(&self.frames())
    }

    /// Every complete telemetry batch (`g h i j k s q x z`) received so far, parsed.
    pub fn telemetry_batches(&self) -> Vec<(u64, TelemetryBatch)> {
        self.batches()
            .iter()
            .filter(|b| b.is_telemetry())
            .filter_map(|b| TelemetryBatch::parse(b).ok().map(|t| (b.cycle, t)))
            .collect()
    }

    /// The latest complete telemetry batch, if any.
    pub fn latest_telemetry(&self) -> Option<TelemetryBatch> {
        self.telemetry_batches().last().map(|(_, t)| *t)
    }

    /// The encoder lines as the test drives them.
    pub fn lines(&self) -> &EncoderLines {
        &self.lines
    }

    /// Change the encoder lines and drive the changed `PINA` bits.
    pub fn update_lines(&mut self, change: impl FnOnce(&mut EncoderLines)) {
        change(&mut self.lines);
        let pina = self.lines.pina();
        let changed = pina ^ self.driven_pina;
        for bit in 0..8 {
            if changed & (1 << bit) != 0 {
                self.set_pa(bit, pina & (1 << bit) != 0);
            }
        }
        self.driven_pina = pina;
    }

    /// Move encoder `wheel` one edge.
    pub fn step_encoder(&mut self, wheel: usize, forward: bool) {
        self.update_lines(|lines| lines.step(wheel, forward));
    }

    fn set_pa(&mut self, bit: u8, high: bool) {
        let mut pins = self.avr.pins();
        let mut pin = match bit {
            0 => pins.pa0(),
            1 => pins.pa1(),
            2 => pins.pa2(),
            3 => pins.pa3(),
            4 => pins.pa4(),
            5 => pins.pa5(),
            6 => pins.pa6(),
            _ => pins.pa7(),
        };
        pin.set(high);
    }

    /// Press (pin 53 = PB0 low) or release (high) the box switch.
    pub fn set_switch_pressed(&mut self, pressed: bool) {
        self.avr.pins().pb0().set(!pressed);
    }

    /// The solenoid output (pin 30 = PC7) is driven high.
    pub fn solenoid_on(&mut self) -> bool {
        let mut pins = self.avr.pins();
        let mut pin = pins.pc7();
        pin.is_output() && pin.is_high()
    }

    /// The simulated motor shield.
    pub fn shield(&self) -> Ref<'_, Pca9685> {
        self.shield.borrow()
    }
}
