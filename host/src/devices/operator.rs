//! Operator commands from outside the loop (the web HMI, the ROS 2 bridge, a console)
//! joined into any device set's inputs, so the core consumes them like every other input
//! and the recording keeps them.
//!
//! [`operator_channel`] gives a cloneable [`OperatorSender`] for the threads that serve the
//! operator and an [`OperatorReceiver`]; [`WithOperator`] wraps a [`Devices`] (the simulated
//! world, the real ports) and hands pending commands to the loop before the next device
//! input, stamped with the time of the last input the loop consumed, so time never runs
//! backwards. A command therefore waits at most one device input: on the robot the 50 Hz
//! host tick bounds that to 20 ms.

use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};

use ratf_core::field::geometry::Pose2;
use ratf_core::runtime::{Devices, Input, OperatorCommand, Outputs, Stamped, Timestamp};

/// Commands that may wait for the loop at once. An operator clicks or a ROS node publishes
/// at tens per second; the loop takes one per device input (thousands per second), so the
/// queue fills only when the loop has stopped, and then senders hear so at once instead of
/// memory growing.
pub const OPERATOR_QUEUE_CAPACITY: usize = 64;

/// Why a command did not reach the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum OperatorSendError {
    /// [`OPERATOR_QUEUE_CAPACITY`] commands are already waiting: the loop is not taking them.
    #[error("the robot's loop is not taking commands ({OPERATOR_QUEUE_CAPACITY} waiting)")]
    Busy,
    /// The loop has ended.
    #[error("the run has ended")]
    Ended,
}

/// The sending side, for the threads that serve an operator; clone it for each.
#[derive(Clone, Debug)]
pub struct OperatorSender {
    tx: SyncSender<OperatorCommand>,
}

impl OperatorSender {
    /// Queue `command` for the loop without blocking.
    pub fn send(&self, command: OperatorCommand) -> Result<(), OperatorSendError> {
        self.tx.try_send(command).map_err(|error| match error {
            TrySendError::Full(_) => OperatorSendError::Busy,
            TrySendError::Disconnected(_) => OperatorSendError::Ended,
        })
    }
}

/// The loop's side: give it to [`WithOperator::new`].
#[derive(Debug)]
pub struct OperatorReceiver {
    rx: Receiver<OperatorCommand>,
}

/// A bounded channel for operator commands (see [`OPERATOR_QUEUE_CAPACITY`]).
pub fn operator_channel() -> (OperatorSender, OperatorReceiver) {
    let (tx, rx) = sync_channel(OPERATOR_QUEUE_CAPACITY);
    (OperatorSender { tx }, OperatorReceiver { rx })
}

/// `devices` with the operator's commands joined in (module documentation).
#[derive(Debug)]
pub struct WithOperator<D> {
    devices: D,
    commands: OperatorReceiver,
    last_time: Timestamp,
}

impl<D> WithOperator<D> {
    /// Join `commands` into `devices`' inputs.
    pub fn new(devices: D, commands: OperatorReceiver) -> Self {
        Self {
            devices,
            commands,
            last_time: Timestamp::ZERO,
        }
    }

    /// The wrapped devices.
    pub fn inner(&self) -> &D {
        &self.devices
    }

    /// The wrapped devices, mutably (a watch closure's access to the world).
    pub fn inner_mut(&mut self) -> &mut D {
        &mut self.devices
    }

    /// The wrapped devices back.
    pub fn into_inner(self) -> D {
        self.devices
    }
}

impl<D: Devices> Devices for WithOperator<D> {
    type Error = D::Error;

    fn next_input(&mut self) -> Result<Option<Stamped>, D::Error> {
        if let Ok(command) = self.commands.rx.try_recv() {
            return Ok(Some(Stamped::new(self.last_time, Input::Operator(command))));
        }
        let input = self.devices.next_input()?;
        if let Some(input) = &input {
            self.last_time = self.last_time.max(input.time);
        }
        Ok(input)
    }

    fn apply(&mut self, input: &Stamped, outputs: &Outputs) -> Result<(), D::Error> {
        // Commands are the operator's: the devices never asked for them and have nothing to
        // carry out for them beyond the core's outputs, which they still get.
        self.devices.apply(input, outputs)
    }

    fn ground_truth(&self) -> Option<Pose2> {
        self.devices.ground_truth()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::VecDeque;

    /// Three host ticks at 20 ms steps, recording what the loop applied.
    struct Ticks {
        left: VecDeque<Stamped>,
        applied: Vec<Stamped>,
    }

    impl Devices for Ticks {
        type Error = std::convert::Infallible;

        fn next_input(&mut self) -> Result<Option<Stamped>, Self::Error> {
            Ok(self.left.pop_front())
        }

        fn apply(&mut self, input: &Stamped, _: &Outputs) -> Result<(), Self::Error> {
            self.applied.push(input.clone());
            Ok(())
        }
    }

    fn ticks() -> Ticks {
        Ticks {
            left: (1..=3)
                .map(|i| Stamped::new(Timestamp::from_us(i * 20_000), Input::HostTick))
                .collect(),
            applied: Vec::new(),
        }
    }

    #[test]
    fn a_command_comes_before_the_next_device_input_stamped_with_the_last_time() {
        let (sender, receiver) = operator_channel();
        let mut devices = WithOperator::new(ticks(), receiver);
        let first = devices.next_input().unwrap().unwrap();
        assert_eq!(first.time, Timestamp::from_us(20_000));
        sender.send(OperatorCommand::Stop).unwrap();
        let command = devices.next_input().unwrap().unwrap();
        assert_eq!(command.time, Timestamp::from_us(20_000));
        assert_eq!(command.input, Input::Operator(OperatorCommand::Stop));
        devices
            .apply(&command, &Outputs::default())
            .expect("infallible");
        let next = devices.next_input().unwrap().unwrap();
        assert_eq!(next.input, Input::HostTick);
        assert_eq!(next.time, Timestamp::from_us(40_000));
        assert_eq!(devices.inner().applied, vec![command]);
    }

    #[test]
    fn a_full_queue_and_an_ended_loop_are_told_to_the_sender() {
        let (sender, receiver) = operator_channel();
        for _ in 0..OPERATOR_QUEUE_CAPACITY {
            sender.send(OperatorCommand::Resume).unwrap();
        }
        assert_eq!(
            sender.send(OperatorCommand::Resume),
            Err(OperatorSendError::Busy)
        );
        drop(WithOperator::new(ticks(), receiver));
        assert_eq!(
            sender.send(OperatorCommand::Resume),
            Err(OperatorSendError::Ended)
        );
    }

    #[test]
    fn without_commands_the_devices_inputs_pass_unchanged() {
        let (_sender, receiver) = operator_channel();
        let mut devices = WithOperator::new(ticks(), receiver);
        let times: Vec<u64> = std::iter::from_fn(|| devices.next_input().unwrap())
            .map(|input| input.time.as_us())
            .collect();
        assert_eq!(times, [20_000, 40_000, 60_000]);
    }
}
