//! The replay player behind `ratf replay FILE --hmi ADDR`: the recording's inputs
//! ([`Recording`], read once by [`crate::recording`]) folded through a core with the
//! runtime's own loop up to the time the page asks for, played at a chosen speed or held.
//! Going back in time starts a fresh core from the first input (the core is a pure fold, so
//! it arrives at exactly the state it had then).

use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use ratf_core::field::geometry::Pose2;
use ratf_core::planning::tasks::TaskError;
use ratf_core::runtime::{Core, Devices, Flow, Outputs, Stamped, Timestamp, run};

use super::commands::ReplayRequest;
use super::hub::Hub;
use super::snapshot::{EventLine, ReplayView, event_kind};
use super::tap::{HmiTap, PUBLISH_PERIOD};
use crate::recording::Recording;

/// The recording's events as the page's timeline.
pub fn timeline(recording: &Recording) -> Vec<EventLine> {
    let field = recording.config.field.field();
    recording
        .outputs
        .iter()
        .flat_map(|record| {
            let t_s = recording
                .inputs
                .get(record.input as usize)
                .map_or(0.0, |input| input.time.as_secs_f64());
            let field = &field;
            record.outputs.events.iter().map(move |event| EventLine {
                t_s,
                kind: event_kind(event),
                text: event.describe(field),
            })
        })
        .collect()
}

/// The recording's length, s of robot time.
pub fn duration_s(recording: &Recording) -> f64 {
    recording
        .inputs
        .last()
        .map_or(0.0, |input| input.time.as_secs_f64())
}

/// The recorded inputs from `next` up to `until` as devices (nothing is carried out).
struct Upto<'a> {
    recording: &'a Recording,
    next: usize,
    until: Timestamp,
    now: Timestamp,
}

impl Devices for Upto<'_> {
    type Error = std::convert::Infallible;

    fn next_input(&mut self) -> Result<Option<Stamped>, Self::Error> {
        let input = self
            .recording
            .inputs
            .get(self.next)
            .filter(|input| input.time <= self.until);
        if let Some(input) = input {
            self.next += 1;
            self.now = input.time;
        }
        Ok(input.cloned())
    }

    fn apply(&mut self, _: &Stamped, _: &Outputs) -> Result<(), Self::Error> {
        Ok(())
    }

    fn ground_truth(&self) -> Option<Pose2> {
        let truth = &self.recording.truth;
        let after = truth.partition_point(|t| t.time <= self.now);
        after.checked_sub(1).map(|i| truth[i].pose)
    }
}

/// The player's state.
struct Player {
    recording: Recording,
    hub: Arc<Hub>,
    core: Core,
    tap: HmiTap,
    next: usize,
    time_us: f64,
    playing: bool,
    speed: f64,
}

impl Player {
    fn new(recording: Recording, hub: Arc<Hub>) -> Result<Self, TaskError> {
        let core = Core::new(&recording.config, recording.session.start_pose)?;
        let tap = HmiTap::new(hub.clone(), "replay", &recording.config);
        Ok(Self {
            recording,
            hub,
            core,
            tap,
            next: 0,
            time_us: 0.0,
            playing: false,
            speed: 1.0,
        })
    }

    fn end_us(&self) -> f64 {
        duration_s(&self.recording) * 1e6
    }

    /// Show the robot at `t_us`.
    fn seek(&mut self, t_us: f64) -> Result<(), TaskError> {
        let t_us = t_us.clamp(0.0, self.end_us());
        if t_us < self.time_us {
            self.core = Core::new(&self.recording.config, self.recording.session.start_pose)?;
            self.tap = HmiTap::new(self.hub.clone(), "replay", &self.recording.config);
            self.next = 0;
        }
        let mut devices = Upto {
            recording: &self.recording,
            next: self.next,
            // Whole µs, rounded: 2.985 s × 1e6 is 2 984 999.999… in binary floating point.
            until: Timestamp::from_us(t_us.round() as u64),
            now: Timestamp::ZERO,
        };
        let Ok(_) = run(
            &mut self.core,
            &mut devices,
            &mut [&mut self.tap],
            |_, _| Flow::Continue,
        );
        self.next = devices.next;
        self.time_us = t_us;
        if self.next >= self.recording.inputs.len() {
            self.playing = false;
        }
        Ok(())
    }

    fn publish(&mut self) {
        self.tap.replay = Some(ReplayView {
            duration_s: duration_s(&self.recording),
            playing: self.playing,
            speed: self.speed,
        });
        self.tap.publish(&self.core);
    }

    fn handle(&mut self, request: ReplayRequest) -> Result<(), TaskError> {
        match request {
            ReplayRequest::Seek(t_s) => self.seek(t_s * 1e6)?,
            ReplayRequest::Play => {
                if self.next >= self.recording.inputs.len() {
                    self.seek(0.0)?;
                }
                self.playing = true;
            }
            ReplayRequest::Pause => self.playing = false,
            ReplayRequest::Speed(speed) => self.speed = speed,
        }
        Ok(())
    }

    fn run(mut self, requests: Receiver<ReplayRequest>) -> Result<(), TaskError> {
        self.publish();
        let mut last = Instant::now();
        loop {
            let wait = if self.playing {
                PUBLISH_PERIOD
            } else {
                Duration::from_secs(1)
            };
            match requests.recv_timeout(wait) {
                Ok(request) => self.handle(request)?,
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return Ok(()),
            }
            let now = Instant::now();
            if self.playing {
                let step_us = (now - last).as_secs_f64() * 1e6 * self.speed;
                self.seek(self.time_us + step_us)?;
            }
            last = now;
            self.publish();
        }
    }
}

/// Play `recording` to `hub` on this thread (the core is not `Send`), taking
/// [`ReplayRequest`]s from `requests` until every sender is gone. It starts paused at time 0.
pub fn play(
    recording: Recording,
    hub: Arc<Hub>,
    requests: Receiver<ReplayRequest>,
) -> Result<(), TaskError> {
    Player::new(recording, hub)?.run(requests)
}
