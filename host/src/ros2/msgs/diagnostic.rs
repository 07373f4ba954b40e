//! `diagnostic_msgs`: the health of the devices, the localiser and the mission.

use serde::{Deserialize, Serialize};

use super::{Header, RosMessage};

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct KeyValue {
    /// The name.
    pub key: String,
    /// The value, as text.
    pub value: String,
}

/// `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// [`DiagnosticStatus::OK`], `WARN`, `ERROR` or `STALE`.
    pub level: u8,
    /// The component, e.g. `ratf: lidar`.
    pub name: String,
    /// A one-line summary.
    pub message: String,
    /// The device's identity, when known.
    pub hardware_id: String,
    /// The figures.
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    /// All is well.
    pub const OK: u8 = 0;
    /// Degraded.
    pub const WARN: u8 = 1;
    /// Failed.
    pub const ERROR: u8 = 2;
    /// No news.
    pub const STALE: u8 = 3;
}

/// `diagnostic_msgs/msg/DiagnosticArray`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// When.
    pub header: Header,
    /// One status per component.
    pub status: Vec<DiagnosticStatus>,
}

impl RosMessage for DiagnosticArray {
    const TYPE_NAME: &'static str = "diagnostic_msgs/msg/DiagnosticArray";
}

#[cfg(test)]
mod tests {
    use super::super::{Time, hex, to_cdr};
    use super::*;

    #[test]
    fn a_status_is_a_byte_then_strings_and_key_values() {
        let message = DiagnosticArray {
            header: Header::new(Time { sec: 0, nanosec: 1 }, ""),
            status: vec![DiagnosticStatus {
                level: DiagnosticStatus::WARN,
                name: "a".into(),
                message: "".into(),
                hardware_id: "".into(),
                values: vec![KeyValue {
                    key: "k".into(),
                    value: "v".into(),
                }],
            }],
        };
        // header 8 + (4 + 1) = 13, pad 16, count → 20, level → 21, pad 24, ...
        let expected = concat!(
            "00010000", "00000000", "01000000", "01000000", "00", "000000", "01000000", "01",
            "000000", "02000000", "6100", "0000", "01000000", "00", "000000", "01000000", "00",
            "000000", "01000000", "02000000", "6b00", "0000", "02000000", "7600",
        );
        assert_eq!(hex(&to_cdr(&message).unwrap()), expected);
    }
}
