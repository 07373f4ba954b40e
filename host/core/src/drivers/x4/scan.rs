//! Scan assembly: verified packets → one timestamped revolution in the robot's convention.
//!
//! **Revolutions.** A revolution starts at a start-of-revolution ("zero") packet (CT bit 0)
//! and ends at the next one, when it is handed over. Samples before the first zero packet
//! belong to a partial revolution and are discarded. The single sample of a zero packet is
//! not used (the original ignores it too; the manual gives it no distance meaning).
//!
//! **Angle convention.** The X4 reports clockwise degrees from its own zero. A point's
//! `angle_rad` here is counter-clockwise, in radians, in the lidar's frame (z up, x towards
//! the X4's 0° mark): `angle_rad = −angle_cw_deg·π/180`, wrapped to [−π, π). This is the
//! original's negation (original-system.md §3.2). Mounting the lidar on the robot (the
//! original: x 0.07 m, yaw 172°) is the caller's transform, not this module's.
//!
//! **Range filter.** Points with a range outside [`ScanConfig::range_min_m`,
//! `ScanConfig::range_max_m`] are dropped and counted (zero distances, "no return", fall
//! below any positive minimum).
//!
//! **Bounded.** A scan holds at most [`ScanConfig::max_points`] points; the storage is
//! reserved up front and never grows; extra points are counted in
//! [`Scan::points_overflowed`].
//!
//! **Time model (acquisition stamp).** The caller passes the time at which each chunk of
//! bytes was received (`now_us`, a monotonic clock in µs). A packet is complete at the
//! receive time of the chunk holding its last byte. The model:
//!
//! 1. the X4 samples at uniform intervals over a revolution: with scan frequency f (from
//!    CT; the revolution's last non-zero report) and n samples in the revolution, the
//!    sample period is dt = 1/(f·n). If the X4 reports no frequency, dt is the manual's
//!    nominal ranging period, 1/5000 s;
//! 2. a packet's last sample is acquired just before the packet is transmitted, so it is
//!    acquired at (receive time − packet length × 10 bits / 128 000 baud);
//! 3. sample k of the revolution (0-based, counting every sample, dropped or not) is thus
//!    acquired at t0 + k·dt. Each packet gives an estimate of t0; receive times can only be
//!    late (buffering in the USB bridge and the OS), so the scan's stamp t0 is the
//!    *earliest* estimate.
//!
//! A point's own acquisition time is `stamp_us + time_offset_us`, for de-skewing.

use super::packet::Packet;
use std::f64::consts::PI;

/// The X4's nominal ranging frequency, Hz (X4 datasheet: 5000 samples per second).
pub const NOMINAL_SAMPLE_RATE_HZ: f64 = 5000.0;
/// The X4's serial rate, baud (original-system.md §3.2).
pub const BAUD_RATE: f64 = 128_000.0;
/// Bits per byte on the wire, 8N1.
const BITS_PER_BYTE: f64 = 10.0;
/// Packets whose timing is kept per revolution (an X4 revolution has about 20–40).
const MAX_TIMED_PACKETS: usize = 128;

/// Scan assembler settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanConfig {
    /// Shortest range kept, m. The original's `dist_min`; the X4 datasheet range starts at
    /// 0.12 m.
    pub range_min_m: f64,
    /// Longest range kept, m. The X4 datasheet range ends at 10 m.
    pub range_max_m: f64,
    /// Most points a scan holds. 2048: an X4 revolution at its slowest (6 Hz) has
    /// 5000/6 ≈ 834 samples, so this leaves a wide margin.
    pub max_points: usize,
}

impl Default for ScanConfig {
    fn default() -> Self {
        Self {
            range_min_m: 0.12,
            range_max_m: 10.0,
            max_points: 2048,
        }
    }
}

/// One point of a scan, in the lidar's frame.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ScanPoint {
    /// Bearing, rad, counter-clockwise, in [−π, π) (see the module doc).
    pub angle_rad: f64,
    /// Range, m.
    pub range_m: f64,
    /// Acquisition time after the scan's stamp, µs.
    pub time_offset_us: f64,
}

/// One revolution of the X4.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Scan {
    /// Estimated acquisition time of the revolution's first sample, µs, on the caller's
    /// clock (see the module doc).
    pub stamp_us: f64,
    /// Sample period used by the time model, µs.
    pub sample_period_us: f64,
    /// Scan frequency reported by the X4, Hz (0 = not reported).
    pub scan_frequency_hz: f64,
    /// Points kept, in acquisition order.
    pub points: Vec<ScanPoint>,
    /// Samples received in the revolution, kept or not.
    pub samples: u32,
    /// Samples dropped by the range filter.
    pub points_out_of_range: u32,
    /// In-range samples dropped because the scan was full.
    pub points_overflowed: u32,
    /// Packets dropped for a bad check code while this revolution was received: the scan
    /// has gaps when this is not 0.
    pub packets_dropped: u32,
}

#[cfg(test)]
impl Scan {
    /// A revolution of `count` points straight ahead at 1 m, stamped `stamp_us` at 7 Hz: for
    /// the runtime's tests, where only whether a revolution has points matters.
    pub(crate) fn points_at_one_metre(stamp_us: f64, count: usize) -> Self {
        let point = ScanPoint {
            angle_rad: 0.0,
            range_m: 1.0,
            time_offset_us: 0.0,
        };
        Self {
            stamp_us,
            sample_period_us: 200.0,
            scan_frequency_hz: 7.0,
            points: vec![point; count],
            samples: 0,
            points_out_of_range: 0,
            points_overflowed: 0,
            packets_dropped: 0,
        }
    }
}

/// Timing of one packet: receive time of its last sample, minus its transmission time, and
/// the index of that sample in the revolution.
#[derive(Clone, Copy, Debug, Default)]
struct PacketTiming {
    last_sample_us: f64,
    last_index: u32,
}

/// Assembles packets into [`Scan`]s.
#[derive(Clone, Debug)]
pub struct ScanAssembler {
    config: ScanConfig,
    /// `Some` once the first zero packet has been seen.
    current: Option<Scan>,
    timings: [PacketTiming; MAX_TIMED_PACKETS],
    timings_len: usize,
}

impl ScanAssembler {
    /// An assembler waiting for the first start-of-revolution packet.
    pub fn new(config: ScanConfig) -> Self {
        Self {
            config,
            current: None,
            timings: [PacketTiming::default(); MAX_TIMED_PACKETS],
            timings_len: 0,
        }
    }

    /// The settings.
    pub const fn config(&self) -> &ScanConfig {
        &self.config
    }

    /// Note a packet dropped for a bad check code.
    pub fn packet_dropped(&mut self) {
        if let Some(scan) = &mut self.current {
            scan.packets_dropped = scan.packets_dropped.saturating_add(1);
        }
    }

    /// Add a verified packet completed at `now_us`; returns the finished revolution when
    /// `packet` starts the next one.
    pub fn push(&mut self, packet: Packet<'_>, now_us: u64) -> Option<Scan> {
        let finished = if packet.is_start_of_revolution() {
            let previous = self.current.replace(self.empty_scan());
            let finished = previous.and_then(|scan| self.finish(scan));
            self.timings_len = 0;
            finished
        } else {
            None
        };
        if packet.is_start_of_revolution() {
            self.note_frequency(&packet);
            return finished;
        }
        let Some(scan) = &mut self.current else {
            return finished;
        };
        if packet.scan_frequency_hz() > 0.0 {
            scan.scan_frequency_hz = packet.scan_frequency_hz();
        }
        let (range_min_m, range_max_m) = (self.config.range_min_m, self.config.range_max_m);
        for sample in packet.samples() {
            let index = scan.samples;
            scan.samples = scan.samples.saturating_add(1);
            let range_m = sample.distance_mm / 1000.0;
            if !(range_min_m..=range_max_m).contains(&range_m) {
                scan.points_out_of_range = scan.points_out_of_range.saturating_add(1);
                continue;
            }
            if scan.points.len() >= self.config.max_points {
                scan.points_overflowed = scan.points_overflowed.saturating_add(1);
                continue;
            }
            scan.points.push(ScanPoint {
                angle_rad: ccw_rad(sample.angle_cw_deg),
                range_m,
                // Sample index for now; converted to µs when the revolution is finished.
                time_offset_us: f64::from(index),
            });
        }
        if packet.sample_count() > 0 && self.timings_len < MAX_TIMED_PACKETS {
            let tx_us = packet.bytes().len() as f64 * BITS_PER_BYTE / BAUD_RATE * 1e6;
            self.timings[self.timings_len] = PacketTiming {
                last_sample_us: now_us as f64 - tx_us,
                last_index: scan.samples - 1,
            };
            self.timings_len += 1;
        }
        finished
    }

    fn empty_scan(&self) -> Scan {
        Scan {
            stamp_us: 0.0,
            sample_period_us: 0.0,
            scan_frequency_hz: 0.0,
            points: Vec::with_capacity(self.config.max_points),
            samples: 0,
            points_out_of_range: 0,
            points_overflowed: 0,
            packets_dropped: 0,
        }
    }

    fn note_frequency(&mut self, packet: &Packet<'_>) {
        if let Some(scan) = &mut self.current
            && packet.scan_frequency_hz() > 0.0
        {
            scan.scan_frequency_hz = packet.scan_frequency_hz();
        }
    }

    /// Stamp a revolution (see the module doc's time model); `None` if it has no samples.
    fn finish(&self, mut scan: Scan) -> Option<Scan> {
        if scan.samples == 0 || self.timings_len == 0 {
            return None;
        }
        let dt_us = if scan.scan_frequency_hz > 0.0 {
            1e6 / (scan.scan_frequency_hz * f64::from(scan.samples))
        } else {
            1e6 / NOMINAL_SAMPLE_RATE_HZ
        };
        scan.sample_period_us = dt_us;
        scan.stamp_us = self.timings[..self.timings_len]
            .iter()
            .map(|t| t.last_sample_us - f64::from(t.last_index) * dt_us)
            .fold(f64::INFINITY, f64::min);
        for point in &mut scan.points {
            point.time_offset_us *= dt_us;
        }
        Some(scan)
    }
}

/// Clockwise degrees → counter-clockwise radians in [−π, π).
fn ccw_rad(angle_cw_deg: f64) -> f64 {
    (-angle_cw_deg.to_radians() + PI).rem_euclid(2.0 * PI) - PI
}

#[cfg(test)]
mod tests {
    use super::super::packet::{PacketSpec, encode_packet};
    use super::*;

    fn packet(start: bool, first: f64, last: f64, d: &[f64]) -> Vec<u8> {
        let mut out = Vec::new();
        encode_packet(
            &PacketSpec {
                start_of_revolution: start,
                scan_frequency_hz: 5.0,
                first_angle_deg: first,
                last_angle_deg: last,
                distances_mm: d,
            },
            &mut out,
        )
        .unwrap();
        out
    }

    #[test]
    fn ccw_conversion() {
        assert_eq!(ccw_rad(0.0), 0.0);
        assert!((ccw_rad(90.0) + PI / 2.0).abs() < 1e-12);
        assert!((ccw_rad(270.0) - PI / 2.0).abs() < 1e-12);
        assert!((ccw_rad(180.0) + PI).abs() < 1e-12, "180° maps to −π");
    }

    #[test]
    fn revolution_is_stamped_by_its_first_sample() {
        let mut asm = ScanAssembler::new(ScanConfig::default());
        let zero = packet(true, 0.0, 0.0, &[0.0]);
        // Two packets of 10 samples; 20 samples per revolution at 5 Hz: dt = 10 ms.
        let a = packet(false, 1.0, 10.0, &[1000.0; 10]);
        let b = packet(false, 11.0, 20.0, &[1000.0; 10]);
        assert!(asm.push(Packet::new(&zero).unwrap(), 0).is_none());
        let tx_us = a.len() as f64 * 10.0 / 128_000.0 * 1e6;
        // First sample at t0 = 1 s: packet a's last sample (index 9) at t0 + 90 ms,
        // received one transmission time later; packet b's arrives 5 ms late.
        let t0 = 1_000_000.0;
        let rx_a = (t0 + 90_000.0 + tx_us) as u64;
        let rx_b = (t0 + 190_000.0 + tx_us + 5_000.0) as u64;
        assert!(asm.push(Packet::new(&a).unwrap(), rx_a).is_none());
        assert!(asm.push(Packet::new(&b).unwrap(), rx_b).is_none());
        let scan = asm.push(Packet::new(&zero).unwrap(), rx_b + 1000).unwrap();
        assert_eq!(scan.samples, 20);
        assert_eq!(scan.points.len(), 20);
        assert!((scan.sample_period_us - 10_000.0).abs() < 1e-9);
        assert!((scan.stamp_us - t0).abs() < 1.0, "stamp {}", scan.stamp_us);
        assert!((scan.points[19].time_offset_us - 190_000.0).abs() < 1e-6);
        assert_eq!(scan.scan_frequency_hz, 5.0);
    }

    #[test]
    fn range_filter_and_overflow_are_counted() {
        let config = ScanConfig {
            max_points: 3,
            ..ScanConfig::default()
        };
        let mut asm = ScanAssembler::new(config);
        let zero = packet(true, 0.0, 0.0, &[0.0]);
        let data = packet(
            false,
            1.0,
            7.0,
            &[0.0, 100.0, 120.0, 5000.0, 10_000.0, 10_001.0, 3000.0],
        );
        // Before the first zero packet: a partial revolution, discarded.
        assert!(asm.push(Packet::new(&data).unwrap(), 0).is_none());
        asm.push(Packet::new(&zero).unwrap(), 0);
        asm.packet_dropped();
        asm.push(Packet::new(&data).unwrap(), 10_000);
        let scan = asm.push(Packet::new(&zero).unwrap(), 20_000).unwrap();
        assert_eq!(scan.samples, 7);
        assert_eq!(scan.points_out_of_range, 3);
        let ranges: Vec<f64> = scan.points.iter().map(|p| p.range_m).collect();
        assert_eq!(ranges, [0.12, 5.0, 10.0]);
        assert_eq!(scan.points_overflowed, 1);
        assert_eq!(scan.packets_dropped, 1);
    }

    #[test]
    fn an_empty_revolution_gives_no_scan() {
        let mut asm = ScanAssembler::new(ScanConfig::default());
        let zero = packet(true, 0.0, 0.0, &[0.0]);
        asm.push(Packet::new(&zero).unwrap(), 0);
        assert!(asm.push(Packet::new(&zero).unwrap(), 1).is_none());
    }
}
