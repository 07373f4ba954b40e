//! Encoder: whole revolutions → the bytes a real X4 sends, for the simulator.
//!
//! A revolution is a start-of-revolution packet (LSN = 1, distance 0, at the first sample's
//! angle) followed by data packets of at most [`RevolutionEncoder::samples_per_packet`]
//! samples each. Samples are given at uniformly spaced *head* angles (the X4's uncorrected,
//! clockwise angles); the receiver adds the angle correction of `super::packet`.
//!
//! A simulator that ray-casts must therefore report, for head angle θ, the distance d of
//! the point at bearing θ + AngCorrect(d). [`distance_at_head_angle`] finds that d.

use super::packet::{
    EncodeError, PacketSpec, angle_correction_deg, distance_for_correction_mm, encode_packet,
};

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

/// Where [`distance_at_head_angle`] starts along the curve of consistent samples, mm: below
/// the X4's 120 mm minimum range (datasheet).
const SEARCH_START_MM: f64 = 100.0;
/// Largest bearing change between two probes of [`distance_at_head_angle`], degrees. An
/// object narrower than this (4.4 mm at 1 m) can be missed; the beacons are ~100 mm wide.
const PROBE_BEARING_STEP_DEG: f64 = 0.25;
/// Probes before [`distance_at_head_angle`] gives up (no return). From 100 mm to the far
/// limit the bearing sweeps 12.4°, about 50 probes at 0.25°.
const MAX_PROBES: usize = 96;
/// Bisection steps that locate the surface once it is bracketed.
const BISECTIONS: usize = 24;
/// Tolerance for "the surface is at or before the probe", mm.
const BLOCKED_TOLERANCE_MM: f64 = 0.01;
/// Largest gap between C and the surface at the bisected crossing for it to count as one,
/// mm (a real crossing closes to ~1e-5 mm; a side entry into a shadow does not close).
const CROSSING_TOLERANCE_MM: f64 = 0.05;

/// The distance the X4 reports at head angle `head_angle_cw_deg`, mm (0 = no return), given
/// `distance_at_bearing`: the distance from the lidar's centre to the first surface at a
/// clockwise bearing in degrees (0 for no return).
///
/// The decoder places a sample of distance d at bearing head + AngCorrect(d), range d. For
/// one head angle these points form a curve C(d) (nearly a ray, bent by the correction); the
/// X4 reports the first surface C meets. This walks C outwards from 100 mm: at each probe d
/// it casts along C's bearing; a surface at or before d means C has entered the surface's
/// shadow, and bisection finds where. If C crossed the surface there, that d satisfies
/// d = distance_at_bearing(head + AngCorrect(d)) and is returned; if C swung into the
/// shadow sideways (a silhouette edge), the walk goes on. Otherwise the ray is free up to
/// the surface it found, so the next probe moves to that surface or to where C's bearing
/// has turned by 0.25°, whichever is nearer. About 50 casts for a head angle that sees
/// nothing, fewer otherwise, plus 24 per bracketed surface.
pub fn distance_at_head_angle(
    head_angle_cw_deg: f64,
    mut distance_at_bearing: impl FnMut(f64) -> f64,
) -> f64 {
    let mut cast = |d: f64| distance_at_bearing(head_angle_cw_deg + angle_correction_deg(d));
    let blocked = |found: f64, d: f64| found > 0.0 && found <= d + BLOCKED_TOLERANCE_MM;
    // The last probe where C was in free space, if the previous probe was.
    let mut free_mm: Option<f64> = None;
    let mut d = SEARCH_START_MM;
    for _ in 0..MAX_PROBES {
        let found = cast(d);
        if blocked(found, d) {
            if d == SEARCH_START_MM {
                // Closer than the search start: report it as it is.
                return found;
            }
            if let Some(mut lo) = free_mm {
                let (mut hi, mut at_hi) = (d, found);
                for _ in 0..BISECTIONS {
                    let mid = 0.5 * (lo + hi);
                    let found = cast(mid);
                    if blocked(found, mid) {
                        (hi, at_hi) = (mid, found);
                    } else {
                        lo = mid;
                    }
                }
                if hi - at_hi <= CROSSING_TOLERANCE_MM {
                    return at_hi;
                }
                // C swung into the surface's shadow from the side (at a silhouette edge)
                // without crossing it: keep walking.
            }
            free_mm = None;
            match distance_for_correction_mm(angle_correction_deg(d) - PROBE_BEARING_STEP_DEG) {
                Some(next) => d = next,
                None => return 0.0,
            }
            continue;
        }
        free_mm = Some(d);
        let bearing_limited =
            distance_for_correction_mm(angle_correction_deg(d) - PROBE_BEARING_STEP_DEG);
        d = match (bearing_limited, found > 0.0) {
            (Some(next), true) => next.min(found),
            (Some(next), false) => next,
            (None, true) => found,
            (None, false) => return 0.0,
        };
    }
    0.0
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

    /// Distance from the origin to a circle of `radius_mm` centred at clockwise bearing
    /// `center_cw_deg`, range `center_mm`, along clockwise bearing `bearing_cw_deg`; 0 if
    /// the ray misses.
    fn circle(center_cw_deg: f64, center_mm: f64, radius_mm: f64, bearing_cw_deg: f64) -> f64 {
        let (cx, cy) = (
            center_mm * (-center_cw_deg.to_radians()).cos(),
            center_mm * (-center_cw_deg.to_radians()).sin(),
        );
        let (ux, uy) = (
            (-bearing_cw_deg.to_radians()).cos(),
            (-bearing_cw_deg.to_radians()).sin(),
        );
        let along = cx * ux + cy * uy;
        let disc = along * along - (cx * cx + cy * cy) + radius_mm * radius_mm;
        if disc < 0.0 || along - disc.sqrt() <= 0.0 {
            0.0
        } else {
            along - disc.sqrt()
        }
    }

    #[test]
    fn the_consistent_distance_on_a_wall() {
        // A surface whose distance grows with bearing: d(b) = 1000 + 10·b mm.
        let wall = |bearing: f64| 1000.0 + 10.0 * bearing;
        let d = distance_at_head_angle(20.0, wall);
        assert!(
            (d - wall(20.0 + angle_correction_deg(d))).abs() < 0.05,
            "{d}"
        );
        // No return stays no return.
        assert_eq!(distance_at_head_angle(20.0, |_| 0.0), 0.0);
    }

    #[test]
    fn a_lone_beacon_is_seen_where_it_is() {
        // A 50 mm-radius pole 1 m away at bearing 30°, nothing else: every sample that sees
        // it must decode to a point on its surface, and some must see it.
        for (center_mm, radius_mm) in [(1000.0, 50.0), (400.0, 50.0), (5000.0, 45.0)] {
            let mut hits = 0;
            for k in 0..4000 {
                let head = 10.0 + k as f64 * 0.01;
                let d = distance_at_head_angle(head, |b| circle(30.0, center_mm, radius_mm, b));
                if d == 0.0 {
                    continue;
                }
                hits += 1;
                let bearing = head + angle_correction_deg(d);
                let on_surface = circle(30.0, center_mm, radius_mm, bearing);
                // Within the format's 0.25 mm distance resolution.
                assert!(
                    (on_surface - d).abs() < 0.25,
                    "head {head}: reported {d} mm at {bearing}°, surface at {on_surface} mm"
                );
            }
            let width_deg = 2.0 * (radius_mm / center_mm).asin().to_degrees();
            let expected_hits = width_deg / 0.01;
            assert!(
                (f64::from(hits) - expected_hits).abs() < 0.1 * expected_hits,
                "{hits} hits for a {width_deg}° wide pole at {center_mm} mm"
            );
        }
    }
}
