//! The one loop: devices → core → devices, with taps seeing everything in order.

use super::core::Core;
use super::input::{Stamped, Timestamp};
use super::output::Outputs;

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
}

/// Something that watches the loop: a recorder, a status subscriber.
pub trait Tap {
    /// `input` was consumed by the core, which returned `outputs`.
    fn on_step(&mut self, input: &Stamped, outputs: &Outputs, core: &Core);
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
        for tap in taps.iter_mut() {
            tap.on_step(&input, &outputs, core);
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
