//! The first step: every device watched with the wheels free, and its report.

use std::time::{Duration, Instant};

use serde_json::json;

use super::report::DeviceReport;
use super::{Check, bounded, lidar};
use crate::devices::open_loop::OpenLoopHold;

impl Check<'_, '_> {
    /// Watch every device with the wheels free; push their reports. `Some(true)` when the
    /// Mega sent telemetry.
    pub(super) fn observe(&mut self) -> Option<bool> {
        let config = self.config;
        let observe = Duration::from_secs_f64(bounded(self.options.observe_s, 0.5, 60.0));
        let mega_open = self.opened.mega.is_ok();
        let lidar_open = self.opened.lidar.is_ok();
        let imu_open = matches!(self.opened.imu, Some(Ok(_)));
        let mut startup = Duration::ZERO;
        if mega_open {
            startup = startup.max(Duration::from_millis(
                config.link.mega_sync_timeout_ms.into(),
            ));
        }
        if lidar_open {
            startup = startup.max(Duration::from_millis(
                config.link.lidar_spinup_timeout_ms.into(),
            ));
        }
        self.say(&format!(
            "ratf check: watching the devices for {:.1} s each (the robot must stand still; \
             the motors are free)",
            observe.as_secs_f64()
        ));
        self.session.hold(OpenLoopHold::COAST);
        let started = Instant::now();
        let observe_us = observe.as_micros() as u64;
        loop {
            if !self.session.pump(Duration::from_millis(20)) {
                return None;
            }
            let now_us = self.session.now_us();
            let done = |open: bool, first: Option<u64>| {
                !open || first.is_some_and(|f| now_us >= f + observe_us)
            };
            let s = &self.session;
            let all = done(mega_open, s.mega_window.first_us())
                && done(lidar_open, s.lidar_window.first_us())
                && done(imu_open, s.imu_window.first_us());
            if all || started.elapsed() >= startup + observe {
                break;
            }
        }
        let window_s = started.elapsed().as_secs_f64();
        let telemetry = self.session.mega_window.batches() > 0;
        let mega = match &self.opened.mega {
            Err(problem) => DeviceReport::missing("mega", problem.clone()),
            Ok(()) => {
                let end = self.session.mega.link_stats();
                let summary = self
                    .session
                    .mega_window
                    .summary((self.session.mega_stats_start, end), window_s);
                let expected_hz = 1e6 / f64::from(config.mega.control_period_us.max(1));
                let problems = summary.problems(expected_hz, &config.link.mega_port);
                DeviceReport::checked("mega", summary.describe(), problems, json!(summary))
            }
        };
        let lidar = match &self.opened.lidar {
            Err(problem) => DeviceReport::missing("lidar", problem.clone()),
            Ok(()) => {
                let mut summary = self.session.lidar_window.summary(window_s);
                summary.identity = lidar::identity_text(self.session.lidar.identity().as_ref());
                let on_field = self.options.on_field;
                let problems = summary.problems(config, &config.link.lidar_port, on_field);
                DeviceReport::checked(
                    "lidar",
                    summary.describe(on_field),
                    problems,
                    json!(summary),
                )
            }
        };
        let imu = match &self.opened.imu {
            None => DeviceReport::skipped("imu", "[link] imu = \"none\"".to_owned()),
            Some(Err(problem)) => DeviceReport::missing("imu", problem.clone()),
            Some(Ok(chip)) => {
                let summary = self.session.imu_window.summary(*chip, window_s);
                let problems = summary.problems(&config.robot.imu.i2c_device);
                DeviceReport::checked("imu", summary.describe(), problems, json!(summary))
            }
        };
        for report in [mega, lidar, imu] {
            let line = report.line();
            self.say(&line);
            self.devices.push(report);
        }
        Some(telemetry)
    }
}
