//! Encoder: whole revolutions → the bytes a real X4 sends, for the simulator.
//!
//! A revolution is a start-of-revolution packet (LSN = 1, distance 0, at the first sample's
//! angle) followed by data packets of at most [`RevolutionEncoder::samples_per_packet`]
//! samples each. Samples are given at uniformly spaced *head* angles (the X4's uncorrected,
//! clockwise angles); the receiver adds the angle correction of `super::packet`.
//!
//! A simulator must therefore report, for head angle θ, the distance d of the point at
//! bearing θ + AngCorrect(d): `ratf_sim::lidar` does so by ray-casting the beam geometry
//! the correction formula describes.

use super::packet::{EncodeError, PacketSpec, encode_packet};

/// Splits revolutions into X4 packets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RevolutionEncoder {
    /// Most samples per data packet (1..=255). The X4 sends packets of up to about 40
    /// samples; any value the format allows works.
    pub samples_per_packet: u8,
    /// Scan frequency reported in CT, Hz (0..=12.7).
    pub scan_frequency_hz: f64,
}

impl Default for RevolutionEncoder {
    fn default() -> Self {
        Self {
            samples_per_packet: 40,
            scan_frequency_hz: 7.0,
        }
    }
}

impl RevolutionEncoder {
    /// Append one revolution to `out`: sample k is at head angle
    /// `first_angle_deg + k·step_deg` (clockwise degrees) with distance `distances_mm[k]`.
    /// Returns the bytes appended; on error `out` is left as it was.
    pub fn encode_revolution(
        &self,
        first_angle_deg: f64,
        step_deg: f64,
        distances_mm: &[f64],
        out: &mut Vec<u8>,
    ) -> Result<usize, EncodeError> {
        let start = out.len();
        let result = self.encode_into(first_angle_deg, step_deg, distances_mm, out);
        if result.is_err() {
            out.truncate(start);
        }
        result.map(|()| out.len() - start)
    }

    fn encode_into(
        &self,
        first_angle_deg: f64,
        step_deg: f64,
        distances_mm: &[f64],
        out: &mut Vec<u8>,
    ) -> Result<(), EncodeError> {
        if !step_deg.is_finite() {
            return Err(EncodeError::BadAngle(step_deg));
        }
        encode_packet(
            &PacketSpec {
                start_of_revolution: true,
                scan_frequency_hz: self.scan_frequency_hz,
                first_angle_deg,
                last_angle_deg: first_angle_deg,
                distances_mm: &[0.0],
            },
            out,
        )?;
        let per_packet = usize::from(self.samples_per_packet.max(1));
        for (chunk_index, chunk) in distances_mm.chunks(per_packet).enumerate() {
            let first_k = chunk_index * per_packet;
            let last_k = first_k + chunk.len() - 1;
            encode_packet(
                &PacketSpec {
                    start_of_revolution: false,
                    scan_frequency_hz: self.scan_frequency_hz,
                    first_angle_deg: first_angle_deg + first_k as f64 * step_deg,
                    last_angle_deg: first_angle_deg + last_k as f64 * step_deg,
                    distances_mm: chunk,
                },
                out,
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::packet::Packet;
    use super::super::parser::{Event, PacketParser};
    use super::*;

    #[test]
    fn a_revolution_is_a_zero_packet_then_data_packets() {
        let encoder = RevolutionEncoder {
            samples_per_packet: 4,
            scan_frequency_hz: 7.0,
        };
        let mut out = Vec::new();
        encoder
            .encode_revolution(0.5, 1.0, &[1000.0; 10], &mut out)
            .unwrap();
        let mut parser = PacketParser::new();
        let mut packets = Vec::new();
        parser.feed(&out, |e| {
            if let Event::Packet(p) = e {
                packets.push((
                    p.is_start_of_revolution(),
                    p.sample_count(),
                    p.first_angle_deg(),
                    p.last_angle_deg(),
                ));
            }
        });
        assert_eq!(
            packets,
            [
                (true, 1, 0.5, 0.5),
                (false, 4, 0.5, 3.5),
                (false, 4, 4.5, 7.5),
                (false, 2, 8.5, 9.5)
            ]
        );
        assert!(Packet::new(&out[..12]).is_some());
    }

    #[test]
    fn errors_leave_the_output_untouched() {
        let mut out = vec![1, 2, 3];
        let result =
            RevolutionEncoder::default().encode_revolution(0.0, 1.0, &[100.0, -1.0], &mut out);
        assert_eq!(result, Err(EncodeError::BadDistance(-1.0)));
        assert_eq!(out, [1, 2, 3]);
    }
}
