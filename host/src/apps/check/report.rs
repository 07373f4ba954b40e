//! The check's summary (pure): one entry per device, `ok` or the problems, as lines and as
//! one JSON object; and the exit code.

use serde::Serialize;
use serde_json::Value;

/// Exit code: every device ok.
pub const EXIT_OK: i32 = 0;
/// Exit code: the configuration could not be loaded.
pub const EXIT_SETUP: i32 = 1;
/// Exit code: at least one device has a problem (the summary says which and what to do).
pub const EXIT_PROBLEM: i32 = 3;
/// Exit code: stopped by Ctrl-C or SIGTERM (the robot was stopped first).
pub const EXIT_INTERRUPTED: i32 = 130;

/// What the check found about one device (or one step of the bring-up).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DeviceReport {
    /// `mega`, `wheels`, `magnet`, `lidar`, `imu` or `server`.
    pub device: &'static str,
    /// No problem found (a skipped device is ok).
    pub ok: bool,
    /// Not checked, and why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub skipped: Option<String>,
    /// What is wrong, each with what to do.
    pub problems: Vec<String>,
    /// What was seen, in one line.
    pub seen: String,
    /// The figures, for `--json`.
    #[serde(skip_serializing_if = "Value::is_null")]
    pub data: Value,
}

impl DeviceReport {
    /// A device checked: ok when `problems` is empty.
    pub fn checked(device: &'static str, seen: String, problems: Vec<String>, data: Value) -> Self {
        Self {
            device,
            ok: problems.is_empty(),
            skipped: None,
            problems,
            seen,
            data,
        }
    }

    /// A device missing or unusable: `problem` says which, where it looked and what to do.
    pub fn missing(device: &'static str, problem: String) -> Self {
        Self::checked(device, String::new(), vec![problem], Value::Null)
    }

    /// A device or step not checked, and why.
    pub fn skipped(device: &'static str, why: String) -> Self {
        Self {
            device,
            ok: true,
            skipped: Some(why),
            problems: Vec::new(),
            seen: String::new(),
            data: Value::Null,
        }
    }

    /// The summary line: `device  ok: …`, `device  skipped: …` or `device  problem: …`.
    pub fn line(&self) -> String {
        let name = self.device;
        if let Some(why) = &self.skipped {
            return format!("{name:<8} skipped: {why}");
        }
        if self.ok {
            return format!("{name:<8} ok: {}", self.seen);
        }
        let mut line = format!("{name:<8} problem: {}", self.problems.join("; "));
        if !self.seen.is_empty() {
            line.push_str(&format!(" (seen: {})", self.seen));
        }
        line
    }
}

/// The whole check.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckReport {
    /// Every device, in the order checked.
    pub devices: Vec<DeviceReport>,
    /// Stopped by Ctrl-C or SIGTERM before the end.
    pub interrupted: bool,
}

impl CheckReport {
    /// True when every device is ok and the check ran to its end.
    pub fn all_ok(&self) -> bool {
        !self.interrupted && self.devices.iter().all(|d| d.ok)
    }

    /// The process's exit code.
    pub fn exit_code(&self) -> i32 {
        if self.interrupted {
            EXIT_INTERRUPTED
        } else if self.all_ok() {
            EXIT_OK
        } else {
            EXIT_PROBLEM
        }
    }

    /// One summary line per device.
    pub fn lines(&self) -> Vec<String> {
        self.devices.iter().map(DeviceReport::line).collect()
    }

    /// `{"devices": [{"device": "mega", "ok": true, …}, …], "ok": …, "interrupted": …}`.
    pub fn json(&self) -> Value {
        serde_json::json!({
            "devices": self.devices,
            "ok": self.all_ok(),
            "interrupted": self.interrupted,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_json_and_exit_codes() {
        let mut report = CheckReport {
            devices: vec![
                DeviceReport::checked("mega", "50.0 batches/s".into(), vec![], Value::Null),
                DeviceReport::skipped("imu", "[link] imu = \"none\"".into()),
            ],
            interrupted: false,
        };
        assert_eq!(
            report.lines(),
            [
                "mega     ok: 50.0 batches/s",
                "imu      skipped: [link] imu = \"none\""
            ]
        );
        assert_eq!(report.exit_code(), EXIT_OK);
        report.devices.push(DeviceReport::missing(
            "lidar",
            "lidar: /dev/x: no such device".into(),
        ));
        assert_eq!(report.exit_code(), EXIT_PROBLEM);
        assert_eq!(
            report.devices[2].line(),
            "lidar    problem: lidar: /dev/x: no such device"
        );
        let json = report.json();
        assert_eq!(json["devices"][0]["device"], "mega");
        assert_eq!(json["devices"][0]["ok"], true);
        assert_eq!(json["devices"][1]["skipped"], "[link] imu = \"none\"");
        assert_eq!(json["devices"][2]["ok"], false);
        assert_eq!(json["ok"], false);
        report.interrupted = true;
        assert_eq!(report.exit_code(), EXIT_INTERRUPTED);
    }
}
