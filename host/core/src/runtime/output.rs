//! What the core asks of the devices after an input.

use serde::{Deserialize, Serialize};

use super::event::Event;
use crate::drivers::mega_link::{EncodeError, MegaLink};
use crate::referee::protocol::Request;

/// The wheel references and the magnet, sent to the Mega at every host tick.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WheelCommand {
    /// Wheel speed references, wheel rad/s, motor index order (wire convention).
    pub wheel_speeds_rad_s: [f32; 4],
    /// Electromagnet level.
    pub solenoid_on: bool,
    /// The Mega stops the wheels itself when its switch closes (`U`, on the last stretch of
    /// a docking approach to a part: [`crate::mission::MissionOutput::stop_on_switch`]).
    #[serde(skip_serializing_if = "std::ops::Not::not", default)]
    pub stop_on_switch: bool,
    /// The factor the commanded twist was scaled by to respect the wheel limit (1 = none).
    pub twist_scale: f64,
    /// Open-loop PWM per motor instead of the references (the operator's
    /// [`super::OperatorCommand::OpenLoop`]): the Mega gets `K` frames, its PI is bypassed.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub open_loop_pwm: Option<[i16; 4]>,
}

impl WheelCommand {
    /// Wheels at zero, magnet off: what a stop sends.
    pub const STOP: Self = Self {
        wheel_speeds_rad_s: [0.0; 4],
        solenoid_on: false,
        stop_on_switch: false,
        twist_scale: 1.0,
        open_loop_pwm: None,
    };

    /// True when the command moves a wheel or holds the magnet on.
    pub fn drives(&self) -> bool {
        self.solenoid_on
            || self.wheel_speeds_rad_s.iter().any(|w| *w != 0.0)
            || self
                .open_loop_pwm
                .is_some_and(|pwm| pwm.iter().any(|p| *p != 0))
    }

    /// The Mega's batch for this command on `link`: `K` frames for an open-loop command,
    /// else the speed references (`G`–`J`), with the magnet (`L`) either way.
    pub fn encode(&self, link: &mut MegaLink) -> Result<Vec<u8>, EncodeError> {
        match self.open_loop_pwm {
            Some(pwm) => Ok(link.encode_pwm(pwm, self.solenoid_on)),
            None => link.encode_references(
                self.wheel_speeds_rad_s,
                self.solenoid_on,
                self.stop_on_switch,
            ),
        }
    }
}

/// A command for the lidar (bring-up through the seam: the X4 streams only once told).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LidarCommand {
    /// Start scanning (`A5 60`).
    StartScan,
}

/// Everything one input produced.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Outputs {
    /// The wheel command, at a host tick.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub wheels: Option<WheelCommand>,
    /// A request to send to the organisers' server now (first try or a retry).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub referee: Option<Request>,
    /// A command for the lidar.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub lidar: Option<LidarCommand>,
    /// What happened.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub events: Vec<Event>,
}

impl Outputs {
    /// True when there is nothing for the devices or the taps.
    pub fn is_empty(&self) -> bool {
        self.wheels.is_none()
            && self.referee.is_none()
            && self.lidar.is_none()
            && self.events.is_empty()
    }
}
