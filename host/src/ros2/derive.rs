//! The ROS 2 topics of one step of the runtime, derived from what the core already knows
//! (its last input, its odometry, its localiser's covariance and last scan report, the
//! parts its planner believes in): nothing here estimates anything.
//!
//! | topic | type | when |
//! |---|---|---|
//! | `/tf_static` | `tf2_msgs/TFMessage` | once, first |
//! | `/markers/field` | `visualization_msgs/MarkerArray` | once, first |
//! | `/scan` | `sensor_msgs/LaserScan` | every scan (corrected ranges) |
//! | `/markers/beacons` | `visualization_msgs/MarkerArray` | every scan |
//! | `/odom` | `nav_msgs/Odometry` | every Mega telemetry batch |
//! | `/imu` | `sensor_msgs/Imu` | every IMU sample |
//! | `/localiser/pose` | `geometry_msgs/PoseWithCovarianceStamped` | every host tick |
//! | `/tf` | `tf2_msgs/TFMessage` | every host tick |
//! | `/sim/true_pose` | `geometry_msgs/PoseStamped` | every host tick, in the simulator |
//! | `/diagnostics` | `diagnostic_msgs/DiagnosticArray` | every second of host ticks |
//! | `/markers/parts` | `visualization_msgs/MarkerArray` | every second of host ticks |

use std::f64::consts::TAU;

use ratf_core::config::Config;
use ratf_core::drivers::imu::ImuSample;
use ratf_core::drivers::x4::scan::Scan;
use ratf_core::field::geometry::{Pose2, wrap_angle};
use ratf_core::field::{Field, PartColor};
use ratf_core::localisation::Health;
use ratf_core::mission::Activity;
use ratf_core::planning::tasks::{Place, State};
use ratf_core::runtime::{Core, DeviceKind, Input, StepView};

use super::frames;
use super::msgs::diagnostic::{DiagnosticArray, DiagnosticStatus, KeyValue};
use super::msgs::geometry::{
    Odometry, Point, Pose, PoseStamped, PoseWithCovariance, PoseWithCovarianceStamped, TfMessage,
    Twist, TwistWithCovariance, Vector3, planar_covariance,
};
use super::msgs::sensor::{Imu, LaserScan};
use super::msgs::visualization::{Marker, MarkerArray};
use super::msgs::{ColorRgba, EncodeError, Header, RosMessage, Time, to_cdr};

/// A topic the robot publishes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Topic {
    /// `/tf_static`.
    TfStatic,
    /// `/tf`.
    Tf,
    /// `/scan`.
    Scan,
    /// `/odom`.
    Odometry,
    /// `/imu`.
    Imu,
    /// `/localiser/pose`.
    Pose,
    /// `/sim/true_pose`.
    TruePose,
    /// `/markers/field`.
    FieldMarkers,
    /// `/markers/beacons`.
    BeaconMarkers,
    /// `/markers/parts`.
    PartMarkers,
    /// `/markers/path`.
    PathMarkers,
    /// `/diagnostics`.
    Diagnostics,
}

impl Topic {
    /// Every topic.
    pub const ALL: [Topic; 12] = [
        Topic::TfStatic,
        Topic::Tf,
        Topic::Scan,
        Topic::Odometry,
        Topic::Imu,
        Topic::Pose,
        Topic::TruePose,
        Topic::FieldMarkers,
        Topic::BeaconMarkers,
        Topic::PartMarkers,
        Topic::PathMarkers,
        Topic::Diagnostics,
    ];

    /// The topic's name (absolute, without a robot namespace).
    pub fn name(self) -> &'static str {
        match self {
            Topic::TfStatic => "/tf_static",
            Topic::Tf => "/tf",
            Topic::Scan => "/scan",
            Topic::Odometry => "/odom",
            Topic::Imu => "/imu",
            Topic::Pose => "/localiser/pose",
            Topic::TruePose => "/sim/true_pose",
            Topic::FieldMarkers => "/markers/field",
            Topic::BeaconMarkers => "/markers/beacons",
            Topic::PartMarkers => "/markers/parts",
            Topic::PathMarkers => "/markers/path",
            Topic::Diagnostics => "/diagnostics",
        }
    }

    /// The message type, `package/msg/Name`.
    pub fn type_name(self) -> &'static str {
        match self {
            Topic::TfStatic | Topic::Tf => TfMessage::TYPE_NAME,
            Topic::Scan => LaserScan::TYPE_NAME,
            Topic::Odometry => Odometry::TYPE_NAME,
            Topic::Imu => Imu::TYPE_NAME,
            Topic::Pose => PoseWithCovarianceStamped::TYPE_NAME,
            Topic::TruePose => PoseStamped::TYPE_NAME,
            Topic::FieldMarkers
            | Topic::BeaconMarkers
            | Topic::PartMarkers
            | Topic::PathMarkers => MarkerArray::TYPE_NAME,
            Topic::Diagnostics => DiagnosticArray::TYPE_NAME,
        }
    }
}

/// One message on its topic.
#[derive(Clone, Debug, PartialEq)]
pub enum Message {
    /// `/tf` or `/tf_static`.
    Tf(Topic, TfMessage),
    /// `/scan`.
    Scan(LaserScan),
    /// `/odom`.
    Odometry(Box<Odometry>),
    /// `/imu`.
    Imu(Box<Imu>),
    /// `/localiser/pose`.
    Pose(Box<PoseWithCovarianceStamped>),
    /// `/sim/true_pose`.
    TruePose(PoseStamped),
    /// One of the marker topics.
    Markers(Topic, MarkerArray),
    /// `/diagnostics`.
    Diagnostics(DiagnosticArray),
}

impl Message {
    /// Its topic.
    pub fn topic(&self) -> Topic {
        match self {
            Message::Tf(topic, _) | Message::Markers(topic, _) => *topic,
            Message::Scan(_) => Topic::Scan,
            Message::Odometry(_) => Topic::Odometry,
            Message::Imu(_) => Topic::Imu,
            Message::Pose(_) => Topic::Pose,
            Message::TruePose(_) => Topic::TruePose,
            Message::Diagnostics(_) => Topic::Diagnostics,
        }
    }

    /// The serialized message (CDR with its encapsulation header).
    pub fn to_cdr(&self) -> Result<Vec<u8>, EncodeError> {
        match self {
            Message::Tf(_, m) => to_cdr(m),
            Message::Scan(m) => to_cdr(m),
            Message::Odometry(m) => to_cdr(m.as_ref()),
            Message::Imu(m) => to_cdr(m.as_ref()),
            Message::Pose(m) => to_cdr(m.as_ref()),
            Message::TruePose(m) => to_cdr(m),
            Message::Markers(_, m) => to_cdr(m),
            Message::Diagnostics(m) => to_cdr(m),
        }
    }
}

/// How often the diagnostics and the parts are published, µs of robot time.
pub const SLOW_PERIOD_US: u64 = 1_000_000;

/// Derives the topics of each step; holds what accumulates (the odometry's variance, the
/// last device faults).
#[derive(Debug)]
pub struct Deriver {
    config: Config,
    field: Field,
    started: bool,
    next_slow_us: u64,
    odometry_variance: [f64; 3],
    faults: Vec<(DeviceKind, String)>,
    leg: Option<Activity>,
}

impl Deriver {
    /// A deriver for a run of `config` (the robot's beliefs: its field, its mounts).
    pub fn new(config: &Config) -> Self {
        Self {
            config: config.clone(),
            field: config.field.field(),
            started: false,
            next_slow_us: 0,
            odometry_variance: [0.0; 3],
            faults: Vec::new(),
            leg: None,
        }
    }

    /// The messages of `step`, appended to `out`.
    pub fn on_step(&mut self, step: &StepView<'_>, out: &mut Vec<Message>) {
        let now_us = step.input.time.as_us();
        let stamp = Time::from_us(now_us);
        let core = step.core;
        if !self.started {
            self.started = true;
            out.push(Message::Tf(
                Topic::TfStatic,
                frames::static_transforms(&self.config),
            ));
            out.push(Message::Markers(
                Topic::FieldMarkers,
                field_markers(&self.field, stamp),
            ));
        }
        match &step.input.input {
            Input::Scan(scan) => {
                out.push(Message::Scan(self.laser_scan(scan)));
                out.push(Message::Markers(
                    Topic::BeaconMarkers,
                    self.beacon_markers(core, stamp),
                ));
            }
            Input::Wheels(_) => {
                if let Some(odometry) = self.odometry(core, stamp) {
                    out.push(Message::Odometry(Box::new(odometry)));
                }
            }
            Input::Imu(sample) => out.push(Message::Imu(Box::new(self.imu(sample)))),
            Input::DeviceFault {
                device, message, ..
            } => {
                self.faults.retain(|(d, _)| d != device);
                self.faults.push((*device, message.clone()));
            }
            Input::HostTick => {
                let estimation = core.robot().estimation();
                let p = estimation.estimator().covariance();
                let rows = [0, 1, 2].map(|i| [p[(i, 0)], p[(i, 1)], p[(i, 2)]]);
                out.push(Message::Pose(Box::new(PoseWithCovarianceStamped {
                    header: Header::new(stamp, frames::MAP),
                    pose: PoseWithCovariance::planar(core.pose(), rows),
                })));
                out.push(Message::Tf(
                    Topic::Tf,
                    frames::dynamic_transforms(stamp, core.pose(), estimation.odometry_pose()),
                ));
                let activity = core.brain().activity();
                if activity != self.leg {
                    self.leg = activity;
                    out.push(Message::Markers(
                        Topic::PathMarkers,
                        self.path_markers(core, stamp),
                    ));
                }
                if let Some(truth) = step.ground_truth {
                    out.push(Message::TruePose(PoseStamped {
                        header: Header::new(stamp, frames::MAP),
                        pose: Pose::planar(truth, 0.0),
                    }));
                }
                if now_us >= self.next_slow_us {
                    self.next_slow_us = now_us + SLOW_PERIOD_US;
                    out.push(Message::Diagnostics(self.diagnostics(core, stamp)));
                    out.push(Message::Markers(
                        Topic::PartMarkers,
                        self.part_markers(core, stamp),
                    ));
                }
            }
            _ => {}
        }
    }

    /// The scan on a uniform grid of [`RAYS_PER_SAMPLE`] rays per sample of the
    /// revolution, from the first point's angle, turning the way the X4 turned: each point
    /// in the ray nearest its own angle as the X4 measured it (so within a quarter of the
    /// X4's step of it: the X4 does not turn uniformly, so a point's sample index alone
    /// would misplace it by degrees), its range corrected as the core corrects it
    /// (`[lidar] range_scale`, `range_offset_m`); rays without a point +∞ (no return).
    /// `time_increment` is the sample period over the rays per sample.
    fn laser_scan(&self, scan: &Scan) -> LaserScan {
        let lidar = &self.config.lidar;
        let rays = ((scan.samples as usize).max(scan.points.len()) * RAYS_PER_SAMPLE)
            .clamp(RAYS_PER_SAMPLE, MAX_RAYS);
        let first = scan.points.first().map_or(0.0, |p| p.angle_rad);
        let direction = sweep_direction(scan);
        let step_rad = TAU / rays as f64;
        let mut ranges = vec![f32::INFINITY; rays];
        for point in &scan.points {
            let turned = (direction * (point.angle_rad - first)).rem_euclid(TAU);
            let ray = (turned / step_rad).round() as usize % rays;
            if ranges[ray].is_infinite() {
                ranges[ray] = lidar.corrected_range_m(point.range_m) as f32;
            }
        }
        let increment = direction * step_rad;
        LaserScan {
            header: Header::new(Time::from_us_f64(scan.stamp_us), frames::LASER),
            angle_min: first as f32,
            angle_max: (first + increment * (rays - 1) as f64) as f32,
            angle_increment: increment as f32,
            time_increment: (scan.sample_period_us * 1e-6 / RAYS_PER_SAMPLE as f64) as f32,
            scan_time: if scan.scan_frequency_hz > 0.0 {
                (1.0 / scan.scan_frequency_hz) as f32
            } else {
                (scan.sample_period_us * 1e-6 * scan.samples as f64) as f32
            },
            range_min: lidar.min_range_m as f32,
            range_max: lidar.max_range_m as f32,
            ranges,
            intensities: Vec::new(),
        }
    }

    /// The wheel odometry after a telemetry batch, with the variance the localiser's
    /// wheel-only noise model (`[localisation] translation_var_m2_per_m`, `_per_rad`,
    /// `wheel_heading_var_rad2_per_rad`, `_per_m`) accumulates over the distance travelled.
    fn odometry(&mut self, core: &Core, stamp: Time) -> Option<Odometry> {
        let step = core.robot().last_odometry()?;
        if step.is_first {
            return None;
        }
        let noise = &self.config.localisation;
        let d = step.body_increment;
        let distance_m = d.dx_m.hypot(d.dy_m);
        let turn_rad = d.dtheta_rad.abs();
        let translation = noise.translation_var_m2_per_m * distance_m
            + noise.translation_var_m2_per_rad * turn_rad;
        let heading = noise.wheel_heading_var_rad2_per_rad * turn_rad
            + noise.wheel_heading_var_rad2_per_m * distance_m;
        self.odometry_variance[0] += translation;
        self.odometry_variance[1] += translation;
        self.odometry_variance[2] += heading;
        let [vx, vy, vyaw] = self.odometry_variance;
        let pose = core.robot().estimation().odometry_pose();
        let twist = step.twist;
        Some(Odometry {
            header: Header::new(stamp, frames::ODOM),
            child_frame_id: frames::BASE.to_owned(),
            pose: PoseWithCovariance::planar(
                pose,
                [[vx, 0.0, 0.0], [0.0, vy, 0.0], [0.0, 0.0, vyaw]],
            ),
            twist: TwistWithCovariance {
                twist: Twist {
                    linear: Vector3 {
                        x: twist.vx_m_s,
                        y: twist.vy_m_s,
                        z: 0.0,
                    },
                    angular: Vector3 {
                        x: 0.0,
                        y: 0.0,
                        z: twist.omega_rad_s,
                    },
                },
                covariance: planar_covariance([
                    [translation, 0.0, 0.0],
                    [0.0, translation, 0.0],
                    [0.0, 0.0, heading],
                ]),
            },
        })
    }

    /// The IMU sample in its own frame; the gyro's variance from its noise density
    /// (`[robot.imu] gyro_noise_density_rad_s_sqrt_hz`) over the read period's bandwidth
    /// is not claimed: the covariances are 0 ("unknown", REP 145) but for the absent
    /// orientation.
    fn imu(&self, sample: &ImuSample) -> Imu {
        let [gx, gy, gz] = sample.gyro_rad_s;
        let [ax, ay, az] = sample.accel_m_s2;
        let mut orientation_covariance = [0.0; 9];
        orientation_covariance[0] = -1.0;
        Imu {
            header: Header::new(Time::from_us(sample.time_us), frames::IMU),
            orientation: Default::default(),
            orientation_covariance,
            angular_velocity: Vector3 {
                x: gx,
                y: gy,
                z: gz,
            },
            angular_velocity_covariance: [0.0; 9],
            linear_acceleration: Vector3 {
                x: ax,
                y: ay,
                z: az,
            },
            linear_acceleration_covariance: [0.0; 9],
        }
    }

    /// The four beacons as the robot believes them, coloured by what the last scan did
    /// with each: green used, red offered but gated out (`[localisation] gate_chi2`), grey
    /// not seen.
    fn beacon_markers(&self, core: &Core, stamp: Time) -> MarkerArray {
        let report = core.localisation_health().last_scan;
        let gate = self.config.localisation.gate_chi2;
        let markers = self
            .field
            .beacons()
            .iter()
            .map(|beacon| {
                let color = match report.nis.get(beacon.index).copied().flatten() {
                    Some(nis) if nis <= gate => ColorRgba::rgb(0.1, 0.8, 0.1),
                    Some(_) => ColorRgba::rgb(0.9, 0.1, 0.1),
                    None => ColorRgba::rgb(0.5, 0.5, 0.5),
                };
                let centre = beacon.circle.center;
                Marker {
                    header: Header::new(stamp, frames::MAP),
                    ns: "beacons".into(),
                    id: beacon.index as i32,
                    kind: Marker::CYLINDER,
                    pose: Pose::planar(Pose2::new(centre.x, centre.y, 0.0), 0.5 * beacon.height_m),
                    scale: Vector3 {
                        x: 2.0 * beacon.circle.radius_m,
                        y: 2.0 * beacon.circle.radius_m,
                        z: beacon.height_m,
                    },
                    color,
                    ..Marker::default()
                }
            })
            .collect();
        MarkerArray { markers }
    }

    /// The parts the planner believes in: at their slot's box, or on the robot when
    /// carried; a `DELETEALL` first so parts gone from the list disappear.
    fn part_markers(&self, core: &Core, stamp: Time) -> MarkerArray {
        let mut markers = vec![Marker {
            header: Header::new(stamp, frames::MAP),
            ns: "parts".into(),
            action: Marker::DELETEALL,
            ..Marker::default()
        }];
        let Some(state) = core.brain().actions().map(|a| a.state()) else {
            return MarkerArray { markers };
        };
        markers.extend(
            part_positions(state, &self.field, core.pose())
                .enumerate()
                .map(|(id, (x, y, color))| Marker {
                    header: Header::new(stamp, frames::MAP),
                    ns: "parts".into(),
                    id: id as i32,
                    kind: Marker::CYLINDER,
                    pose: Pose::planar(Pose2::new(x, y, 0.0), 0.03),
                    scale: Vector3 {
                        x: 0.04,
                        y: 0.04,
                        z: 0.06,
                    },
                    color: part_color(color),
                    ..Marker::default()
                }),
        );
        MarkerArray { markers }
    }

    /// The route the robot set off on (the navigator's own, as planned when the leg began)
    /// and the slot it goes to; a `DELETEALL` first, so only the current leg shows.
    fn path_markers(&self, core: &Core, stamp: Time) -> MarkerArray {
        let mut markers = vec![Marker {
            header: Header::new(stamp, frames::MAP),
            ns: "path".into(),
            action: Marker::DELETEALL,
            ..Marker::default()
        }];
        let (Some(Activity::ToPick { .. } | Activity::ToDrop { .. }), Some(route)) =
            (core.brain().activity(), core.brain().planned_route())
        else {
            return MarkerArray { markers };
        };
        let color = ColorRgba::rgb(0.55, 0.2, 0.85);
        markers.push(Marker {
            header: Header::new(stamp, frames::MAP),
            ns: "path".into(),
            id: 0,
            kind: Marker::LINE_STRIP,
            pose: Pose::planar(Pose2::default(), 0.0),
            scale: Vector3 {
                x: 0.01,
                y: 0.0,
                z: 0.0,
            },
            color,
            points: route
                .points()
                .iter()
                .map(|p| Point {
                    x: p.x,
                    y: p.y,
                    z: 0.01,
                })
                .collect(),
            ..Marker::default()
        });
        // The route's own goal: a drop's ends short of the slot's pick pose.
        markers.push(Marker {
            header: Header::new(stamp, frames::MAP),
            ns: "path".into(),
            id: 1,
            kind: Marker::SPHERE,
            pose: Pose::planar(route.goal(), 0.02),
            scale: Vector3 {
                x: 0.04,
                y: 0.04,
                z: 0.04,
            },
            color,
            ..Marker::default()
        });
        MarkerArray { markers }
    }

    /// Health of the devices, the localiser, the server link and the mission.
    fn diagnostics(&self, core: &Core, stamp: Time) -> DiagnosticArray {
        let status = core.status();
        let counts = status.inputs;
        let health = core.localisation_health();
        let device = |kind: DeviceKind, name: &str, count: u64, unit: &str| {
            let fault = self.faults.iter().find(|(d, _)| *d == kind);
            let (level, message) = match fault {
                Some((_, message)) => (DiagnosticStatus::ERROR, message.clone()),
                None if count == 0 => (DiagnosticStatus::WARN, format!("no {unit} yet")),
                None => (DiagnosticStatus::OK, format!("{count} {unit}")),
            };
            DiagnosticStatus {
                level,
                name: format!("ratf: {name}"),
                message,
                hardware_id: String::new(),
                values: vec![value(unit, count)],
            }
        };
        let mut mega = device(
            DeviceKind::Mega,
            "Mega link",
            counts.wheel_batches,
            "batches",
        );
        mega.values.push(value("resets", counts.mega_resets));
        mega.values
            .push(value("switch_pressed", status.switch_pressed));
        let server = self.faults.iter().find(|(d, _)| *d == DeviceKind::Referee);
        let server = DiagnosticStatus {
            level: if server.is_some() {
                DiagnosticStatus::ERROR
            } else {
                DiagnosticStatus::OK
            },
            name: "ratf: server".into(),
            message: match (server, status.started) {
                (Some((_, message)), _) => message.clone(),
                (None, Some(_)) => "part list received".into(),
                (None, None) => "waiting for the part list".into(),
            },
            hardware_id: String::new(),
            values: vec![value(
                "started_s",
                status
                    .started
                    .map_or_else(|| "-".into(), |t| format!("{:.3}", t.as_secs_f64())),
            )],
        };
        let localiser = localiser_status(&health);
        let mission = DiagnosticStatus {
            level: if status.stopped {
                DiagnosticStatus::WARN
            } else {
                DiagnosticStatus::OK
            },
            name: "ratf: mission".into(),
            message: format!(
                "{:?}{}{}",
                status.phase,
                if status.stopped { ", stopped" } else { "" },
                if status.manual { ", manual" } else { "" }
            ),
            hardware_id: String::new(),
            values: vec![
                value("phase", format!("{:?}", status.phase)),
                value("placed", status.placed),
                value("stopped", status.stopped),
                value("manual", status.manual),
            ],
        };
        DiagnosticArray {
            header: Header::new(stamp, ""),
            status: vec![
                mega,
                device(DeviceKind::Lidar, "lidar", counts.scans, "scans"),
                device(DeviceKind::Imu, "IMU", counts.imu_samples, "samples"),
                server,
                localiser,
                mission,
            ],
        }
    }
}

/// Most rays a scan message carries (the X4 gives about 720 samples per revolution).
const MAX_RAYS: usize = 8192;

/// Rays per sample of the revolution: two, so that two neighbouring samples whose angles
/// jitter by up to a quarter of a step still land in rays of their own.
pub const RAYS_PER_SAMPLE: usize = 2;

/// +1 when the scan's angles grow in acquisition order, −1 when they fall (the X4 turns
/// clockwise, so its counter-clockwise angles fall): the sign of the sum of the wrapped
/// steps between consecutive points.
fn sweep_direction(scan: &Scan) -> f64 {
    let turned: f64 = scan
        .points
        .windows(2)
        .map(|pair| wrap_angle(pair[1].angle_rad - pair[0].angle_rad))
        .sum();
    if turned > 0.0 { 1.0 } else { -1.0 }
}

fn value(key: &str, value: impl ToString) -> KeyValue {
    KeyValue {
        key: key.to_owned(),
        value: value.to_string(),
    }
}

/// Where each part of `state` is (x, y, world frame) and its colour.
fn part_positions<'a>(
    state: &'a State,
    field: &'a Field,
    robot: Pose2,
) -> impl Iterator<Item = (f64, f64, PartColor)> + 'a {
    state.parts.iter().filter_map(move |part| {
        let (x, y) = match part.place {
            Place::At(location) => {
                let centre = location.slot(field)?.box_center;
                (centre.x, centre.y)
            }
            Place::Carried => (robot.x, robot.y),
        };
        Some((x, y, part.color))
    })
}

fn part_color(color: PartColor) -> ColorRgba {
    match color {
        PartColor::Red => ColorRgba::rgb(0.9, 0.1, 0.1),
        PartColor::Green => ColorRgba::rgb(0.1, 0.8, 0.1),
        PartColor::Blue => ColorRgba::rgb(0.1, 0.3, 0.9),
    }
}

/// The localiser's diagnostic: a warning while it is lost (`Health::relocking`: it raised
/// its uncertainty after scans without a beacon and no scan has fixed the pose since).
fn localiser_status(health: &Health) -> DiagnosticStatus {
    DiagnosticStatus {
        level: if health.relocking {
            DiagnosticStatus::WARN
        } else {
            DiagnosticStatus::OK
        },
        name: "ratf: localiser".into(),
        message: format!(
            "σ {:.3} m, {:.2}°{}",
            health.position_std_m,
            health.heading_std_rad.to_degrees(),
            if health.relocking { ", lost" } else { "" }
        ),
        hardware_id: String::new(),
        values: vec![
            value("position_std_m", health.position_std_m),
            value("heading_std_rad", health.heading_std_rad),
            value("scans_applied", health.scans_applied),
            value("beacons_used", health.beacons_used),
            value("beacons_gated", health.beacons_gated),
            value("scans_without_beacons", health.scans_without_beacons),
            value("relocks", health.relocks),
            value("relocking", health.relocking),
            value("relocks_refused", health.relocks_refused),
        ],
    }
}

/// The field as the robot believes it: the printed floor, its border, and every wall
/// and divider of the warehouses and machines as a box.
pub fn field_markers(field: &Field, stamp: Time) -> MarkerArray {
    let floor = field.printed_area();
    let centre = floor.center();
    let mut markers = vec![Marker {
        header: Header::new(stamp, frames::MAP),
        ns: "field/floor".into(),
        kind: Marker::CUBE,
        pose: Pose::planar(Pose2::new(centre.x, centre.y, 0.0), -0.001),
        scale: Vector3 {
            x: floor.size_x(),
            y: floor.size_y(),
            z: 0.002,
        },
        color: ColorRgba::rgb(0.85, 0.85, 0.8),
        ..Marker::default()
    }];
    for (id, obstacle) in field.obstacles().iter().enumerate() {
        let c = obstacle.rect.center();
        markers.push(Marker {
            header: Header::new(stamp, frames::MAP),
            ns: format!("field/{:?}", obstacle.kind),
            id: id as i32,
            kind: Marker::CUBE,
            pose: Pose::planar(Pose2::new(c.x, c.y, 0.0), 0.5 * obstacle.height_m),
            scale: Vector3 {
                x: obstacle.rect.size_x(),
                y: obstacle.rect.size_y(),
                z: obstacle.height_m,
            },
            color: ColorRgba::rgb(0.3, 0.3, 0.35),
            ..Marker::default()
        });
    }
    MarkerArray { markers }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_core::drivers::x4::scan::ScanPoint;

    fn scan(angles: &[f64], samples: u32) -> Scan {
        Scan {
            stamp_us: 1_000_000.0,
            sample_period_us: 200.0,
            scan_frequency_hz: 7.0,
            points: angles
                .iter()
                .enumerate()
                .map(|(k, a)| ScanPoint {
                    angle_rad: *a,
                    range_m: 1.0 + k as f64,
                    time_offset_us: 200.0 * k as f64,
                })
                .collect(),
            samples,
            points_out_of_range: 0,
            points_overflowed: 0,
            packets_dropped: 0,
        }
    }

    #[test]
    fn each_range_sits_at_its_own_angle_and_gaps_are_infinite() {
        let deriver = Deriver::new(&Config::default());
        let step = TAU / 8.0;
        // Clockwise (decreasing angles) across ±π, one sample dropped, one jittered by
        // less than a quarter step: 8 samples → 16 rays of 22.5°.
        let angles = [-2.5, -2.5 - step + 0.1 + TAU, -2.5 - 3.0 * step + TAU];
        let message = deriver.laser_scan(&scan(&angles, 8));
        assert_eq!(message.ranges.len(), 16);
        assert!((f64::from(message.angle_increment) + TAU / 16.0).abs() < 1e-6);
        assert!((f64::from(message.angle_min) + 2.5).abs() < 1e-6);
        let lidar = &Config::default().lidar;
        let expected = |r: f64| lidar.corrected_range_m(r) as f32;
        assert_eq!(message.ranges[0], expected(1.0));
        assert_eq!(message.ranges[2], expected(2.0));
        assert_eq!(message.ranges[6], expected(3.0));
        assert_eq!(
            message.ranges.iter().filter(|r| r.is_finite()).count(),
            3,
            "{:?}",
            message.ranges
        );
        assert!((f64::from(message.time_increment) - 100e-6).abs() < 1e-9);
        assert_eq!(message.header.stamp, Time { sec: 1, nanosec: 0 });
        assert_eq!(message.header.frame_id, frames::LASER);
    }

    #[test]
    fn a_counter_clockwise_scan_turns_the_grid_the_other_way() {
        let deriver = Deriver::new(&Config::default());
        let message = deriver.laser_scan(&scan(&[0.0, 0.5, 1.0], 12));
        assert!(message.angle_increment > 0.0);
    }

    #[test]
    fn an_empty_scan_has_no_return_on_every_ray() {
        let deriver = Deriver::new(&Config::default());
        let message = deriver.laser_scan(&scan(&[], 720));
        assert_eq!(message.ranges.len(), 720 * RAYS_PER_SAMPLE);
        assert!(message.ranges.iter().all(|r| r.is_infinite()));
        assert!(message.angle_increment < 0.0);
    }

    #[test]
    fn the_field_has_a_floor_and_every_obstacle() {
        let field = Field::competition();
        let markers = field_markers(&field, Time::default());
        assert_eq!(markers.markers.len(), 1 + field.obstacles().len());
        assert!(to_cdr(&markers).is_ok());
    }

    /// A lost localiser warns; before, the warning compared `scans_without_beacons` with
    /// the relock limit, which the localiser resets to 0 on reaching it, so it never came.
    #[test]
    fn a_lost_localiser_is_a_warning_and_a_found_one_is_not() {
        let lost = Health {
            relocking: true,
            relocks: 1,
            ..Health::default()
        };
        let status = localiser_status(&lost);
        assert_eq!(status.level, DiagnosticStatus::WARN, "{status:?}");
        assert!(status.message.ends_with(", lost"), "{status:?}");
        let found = Health {
            scans_without_beacons: 2,
            relocks: 1,
            ..Health::default()
        };
        assert_eq!(localiser_status(&found).level, DiagnosticStatus::OK);
    }

    #[test]
    fn every_topic_has_a_definition() {
        for topic in Topic::ALL {
            assert!(
                super::super::msgs::definition::full_text(topic.type_name()).is_some(),
                "{}",
                topic.name()
            );
        }
    }
}
