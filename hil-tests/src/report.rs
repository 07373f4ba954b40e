//! The HIL figures of merit and where they are written: `target/hil-report.json` in the
//! workspace's target directory (`$CARGO_TARGET_DIR` if set, else `<workspace>/target`).

use serde_json::{Value, json};
use std::path::PathBuf;

/// File name of the report inside the target directory.
pub const REPORT_FILE: &str = "hil-report.json";

/// Encoder ISR cost, cycles per invocation, hardware entry and `reti` included.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IsrCycles {
    /// Shortest path.
    pub min: u64,
    /// Median invocation: known only when every path costs the same (`min == max`), since
    /// the count is static; `None` otherwise.
    pub median: Option<u64>,
    /// Longest path.
    pub max: u64,
}

/// Every figure the report carries.
#[derive(Clone, Debug, PartialEq)]
pub struct HilReport {
    /// The ELF measured.
    pub elf: PathBuf,
    /// TIMER1_COMPA ISR cycles.
    pub isr_cycles: IsrCycles,
    /// Flash use (`.text` + `.data`), bytes.
    pub flash_bytes: u64,
    /// Static RAM use (`.data` + `.bss` + `.noinit`), bytes.
    pub ram_bytes: u64,
    /// Highest per-encoder edge rate (all four encoders at once) with no lost count, Hz.
    pub max_lossless_edge_rate_hz: Option<f64>,
    /// Time from the last `G` to every motor off and the solenoid released, ms.
    pub watchdog_stop_ms: Option<f64>,
    /// Time from the last `G` to the first output switched off, ms.
    pub watchdog_trip_ms: Option<f64>,
    /// Control window close to the batch's first byte, µs: motors off (timed out).
    pub telemetry_latency_idle_us: Option<u64>,
    /// The same while the host drives the wheels (PI controllers running).
    pub telemetry_latency_driving_us: Option<u64>,
}

impl HilReport {
    /// The report as JSON.
    pub fn to_json(&self) -> Value {
        json!({
            "elf": self.elf.display().to_string(),
            "isr_cycles": {
                "min": self.isr_cycles.min,
                "median": self.isr_cycles.median,
                "max": self.isr_cycles.max,
                "method": "static: every path of avr-objdump -d from vector 17 to reti, \
                           ATmega2560 timings, +5 hardware entry",
            },
            "flash_bytes": self.flash_bytes,
            "ram_bytes": self.ram_bytes,
            "max_lossless_edge_rate_hz": self.max_lossless_edge_rate_hz,
            "watchdog_stop_ms": self.watchdog_stop_ms,
            "watchdog_trip_ms": self.watchdog_trip_ms,
            "telemetry_latency_idle_us": self.telemetry_latency_idle_us,
            "telemetry_latency_driving_us": self.telemetry_latency_driving_us,
        })
    }
}

/// Where the report goes: `$CARGO_TARGET_DIR/hil-report.json`, else
/// `<workspace>/target/hil-report.json`.
pub fn report_path() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| crate::firmware::workspace_root().join("target"))
        .join(REPORT_FILE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_carries_every_figure() {
        let report = HilReport {
            elf: PathBuf::from("fw.elf"),
            isr_cycles: IsrCycles {
                min: 99,
                median: Some(99),
                max: 99,
            },
            flash_bytes: 17448,
            ram_bytes: 495,
            max_lossless_edge_rate_hz: Some(45_000.0),
            watchdog_stop_ms: Some(109.5),
            watchdog_trip_ms: None,
            telemetry_latency_idle_us: Some(5500),
            telemetry_latency_driving_us: None,
        };
        let v = report.to_json();
        assert_eq!(v["isr_cycles"]["median"], 99);
        assert_eq!(v["flash_bytes"], 17448);
        assert_eq!(v["max_lossless_edge_rate_hz"], 45_000.0);
        assert!(v["watchdog_trip_ms"].is_null());
        assert!(report_path().ends_with("hil-report.json"));
    }
}
