//! A stop's sightings: the poles' centres found in each still scan, averaged per beacon.

use std::collections::BTreeMap;

use crate::config::Config;
use crate::drivers::x4::scan::Scan;
use crate::field::Field;
use crate::field::geometry::{Pose2, Vec2};
use crate::localisation::beacons;

/// Search radius around each beacon's predicted centre, m. Generous because, before
/// calibration, a 3° mount error puts a pole 2 m away 10 cm from where it is expected;
/// the poles stand at least 0.2 m apart (`[field] beacons_m` is checked for it) and
/// nothing else reaches the scan plane on a competition floor.
pub const SEARCH_RADIUS_M: f64 = 0.15;

/// Still scans a stop needs, and scans a ray's bin must have a range in to count.
pub const MIN_SCANS: usize = 3;

/// Floor of a sighting's range standard deviation, m: what averaging cannot remove (the
/// pole's own roundness and the lidar's range quantisation, about 1 mm).
const RANGE_STD_FLOOR_M: f64 = 0.001;

/// Floor of a sighting's bearing standard deviation, rad (0.05°, a tenth of the X4's ray
/// spacing).
const BEARING_STD_FLOOR_RAD: f64 = 0.05 * std::f64::consts::PI / 180.0;

/// The sample median's standard error over the mean's, for normal noise (√(π/2)).
const MEDIAN_EFFICIENCY: f64 = 1.2533;

/// One beacon seen from one stop: its centre averaged over the stop's scans, in the
/// lidar's own frame with the lidar's raw ranges (the range calibration not applied).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sighting {
    /// Which beacon (index into the field's beacons).
    pub beacon: usize,
    /// Distance from the lidar's origin to the centre, m.
    pub range_m: f64,
    /// Bearing of the centre, rad, counter-clockwise from the lidar's zero angle.
    pub bearing_rad: f64,
    /// Standard deviation of `range_m` (from the pole's fit in the stop's quiet scan,
    /// floored), m.
    pub range_std_m: f64,
    /// Standard deviation of `bearing_rad` (likewise), rad.
    pub bearing_std_rad: f64,
    /// Still scans the stop's quiet scan was made from.
    pub scans: usize,
}

/// What the robot saw and believed at one stop.
#[derive(Clone, Debug, PartialEq)]
pub struct Stop {
    /// The wheel odometry's pose there (its own frame; only differences between stops are
    /// used).
    pub odometry: Pose2,
    /// Where the robot was believed to stand when its poles were looked for (the
    /// localiser's pose or the odometry's, see [`StopRecorder`]): the fit's start.
    pub estimate: Pose2,
    /// The beacons found in the stop's quiet scan.
    pub sightings: Vec<Sighting>,
}

/// Collects one stop's scans: per ray direction (binned at the lidar's angle step), the
/// ranges of every still scan; at the end, their medians make one quiet scan in which the
/// poles are found as the localiser finds them (a tenth of the noise after ten scans, so a
/// noisy lidar still shows round poles).
///
/// Where to look for each pole comes from a pose the robot believes it stands at. Two
/// beliefs are at hand and either can be wrong: the localiser's estimate drifts when the
/// uncalibrated lidar's sightings and a biased gyro pull it (13° at a stop of seed 36 in the
/// harsh world, where the poles it then found were not the ones it named), and the wheels'
/// odometry drifts with roller slip (a strafe 15 % short). [`StopRecorder::finish`] looks
/// around each and keeps the look that found more poles.
#[derive(Clone, Debug)]
pub struct StopRecorder {
    field: Field,
    mount: Pose2,
    step_rad: f64,
    radius_m: f64,
    config: crate::config::LocalisationConfig,
    bins: BTreeMap<i64, Bin>,
    scans: usize,
}

impl StopRecorder {
    /// A recorder for a stop, with the lidar mount and the beacons of `config` and `field`.
    pub fn new(config: &Config, field: &Field) -> Self {
        Self {
            field: field.clone(),
            mount: config.robot.lidar_mount(),
            step_rad: config.lidar.angle_step_deg.to_radians(),
            radius_m: field.beacons()[0].circle.radius_m,
            config: config.localisation.clone(),
            bins: BTreeMap::new(),
            scans: 0,
        }
    }

    /// Add a scan taken while the robot stood still.
    pub fn add_scan(&mut self, scan: &Scan) {
        self.scans += 1;
        for p in &scan.points {
            let bin = (p.angle_rad / self.step_rad).round() as i64;
            let bin = self.bins.entry(bin).or_default();
            bin.ranges.push(p.range_m);
            bin.angle_sum_rad += p.angle_rad;
        }
    }

    /// The stop: a sighting per beacon found in the stop's quiet scan around the best of
    /// `looks` (poses the robot may stand at, world frame: the one around which the most
    /// poles were found, then the one they were found nearest to, then the first), with the
    /// odometry's pose there (no sightings with fewer than [`MIN_SCANS`] scans).
    pub fn finish(self, odometry: Pose2, looks: &[Pose2]) -> Stop {
        let first = looks.first().copied().unwrap_or(odometry);
        let mut best = Stop {
            odometry,
            estimate: first,
            sightings: Vec::new(),
        };
        if self.scans < MIN_SCANS {
            return best;
        }
        let quorum = MIN_SCANS.max(self.scans / 2);
        let mut points = Vec::new();
        let (mut spread_sum, mut spread_bins) = (0.0, 0usize);
        for bin in self.bins.values() {
            let ranges = &bin.ranges;
            if ranges.len() < quorum {
                continue;
            }
            let median = median(ranges);
            let n = ranges.len() as f64;
            let variance = ranges.iter().map(|r| (r - median).powi(2)).sum::<f64>() / (n - 1.0);
            spread_sum += variance / n;
            spread_bins += 1;
            points.push(Vec2::from_angle(bin.angle_sum_rad / n) * median);
        }
        // The noise left on each median range, pooled over the rays.
        let median_std_m = (spread_sum / spread_bins.max(1) as f64).sqrt() * MEDIAN_EFFICIENCY;
        // The localiser's floors stand for what a single scan in motion cannot know (the
        // calibration's residuals, de-skew); a still stop's medians have their own floors,
        // applied below.
        let mut config = self.config.clone();
        config.range_noise_std_m = median_std_m.max(RANGE_STD_FLOOR_M);
        config.range_floor_std_m = 0.0;
        config.bearing_floor_std_deg = 0.0;
        let mut best_miss_m2 = f64::INFINITY;
        for &look in looks {
            let (sightings, miss_m2) = self.sightings_around(look, &points, &config);
            let better = sightings.len() > best.sightings.len()
                || (sightings.len() == best.sightings.len() && miss_m2 < best_miss_m2);
            if better {
                best.estimate = look;
                best.sightings = sightings;
                best_miss_m2 = miss_m2;
            }
        }
        best
    }

    /// The poles found in the quiet scan `points` near where they stand as seen from the
    /// robot at `look`, and the sum of their squared distances from there, m².
    fn sightings_around(
        &self,
        look: Pose2,
        points: &[Vec2],
        config: &crate::config::LocalisationConfig,
    ) -> (Vec<Sighting>, f64) {
        let lidar = look.compose(self.mount);
        let expected = beacons::expected_from(&self.field, lidar, SEARCH_RADIUS_M);
        let found = beacons::extract(points, &[], &expected, self.step_rad, self.radius_m, config);
        let (mut sightings, mut miss_m2) = (Vec::new(), 0.0);
        for (expected, clusters) in expected.iter().zip(found) {
            let miss = |range_m: f64, bearing_rad: f64| {
                centre_of(range_m, bearing_rad).distance(expected.centre)
            };
            let nearest = clusters.candidates.iter().min_by(|a, b| {
                miss(a.range_m, a.bearing_rad).total_cmp(&miss(b.range_m, b.bearing_rad))
            });
            if let Some(obs) = nearest {
                miss_m2 += miss(obs.range_m, obs.bearing_rad).powi(2);
                sightings.push(Sighting {
                    beacon: expected.beacon,
                    range_m: obs.range_m,
                    bearing_rad: obs.bearing_rad,
                    range_std_m: obs.covariance[(0, 0)].sqrt().max(RANGE_STD_FLOOR_M),
                    bearing_std_rad: obs.covariance[(1, 1)].sqrt().max(BEARING_STD_FLOOR_RAD),
                    scans: self.scans,
                });
            }
        }
        (sightings, miss_m2)
    }
}

/// The ranges read along one ray direction over a stop's scans, and their angles' sum (the
/// X4's rays do not repeat exactly from one revolution to the next: a range is placed at its
/// rays' mean angle, not at the bin's nominal one, which would bend a pole's outline).
#[derive(Clone, Debug, Default)]
struct Bin {
    ranges: Vec<f64>,
    angle_sum_rad: f64,
}

fn centre_of(range_m: f64, bearing_rad: f64) -> Vec2 {
    Vec2::from_angle(bearing_rad) * range_m
}

fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mid = sorted.len() / 2;
    if sorted.len().is_multiple_of(2) {
        (sorted[mid - 1] + sorted[mid]) / 2.0
    } else {
        sorted[mid]
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::FRAC_PI_2;

    use super::*;
    use crate::drivers::x4::scan::ScanPoint;
    use crate::rng::SimRng;

    /// A still scan of the field's poles from `lidar` (world pose), rays every `step`, range
    /// noise σ `noise_m`, read as `scale × true + offset`.
    fn scan(field: &Field, lidar: Pose2, step: f64, noise_m: f64, rng: &mut SimRng) -> Scan {
        let rays = (std::f64::consts::TAU / step).round() as i64;
        let points = (0..rays)
            .filter_map(|i| {
                let angle = -std::f64::consts::PI + i as f64 * step;
                let direction = Vec2::from_angle(lidar.yaw_rad + angle);
                let origin = lidar.position();
                field.beacons().iter().find_map(|b| {
                    let to_centre = b.circle.center - origin;
                    let along = to_centre.dot(direction);
                    let miss2 = to_centre.dot(to_centre) - along * along;
                    let r2 = b.circle.radius_m * b.circle.radius_m;
                    (along > 0.0 && miss2 < r2).then(|| ScanPoint {
                        angle_rad: angle,
                        range_m: along - (r2 - miss2).sqrt() + rng.normal(noise_m),
                        time_offset_us: 0.0,
                    })
                })
            })
            .collect();
        Scan {
            stamp_us: 0.0,
            sample_period_us: 0.0,
            scan_frequency_hz: 7.0,
            points,
            samples: rays as u32,
            points_out_of_range: 0,
            points_overflowed: 0,
            packets_dropped: 0,
        }
    }

    #[test]
    fn a_noisy_lidar_still_sees_every_pole_at_its_centre_after_ten_scans() {
        let config = Config::default();
        let field = Field::competition();
        let robot = Pose2::new(-0.64, -0.2, 1.5);
        let mount = config.robot.lidar_mount();
        let lidar = robot.compose(mount);
        let mut rng = SimRng::new(7);
        // 25 mm of noise: twice the harsh world's at 2 m; one scan of it breaks the poles'
        // circle fits.
        let mut recorder = StopRecorder::new(&config, &field);
        let step = config.lidar.angle_step_deg.to_radians();
        for _ in 0..10 {
            recorder.add_scan(&scan(&field, lidar, step, 0.025, &mut rng));
        }
        let stop = recorder.finish(robot, &[robot]);
        assert_eq!(stop.sightings.len(), 4, "{stop:?}");
        for s in &stop.sightings {
            let truth = lidar.inverse_transform_point(field.beacons()[s.beacon].circle.center);
            let seen = centre_of(s.range_m, s.bearing_rad);
            assert!(
                seen.distance(truth) < 0.015,
                "beacon {}: {seen:?} vs {truth:?}",
                s.beacon
            );
            assert!(s.range_std_m >= RANGE_STD_FLOOR_M && s.scans == 10);
        }
    }

    #[test]
    fn a_still_stop_s_sightings_carry_their_medians_uncertainty_not_the_localiser_s_floors() {
        let config = Config::default();
        let field = Field::competition();
        let robot = Pose2::new(-0.64, -0.2, 1.5);
        let lidar = robot.compose(config.robot.lidar_mount());
        let mut rng = SimRng::new(3);
        let mut recorder = StopRecorder::new(&config, &field);
        let step = config.lidar.angle_step_deg.to_radians();
        for _ in 0..14 {
            recorder.add_scan(&scan(&field, lidar, step, 0.005, &mut rng));
        }
        let stop = recorder.finish(robot, &[robot]);
        assert_eq!(stop.sightings.len(), 4, "{stop:?}");
        let floor_m = config.localisation.range_floor_std_m;
        let floor_rad = config.localisation.bearing_floor_std_deg.to_radians();
        for s in &stop.sightings {
            // 5 mm of noise, the median of 14 scans, a few rays per pole: about 1 mm.
            assert!(s.range_std_m < floor_m / 2.0, "{s:?}");
            assert!(s.bearing_std_rad < floor_rad / 2.0, "{s:?}");
        }
    }

    #[test]
    fn the_poles_are_looked_for_around_the_pose_that_finds_the_most_of_them() {
        let config = Config::default();
        let field = Field::competition();
        let robot = Pose2::new(-0.64, -0.065, FRAC_PI_2);
        let lidar = robot.compose(config.robot.lidar_mount());
        let drifted = Pose2::new(-0.56, -0.15, FRAC_PI_2 - 13f64.to_radians());
        let mut rng = SimRng::new(5);
        let mut recorder = StopRecorder::new(&config, &field);
        let step = config.lidar.angle_step_deg.to_radians();
        for _ in 0..10 {
            recorder.add_scan(&scan(&field, lidar, step, 0.005, &mut rng));
        }
        let around_drifted = recorder.clone().finish(robot, &[drifted]);
        assert!(around_drifted.sightings.len() < 4, "{around_drifted:?}");
        let stop = recorder.finish(robot, &[drifted, robot]);
        assert_eq!(stop.estimate, robot);
        assert_eq!(stop.sightings.len(), 4, "{stop:?}");
    }

    #[test]
    fn too_few_scans_give_no_sightings() {
        let config = Config::default();
        let field = Field::competition();
        let robot = Pose2::new(-0.64, -0.2, 1.5);
        let mut recorder = StopRecorder::new(&config, &field);
        let mut rng = SimRng::new(1);
        let step = config.lidar.angle_step_deg.to_radians();
        recorder.add_scan(&scan(&field, robot, step, 0.0, &mut rng));
        assert!(recorder.finish(robot, &[robot]).sightings.is_empty());
    }

    #[test]
    fn the_median_of_an_even_count_is_the_middle_pair_s_mean() {
        assert_eq!(median(&[3.0, 1.0, 2.0, 10.0]), 2.5);
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
    }
}
