//! `ratf check`: the wiring check a team runs first (issue 13, item 3).
//!
//! 1. **What each device sees**, for `--observe-s` seconds from its first datum (the wheels
//!    free: every motor at PWM 0): the Mega's telemetry rate, integrity errors both ways,
//!    resets, encoder ticks, the switch ([`mega`]); the lidar's rotation rate, points per
//!    scan and the beacons found where the configuration puts them ([`lidar`]); the IMU's
//!    `WHO_AM_I` and gyro bias ([`imu`]); whether the server answers, and from where
//!    ([`server`]). A device missing is reported as `ratf run` reports it (which, where it
//!    looked, what key to set) and the check carries on with the others.
//! 2. **By hand** (interactive only): each wheel turned forward by hand, the switch
//!    pressed; the encoder counts say which encoder counted, which way ([`wheels`]).
//! 3. **Guided bring-up**: after "wheels off the ground?" (`--yes` answers it), each motor
//!    in turn at `--pwm-percent` open loop for `--spin-s` ([`OpenLoopHold`](crate::devices::open_loop::OpenLoopHold), resent every
//!    host tick so the Mega's 100 ms watchdog does not cut it), its direction judged from
//!    the encoder counts; then the magnet on for half a second and off.
//! 4. **A summary**, one line per device ([`report`]).
//!
//! Every way out (the end, Ctrl-C, a panic) ends the hold and sends zero references and
//! magnet off ([`session::StopGuard`]). The device threads have their own quit flag, so the
//! Mega's port is still open when Ctrl-C's stop is written.

mod bringup;
pub mod imu;
pub mod lidar;
pub mod mega;
mod observe;
pub mod operator;
pub mod report;
pub mod server;
pub mod session;
pub mod wheels;

use std::thread::JoinHandle;
use std::time::Duration;

use ratf_core::config::{Config, ImuDevice};
use ratf_core::drivers::imu::Chip;
use serde_json::json;

use self::lidar::BeaconSearch;
use self::operator::Operator;
use self::report::{CheckReport, DeviceReport};
use self::session::{Session, StopGuard};
use super::run::port_problem;
use crate::devices::lidar::{self as lidar_device, LidarHandle, LidarSettings};
use crate::devices::mega::{self as mega_device, MegaHandle, MegaSettings, open_port};
use crate::devices::{Clock, Shared, imu as imu_device};

/// After a wheel's spin, how long its coasting is still counted.
const SETTLE: Duration = Duration::from_millis(400);
/// How long the magnet is held on.
const MAGNET_ON: Duration = Duration::from_millis(500);
/// A moving hold ends this long after it should have been replaced, if the check stalls.
const HOLD_MARGIN_US: u64 = 200_000;

/// How the check runs.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckOptions {
    /// How long each device is watched from its first datum, s.
    pub observe_s: f64,
    /// The robot stands at the start pose among the beacons (else the beacons are not
    /// judged).
    pub on_field: bool,
    /// Open-loop PWM of the bring-up, percent of `[mega] pwm_max`.
    pub pwm_percent: f64,
    /// How long each motor turns, s.
    pub spin_s: f64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        Self {
            observe_s: 2.0,
            on_field: true,
            pwm_percent: 20.0,
            spin_s: 1.0,
        }
    }
}

impl CheckOptions {
    /// Every option within its range, or which flag is not and what it takes.
    pub fn validate(&self) -> Result<(), String> {
        let within = |flag: &str, value: f64, lo: f64, hi: f64| {
            if (lo..=hi).contains(&value) {
                Ok(())
            } else {
                Err(format!("{flag} {value}: expected {lo} to {hi}"))
            }
        };
        within("--observe-s", self.observe_s, 0.5, 60.0)?;
        within("--pwm-percent", self.pwm_percent, 1.0, 100.0)?;
        within("--spin-s", self.spin_s, 0.1, 10.0)
    }
}

/// `value` within `lo..=hi`, or `lo` when it is not a number.
fn bounded(value: f64, lo: f64, hi: f64) -> f64 {
    if value.is_nan() {
        lo
    } else {
        value.clamp(lo, hi)
    }
}

/// What was opened.
struct Opened {
    mega: Result<(), String>,
    lidar: Result<(), String>,
    imu: Option<Result<Chip, String>>,
    threads: Vec<JoinHandle<()>>,
}

/// Open every device the configuration names and start its thread (on `devices`' quit
/// flag); a device that cannot be opened is noted with what to do.
fn open(
    config: &Config,
    clock: Clock,
    tx: &crate::devices::DeviceSender,
    mega: &MegaHandle,
    lidar: &LidarHandle,
    devices: &Shared,
) -> Opened {
    let mut threads = Vec::new();
    let mut started = |spawned: std::io::Result<JoinHandle<()>>, what: &str| match spawned {
        Ok(thread) => {
            threads.push(thread);
            Ok(())
        }
        Err(e) => Err(format!("{what}: starting its thread: {e}")),
    };
    let settings = MegaSettings::from_config(config);
    let mega_opened = match open_port(&settings.port, settings.baud) {
        Ok(port) => started(
            mega_device::spawn(
                settings.clone(),
                port,
                clock,
                tx.clone(),
                mega.clone(),
                devices.clone(),
            ),
            "mega",
        ),
        Err(e) => Err(port_problem("mega", "mega_port", &settings.port, &e)),
    };
    let settings = LidarSettings::from_config(config);
    let lidar_opened = match open_port(&settings.port, settings.baud) {
        Ok(port) => started(
            lidar_device::spawn(
                settings.clone(),
                port,
                clock,
                tx.clone(),
                lidar.clone(),
                devices.clone(),
            ),
            "lidar",
        ),
        Err(e) => Err(port_problem("lidar", "lidar_port", &settings.port, &e)),
    };
    if lidar_opened.is_ok() {
        lidar.start_scan();
    }
    let imu = match config.link.imu {
        ImuDevice::None => None,
        ImuDevice::Mpu9255 => {
            let bus = &config.robot.imu.i2c_device;
            Some(match imu_device::open_i2c_chip(bus, &config.robot.imu) {
                Ok((chip, source)) => {
                    let yaw_rad = config.robot.imu.yaw_deg.to_radians();
                    started(
                        imu_device::spawn(source, yaw_rad, clock, tx.clone(), devices.clone()),
                        "imu",
                    )
                    .map(|()| chip)
                }
                Err(e) => Err(format!(
                    "imu: {e}; enable I2C and check the wiring, set [robot.imu] i2c_device, or \
                     set [link] imu = \"none\" to run without it"
                )),
            })
        }
    };
    Opened {
        mega: mega_opened,
        lidar: lidar_opened,
        imu,
        threads,
    }
}

/// Run the check: see the module documentation. `interrupt` is the flag Ctrl-C and
/// SIGTERM set; `operator` is the person at the robot (or nobody, with `--yes`).
pub fn run_check(
    config: &Config,
    options: &CheckOptions,
    interrupt: &Shared,
    operator: &mut dyn Operator,
) -> CheckReport {
    let clock = Clock::start();
    let devices = Shared::new();
    let (tx, rx) = crate::devices::inbox(&devices);
    let mega = {
        let settings = MegaSettings::from_config(config);
        MegaHandle::new(settings.link, settings.controller)
    };
    let lidar = LidarHandle::new();
    let opened = open(config, clock, &tx, &mega, &lidar, &devices);
    drop(tx);
    let guard = StopGuard {
        mega: mega.clone(),
        lidar: lidar.clone(),
        clock,
    };
    let referee = config.referee.clone();
    let probe_interrupt = interrupt.clone();
    let prober = std::thread::Builder::new()
        .name("check-server".to_owned())
        .spawn(move || server::probe(&referee, || probe_interrupt.quitting()));
    let search = BeaconSearch::new(config, config.field.field().start_pose());
    let mut check = Check {
        config,
        options,
        session: Session::new(clock, rx, interrupt, search, mega, lidar.clone()),
        operator,
        opened: &opened,
        devices: Vec::new(),
    };
    let finished = check.run(prober);
    let report = CheckReport {
        devices: std::mem::take(&mut check.devices),
        interrupted: finished.is_none() || interrupt.quitting(),
    };
    drop(check);
    // Stop the robot first, then end the threads.
    drop(guard);
    devices.request_quit();
    for thread in opened.threads {
        let _ = thread.join();
    }
    report
}

/// The check's state between its steps.
struct Check<'a, 'b> {
    config: &'a Config,
    options: &'a CheckOptions,
    session: Session<'a>,
    operator: &'b mut dyn Operator,
    opened: &'a Opened,
    devices: Vec<DeviceReport>,
}

type Prober = std::io::Result<JoinHandle<Result<server::Probe, String>>>;

impl Check<'_, '_> {
    /// Every step; `None` when interrupted.
    fn run(&mut self, prober: Prober) -> Option<()> {
        let telemetry = self.observe()?;
        self.devices.push(match prober.map(JoinHandle::join) {
            Ok(Ok(Ok(probe))) => match server::judge(&probe) {
                Ok(seen) => DeviceReport::checked("server", seen, Vec::new(), json!(probe)),
                Err(problem) => {
                    DeviceReport::checked("server", String::new(), vec![problem], json!(probe))
                }
            },
            Ok(Ok(Err(problem))) => DeviceReport::missing("server", format!("server: {problem}")),
            Ok(Err(_)) | Err(_) => {
                DeviceReport::missing("server", "server: the probe's thread failed".to_owned())
            }
        });
        if !telemetry {
            let why = "no telemetry from the Mega".to_owned();
            for step in ["encoders", "switch", "wheels", "magnet"] {
                self.devices.push(DeviceReport::skipped(step, why.clone()));
            }
            return Some(());
        }
        self.by_hand()?;
        self.bring_up()?;
        self.magnet()
    }

    fn say(&mut self, line: &str) {
        self.operator.say(line);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_out_of_range_name_their_flag() {
        assert!(CheckOptions::default().validate().is_ok());
        let nan = CheckOptions {
            observe_s: f64::NAN,
            ..CheckOptions::default()
        };
        assert_eq!(
            nan.validate().unwrap_err(),
            "--observe-s NaN: expected 0.5 to 60"
        );
        let fast = CheckOptions {
            pwm_percent: 250.0,
            ..CheckOptions::default()
        };
        assert!(
            fast.validate()
                .unwrap_err()
                .starts_with("--pwm-percent 250")
        );
        assert_eq!(bounded(f64::NAN, 0.1, 10.0), 0.1);
        assert_eq!(bounded(f64::INFINITY, 0.1, 10.0), 10.0);
    }
}
