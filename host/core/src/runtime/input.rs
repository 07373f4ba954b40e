//! What the core consumes: timestamped inputs.

use serde::{Deserialize, Serialize};

use crate::drivers::imu::ImuSample;
use crate::drivers::mega_link::WheelTelemetry;
use crate::drivers::x4::scan::Scan;
use crate::field::PartColor;
use crate::field::geometry::Pose2;
use crate::kinematics::BodyTwist;

/// A time on the robot's monotonic clock, µs since the devices' common epoch (power-up in
/// the simulator, the process start on the robot). Only devices read a clock; the core
/// sees time only through these stamps.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Timestamp(u64);

impl Timestamp {
    /// The epoch.
    pub const ZERO: Self = Self(0);

    /// `us` µs after the epoch.
    pub const fn from_us(us: u64) -> Self {
        Self(us)
    }

    /// µs after the epoch.
    pub const fn as_us(self) -> u64 {
        self.0
    }

    /// Seconds after the epoch.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-6
    }
}

impl std::fmt::Display for Timestamp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.2} s", self.as_secs_f64())
    }
}

/// A device the core hears from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeviceKind {
    /// The Arduino Mega (wheels, switch, magnet).
    Mega,
    /// The YDLIDAR X4.
    Lidar,
    /// The MPU9255.
    Imu,
    /// The organisers' server.
    Referee,
}

impl std::fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Mega => "Mega",
            Self::Lidar => "lidar",
            Self::Imu => "IMU",
            Self::Referee => "server",
        })
    }
}

/// How long an [`OperatorCommand::Drive`] or [`OperatorCommand::OpenLoop`] holds, µs: a
/// driver that stops sending (a dropped joystick, a crashed script) stops the robot within
/// half a second, as ROS 2's `cmd_vel` conventions expect.
pub const MANUAL_DEADMAN_US: u64 = 500_000;

/// What an operator asks for (HMI, console, ROS 2): recorded like every other input.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum OperatorCommand {
    /// Start the round now with this part list (incoming slots 1–4; `None` = empty), with or
    /// without the server (competition practice).
    ForceStart {
        /// The parts in the incoming slots.
        parts: [Option<PartColor>; 4],
    },
    /// Stop: zero wheel references and magnet off until [`OperatorCommand::Resume`].
    Stop,
    /// Carry on after a stop, or hand the wheels back to the mission after
    /// [`OperatorCommand::Drive`].
    Resume,
    /// The operator takes the wheels: drive with `twist` (robot frame) instead of the
    /// mission, for [`MANUAL_DEADMAN_US`] after this command, then stand still until the
    /// next `Drive` or [`OperatorCommand::Resume`] (a joystick, a calibration or
    /// identification drive: each sends it again every host tick). A stop still wins;
    /// the magnet stays as the mission holds it.
    Drive {
        /// Robot-frame velocity.
        twist: BodyTwist,
    },
    /// The operator takes the wheels open loop (motor identification, `ratf tune motors`):
    /// the Mega gets this signed PWM per motor (`K` frames, motor index order; the Mega
    /// clamps the magnitude to 255) instead of speed references, for
    /// [`MANUAL_DEADMAN_US`] after this command, then zero references until the next
    /// command. Otherwise as [`OperatorCommand::Drive`]: a stop wins, the magnet stays as
    /// the mission holds it, [`OperatorCommand::Resume`] hands the wheels back.
    OpenLoop {
        /// Signed PWM per motor, motor index order (wire convention).
        pwm: [i16; 4],
    },
    /// The robot stands at this pose (world frame): restart the pose estimate there.
    SetPose {
        /// The pose.
        pose: Pose2,
    },
}

/// One input to the core.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Input {
    /// The host's 50 Hz timer: decide and command the wheels now.
    HostTick,
    /// A telemetry batch from the Mega.
    Wheels(WheelTelemetry),
    /// The Mega rebooted (its `r` frame): its tick counters restart from zero.
    MegaReset,
    /// One lidar revolution.
    Scan(Scan),
    /// One IMU reading.
    Imu(ImuSample),
    /// A datagram from the organisers' server (only from the configured address).
    Referee {
        /// The datagram's bytes.
        datagram: Vec<u8>,
    },
    /// An operator's command.
    Operator(OperatorCommand),
    /// A device failed (port gone, timeout, a health error): the core stops driving blind.
    DeviceFault {
        /// Which device.
        device: DeviceKind,
        /// What happened, as the device put it.
        message: String,
        /// The device's thread is reopening its port (an unplug, a read error): the core
        /// holds the robot still, magnet off, until the device speaks again, and the
        /// mission goes on (a USB replug, issue 17). `false` (a lidar's health error, and
        /// every fault recorded before this field existed): stopped until the operator
        /// resumes.
        #[serde(default)]
        reconnecting: bool,
    },
}

impl Input {
    /// A short name of the input's kind, for logs and divergence reports.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::HostTick => "host_tick",
            Self::Wheels(_) => "wheels",
            Self::MegaReset => "mega_reset",
            Self::Scan(_) => "scan",
            Self::Imu(_) => "imu",
            Self::Referee { .. } => "referee",
            Self::Operator(_) => "operator",
            Self::DeviceFault { .. } => "device_fault",
        }
    }
}

/// An input with the time it arrived.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stamped {
    /// When it arrived (for a datagram or telemetry: when its last byte was read).
    pub time: Timestamp,
    /// What arrived.
    pub input: Input,
}

impl Stamped {
    /// `input` at `time`.
    pub fn new(time: Timestamp, input: Input) -> Self {
        Self { time, input }
    }
}
