//! `ratf tune motors --robot`: the PWM steps on the robot's own Mega (its port from the
//! configuration), held open loop through the Mega's thread ([`MegaHandle::hold_open_loop`],
//! `K` frames resent every host tick, as `ratf check` turns the wheels), the telemetry
//! collected as samples for the fit.
//!
//! Each hold ends 0.2 s after it was set unless renewed, so a host that dies mid-step stops
//! the wheels (and the Mega's own watchdog stops them 100 ms after the last `K`). Ctrl-C
//! stops at once: zero PWM, then the thread ends. A sample's voltage is the PWM held when
//! the Mega sampled its encoders; the host resends holds on its own 20 ms tick, so the
//! fitted delay includes up to one host tick of the host's latency.

use std::time::Duration;

use ratf_core::config::Config;
use ratf_core::identification::motor_model::Sample;
use ratf_core::runtime::Input;

use super::motors::{StepPlan, patterns};
use crate::devices::mega::{self as mega_device, MegaHandle, MegaSettings, open_port};
use crate::devices::open_loop::OpenLoopHold;
use crate::devices::{Clock, Message, Shared, inbox};

/// How long each hold lasts unless renewed, µs.
const HOLD_US: u64 = 200_000;
/// A batch arriving sooner than this after the previous one came in a burst, µs (the
/// Mega sends one every 20 ms).
const BURST_US: u64 = 5_000;
/// Largest share of batches that may come in bursts.
const MAX_BURST_SHARE: f64 = 0.02;
/// How long to wait for the Mega's first telemetry, s.
const FIRST_TELEMETRY_S: f64 = 3.0;

/// Why the steps could not be run.
#[derive(Debug, thiserror::Error)]
pub enum RobotStepsError {
    /// The port could not be opened.
    #[error(
        "mega: cannot open {port}: {error}; check [link] mega_port and the USB cable \
         (ratf check)"
    )]
    Port {
        /// The port.
        port: String,
        /// What failed.
        error: String,
    },
    /// The Mega's thread could not start.
    #[error("mega: starting its thread: {0}")]
    Thread(std::io::Error),
    /// No telemetry came.
    #[error(
        "mega: no telemetry within {FIRST_TELEMETRY_S} s on {0}: run `ratf check` (is the \
         firmware flashed, is it the right port?)"
    )]
    Silent(String),
    /// The Mega went away during the steps.
    #[error("mega: {0}")]
    Gone(String),
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
        /// All batches.
        batches: usize,
    },
    /// Ctrl-C or SIGTERM.
    #[error("stopped by Ctrl-C or SIGTERM; the wheels were stopped")]
    Interrupted,
}

/// Run `plan` on the robot's Mega; per wheel, one sample per telemetry batch, with
/// `battery_v` at PWM `[mega] pwm_max`. `interrupt` is Ctrl-C's flag.
pub fn run_on_robot(
    config: &Config,
    plan: &StepPlan,
    battery_v: f64,
    interrupt: &Shared,
) -> Result<Vec<Vec<Sample>>, RobotStepsError> {
    let settings = MegaSettings::from_config(config);
    let port = open_port(&settings.port, settings.baud).map_err(|e| RobotStepsError::Port {
        port: settings.port.clone(),
        error: e.to_string(),
    })?;
    let clock = Clock::start();
    let shared = Shared::new();
    let (tx, rx) = inbox(&shared);
    let mega = MegaHandle::new(settings.link, settings.controller);
    let thread = mega_device::spawn(
        settings.clone(),
        port,
        clock,
        tx,
        mega.clone(),
        shared.clone(),
    )
    .map_err(RobotStepsError::Thread)?;
    let result = steps(
        config,
        plan,
        battery_v,
        interrupt,
        &settings.port,
        clock,
        &rx,
        &mega,
    );
    mega.stop(clock.now());
    // Let the stop reach the Mega before the thread ends.
    std::thread::sleep(Duration::from_millis(60));
    shared.request_quit();
    let _ = thread.join();
    result
}

#[allow(clippy::too_many_arguments)]
fn steps(
    config: &Config,
    plan: &StepPlan,
    battery_v: f64,
    interrupt: &Shared,
    port: &str,
    clock: Clock,
    rx: &std::sync::mpsc::Receiver<Message>,
    mega: &MegaHandle,
) -> Result<Vec<Vec<Sample>>, RobotStepsError> {
    let patterns = patterns(config);
    let pwm_max = f64::from(config.mega.pwm_max);
    let rad_per_tick = std::f64::consts::TAU / config.robot.ticks_per_wheel_rev;
    let mut wheels = vec![Vec::new(); 4];
    // (since µs, PWM) per hold set, to find the PWM in force at a sample.
    let mut held: Vec<(u64, [i16; 4])> = Vec::new();
    let mut start_us: Option<u64> = None;
    let mut renewed_us = 0u64;
    let (mut bursts, mut last_arrival_us) = (0usize, None::<u64>);
    let asked_at = clock.now().as_us();
    loop {
        if interrupt.quitting() {
            return Err(RobotStepsError::Interrupted);
        }
        let now_us = clock.now().as_us();
        match start_us {
            None if now_us.saturating_sub(asked_at) as f64 * 1e-6 > FIRST_TELEMETRY_S => {
                return Err(RobotStepsError::Silent(port.to_owned()));
            }
            None => {}
            Some(start) => {
                let t_s = now_us.saturating_sub(start) as f64 * 1e-6;
                let Some(pwm) = plan.pwm_at(&patterns, t_s) else {
                    let batches = wheels[0].len();
                    if bursts as f64 > MAX_BURST_SHARE * batches as f64 {
                        return Err(RobotStepsError::Bursty { bursts, batches });
                    }
                    return Ok(wheels);
                };
                // A new PWM is written at once; the same one is renewed halfway through its
                // hold (the Mega's thread resends it every tick meanwhile).
                let renew = match held.last() {
                    Some(&(_, last)) if last != pwm => true,
                    Some(_) => now_us >= renewed_us + HOLD_US / 2,
                    None => true,
                };
                if renew {
                    if held.last().map(|(_, p)| *p) != Some(pwm) {
                        held.push((now_us, pwm));
                    }
                    renewed_us = now_us;
                    mega.hold_open_loop(
                        OpenLoopHold {
                            pwm,
                            solenoid_on: false,
                            until_us: now_us + HOLD_US,
                        },
                        clock.now(),
                    );
                }
            }
        }
        let message = match rx.recv_timeout(Duration::from_millis(5)) {
            Ok(message) => message,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => continue,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Err(RobotStepsError::Gone("its thread ended".to_owned()));
            }
        };
        match message {
            Message::Input(stamped) => {
                let Input::Wheels(t) = stamped.input else {
                    continue;
                };
                let arrived_us = stamped.time.as_us();
                if last_arrival_us.is_some_and(|last| arrived_us < last + BURST_US) {
                    bursts += 1;
                }
                last_arrival_us = Some(arrived_us);
                if start_us.is_none() {
                    start_us = Some(arrived_us);
                    continue;
                }
                let (Some(deltas), true) = (t.deltas_ticks, t.period_us > 0) else {
                    continue;
                };
                let pwm = held
                    .iter()
                    .rev()
                    .find(|(since, _)| *since <= t.sampled_at_us)
                    .map_or([0; 4], |(_, pwm)| *pwm);
                let period_s = f64::from(t.period_us) * 1e-6;
                for (k, wheel) in wheels.iter_mut().enumerate() {
                    wheel.push(Sample {
                        period_s,
                        voltage_v: f64::from(pwm[k]) / pwm_max * battery_v,
                        speed_rad_s: f64::from(deltas[k]) * rad_per_tick / period_s,
                    });
                }
            }
            Message::Gone { message, .. } => return Err(RobotStepsError::Gone(message)),
            Message::Link(..) => {}
        }
    }
}
