//! The one loop: devices → core → devices, with taps seeing everything in order.

use super::core::Core;
use super::input::{Stamped, Timestamp};
use super::output::Outputs;
use crate::field::geometry::Pose2;

/// A set of devices: where the core's inputs come from and where its outputs go. The
/// simulated world, the real ports and a recording each implement it.
pub trait Devices {
    /// Why a device set stops working.
    type Error;

    /// The next input, in the order the core must consume it (on the robot: the order of
    /// arrival); `None` when there is nothing more (a recording's end, a world stopped).
    fn next_input(&mut self) -> Result<Option<Stamped>, Self::Error>;

    /// Carry out what the core asked after `input`.
    fn apply(&mut self, input: &Stamped, outputs: &Outputs) -> Result<(), Self::Error>;

    /// The robot's true pose now, when the devices know it (the simulator does; real ports
    /// and recordings do not). For taps only: the core never sees it.
    fn ground_truth(&self) -> Option<Pose2> {
        None
    }
}

/// One step of the loop as a tap sees it.
#[derive(Clone, Copy, Debug)]
pub struct StepView<'a> {
    /// The input the core consumed.
    pub input: &'a Stamped,
    /// What it returned.
    pub outputs: &'a Outputs,
    /// The core after the step.
    pub core: &'a Core,
    /// The true pose, in the simulator.
    pub ground_truth: Option<Pose2>,
}

/// Something that watches the loop: a recorder, a status subscriber.
pub trait Tap {
    /// The core consumed an input.
    fn on_step(&mut self, step: &StepView<'_>);
}

/// Whether the loop goes on after a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    /// Next input.
    Continue,
    /// Stop now.
    Stop,
}

/// What a run did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunSummary {
    /// Inputs consumed.
    pub inputs: u64,
    /// The time of the last one.
    pub last_time: Timestamp,
}

/// Drive `core` with `devices` until they run out or `watch` (called after every step with
/// the core and the devices) says stop; every tap sees every step, in order.
pub fn run<D: Devices>(
    core: &mut Core,
    devices: &mut D,
    taps: &mut [&mut dyn Tap],
    mut watch: impl FnMut(&Core, &mut D) -> Flow,
) -> Result<RunSummary, D::Error> {
    let mut summary = RunSummary::default();
    while let Some(input) = devices.next_input()? {
        let outputs = core.step(&input);
        let view = StepView {
            input: &input,
            outputs: &outputs,
            core,
            ground_truth: devices.ground_truth(),
        };
        for tap in taps.iter_mut() {
            tap.on_step(&view);
        }
        devices.apply(&input, &outputs)?;
        summary.inputs += 1;
        summary.last_time = input.time;
        if watch(core, devices) == Flow::Stop {
            break;
        }
    }
    Ok(summary)
}
