//! Replay: re-run the core over a recording's inputs, in the recorded order, and compare.
//!
//! With the recorded configuration, every output must come out identical (the core is a
//! pure fold): the first difference is reported with its time, its input and what
//! differs. With another configuration, the same inputs are fed open-loop (the world does
//! not react to the new decisions), and the report says how far the pose estimate moved and
//! where the decisions first changed.

use serde::Serialize;

use crate::recording::{OutputRecord, Recording};
use ratf_core::config::Config;
use ratf_core::field::Field;
use ratf_core::planning::tasks::TaskError;
use ratf_core::runtime::{Core, Devices, Event, Flow, Input, Outputs, Stamped, Timestamp, run};

/// Where a replay first differed from the recording.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Divergence {
    /// The input's time.
    pub time: Timestamp,
    /// The input's index (0-based, in consumption order).
    pub input: u64,
    /// The input's kind (`host_tick`, `scan`, …).
    pub input_kind: String,
    /// What differs: `wheels`, `referee`, `lidar` or `events`.
    pub output: String,
    /// The recorded value (JSON).
    pub recorded: serde_json::Value,
    /// The replayed value (JSON).
    pub replayed: serde_json::Value,
}

/// What a replay found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReplayReport {
    /// Inputs re-run.
    pub inputs: u64,
    /// Inputs whose outputs differed from the recorded ones.
    pub divergences: u64,
    /// The first of them.
    pub first_divergence: Option<Divergence>,
    /// Largest distance between the recorded and the replayed pose estimate at a host tick,
    /// m.
    pub max_pose_difference_m: f64,
    /// RMS of that distance over the host ticks, m.
    pub rms_pose_difference_m: f64,
    /// Events in the recording.
    pub recorded_events: usize,
    /// Events in the replay.
    pub replayed_events: usize,
    /// Robot time covered, s.
    pub robot_time_s: f64,
    /// The recording ended early (crash or kill).
    pub truncated: bool,
}

/// The recording as devices: its inputs in order; outputs compared with the recorded ones.
struct RecordingDevices<'a> {
    inputs: std::slice::Iter<'a, Stamped>,
    recorded: std::iter::Peekable<std::slice::Iter<'a, OutputRecord>>,
    index: u64,
    divergences: u64,
    first: Option<Divergence>,
    recorded_events: Vec<Event>,
    replayed_events: Vec<Event>,
}

fn json(value: &impl Serialize) -> serde_json::Value {
    serde_json::to_value(value).unwrap_or(serde_json::Value::Null)
}

/// The first part of `replayed` that differs from `recorded`, with both values.
fn difference(
    recorded: &Outputs,
    replayed: &Outputs,
) -> Option<(String, serde_json::Value, serde_json::Value)> {
    if recorded.wheels != replayed.wheels {
        return Some((
            "wheels".into(),
            json(&recorded.wheels),
            json(&replayed.wheels),
        ));
    }
    if recorded.referee != replayed.referee {
        return Some((
            "referee".into(),
            json(&recorded.referee),
            json(&replayed.referee),
        ));
    }
    if recorded.lidar != replayed.lidar {
        return Some(("lidar".into(), json(&recorded.lidar), json(&replayed.lidar)));
    }
    if recorded.events != replayed.events {
        return Some((
            "events".into(),
            json(&recorded.events),
            json(&replayed.events),
        ));
    }
    None
}

impl Devices for RecordingDevices<'_> {
    type Error = std::convert::Infallible;

    fn next_input(&mut self) -> Result<Option<Stamped>, Self::Error> {
        Ok(self.inputs.next().cloned())
    }

    fn apply(&mut self, input: &Stamped, outputs: &Outputs) -> Result<(), Self::Error> {
        let empty = Outputs::default();
        let recorded = match self.recorded.peek() {
            Some(record) if record.input == self.index => {
                self.recorded.next().map_or(&empty, |r| &r.outputs)
            }
            _ => &empty,
        };
        self.recorded_events.extend(recorded.events.iter().cloned());
        self.replayed_events.extend(outputs.events.iter().cloned());
        if let Some((output, recorded, replayed)) = difference(recorded, outputs) {
            self.divergences += 1;
            self.first.get_or_insert(Divergence {
                time: input.time,
                input: self.index,
                input_kind: input.input.kind().to_owned(),
                output,
                recorded,
                replayed,
            });
        }
        self.index += 1;
        Ok(())
    }
}

/// Re-run `recording` with `config` (its own when `None`); `on_event` hears the replayed
/// events with their time.
pub fn replay(
    recording: &Recording,
    config: Option<&Config>,
    mut on_event: impl FnMut(Timestamp, &Event),
) -> Result<ReplayReport, TaskError> {
    let config = config.unwrap_or(&recording.config);
    let mut core = Core::new(config, recording.session.start_pose)?;
    let mut devices = RecordingDevices {
        inputs: recording.inputs.iter(),
        recorded: recording.outputs.iter().peekable(),
        index: 0,
        divergences: 0,
        first: None,
        recorded_events: Vec::new(),
        replayed_events: Vec::new(),
    };
    let mut recorded_poses = recording.poses.iter();
    let (mut max_d, mut sum_sq, mut ticks) = (0.0f64, 0.0, 0u64);
    let mut last_time = Timestamp::ZERO;
    let mut events_seen = 0;
    let summary = run(&mut core, &mut devices, &mut [], |core, devices| {
        for event in &devices.replayed_events[events_seen..] {
            on_event(core.status().time, event);
        }
        events_seen = devices.replayed_events.len();
        let status = core.status();
        last_time = status.time;
        // After each host tick the recording holds the pose the core had then.
        let ticked = devices
            .index
            .checked_sub(1)
            .and_then(|i| recording.inputs.get(i as usize))
            .is_some_and(|input| input.input == Input::HostTick);
        if ticked && let Some(recorded) = recorded_poses.next() {
            let d = recorded.pose.position().distance(status.pose.position());
            max_d = max_d.max(d);
            sum_sq += d * d;
            ticks += 1;
        }
        Flow::Continue
    });
    let Ok(summary) = summary;
    Ok(ReplayReport {
        inputs: summary.inputs,
        divergences: devices.divergences,
        first_divergence: devices.first,
        max_pose_difference_m: max_d,
        rms_pose_difference_m: (sum_sq / ticks.max(1) as f64).sqrt(),
        recorded_events: devices.recorded_events.len(),
        replayed_events: devices.replayed_events.len(),
        robot_time_s: last_time.as_secs_f64(),
        truncated: recording.truncated,
    })
}

/// The events of a recording as a team reads them, with their time.
pub fn recorded_events(recording: &Recording) -> Vec<(Timestamp, String)> {
    let field = &Field::competition();
    recording
        .outputs
        .iter()
        .flat_map(|record| {
            let time = recording
                .inputs
                .get(record.input as usize)
                .map_or(Timestamp::ZERO, |input| input.time);
            record
                .outputs
                .events
                .iter()
                .map(move |event| (time, event.describe(field)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::apps::round::{RoundOptions, run_recorded};
    use ratf_core::config::Policy;

    /// A recorded round 1 at seed 1 (the shortest), in a fresh directory.
    fn recorded_round(name: &str) -> (std::path::PathBuf, crate::apps::round::RoundReport) {
        let dir = std::env::temp_dir().join(format!("ratf-replay-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("round1.mcap");
        let options = RoundOptions::new(1, 1, Policy::Ours);
        let report = run_recorded(&Config::default(), &options, &path, |_| {}).unwrap();
        (path, report)
    }

    #[test]
    fn a_recorded_simulated_round_replays_bit_identically() {
        let (path, report) = recorded_round("identical");
        assert_eq!(report.points, 4, "{report:?}");
        let recording = Recording::read(&path).unwrap();
        assert!(!recording.truncated);
        assert_eq!(recording.inputs.len() as u64, report.inputs);
        assert!(
            !recording.truth.is_empty(),
            "the world's truth is on its topic"
        );
        let mut finished = false;
        let replayed = replay(&recording, None, |_, event| {
            finished |= *event == Event::Finished;
        })
        .unwrap();
        assert_eq!(replayed.inputs, report.inputs);
        assert_eq!(replayed.divergences, 0, "{:?}", replayed.first_divergence);
        assert_eq!(replayed.max_pose_difference_m, 0.0);
        assert_eq!(replayed.recorded_events, replayed.replayed_events);
        assert!(finished, "the replayed core finishes the round too");
    }

    #[test]
    fn a_round_whose_robot_believes_other_than_its_world_replays_from_the_robot_s_beliefs() {
        let dir = std::env::temp_dir().join(format!("ratf-replay-beliefs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("round1.mcap");
        let world = Config::default();
        // What `ratf sim --calibrated` does: the robot's beliefs differ from the world's.
        let mut robot = world.clone();
        robot.lidar.range_scale = 1.003;
        let options = RoundOptions::new(1, 1, Policy::Ours);
        let report = crate::apps::round::run_recorded_live(
            &world,
            &robot,
            &options,
            &path,
            &mut [],
            crate::apps::round::Live::default(),
            |_| {},
        )
        .unwrap();
        let recording = Recording::read(&path).unwrap();
        assert_eq!(recording.config.lidar.range_scale, 1.003);
        let replayed = replay(&recording, None, |_, _| {}).unwrap();
        assert_eq!(replayed.inputs, report.inputs);
        assert_eq!(replayed.divergences, 0, "{:?}", replayed.first_divergence);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_changed_input_is_reported_as_the_first_divergence() {
        let (path, _) = recorded_round("changed");
        let mut recording = Recording::read(&path).unwrap();
        // Shift one telemetry batch mid-round by a few encoder ticks: the odometry, and so
        // the next wheel command, must change, and the replay must say where.
        let index = recording
            .inputs
            .iter()
            .enumerate()
            .filter(|(_, s)| matches!(s.input, Input::Wheels(_)))
            .nth(1000)
            .map(|(i, _)| i)
            .unwrap();
        if let Input::Wheels(telemetry) = &mut recording.inputs[index].input {
            telemetry.totals[0] += 50;
        }
        let replayed = replay(&recording, None, |_, _| {}).unwrap();
        let first = replayed.first_divergence.expect("no divergence found");
        assert!(first.input > index as u64, "{first:?}");
        assert_eq!(first.input_kind, "host_tick");
        assert_eq!(first.output, "wheels");
        assert!(replayed.divergences > 0);
    }

    #[test]
    fn a_recording_cut_short_is_read_up_to_its_last_complete_chunk() {
        let (path, report) = recorded_round("cut");
        let bytes = std::fs::read(&path).unwrap();
        let cut = &bytes[..bytes.len() / 2];
        let recording = Recording::from_bytes(&path, cut).unwrap();
        assert!(recording.truncated);
        assert!(
            !recording.inputs.is_empty() && (recording.inputs.len() as u64) < report.inputs,
            "{} of {} inputs",
            recording.inputs.len(),
            report.inputs
        );
        // What was read replays without divergence.
        let replayed = replay(&recording, None, |_, _| {}).unwrap();
        assert_eq!(replayed.divergences, 0, "{:?}", replayed.first_divergence);
    }

    #[test]
    fn a_recording_cut_anywhere_reads_as_a_prefix_or_an_error_never_a_panic() {
        let (path, report) = recorded_round("cut-anywhere");
        let bytes = std::fs::read(&path).unwrap();
        let whole = Recording::read(&path).unwrap();
        assert_eq!(whole.inputs.len() as u64, report.inputs);
        // 200 cuts spread over the file, plus the first and last few bytes.
        let step = (bytes.len() / 200).max(1);
        let cuts = (0..bytes.len())
            .step_by(step)
            .chain(1..64)
            .chain(bytes.len() - 64..bytes.len());
        let mut read_some = 0;
        let mut previous = (0, 0);
        for cut in cuts {
            match Recording::from_bytes(&path, &bytes[..cut]) {
                Ok(recording) => {
                    let n = recording.inputs.len();
                    // Cut in the summary after the data: everything is there.
                    assert!(
                        recording.truncated || n == whole.inputs.len(),
                        "cut at {cut}"
                    );
                    assert_eq!(recording.inputs[..], whole.inputs[..n], "cut at {cut}");
                    assert_eq!(recording.session, whole.session);
                    if cut > previous.0 {
                        assert!(n >= previous.1, "cut at {cut}: {n} < {} inputs", previous.1);
                        previous = (cut, n);
                    }
                    read_some += 1;
                }
                // Before the session's chunk is complete there is nothing to read.
                Err(e) => assert!(e.to_string().contains(&path.display().to_string()), "{e}"),
            }
        }
        assert!(read_some > 150, "only {read_some} cuts were readable");
    }
}
