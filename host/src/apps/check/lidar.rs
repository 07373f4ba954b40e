//! What the lidar sent during a window (pure): rotation rate, points per scan, packets lost,
//! and the beacons found where the configuration puts them.
//!
//! **Beacons.** Each scan goes through the core's beacon extraction
//! ([`ratf_core::localisation::beacons::extract`], the localiser's own) with every beacon
//! expected where `[field] beacons_m` puts it as seen from the start pose with the lidar's
//! mount (`[robot] lidar_*`), searched within `[localisation] max_search_radius_m`; a
//! beacon is found in a scan when a pole-like cluster (a circle of the pole's radius, the
//! expected point count) is there. Ranges are corrected by `[lidar] range_scale` and
//! `range_offset_m` first, as `ratf run` does. The robot stands still, so nothing is
//! de-skewed. The X4's device-info and health commands are not implemented by the parser,
//! so neither is reported.

use ratf_core::config::Config;
use ratf_core::drivers::x4::scan::Scan;
use ratf_core::field::geometry::{Pose2, Vec2};
use ratf_core::localisation::beacons::{self, Expected, extract};
use serde::Serialize;

use crate::devices::lidar::LidarIdentity;
use ratf_core::drivers::x4::info::HealthStatus;

/// Where each beacon should be, and how to look for it.
#[derive(Clone, Debug)]
pub struct BeaconSearch {
    expected: Vec<Expected>,
    radius_m: f64,
    config: Config,
}

impl BeaconSearch {
    /// The configured beacons seen from `pose` (the robot's; the lidar's mount applied).
    pub fn new(config: &Config, pose: Pose2) -> Self {
        let field = config.field.field();
        let lidar = pose.compose(config.robot.lidar_mount());
        let expected =
            beacons::expected_from(&field, lidar, config.localisation.max_search_radius_m);
        Self {
            expected,
            radius_m: field.beacons()[0].circle.radius_m,
            config: config.clone(),
        }
    }

    /// Per beacon, the distance from where it was expected to the nearest pole-like cluster
    /// in `scan`, m (`None`: not found).
    pub fn find(&self, scan: &Scan) -> Vec<Option<f64>> {
        let lidar = &self.config.lidar;
        let points: Vec<Vec2> = scan
            .points
            .iter()
            .map(|p| Vec2::from_angle(p.angle_rad) * lidar.corrected_range_m(p.range_m))
            .collect();
        let samples = if scan.samples > 0 {
            scan.samples as usize
        } else {
            points.len().max(1)
        };
        let step_rad = std::f64::consts::TAU / samples as f64;
        let found = extract(
            &points,
            &[],
            &self.expected,
            step_rad,
            self.radius_m,
            &self.config.localisation,
        );
        found
            .iter()
            .zip(&self.expected)
            .map(|(clusters, e)| {
                clusters
                    .candidates
                    .iter()
                    .map(|o| {
                        let centre = Vec2::from_angle(o.bearing_rad) * o.range_m;
                        centre.distance(e.centre)
                    })
                    .min_by(f64::total_cmp)
            })
            .collect()
    }
}

/// One scan as the check keeps it.
#[derive(Clone, Debug, PartialEq)]
struct ScanSeen {
    at_us: u64,
    reported_hz: f64,
    samples: u32,
    points: usize,
    packets_dropped: u32,
    beacons: Vec<Option<f64>>,
}

/// Scans collected over a window.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LidarWindow {
    scans: Vec<ScanSeen>,
    device_faults: Vec<String>,
}

/// Scans kept per window (a minute at the X4's fastest): the window's memory is bounded.
const MAX_SCANS: usize = 12 * 60;

impl LidarWindow {
    /// One revolution, arrived at `at_us`, with the beacons `search` found in it.
    pub fn on_scan(&mut self, scan: &Scan, at_us: u64, search: &BeaconSearch) {
        if self.scans.len() >= MAX_SCANS {
            return;
        }
        self.scans.push(ScanSeen {
            at_us,
            reported_hz: scan.scan_frequency_hz,
            samples: scan.samples,
            points: scan.points.len(),
            packets_dropped: scan.packets_dropped,
            beacons: search.find(scan),
        });
    }

    /// The lidar's thread reported a fault (port lost, no scan after the start command).
    pub fn on_fault(&mut self, message: &str) {
        self.device_faults.push(message.to_owned());
    }

    /// When the first scan arrived, µs.
    pub fn first_us(&self) -> Option<u64> {
        self.scans.first().map(|s| s.at_us)
    }

    /// The summary.
    pub fn summary(&self, window_s: f64) -> LidarSummary {
        let n = self.scans.len();
        let rotation_hz = match (self.scans.first(), self.scans.last()) {
            (Some(a), Some(b)) if b.at_us > a.at_us => {
                (n - 1) as f64 / ((b.at_us - a.at_us) as f64 * 1e-6)
            }
            _ => 0.0,
        };
        let beacons = (0..4)
            .map(|k| {
                let offsets: Vec<f64> = self
                    .scans
                    .iter()
                    .filter_map(|s| s.beacons.get(k).copied().flatten())
                    .collect();
                BeaconSeen {
                    beacon: k,
                    found_fraction: if n > 0 {
                        offsets.len() as f64 / n as f64
                    } else {
                        0.0
                    },
                    median_offset_mm: median(offsets).map(|m| m * 1e3),
                }
            })
            .collect();
        LidarSummary {
            window_s,
            scans: n as u32,
            rotation_hz,
            reported_hz: median(self.scans.iter().map(|s| s.reported_hz).collect()).unwrap_or(0.0),
            samples_per_scan: median(self.scans.iter().map(|s| f64::from(s.samples)).collect())
                .unwrap_or(0.0),
            points_per_scan: median(self.scans.iter().map(|s| s.points as f64).collect())
                .unwrap_or(0.0),
            packets_dropped: self.scans.iter().map(|s| s.packets_dropped).sum(),
            beacons,
            device_faults: self.device_faults.clone(),
            identity: String::new(),
        }
    }
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    values.retain(|v| v.is_finite());
    values.sort_by(f64::total_cmp);
    let n = values.len();
    (n > 0).then(|| {
        if n % 2 == 1 {
            values[n / 2]
        } else {
            0.5 * (values[n / 2 - 1] + values[n / 2])
        }
    })
}

/// One beacon over the window.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BeaconSeen {
    /// Beacon index (B0..B3).
    pub beacon: usize,
    /// Share of the scans in which it was found.
    pub found_fraction: f64,
    /// Median distance from where it was expected to where it was found, mm.
    pub median_offset_mm: Option<f64>,
}

/// What the lidar sent during a window.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LidarSummary {
    /// The window's length, s.
    pub window_s: f64,
    /// Revolutions received.
    pub scans: u32,
    /// Revolutions per second, from their arrival times.
    pub rotation_hz: f64,
    /// Median scan frequency the X4 reported, Hz.
    pub reported_hz: f64,
    /// Median samples per revolution (kept or not).
    pub samples_per_scan: f64,
    /// Median points per revolution within `[lidar] min_range_m`..`max_range_m`.
    pub points_per_scan: f64,
    /// Packets dropped for a bad check code.
    pub packets_dropped: u32,
    /// Each beacon.
    pub beacons: Vec<BeaconSeen>,
    /// Faults the lidar's thread reported.
    pub device_faults: Vec<String>,
    /// What the X4 said of itself (device information and health), in a person's words.
    pub identity: String,
}

/// The X4's answers to the device-information and health requests, in a person's words.
pub fn identity_text(identity: Option<&LidarIdentity>) -> String {
    let info = identity.and_then(|i| i.info).map_or_else(
        || "no device information (a clone?)".to_owned(),
        |i| i.describe(),
    );
    let health = match identity.and_then(|i| i.health) {
        None => "no health report".to_owned(),
        Some(h) if h.status == HealthStatus::Ok => "health ok".to_owned(),
        Some(h) => format!("health {:?}, error code 0x{:04X}", h.status, h.error_code),
    };
    format!("{info}; {health}")
}

impl LidarSummary {
    /// Beacons found in at least half of the scans.
    pub fn beacons_found(&self) -> usize {
        self.beacons
            .iter()
            .filter(|b| b.found_fraction >= 0.5)
            .count()
    }

    /// What is wrong, each with what to check; `on_field`: the robot stands at the start
    /// pose among the beacons (else the beacons are not judged).
    pub fn problems(&self, config: &Config, port: &str, on_field: bool) -> Vec<String> {
        let mut problems = Vec::new();
        if self.scans < 2 {
            problems.push(format!(
                "{port}: opened, but {} scan(s) in {:.1} s after the start command: is the X4 \
                 powered (its USB port must give 5 V, 0.5 A; use a powered hub) and spinning? \
                 check [link] lidar_baud (128000)",
                self.scans, self.window_s
            ));
            return problems;
        }
        let nominal = config.lidar.scan_rate_hz;
        if (self.rotation_hz - nominal).abs() > 0.3 * nominal {
            problems.push(format!(
                "turns at {:.1} Hz, [lidar] scan_rate_hz says {nominal}: a weak power supply \
                 slows the X4; set scan_rate_hz to what it does",
                self.rotation_hz
            ));
        }
        let expected_samples = 360.0 / config.lidar.angle_step_deg;
        if self.samples_per_scan < 0.5 * expected_samples {
            problems.push(format!(
                "{:.0} samples per scan, [lidar] angle_step_deg = {} means {expected_samples:.0}",
                self.samples_per_scan, config.lidar.angle_step_deg
            ));
        }
        if self.packets_dropped > self.scans {
            problems.push(format!(
                "{} packets with a bad check code in {} scans: check the USB cable",
                self.packets_dropped, self.scans
            ));
        }
        if on_field && self.beacons_found() < 3 {
            problems.push(format!(
                "{} of 4 beacons found where [field] beacons_m puts them, seen from the start \
                 pose: put the robot at the start pose, check the poles and [field] beacons_m, \
                 [robot] lidar_yaw_deg (or pass --off-field on a stand)",
                self.beacons_found()
            ));
        }
        for fault in &self.device_faults {
            problems.push(format!("link: {fault}"));
        }
        problems
    }

    /// One line of what was seen.
    pub fn describe(&self, judged_beacons: bool) -> String {
        let beacons = self
            .beacons
            .iter()
            .map(|b| match b.median_offset_mm {
                Some(mm) => format!(
                    "B{} {:.0} % ({mm:.0} mm off)",
                    b.beacon,
                    b.found_fraction * 100.0
                ),
                None => format!("B{} not found", b.beacon),
            })
            .collect::<Vec<_>>()
            .join(", ");
        format!(
            "{}; {:.1} Hz ({:.1} Hz reported), {:.0} points per scan of {:.0} samples, {} bad \
             packets; beacons{}: {beacons}",
            self.identity,
            self.rotation_hz,
            self.reported_hz,
            self.points_per_scan,
            self.samples_per_scan,
            self.packets_dropped,
            if judged_beacons {
                ""
            } else {
                " (off field, not judged)"
            }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_x4_s_identity_reads_as_a_person_would_say_it() {
        use ratf_core::drivers::x4::info::{DeviceInfo, Health};
        assert_eq!(
            identity_text(None),
            "no device information (a clone?); no health report"
        );
        let info = DeviceInfo {
            model: 6,
            firmware_major: 1,
            firmware_minor: 7,
            hardware: 1,
            serial: [2; 16],
        };
        let healthy = LidarIdentity {
            info: Some(info),
            health: Some(Health {
                status: HealthStatus::Ok,
                error_code: 0,
            }),
        };
        assert_eq!(
            identity_text(Some(&healthy)),
            "X4, firmware 1.7, hardware 1, serial 2222222222222222; health ok"
        );
        let failing = LidarIdentity {
            health: Some(Health {
                status: HealthStatus::Error,
                error_code: 0x0102,
            }),
            ..healthy
        };
        assert!(identity_text(Some(&failing)).ends_with("health Error, error code 0x0102"));
    }
    use ratf_core::drivers::x4::scan::ScanPoint;
    use ratf_core::field::Field;

    /// A revolution from the start pose with only the four poles (0.5° rays).
    fn poles_scan(config: &Config, pose: Pose2, stamp_us: f64) -> Scan {
        let search = BeaconSearch::new(config, pose);
        let field = config.field.field();
        let radius = field.beacons()[0].circle.radius_m;
        let mut points = Vec::new();
        for i in 0..720 {
            let a = -std::f64::consts::PI + f64::from(i) * 0.5_f64.to_radians();
            let dir = Vec2::from_angle(a);
            let hit = search
                .expected
                .iter()
                .filter_map(|e| {
                    // Ray–circle intersection from the lidar's origin.
                    let along = dir.dot(e.centre);
                    let off2 = e.centre.dot(e.centre) - along * along;
                    (along > 0.0 && off2 <= radius * radius)
                        .then(|| along - (radius * radius - off2).sqrt())
                })
                .min_by(f64::total_cmp);
            if let Some(range_m) = hit {
                points.push(ScanPoint {
                    angle_rad: a,
                    range_m,
                    time_offset_us: 0.0,
                });
            }
        }
        Scan {
            stamp_us,
            sample_period_us: 200.0,
            scan_frequency_hz: 7.0,
            points,
            samples: 720,
            points_out_of_range: 0,
            points_overflowed: 0,
            packets_dropped: 0,
        }
    }

    #[test]
    fn every_beacon_is_found_from_the_start_pose_and_the_rate_measured() {
        let config = Config::default();
        let pose = Field::competition().start_pose();
        let search = BeaconSearch::new(&config, pose);
        let mut window = LidarWindow::default();
        for i in 0..15u64 {
            let scan = poles_scan(&config, pose, 0.0);
            window.on_scan(&scan, i * 142_857, &search);
        }
        let s = window.summary(2.0);
        assert_eq!(s.scans, 15);
        assert!((s.rotation_hz - 7.0).abs() < 0.01, "{s:?}");
        assert_eq!(s.beacons_found(), 4, "{s:?}");
        for b in &s.beacons {
            assert!(b.median_offset_mm.is_some_and(|mm| mm < 5.0), "{b:?}");
        }
        assert!(s.problems(&config, "/dev/ratf-lidar", true).is_empty());
    }

    #[test]
    fn a_robot_far_from_the_start_pose_finds_too_few_beacons_unless_off_field() {
        let config = Config::default();
        let pose = Field::competition().start_pose();
        // The scan as taken from 0.6 m away and turned 90°.
        let away = Pose2::new(pose.x + 0.6, pose.y + 0.3, pose.yaw_rad + 1.5);
        let search = BeaconSearch::new(&config, pose);
        let mut window = LidarWindow::default();
        for i in 0..10u64 {
            window.on_scan(&poles_scan(&config, away, 0.0), i * 142_857, &search);
        }
        let s = window.summary(2.0);
        assert!(s.beacons_found() < 3, "{s:?}");
        let problems = s.problems(&config, "/dev/ratf-lidar", true).join("\n");
        assert!(
            problems.contains("put the robot at the start pose"),
            "{problems}"
        );
        assert!(s.problems(&config, "/dev/ratf-lidar", false).is_empty());
    }

    #[test]
    fn a_silent_or_slow_lidar_is_a_problem() {
        let config = Config::default();
        let silent = LidarWindow::default().summary(2.0);
        let problems = silent.problems(&config, "/dev/ratf-lidar", false);
        assert!(problems[0].contains("0 scan(s) in 2.0 s"), "{problems:?}");
        let pose = Field::competition().start_pose();
        let search = BeaconSearch::new(&config, pose);
        let mut window = LidarWindow::default();
        for i in 0..5u64 {
            window.on_scan(&poles_scan(&config, pose, 0.0), i * 250_000, &search);
        }
        let problems = window
            .summary(2.0)
            .problems(&config, "/dev/ratf-lidar", true)
            .join("\n");
        assert!(problems.contains("turns at 4.0 Hz"), "{problems}");
    }
}
