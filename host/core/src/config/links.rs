//! Cross-key checks of the serial links' load: a stream a line cannot carry queues without
//! end in the simulator and loses data on the robot, and the round silently scores nothing.
//! Each message gives the arithmetic and the value that would fit.
//!
//! - Mega → host: one telemetry batch per `mega.control_period_us` at `link.mega_baud`;
//! - host → Mega: one reference batch per 50 Hz host tick at `link.mega_baud`;
//! - X4 → host: `360 / lidar.angle_step_deg` samples per revolution, `lidar.scan_rate_hz`
//!   revolutions a second, in packets of 40, at `link.lidar_baud`.

use super::Config;
use super::check::{Checker, Issue, any_rejected, num};
use super::limits::{
    BITS_PER_BYTE, HOST_REFERENCE_PERIOD_US, LIDAR_LINK_MAX_LOAD, MEGA_LINK_MAX_LOAD,
    REFERENCE_BATCH_BYTES,
};
use crate::drivers::x4::packet::{MAX_SCAN_FREQUENCY_HZ, PACKET_HEADER_LEN};
use crate::drivers::x4::scan::ScanConfig;

/// Frames in one Mega telemetry batch: `g h i j k s q x` (protocol/README.md §4).
const TELEMETRY_FRAMES: u32 = 8;
/// Bytes per frame on the Mega link (protocol/README.md §1).
const FRAME_BYTES: u32 = 9;
/// Samples per X4 data packet: the X4's typical packet, as the simulated X4 sends
/// (real-world-errors.md §1: "40 samples").
const SAMPLES_PER_PACKET: u64 = 40;

/// Every link-load issue of `config`.
pub(crate) fn check(config: &Config, issues: &mut Vec<Issue>) {
    let mega = [
        "mega.control_period_us",
        "mega.telemetry_latency_us",
        "link.mega_baud",
    ];
    if !any_rejected(issues, &mega) {
        mega_telemetry(config, &mut Checker::new("mega", issues));
    }
    if !any_rejected(issues, &["link.mega_baud"]) {
        mega_references(config, &mut Checker::new("link", issues));
    }
    let lidar = [
        "lidar.scan_rate_hz",
        "lidar.angle_step_deg",
        "link.lidar_baud",
    ];
    if !any_rejected(issues, &lidar) {
        lidar_stream(config, &mut Checker::new("lidar", issues));
    }
}

/// Time `bytes` take on a line at `baud`, µs.
fn wire_us(bytes: u32, baud: u32) -> f64 {
    f64::from(bytes) * BITS_PER_BYTE * 1e6 / f64::from(baud)
}

fn mega_telemetry(config: &Config, c: &mut Checker<'_>) {
    let period_us = config.mega.control_period_us;
    let baud = config.link.mega_baud;
    if period_us == 0 || baud == 0 {
        return;
    }
    let frames = TELEMETRY_FRAMES + u32::from(config.mega.send_checksums);
    let bytes = frames * FRAME_BYTES;
    let wire = wire_us(bytes, baud);
    let latency = f64::from(config.mega.telemetry_latency_us);
    let needed = wire + latency;
    let allowed = MEGA_LINK_MAX_LOAD * f64::from(period_us);
    let shortest_ms = (needed / MEGA_LINK_MAX_LOAD / 1000.0).ceil();
    c.require("control_period_us", period_us, needed <= allowed, || {
        format!(
            "the Mega's telemetry does not fit: a batch of {bytes} bytes × 10 bits / {baud} \
             baud (link.mega_baud) = {:.2} ms on the wire, plus mega.telemetry_latency_us \
             {:.2} ms = {:.2} ms, more than {:.0} % of the period ({:.2} ms); batches would \
             queue without end. At {baud} baud the period must be at least {shortest_ms} ms",
            wire / 1000.0,
            latency / 1000.0,
            needed / 1000.0,
            MEGA_LINK_MAX_LOAD * 100.0,
            allowed / 1000.0,
        )
    });
}

fn mega_references(config: &Config, c: &mut Checker<'_>) {
    let baud = config.link.mega_baud;
    if baud == 0 {
        return;
    }
    let wire = wire_us(REFERENCE_BATCH_BYTES, baud);
    let allowed = MEGA_LINK_MAX_LOAD * f64::from(HOST_REFERENCE_PERIOD_US);
    let lowest_baud =
        (f64::from(REFERENCE_BATCH_BYTES) * BITS_PER_BYTE * 1e6 / allowed).ceil() as u64;
    c.require("mega_baud", baud, wire <= allowed, || {
        format!(
            "the references do not fit: a batch of {REFERENCE_BATCH_BYTES} bytes (G H I J L U Z) \
             × 10 bits / {baud} baud = {:.2} ms on the wire, more than {:.0} % of the host's \
             {} ms tick ({:.2} ms); at least {lowest_baud} baud",
            wire / 1000.0,
            MEGA_LINK_MAX_LOAD * 100.0,
            HOST_REFERENCE_PERIOD_US / 1000,
            allowed / 1000.0,
        )
    });
}

/// Bytes of one revolution of `samples` samples: the start-of-revolution packet (one
/// sample) and the data packets of [`SAMPLES_PER_PACKET`], each with its 10-byte header.
fn revolution_bytes(samples: u64) -> u64 {
    let header = PACKET_HEADER_LEN as u64;
    let packets = samples.div_ceil(SAMPLES_PER_PACKET);
    (header + 2) + packets * header + 2 * samples
}

fn lidar_stream(config: &Config, c: &mut Checker<'_>) {
    let lidar = &config.lidar;
    let baud = config.link.lidar_baud;
    let (rate, step) = (lidar.scan_rate_hz, lidar.angle_step_deg);
    // Only for values the per-key checks accept: the arithmetic below needs them sane.
    if baud == 0 || !(4.0..=MAX_SCAN_FREQUENCY_HZ).contains(&rate) || !(0.1..=2.0).contains(&step) {
        return;
    }
    // As the simulated X4 counts them.
    let samples = (360.0 / step).round().max(1.0) as u64;
    let capacity_bit_s = LIDAR_LINK_MAX_LOAD * f64::from(baud);
    let bit_s = |samples: u64| revolution_bytes(samples) as f64 * rate * BITS_PER_BYTE;
    let fits = bit_s(samples) <= capacity_bit_s;
    let max_points = ScanConfig::default().max_points as u64;
    let most = (1..=max_points)
        .rev()
        .find(|&n| bit_s(n) <= capacity_bit_s)
        .unwrap_or(1);
    let finest_deg = (360.0 / most as f64 * 100.0).ceil() / 100.0;
    c.require("angle_step_deg", num(step), fits, || {
        format!(
            "the X4's stream does not fit its line: {samples} samples a revolution × \
             lidar.scan_rate_hz {} in packets of {SAMPLES_PER_PACKET} = {:.0} bytes/s × 10 \
             bits = {:.0} bit/s, {:.0} % of link.lidar_baud {baud} (at most {:.0} %); the scans \
             would queue without end. At {} Hz use angle_step_deg ≥ {finest_deg}°",
            num(rate),
            bit_s(samples) / BITS_PER_BYTE,
            bit_s(samples),
            bit_s(samples) / f64::from(baud) * 100.0,
            LIDAR_LINK_MAX_LOAD * 100.0,
            num(rate),
        )
    });
    c.require("angle_step_deg", num(step), samples <= max_points, || {
        format!(
            "{samples} samples a revolution: the scan assembler keeps at most {max_points} \
             (drivers::x4::scan), the rest would be dropped"
        )
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_links_carry_their_load_with_the_documented_figures() {
        // 9 frames × 9 bytes at 115 200 baud: 7.03 ms, 35 % of 20 ms (with the latency, 46 %).
        assert!((wire_us(81, 115_200) - 7_031.25).abs() < 1e-6);
        // 720 samples in 18 packets + the zero packet: 1632 bytes, ×7 Hz ×10 = 89 % of 128 000.
        assert_eq!(revolution_bytes(720), 1632);
        let load = revolution_bytes(720) as f64 * 7.0 * 10.0 / 128_000.0;
        assert!((load - 0.8925).abs() < 1e-4, "{load}");
        let mut issues = Vec::new();
        check(&Config::default(), &mut issues);
        assert!(issues.is_empty(), "{issues:?}");
    }
}
