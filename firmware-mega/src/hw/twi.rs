//! TWI (I2C) master on pins 20 (SDA, PD1) and 21 (SCL, PD0), implementing embedded-hal 1.0
//! `I2c` with 7-bit addresses, polled, at `board::I2C_BUS_HZ` (400 kHz).
//!
//! Every wait for the hardware is bounded by `board::I2C_WAIT_POLLS` polls, so a missing
//! shield (address NACK), a stuck bus or lost arbitration ends the transfer with an error
//! instead of hanging the main loop. After a timeout the TWI unit is reset (disabled and
//! re-enabled), which releases the pins; the caller decides when to retry.
//!
//! Status codes and the register protocol: ATmega2560 datasheet §24.6 (tables 24-2, 24-3).

use crate::board::{I2C_TWBR, I2C_WAIT_POLLS};
use avr_device::atmega2560::TWI;
use embedded_hal::i2c::{self, ErrorKind, NoAcknowledgeSource, Operation, SevenBitAddress};

/// TWCR bits (datasheet §24.9.2).
const TWINT: u8 = 1 << 7;
const TWEA: u8 = 1 << 6;
const TWSTA: u8 = 1 << 5;
const TWSTO: u8 = 1 << 4;
const TWEN: u8 = 1 << 2;

/// TWSR status codes, prescaler bits masked (datasheet tables 24-2 and 24-3).
const START: u8 = 0x08;
const REPEATED_START: u8 = 0x10;
const WRITE_ADDRESS_ACK: u8 = 0x18;
const WRITE_ADDRESS_NACK: u8 = 0x20;
const WRITE_DATA_ACK: u8 = 0x28;
const WRITE_DATA_NACK: u8 = 0x30;
const ARBITRATION_LOST: u8 = 0x38;
const READ_ADDRESS_ACK: u8 = 0x40;
const READ_ADDRESS_NACK: u8 = 0x48;
const READ_DATA_ACK: u8 = 0x50;
const READ_DATA_NACK: u8 = 0x58;

/// Why a transfer failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TwiError {
    /// The hardware did not finish a step within `I2C_WAIT_POLLS` polls (bus stuck or held).
    Timeout,
    /// Another master won arbitration.
    ArbitrationLost,
    /// No device acknowledged the address.
    AddressNack,
    /// The device did not acknowledge a data byte.
    DataNack,
    /// The TWI reported a status this master does not expect (the value, masked).
    UnexpectedStatus(u8),
}

impl i2c::Error for TwiError {
    fn kind(&self) -> ErrorKind {
        match self {
            TwiError::Timeout | TwiError::UnexpectedStatus(_) => ErrorKind::Bus,
            TwiError::ArbitrationLost => ErrorKind::ArbitrationLoss,
            TwiError::AddressNack => ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address),
            TwiError::DataNack => ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data),
        }
    }
}

/// The TWI master.
pub struct Twi {
    twi: TWI,
}

impl Twi {
    /// Configure the bit rate (prescaler 1, `TWBR` = `board::I2C_TWBR`) and enable the unit.
    /// The board's shield has its own pull-ups on SDA/SCL; the internal ones are not used.
    pub fn new(twi: TWI) -> Self {
        twi.twsr().write(|w| w.twps().prescaler_1());
        twi.twbr().write(|w| w.set(I2C_TWBR));
        let mut this = Self { twi };
        this.control(TWEN);
        this
    }

    fn control(&mut self, bits: u8) {
        // SAFETY: every TWCR bit pattern is a defined command (datasheet §24.9.2); the ones
        // written here are the documented START/STOP/data/ACK commands with TWEN set, or 0.
        self.twi.twcr().write(|w| unsafe { w.bits(bits) });
    }

    fn status(&self) -> u8 {
        self.twi.twsr().read().bits() & 0xF8
    }

    /// Wait (bounded) for the current step to finish; returns the status.
    fn wait(&mut self) -> Result<u8, TwiError> {
        for _ in 0..I2C_WAIT_POLLS {
            if self.twi.twcr().read().bits() & TWINT != 0 {
                return Ok(self.status());
            }
        }
        Err(TwiError::Timeout)
    }

    fn start(&mut self, address: SevenBitAddress, read: bool) -> Result<(), TwiError> {
        self.control(TWINT | TWSTA | TWEN);
        match self.wait()? {
            START | REPEATED_START => {}
            ARBITRATION_LOST => return Err(TwiError::ArbitrationLost),
            other => return Err(TwiError::UnexpectedStatus(other)),
        }
        self.twi
            .twdr()
            .write(|w| w.set((address << 1) | u8::from(read)));
        self.control(TWINT | TWEN);
        match self.wait()? {
            WRITE_ADDRESS_ACK | READ_ADDRESS_ACK => Ok(()),
            WRITE_ADDRESS_NACK | READ_ADDRESS_NACK => Err(TwiError::AddressNack),
            ARBITRATION_LOST => Err(TwiError::ArbitrationLost),
            other => Err(TwiError::UnexpectedStatus(other)),
        }
    }

    fn write_byte(&mut self, byte: u8) -> Result<(), TwiError> {
        self.twi.twdr().write(|w| w.set(byte));
        self.control(TWINT | TWEN);
        match self.wait()? {
            WRITE_DATA_ACK => Ok(()),
            WRITE_DATA_NACK => Err(TwiError::DataNack),
            ARBITRATION_LOST => Err(TwiError::ArbitrationLost),
            other => Err(TwiError::UnexpectedStatus(other)),
        }
    }

    fn read_byte(&mut self, ack: bool) -> Result<u8, TwiError> {
        self.control(TWINT | TWEN | if ack { TWEA } else { 0 });
        match self.wait()? {
            READ_DATA_ACK | READ_DATA_NACK => Ok(self.twi.twdr().read().bits()),
            ARBITRATION_LOST => Err(TwiError::ArbitrationLost),
            other => Err(TwiError::UnexpectedStatus(other)),
        }
    }

    /// Send STOP and wait (bounded) for it to go out; on timeout, reset the unit.
    fn stop(&mut self) {
        self.control(TWINT | TWSTO | TWEN);
        for _ in 0..I2C_WAIT_POLLS {
            if self.twi.twcr().read().bits() & TWSTO == 0 {
                return;
            }
        }
        self.reset();
    }

    /// Disable and re-enable the unit: releases SDA/SCL and clears its state machine.
    fn reset(&mut self) {
        self.control(0);
        self.control(TWEN);
    }

    fn run(
        &mut self,
        address: SevenBitAddress,
        operations: &mut [Operation<'_>],
    ) -> Result<(), TwiError> {
        let mut previous_was_read: Option<bool> = None;
        let count = operations.len();
        for index in 0..count {
            let next_is_read = operations
                .get(index + 1)
                .map(|op| matches!(op, Operation::Read(_)));
            match &mut operations[index] {
                Operation::Write(bytes) => {
                    if previous_was_read != Some(false) {
                        self.start(address, false)?;
                    }
                    for &byte in bytes.iter() {
                        self.write_byte(byte)?;
                    }
                    previous_was_read = Some(false);
                }
                Operation::Read(buffer) => {
                    if previous_was_read != Some(true) {
                        self.start(address, true)?;
                    }
                    let len = buffer.len();
                    for (i, slot) in buffer.iter_mut().enumerate() {
                        // NACK the last byte before a STOP or a repeated START.
                        let last = i + 1 == len && next_is_read != Some(true);
                        *slot = self.read_byte(!last)?;
                    }
                    previous_was_read = Some(true);
                }
            }
        }
        Ok(())
    }
}

impl i2c::ErrorType for Twi {
    type Error = TwiError;
}

impl i2c::I2c<SevenBitAddress> for Twi {
    fn transaction(
        &mut self,
        address: SevenBitAddress,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        let result = self.run(address, operations);
        match result {
            Err(TwiError::Timeout) => self.reset(),
            _ => self.stop(),
        }
        result
    }
}
