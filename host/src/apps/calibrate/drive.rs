//! The calibration drive through the robot's own runtime: the drive's twists enter the core
//! as the operator's [`ratf_core::runtime::OperatorCommand::Drive`]
//! ([`crate::apps::operator_script`]: a recording holds them, and the same code drives the
//! simulated world and the real devices), and a tap collects what the robot saw and
//! believed at each stop.

use ratf_core::calibration::{Stop, StopRecorder};
use ratf_core::config::Config;
use ratf_core::drivers::x4::scan::Scan;
use ratf_core::field::Field;
use ratf_core::field::geometry::Pose2;
use ratf_core::runtime::{Core, Devices, Flow, Input, StepView, Tap, run};

use crate::apps::operator_script::{OperatorScript, ScriptClock, ScriptedDrive};
use crate::apps::scripts::StopWindow;

/// Time after a stop begins for the robot to come to rest, s (the legs' 0.3 s ramp and the
/// wheels' settling).
pub const SETTLE_S: f64 = 0.5;

/// One stop's scans and the robot's poses there.
#[derive(Clone, Debug, Default)]
struct StopData {
    scans: Vec<Scan>,
    /// Odometry and estimate once the robot came to rest.
    poses: Option<(Pose2, Pose2)>,
}

/// Collects, for every stop window of the drive, the scans taken wholly inside it (after the
/// settling time) and the odometry's and the localiser's poses once the robot rests.
#[derive(Debug)]
pub struct StopCollector {
    windows: Vec<StopWindow>,
    clock: ScriptClock,
    stops: Vec<StopData>,
}

impl StopCollector {
    /// A collector for `windows` (script seconds).
    pub fn new(windows: Vec<StopWindow>) -> Self {
        let stops = vec![StopData::default(); windows.len()];
        Self {
            windows,
            clock: ScriptClock::default(),
            stops,
        }
    }

    /// The stop window a scan lies wholly in (after the settling time), if any.
    fn window_of(&self, scan: &Scan) -> Option<usize> {
        let start_s = self.clock.seconds_at(scan.stamp_us)?;
        let span_s = scan.sample_period_us * f64::from(scan.samples) * 1e-6;
        self.windows
            .iter()
            .position(|w| start_s >= w.start_s + SETTLE_S && start_s + span_s <= w.end_s)
    }

    /// The stops as the fit takes them: each stop's sightings in the beliefs of `config`
    /// on `field`; a stop the drive never rested at is left out. The poles are looked for
    /// around the localiser's pose, the odometry's, and the last stop's look moved on by
    /// the odometry since (one leg of roller slip, where the odometry alone carries every
    /// leg's; see [`StopRecorder`]).
    pub fn finish(self, config: &Config, field: &Field) -> Vec<Stop> {
        let mut stops: Vec<Stop> = Vec::new();
        for stop in self.stops {
            let Some((odometry, estimate)) = stop.poses else {
                continue;
            };
            let mut looks = vec![estimate, odometry];
            if let Some(last) = stops.last() {
                looks.push(last.estimate.compose(last.odometry.relative(odometry)));
            }
            let mut recorder = StopRecorder::new(config, field);
            for scan in &stop.scans {
                recorder.add_scan(scan);
            }
            stops.push(recorder.finish(odometry, &looks));
        }
        stops
    }
}

impl Tap for StopCollector {
    fn on_step(&mut self, step: &StepView<'_>) {
        let Some(now_s) = self.clock.observe(step.input) else {
            return;
        };
        if let Input::Scan(scan) = &step.input.input
            && let Some(k) = self.window_of(scan)
        {
            self.stops[k].scans.push(scan.clone());
        }
        for (window, stop) in self.windows.iter().zip(&mut self.stops) {
            if stop.poses.is_none() && now_s >= window.start_s + SETTLE_S && now_s < window.end_s {
                let robot = step.core.robot();
                stop.poses = Some((robot.estimation().odometry_pose(), robot.pose()));
            }
        }
    }
}

/// What a calibration drive brought back.
#[derive(Debug)]
pub struct Driven<D> {
    /// The stops, as the fit takes them.
    pub stops: Vec<Stop>,
    /// The devices, handed back.
    pub devices: D,
    /// The script ran to its end (not cut short by `quit` or the devices running out).
    pub finished: bool,
}

/// Drive `script` with `core` on `devices` (every tap sees every step; the script sees the
/// core's estimate after each, [`OperatorScript::command_with`]) and collect the stops of
/// `windows`, in the beliefs of `config`; stops early when `quit` says so.
pub fn drive_and_collect<D: Devices, S: OperatorScript + ?Sized>(
    core: &mut Core,
    devices: D,
    script: &S,
    windows: Vec<StopWindow>,
    config: &Config,
    taps: &mut [&mut dyn Tap],
    mut quit: impl FnMut() -> bool,
) -> Result<Driven<D>, D::Error> {
    let mut scripted = ScriptedDrive::new(devices, script);
    let mut collector = StopCollector::new(windows);
    {
        let mut all: Vec<&mut dyn Tap> = Vec::with_capacity(taps.len() + 1);
        all.push(&mut collector);
        for tap in taps.iter_mut() {
            all.push(&mut **tap);
        }
        run(core, &mut scripted, &mut all, |core, devices| {
            devices.observe_estimate(core.robot().pose());
            if devices.finished() || quit() {
                Flow::Stop
            } else {
                Flow::Continue
            }
        })?;
    }
    let field = config.field.field();
    Ok(Driven {
        stops: collector.finish(config, &field),
        finished: scripted.finished(),
        devices: scripted.into_devices(),
    })
}
