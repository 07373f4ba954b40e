//! Scripted operator commands through the robot's own runtime: a script (a calibration
//! drive's twists, an identification's PWM steps) enters the core as the operator's
//! commands before every host tick, so a recording holds them and the same code drives the
//! simulated world and the real devices.

use ratf_core::field::geometry::Pose2;
use ratf_core::runtime::{Devices, Input, OperatorCommand, Outputs, Stamped, Timestamp};

/// What a script commands over time.
pub trait OperatorScript {
    /// The command at `seconds` since the script started.
    fn command_at(&self, seconds: f64) -> OperatorCommand;
    /// The command at `seconds` for a robot the core estimates at `estimate` (its last
    /// step's pose, `None` before any): a script that closes its loop on the estimate
    /// overrides this; by default, the open-loop command.
    fn command_with(&self, seconds: f64, estimate: Option<Pose2>) -> OperatorCommand {
        let _ = estimate;
        self.command_at(seconds)
    }
    /// When the script ends, s.
    fn duration_s(&self) -> f64;
}

/// A script's own clock: it starts at the first host tick after the Mega has spoken (the
/// core drives nothing before), so the script runs the same on a board that took a second
/// to boot as in the simulator.
#[derive(Clone, Copy, Debug, Default)]
pub struct ScriptClock {
    mega_heard: bool,
    start: Option<Timestamp>,
}

impl ScriptClock {
    /// Follow `input`; the script's time at it, s, once started.
    pub fn observe(&mut self, input: &Stamped) -> Option<f64> {
        match input.input {
            Input::Wheels(_) | Input::MegaReset => self.mega_heard = true,
            Input::HostTick if self.mega_heard && self.start.is_none() => {
                self.start = Some(input.time);
            }
            _ => {}
        }
        self.seconds_at(input.time.as_us() as f64)
    }

    /// The script's time at `time_us` on the robot's clock, s, once started.
    pub fn seconds_at(&self, time_us: f64) -> Option<f64> {
        self.start
            .map(|start| (time_us - start.as_us() as f64) * 1e-6)
    }
}

/// `devices` with the script's command sent to the core before every host tick.
#[derive(Debug)]
pub struct ScriptedDrive<'a, D, S: ?Sized> {
    devices: D,
    script: &'a S,
    clock: ScriptClock,
    held_tick: Option<Stamped>,
    finished: bool,
    estimate: Option<Pose2>,
}

impl<'a, D: Devices, S: OperatorScript + ?Sized> ScriptedDrive<'a, D, S> {
    /// Run `script` on `devices`.
    pub fn new(devices: D, script: &'a S) -> Self {
        Self {
            devices,
            script,
            clock: ScriptClock::default(),
            held_tick: None,
            finished: false,
            estimate: None,
        }
    }

    /// The core's pose estimate after its last step, for a script that closes its loop on
    /// it ([`OperatorScript::command_with`]).
    pub fn observe_estimate(&mut self, estimate: Pose2) {
        self.estimate = Some(estimate);
    }

    /// The script has run to its end.
    pub fn finished(&self) -> bool {
        self.finished
    }

    /// The devices, handed back.
    pub fn into_devices(self) -> D {
        self.devices
    }
}

impl<D: Devices, S: OperatorScript + ?Sized> Devices for ScriptedDrive<'_, D, S> {
    type Error = D::Error;

    fn next_input(&mut self) -> Result<Option<Stamped>, D::Error> {
        if let Some(tick) = self.held_tick.take() {
            return Ok(Some(tick));
        }
        let Some(input) = self.devices.next_input()? else {
            return Ok(None);
        };
        match self.clock.observe(&input) {
            Some(seconds) if matches!(input.input, Input::HostTick) => {
                self.finished = seconds > self.script.duration_s();
                let command = Stamped::new(
                    input.time,
                    Input::Operator(self.script.command_with(seconds, self.estimate)),
                );
                self.held_tick = Some(input);
                Ok(Some(command))
            }
            _ => Ok(Some(input)),
        }
    }

    fn apply(&mut self, input: &Stamped, outputs: &Outputs) -> Result<(), D::Error> {
        self.devices.apply(input, outputs)
    }

    fn ground_truth(&self) -> Option<Pose2> {
        self.devices.ground_truth()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::apps::scripts::calibration_drive;
    use std::collections::VecDeque;

    /// Inputs from a list; outputs ignored.
    struct Listed(VecDeque<Stamped>);

    impl Devices for Listed {
        type Error = std::convert::Infallible;

        fn next_input(&mut self) -> Result<Option<Stamped>, Self::Error> {
            Ok(self.0.pop_front())
        }

        fn apply(&mut self, _: &Stamped, _: &Outputs) -> Result<(), Self::Error> {
            Ok(())
        }
    }

    fn at(ms: u64, input: Input) -> Stamped {
        Stamped::new(Timestamp::from_us(ms * 1_000), input)
    }

    #[test]
    fn the_script_drives_before_every_tick_once_the_mega_has_spoken() {
        let (script, _) = calibration_drive();
        let inputs = [
            at(0, Input::HostTick),
            at(10, Input::MegaReset),
            at(20, Input::HostTick),
            at(40, Input::HostTick),
        ];
        let mut scripted = ScriptedDrive::new(Listed(inputs.into_iter().collect()), &script);
        let mut seen = Vec::new();
        while let Some(input) = scripted.next_input().unwrap() {
            seen.push(match input.input {
                Input::HostTick => "tick",
                Input::MegaReset => "reset",
                Input::Operator(OperatorCommand::Drive { .. }) => "drive",
                _ => "other",
            });
        }
        assert_eq!(seen, ["tick", "reset", "drive", "tick", "drive", "tick"]);
        assert!(!scripted.finished());
    }
}
