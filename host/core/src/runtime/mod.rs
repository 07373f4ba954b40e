//! The runtime seam: the robot's software as a fold over timestamped inputs.
//!
//! [`Core::step`] takes one [`Stamped`] [`Input`] — the host's 50 Hz tick, Mega telemetry
//! and resets, lidar scans, IMU samples, datagrams from the organisers' server, operator
//! commands, device faults — and returns the [`Outputs`] for the devices: the wheel command
//! and the magnet (at a tick), at most one request to the server, the lidar's start command,
//! and what happened ([`Event`]s). [`Core::status`] is what a display shows. The core reads
//! no clock: every input carries its [`Timestamp`] (µs on the robot's monotonic clock), so a
//! recording of the inputs replays exactly.
//!
//! [`run`] is the one loop that drives a core with a set of [`Devices`] — the simulated
//! world (`ratf-sim`), the real ports, or a recording — and [`Tap`]s that see every input
//! and output in order (the recorder, status subscribers). `ratf sim`, `ratf run` and `ratf
//! replay` differ only in the devices they pass (architecture.md, "The runtime").

mod brain;
mod bringup;
mod core;
mod event;
mod input;
mod output;
mod run;
mod silence;

pub use self::brain::{Brain, Phase};
pub use self::bringup::{BiasOutcome, GYRO_BIAS_SAMPLES, GYRO_SETTLE_US, GyroBiasStartup};
pub use self::core::{Core, Status};
pub use self::event::{Event, slot_name};
pub use self::input::{DeviceKind, Input, MANUAL_DEADMAN_US, OperatorCommand, Stamped, Timestamp};
pub use self::output::{LidarCommand, Outputs, WheelCommand};
pub use self::run::{Devices, Flow, RunSummary, StepView, Tap, run};
pub use self::silence::{
    BLIND_MAGNET_HOLD_US, Hold, LIDAR_PACKET_SILENCE_US, LIDAR_SILENCE_REVOLUTIONS,
    MAGNET_OFF_AFTER_US, MEGA_SILENCE_PERIODS, MegaHeard, PacketWatch, SilenceGuard,
};
