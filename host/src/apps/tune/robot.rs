//! `ratf tune motors --robot` and `--from-recording`: the identification's PWM steps
//! through the robot's own runtime. Each step enters the core as the operator's
//! [`OperatorCommand::OpenLoop`] before every host tick ([`crate::apps::operator_script`]),
//! the core sends it to the Mega as `K` frames, the recorder writes the run, and a tap
//! ([`PwmSampler`]) turns each telemetry batch into one sample per wheel.
//!
//! Safety is the core's: an open-loop command holds for the core's deadman (0.5 s) unless
//! renewed, a stop or a device fault wins at once, and the Mega's own watchdog stops every
//! motor 100 ms after its last `K`; Ctrl-C stops the loop, and on every way out the wheels
//! get zero references and the magnet goes off. The PWM of a sample is the one the core
//! commanded at the last host tick before the Mega sampled its encoders, so the fitted
//! delay includes up to one host tick (20 ms) of the host's own latency.
//!
//! A recording of such a run holds the commands among its inputs: the core rebuilt from it
//! and re-run with the same tap gives the same samples ([`from_recording`]), and the
//! recorded configuration's `[motor] battery_voltage_v` is the battery the run was told.

use std::path::{Path, PathBuf};

use ratf_core::config::Config;
use ratf_core::identification::motor_model::Sample;
use ratf_core::planning::tasks::TaskError;
use ratf_core::runtime::{
    Core, Devices, Flow, Input, OperatorCommand, StepView, Tap, Timestamp, run,
};

use super::motors::{StepPlan, patterns};
use crate::apps::calibrate::robot::open_recorder;
use crate::apps::operator_script::{OperatorScript, ScriptedDrive};
use crate::apps::run::{RunError, open_devices};
use crate::devices::{DeviceError, Shared};
use crate::recording::{RecordedInputs, Recording, RecordingError};

/// The kind of a recording of the identification (its session's `kind`).
pub const RECORDING_KIND: &str = "tune-motors";
/// A batch arriving sooner than this after the previous one came in a burst, µs (the
/// Mega sends one every 20 ms).
const BURST_US: u64 = 5_000;
/// Largest share of batches that may come in bursts.
const MAX_BURST_SHARE: f64 = 0.02;
/// How long to wait for the Mega's first word, s.
pub const FIRST_TELEMETRY_S: f64 = 3.0;

/// Why the identification's steps could not be run or read back.
#[derive(Debug, thiserror::Error)]
pub enum TuneRobotError {
    /// A device could not be opened or the core built.
    #[error(transparent)]
    Setup(#[from] RunError),
    /// A device failed during the steps.
    #[error("during the steps: {0}")]
    Device(#[from] DeviceError),
    /// The recording could not be written or read.
    #[error("recording: {0}")]
    Recording(#[from] Box<RecordingError>),
    /// The core could not be rebuilt from a recorded configuration.
    #[error("the recorded configuration: {0}")]
    Core(#[from] TaskError),
    /// The Mega never spoke.
    #[error(
        "mega: no telemetry within {FIRST_TELEMETRY_S} s: run `ratf check` (is the firmware \
         flashed, is it the right port?)"
    )]
    Silent,
    /// Telemetry came in bursts: which PWM each sample saw cannot be told.
    #[error(
        "mega: {bursts} of {batches} telemetry batches arrived within {} ms of the previous \
         one: the host's clock cannot tell which PWM each sample saw, so the fit would be \
         wrong; run on an unloaded host with the Mega on its own USB port",
        BURST_US / 1000
    )]
    Bursty {
        /// Batches that arrived in a burst.
        bursts: usize,
        /// All batches under open-loop commands.
        batches: usize,
    },
    /// Ctrl-C or SIGTERM.
    #[error("stopped by Ctrl-C or SIGTERM; the wheels were stopped and nothing was fitted")]
    Interrupted,
    /// The recording is of another kind of run.
    #[error(
        "{}: a recording of a {kind:?} run, not of the motor identification: give the \
         recording `ratf tune motors --robot` wrote",
        .path.display()
    )]
    NotTuning {
        /// The file.
        path: PathBuf,
        /// Its session's kind.
        kind: String,
    },
}

/// The identification's PWM steps as the operator's open-loop commands.
#[derive(Clone, Debug, PartialEq)]
pub struct PwmSteps {
    plan: StepPlan,
    patterns: [[i8; 4]; 3],
}

impl PwmSteps {
    /// The steps of `plan` in the wheel patterns of `config`'s kinematics.
    pub fn new(config: &Config, plan: &StepPlan) -> Self {
        Self {
            plan: plan.clone(),
            patterns: patterns(config),
        }
    }
}

impl OperatorScript for PwmSteps {
    fn command_at(&self, seconds: f64) -> OperatorCommand {
        OperatorCommand::OpenLoop {
            pwm: self.plan.pwm_at(&self.patterns, seconds).unwrap_or([0; 4]),
        }
    }

    fn duration_s(&self) -> f64 {
        self.plan.duration_s()
    }
}

/// A tap that turns each telemetry batch under an open-loop command into one sample per
/// wheel: the speed from the batch's encoder deltas, the voltage from the PWM the core
/// commanded last before the batch was sampled, at the configuration's battery voltage.
#[derive(Clone, Debug)]
pub struct PwmSampler {
    volts_per_pwm: f64,
    rad_per_tick: f64,
    /// (since, PWM) at every change of the core's open-loop command (`None`: closed loop).
    commanded: Vec<(Timestamp, Option<[i16; 4]>)>,
    wheels: Vec<Vec<Sample>>,
    batches: usize,
    bursts: usize,
    last_arrival: Option<Timestamp>,
}

impl PwmSampler {
    /// A sampler in the beliefs of `config` (`[mega] pwm_max`, `[motor]
    /// battery_voltage_v`, `robot.ticks_per_wheel_rev`).
    pub fn new(config: &Config) -> Self {
        Self {
            volts_per_pwm: config.motor.battery_voltage_v / f64::from(config.mega.pwm_max),
            rad_per_tick: std::f64::consts::TAU / config.robot.ticks_per_wheel_rev,
            commanded: Vec::new(),
            wheels: vec![Vec::new(); 4],
            batches: 0,
            bursts: 0,
            last_arrival: None,
        }
    }

    /// Per wheel, the samples; refused when the telemetry came in bursts.
    pub fn finish(self) -> Result<Vec<Vec<Sample>>, TuneRobotError> {
        if self.bursts as f64 > MAX_BURST_SHARE * self.batches as f64 {
            return Err(TuneRobotError::Bursty {
                bursts: self.bursts,
                batches: self.batches,
            });
        }
        Ok(self.wheels)
    }

    fn pwm_at(&self, time: Timestamp) -> Option<[i16; 4]> {
        self.commanded
            .iter()
            .rev()
            .find(|(since, _)| *since <= time)
            .and_then(|(_, pwm)| *pwm)
    }
}

impl Tap for PwmSampler {
    fn on_step(&mut self, step: &StepView<'_>) {
        match &step.input.input {
            Input::HostTick => {
                let Some(wheels) = step.outputs.wheels else {
                    return;
                };
                let pwm = wheels.open_loop_pwm;
                if self.commanded.last().map(|(_, last)| *last) != Some(pwm) {
                    self.commanded.push((step.input.time, pwm));
                }
            }
            Input::Wheels(t) => {
                let sampled = Timestamp::from_us(t.sampled_at_us);
                let (Some(pwm), Some(deltas), true) =
                    (self.pwm_at(sampled), t.deltas_ticks, t.period_us > 0)
                else {
                    return;
                };
                let arrived = step.input.time;
                if self
                    .last_arrival
                    .is_some_and(|last| arrived.as_us() < last.as_us() + BURST_US)
                {
                    self.bursts += 1;
                }
                self.last_arrival = Some(arrived);
                self.batches += 1;
                let period_s = f64::from(t.period_us) * 1e-6;
                for (k, wheel) in self.wheels.iter_mut().enumerate() {
                    wheel.push(Sample {
                        period_s,
                        voltage_v: f64::from(pwm[k]) * self.volts_per_pwm,
                        speed_rad_s: f64::from(deltas[k]) * self.rad_per_tick / period_s,
                    });
                }
            }
            _ => {}
        }
    }
}

/// What the steps brought back.
#[derive(Debug)]
pub struct Stepped {
    /// The sampler, to finish.
    pub sampler: PwmSampler,
    /// The steps ran to their end (not cut short by `quit`, the Mega's silence or the
    /// devices running out).
    pub finished: bool,
    /// The Mega never spoke within [`FIRST_TELEMETRY_S`] of the first input.
    pub silent: bool,
}

/// Run the steps of `plan` with `core` on `devices` (every tap sees every step), sampled in
/// the beliefs of `config`; stops early when `quit` says so or the Mega never speaks.
pub fn run_steps<D: Devices>(
    core: &mut Core,
    devices: D,
    plan: &StepPlan,
    config: &Config,
    taps: &mut [&mut dyn Tap],
    mut quit: impl FnMut() -> bool,
) -> Result<Stepped, D::Error> {
    let steps = PwmSteps::new(config, plan);
    let mut scripted = ScriptedDrive::new(devices, &steps);
    let mut sampler = PwmSampler::new(config);
    let mut first: Option<Timestamp> = None;
    let mut silent = false;
    {
        let mut all: Vec<&mut dyn Tap> = Vec::with_capacity(taps.len() + 1);
        all.push(&mut sampler);
        for tap in taps.iter_mut() {
            all.push(&mut **tap);
        }
        run(core, &mut scripted, &mut all, |core, devices| {
            let status = core.status();
            let since = first.get_or_insert(status.time).as_us();
            let heard = status.inputs.mega_resets + status.inputs.wheel_batches > 0;
            silent = !heard
                && status.time.as_us().saturating_sub(since) as f64 * 1e-6 > FIRST_TELEMETRY_S;
            if silent || devices.finished() || quit() {
                Flow::Stop
            } else {
                Flow::Continue
            }
        })?;
    }
    Ok(Stepped {
        finished: scripted.finished(),
        silent,
        sampler,
    })
}

/// The samples of an identification on the robot, and its recording.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotSteps {
    /// Per wheel, one sample per telemetry batch under the steps.
    pub wheels: Vec<Vec<Sample>>,
    /// The recording of the run.
    pub recording: PathBuf,
}

/// Run `plan` on the robot's devices (`config`'s ports, as `ratf run` opens them: the core
/// holds the wheels while the lidar is silent), the samples' voltages at `battery_v` (a
/// multimeter's reading), recorded to `recording`. `shared` carries the quit flag (wire the
/// signals to it first) and the panic flag; on every way out the wheels get zero
/// references and the magnet goes off.
pub fn run_on_robot(
    config: &Config,
    plan: &StepPlan,
    battery_v: f64,
    recording: &Path,
    shared: &Shared,
) -> Result<RobotSteps, TuneRobotError> {
    let mut config = config.clone();
    config.motor.battery_voltage_v = battery_v;
    let start = config.field.field().start_pose();
    let mut core = Core::new(&config, start).map_err(RunError::from)?;
    let mut recorder =
        open_recorder(&config, start, RECORDING_KIND, recording).map_err(Box::new)?;
    let opened = open_devices(&config, shared, Vec::new())?;
    let stepped = run_steps(
        &mut core,
        opened.devices,
        plan,
        &config,
        &mut [&mut recorder],
        || shared.quitting(),
    );
    opened.running.close(shared);
    let recording = recorder.finish().map_err(Box::new)?;
    let stepped = stepped?;
    if stepped.silent {
        return Err(TuneRobotError::Silent);
    }
    if !stepped.finished {
        return Err(TuneRobotError::Interrupted);
    }
    Ok(RobotSteps {
        wheels: stepped.sampler.finish()?,
        recording,
    })
}

/// The samples from the recording at `path` of an identification (by [`run_on_robot`]):
/// the core rebuilt from the recorded configuration and re-run over the recorded inputs
/// (the steps' commands among them) with the same sampler; the voltages at the recorded
/// `[motor] battery_voltage_v`. A recording of another kind of run is refused; one cut
/// short (Ctrl-C, a kill) gives the samples up to its end, and the fit says whether they
/// suffice.
pub fn from_recording(path: &Path) -> Result<Vec<Vec<Sample>>, TuneRobotError> {
    let recording = Recording::read(path).map_err(Box::new)?;
    if recording.session.kind != RECORDING_KIND {
        return Err(TuneRobotError::NotTuning {
            path: path.to_owned(),
            kind: recording.session.kind,
        });
    }
    let config = &recording.config;
    let mut core = Core::new(config, recording.session.start_pose)?;
    let mut sampler = PwmSampler::new(config);
    let Ok(_) = run(
        &mut core,
        &mut RecordedInputs::of(&recording),
        &mut [&mut sampler],
        |_, _| Flow::Continue,
    );
    sampler.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::apps::tune::motors::{assert_recovers_within_5_percent, true_models};
    use crate::recording::Recorder;
    use ratf_core::config::WorldProfile;
    use ratf_sim::devices::SimDevices;
    use ratf_sim::world::Scenario;

    #[test]
    fn steps_through_the_runtime_identify_the_simulated_motors_and_their_recording_fits_the_same() {
        let mut world_config = Config::default();
        world_config.sim.world = WorldProfile::Realistic;
        world_config.sim.seed = 7;
        let devices = SimDevices::new(&world_config, &Scenario::new(&world_config)).unwrap();
        let truth = devices.world().truth().clone();
        // The team measured the battery with a multimeter.
        let mut config = world_config.clone();
        config.motor.battery_voltage_v = truth.battery_voltage_v;
        let start = config.field.field().start_pose();
        let path =
            std::env::temp_dir().join(format!("ratf-tune-runtime-{}.mcap", std::process::id()));
        let mut recorder = open_recorder(&config, start, RECORDING_KIND, &path).unwrap();
        let mut core = Core::new(&config, start).unwrap();
        let plan = StepPlan::default();
        let stepped = run_steps(
            &mut core,
            devices,
            &plan,
            &config,
            &mut [&mut recorder as &mut dyn Tap],
            || false,
        )
        .unwrap();
        assert!(stepped.finished && !stepped.silent);
        let path = Recorder::finish(recorder).unwrap();
        let wheels = stepped.sampler.finish().unwrap();
        // Every step is sampled: 50 batches a second over the plan (its rests included).
        let expected = (plan.duration_s() * 50.0) as usize;
        assert!(
            wheels.iter().all(|w| w.len().abs_diff(expected) <= 5),
            "{} samples, expected about {expected}",
            wheels[0].len()
        );
        assert_recovers_within_5_percent(&wheels, &true_models(&world_config, &truth));
        assert_eq!(from_recording(&path).unwrap(), wheels);
        let _ = std::fs::remove_file(&path);
    }

    #[test]
    fn a_recording_of_another_kind_of_run_is_refused() {
        let config = Config::default();
        let start = config.field.field().start_pose();
        let path =
            std::env::temp_dir().join(format!("ratf-tune-not-tuning-{}.mcap", std::process::id()));
        let recorder = open_recorder(&config, start, "round", &path).unwrap();
        recorder.finish().unwrap();
        let error = from_recording(&path).unwrap_err();
        assert!(
            matches!(&error, TuneRobotError::NotTuning { kind, .. } if kind == "round"),
            "{error}"
        );
        let _ = std::fs::remove_file(&path);
    }
}
