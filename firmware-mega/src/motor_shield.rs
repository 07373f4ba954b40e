//! The Adafruit Motor Shield V2 (a PCA9685 16-channel PWM controller driving two TB6612
//! H-bridges), over any embedded-hal 1.0 `I2c`.
//!
//! The register bytes are computed by plain functions ([`init_writes`], [`motor_write`]) so
//! they are easy to check against the datasheet; [`MotorShield`] only sends them, writes
//! only motors whose PWM changed, and counts failed transfers.
//!
//! Sources: PCA9685 datasheet (NXP, rev. 4) §7.3 (registers), §7.3.1 (MODE1), §7.3.3 (LED
//! output and full on/off bits), §7.3.5 (PRE_SCALE); the channel wiring of the shield's
//! M1..M4 as used by the Adafruit_MotorShield library's `getMotor()` (see
//! `hardware/pinmap.md`).

use crate::board::{MOTOR_PWM_HZ, MOTOR_SHIELD_I2C_ADDRESS};
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;

/// Motors on the shield.
pub const MOTORS: usize = 4;

/// MODE1 register address.
const MODE1: u8 = 0x00;
/// PRE_SCALE register address.
const PRE_SCALE: u8 = 0xFE;
/// LED0_ON_L: channel `n`'s four registers start at `LED0_ON_L + 4n`.
const LED0_ON_L: u8 = 0x06;
/// ALL_LED_OFF_H: writing bit 4 turns every channel fully off.
const ALL_LED_OFF_H: u8 = 0xFD;

/// MODE1 bits: RESTART, AI (register auto-increment), SLEEP, ALLCALL.
const MODE1_RESTART: u8 = 0x80;
const MODE1_AI: u8 = 0x20;
const MODE1_SLEEP: u8 = 0x10;
const MODE1_ALLCALL: u8 = 0x01;
/// The full-on / full-off bit in LEDn_ON_H / LEDn_OFF_H.
const FULL: u8 = 0x10;

/// The PCA9685's internal oscillator, Hz (datasheet §7.3.5).
const OSCILLATOR_HZ: u32 = 25_000_000;
/// PRE_SCALE for `MOTOR_PWM_HZ`: round(25 MHz / (4096 × 1600)) − 1 = round(3.81) − 1 = 3
/// (datasheet equation 1), which gives 25 MHz / (4096 × 4) = 1526 Hz.
pub const PRESCALE: u8 = ((OSCILLATOR_HZ + 2048 * MOTOR_PWM_HZ) / (4096 * MOTOR_PWM_HZ) - 1) as u8;
const _: () = assert!(PRESCALE == 3);

/// Wait after waking the oscillator before restarting the outputs, µs (datasheet §7.3.1:
/// "500 µs max").
pub const OSCILLATOR_WAKE_US: u32 = 500;

/// The PCA9685 channels of one shield motor port.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MotorChannels {
    /// Speed (PWM) channel, to the H-bridge's PWM input.
    pub pwm: u8,
    /// Direction input IN1 (high for forward).
    pub in1: u8,
    /// Direction input IN2 (high for backward).
    pub in2: u8,
}

/// Channels of shield ports M1..M4 (Adafruit_MotorShield `getMotor()`). Motor index `k`
/// of the protocol drives port M`k+1`: 0 → M1 back-right, 1 → M2 back-left, 2 → M3
/// front-right, 3 → M4 front-left (original-system.md §2.1).
pub const CHANNELS: [MotorChannels; MOTORS] = [
    MotorChannels {
        pwm: 8,
        in2: 9,
        in1: 10,
    },
    MotorChannels {
        pwm: 13,
        in2: 12,
        in1: 11,
    },
    MotorChannels {
        pwm: 2,
        in2: 3,
        in1: 4,
    },
    MotorChannels {
        pwm: 7,
        in2: 6,
        in1: 5,
    },
];

/// Register bytes of one channel: LEDn_ON_L, ON_H, OFF_L, OFF_H for a 12-bit duty 0..=4096
/// (4096 = full on, 0 = full off, datasheet §7.3.3).
pub const fn channel_bytes(duty: u16) -> [u8; 4] {
    if duty >= 4096 {
        [0, FULL, 0, 0]
    } else if duty == 0 {
        [0, 0, 0, FULL]
    } else {
        [0, 0, (duty & 0xFF) as u8, (duty >> 8) as u8]
    }
}

/// The 12-bit duty of a PWM magnitude 0..=255: ×16 (the Adafruit library's `setSpeed`),
/// except that 255 is full on (the library's 255 × 16 = 4080 leaves the output 0.4 % off).
pub const fn duty_of(pwm_magnitude: u8) -> u16 {
    if pwm_magnitude == u8::MAX {
        4096
    } else {
        pwm_magnitude as u16 * 16
    }
}

/// Length of one motor write: the first register address and 3 channels × 4 bytes.
pub const MOTOR_WRITE_LEN: usize = 13;

/// The single auto-incremented write that sets motor `motor` (0..4) to signed `pwm`
/// (clamped to ±255). The three channels of every port are consecutive, so one write starting
/// at the lowest covers them. Positive = forward (IN1 high, IN2 low), negative = backward,
/// 0 = released (both low, PWM off: the motor coasts), as the Adafruit library's
/// `run(FORWARD/BACKWARD/RELEASE)` and `setSpeed`.
pub fn motor_write(motor: usize, pwm: i16) -> [u8; MOTOR_WRITE_LEN] {
    let channels = CHANNELS[motor % MOTORS];
    let magnitude = pwm.unsigned_abs().min(255) as u8;
    let (in1, in2) = match pwm {
        0 => (0, 0),
        p if p > 0 => (4096, 0),
        _ => (0, 4096),
    };
    let first = channels.pwm.min(channels.in1).min(channels.in2);
    let mut bytes = [0u8; MOTOR_WRITE_LEN];
    bytes[0] = LED0_ON_L + 4 * first;
    for (channel, duty) in [
        (channels.pwm, duty_of(magnitude)),
        (channels.in1, in1),
        (channels.in2, in2),
    ] {
        let offset = 1 + 4 * usize::from(channel - first);
        bytes[offset..offset + 4].copy_from_slice(&channel_bytes(duty));
    }
    bytes
}

/// The register writes that initialise the shield, in order, and whether the oscillator
/// wake delay must follow each: all outputs off; sleep (PRE_SCALE is writable only in
/// sleep) with auto-increment; PRE_SCALE; wake; then, after [`OSCILLATOR_WAKE_US`],
/// RESTART with auto-increment.
pub const fn init_writes() -> [([u8; 2], bool); 5] {
    [
        ([ALL_LED_OFF_H, FULL], false),
        ([MODE1, MODE1_SLEEP | MODE1_AI | MODE1_ALLCALL], false),
        ([PRE_SCALE, PRESCALE], false),
        ([MODE1, MODE1_AI | MODE1_ALLCALL], true),
        ([MODE1, MODE1_RESTART | MODE1_AI | MODE1_ALLCALL], false),
    ]
}

/// The shield driver: see the module documentation.
pub struct MotorShield<I> {
    i2c: I,
    /// Last PWM written successfully per motor; `None` = unknown (not yet written, or the
    /// shield needs initialising).
    written: [Option<i16>; MOTORS],
    initialised: bool,
    faults: u16,
}

impl<I: I2c> MotorShield<I> {
    /// A driver for a shield not yet initialised (the first [`MotorShield::apply`] does it).
    pub fn new(i2c: I) -> Self {
        Self {
            i2c,
            written: [None; MOTORS],
            initialised: false,
            faults: 0,
        }
    }

    /// Failed transfers since boot (wrapping): reported on telemetry channel `x`.
    pub fn faults(&self) -> u16 {
        self.faults
    }

    fn fault(&mut self) {
        self.faults = self.faults.wrapping_add(1);
        self.initialised = false;
        self.written = [None; MOTORS];
    }

    fn initialise(&mut self, delay: &mut impl DelayNs) -> bool {
        for (bytes, then_wait) in init_writes() {
            if self.i2c.write(MOTOR_SHIELD_I2C_ADDRESS, &bytes).is_err() {
                self.fault();
                return false;
            }
            if then_wait {
                delay.delay_us(OSCILLATOR_WAKE_US);
            }
        }
        self.initialised = true;
        true
    }

    /// Drive the motors to `pwm` (motor index order). Initialises the shield first if it is
    /// not (at boot, or after a fault: a failed transfer makes the next call start over);
    /// then writes only the motors whose PWM changed. Stops at the first failed transfer,
    /// which is counted; never waits longer than the TWI's bounded timeouts.
    pub fn apply(&mut self, pwm: [i16; MOTORS], delay: &mut impl DelayNs) {
        if !self.initialised && !self.initialise(delay) {
            return;
        }
        for (motor, &target) in pwm.iter().enumerate() {
            if self.written[motor] == Some(target) {
                continue;
            }
            if self
                .i2c
                .write(MOTOR_SHIELD_I2C_ADDRESS, &motor_write(motor, target))
                .is_err()
            {
                self.fault();
                return;
            }
            self.written[motor] = Some(target);
        }
    }
}

// Compile-time checks of the byte layout against the datasheet and the channel map.
const _: () = {
    let on = channel_bytes(4096);
    let off = channel_bytes(0);
    let half = channel_bytes(2048);
    assert!(on[1] == FULL && off[3] == FULL && half[2] == 0 && half[3] == 8);
    assert!(duty_of(1) == 16 && duty_of(254) == 4064 && duty_of(255) == 4096);
};

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal::i2c::{ErrorKind, ErrorType, NoAcknowledgeSource, Operation};
    use std::vec::Vec;

    /// The value of channel `channel`'s four registers in a motor write.
    fn channel_in(write: &[u8; MOTOR_WRITE_LEN], channel: u8) -> [u8; 4] {
        let first = (write[0] - LED0_ON_L) / 4;
        let offset = 1 + 4 * usize::from(channel - first);
        write[offset..offset + 4].try_into().unwrap()
    }

    #[test]
    fn each_port_sets_pwm_and_direction_on_its_own_channels() {
        for (motor, channels) in CHANNELS.iter().enumerate() {
            let forward = motor_write(motor, 100);
            assert_eq!(channel_in(&forward, channels.pwm), channel_bytes(1600));
            assert_eq!(channel_in(&forward, channels.in1), channel_bytes(4096));
            assert_eq!(channel_in(&forward, channels.in2), channel_bytes(0));
            let backward = motor_write(motor, -255);
            assert_eq!(channel_in(&backward, channels.pwm), channel_bytes(4096));
            assert_eq!(channel_in(&backward, channels.in1), channel_bytes(0));
            assert_eq!(channel_in(&backward, channels.in2), channel_bytes(4096));
            let released = motor_write(motor, 0);
            for channel in [channels.pwm, channels.in1, channels.in2] {
                assert_eq!(channel_in(&released, channel), channel_bytes(0));
            }
        }
    }

    #[test]
    fn m1_forward_is_the_expected_register_bytes() {
        // M1: LED8 (PWM) = duty 0x640, LED9 (IN2) full off, LED10 (IN1) full on.
        assert_eq!(
            motor_write(0, 100),
            [0x26, 0, 0, 0x40, 0x06, 0, 0, 0, 0x10, 0, 0x10, 0, 0]
        );
    }

    #[test]
    fn out_of_range_pwm_is_clamped() {
        assert_eq!(motor_write(2, 1000), motor_write(2, 255));
        assert_eq!(motor_write(2, i16::MIN), motor_write(2, -255));
    }

    /// A fake bus: records writes, and fails the `fail_at`-th transfer (0-based) if set.
    #[derive(Default)]
    struct FakeBus {
        writes: Vec<Vec<u8>>,
        transfers: usize,
        fail_at: Option<usize>,
    }

    #[derive(Debug)]
    struct Nack;

    impl embedded_hal::i2c::Error for Nack {
        fn kind(&self) -> ErrorKind {
            ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address)
        }
    }

    impl ErrorType for FakeBus {
        type Error = Nack;
    }

    impl I2c for FakeBus {
        fn transaction(
            &mut self,
            address: u8,
            operations: &mut [Operation<'_>],
        ) -> Result<(), Nack> {
            assert_eq!(address, MOTOR_SHIELD_I2C_ADDRESS);
            let attempt = self.transfers;
            self.transfers += 1;
            if self.fail_at == Some(attempt) {
                return Err(Nack);
            }
            for operation in operations {
                if let Operation::Write(bytes) = operation {
                    self.writes.push(bytes.to_vec());
                }
            }
            Ok(())
        }
    }

    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _ns: u32) {}
    }

    #[test]
    fn first_apply_initialises_then_only_changed_motors_are_written() {
        let mut shield = MotorShield::new(FakeBus::default());
        shield.apply([0; MOTORS], &mut NoDelay);
        let init: Vec<Vec<u8>> = init_writes().iter().map(|(b, _)| b.to_vec()).collect();
        assert_eq!(shield.i2c.writes[..5], init[..]);
        assert_eq!(shield.i2c.writes.len(), 5 + MOTORS);
        shield.i2c.writes.clear();
        shield.apply([0, 50, 0, 0], &mut NoDelay);
        assert_eq!(shield.i2c.writes, [motor_write(1, 50).to_vec()]);
        shield.i2c.writes.clear();
        shield.apply([0, 50, 0, 0], &mut NoDelay);
        assert!(shield.i2c.writes.is_empty());
        assert_eq!(shield.faults(), 0);
    }

    #[test]
    fn a_fault_is_counted_and_the_next_apply_reinitialises() {
        let bus = FakeBus {
            fail_at: Some(6),
            ..FakeBus::default()
        };
        let mut shield = MotorShield::new(bus);
        shield.apply([10, 20, 30, 40], &mut NoDelay);
        // 5 init writes succeed, motor 0 succeeds, motor 1 fails: the call stops there.
        assert_eq!(shield.faults(), 1);
        assert_eq!(shield.i2c.writes.len(), 6);
        shield.i2c.writes.clear();
        shield.apply([10, 20, 30, 40], &mut NoDelay);
        assert_eq!(
            shield.i2c.writes.len(),
            5 + MOTORS,
            "re-init and all motors"
        );
        assert_eq!(shield.faults(), 1);
    }

    #[test]
    fn a_dead_bus_costs_one_transfer_per_apply() {
        struct DeadBus(usize);
        impl ErrorType for DeadBus {
            type Error = Nack;
        }
        impl I2c for DeadBus {
            fn transaction(&mut self, _: u8, _: &mut [Operation<'_>]) -> Result<(), Nack> {
                self.0 += 1;
                Err(Nack)
            }
        }
        let mut shield = MotorShield::new(DeadBus(0));
        for tick in 1..=3u16 {
            shield.apply([100; MOTORS], &mut NoDelay);
            assert_eq!(shield.faults(), tick);
        }
        assert_eq!(shield.i2c.0, 3);
    }
}
