//! A simulated round with faults (issue 17): the world's and devices' faults through
//! [`FaultInjector`], the server's answers lost, delayed, doubled or garbled as the plan
//! says, and a watch on the core's outputs after a fault that must stop the robot.
//!
//! **Unsafe event**: a host tick whose wheel command is non-zero, or whose magnet is on,
//! later than [`STOP_WITHIN_US`] after the robot *could* know of the fault. A lidar that
//! stops and one between two packets look the same until a packet is late, and a Mega that
//! is gone looks like one between two batches until a batch is late, so the watch starts
//! after the silence limits ([`ratf_core::runtime::LIDAR_PACKET_SILENCE_US`] of the lidar
//! device's packet watch, [`ratf_core::runtime::MEGA_SILENCE_PERIODS`] control periods of
//! the core's) and the 150 ms count from there. The time from the fault itself to the
//! robot's last driving command is reported too ([`FaultOutcome::stop_after_fault_us`]);
//! issue 17 asks for it within 150 ms as well, which the limits leave room for.

use std::collections::VecDeque;

use ratf_core::config::Config;
use ratf_core::runtime::{LIDAR_PACKET_SILENCE_US, MEGA_SILENCE_PERIODS, Outputs};
use ratf_sim::devices::SimDevices;
use ratf_sim::faults::{FaultInjector, FaultKind, FaultPlan, ServerFault, garbage_datagram};
use ratf_sim::lidar::Solid;

/// After a fault that must stop the robot the round ends this much later, µs (2 s: long
/// enough to see it stay stopped).
pub const AFTER_STOP_FAULT_US: u64 = 2_000_000;

/// The target: motors at zero and magnet off this soon after the fault is knowable, µs
/// (issue 17).
pub const STOP_WITHIN_US: u64 = 150_000;

/// What the faults did in one round.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultOutcome {
    /// Events planned.
    pub planned: usize,
    /// Events that really happened (a slip needs a carried part, a knock a standing one).
    pub injected: usize,
    /// Host ticks that drove after the stop deadline (see the module documentation).
    pub unsafe_ticks: u32,
    /// From the first fault that must stop the robot to its last driving command, µs
    /// (`Some(0)`: it was not driving then).
    pub stop_after_fault_us: Option<u64>,
    /// Server answers lost, delayed, doubled or garbled.
    pub answers_touched: u32,
}

/// The faults of one round.
#[derive(Debug)]
pub struct RoundFaults {
    injector: FaultInjector,
    late: VecDeque<(u64, Vec<u8>)>,
    /// (fault start, deadline) of the first fault that must stop the robot.
    stop: Option<(u64, u64)>,
    last_drive_us: Option<u64>,
    unsafe_ticks: u32,
    answers_touched: u32,
}

impl RoundFaults {
    /// `plan` in a world standing `clutter`, watched with the silence limits of the robot's
    /// `config`.
    pub fn new(plan: FaultPlan, config: &Config, clutter: Vec<Solid>) -> Self {
        let stop = plan.first_unrecoverable().map(|e| {
            let grace_us = match e.kind {
                FaultKind::LidarGone => LIDAR_PACKET_SILENCE_US,
                _ => MEGA_SILENCE_PERIODS * u64::from(config.mega.control_period_us),
            };
            (e.start_us, e.start_us + grace_us + STOP_WITHIN_US)
        });
        Self {
            injector: FaultInjector::new(plan, clutter),
            late: VecDeque::new(),
            stop,
            last_drive_us: None,
            unsafe_ticks: 0,
            answers_touched: 0,
        }
    }

    /// The plan.
    pub fn plan(&self) -> &FaultPlan {
        self.injector.plan()
    }

    /// Apply what is due before the world steps.
    pub fn before_step(&mut self, sim: &mut SimDevices) {
        self.injector.before_step(sim);
    }

    /// What reaches the robot of a server answer sent at `now_us`.
    pub fn answer(&mut self, now_us: u64, datagram: Vec<u8>) -> Vec<Vec<u8>> {
        let Some(fault) = self.plan().server_fault(now_us) else {
            return vec![datagram];
        };
        self.answers_touched += 1;
        match fault {
            ServerFault::Silent => Vec::new(),
            ServerFault::Late(delay_us) => {
                self.late.push_back((now_us + delay_us, datagram));
                Vec::new()
            }
            ServerFault::Duplicate => vec![datagram.clone(), datagram],
            ServerFault::Garbage(seed) => vec![garbage_datagram(seed)],
        }
    }

    /// A late answer due by `now_us`, if any.
    pub fn late_answer(&mut self, now_us: u64) -> Option<Vec<u8>> {
        let due = self.late.front().is_some_and(|(at, _)| *at <= now_us);
        due.then(|| self.late.pop_front().map(|(_, d)| d)).flatten()
    }

    /// Watch the core's outputs at `now_us`.
    pub fn watch(&mut self, now_us: u64, outputs: &Outputs) {
        let Some((start_us, deadline_us)) = self.stop else {
            return;
        };
        let Some(wheels) = outputs.wheels else {
            return;
        };
        if wheels.drives() && now_us >= start_us {
            self.last_drive_us = Some(now_us);
            if now_us > deadline_us {
                self.unsafe_ticks += 1;
            }
        }
    }

    /// What the faults did.
    pub fn outcome(&self) -> FaultOutcome {
        FaultOutcome {
            planned: self.plan().events.len(),
            // A server fault happened only if an answer fell in it.
            injected: self
                .plan()
                .events
                .iter()
                .zip(self.injector.injected())
                .filter(|(e, i)| **i && (!e.kind.is_server() || self.answers_touched > 0))
                .count(),
            unsafe_ticks: self.unsafe_ticks,
            stop_after_fault_us: self
                .stop
                .map(|(start, _)| self.last_drive_us.map_or(0, |t| t - start)),
            answers_touched: self.answers_touched,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::apps::round::{Live, RoundOptions, run_faulted};
    use ratf_core::config::{Policy, WorldProfile};
    use ratf_sim::faults::FaultEvent;

    fn realistic() -> Config {
        let mut config = Config::default();
        config.sim.world = WorldProfile::Realistic;
        config
    }

    fn one(kind: FaultKind, start_s: f64, duration_s: Option<f64>) -> FaultPlan {
        let start_us = (start_s * 1e6) as u64;
        FaultPlan {
            events: vec![FaultEvent {
                kind,
                start_us,
                end_us: duration_s.map_or(u64::MAX, |d| start_us + (d * 1e6) as u64),
                seed: 1,
            }],
        }
    }

    /// Issue 17's safety target, at several instants of a realistic round 1 (seed 1): a lidar
    /// or a Mega gone for good stops the wheels and the magnet within 150 ms of the fault
    /// (so of its becoming knowable too), and they stay stopped.
    #[test]
    fn a_lidar_or_mega_gone_for_good_stops_the_robot_and_the_magnet() {
        let config = realistic();
        let options = RoundOptions::new(1, 1, Policy::Ours);
        for kind in [FaultKind::LidarGone, FaultKind::MegaGone] {
            for start_s in [6.0, 13.3, 21.7] {
                let plan = one(kind, start_s, None);
                let (report, outcome) = run_faulted(
                    &config,
                    &config,
                    &options,
                    Some(plan),
                    &mut [],
                    Live::default(),
                    |_| {},
                )
                .unwrap();
                assert_eq!(outcome.injected, 1);
                assert_eq!(
                    outcome.unsafe_ticks, 0,
                    "{kind} at {start_s} s: {outcome:?}"
                );
                let stop_us = outcome.stop_after_fault_us.unwrap();
                assert!(
                    stop_us <= STOP_WITHIN_US,
                    "{kind} at {start_s} s: {stop_us} µs"
                );
                assert!(report.points < 4, "the round cannot go on");
            }
        }
    }

    /// Recoverable faults at seed 1 of round 1 (a USB cable out for 1.5 s among them): the
    /// robot still scores fully.
    #[test]
    fn through_a_lidar_dropout_a_mega_reset_a_replug_or_a_silent_server_round_1_still_scores_fully()
    {
        let config = realistic();
        let options = RoundOptions::new(1, 1, Policy::Ours);
        for (kind, duration_s) in [
            (FaultKind::LidarDropout, 3.0),
            (FaultKind::MegaReset, 0.5),
            (FaultKind::ServerSilent, 5.0),
            (FaultKind::ImuFailure, 30.0),
            (FaultKind::MegaReplug, 1.5),
            (FaultKind::LidarReplug, 1.5),
        ] {
            let plan = one(kind, 8.0, Some(duration_s));
            let (report, outcome) = run_faulted(
                &config,
                &config,
                &options,
                Some(plan),
                &mut [],
                Live::default(),
                |_| {},
            )
            .unwrap();
            assert_eq!(outcome.planned, 1);
            assert_eq!(
                (report.points, report.outgoing, report.timeouts),
                (4, 4, 0),
                "{kind}: {report:?}"
            );
        }
    }
}
