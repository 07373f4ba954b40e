//! One YDLIDAR X4 scan packet: layout, check code, decoding of its samples, and encoding.
//!
//! Layout (all multi-byte fields little-endian; original-system.md §3.2, X4 development
//! manual):
//!
//! | offset | bytes | field | meaning |
//! |---|---|---|---|
//! | 0 | 2 | PH  | packet header 0x55AA (bytes `AA 55`) |
//! | 2 | 1 | CT  | bit 0: 1 = start-of-revolution ("zero") packet; bits 7:1: scan frequency × 10 (Hz) |
//! | 3 | 1 | LSN | number of samples |
//! | 4 | 2 | FSA | first sample angle: bit 0 is a check bit (always 1), bits 15:1 = angle × 64 (degrees) |
//! | 6 | 2 | LSA | last sample angle, same encoding |
//! | 8 | 2 | CS  | check code |
//! | 10 | 2 × LSN | Si | samples: distance × 4 (mm) |
//!
//! **Check code.** CS is the XOR of every 16-bit little-endian word of the packet except CS
//! itself: PH ⊕ (CT | LSN << 8) ⊕ FSA ⊕ LSA ⊕ S0 ⊕ … ⊕ S(LSN−1). This is the manual's
//! definition, and it is how the vendor SDK computes it (it seeds the running XOR with PH,
//! folds in FSA, every sample, then `CT | LSN << 8` and LSA; XOR is order-independent).
//! Every field is a whole number of 16-bit words at an even offset, so the check code is
//! simply the XOR of the words at offsets 0, 2, 4, 6, 10, 12, …; [`check_code`] computes it
//! that way and the tests check it against the field-by-field definition.
//!
//! **Angles.** The X4 turns clockwise seen from above, and its angles grow clockwise. For
//! sample i of n (0-based), with first/last angles FSA, LSA in degrees and Δ = LSA − FSA
//! (+360 when negative, the packet crossed 0°):
//!
//! - raw angle = FSA + Δ·i/(n − 1) (for n = 1: FSA, no division);
//! - corrected angle = raw angle + AngCorrect(d), with d the distance in mm and
//!   AngCorrect(d) = 0 if d = 0, else atan(21.8·(155.3 − d)/(155.3·d)) converted from
//!   radians to degrees with ×180/π (the manual's formula; the original code used ×360/π,
//!   doubling it, original-system.md §3.2). 21.8 mm and 155.3 mm are the manual's
//!   constants of the triangulation geometry. The correction is +4.44° at 100 mm, 0 at
//!   155.3 mm, and tends to −atan(21.8/155.3) = −7.99° far away.
//!
//! Conversion to the robot's convention is done by the scan assembler (`super::scan`).

use std::f64::consts::PI;

/// Packet header bytes (PH = 0x55AA, little-endian).
pub const PACKET_HEADER: [u8; 2] = [0xAA, 0x55];
/// Bytes before the samples: PH, CT, LSN, FSA, LSA, CS.
pub const PACKET_HEADER_LEN: usize = 10;
/// Largest number of samples in one packet: LSN is one byte.
pub const MAX_SAMPLES_PER_PACKET: usize = u8::MAX as usize;
/// Largest packet on the wire, bytes.
pub const MAX_PACKET_LEN: usize = PACKET_HEADER_LEN + 2 * MAX_SAMPLES_PER_PACKET;
/// Angle correction constant (mm), X4 development manual.
pub const CORRECTION_OFFSET_MM: f64 = 21.8;
/// Angle correction constant (mm), X4 development manual.
pub const CORRECTION_BASE_MM: f64 = 155.3;
/// Largest distance a sample can carry, mm (a 16-bit quarter-millimetre count).
pub const MAX_DISTANCE_MM: f64 = u16::MAX as f64 / 4.0;
/// Largest scan frequency CT can carry, Hz (7 bits of frequency × 10).
pub const MAX_SCAN_FREQUENCY_HZ: f64 = 12.7;

/// The X4 check code of a packet's bytes: the XOR of every little-endian 16-bit word except
/// the CS word at offset 8. `bytes` is the whole packet; a trailing odd byte is ignored (a
/// well-formed packet has none).
pub fn check_code(bytes: &[u8]) -> u16 {
    bytes
        .chunks_exact(2)
        .enumerate()
        .filter(|&(word, _)| word != 4)
        .fold(0, |cs, (_, w)| cs ^ u16::from_le_bytes([w[0], w[1]]))
}

/// The X4's angle correction for a sample at `distance_mm`, degrees (see the module doc).
pub fn angle_correction_deg(distance_mm: f64) -> f64 {
    if distance_mm == 0.0 {
        0.0
    } else {
        (CORRECTION_OFFSET_MM * (CORRECTION_BASE_MM - distance_mm)
            / (CORRECTION_BASE_MM * distance_mm))
            .atan()
            * 180.0
            / PI
    }
}

/// Degrees carried by an FSA/LSA field.
fn angle_field_deg(raw: u16) -> f64 {
    f64::from(raw >> 1) / 64.0
}

/// A complete packet whose check code has been verified, borrowed from the parser's buffer.
#[derive(Clone, Copy, Debug)]
pub struct Packet<'a> {
    bytes: &'a [u8],
}

impl<'a> Packet<'a> {
    /// A view of `bytes` if it is exactly one well-formed packet with a correct check code;
    /// `None` otherwise.
    pub fn new(bytes: &'a [u8]) -> Option<Self> {
        if bytes.len() < PACKET_HEADER_LEN || bytes[..2] != PACKET_HEADER {
            return None;
        }
        let packet = Self { bytes };
        let expected_len = PACKET_HEADER_LEN + 2 * packet.sample_count();
        (bytes.len() == expected_len && check_code(bytes) == packet.cs()).then_some(packet)
    }

    fn word(&self, offset: usize) -> u16 {
        u16::from_le_bytes([self.bytes[offset], self.bytes[offset + 1]])
    }

    fn cs(&self) -> u16 {
        self.word(8)
    }

    /// The packet's bytes.
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// True for the start-of-revolution ("zero") packet (CT bit 0).
    pub fn is_start_of_revolution(&self) -> bool {
        self.bytes[2] & 1 == 1
    }

    /// Scan frequency reported in CT bits 7:1, Hz (0.1 Hz resolution; 0 = not reported).
    pub fn scan_frequency_hz(&self) -> f64 {
        f64::from(self.bytes[2] >> 1) / 10.0
    }

    /// LSN: number of samples.
    pub fn sample_count(&self) -> usize {
        usize::from(self.bytes[3])
    }

    /// FSA in degrees (clockwise, the X4's own convention), before correction.
    pub fn first_angle_deg(&self) -> f64 {
        angle_field_deg(self.word(4))
    }

    /// LSA in degrees (clockwise, the X4's own convention), before correction.
    pub fn last_angle_deg(&self) -> f64 {
        angle_field_deg(self.word(6))
    }

    /// Distance of sample `i`, mm (Si / 4); `None` past the last sample.
    pub fn distance_mm(&self, i: usize) -> Option<f64> {
        (i < self.sample_count()).then(|| f64::from(self.word(PACKET_HEADER_LEN + 2 * i)) / 4.0)
    }

    /// Every sample as (corrected clockwise angle in degrees within [0, 360), distance mm),
    /// in order (see the module doc for the formulas).
    pub fn samples(&self) -> impl Iterator<Item = Sample> + '_ {
        let n = self.sample_count();
        let first = self.first_angle_deg();
        let mut span = self.last_angle_deg() - first;
        if span < 0.0 {
            span += 360.0;
        }
        (0..n).map(move |i| {
            let distance_mm = self.distance_mm(i).unwrap_or(0.0);
            let raw = if n > 1 {
                first + span * i as f64 / (n - 1) as f64
            } else {
                first
            };
            Sample {
                angle_cw_deg: (raw + angle_correction_deg(distance_mm)).rem_euclid(360.0),
                distance_mm,
            }
        })
    }
}

/// One decoded sample in the X4's own convention.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Corrected angle, degrees clockwise from the X4's zero, in [0, 360).
    pub angle_cw_deg: f64,
    /// Distance, mm (0 = no return).
    pub distance_mm: f64,
}

/// What a packet to encode holds (angles before correction, as the X4 sends them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PacketSpec<'a> {
    /// CT bit 0: this is the start-of-revolution packet.
    pub start_of_revolution: bool,
    /// Scan frequency to report in CT, Hz (0 ..= 12.7, rounded to 0.1 Hz).
    pub scan_frequency_hz: f64,
    /// FSA, degrees clockwise (any value; reduced to [0, 360), rounded to 1/64°).
    pub first_angle_deg: f64,
    /// LSA, degrees clockwise (same encoding).
    pub last_angle_deg: f64,
    /// Sample distances, mm (0 ..= 16383.75, rounded to 0.25 mm); at most 255 samples.
    pub distances_mm: &'a [f64],
}

/// Why a packet cannot be encoded.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum EncodeError {
    /// LSN is one byte.
    #[error("{0} samples do not fit in one X4 packet (at most 255)")]
    TooManySamples(usize),
    /// A sample distance is negative, not finite or above 16383.75 mm.
    #[error("distance {0} mm cannot be encoded (0 ..= 16383.75 mm)")]
    BadDistance(f64),
    /// The scan frequency is negative, not finite or above 12.7 Hz.
    #[error("scan frequency {0} Hz cannot be encoded (0 ..= 12.7 Hz)")]
    BadFrequency(f64),
    /// An angle is not finite.
    #[error("angle {0}° is not finite")]
    BadAngle(f64),
}

/// FSA/LSA field for `angle_deg`: angle × 64 in bits 15:1, check bit 0 set.
fn angle_field(angle_deg: f64) -> Result<u16, EncodeError> {
    if !angle_deg.is_finite() {
        return Err(EncodeError::BadAngle(angle_deg));
    }
    let units = (angle_deg.rem_euclid(360.0) * 64.0).round() as u32 % (360 * 64);
    Ok(((units << 1) | 1) as u16)
}

/// Append the packet `spec` describes to `out`, with its check code; returns its length.
pub fn encode_packet(spec: &PacketSpec<'_>, out: &mut Vec<u8>) -> Result<usize, EncodeError> {
    let n = spec.distances_mm.len();
    let lsn = u8::try_from(n).map_err(|_| EncodeError::TooManySamples(n))?;
    let f = spec.scan_frequency_hz;
    if !(0.0..=MAX_SCAN_FREQUENCY_HZ).contains(&f) {
        return Err(EncodeError::BadFrequency(f));
    }
    let ct = (((f * 10.0).round() as u8) << 1) | u8::from(spec.start_of_revolution);
    let fsa = angle_field(spec.first_angle_deg)?;
    let lsa = angle_field(spec.last_angle_deg)?;
    let start = out.len();
    out.extend_from_slice(&PACKET_HEADER);
    out.extend_from_slice(&[ct, lsn]);
    out.extend_from_slice(&fsa.to_le_bytes());
    out.extend_from_slice(&lsa.to_le_bytes());
    out.extend_from_slice(&[0, 0]);
    for &d in spec.distances_mm {
        if !(0.0..=MAX_DISTANCE_MM).contains(&d) {
            out.truncate(start);
            return Err(EncodeError::BadDistance(d));
        }
        out.extend_from_slice(&((d * 4.0).round() as u16).to_le_bytes());
    }
    let cs = check_code(&out[start..]);
    out[start + 8..start + 10].copy_from_slice(&cs.to_le_bytes());
    Ok(out.len() - start)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The check code computed field by field, as the manual defines it.
    fn check_code_by_fields(ct: u8, lsn: u8, fsa: u16, lsa: u16, samples: &[u16]) -> u16 {
        samples.iter().fold(
            0x55AA ^ (u16::from(ct) | (u16::from(lsn) << 8)) ^ fsa ^ lsa,
            |cs, s| cs ^ s,
        )
    }

    #[test]
    fn check_code_matches_the_field_definition() {
        let distances = [1000.0, 250.25, 0.0, 16383.75, 3.5];
        let spec = PacketSpec {
            start_of_revolution: false,
            scan_frequency_hz: 7.2,
            first_angle_deg: 10.5,
            last_angle_deg: 12.25,
            distances_mm: &distances,
        };
        let mut bytes = Vec::new();
        encode_packet(&spec, &mut bytes).unwrap();
        let samples: Vec<u16> = distances.iter().map(|d| (d * 4.0) as u16).collect();
        let fsa = ((10.5 * 64.0) as u16) << 1 | 1;
        let lsa = ((12.25 * 64.0) as u16) << 1 | 1;
        let expected = check_code_by_fields(72 << 1, 5, fsa, lsa, &samples);
        assert_eq!(u16::from_le_bytes([bytes[8], bytes[9]]), expected);
        assert_eq!(bytes[2], 144);
        assert_eq!(bytes[3], 5);
        assert!(Packet::new(&bytes).is_some());
    }

    #[test]
    fn a_hand_built_packet_decodes() {
        // CT = 0 (no frequency), LSN = 2, FSA = 90°, LSA = 91°, samples 400 mm and 0.
        let fsa: u16 = (90 * 64) << 1 | 1;
        let lsa: u16 = (91 * 64) << 1 | 1;
        let s = [1600u16, 0];
        let cs = check_code_by_fields(0, 2, fsa, lsa, &s);
        let mut bytes = vec![0xAA, 0x55, 0, 2];
        for w in [fsa, lsa, cs, s[0], s[1]] {
            bytes.extend_from_slice(&w.to_le_bytes());
        }
        let packet = Packet::new(&bytes).unwrap();
        let samples: Vec<Sample> = packet.samples().collect();
        assert_eq!(samples.len(), 2);
        assert_eq!(samples[0].distance_mm, 400.0);
        let expected0 = 90.0
            + (21.8 * (155.3 - 400.0) / (155.3 * 400.0_f64))
                .atan()
                .to_degrees();
        assert!((samples[0].angle_cw_deg - expected0).abs() < 1e-9);
        // A zero distance gets no correction.
        assert_eq!(samples[1].angle_cw_deg, 91.0);
        let mut corrupted = bytes.clone();
        corrupted[11] ^= 0x01;
        assert!(Packet::new(&corrupted).is_none());
    }

    #[test]
    fn angle_correction_sign_and_magnitude() {
        // Reference values computed independently (Python `math.degrees(math.atan(...))`).
        for (d, expected) in [
            (100.0, 4.438_771),
            (155.3, 0.0),
            (400.0, -4.908_146),
            (1000.0, -6.762_186),
            (10_000.0, -7.868_069),
        ] {
            let got = angle_correction_deg(d);
            assert!(
                (got - expected).abs() < 1e-5,
                "d = {d}: {got} vs {expected}"
            );
        }
        assert_eq!(angle_correction_deg(0.0), 0.0);
        // The far limit is −atan(21.8/155.3).
        let limit = -(21.8_f64 / 155.3).atan().to_degrees();
        assert!((angle_correction_deg(1e9) - limit).abs() < 1e-5);
        assert!((limit + 7.9905).abs() < 1e-3);
    }

    #[test]
    fn a_single_sample_packet_uses_fsa() {
        let spec = PacketSpec {
            start_of_revolution: false,
            scan_frequency_hz: 7.0,
            first_angle_deg: 45.0,
            last_angle_deg: 45.0,
            distances_mm: &[155.3],
        };
        let mut bytes = Vec::new();
        encode_packet(&spec, &mut bytes).unwrap();
        let samples: Vec<Sample> = Packet::new(&bytes).unwrap().samples().collect();
        assert_eq!(samples.len(), 1);
        // 155.3 mm is quantised to 155.25 mm, whose correction is tiny but not zero.
        let expected = 45.0 + angle_correction_deg(155.25);
        assert!((samples[0].angle_cw_deg - expected).abs() < 1e-9);
        assert!((samples[0].angle_cw_deg - 45.0).abs() < 0.01);
    }

    #[test]
    fn wrapping_packets_cross_zero() {
        let spec = PacketSpec {
            start_of_revolution: false,
            scan_frequency_hz: 7.0,
            first_angle_deg: 359.0,
            last_angle_deg: 1.0,
            distances_mm: &[0.0, 0.0, 0.0],
        };
        let mut bytes = Vec::new();
        encode_packet(&spec, &mut bytes).unwrap();
        let angles: Vec<f64> = Packet::new(&bytes)
            .unwrap()
            .samples()
            .map(|s| s.angle_cw_deg)
            .collect();
        assert_eq!(angles, [359.0, 0.0, 1.0]);
    }

    #[test]
    fn encoding_rejects_bad_input() {
        let too_many = vec![0.0; 256];
        let mut out = Vec::new();
        let base = PacketSpec {
            start_of_revolution: false,
            scan_frequency_hz: 7.0,
            first_angle_deg: 0.0,
            last_angle_deg: 1.0,
            distances_mm: &too_many,
        };
        assert_eq!(
            encode_packet(&base, &mut out),
            Err(EncodeError::TooManySamples(256))
        );
        let spec = PacketSpec {
            distances_mm: &[1.0, 20_000.0],
            ..base
        };
        assert_eq!(
            encode_packet(&spec, &mut out),
            Err(EncodeError::BadDistance(20_000.0))
        );
        assert!(out.is_empty(), "a failed encode leaves nothing behind");
        let spec = PacketSpec {
            distances_mm: &[1.0],
            scan_frequency_hz: 13.0,
            ..base
        };
        assert_eq!(
            encode_packet(&spec, &mut out),
            Err(EncodeError::BadFrequency(13.0))
        );
        let spec = PacketSpec {
            distances_mm: &[1.0],
            first_angle_deg: f64::NAN,
            ..base
        };
        assert!(matches!(
            encode_packet(&spec, &mut out),
            Err(EncodeError::BadAngle(_))
        ));
    }
}
