//! Typed messages for every channel, both ways (original-system.md §2.6).
//!
//! Host → Mega ([`Command`], uppercase letters): `G H I J` wheel speed reference (IEEE-754
//! `f32` bits, wheel rad/s), `K` direct PWM (motor index in bits 24–25, signed `i16` PWM in
//! bits 0–15), `L` solenoid (0 or 1), `U` stop on the switch (0 or 1, ours: see
//! [`Command::StopOnSwitch`]).
//!
//! Mega → host ([`Telemetry`], lowercase letters): `g h i j` cumulative encoder ticks
//! (`i32`, wrapping), `k` measured control period (µs), `s` switch level (0 = pressed, as
//! the pin reads), `r` reset (sent at boot, value 0). Two diagnostics channels are ours:
//! `q` (invalid quadrature transitions) and `x` (fault counters). A peer that only speaks
//! the original protocol ignores them, as it ignores any unregistered channel.
//!
//! The controller settings `M`..`T` (host → Mega) and their acknowledgement `y` are ours
//! too; [`crate::settings`] describes them.
//!
//! The letters `Z` and `z` are reserved for the [`crate::integrity`] checksum frames.

use crate::channels::Frame;
use crate::settings::{SETTINGS_ACK_CHANNEL, Setting, SettingsAck};
use core::fmt;

/// A wheel, numbered as the firmware's motor index (original-system.md §2.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Wheel {
    /// Motor 0, shield port M1.
    BackRight = 0,
    /// Motor 1, shield port M2.
    BackLeft = 1,
    /// Motor 2, shield port M3.
    FrontRight = 2,
    /// Motor 3, shield port M4.
    FrontLeft = 3,
}

/// Number of wheels (and motors, and encoders).
pub const WHEEL_COUNT: usize = 4;

impl Wheel {
    /// All wheels in motor-index order.
    pub const ALL: [Wheel; WHEEL_COUNT] = [
        Wheel::BackRight,
        Wheel::BackLeft,
        Wheel::FrontRight,
        Wheel::FrontLeft,
    ];

    /// The wheel with motor index `index` (0..=3).
    pub const fn from_index(index: u8) -> Option<Self> {
        match index {
            0 => Some(Self::BackRight),
            1 => Some(Self::BackLeft),
            2 => Some(Self::FrontRight),
            3 => Some(Self::FrontLeft),
            _ => None,
        }
    }

    /// The motor index (0..=3), also the index into per-wheel arrays.
    pub const fn index(self) -> usize {
        self as usize
    }
}

/// Channel letters of the wheel speed references, by wheel index.
pub const WHEEL_SPEED_CHANNELS: [u8; WHEEL_COUNT] = *b"GHIJ";
/// Channel letters of the cumulative tick counts, by wheel index.
pub const TICKS_CHANNELS: [u8; WHEEL_COUNT] = *b"ghij";
/// Direct PWM channel.
pub const MOTOR_PWM_CHANNEL: u8 = b'K';
/// Solenoid channel.
pub const SOLENOID_CHANNEL: u8 = b'L';
/// Stop-on-switch channel (ours).
pub const STOP_ON_SWITCH_CHANNEL: u8 = b'U';
/// Measured control period channel.
pub const LOOP_PERIOD_CHANNEL: u8 = b'k';
/// Switch level channel.
pub const SWITCH_CHANNEL: u8 = b's';
/// Reset channel, sent once at boot.
pub const RESET_CHANNEL: u8 = b'r';
/// Invalid quadrature transitions channel (ours).
pub const QUADRATURE_ERRORS_CHANNEL: u8 = b'q';
/// Fault counters channel (ours).
pub const FAULTS_CHANNEL: u8 = b'x';

/// Why a frame is not a valid message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MessageError {
    /// No message of this direction uses this channel letter.
    UnknownChannel(u8),
    /// A `G`..`J` reference or an `M`..`T` setting is NaN or infinite (it would poison the
    /// controller).
    NotFinite {
        /// The channel letter.
        channel: u8,
    },
    /// Bits that must be zero are set (e.g. `K` outside bits 0–15 and 24–25).
    ReservedBits {
        /// The channel letter.
        channel: u8,
        /// The whole received value.
        value: u32,
    },
    /// A boolean channel (`L`, `s`) carries something other than 0 or 1.
    NotBoolean {
        /// The channel letter.
        channel: u8,
        /// The received value.
        value: u32,
    },
}

impl fmt::Display for MessageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::UnknownChannel(c) => write!(f, "no message uses channel '{}'", c as char),
            Self::NotFinite { channel } => {
                write!(
                    f,
                    "channel '{}' carries a non-finite float",
                    channel as char
                )
            }
            Self::ReservedBits { channel, value } => write!(
                f,
                "channel '{}' value 0x{value:08X} has reserved bits set",
                channel as char
            ),
            Self::NotBoolean { channel, value } => write!(
                f,
                "channel '{}' value {value} is not 0 or 1",
                channel as char
            ),
        }
    }
}

impl core::error::Error for MessageError {}

/// A message from the host to the Mega.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// `G`..`J`: closed-loop speed reference for one wheel, in wheel (gearbox output) rad/s.
    /// Enables that wheel's PI controller.
    WheelSpeed {
        /// The wheel.
        wheel: Wheel,
        /// Reference, wheel rad/s (positive = the motor's forward direction).
        speed_rad_s: f32,
    },
    /// `K`: open-loop PWM for one motor; disables that wheel's PI controller. The Mega clamps
    /// the magnitude to its PWM limit (255).
    MotorPwm {
        /// The wheel.
        wheel: Wheel,
        /// Signed PWM, negative = reverse.
        pwm: i16,
    },
    /// `L`: electromagnet on or off.
    Solenoid {
        /// True energises the electromagnet.
        on: bool,
    },
    /// `U` (ours): while armed, the Mega stops the wheels under speed control itself, at the
    /// control tick that first reads the box switch pressed, and holds their references at
    /// zero for [`crate::mcu::SWITCH_STOP_HOLD_US`] or until the host disarms it. The host arms it on the last stretch of a docking
    /// approach to a part, so the robot stops up to a telemetry batch, the host's tick, a
    /// command and a control period sooner than by the host's own reading of the switch
    /// (about 30 ms, some 2 mm at the approach's 6 cm/s), which is where its body met a
    /// neighbour standing proud (issue 11, the harsh world). An original Mega ignores it.
    StopOnSwitch {
        /// True arms the stop; false disarms it and frees a stop already made.
        armed: bool,
    },
    /// `M`..`T`: one controller setting ([`crate::settings`]). Decoding checks only that
    /// the value is finite; the Mega checks its range ([`Setting::validate`]).
    Setting {
        /// Which setting.
        setting: Setting,
        /// The value, in the setting's unit.
        value: f32,
    },
}

impl Command {
    /// The frame that carries this command.
    pub fn to_frame(&self) -> Frame {
        let (channel, value) = match *self {
            Self::WheelSpeed { wheel, speed_rad_s } => {
                (WHEEL_SPEED_CHANNELS[wheel.index()], speed_rad_s.to_bits())
            }
            Self::MotorPwm { wheel, pwm } => (
                MOTOR_PWM_CHANNEL,
                (u32::from(wheel as u8) << 24) | u32::from(pwm as u16),
            ),
            Self::Solenoid { on } => (SOLENOID_CHANNEL, u32::from(on)),
            Self::StopOnSwitch { armed } => (STOP_ON_SWITCH_CHANNEL, u32::from(armed)),
            Self::Setting { setting, value } => (setting.channel(), value.to_bits()),
        };
        // Every letter above is a valid channel letter.
        match Frame::new(channel, value) {
            Ok(frame) => frame,
            Err(_) => unreachable!(),
        }
    }

    /// The command a frame carries.
    pub fn from_frame(frame: Frame) -> Result<Self, MessageError> {
        let (channel, value) = (frame.channel(), frame.value());
        match channel {
            b'G'..=b'J' => {
                let speed_rad_s = f32::from_bits(value);
                if !speed_rad_s.is_finite() {
                    return Err(MessageError::NotFinite { channel });
                }
                let wheel = Wheel::ALL[usize::from(channel - b'G')];
                Ok(Self::WheelSpeed { wheel, speed_rad_s })
            }
            MOTOR_PWM_CHANNEL => {
                if value & !0x0300_FFFF != 0 {
                    return Err(MessageError::ReservedBits { channel, value });
                }
                let wheel = Wheel::ALL[((value >> 24) & 0b11) as usize];
                Ok(Self::MotorPwm {
                    wheel,
                    pwm: value as u16 as i16,
                })
            }
            SOLENOID_CHANNEL => Ok(Self::Solenoid {
                on: boolean(channel, value)?,
            }),
            STOP_ON_SWITCH_CHANNEL => Ok(Self::StopOnSwitch {
                armed: boolean(channel, value)?,
            }),
            _ => match Setting::from_channel(channel) {
                Some(setting) => {
                    let value = f32::from_bits(value);
                    if !value.is_finite() {
                        return Err(MessageError::NotFinite { channel });
                    }
                    Ok(Self::Setting { setting, value })
                }
                None => Err(MessageError::UnknownChannel(channel)),
            },
        }
    }
}

/// Per-wheel counts of invalid (skipped-state) quadrature transitions, each wrapping at 256.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct QuadratureErrors(pub [u8; WHEEL_COUNT]);

/// Fault counters the Mega reports on channel `x`: four wrapping 8-bit counters, one byte
/// each (a host reading them every 20 ms sees every increment as long as fewer than 256 faults
/// of a kind happen between two batches).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Faults {
    /// I2C transfers to the motor shield that failed (NACK, bus error, timeout). Byte 0.
    pub i2c: u8,
    /// Received batches discarded by the integrity check (CRC, count or sequence). Byte 1.
    pub rx_batches_discarded: u8,
    /// Received frames rejected as malformed messages. Byte 2.
    pub rx_bad_messages: u8,
    /// Serial bytes lost by the Mega: received bytes that found its receive buffer full, and
    /// telemetry bytes that found its transmit buffer full. Byte 3.
    pub serial_bytes_dropped: u8,
}

impl Faults {
    /// The counters as the `x` value: byte 0 (least significant) is `i2c`.
    pub const fn to_value(self) -> u32 {
        u32::from_le_bytes([
            self.i2c,
            self.rx_batches_discarded,
            self.rx_bad_messages,
            self.serial_bytes_dropped,
        ])
    }

    /// The counters of an `x` value.
    pub const fn from_value(value: u32) -> Self {
        let [
            i2c,
            rx_batches_discarded,
            rx_bad_messages,
            serial_bytes_dropped,
        ] = value.to_le_bytes();
        Self {
            i2c,
            rx_batches_discarded,
            rx_bad_messages,
            serial_bytes_dropped,
        }
    }
}

/// A message from the Mega to the host.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Telemetry {
    /// `g`..`j`: cumulative encoder ticks of one wheel since boot (wrapping).
    Ticks {
        /// The wheel.
        wheel: Wheel,
        /// Cumulative ticks, two's complement, wrapping.
        total: i32,
    },
    /// `k`: measured interval between the last two control ticks, µs.
    LoopPeriod {
        /// Microseconds.
        period_us: u32,
    },
    /// `s`: the box micro-switch.
    Switch {
        /// True when the lever is pressed (the pin reads 0).
        pressed: bool,
    },
    /// `r`: the Mega has (re)booted; cumulative counters restart from zero.
    Reset,
    /// `q`: invalid quadrature transition counters.
    QuadratureErrors(QuadratureErrors),
    /// `x`: fault counters.
    Faults(Faults),
    /// `y`: the controller settings in force ([`crate::settings`]).
    SettingsAck(SettingsAck),
}

impl Telemetry {
    /// The frame that carries this message.
    pub fn to_frame(&self) -> Frame {
        let (channel, value) = match *self {
            Self::Ticks { wheel, total } => (TICKS_CHANNELS[wheel.index()], total as u32),
            Self::LoopPeriod { period_us } => (LOOP_PERIOD_CHANNEL, period_us),
            // The wire carries the pin level: 0 = pressed (pull-up, switch to ground).
            Self::Switch { pressed } => (SWITCH_CHANNEL, u32::from(!pressed)),
            Self::Reset => (RESET_CHANNEL, 0),
            Self::QuadratureErrors(QuadratureErrors(counts)) => {
                (QUADRATURE_ERRORS_CHANNEL, u32::from_le_bytes(counts))
            }
            Self::Faults(faults) => (FAULTS_CHANNEL, faults.to_value()),
            Self::SettingsAck(ack) => (SETTINGS_ACK_CHANNEL, ack.to_value()),
        };
        match Frame::new(channel, value) {
            Ok(frame) => frame,
            Err(_) => unreachable!(),
        }
    }

    /// The message a frame carries.
    pub fn from_frame(frame: Frame) -> Result<Self, MessageError> {
        let (channel, value) = (frame.channel(), frame.value());
        match channel {
            b'g'..=b'j' => Ok(Self::Ticks {
                wheel: Wheel::ALL[usize::from(channel - b'g')],
                total: value as i32,
            }),
            LOOP_PERIOD_CHANNEL => Ok(Self::LoopPeriod { period_us: value }),
            SWITCH_CHANNEL => Ok(Self::Switch {
                pressed: !boolean(channel, value)?,
            }),
            // The original sends 0; any value means the same thing (a reboot).
            RESET_CHANNEL => Ok(Self::Reset),
            QUADRATURE_ERRORS_CHANNEL => Ok(Self::QuadratureErrors(QuadratureErrors(
                value.to_le_bytes(),
            ))),
            FAULTS_CHANNEL => Ok(Self::Faults(Faults::from_value(value))),
            SETTINGS_ACK_CHANNEL => Ok(Self::SettingsAck(SettingsAck::from_value(value))),
            _ => Err(MessageError::UnknownChannel(channel)),
        }
    }
}

fn boolean(channel: u8, value: u32) -> Result<bool, MessageError> {
    match value {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(MessageError::NotBoolean { channel, value }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn wheel() -> impl Strategy<Value = Wheel> {
        (0u8..4).prop_map(|i| Wheel::from_index(i).unwrap())
    }

    fn command() -> impl Strategy<Value = Command> {
        prop_oneof![
            (wheel(), -1.0e6f32..1.0e6)
                .prop_map(|(wheel, speed_rad_s)| Command::WheelSpeed { wheel, speed_rad_s }),
            (wheel(), any::<i16>()).prop_map(|(wheel, pwm)| Command::MotorPwm { wheel, pwm }),
            any::<bool>().prop_map(|on| Command::Solenoid { on }),
            any::<bool>().prop_map(|armed| Command::StopOnSwitch { armed }),
            (0usize..8, -1.0e6f32..1.0e6).prop_map(|(k, value)| Command::Setting {
                setting: Setting::ALL[k],
                value,
            }),
        ]
    }

    fn telemetry() -> impl Strategy<Value = Telemetry> {
        prop_oneof![
            (wheel(), any::<i32>()).prop_map(|(wheel, total)| Telemetry::Ticks { wheel, total }),
            any::<u32>().prop_map(|period_us| Telemetry::LoopPeriod { period_us }),
            any::<bool>().prop_map(|pressed| Telemetry::Switch { pressed }),
            Just(Telemetry::Reset),
            any::<[u8; 4]>().prop_map(|c| Telemetry::QuadratureErrors(QuadratureErrors(c))),
            any::<u32>().prop_map(|v| Telemetry::Faults(Faults::from_value(v))),
            any::<u32>().prop_map(|v| Telemetry::SettingsAck(SettingsAck::from_value(v))),
        ]
    }

    proptest! {
        #[test]
        fn every_command_round_trips(cmd in command()) {
            prop_assert_eq!(Command::from_frame(cmd.to_frame()), Ok(cmd));
        }

        #[test]
        fn every_telemetry_message_round_trips(msg in telemetry()) {
            prop_assert_eq!(Telemetry::from_frame(msg.to_frame()), Ok(msg));
        }
    }

    fn encoded_command(cmd: Command) -> [u8; 9] {
        cmd.to_frame().encode()
    }

    #[test]
    fn golden_command_bytes() {
        let wheel_speed = |wheel, speed_rad_s| Command::WheelSpeed { wheel, speed_rad_s };
        assert_eq!(
            &encoded_command(wheel_speed(Wheel::BackRight, 1.0)),
            b"G3F800000"
        );
        assert_eq!(
            &encoded_command(wheel_speed(Wheel::BackLeft, -2.5)),
            b"HC0200000"
        );
        assert_eq!(
            &encoded_command(wheel_speed(Wheel::FrontRight, 0.0)),
            b"I00000000"
        );
        assert_eq!(
            &encoded_command(wheel_speed(Wheel::FrontLeft, 10.0)),
            b"J41200000"
        );
        let pwm = Command::MotorPwm {
            wheel: Wheel::FrontRight,
            pwm: -100,
        };
        assert_eq!(&encoded_command(pwm), b"K0200FF9C");
        assert_eq!(
            &encoded_command(Command::Solenoid { on: true }),
            b"L00000001"
        );
        assert_eq!(
            &encoded_command(Command::StopOnSwitch { armed: true }),
            b"U00000001"
        );
        let limit = Command::Setting {
            setting: Setting::VoltageLimit,
            value: 10.0,
        };
        assert_eq!(&encoded_command(limit), b"S41200000");
    }

    #[test]
    fn golden_telemetry_bytes() {
        let bytes = |m: Telemetry| m.to_frame().encode();
        let ticks = Telemetry::Ticks {
            wheel: Wheel::BackRight,
            total: -2,
        };
        assert_eq!(&bytes(ticks), b"gFFFFFFFE");
        let ticks = Telemetry::Ticks {
            wheel: Wheel::FrontLeft,
            total: 2803,
        };
        assert_eq!(&bytes(ticks), b"j00000AF3");
        assert_eq!(
            &bytes(Telemetry::LoopPeriod { period_us: 20_016 }),
            b"k00004E30"
        );
        assert_eq!(&bytes(Telemetry::Switch { pressed: true }), b"s00000000");
        assert_eq!(&bytes(Telemetry::Switch { pressed: false }), b"s00000001");
        assert_eq!(&bytes(Telemetry::Reset), b"r00000000");
        let faults = Faults {
            i2c: 3,
            rx_batches_discarded: 0x10,
            rx_bad_messages: 0,
            serial_bytes_dropped: 0xFF,
        };
        assert_eq!(&bytes(Telemetry::Faults(faults)), b"xFF001003");
        let ack = SettingsAck {
            applied: 0xFF,
            refused: 0x02,
            fingerprint: 0xABCD,
        };
        assert_eq!(&bytes(Telemetry::SettingsAck(ack)), b"yABCD02FF");
    }

    #[test]
    fn malformed_frames_are_errors_not_values() {
        let frame = |c, v| Frame::new(c, v).unwrap();
        assert_eq!(
            Command::from_frame(frame(b'G', f32::NAN.to_bits())),
            Err(MessageError::NotFinite { channel: b'G' })
        );
        assert_eq!(
            Command::from_frame(frame(b'K', 0x0400_0001)),
            Err(MessageError::ReservedBits {
                channel: b'K',
                value: 0x0400_0001
            })
        );
        for channel in [SOLENOID_CHANNEL, STOP_ON_SWITCH_CHANNEL] {
            assert_eq!(
                Command::from_frame(frame(channel, 2)),
                Err(MessageError::NotBoolean { channel, value: 2 })
            );
        }
        assert_eq!(
            Command::from_frame(frame(b'S', f32::INFINITY.to_bits())),
            Err(MessageError::NotFinite { channel: b'S' })
        );
        assert_eq!(
            Command::from_frame(frame(b'V', 0)),
            Err(MessageError::UnknownChannel(b'V'))
        );
        assert_eq!(
            Command::from_frame(frame(b'g', 0)),
            Err(MessageError::UnknownChannel(b'g'))
        );
        assert_eq!(
            Telemetry::from_frame(frame(b'G', 0)),
            Err(MessageError::UnknownChannel(b'G'))
        );
    }
}
