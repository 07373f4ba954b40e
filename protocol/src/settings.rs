//! The controller settings the host sends the Mega (ratf channels `M`..`T`) and the Mega's
//! acknowledgement (`y`).
//!
//! The robot's configuration file is the one source of truth: the host sends every setting
//! at start-up and again after each Mega reset (`r`), and the Mega uses them in place of its
//! compiled defaults ([`crate::mcu::McuConfig::default`]). A host that sends none gets the
//! defaults. An original Mega ignores the letters (it registers no such channel).
//!
//! Each setting is one frame: the letter and the IEEE-754 `f32` bits of the value.
//!
//! | letter | setting | unit | accepted |
//! |---|---|---|---|
//! | `M` | PI proportional gain Kc | V/(rad/s) | finite, ≥ 0 |
//! | `N` | PI integral gain Ki | V/rad | finite, ≥ 0 |
//! | `O` | feed-forward Kf | V/(rad/s) | finite, ≥ 0 |
//! | `P` | dead zone V0 | V | finite, 0 ..= [`MAX_BATTERY_VOLTAGE_V`] |
//! | `Q` | dead zone Vd | V | finite, 0 ..= [`MAX_BATTERY_VOLTAGE_V`] |
//! | `R` | battery voltage (what PWM `pwm_max` delivers) | V | finite, > 0, ≤ [`MAX_BATTERY_VOLTAGE_V`] |
//! | `S` | PI voltage limit (saturation, anti-windup) | V | finite, > 0, ≤ the battery voltage in force |
//! | `T` | encoder ticks per wheel revolution | ticks | finite, ≥ 1, ≤ [`MAX_TICKS_PER_WHEEL_REV`] |
//!
//! A refused value is never applied: the setting keeps its value, the frame counts as a bad
//! message (`x` byte 2) and the setting's bit is set in the refused mask of `y` until a valid
//! value arrives.
//!
//! `y` (every telemetry batch): byte 0 = the settings received from the host since boot and
//! in force (bit k = setting k), byte 1 = the settings whose last value was refused, bytes
//! 2–3 = [`fingerprint`] of all eight values in force, so the host can check that the Mega
//! uses exactly its values.

use crate::integrity::Crc16;
use core::fmt;

/// Number of settings.
pub const SETTING_COUNT: usize = 8;
/// The setting channel letters, by [`Setting`] index.
pub const SETTING_CHANNELS: [u8; SETTING_COUNT] = *b"MNOPQRST";
/// The acknowledgement channel (Mega → host).
pub const SETTINGS_ACK_CHANNEL: u8 = b'y';
/// Highest battery voltage the Mega accepts, V: the motor shield's bridges take at most
/// 13.5 V (Adafruit Motor Shield V2, TB6612).
pub const MAX_BATTERY_VOLTAGE_V: f32 = 13.5;
/// Highest encoder resolution the Mega accepts, ticks per wheel revolution: the 1 kHz fold
/// is exact below 128 counts per ms, i.e. 2 revolutions per second at 64 000 ticks.
pub const MAX_TICKS_PER_WHEEL_REV: f32 = 64_000.0;

/// One controller setting, numbered as its bit in the acknowledgement masks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Setting {
    /// `M`: PI proportional gain Kc, V/(rad/s).
    Kc = 0,
    /// `N`: PI integral gain Ki, V/rad.
    Ki = 1,
    /// `O`: feed-forward Kf, V/(rad/s) of reference.
    Kf = 2,
    /// `P`: Hammerstein dead zone V0, V.
    DeadZoneV0 = 3,
    /// `Q`: Hammerstein compensated range Vd, V.
    DeadZoneVd = 4,
    /// `R`: battery voltage, V: what PWM `pwm_max` delivers.
    BatteryVoltage = 5,
    /// `S`: the PI's voltage limit (saturation and anti-windup), V.
    VoltageLimit = 6,
    /// `T`: encoder ticks per wheel revolution.
    TicksPerWheelRev = 7,
}

impl Setting {
    /// All settings, in the order the host sends them (the battery voltage before the limit
    /// it bounds).
    pub const ALL: [Setting; SETTING_COUNT] = [
        Setting::Kc,
        Setting::Ki,
        Setting::Kf,
        Setting::DeadZoneV0,
        Setting::DeadZoneVd,
        Setting::BatteryVoltage,
        Setting::VoltageLimit,
        Setting::TicksPerWheelRev,
    ];

    /// The setting carried on `channel`, if any.
    pub const fn from_channel(channel: u8) -> Option<Self> {
        match channel {
            b'M'..=b'T' => Some(Self::ALL[(channel - b'M') as usize]),
            _ => None,
        }
    }

    /// The channel letter.
    pub const fn channel(self) -> u8 {
        SETTING_CHANNELS[self as usize]
    }

    /// The bit of this setting in the acknowledgement masks.
    pub const fn bit(self) -> u8 {
        1 << self as u8
    }

    /// Check `value` for this setting, given the battery voltage in force (which bounds the
    /// voltage limit). The Mega applies only values that pass.
    pub fn validate(self, value: f32, battery_voltage_v: f32) -> Result<(), SettingError> {
        let ok = value.is_finite()
            && match self {
                Self::Kc | Self::Ki | Self::Kf => value >= 0.0,
                Self::DeadZoneV0 | Self::DeadZoneVd => {
                    (0.0..=MAX_BATTERY_VOLTAGE_V).contains(&value)
                }
                Self::BatteryVoltage => value > 0.0 && value <= MAX_BATTERY_VOLTAGE_V,
                Self::VoltageLimit => value > 0.0 && value <= battery_voltage_v,
                Self::TicksPerWheelRev => (1.0..=MAX_TICKS_PER_WHEEL_REV).contains(&value),
            };
        if ok {
            Ok(())
        } else {
            Err(SettingError {
                setting: self,
                value,
            })
        }
    }
}

/// A setting value the Mega refuses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SettingError {
    /// The setting.
    pub setting: Setting,
    /// The refused value.
    pub value: f32,
}

impl fmt::Display for SettingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let accepted = match self.setting {
            Setting::Kc | Setting::Ki | Setting::Kf => "a finite value >= 0",
            Setting::DeadZoneV0 | Setting::DeadZoneVd => "a finite value within 0..=13.5 V",
            Setting::BatteryVoltage => "a finite value within (0, 13.5] V",
            Setting::VoltageLimit => "a finite value > 0 V and no more than the battery voltage",
            Setting::TicksPerWheelRev => "a finite value within 1..=64000",
        };
        write!(
            f,
            "setting {:?} (channel '{}') value {} refused: the Mega accepts {accepted}",
            self.setting,
            self.setting.channel() as char,
            self.value
        )
    }
}

impl core::error::Error for SettingError {}

/// The Mega's acknowledgement of the settings (`y`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SettingsAck {
    /// Settings received from the host since boot and in force (bit = [`Setting::bit`]).
    pub applied: u8,
    /// Settings whose last received value was refused.
    pub refused: u8,
    /// [`fingerprint`] of the eight values in force.
    pub fingerprint: u16,
}

impl SettingsAck {
    /// The `y` value: byte 0 `applied`, byte 1 `refused`, bytes 2–3 `fingerprint`.
    pub const fn to_value(self) -> u32 {
        u32::from_le_bytes([
            self.applied,
            self.refused,
            self.fingerprint as u8,
            (self.fingerprint >> 8) as u8,
        ])
    }

    /// The acknowledgement of a `y` value.
    pub const fn from_value(value: u32) -> Self {
        let [applied, refused, low, high] = value.to_le_bytes();
        Self {
            applied,
            refused,
            fingerprint: u16::from_le_bytes([low, high]),
        }
    }

    /// True when every setting came from the host, none was refused, and the values in force
    /// are those of `expected` (compared by [`fingerprint`]).
    pub fn confirms(&self, expected: &[f32; SETTING_COUNT]) -> bool {
        self.applied == 0xFF && self.refused == 0 && self.fingerprint == fingerprint(expected)
    }
}

/// CRC-16/CCITT-FALSE of the eight values' `f32` bits, little-endian, in [`Setting`] order.
pub fn fingerprint(values: &[f32; SETTING_COUNT]) -> u16 {
    values
        .iter()
        .fold(Crc16::new(), |crc, value| {
            crc.update(&value.to_bits().to_le_bytes())
        })
        .value()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::string::ToString;

    #[test]
    fn letters_and_bits() {
        for (k, setting) in Setting::ALL.iter().enumerate() {
            assert_eq!(*setting as usize, k);
            assert_eq!(Setting::from_channel(setting.channel()), Some(*setting));
            assert_eq!(setting.bit(), 1 << k);
        }
        assert_eq!(Setting::from_channel(b'L'), None);
        assert_eq!(Setting::from_channel(b'U'), None);
    }

    #[test]
    fn invalid_values_are_refused() {
        let battery = 11.1;
        for setting in Setting::ALL {
            assert!(setting.validate(f32::NAN, battery).is_err(), "{setting:?}");
            assert!(setting.validate(f32::INFINITY, battery).is_err());
            assert!(setting.validate(-0.5, battery).is_err());
        }
        assert!(Setting::Kc.validate(0.0, battery).is_ok());
        assert!(Setting::Ki.validate(1.0e3, battery).is_ok());
        assert!(Setting::BatteryVoltage.validate(0.0, battery).is_err());
        assert!(Setting::BatteryVoltage.validate(13.6, battery).is_err());
        assert!(Setting::BatteryVoltage.validate(12.6, battery).is_ok());
        assert!(Setting::VoltageLimit.validate(11.1, battery).is_ok());
        let above = Setting::VoltageLimit.validate(11.2, battery).unwrap_err();
        assert_eq!(above.setting, Setting::VoltageLimit);
        assert!(above.to_string().contains("channel 'S'"));
        assert!(Setting::TicksPerWheelRev.validate(0.5, battery).is_err());
        assert!(Setting::TicksPerWheelRev.validate(2803.2, battery).is_ok());
    }

    #[test]
    fn fingerprint_sees_every_value() {
        let values = [0.4566, 4.566, 0.0, 0.0, 0.0, 11.1, 11.1, 2803.2];
        let base = fingerprint(&values);
        for k in 0..SETTING_COUNT {
            let mut changed = values;
            changed[k] += 0.001;
            assert_ne!(fingerprint(&changed), base, "setting {k}");
        }
    }

    proptest! {
        #[test]
        fn ack_round_trips(value in any::<u32>()) {
            prop_assert_eq!(SettingsAck::from_value(value).to_value(), value);
        }
    }
}
