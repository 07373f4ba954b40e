//! A simulated PCA9685 16-channel PWM controller, register-exact enough for the Adafruit
//! Motor Shield V2 (the robot's motor driver, original-system.md §2.1).
//!
//! [`Pca9685`] is the pure register file: it takes the TWI events the firmware's master
//! generates (start with an address byte, written bytes, reads, stop) and updates its 256
//! registers as the datasheet (NXP PCA9685 rev. 4, §7.3) says:
//!
//! - the first byte written after the address selects the register pointer;
//! - each further byte is stored at the pointer, which advances only when MODE1 bit 5
//!   (`AI`, auto-increment) is set — a firmware that forgets `AI` writes every byte of a
//!   4-byte `LED_ON_L..LED_OFF_H` burst into `LED_ON_L`, as the real chip would;
//! - reads return the register at the pointer (auto-incremented the same way);
//! - the outputs follow the LED registers at the I2C STOP (MODE2 bit 3 `OCH` = 0, the
//!   power-on default) or at every byte's ACK (`OCH` = 1), datasheet §7.3.2: a channel
//!   never shows a half-written 4-byte update.
//!
//! [`Pca9685Slave`] adapts it to avr-tester's `TwiSlave` (simavr's TWI messages). Every
//! register write is also counted, so a test can tell "the firmware wrote 0" from "the
//! firmware never wrote".

use avr_tester::{TwiPacket, TwiSlave};
use std::cell::RefCell;
use std::rc::Rc;

/// The shield's 7-bit I2C address: 0x60, the Adafruit Motor Shield V2 default (no address
/// jumpers soldered).
pub const SHIELD_ADDRESS_7BIT: u8 = 0x60;
/// MODE1 register address (datasheet §7.3.1).
pub const MODE1: u8 = 0x00;
/// MODE1 auto-increment bit (`AI`, bit 5).
pub const MODE1_AI: u8 = 1 << 5;
/// Address of channel 0's `LED_ON_L`; channel `ch` starts at `0x06 + 4·ch` (§7.3.3).
pub const LED0_ON_L: u8 = 0x06;
/// Bit 4 of `LED_ON_H`: the channel is fully on. Bit 4 of `LED_OFF_H`: fully off (wins).
pub const FULL_BIT: u8 = 1 << 4;
/// MODE2 register address (datasheet §7.3.2).
pub const MODE2: u8 = 0x01;
/// MODE2 `OCH` bit (bit 3): 0 = outputs change on STOP, 1 = on ACK.
pub const MODE2_OCH: u8 = 1 << 3;
/// Counter steps in one PWM period (12-bit counter).
pub const PWM_STEPS: u16 = 4096;

/// One channel's output as decoded from its four registers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChannelOutput {
    /// Steps per 4096-step period the output is high (0..=4096; 4096 = full on).
    pub high_steps: u16,
}

impl ChannelOutput {
    /// True when the output is high for more than half of the period: how a logic input
    /// (the TB6612's IN1/IN2) driven by this channel reads it.
    pub fn is_high(self) -> bool {
        self.high_steps > PWM_STEPS / 2
    }

    /// Duty cycle, 0.0..=1.0.
    pub fn duty(self) -> f64 {
        f64::from(self.high_steps) / f64::from(PWM_STEPS)
    }
}

/// The PCA9685 register file and its I2C transaction state.
#[derive(Clone, Debug)]
pub struct Pca9685 {
    registers: [u8; 256],
    /// The registers as the outputs last latched them.
    latched: [u8; 256],
    pointer: u8,
    /// Within a write transaction: the next byte written is the register pointer.
    expecting_pointer: bool,
    register_writes: u64,
    transactions: u64,
}

impl Default for Pca9685 {
    fn default() -> Self {
        Self::new()
    }
}

impl Pca9685 {
    /// The power-on state: MODE1 = 0x11 (`SLEEP` and `ALLCALL`), every channel fully off
    /// (`LED_OFF_H` = 0x10), as the datasheet's register table gives.
    pub fn new() -> Self {
        let mut registers = [0u8; 256];
        registers[usize::from(MODE1)] = 0x11;
        registers[usize::from(MODE2)] = 0x04;
        for ch in 0..16u8 {
            registers[usize::from(LED0_ON_L + 4 * ch + 3)] = FULL_BIT;
        }
        registers[0xFE] = 0x1E;
        Self {
            registers,
            latched: registers,
            pointer: 0,
            expecting_pointer: false,
            register_writes: 0,
            transactions: 0,
        }
    }

    /// A write transaction addressed to this chip has started.
    pub fn start_write(&mut self) {
        self.expecting_pointer = true;
        self.transactions += 1;
    }

    /// A read transaction addressed to this chip has started (the pointer is kept).
    pub fn start_read(&mut self) {
        self.expecting_pointer = false;
        self.transactions += 1;
    }

    /// A byte written by the master inside a write transaction.
    pub fn write_byte(&mut self, byte: u8) {
        if self.expecting_pointer {
            self.pointer = byte;
            self.expecting_pointer = false;
            return;
        }
        self.registers[usize::from(self.pointer)] = byte;
        self.register_writes += 1;
        if self.registers[usize::from(MODE2)] & MODE2_OCH != 0 {
            self.latched = self.registers;
        }
        self.advance_pointer();
    }

    /// The master ended the transaction (STOP): the outputs take the new register values.
    pub fn stop(&mut self) {
        self.latched = self.registers;
    }

    /// A byte read by the master inside a read transaction.
    pub fn read_byte(&mut self) -> u8 {
        let byte = self.registers[usize::from(self.pointer)];
        self.advance_pointer();
        byte
    }

    fn advance_pointer(&mut self) {
        if self.registers[usize::from(MODE1)] & MODE1_AI != 0 {
            // The datasheet's auto-increment wraps from 0x45 (LED15_OFF_H) / 0xFF to 0.
            self.pointer = self.pointer.wrapping_add(1);
        }
    }

    /// The value of register `address`.
    pub fn register(&self, address: u8) -> u8 {
        self.registers[usize::from(address)]
    }

    /// Register writes received so far (pointer bytes excluded).
    pub fn register_writes(&self) -> u64 {
        self.register_writes
    }

    /// Transactions addressed to this chip so far.
    pub fn transactions(&self) -> u64 {
        self.transactions
    }

    /// Channel `ch`'s (0..=15) output as last latched, decoded as the datasheet's §7.3.3
    /// says: full off wins over full on, full on wins over the counts, otherwise high from
    /// `ON` to `OFF` (modulo 4096).
    pub fn channel(&self, ch: u8) -> ChannelOutput {
        let base = usize::from(LED0_ON_L + 4 * (ch & 0x0F));
        let on_l = self.latched[base];
        let on_h = self.latched[base + 1];
        let off_l = self.latched[base + 2];
        let off_h = self.latched[base + 3];
        let high_steps = if off_h & FULL_BIT != 0 {
            0
        } else if on_h & FULL_BIT != 0 {
            PWM_STEPS
        } else {
            let on = u16::from(on_l) | (u16::from(on_h & 0x0F) << 8);
            let off = u16::from(off_l) | (u16::from(off_h & 0x0F) << 8);
            off.wrapping_sub(on) & (PWM_STEPS - 1)
        };
        ChannelOutput { high_steps }
    }
}

/// avr-tester TWI slave answering at [`SHIELD_ADDRESS_7BIT`], sharing its [`Pca9685`]
/// with the test through `Rc<RefCell<_>>` (the simulator owns the slave).
pub struct Pca9685Slave {
    chip: Rc<RefCell<Pca9685>>,
}

impl Pca9685Slave {
    /// A slave driving `chip`.
    pub fn new(chip: Rc<RefCell<Pca9685>>) -> Self {
        Self { chip }
    }
}

impl TwiSlave for Pca9685Slave {
    fn recv(&mut self, packet: TwiPacket) -> Option<TwiPacket> {
        // simavr passes the 8-bit address byte (7-bit address << 1 | R/W).
        if packet.addr >> 1 != SHIELD_ADDRESS_7BIT {
            return None;
        }
        let mut chip = self.chip.borrow_mut();
        if packet.is_start() {
            if packet.addr & 1 == 0 {
                chip.start_write();
            } else {
                chip.start_read();
            }
            return Some(packet.respond_ack());
        }
        if packet.is_stop() {
            chip.stop();
            return Some(packet.respond_ack());
        }
        if packet.is_write() {
            chip.write_byte(packet.data);
            return Some(packet.respond_ack());
        }
        if packet.is_read() {
            return Some(packet.respond_data(chip.read_byte()));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(chip: &mut Pca9685, bytes: &[u8]) {
        chip.start_write();
        for &b in bytes {
            chip.write_byte(b);
        }
        chip.stop();
    }

    #[test]
    fn power_on_channels_are_off() {
        let chip = Pca9685::new();
        for ch in 0..16 {
            assert_eq!(chip.channel(ch).high_steps, 0);
        }
    }

    #[test]
    fn auto_increment_burst_sets_a_channel() {
        let mut chip = Pca9685::new();
        write(&mut chip, &[MODE1, MODE1_AI]);
        // Channel 8: ON = 0, OFF = 2040 (= 127.5 · 16).
        write(&mut chip, &[LED0_ON_L + 32, 0, 0, 0xF8, 0x07]);
        assert_eq!(chip.channel(8).high_steps, 2040);
        assert!(!chip.channel(8).is_high());
        assert_eq!(chip.register_writes(), 5);
    }

    #[test]
    fn without_auto_increment_bytes_land_on_one_register() {
        let mut chip = Pca9685::new();
        write(&mut chip, &[MODE1, 0x00]);
        write(&mut chip, &[LED0_ON_L + 32, 1, 2, 3, 4]);
        assert_eq!(chip.register(LED0_ON_L + 32), 4);
        assert_eq!(chip.register(LED0_ON_L + 33), 0);
    }

    #[test]
    fn full_off_wins_over_full_on() {
        let mut chip = Pca9685::new();
        write(&mut chip, &[MODE1, MODE1_AI]);
        write(&mut chip, &[LED0_ON_L + 4 * 10, 0, FULL_BIT, 0, 0]);
        assert_eq!(chip.channel(10).high_steps, PWM_STEPS);
        assert!(chip.channel(10).is_high());
        write(&mut chip, &[LED0_ON_L + 4 * 10 + 3, FULL_BIT]);
        assert_eq!(chip.channel(10).high_steps, 0);
    }

    #[test]
    fn counts_wrap_modulo_4096() {
        let mut chip = Pca9685::new();
        write(&mut chip, &[MODE1, MODE1_AI]);
        // ON = 4000, OFF = 100: high for 196 steps across the wrap.
        write(&mut chip, &[LED0_ON_L, 0xA0, 0x0F, 100, 0]);
        assert_eq!(chip.channel(0).high_steps, 196);
    }

    #[test]
    fn outputs_change_at_stop_unless_och_is_set() {
        let mut chip = Pca9685::new();
        write(&mut chip, &[MODE1, MODE1_AI]);
        chip.start_write();
        for b in [LED0_ON_L, 0, 0, 0x00, 0x08] {
            chip.write_byte(b);
        }
        assert_eq!(chip.channel(0).high_steps, 0, "changed before STOP");
        chip.stop();
        assert_eq!(chip.channel(0).high_steps, 2048);
        write(&mut chip, &[MODE2, MODE2_OCH]);
        chip.start_write();
        for b in [LED0_ON_L + 3, 0x04] {
            chip.write_byte(b);
        }
        assert_eq!(chip.channel(0).high_steps, 1024, "OCH = 1 changes on ACK");
    }

    #[test]
    fn reads_return_registers() {
        let mut chip = Pca9685::new();
        write(&mut chip, &[MODE1]);
        chip.start_read();
        assert_eq!(chip.read_byte(), 0x11);
    }
}
