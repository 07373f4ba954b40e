//! Recordings of the runtime: every input the core consumed, in order, every output it
//! produced, its status at each host tick, and in the simulator the world's truth on its
//! own topic (never read by the core), in an MCAP file (zstd-compressed chunks, JSON
//! messages) that `ratf replay`, Foxglove and the `mcap` Python package can read.
//!
//! Topics, each message JSON (`message_encoding = "json"`), `log_time` the robot's clock in ns:
//!
//! | topic | message | when |
//! |---|---|---|
//! | `/ratf/session` | [`Session`]: the configuration (TOML), the start pose, the kind of run | first |
//! | `/ratf/input` | a [`Stamped`] input (`{"time": µs, "input": {"type": …}}`) | every input, in the order consumed |
//! | `/ratf/output` | [`OutputRecord`]: the input's index and its non-empty [`Outputs`] | when an input produced any |
//! | `/ratf/status` | the core's [`Status`](ratf_core::runtime::Status) | after every host tick |
//! | `/sim/truth` | [`TruthRecord`]: the true pose | after every host tick, in the simulator |
//!
//! Beside them, the same run as ROS 2 messages (`ros2msg` schemas, `cdr` encoding) for
//! Foxglove and `ros2 bag`: see [`crate::ros2::derive`] for the topics.
//!
//! A run killed half-way leaves a file readable up to its last complete chunk; chunks are
//! [`CHUNK_BYTES`] of messages, a fraction of a second of a round, so little is lost.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use ratf_core::config::Config;
use ratf_core::field::geometry::Pose2;
use ratf_core::runtime::{Devices, Input, Outputs, Stamped, StepView, Tap, Timestamp};

use crate::ros2::msgs::EncodeError;
use crate::ros2::record::Ros2Channels;

/// Uncompressed bytes of messages per MCAP chunk: 64 KiB, a fraction of a second of a round
/// (mcap's default, 1 MiB, would leave the last few seconds before a crash unreadable).
pub const CHUNK_BYTES: u64 = 64 * 1024;

/// Topic of the session record.
pub const SESSION_TOPIC: &str = "/ratf/session";
/// Topic of the inputs.
pub const INPUT_TOPIC: &str = "/ratf/input";
/// Topic of the outputs.
pub const OUTPUT_TOPIC: &str = "/ratf/output";
/// Topic of the status.
pub const STATUS_TOPIC: &str = "/ratf/status";
/// Topic of the simulator's ground truth.
pub const TRUTH_TOPIC: &str = "/sim/truth";

/// What a recording needs to rebuild the core: its configuration and where it believed it
/// started.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Session {
    /// `sim` or `robot`.
    pub kind: String,
    /// The configuration, as TOML (every key).
    pub config_toml: String,
    /// The pose the core believed at start, world frame.
    pub start_pose: Pose2,
    /// The `ratf` version that wrote the file.
    pub version: String,
}

/// The outputs of the input with index `input` (0-based, in `/ratf/input` order).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutputRecord {
    /// Index of the input.
    pub input: u64,
    /// What it produced.
    pub outputs: Outputs,
}

/// The simulator's true pose at a host tick.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TruthRecord {
    /// When.
    pub time: Timestamp,
    /// The true pose, world frame.
    pub pose: Pose2,
}

/// The pose part of a recorded status (what replay compares).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
pub struct StatusPose {
    /// When.
    pub time: Timestamp,
    /// The pose estimate.
    pub pose: Pose2,
}

/// Why a recording could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be created, read or written.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The MCAP layer failed.
    #[error("{}: MCAP: {source}", .path.display())]
    Mcap {
        /// The file.
        path: PathBuf,
        /// mcap's error.
        #[source]
        source: mcap::McapError,
    },
    /// A message did not decode.
    #[error("{}: message {index} on {topic}: {source}", .path.display())]
    Decode {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// The message's index on its topic.
        index: u64,
        /// serde_json's error.
        #[source]
        source: serde_json::Error,
    },
    /// The file has no session record (not a ratf recording).
    #[error("{}: no {SESSION_TOPIC} record: not a ratf recording", .path.display())]
    NoSession {
        /// The file.
        path: PathBuf,
    },
    /// A ROS 2 message could not be encoded.
    #[error("{}: {source}", .path.display())]
    Ros2 {
        /// The file.
        path: PathBuf,
        /// The encoder's error.
        #[source]
        source: EncodeError,
    },
    /// The session's configuration is not valid.
    #[error("{}: the recorded configuration: {source}", .path.display())]
    Config {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: Box<ratf_core::config::ConfigError>,
    },
}

/// Writes a recording; a [`Tap`] of the runtime.
pub struct Recorder {
    path: PathBuf,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    channels: Channels,
    ros2: Option<Ros2Channels>,
    inputs: u64,
    sequence: u32,
    error: Option<RecordingError>,
}

#[derive(Clone, Copy, Debug)]
struct Channels {
    input: u16,
    output: u16,
    status: u16,
    truth: u16,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("path", &self.path)
            .field("inputs", &self.inputs)
            .finish()
    }
}

impl Recorder {
    /// Create `path` and write the session record.
    pub fn create(path: &Path, session: &Session) -> Result<Self, RecordingError> {
        let mcap_error = |source| RecordingError::Mcap {
            path: path.to_owned(),
            source,
        };
        let config = Config::from_toml_str(&session.config_toml).map_err(|source| {
            RecordingError::Config {
                path: path.to_owned(),
                source: Box::new(source),
            }
        })?;
        let file = File::create(path).map_err(|source| RecordingError::Io {
            path: path.to_owned(),
            source,
        })?;
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(CHUNK_BYTES))
            .profile("")
            .library(format!("ratf {}", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))
            .map_err(mcap_error)?;
        let mut channel = |topic: &str, schema: &str| -> Result<u16, RecordingError> {
            let schema_id = writer
                .add_schema(schema, "jsonschema", br#"{"type":"object"}"#)
                .map_err(mcap_error)?;
            writer
                .add_channel(schema_id, topic, "json", &BTreeMap::new())
                .map_err(mcap_error)
        };
        let session_channel = channel(SESSION_TOPIC, "ratf.Session")?;
        let channels = Channels {
            input: channel(INPUT_TOPIC, "ratf.Input")?,
            output: channel(OUTPUT_TOPIC, "ratf.Outputs")?,
            status: channel(STATUS_TOPIC, "ratf.Status")?,
            truth: channel(TRUTH_TOPIC, "ratf.Truth")?,
        };
        let ros2 = Ros2Channels::add(&mut writer, &config).map_err(mcap_error)?;
        let mut recorder = Self {
            path: path.to_owned(),
            writer: Some(writer),
            channels,
            ros2: Some(ros2),
            inputs: 0,
            sequence: 0,
            error: None,
        };
        recorder.write(session_channel, Timestamp::ZERO, session);
        match recorder.error.take() {
            Some(e) => Err(e),
            None => Ok(recorder),
        }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Record the simulator's true pose at `time` (on its own topic).
    pub fn write_truth(&mut self, time: Timestamp, pose: Pose2) {
        self.write(self.channels.truth, time, &TruthRecord { time, pose });
    }

    fn write(&mut self, channel_id: u16, time: Timestamp, message: &impl Serialize) {
        if self.error.is_some() {
            return;
        }
        let data = match serde_json::to_vec(message) {
            Ok(data) => data,
            Err(source) => {
                self.error = Some(RecordingError::Io {
                    path: self.path.clone(),
                    source: source.into(),
                });
                return;
            }
        };
        self.write_bytes(channel_id, time, &data);
    }

    fn write_bytes(&mut self, channel_id: u16, time: Timestamp, data: &[u8]) {
        if self.error.is_some() {
            return;
        }
        let Some(writer) = self.writer.as_mut() else {
            return;
        };
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: time.as_us().saturating_mul(1_000),
            publish_time: time.as_us().saturating_mul(1_000),
        };
        self.sequence = self.sequence.wrapping_add(1);
        if let Err(source) = writer.write_to_known_channel(&header, data) {
            self.error = Some(RecordingError::Mcap {
                path: self.path.clone(),
                source,
            });
        }
    }

    /// Close the file (summary and footer); the first error met while recording, if any.
    pub fn finish(mut self) -> Result<PathBuf, RecordingError> {
        if let Some(mut writer) = self.writer.take()
            && let Err(source) = writer.finish()
        {
            self.error.get_or_insert(RecordingError::Mcap {
                path: self.path.clone(),
                source,
            });
        }
        match self.error.take() {
            Some(e) => Err(e),
            None => Ok(self.path.clone()),
        }
    }
}

impl Tap for Recorder {
    fn on_step(&mut self, step: &StepView<'_>) {
        let StepView {
            input,
            outputs,
            core,
            ground_truth,
        } = *step;
        self.write(self.channels.input, input.time, input);
        if !outputs.is_empty() {
            let record = OutputRecord {
                input: self.inputs,
                outputs: outputs.clone(),
            };
            self.write(self.channels.output, input.time, &record);
        }
        if input.input == Input::HostTick {
            self.write(self.channels.status, input.time, &core.status());
            if let Some(pose) = ground_truth {
                self.write_truth(input.time, pose);
            }
        }
        if let Some(mut ros2) = self.ros2.take() {
            let written = ros2.on_step(step, |channel, data| {
                self.write_bytes(channel, input.time, data)
            });
            if let Err(source) = written {
                self.error.get_or_insert(RecordingError::Ros2 {
                    path: self.path.clone(),
                    source,
                });
            }
            self.ros2 = Some(ros2);
        }
        self.inputs += 1;
    }
}

/// A recording read back.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// The session: configuration and start pose.
    pub session: Session,
    /// The configuration, parsed and validated.
    pub config: Config,
    /// Every input, in the order the core consumed it.
    pub inputs: Vec<Stamped>,
    /// The non-empty outputs, by input index, in order.
    pub outputs: Vec<OutputRecord>,
    /// The core's pose at each host tick.
    pub poses: Vec<StatusPose>,
    /// The simulator's truth at each host tick (empty for a real run).
    pub truth: Vec<TruthRecord>,
    /// True when the file ended early (a crash or kill): everything up to the last
    /// complete chunk was read.
    pub truncated: bool,
}

/// A recording's inputs as devices, in the order the core consumed them; outputs go nowhere.
/// A core rebuilt from the recorded configuration and start pose and run over them with a
/// collecting tap sees what the recorded run's core saw (the core is a pure fold): how
/// `ratf calibrate odometry` and `ratf tune motors` fit again from a recording.
#[derive(Debug)]
pub struct RecordedInputs<'a>(std::slice::Iter<'a, Stamped>);

impl<'a> RecordedInputs<'a> {
    /// The inputs of `recording`.
    pub fn of(recording: &'a Recording) -> Self {
        Self(recording.inputs.iter())
    }
}

impl Devices for RecordedInputs<'_> {
    type Error = std::convert::Infallible;

    fn next_input(&mut self) -> Result<Option<Stamped>, Self::Error> {
        Ok(self.0.next().cloned())
    }

    fn apply(&mut self, _: &Stamped, _: &Outputs) -> Result<(), Self::Error> {
        Ok(())
    }
}

impl Recording {
    /// Read `path`.
    pub fn read(path: &Path) -> Result<Self, RecordingError> {
        let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_bytes(path, &bytes)
    }

    /// Parse the bytes of a recording (`path` names it in errors).
    pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Self, RecordingError> {
        let mut session: Option<Session> = None;
        let mut inputs = Vec::new();
        let mut outputs = Vec::new();
        let mut poses = Vec::new();
        let mut truth = Vec::new();
        let end = crate::mcap_read::for_each_message(bytes, |topic, sequence, data| {
            let decode_error = |source| RecordingError::Decode {
                path: path.to_owned(),
                topic: topic.to_owned(),
                index: u64::from(sequence),
                source,
            };
            match topic {
                SESSION_TOPIC => {
                    session = Some(serde_json::from_slice(data).map_err(decode_error)?)
                }
                INPUT_TOPIC => inputs.push(serde_json::from_slice(data).map_err(decode_error)?),
                OUTPUT_TOPIC => outputs.push(serde_json::from_slice(data).map_err(decode_error)?),
                STATUS_TOPIC => poses.push(serde_json::from_slice(data).map_err(decode_error)?),
                TRUTH_TOPIC => truth.push(serde_json::from_slice(data).map_err(decode_error)?),
                _ => {}
            }
            Ok(())
        })?;
        let truncated = end == crate::mcap_read::End::Truncated;
        if truncated {
            // Its outputs may have been in the chunk that was lost.
            inputs.pop();
        }
        let session = session.ok_or_else(|| RecordingError::NoSession {
            path: path.to_owned(),
        })?;
        let config = Config::from_toml_str(&session.config_toml).map_err(|source| {
            RecordingError::Config {
                path: path.to_owned(),
                source: Box::new(source),
            }
        })?;
        Ok(Self {
            session,
            config,
            inputs,
            outputs,
            poses,
            truth,
            truncated,
        })
    }
}
