//! The live ROS 2 bridge (cargo feature `ros2`): the topics of [`super::derive`] published
//! on DDS as a [`Tap`] of the runtime, and `cmd_vel` and `initialpose` subscribed and turned
//! into operator commands ([`crate::devices::operator`]), so they enter the core as inputs
//! and are recorded too.
//!
//! DDS is `ros2-client` on RustDDS (pure Rust, no ROS installation). Naming is ROS 2's:
//! topic `/scan` of a robot in namespace `/robot1` is the DDS topic `rt/robot1/scan` of type
//! `sensor_msgs::msg::dds_::LaserScan_`. QoS: every writer reliable, keep last 10 (a
//! best-effort writer never matches a reliable reader); `/tf_static` and `/markers/field`
//! reliable and transient-local, keep last 1, so rviz2 started late still gets them.
//!
//! `cmd_vel` (`geometry_msgs/Twist`, robot frame) drives only when the operator enabled it
//! ([`BridgeOptions::cmd_vel`], `--ros2-cmd-vel`): each message is an
//! [`OperatorCommand::Drive`], which holds for the core's 0.5 s deadman. `initialpose`
//! (`geometry_msgs/PoseWithCovarianceStamped`, frame `map`) is an
//! [`OperatorCommand::SetPose`].

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use ros2_client::dds::rustdds::{
    DomainParticipantBuilder, DomainParticipantStatusEvent, DomainParticipantStatusListener,
    StatusEvented,
};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile,
    Subscription,
};

use ratf_core::config::Config;
use ratf_core::field::geometry::Pose2;
use ratf_core::kinematics::BodyTwist;
use ratf_core::runtime::{OperatorCommand, StepView, Tap};

use super::derive::{Deriver, Message, Topic};
use super::frames;
use super::live::{BridgeError, BridgeOptions};
use super::msgs::diagnostic::DiagnosticArray;
use super::msgs::geometry::{PoseStamped, PoseWithCovarianceStamped, TfMessage, Twist};
use super::msgs::sensor::{Imu, LaserScan};
use super::msgs::visualization::MarkerArray;
use super::msgs::{RosMessage, geometry::Odometry};
use crate::devices::operator::OperatorSender;

macro_rules! ros_message {
    ($($t:ty),*) => { $(impl ros2_client::Message for $t {})* };
}
ros_message!(
    TfMessage,
    LaserScan,
    Odometry,
    Imu,
    PoseWithCovarianceStamped,
    PoseStamped,
    MarkerArray,
    DiagnosticArray,
    Twist
);

/// Counters of what came in from ROS 2.
#[derive(Debug, Default)]
pub struct BridgeCounters {
    /// `cmd_vel` messages passed on as drive commands.
    pub cmd_vel_driven: AtomicU64,
    /// `cmd_vel` messages ignored because the operator has not enabled it.
    pub cmd_vel_ignored: AtomicU64,
    /// `initialpose` messages passed on.
    pub initial_poses: AtomicU64,
    /// Messages refused (wrong frame, not finite, the operator queue full).
    pub refused: AtomicU64,
    /// Peers whose QoS does not match ours (reported on stderr as they are found).
    pub qos_mismatches: AtomicU64,
}

struct Publishers {
    tf_static: Publisher<TfMessage>,
    tf: Publisher<TfMessage>,
    scan: Publisher<LaserScan>,
    odometry: Publisher<Odometry>,
    imu: Publisher<Imu>,
    pose: Publisher<PoseWithCovarianceStamped>,
    true_pose: Publisher<PoseStamped>,
    field: Publisher<MarkerArray>,
    beacons: Publisher<MarkerArray>,
    parts: Publisher<MarkerArray>,
    path: Publisher<MarkerArray>,
    diagnostics: Publisher<DiagnosticArray>,
}

/// The live bridge: a [`Tap`] publishing every step's topics, and a thread taking
/// `cmd_vel` and `initialpose`.
pub struct Bridge {
    publishers: Publishers,
    deriver: Deriver,
    messages: Vec<Message>,
    publish_errors: u64,
    counters: Arc<BridgeCounters>,
    stop: Arc<AtomicBool>,
    listener: Option<JoinHandle<()>>,
    _node: Node,
}

impl std::fmt::Debug for Bridge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bridge")
            .field("publish_errors", &self.publish_errors)
            .field("counters", &self.counters)
            .finish()
    }
}

/// Reliable, keep last 10: what every live topic uses.
fn live_qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Fail)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

/// Reliable, transient-local, keep last 1: `/tf_static` and the field.
fn latched_qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Fail)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}

/// `package/msg/Name` → its `MessageTypeName`.
fn type_name(full: &str) -> MessageTypeName {
    let mut parts = full.split('/');
    let package = parts.next().unwrap_or_default();
    let name = parts.next_back().unwrap_or_default();
    MessageTypeName::new(package, name)
}

impl Bridge {
    /// Join the ROS 2 graph with `options` for a run of `config`; ROS commands go to
    /// `operator`.
    pub fn start(
        config: &Config,
        options: &BridgeOptions,
        operator: OperatorSender,
    ) -> Result<Self, BridgeError> {
        let dds = |e: &dyn std::fmt::Display| BridgeError::Dds(e.to_string());
        let namespace = if options.namespace.is_empty() {
            "/".to_owned()
        } else {
            options.namespace.clone()
        };
        let mut builder = DomainParticipantBuilder::new(options.domain_id);
        if options.loopback_only {
            builder = builder.with_only_networks([std::net::Ipv4Addr::LOCALHOST]);
        }
        let participant = builder.build().map_err(|e| dds(&e))?;
        let status = participant.status_listener();
        let context = Context::from_domain_participant(participant).map_err(|e| dds(&e))?;
        let node_name = NodeName::new(&namespace, "ratf")
            .map_err(|_| BridgeError::Namespace(options.namespace.clone()))?;
        let mut node = context
            .new_node(node_name, NodeOptions::new())
            .map_err(|e| dds(&e))?;
        let name = |topic: &str| -> Result<Name, BridgeError> {
            let full = if namespace == "/" {
                topic.to_owned()
            } else {
                format!("{namespace}{topic}")
            };
            Name::parse(&full).map_err(|_| BridgeError::Namespace(options.namespace.clone()))
        };
        macro_rules! publisher {
            ($topic:expr, $qos:expr) => {{
                let topic = $topic;
                let qos = $qos;
                let dds_topic = node
                    .create_topic(&name(topic.name())?, type_name(topic.type_name()), &qos)
                    .map_err(|e| dds(&e))?;
                node.create_publisher(&dds_topic, Some(qos))
                    .map_err(|e| dds(&e))?
            }};
        }
        let publishers = Publishers {
            tf_static: publisher!(Topic::TfStatic, latched_qos()),
            tf: publisher!(Topic::Tf, live_qos()),
            scan: publisher!(Topic::Scan, live_qos()),
            odometry: publisher!(Topic::Odometry, live_qos()),
            imu: publisher!(Topic::Imu, live_qos()),
            pose: publisher!(Topic::Pose, live_qos()),
            true_pose: publisher!(Topic::TruePose, live_qos()),
            field: publisher!(Topic::FieldMarkers, latched_qos()),
            beacons: publisher!(Topic::BeaconMarkers, live_qos()),
            parts: publisher!(Topic::PartMarkers, live_qos()),
            path: publisher!(Topic::PathMarkers, live_qos()),
            diagnostics: publisher!(Topic::Diagnostics, live_qos()),
        };
        let command_qos = QosProfile::subscription_default()
            .reliability_reliable(WhenFull::DEFAULT)
            .history(History::KeepLast { depth: 10 });
        let cmd_vel_topic = node
            .create_topic(
                &name("/cmd_vel")?,
                type_name(Twist::TYPE_NAME),
                &command_qos,
            )
            .map_err(|e| dds(&e))?;
        let cmd_vel: Subscription<Twist> = node
            .create_subscription(&cmd_vel_topic, Some(command_qos.clone()))
            .map_err(|e| dds(&e))?;
        let pose_topic = node
            .create_topic(
                &name("/initialpose")?,
                type_name(PoseWithCovarianceStamped::TYPE_NAME),
                &command_qos,
            )
            .map_err(|e| dds(&e))?;
        let initial_pose: Subscription<PoseWithCovarianceStamped> = node
            .create_subscription(&pose_topic, Some(command_qos))
            .map_err(|e| dds(&e))?;
        let counters = Arc::new(BridgeCounters::default());
        let stop = Arc::new(AtomicBool::new(false));
        let listener = {
            let counters = Arc::clone(&counters);
            let stop = Arc::clone(&stop);
            let drive = options.cmd_vel;
            std::thread::Builder::new()
                .name("ros2-commands".into())
                .spawn(move || {
                    let peers = Peers {
                        cmd_vel,
                        initial_pose,
                        status,
                    };
                    listen(&peers, drive, &operator, &counters, &stop)
                })
                .map_err(|e| dds(&e))?
        };
        Ok(Self {
            publishers,
            deriver: Deriver::new(config),
            messages: Vec::new(),
            publish_errors: 0,
            counters,
            stop,
            listener: Some(listener),
            _node: node,
        })
    }

    /// What came in from ROS 2 so far.
    pub fn counters(&self) -> &BridgeCounters {
        &self.counters
    }

    /// Messages DDS refused to send (a full send window of a reliable writer).
    pub fn publish_errors(&self) -> u64 {
        self.publish_errors
    }

    fn publish(&mut self, message: Message) {
        let p = &self.publishers;
        let sent = match message {
            Message::Tf(Topic::TfStatic, m) => p.tf_static.publish(m).is_ok(),
            Message::Tf(_, m) => p.tf.publish(m).is_ok(),
            Message::Scan(m) => p.scan.publish(m).is_ok(),
            Message::Odometry(m) => p.odometry.publish(*m).is_ok(),
            Message::Imu(m) => p.imu.publish(*m).is_ok(),
            Message::Pose(m) => p.pose.publish(*m).is_ok(),
            Message::TruePose(m) => p.true_pose.publish(m).is_ok(),
            Message::Markers(Topic::FieldMarkers, m) => p.field.publish(m).is_ok(),
            Message::Markers(Topic::BeaconMarkers, m) => p.beacons.publish(m).is_ok(),
            Message::Markers(Topic::PathMarkers, m) => p.path.publish(m).is_ok(),
            Message::Markers(_, m) => p.parts.publish(m).is_ok(),
            Message::Diagnostics(m) => p.diagnostics.publish(m).is_ok(),
        };
        if !sent {
            self.publish_errors += 1;
        }
    }
}

impl Tap for Bridge {
    fn on_step(&mut self, step: &StepView<'_>) {
        let mut messages = std::mem::take(&mut self.messages);
        self.deriver.on_step(step, &mut messages);
        for message in messages.drain(..) {
            self.publish(message);
        }
        self.messages = messages;
    }
}

impl Drop for Bridge {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(listener) = self.listener.take() {
            let _ = listener.join();
        }
    }
}

/// How often the command thread looks for `cmd_vel` and `initialpose` (well inside the
/// 20 ms host tick).
const POLL_PERIOD: Duration = Duration::from_millis(5);

/// What the command thread reads.
struct Peers {
    cmd_vel: Subscription<Twist>,
    initial_pose: Subscription<PoseWithCovarianceStamped>,
    status: DomainParticipantStatusListener,
}

fn listen(
    peers: &Peers,
    drive: bool,
    operator: &OperatorSender,
    counters: &BridgeCounters,
    stop: &AtomicBool,
) {
    while !stop.load(Ordering::Relaxed) {
        while let Ok(Some((twist, _))) = peers.cmd_vel.take() {
            if !drive {
                counters.cmd_vel_ignored.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            let sent = drive_command(&twist).is_some_and(|c| operator.send(c).is_ok());
            let counter = if sent {
                &counters.cmd_vel_driven
            } else {
                &counters.refused
            };
            counter.fetch_add(1, Ordering::Relaxed);
        }
        while let Ok(Some((pose, _))) = peers.initial_pose.take() {
            let sent = set_pose_command(&pose).is_some_and(|c| operator.send(c).is_ok());
            let counter = if sent {
                &counters.initial_poses
            } else {
                &counters.refused
            };
            counter.fetch_add(1, Ordering::Relaxed);
        }
        while let Some(event) = peers.status.try_recv_status() {
            report_qos_mismatch(&event, counters);
        }
        std::thread::sleep(POLL_PERIOD);
    }
}

/// A peer whose QoS cannot match ours would get nothing, silently: say so on stderr.
fn report_qos_mismatch(event: &DomainParticipantStatusEvent, counters: &BridgeCounters) {
    let (side, requested, offered) = match event {
        DomainParticipantStatusEvent::RemoteReaderQosIncompatible {
            requested_qos,
            offered_qos,
            ..
        } => ("a subscriber", requested_qos, offered_qos),
        DomainParticipantStatusEvent::RemoteWriterQosIncompatible {
            requested_qos,
            offered_qos,
            ..
        } => ("a publisher", requested_qos, offered_qos),
        _ => return,
    };
    counters.qos_mismatches.fetch_add(1, Ordering::Relaxed);
    eprintln!(
        "ROS 2: QoS mismatch with {side}, no data will flow between us: it requests \
         reliability {:?}, durability {:?}; the writer offers reliability {:?}, durability \
         {:?}. Our topics are reliable and volatile (tf_static and markers/field: \
         transient-local); cmd_vel and initialpose are read reliable: set the peer's QoS \
         to match",
        requested.reliability(),
        requested.durability(),
        offered.reliability(),
        offered.durability()
    );
}

/// A `cmd_vel` twist (robot frame: x forward, y left, yaw rate) as a drive command;
/// `None` when not finite.
pub fn drive_command(twist: &Twist) -> Option<OperatorCommand> {
    let t = BodyTwist::new(twist.linear.x, twist.linear.y, twist.angular.z);
    [t.vx_m_s, t.vy_m_s, t.omega_rad_s]
        .iter()
        .all(|v| v.is_finite())
        .then_some(OperatorCommand::Drive { twist: t })
}

/// An `initialpose` as a set-pose command; `None` unless in `map` (or no frame) and finite.
pub fn set_pose_command(message: &PoseWithCovarianceStamped) -> Option<OperatorCommand> {
    let frame = message.header.frame_id.trim_start_matches('/');
    if !(frame.is_empty() || frame == frames::MAP) {
        return None;
    }
    let p = message.pose.pose;
    let q = p.orientation;
    let yaw = (2.0 * (q.w * q.z + q.x * q.y)).atan2(1.0 - 2.0 * (q.y * q.y + q.z * q.z));
    let pose = Pose2::new(p.position.x, p.position.y, yaw);
    pose.is_finite()
        .then_some(OperatorCommand::SetPose { pose })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros2::msgs::geometry::{PoseWithCovariance, Vector3};
    use crate::ros2::msgs::{Header, Time};

    #[test]
    fn cmd_vel_is_a_robot_frame_drive_and_nan_is_refused() {
        let twist = Twist {
            linear: Vector3 {
                x: 0.2,
                y: -0.1,
                z: 0.0,
            },
            angular: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 0.5,
            },
        };
        assert_eq!(
            drive_command(&twist),
            Some(OperatorCommand::Drive {
                twist: BodyTwist::new(0.2, -0.1, 0.5)
            })
        );
        let mut bad = twist;
        bad.angular.z = f64::NAN;
        assert_eq!(drive_command(&bad), None);
    }

    #[test]
    fn initialpose_in_map_sets_the_pose_and_another_frame_is_refused() {
        let mut message = PoseWithCovarianceStamped {
            header: Header::new(Time::default(), "map"),
            pose: PoseWithCovariance::planar(Pose2::new(0.3, -0.2, 1.0), [[0.0; 3]; 3]),
        };
        let Some(OperatorCommand::SetPose { pose }) = set_pose_command(&message) else {
            panic!("no set-pose command");
        };
        assert!((pose.x - 0.3).abs() < 1e-12 && (pose.y + 0.2).abs() < 1e-12);
        assert!((pose.yaw_rad - 1.0).abs() < 1e-12);
        message.header.frame_id = "odom".into();
        assert_eq!(set_pose_command(&message), None);
    }
}
