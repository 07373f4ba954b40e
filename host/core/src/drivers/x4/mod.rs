//! The YDLIDAR X4 protocol (original-system.md §3.2), fixed per §10.11.
//!
//! - [`packet`]: one scan packet — layout, check code, decoding, encoding;
//! - [`parser`]: bytes (any chunking) → verified packets;
//! - [`scan`]: packets → timestamped revolutions in the robot's angle convention;
//! - [`encoder`]: revolutions → bytes, for the simulator;
//! - [`info`]: the device-information and health requests and their replies;
//! - here: the host's commands, the response header, and [`X4Driver`], parser + assembler.
//!
//! The serial link runs at 128 000 baud, 8N1 (the real port is opened elsewhere). The host
//! sends [`Command::StartScan`]; the X4 answers with [`RESPONSE_HEADER`] and then streams
//! packets until [`Command::StopScan`].

pub mod encoder;
pub mod info;
pub mod packet;
pub mod parser;
pub mod scan;

use info::Request;
use parser::{Event, PacketParser, ParserStats};
use scan::{Scan, ScanAssembler, ScanConfig};

/// First byte of every host command.
pub const COMMAND_PREFIX: u8 = 0xA5;
/// The response descriptor the X4 sends after the start command (X4 development manual):
/// start flag `A5 5A`, response length 5 (30 bits, little-endian, `05 00 00`), mode and
/// type `40 81` (continuous response, scan data).
pub const RESPONSE_HEADER: [u8; 7] = [0xA5, 0x5A, 0x05, 0x00, 0x00, 0x40, 0x81];

/// A host → X4 command (two bytes each).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// Start scanning: `A5 60`.
    StartScan,
    /// Stop scanning: `A5 65`.
    StopScan,
    /// Soft restart: `A5 80` (unused by the robot; decoded so the simulator can answer).
    SoftRestart,
}

impl Command {
    /// The two command bytes.
    pub const fn bytes(self) -> [u8; 2] {
        [COMMAND_PREFIX, self.code()]
    }

    const fn code(self) -> u8 {
        match self {
            Self::StartScan => 0x60,
            Self::StopScan => 0x65,
            Self::SoftRestart => 0x80,
        }
    }

    fn from_code(code: u8) -> Option<Self> {
        [Self::StartScan, Self::StopScan, Self::SoftRestart]
            .into_iter()
            .find(|c| c.code() == code)
    }
}

/// What the X4 received from the host: a command, or a request with a single reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Received {
    /// A scan command.
    Command(Command),
    /// A device-information or health request.
    Request(Request),
}

/// The X4's side of the command link: bytes from the host → commands (for the simulator).
/// Unknown commands and stray bytes are skipped.
#[derive(Clone, Copy, Debug, Default)]
pub struct CommandDecoder {
    after_prefix: bool,
}

impl CommandDecoder {
    /// A decoder waiting for a command prefix.
    pub const fn new() -> Self {
        Self {
            after_prefix: false,
        }
    }

    /// Feed host bytes (any chunking); `on_command` gets every recognised command (requests
    /// are skipped: see [`Self::feed_all`]).
    pub fn feed(&mut self, bytes: &[u8], mut on_command: impl FnMut(Command)) {
        self.feed_all(bytes, |received| {
            if let Received::Command(command) = received {
                on_command(command);
            }
        });
    }

    /// Feed host bytes (any chunking); `on_received` gets every recognised command and
    /// request.
    pub fn feed_all(&mut self, bytes: &[u8], mut on_received: impl FnMut(Received)) {
        for &byte in bytes {
            if self.after_prefix {
                self.after_prefix = byte == COMMAND_PREFIX;
                if let Some(command) = Command::from_code(byte) {
                    on_received(Received::Command(command));
                } else if let Some(request) = Request::from_code(byte) {
                    on_received(Received::Request(request));
                }
            } else {
                self.after_prefix = byte == COMMAND_PREFIX;
            }
        }
    }
}

/// The host's X4 driver: received bytes → [`Scan`]s. Pure: the caller passes the receive
/// time of each chunk (µs on a monotonic clock).
#[derive(Clone, Debug)]
pub struct X4Driver {
    parser: PacketParser,
    assembler: ScanAssembler,
    last_packet_us: Option<u64>,
}

impl X4Driver {
    /// A driver with the given scan settings.
    pub fn new(config: ScanConfig) -> Self {
        Self {
            parser: PacketParser::new(),
            assembler: ScanAssembler::new(config),
            last_packet_us: None,
        }
    }

    /// Feed bytes received at `now_us`; `on_scan` gets every completed revolution.
    pub fn feed(&mut self, bytes: &[u8], now_us: u64, mut on_scan: impl FnMut(Scan)) {
        let assembler = &mut self.assembler;
        let last_packet_us = &mut self.last_packet_us;
        self.parser.feed(bytes, |event| match event {
            Event::Packet(packet) => {
                *last_packet_us = Some(now_us);
                if let Some(scan) = assembler.push(packet, now_us) {
                    on_scan(scan);
                }
            }
            Event::ChecksumError => assembler.packet_dropped(),
        });
    }

    /// When the last packet with a valid check code was received, µs (`None`: none yet):
    /// the stream's liveness, finer than revolutions ([`crate::runtime::PacketWatch`]).
    pub const fn last_packet_us(&self) -> Option<u64> {
        self.last_packet_us
    }

    /// Parser counters (packets, check-code errors, skipped bytes).
    pub const fn stats(&self) -> ParserStats {
        self.parser.stats()
    }
}

#[cfg(test)]
mod tests {
    use super::encoder::RevolutionEncoder;
    use super::packet::angle_correction_deg;
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    /// The response header, one revolution of `distances`, then the next zero packet (which
    /// completes the revolution).
    fn stream(encoder: &RevolutionEncoder, step_deg: f64, distances: &[f64]) -> Vec<u8> {
        let mut out = RESPONSE_HEADER.to_vec();
        encoder
            .encode_revolution(0.0, step_deg, distances, &mut out)
            .unwrap();
        encoder
            .encode_revolution(0.0, step_deg, &[], &mut out)
            .unwrap();
        out
    }

    fn wrap_pi(a: f64) -> f64 {
        (a + PI).rem_euclid(2.0 * PI) - PI
    }

    #[test]
    fn commands() {
        assert_eq!(Command::StartScan.bytes(), [0xA5, 0x60]);
        assert_eq!(Command::StopScan.bytes(), [0xA5, 0x65]);
        let mut decoder = CommandDecoder::new();
        let mut got = Vec::new();
        decoder.feed(&[0x00, 0xA5], |c| got.push(c));
        decoder.feed(&[0x60, 0xA5, 0xA5, 0x65, 0xA5, 0x99, 0x65], |c| got.push(c));
        assert_eq!(got, [Command::StartScan, Command::StopScan]);
        let mut all = Vec::new();
        decoder.feed_all(&[0xA5, 0x65, 0x90, 0xA5, 0x90, 0xA5], |r| all.push(r));
        decoder.feed_all(&[0x91, 0xA5, 0x60], |r| all.push(r));
        assert_eq!(
            all,
            [
                Received::Command(Command::StopScan),
                Received::Request(Request::DeviceInfo),
                Received::Request(Request::Health),
                Received::Command(Command::StartScan),
            ]
        );
    }

    proptest! {
        #[test]
        fn encoder_to_driver_round_trip(
            distances in proptest::collection::vec(
                prop_oneof![Just(0.0), 50.0..12_000.0f64], 1..900),
            per_packet in 1u8..=255,
            freq_x10 in 0u8..=127,
        ) {
            let step_deg = 360.0 / distances.len() as f64;
            let encoder = RevolutionEncoder {
                samples_per_packet: per_packet,
                scan_frequency_hz: f64::from(freq_x10) / 10.0,
            };
            let bytes = stream(&encoder, step_deg, &distances);
            let config = ScanConfig::default();
            let mut driver = X4Driver::new(config);
            let mut scans = Vec::new();
            driver.feed(&bytes, 1_000_000, |s| scans.push(s));
            prop_assert_eq!(scans.len(), 1);
            let scan = &scans[0];
            prop_assert_eq!(scan.samples as usize, distances.len());
            // Expected points, computed from the manual's formulas directly.
            let expected: Vec<(f64, f64)> = distances
                .iter()
                .enumerate()
                .filter_map(|(k, &d)| {
                    let d = (d * 4.0).round() / 4.0;
                    let range_m = d / 1000.0;
                    let head = k as f64 * step_deg;
                    let cw_deg = head + angle_correction_deg(d);
                    (config.range_min_m..=config.range_max_m)
                        .contains(&range_m)
                        .then(|| (wrap_pi(-cw_deg.to_radians()), range_m))
                })
                .collect();
            prop_assert_eq!(scan.points.len(), expected.len());
            prop_assert_eq!(
                scan.points_out_of_range as usize,
                distances.len() - expected.len()
            );
            for (point, (angle, range)) in scan.points.iter().zip(expected) {
                prop_assert_eq!(point.range_m, range);
                // FSA/LSA are quantised to 1/64°; interpolation stays within that.
                let error = wrap_pi(point.angle_rad - angle).abs();
                prop_assert!(error < (1.0 / 64.0f64).to_radians(), "error {}", error);
            }
        }
    }

    #[test]
    fn a_scan_split_at_every_offset_gives_the_same_result() {
        let distances: Vec<f64> = (0..200).map(|k| 300.0 + 17.0 * f64::from(k)).collect();
        let encoder = RevolutionEncoder {
            samples_per_packet: 37,
            scan_frequency_hz: 7.0,
        };
        let bytes = stream(&encoder, 1.8, &distances);
        let whole = {
            let mut driver = X4Driver::new(ScanConfig::default());
            let mut scans = Vec::new();
            driver.feed(&bytes, 500, |s| scans.push(s));
            scans
        };
        assert_eq!(whole.len(), 1);
        assert_eq!(whole[0].points.len(), 200);
        for cut in 0..=bytes.len() {
            let mut driver = X4Driver::new(ScanConfig::default());
            let mut scans = Vec::new();
            driver.feed(&bytes[..cut], 500, |s| scans.push(s));
            driver.feed(&bytes[cut..], 500, |s| scans.push(s));
            assert_eq!(scans, whole, "split at {cut}");
        }
        // Byte by byte.
        let mut driver = X4Driver::new(ScanConfig::default());
        let mut scans = Vec::new();
        for b in &bytes {
            driver.feed(std::slice::from_ref(b), 500, |s| scans.push(s));
        }
        assert_eq!(scans, whole);
    }

    #[test]
    fn a_corrupted_packet_is_dropped_and_reported_in_the_scan() {
        let encoder = RevolutionEncoder {
            samples_per_packet: 10,
            scan_frequency_hz: 7.0,
        };
        let mut bytes = stream(&encoder, 1.0, &[1000.0; 30]);
        // Corrupt a sample byte of the second data packet (after the response header, the
        // zero packet of 12 bytes and the first data packet of 30 bytes).
        let at = RESPONSE_HEADER.len() + 12 + 30 + 15;
        bytes[at] ^= 0x10;
        let mut driver = X4Driver::new(ScanConfig::default());
        let mut scans = Vec::new();
        driver.feed(&bytes, 0, |s| scans.push(s));
        assert_eq!(scans.len(), 1);
        assert_eq!(scans[0].points.len(), 20);
        assert_eq!(scans[0].packets_dropped, 1);
        assert_eq!(driver.stats().checksum_errors, 1);
        assert_eq!(driver.stats().response_headers, 1);
    }

    #[test]
    fn the_last_packet_time_moves_with_valid_packets_only() {
        let encoder = RevolutionEncoder {
            samples_per_packet: 10,
            scan_frequency_hz: 7.0,
        };
        let bytes = stream(&encoder, 1.0, &[1000.0; 30]);
        let mut driver = X4Driver::new(ScanConfig::default());
        assert_eq!(driver.last_packet_us(), None);
        driver.feed(&bytes, 7_000, |_| {});
        assert_eq!(driver.last_packet_us(), Some(7_000));
        driver.feed(&[0x55; 64], 9_000, |_| {});
        assert_eq!(driver.last_packet_us(), Some(7_000), "garbage is no packet");
        let mut corrupted = bytes[RESPONSE_HEADER.len()..RESPONSE_HEADER.len() + 12].to_vec();
        corrupted[11] ^= 0x10;
        driver.feed(&corrupted, 11_000, |_| {});
        assert_eq!(
            driver.last_packet_us(),
            Some(7_000),
            "nor is a corrupted one"
        );
    }

    /// Stamp error of the time model (scan.rs) against known acquisition times: packets
    /// of 40 samples, each received after its transmission time plus a random delay of
    /// 0..4 ms. Prints the errors (`cargo test -p ratf-host --lib stamp_error -- --nocapture`).
    #[test]
    fn stamp_error_with_late_receive_times() {
        for true_frequency_hz in [7.0, 7.04] {
            let samples_per_revolution = 720usize;
            let dt_us = 1e6 / (true_frequency_hz * samples_per_revolution as f64);
            let encoder = RevolutionEncoder {
                samples_per_packet: 40,
                // CT carries 0.1 Hz steps: 7.04 Hz is reported as 7.0.
                scan_frequency_hz: 7.0,
            };
            let mut driver = X4Driver::new(ScanConfig::default());
            let mut lcg: u64 = 12345;
            let mut errors_us = Vec::new();
            let mut start_us = 1_000_000.0;
            for _ in 0..10 {
                let mut bytes = Vec::new();
                encoder
                    .encode_revolution(0.0, 0.5, &[2000.0; 720], &mut bytes)
                    .unwrap();
                // Zero packet (12 bytes), then 18 packets of 40 samples (90 bytes each).
                let mut scans = Vec::new();
                driver.feed(&bytes[..12], start_us as u64, |s| scans.push(s));
                for (j, packet) in bytes[12..].chunks(90).enumerate() {
                    let last_sample_us = start_us + ((j + 1) * 40 - 1) as f64 * dt_us;
                    lcg = lcg
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let delay_us = (lcg >> 33) as f64 / (1u64 << 31) as f64 * 4000.0;
                    let rx_us = last_sample_us + 90.0 * 10.0 / 128_000.0 * 1e6 + delay_us;
                    driver.feed(packet, rx_us as u64, |s| scans.push(s));
                }
                if let Some(scan) = scans.first() {
                    errors_us.push(scan.stamp_us - (start_us - 1e6 / true_frequency_hz));
                }
                start_us += 1e6 / true_frequency_hz;
            }
            let worst = errors_us.iter().fold(0.0f64, |w, e| w.max(e.abs()));
            println!(
                "X4 stamp error at {true_frequency_hz} Hz (reported 7.0): {} scans, worst {worst:.0} µs, errors {:?}",
                errors_us.len(),
                errors_us.iter().map(|e| e.round()).collect::<Vec<_>>()
            );
            assert_eq!(errors_us.len(), 9);
            assert!(worst < 2_000.0, "worst stamp error {worst} µs");
        }
    }
}
