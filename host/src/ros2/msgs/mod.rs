//! ROS 2 messages, one definition per type: a serde struct whose fields follow the `.msg`
//! file's order (the CDR layout is the field order, nothing else), and the `ros2msg`
//! definition text rosbag2 would embed for it ([`definition`]). The recording writes them
//! with [`to_cdr`]; the live bridge hands the same structs to its DDS layer.
//!
//! The `.msg` files under `defs/` are ROS 2 Jazzy's (common_interfaces 5.3, rcl_interfaces,
//! geometry2), copied verbatim, comments included, because rosbag2 embeds them verbatim.

pub mod definition;
pub mod diagnostic;
pub mod geometry;
pub mod sensor;
pub mod visualization;

use serde::{Deserialize, Serialize};

/// A ROS 2 message type: its full name and its `.msg` text.
pub trait RosMessage: Serialize {
    /// The type's full name, `package/msg/Name` (what rosbag2 and Foxglove show, and the
    /// MCAP schema's name).
    const TYPE_NAME: &'static str;
}

/// The CDR encapsulation header of little-endian plain CDR (XCDR1, `CDR_LE`): what every
/// ROS 2 RMW writes before a message and what MCAP's `cdr` message encoding expects.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Why a message could not be encoded (a sequence too long for CDR's u32 length).
#[derive(Debug, thiserror::Error)]
#[error("CDR encoding of {type_name}: {message}")]
pub struct EncodeError {
    /// The message's type.
    pub type_name: &'static str,
    /// cdr-encoding's message.
    pub message: String,
}

/// `message` as a serialized ROS 2 message: the encapsulation header, then little-endian
/// CDR aligned from the byte after the header.
pub fn to_cdr<M: RosMessage>(message: &M) -> Result<Vec<u8>, EncodeError> {
    let mut bytes = CDR_LE_HEADER.to_vec();
    cdr_encoding::to_writer::<M, byteorder::LittleEndian, _>(&mut bytes, message).map_err(|e| {
        EncodeError {
            type_name: M::TYPE_NAME,
            message: e.to_string(),
        }
    })?;
    Ok(bytes)
}

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds past `sec`, below 10⁹.
    pub nanosec: u32,
}

impl Time {
    /// The time `us` µs after the robot clock's epoch (saturating past 2³¹ s).
    pub fn from_us(us: u64) -> Self {
        Self {
            sec: i32::try_from(us / 1_000_000).unwrap_or(i32::MAX),
            nanosec: (us % 1_000_000) as u32 * 1_000,
        }
    }

    /// A fractional µs stamp (a scan's acquisition time), rounded to the ns; negative
    /// stamps clamp to the epoch.
    pub fn from_us_f64(us: f64) -> Self {
        let ns = (us.max(0.0) * 1_000.0).round() as u64;
        Self {
            sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    /// Nanoseconds since the epoch (the MCAP log time of a message stamped so).
    pub fn as_ns(self) -> u64 {
        u64::try_from(self.sec).unwrap_or(0) * 1_000_000_000 + u64::from(self.nanosec)
    }
}

/// `builtin_interfaces/msg/Duration`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Duration {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds past `sec`.
    pub nanosec: u32,
}

/// `std_msgs/msg/Header`: when and in which frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// When the data was acquired.
    pub stamp: Time,
    /// The coordinate frame (tf name).
    pub frame_id: String,
}

impl Header {
    /// A header at `stamp` in `frame_id`.
    pub fn new(stamp: Time, frame_id: &str) -> Self {
        Self {
            stamp,
            frame_id: frame_id.to_owned(),
        }
    }
}

/// `std_msgs/msg/ColorRGBA`, components in [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ColorRgba {
    /// Red.
    pub r: f32,
    /// Green.
    pub g: f32,
    /// Blue.
    pub b: f32,
    /// Opacity.
    pub a: f32,
}

impl ColorRgba {
    /// An opaque colour.
    pub const fn rgb(r: f32, g: f32, b: f32) -> Self {
        Self { r, g, b, a: 1.0 }
    }
}

#[cfg(test)]
pub(crate) fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Stamped(Header);
    impl RosMessage for Stamped {
        const TYPE_NAME: &'static str = "std_msgs/msg/Header";
    }

    #[test]
    fn a_header_is_the_encapsulation_then_sec_nanosec_and_a_nul_terminated_string() {
        let bytes = to_cdr(&Stamped(Header::new(Time::from_us(1_500_000), "map"))).unwrap();
        assert_eq!(
            hex(&bytes),
            concat!("00010000", "01000000", "0065cd1d", "04000000", "6d617000")
        );
    }

    #[test]
    fn times_split_into_seconds_and_nanoseconds() {
        assert_eq!(
            Time::from_us(3_000_007),
            Time {
                sec: 3,
                nanosec: 7_000
            }
        );
        assert_eq!(
            Time::from_us_f64(1_000_000.4),
            Time {
                sec: 1,
                nanosec: 400
            }
        );
        assert_eq!(Time::from_us_f64(-5.0), Time::default());
        assert_eq!(Time::from_us(2_500_000).as_ns(), 2_500_000_000);
    }
}
