//! The Adafruit Motor Shield V2 seen through its PCA9685: which channels drive which motor,
//! and the signed PWM / voltage they amount to.
//!
//! Each DC-motor port has a PWM channel (speed) and two logic channels IN1/IN2 (direction)
//! into a TB6612 H-bridge (Adafruit_MotorShield.cpp, `getMotor`): M1 = PWM 8, IN2 9, IN1 10;
//! M2 = PWM 13, IN2 12, IN1 11; M3 = PWM 2, IN2 3, IN1 4; M4 = PWM 7, IN2 6, IN1 5. The
//! library's `FORWARD` sets IN1 high and IN2 low, `BACKWARD` the opposite, `RELEASE` both
//! low; `setSpeed(s)` writes a 12-bit duty of `s · 16`, so the 8-bit PWM is
//! `high_steps / 16`. The firmware maps motor index k to port M(k+1).
//!
//! Sign convention (the firmware's and the plant's): positive PWM = `FORWARD` = positive
//! wheel speed = encoder counting up.

use crate::pca9685::{ChannelOutput, Pca9685};
use ratf_protocol::messages::WHEEL_COUNT;

/// PCA9685 channels of one motor port.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PortChannels {
    /// Speed (PWM) channel.
    pub pwm: u8,
    /// IN1 channel (high = forward).
    pub in1: u8,
    /// IN2 channel (high = backward).
    pub in2: u8,
}

/// Channels of ports M1..M4, which are motors 0..3.
pub const MOTOR_PORTS: [PortChannels; WHEEL_COUNT] = [
    PortChannels {
        pwm: 8,
        in1: 10,
        in2: 9,
    },
    PortChannels {
        pwm: 13,
        in1: 11,
        in2: 12,
    },
    PortChannels {
        pwm: 2,
        in1: 4,
        in2: 3,
    },
    PortChannels {
        pwm: 7,
        in1: 5,
        in2: 6,
    },
];

/// Largest 8-bit PWM: the library's `uint8_t` speed.
pub const PWM_MAX: i16 = 255;
/// 12-bit duty of PWM 255: `setSpeed(255)` writes 255 · 16.
pub const FULL_SCALE_STEPS: f64 = 4080.0;
/// Battery voltage at full duty, V: 11.1 V, the 3S LiPo's nominal (original-system.md §2.2).
pub const BATTERY_VOLTAGE_V: f64 = 11.1;

/// What the H-bridge of one port does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bridge {
    /// IN1 high, IN2 low.
    Forward,
    /// IN2 high, IN1 low.
    Backward,
    /// Both low: the motor coasts.
    Release,
    /// Both high: short brake.
    Brake,
}

/// One motor's decoded drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorDrive {
    /// H-bridge state.
    pub bridge: Bridge,
    /// Speed channel output.
    pub pwm_channel: ChannelOutput,
}

impl MotorDrive {
    /// Decode motor `motor` (0..=3) from the chip's registers.
    pub fn read(chip: &Pca9685, motor: usize) -> Self {
        let port = MOTOR_PORTS[motor];
        let in1 = chip.channel(port.in1).is_high();
        let in2 = chip.channel(port.in2).is_high();
        let bridge = match (in1, in2) {
            (true, false) => Bridge::Forward,
            (false, true) => Bridge::Backward,
            (false, false) => Bridge::Release,
            (true, true) => Bridge::Brake,
        };
        Self {
            bridge,
            pwm_channel: chip.channel(port.pwm),
        }
    }

    /// Signed 8-bit PWM as the firmware commanded it: `±round(high_steps / 16)`, clamped to
    /// ±255; 0 when the bridge neither drives forward nor backward.
    pub fn signed_pwm(&self) -> i16 {
        let magnitude =
            ((f64::from(self.pwm_channel.high_steps) / 16.0).round() as i16).clamp(0, PWM_MAX);
        match self.bridge {
            Bridge::Forward => magnitude,
            Bridge::Backward => -magnitude,
            Bridge::Release | Bridge::Brake => 0,
        }
    }

    /// Motor terminal voltage, V: duty / (255 · 16) × 11.1 V with the bridge's sign,
    /// capped at the battery voltage (full-on is 4096 steps).
    pub fn voltage_v(&self) -> f64 {
        let fraction = (f64::from(self.pwm_channel.high_steps) / FULL_SCALE_STEPS).min(1.0);
        let magnitude_v = fraction * BATTERY_VOLTAGE_V;
        match self.bridge {
            Bridge::Forward => magnitude_v,
            Bridge::Backward => -magnitude_v,
            Bridge::Release | Bridge::Brake => 0.0,
        }
    }
}

/// Signed PWM of all four motors.
pub fn signed_pwms(chip: &Pca9685) -> [i16; WHEEL_COUNT] {
    std::array::from_fn(|k| MotorDrive::read(chip, k).signed_pwm())
}

/// Terminal voltage of all four motors, V.
pub fn voltages_v(chip: &Pca9685) -> [f64; WHEEL_COUNT] {
    std::array::from_fn(|k| MotorDrive::read(chip, k).voltage_v())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pca9685::{FULL_BIT, LED0_ON_L, MODE1, MODE1_AI};

    fn set(chip: &mut Pca9685, ch: u8, regs: [u8; 4]) {
        chip.start_write();
        chip.write_byte(LED0_ON_L + 4 * ch);
        for r in regs {
            chip.write_byte(r);
        }
        chip.stop();
    }

    fn adafruit_run(chip: &mut Pca9685, motor: usize, pwm: i16) {
        let port = MOTOR_PORTS[motor];
        let high = [0, FULL_BIT, 0, 0];
        let low = [0, 0, 0, 0];
        let (in1, in2) = match pwm.signum() {
            1 => (high, low),
            -1 => (low, high),
            _ => (low, low),
        };
        set(chip, port.in1, in1);
        set(chip, port.in2, in2);
        let duty = pwm.unsigned_abs() * 16;
        set(
            chip,
            port.pwm,
            [0, 0, (duty & 0xFF) as u8, (duty >> 8) as u8],
        );
    }

    #[test]
    fn adafruit_library_writes_decode_to_the_commanded_pwm() {
        let mut chip = Pca9685::new();
        chip.start_write();
        chip.write_byte(MODE1);
        chip.write_byte(MODE1_AI);
        chip.stop();
        let commanded = [255, -100, 1, -255];
        for (motor, &pwm) in commanded.iter().enumerate() {
            adafruit_run(&mut chip, motor, pwm);
        }
        assert_eq!(signed_pwms(&chip), commanded);
        let v = voltages_v(&chip);
        assert!((v[0] - 11.1).abs() < 1e-9);
        assert!((v[1] + 100.0 / 255.0 * 11.1).abs() < 1e-9);
        adafruit_run(&mut chip, 2, 0);
        assert_eq!(signed_pwms(&chip)[2], 0);
        assert_eq!(voltages_v(&chip)[2], 0.0);
    }

    #[test]
    fn power_on_is_released() {
        let chip = Pca9685::new();
        assert_eq!(signed_pwms(&chip), [0; 4]);
        assert_eq!(MotorDrive::read(&chip, 0).bridge, Bridge::Release);
    }
}
