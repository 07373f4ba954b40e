//! The ROS 2 topics in a recording: one MCAP channel per [`Topic`] with its `ros2msg`
//! schema and `cdr` message encoding (as rosbag2's MCAP storage writes them), fed by a
//! [`Deriver`] at every step of the runtime.

use std::collections::{BTreeMap, HashMap};
use std::io::{Seek, Write};

use ratf_core::config::Config;
use ratf_core::runtime::StepView;

use super::derive::{Deriver, Message, Topic};
use super::msgs::EncodeError;
use super::msgs::definition::full_text;

/// The ROS 2 side of a recorder: its channels and its deriver.
#[derive(Debug)]
pub struct Ros2Channels {
    channels: HashMap<Topic, u16>,
    deriver: Deriver,
    messages: Vec<Message>,
}

impl Ros2Channels {
    /// Add a schema and a channel per topic to `writer`, for a run of `config`.
    pub fn add<W: Write + Seek>(
        writer: &mut mcap::Writer<W>,
        config: &Config,
    ) -> Result<Self, mcap::McapError> {
        let mut schemas = HashMap::new();
        let mut channels = HashMap::new();
        for topic in Topic::ALL {
            let type_name = topic.type_name();
            let schema_id = match schemas.get(type_name) {
                Some(id) => *id,
                None => {
                    let text = full_text(type_name).unwrap_or_default();
                    let id = writer.add_schema(type_name, "ros2msg", text.as_bytes())?;
                    schemas.insert(type_name, id);
                    id
                }
            };
            let channel = writer.add_channel(schema_id, topic.name(), "cdr", &BTreeMap::new())?;
            channels.insert(topic, channel);
        }
        Ok(Self {
            channels,
            deriver: Deriver::new(config),
            messages: Vec::new(),
        })
    }

    /// The messages of `step`, each with its channel and its CDR bytes.
    pub fn on_step(
        &mut self,
        step: &StepView<'_>,
        mut write: impl FnMut(u16, &[u8]),
    ) -> Result<(), EncodeError> {
        self.messages.clear();
        self.deriver.on_step(step, &mut self.messages);
        for message in &self.messages {
            if let Some(channel) = self.channels.get(&message.topic()) {
                write(*channel, &message.to_cdr()?);
            }
        }
        Ok(())
    }
}
