//! Computes every HIL figure of merit, prints them and writes `target/hil-report.json`:
//! flash and RAM use (`avr-size -A`), the encoder ISR's cycles (static, `avr-objdump -d`),
//! the highest lossless encoder edge rate (bisection over simulated trials), and the
//! watchdog's stop time, and the latency from a control window's close to its batch's
//! first byte (idle and driving). Exits non-zero (the test fails) if any figure cannot be measured,
//! or if the edge-rate search is not monotonic below the rate it found.

use ratf_hil_tests::edge_rate::{max_lossless_rate, run_trial};
use ratf_hil_tests::firmware::{elf_path, memory_use};
use ratf_hil_tests::isr_cycles::{TIMER1_COMPA_VECTOR, disassemble, isr_bounds};
use ratf_hil_tests::latency::telemetry_latency_us;
use ratf_hil_tests::report::{HilReport, IsrCycles, report_path};
use ratf_hil_tests::sim::{CYCLES_PER_MS, Hil};
use ratf_hil_tests::watchdog::measure_watchdog;
use std::process::ExitCode;

/// Edges per encoder per trial: 2000, enough for a 1-in-1000 loss to show.
const TRIAL_EDGES: u32 = 2_000;

fn run() -> Result<HilReport, String> {
    let elf = elf_path().map_err(|e| e.to_string())?;
    let memory = memory_use(&elf).map_err(|e| e.to_string())?;
    let code = disassemble(&elf).map_err(|e| e.to_string())?;
    let bounds = isr_bounds(&code, TIMER1_COMPA_VECTOR).map_err(|e| e.to_string())?;
    let isr_cycles = IsrCycles {
        min: bounds.min,
        // A branch-free ISR costs the same on every invocation; otherwise a static count
        // cannot give a median.
        median: (bounds.min == bounds.max).then_some(bounds.max),
        max: bounds.max,
    };

    let (max_rate, trials) =
        max_lossless_rate(1_000.0, 100_000.0, 250.0, TRIAL_EDGES).map_err(|e| e.to_string())?;
    for t in &trials {
        println!(
            "edge-rate trial {:>8.0} Hz: {} (counted {:?}, expected {:?}, q {:?})",
            t.rate_hz,
            if t.lossless() { "lossless" } else { "LOST" },
            t.counted,
            t.expected,
            t.quadrature_errors
        );
    }
    if let Some(max) = max_rate {
        for fraction in [0.5, 0.75, 0.9] {
            let rate = (max * fraction).round();
            let t = run_trial(rate, TRIAL_EDGES).map_err(|e| e.to_string())?;
            if !t.lossless() {
                return Err(format!(
                    "edge-rate search not monotonic: lossless at {max} Hz but not at {rate} Hz: \
                     {t:?}"
                ));
            }
        }
    }

    let mut hil = Hil::boot().map_err(|e| e.to_string())?;
    if !hil.run_until_telemetry_batches(1, 60 * CYCLES_PER_MS) {
        return Err("no telemetry within 60 ms of boot".to_owned());
    }
    let watchdog = measure_watchdog(&mut hil, 500);
    let latency_idle = telemetry_latency_us(false, 10).map_err(|e| e.to_string())?;
    let latency_driving = telemetry_latency_us(true, 10).map_err(|e| e.to_string())?;

    Ok(HilReport {
        elf,
        isr_cycles,
        flash_bytes: memory.flash_bytes,
        ram_bytes: memory.ram_bytes,
        max_lossless_edge_rate_hz: max_rate,
        watchdog_stop_ms: watchdog.stop_ms(),
        watchdog_trip_ms: watchdog.trip_ms(),
        telemetry_latency_idle_us: latency_idle,
        telemetry_latency_driving_us: latency_driving,
    })
}

fn main() -> ExitCode {
    let report = match run() {
        Ok(report) => report,
        Err(e) => {
            eprintln!("hil_report: {e}");
            return ExitCode::FAILURE;
        }
    };
    let json = report.to_json();
    let text = match serde_json::to_string_pretty(&json) {
        Ok(text) => text,
        Err(e) => {
            eprintln!("hil_report: cannot serialise the report: {e}");
            return ExitCode::FAILURE;
        }
    };
    println!("{text}");
    let path = report_path();
    if let Err(e) = std::fs::write(&path, text + "\n") {
        eprintln!("hil_report: cannot write {}: {e}", path.display());
        return ExitCode::FAILURE;
    }
    println!("written to {}", path.display());
    ExitCode::SUCCESS
}
