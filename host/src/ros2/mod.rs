//! ratf in the ROS 2 ecosystem: the robot's state as ROS 2 messages, written into every
//! recording beside the raw inputs (so a file opens in Foxglove and `ros2 bag` as it is).
//!
//! - [`msgs`]: one serde definition per message type, in `.msg` field order, with the
//!   `ros2msg` text rosbag2 embeds;
//! - [`frames`]: the tf frame names and the static transforms;
//! - [`derive`](mod@derive): the topics derived from each step of the runtime;
//! - [`record`]: those topics as MCAP channels (`ros2msg` schemas, `cdr` encoding);
//! - [`live`]: `ratf run --ros2`'s options, and `bridge` (cargo feature `ros2`): the same
//!   topics live on DDS, and `cmd_vel` and `initialpose` back in as operator commands.

#[cfg(feature = "ros2")]
pub mod bridge;
pub mod derive;
pub mod frames;
pub mod live;
pub mod msgs;
pub mod record;
