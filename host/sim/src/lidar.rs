//! The simulated YDLIDAR X4: a spinning range sensor that emits real X4 packets.
//!
//! The head turns clockwise at `lidar.scan_rate_hz` and ranges every `1/(rate · samples)`
//! seconds, `samples = 360 / lidar.angle_step_deg` per revolution (7 Hz and 0.5° give 720
//! samples, 198 µs apart). Each sample is taken at its own simulated time with the robot's
//! pose at that instant, so the robot's motion during the ~143 ms sweep is in the data, as on
//! the real sensor. Samples are packed 40 to a packet (the X4's typical size), each
//! revolution opening with a start-of-revolution packet, and the packet bytes go out on the
//! 128 000 baud line when its last sample is taken. The beam is modelled with the geometry
//! behind the X4's angle correction (see `BEAM_OFFSET_M`).
//!
//! What it sees: only things that reach its scan plane (`robot.lidar_height_m`, 0.20 m by
//! default). The beacons (0.5 m poles) do; the warehouse and machine walls (0.130 m), the
//! dividers (0.065 m) and the parts (0.065 m) do not. Clutter standing outside the field
//! (people's legs, a table) is seen when it is tall enough. The robot does not see itself.
//!
//! Errors modelled: Gaussian range noise (`lidar.range_noise_std_m`); no return (distance 0)
//! below the minimum or beyond the maximum range; the distance quantisation (0.25 mm) and
//! angle quantisation (1/64°) of the packet format; the X4's angle correction (the sample at
//! head angle θ is the point at bearing θ + AngCorrect(d)).
//!
//! Rotation speed ([`SimLidar::with_rotation`]): the X4's motor is not speed-controlled
//! from the host, so its true rate is a per-unit factor off the configured one with a slow
//! sinusoidal wander within the round. The factor is taken at each revolution's start and
//! holds for that revolution; the samples keep their configured angular grid (the real X4
//! samples at a fixed 5 kHz so its step follows the speed; the host reads angles from the
//! packets, so what matters here is the timing) and the packets report the true rate, as the
//! X4's own frequency field does (0.1 Hz resolution).
//!
//! Asked for its device information (`A5 90`) or health (`A5 91`), it answers as a healthy
//! X4 would ([`reply`]): model 6, firmware 1.7, hardware 1.

use crate::serial::SerialLine;
use ratf_core::config::{ClutterConfig, LidarConfig, RobotConfig};
use ratf_core::drivers::x4::info::{DeviceInfo, Health, HealthStatus, MODEL_X4, Reply, Request};
use ratf_core::drivers::x4::packet::{
    CORRECTION_BASE_MM, CORRECTION_OFFSET_MM, PacketSpec, encode_packet,
};
use ratf_core::field::Field;
use ratf_core::field::geometry::{Circle, Pose2, Rect, Vec2, wrap_angle};
use ratf_core::rng::SimRng;

/// Samples per data packet, as the X4 typically sends.
const SAMPLES_PER_PACKET: usize = 40;

/// The ranging beam's geometry behind the X4's angle correction: the datasheet's
/// `AngCorrect = atan(21.8·(155.3 − d)/(155.3·d))` is exactly the bearing of a point at
/// distance d on a beam that starts 21.8 mm to the clockwise side of the head's axis and
/// crosses that axis 155.3 mm out. Ray-casting that beam makes the simulated samples agree
/// with the correction for any object, however narrow (a 9 cm pole spans less than the 7°
/// correction at 1 m, so shifting a centre-ray distance by the correction would miss it).
const BEAM_OFFSET_M: f64 = CORRECTION_OFFSET_MM / 1000.0;
/// Where the beam crosses the head's axis, m (see [`BEAM_OFFSET_M`]).
const BEAM_CROSSING_M: f64 = CORRECTION_BASE_MM / 1000.0;

/// What the simulated X4 says it is: model 6 (the X4), firmware 1.7 and hardware 1 (values
/// seen on sold units; any would do), a serial number of one digit a byte as the X4 sends.
pub const DEVICE_INFO: DeviceInfo = DeviceInfo {
    model: MODEL_X4,
    firmware_major: 1,
    firmware_minor: 7,
    hardware: 1,
    serial: [2, 0, 2, 6, 1, 1, 2, 5, 0, 0, 0, 0, 0, 0, 0, 1],
};

/// The simulated X4's reply to `request`: [`DEVICE_INFO`], or a health without error. A
/// free function, as it depends on no state: write its bytes ([`Reply::encode`]) to the
/// host whether or not the lidar is scanning.
pub fn reply(request: Request) -> Reply {
    match request {
        Request::DeviceInfo => Reply::DeviceInfo(DEVICE_INFO),
        Request::Health => Reply::Health(Health {
            status: HealthStatus::Ok,
            error_code: 0,
        }),
    }
}

/// Something standing on or around the floor that may reach the lidar's plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A vertical cylinder (a beacon, a person's leg, a table leg).
    Cylinder(Circle),
    /// A vertical box (a wall, a table seen side-on).
    Block(Rect),
}

/// A [`Shape`] with its height above the floor, m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solid {
    /// Footprint.
    pub shape: Shape,
    /// Top above the floor, m.
    pub height_m: f64,
}

impl Solid {
    fn ray_distance(&self, origin: Vec2, direction: Vec2) -> Option<f64> {
        match self.shape {
            Shape::Cylinder(circle) => circle.ray_intersection(origin, direction),
            Shape::Block(rect) => rect.ray_intersection(origin, direction),
        }
    }
}

impl From<&ClutterConfig> for Solid {
    fn from(clutter: &ClutterConfig) -> Self {
        match *clutter {
            ClutterConfig::Cylinder {
                x_m,
                y_m,
                radius_m,
                height_m,
            } => Solid {
                shape: Shape::Cylinder(Circle::new(Vec2::new(x_m, y_m), radius_m)),
                height_m,
            },
            ClutterConfig::Block {
                x_min_m,
                x_max_m,
                y_min_m,
                y_max_m,
                height_m,
            } => Solid {
                shape: Shape::Block(Rect::from_spans(x_min_m, x_max_m, y_min_m, y_max_m)),
                height_m,
            },
        }
    }
}

/// A person standing with their legs around `center` ([`ClutterConfig::person`]).
pub fn person(center: Vec2) -> [Solid; 2] {
    ClutterConfig::person(center.x, center.y).map(|leg| Solid::from(&leg))
}

/// Everything the lidar can hit, already filtered to what reaches its plane.
#[derive(Clone, Debug, PartialEq)]
pub struct LidarScene {
    solids: Vec<Solid>,
}

impl LidarScene {
    /// The field's beacons and walls plus `clutter`, keeping what is taller than
    /// `plane_height_m`.
    pub fn new(field: &Field, clutter: &[Solid], plane_height_m: f64) -> Self {
        let beacons = field.beacons().iter().map(|b| Solid {
            shape: Shape::Cylinder(b.circle),
            height_m: b.height_m,
        });
        let walls = field.obstacles().into_iter().map(|o| Solid {
            shape: Shape::Block(o.rect),
            height_m: o.height_m,
        });
        let solids = beacons
            .chain(walls)
            .chain(clutter.iter().copied())
            .filter(|s| s.height_m > plane_height_m)
            .collect();
        Self { solids }
    }

    /// The solids the lidar can see.
    pub fn solids(&self) -> &[Solid] {
        &self.solids
    }

    /// Distance along the ray to the nearest solid, m, or `None`.
    pub fn cast(&self, origin: Vec2, direction: Vec2) -> Option<f64> {
        self.solids
            .iter()
            .filter_map(|s| s.ray_distance(origin, direction))
            .min_by(f64::total_cmp)
    }
}

/// The simulated X4.
#[derive(Clone, Debug)]
pub struct SimLidar {
    config: LidarConfig,
    /// Lidar frame in the robot frame (x towards the head's 0°; its angles turn clockwise).
    mount: Pose2,
    samples_per_revolution: u64,
    sample_period_ns: u64,
    /// Index of the next sample since the sensor started.
    next_sample: u64,
    /// When the next sample is taken, ns.
    next_sample_ns: u64,
    /// Time between two samples in the current revolution, ns.
    revolution_sample_ns: u64,
    /// The head's rate in the current revolution, Hz.
    revolution_rate_hz: f64,
    /// The true rotation speed, if it differs from the configured one.
    rotation: Option<Rotation>,
    packet: Vec<f64>,
    packet_first_index: u64,
    rng: SimRng,
    /// When `false` every sample reads "no return" (a fault-injection switch).
    pub enabled: bool,
    /// Range calibration error: reading = true range × scale + offset.
    range_scale: f64,
    /// See `range_scale`, m.
    range_offset_m: f64,
    /// Range noise σ growth per metre of range (added to `range_noise_std_m`).
    noise_per_m: f64,
}

impl SimLidar {
    /// A lidar mounted as in `robot`, ranging as in `config`, with its own noise stream.
    pub fn new(config: &LidarConfig, robot: &RobotConfig, rng: SimRng) -> Self {
        let samples_per_revolution = (360.0 / config.angle_step_deg).round().max(1.0) as u64;
        let sample_period_ns =
            (1e9 / (config.scan_rate_hz * samples_per_revolution as f64)).round() as u64;
        Self {
            config: config.clone(),
            mount: robot.lidar_mount(),
            samples_per_revolution,
            sample_period_ns,
            next_sample: 0,
            next_sample_ns: 0,
            revolution_sample_ns: sample_period_ns,
            revolution_rate_hz: config.scan_rate_hz,
            rotation: None,
            packet: Vec::with_capacity(SAMPLES_PER_PACKET),
            packet_first_index: 0,
            rng,
            enabled: true,
            range_scale: 1.0,
            range_offset_m: 0.0,
            noise_per_m: 0.0,
        }
    }

    /// This lidar with a range calibration error (reading = true × `scale` + `offset_m`)
    /// and noise whose σ grows by `noise_per_m` per metre of range.
    pub fn with_range_errors(mut self, scale: f64, offset_m: f64, noise_per_m: f64) -> Self {
        self.range_scale = scale;
        self.range_offset_m = offset_m;
        self.noise_per_m = noise_per_m;
        self
    }

    /// This lidar with its head turning at `rotation`'s true speed rather than exactly
    /// the configured `scan_rate_hz`.
    pub fn with_rotation(mut self, rotation: Rotation) -> Self {
        self.rotation = Some(rotation);
        self
    }

    /// The head's rate in the current revolution, Hz.
    pub fn rate_hz(&self) -> f64 {
        self.revolution_rate_hz
    }

    /// Time between two samples at the configured rate, ns.
    pub fn sample_period_ns(&self) -> u64 {
        self.sample_period_ns
    }

    /// Samples per revolution.
    pub fn samples_per_revolution(&self) -> u64 {
        self.samples_per_revolution
    }

    fn step_deg(&self) -> f64 {
        360.0 / self.samples_per_revolution as f64
    }

    /// Take every sample due in (`from_ns`, `to_ns`], the robot moving from `from_pose` to
    /// `to_pose` meanwhile, and send completed packets on `line`.
    pub fn advance(
        &mut self,
        from_ns: u64,
        from_pose: Pose2,
        to_ns: u64,
        to_pose: Pose2,
        scene: &LidarScene,
        line: &mut SerialLine,
    ) {
        loop {
            let t_ns = self.next_sample_ns;
            if t_ns > to_ns {
                break;
            }
            let fraction = if to_ns > from_ns {
                (t_ns.saturating_sub(from_ns)) as f64 / (to_ns - from_ns) as f64
            } else {
                1.0
            };
            let robot = interpolate(from_pose, to_pose, fraction);
            self.take_sample(robot, scene, t_ns, line);
        }
    }

    fn take_sample(&mut self, robot: Pose2, scene: &LidarScene, t_ns: u64, line: &mut SerialLine) {
        let index_in_rev = self.next_sample % self.samples_per_revolution;
        let head_deg = index_in_rev as f64 * self.step_deg();
        if index_in_rev == 0 {
            if let Some(rotation) = self.rotation {
                let factor = rotation.factor_at(t_ns as f64 * 1e-9);
                self.revolution_rate_hz = self.config.scan_rate_hz * factor;
                self.revolution_sample_ns = (self.sample_period_ns as f64 / factor).round() as u64;
            }
            self.flush(line, t_ns);
            let mut bytes = Vec::new();
            // The zero packet only marks the revolution; its single sample carries no range.
            if encode_packet(&self.spec(true, head_deg, head_deg, &[0.0]), &mut bytes).is_ok() {
                line.send(&bytes, t_ns);
            }
        }
        if self.packet.is_empty() {
            self.packet_first_index = index_in_rev;
        }
        let distance_mm = if self.enabled {
            self.measure(robot, head_deg, scene)
        } else {
            0.0
        };
        self.packet.push(distance_mm);
        self.next_sample += 1;
        self.next_sample_ns += self.revolution_sample_ns;
        let revolution_ends = self.next_sample.is_multiple_of(self.samples_per_revolution);
        if self.packet.len() == SAMPLES_PER_PACKET || revolution_ends {
            self.flush(line, t_ns);
        }
    }

    fn measure(&mut self, robot: Pose2, head_deg: f64, scene: &LidarScene) -> f64 {
        let lidar = robot.compose(self.mount);
        let head = Vec2::from_angle(lidar.yaw_rad - head_deg.to_radians());
        let clockwise_side = Vec2::new(head.y, -head.x);
        let origin = lidar.position() + clockwise_side * BEAM_OFFSET_M;
        let beam = head.rotated((BEAM_OFFSET_M / BEAM_CROSSING_M).atan());
        let Some(along_beam_m) = scene.cast(origin, beam) else {
            return 0.0;
        };
        let hit = origin + beam * along_beam_m;
        let true_m = hit.distance(lidar.position());
        let sigma_m = self.config.range_noise_std_m + self.noise_per_m * true_m;
        let noisy_m = true_m * self.range_scale + self.range_offset_m + self.rng.normal(sigma_m);
        if noisy_m < self.config.min_range_m || noisy_m > self.config.max_range_m {
            0.0
        } else {
            noisy_m * 1000.0
        }
    }

    fn spec<'a>(&self, start: bool, first_deg: f64, last_deg: f64, d: &'a [f64]) -> PacketSpec<'a> {
        PacketSpec {
            start_of_revolution: start,
            scan_frequency_hz: self.revolution_rate_hz.min(12.7),
            first_angle_deg: first_deg,
            last_angle_deg: last_deg,
            distances_mm: d,
        }
    }

    fn flush(&mut self, line: &mut SerialLine, t_ns: u64) {
        if self.packet.is_empty() {
            return;
        }
        let first = self.packet_first_index as f64 * self.step_deg();
        let last = first + (self.packet.len() - 1) as f64 * self.step_deg();
        let mut bytes = Vec::new();
        // Distances are within 0..=10 m and the frequency within the format: cannot fail.
        if encode_packet(&self.spec(false, first, last, &self.packet), &mut bytes).is_ok() {
            line.send(&bytes, t_ns);
        }
        self.packet.clear();
    }
}

/// The X4's true rotation speed over a round: `mean_factor × (1 + wander × sin(2π t /
/// wander_period_s + wander_phase_rad))` times the configured rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotation {
    /// The unit's mean rate over the configured one.
    pub mean_factor: f64,
    /// The wander's amplitude, a fraction of the mean.
    pub wander: f64,
    /// The wander's period, s.
    pub wander_period_s: f64,
    /// The wander's phase at time 0, rad.
    pub wander_phase_rad: f64,
}

impl Rotation {
    /// The true rate over the configured one at `t_s` seconds.
    pub fn factor_at(&self, t_s: f64) -> f64 {
        let angle = std::f64::consts::TAU * t_s / self.wander_period_s.max(1e-3);
        (self.mean_factor * (1.0 + self.wander * (angle + self.wander_phase_rad).sin())).max(0.1)
    }
}

/// The pose a `fraction` (0..=1) of the way from `a` to `b` (linear in position and yaw).
pub fn interpolate(a: Pose2, b: Pose2, fraction: f64) -> Pose2 {
    let f = fraction.clamp(0.0, 1.0);
    Pose2::new(
        a.x + (b.x - a.x) * f,
        a.y + (b.y - a.y) * f,
        a.yaw_rad + wrap_angle(b.yaw_rad - a.yaw_rad) * f,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_core::drivers::x4::X4Driver;
    use ratf_core::drivers::x4::scan::ScanConfig;

    fn scan_once(
        robot: Pose2,
        noise_m: f64,
    ) -> (Vec<ratf_core::drivers::x4::scan::Scan>, SimLidar) {
        scan_once_with(robot, noise_m, (1.0, 0.0))
    }

    /// One scan with a range calibration error (scale, offset m).
    fn scan_once_with(
        robot: Pose2,
        noise_m: f64,
        (scale, offset_m): (f64, f64),
    ) -> (Vec<ratf_core::drivers::x4::scan::Scan>, SimLidar) {
        let field = Field::competition();
        let robot_config = RobotConfig::default();
        let config = LidarConfig {
            range_noise_std_m: noise_m,
            ..LidarConfig::default()
        };
        let scene = LidarScene::new(&field, &[], robot_config.lidar_height_m);
        let mut lidar = SimLidar::new(&config, &robot_config, SimRng::new(1))
            .with_range_errors(scale, offset_m, 0.0);
        let mut line = SerialLine::new(128_000);
        let mut driver = X4Driver::new(ScanConfig::default());
        let mut scans = Vec::new();
        // 2.5 revolutions: the second zero packet hands over one whole scan.
        let end_ns = (2.5 / config.scan_rate_hz * 1e9) as u64;
        let mut t = 0;
        while t < end_ns {
            let next = t + 1_000_000;
            lidar.advance(t, robot, next, robot, &scene, &mut line);
            let bytes = line.receive(next);
            driver.feed(&bytes, next / 1000, |s| scans.push(s));
            t = next;
        }
        (scans, lidar)
    }

    #[test]
    fn it_answers_device_info_and_health_as_a_healthy_x4() {
        use ratf_core::drivers::x4::info::ReplyParser;
        let mut bytes = Vec::new();
        for request in [Request::DeviceInfo, Request::Health] {
            reply(request).encode(&mut bytes);
        }
        let mut replies = Vec::new();
        ReplyParser::new().feed(&bytes, |r| replies.push(r));
        assert_eq!(
            replies,
            [
                Reply::DeviceInfo(DEVICE_INFO),
                Reply::Health(Health {
                    status: HealthStatus::Ok,
                    error_code: 0
                })
            ]
        );
        assert_eq!(
            DEVICE_INFO.describe(),
            "X4, firmware 1.7, hardware 1, serial 2026112500000001"
        );
    }

    #[test]
    fn only_the_beacons_reach_the_scan_plane_by_default() {
        let field = Field::competition();
        let scene = LidarScene::new(&field, &[], 0.20);
        assert_eq!(scene.solids().len(), 4);
        let config = ratf_core::config::Config::default();
        let clutter = crate::world::Scenario::new(&config).clutter;
        let with_clutter = LidarScene::new(&field, &clutter, 0.20);
        assert_eq!(with_clutter.solids().len(), 4 + config.sim.clutter.len());
    }

    #[test]
    fn a_revolution_has_the_configured_samples_and_rate() {
        let (scans, lidar) = scan_once(Pose2::new(0.0, 0.0, 0.0), 0.0);
        assert_eq!(lidar.samples_per_revolution(), 720);
        assert_eq!(
            scans.len(),
            2,
            "two zero packets after the first revolution"
        );
        let scan = &scans[1];
        assert_eq!(scan.samples, 720);
        assert!((scan.scan_frequency_hz - 7.0).abs() < 1e-9);
    }

    /// Samples taken and scans handed out over `seconds` by a lidar turning at `rotation`.
    fn spin(
        rotation: Option<Rotation>,
        seconds: f64,
    ) -> (u64, Vec<ratf_core::drivers::x4::scan::Scan>) {
        let robot_config = RobotConfig::default();
        let config = LidarConfig::default();
        let scene = LidarScene::new(&Field::competition(), &[], robot_config.lidar_height_m);
        let mut lidar = SimLidar::new(&config, &robot_config, SimRng::new(1));
        if let Some(rotation) = rotation {
            lidar = lidar.with_rotation(rotation);
        }
        let mut line = SerialLine::new(128_000);
        let mut driver = X4Driver::new(ScanConfig::default());
        let mut scans = Vec::new();
        let robot = Pose2::new(0.0, 0.0, 0.0);
        let end_ns = (seconds * 1e9) as u64;
        let mut t = 0;
        while t < end_ns {
            let next = t + 1_000_000;
            lidar.advance(t, robot, next, robot, &scene, &mut line);
            driver.feed(&line.receive(next), next / 1000, |s| scans.push(s));
            t = next;
        }
        (lidar.next_sample, scans)
    }

    #[test]
    fn a_head_turning_off_its_rate_takes_its_revolutions_at_its_own_pace_and_says_so() {
        // 2 % fast, no wander: 10 s hold 71.4 revolutions instead of 70.
        let fast = Rotation {
            mean_factor: 1.02,
            wander: 0.0,
            wander_period_s: 60.0,
            wander_phase_rad: 0.0,
        };
        let (samples, scans) = spin(Some(fast), 10.0);
        let revolutions = samples as f64 / 720.0;
        assert!((revolutions - 71.4).abs() < 0.05, "{revolutions}");
        // The packets carry the true rate, at the format's 0.1 Hz resolution.
        assert!(
            scans
                .iter()
                .skip(1)
                .all(|s| (s.scan_frequency_hz - 7.1).abs() < 0.051)
        );
        // The configured rate, exactly as without a rotation.
        let (plain, _) = spin(None, 10.0);
        let unit = Rotation {
            mean_factor: 1.0,
            ..fast
        };
        assert_eq!(spin(Some(unit), 10.0).0, plain);
        assert_eq!(plain, 70 * 720);
    }

    #[test]
    fn the_rate_wanders_slowly_within_its_bounds() {
        let rotation = Rotation {
            mean_factor: 0.99,
            wander: 0.005,
            wander_period_s: 40.0,
            wander_phase_rad: 1.0,
        };
        let factors: Vec<f64> = (0..1200)
            .map(|i| rotation.factor_at(f64::from(i) * 0.1))
            .collect();
        let (lo, hi) = factors
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), &f| (lo.min(f), hi.max(f)));
        assert!((lo - 0.99 * 0.995).abs() < 1e-5 && (hi - 0.99 * 1.005).abs() < 1e-5);
        // Slow: 0.1 s apart (less than a revolution), the rate moves by less than 0.01 %.
        assert!(factors.windows(2).all(|w| (w[1] - w[0]).abs() < 1e-4));
    }

    #[test]
    fn each_beacon_is_seen_at_its_range_and_bearing_with_the_mount_pose() {
        let robot = Pose2::new(-0.3, 0.1, 0.4);
        let (scans, _) = scan_once(robot, 0.0);
        let scan = &scans[1];
        let config = RobotConfig::default();
        let lidar = robot.compose(config.lidar_mount());
        for beacon in Field::competition().beacons() {
            // The nearest surface point seen from the lidar is on the line to the centre.
            let expected_range =
                lidar.position().distance(beacon.circle.center) - beacon.circle.radius_m;
            let local = lidar.inverse_transform_point(beacon.circle.center);
            let expected_angle = local.y.atan2(local.x);
            let nearest = scan
                .points
                .iter()
                .min_by(|a, b| {
                    wrap_angle(a.angle_rad - expected_angle)
                        .abs()
                        .total_cmp(&wrap_angle(b.angle_rad - expected_angle).abs())
                })
                .unwrap();
            assert!(
                wrap_angle(nearest.angle_rad - expected_angle).abs() < 0.3f64.to_radians(),
                "beacon {} bearing {} vs {}",
                beacon.index,
                nearest.angle_rad,
                expected_angle
            );
            assert!(
                (nearest.range_m - expected_range).abs() < 0.003,
                "beacon {} range {} vs {}",
                beacon.index,
                nearest.range_m,
                expected_range
            );
        }
    }

    #[test]
    fn a_range_scale_error_reads_every_range_long_by_that_scale() {
        let robot = Pose2::new(-0.3, 0.1, 0.4);
        let (exact, _) = scan_once_with(robot, 0.0, (1.0, 0.0));
        let (long, _) = scan_once_with(robot, 0.0, (1.01, 0.005));
        let (exact, long) = (&exact[1], &long[1]);
        assert_eq!(exact.points.len(), long.points.len());
        for (e, l) in exact.points.iter().zip(&long.points) {
            // Millimetre quantisation of the X4's distances: within 1 mm of the model.
            let want = e.range_m * 1.01 + 0.005;
            assert!((l.range_m - want).abs() < 1.5e-3, "{} vs {want}", l.range_m);
        }
    }

    #[test]
    fn motion_during_the_sweep_shows_in_the_data() {
        // Moving at 1 m/s for one revolution shifts the last samples by ~0.14 m.
        let field = Field::competition();
        let config = RobotConfig::default();
        let scene = LidarScene::new(&field, &[], config.lidar_height_m);
        let mut moving = SimLidar::new(&LidarConfig::default(), &config, SimRng::new(1));
        let mut still = moving.clone();
        let (mut a, mut b) = (SerialLine::new(128_000), SerialLine::new(128_000));
        let start = Pose2::new(0.0, 0.0, 0.0);
        let rev_ns = (1e9 / 7.0) as u64;
        let end = Pose2::new(rev_ns as f64 * 1e-9, 0.0, 0.0);
        moving.advance(0, start, rev_ns, end, &scene, &mut a);
        still.advance(0, start, rev_ns, start, &scene, &mut b);
        assert_ne!(a.receive(u64::MAX), b.receive(u64::MAX));
    }
}
