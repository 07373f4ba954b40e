//! The core: the robot's whole software behind one step function.

use serde::Serialize;

use crate::config::Config;
use crate::field::geometry::Pose2;
use crate::kinematics::BodyTwist;
use crate::localisation::Health;
use crate::mission::BeaconFix;
use crate::planning::tasks::TaskError;
use crate::robot::{EstimatorKind, InputCounts, Robot};

use super::brain::{Brain, Phase};
use super::bringup::{BiasOutcome, GyroBiasStartup};
use super::event::Event;
use super::input::{Input, MANUAL_DEADMAN_US, OperatorCommand, Stamped, Timestamp};
use super::output::{LidarCommand, Outputs, WheelCommand};
use super::silence::SilenceGuard;

/// What a display shows of the core (the HMI, the live status line, the logs).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Status {
    /// The time of the last input.
    pub time: Timestamp,
    /// The pose estimate, world frame.
    pub pose: Pose2,
    /// Standard deviations of the estimate: position (largest axis), m, and heading, rad.
    pub pose_std: (f64, f64),
    /// Where the round is.
    pub phase: Phase,
    /// When the round's clock started (the part list), if it has.
    pub started: Option<Timestamp>,
    /// The operator has stopped the robot.
    pub stopped: bool,
    /// The operator drives the robot ([`OperatorCommand::Drive`] or
    /// [`OperatorCommand::OpenLoop`]); the mission waits.
    pub manual: bool,
    /// Parts placed so far (the robot's own count, not the referee's points).
    pub placed: u32,
    /// The box switch as last reported.
    pub switch_pressed: bool,
    /// What the core has received.
    pub inputs: InputCounts,
}

/// How the operator moves the wheels.
#[derive(Clone, Copy, Debug)]
enum ManualMotion {
    /// A robot-frame twist, through the kinematics and the Mega's PI.
    Twist(BodyTwist),
    /// Signed PWM per motor, open loop.
    Pwm([i16; 4]),
}

/// The operator's last [`OperatorCommand::Drive`] or [`OperatorCommand::OpenLoop`].
#[derive(Clone, Copy, Debug)]
struct ManualDrive {
    motion: ManualMotion,
    until_us: u64,
}

/// The robot's software: see the module documentation of [`crate::runtime`].
#[derive(Debug)]
pub struct Core {
    robot: Robot,
    brain: Brain,
    stopped: bool,
    manual: Option<ManualDrive>,
    lidar_started: bool,
    gyro_bias: GyroBiasStartup,
    placed: u32,
    time: Timestamp,
    silence: SilenceGuard,
}

impl Core {
    /// A core for `config` (its round, policy and beliefs), believing the robot starts at
    /// `start_pose`, with the estimator of its policy ([`EstimatorKind::for_policy`]).
    pub fn new(config: &Config, start_pose: Pose2) -> Result<Self, TaskError> {
        let kind = EstimatorKind::for_policy(config.competition.policy);
        Self::with_estimator(config, kind, start_pose)
    }

    /// A core with the pose estimator `kind`.
    pub fn with_estimator(
        config: &Config,
        kind: EstimatorKind,
        start_pose: Pose2,
    ) -> Result<Self, TaskError> {
        Ok(Self {
            robot: Robot::with_estimator(config, kind, start_pose),
            brain: Brain::new(config)?,
            stopped: false,
            manual: None,
            lidar_started: false,
            gyro_bias: GyroBiasStartup::default(),
            placed: 0,
            time: Timestamp::ZERO,
            silence: SilenceGuard::new(config),
        })
    }

    /// Consume one input; what the devices must do and what happened.
    pub fn step(&mut self, stamped: &Stamped) -> Outputs {
        let now_us = stamped.time.as_us();
        self.time = stamped.time;
        let mut outputs = Outputs::default();
        match &stamped.input {
            Input::HostTick => self.on_tick(now_us, &mut outputs),
            Input::Wheels(_) | Input::MegaReset | Input::Scan(_) | Input::Imu(_) => {
                self.silence.heard(&stamped.input, now_us);
                self.robot.handle(stamped)
            }
            Input::Referee { datagram } => {
                self.brain
                    .on_datagram(now_us, datagram, &mut outputs.events)
            }
            Input::Operator(command) => self.on_operator(now_us, command, &mut outputs),
            Input::DeviceFault {
                device,
                message,
                reconnecting,
            } => {
                // A port being reopened holds the robot until the device speaks again (a
                // replug goes on with the round); any other fault stops it for good.
                let held = *reconnecting && self.silence.lost(*device, now_us);
                if !held {
                    self.stopped = true;
                    outputs.wheels = Some(WheelCommand::STOP);
                }
                outputs.events.push(Event::DeviceFault {
                    device: *device,
                    message: message.clone(),
                    reconnecting: held,
                });
            }
        }
        self.bring_up(&stamped.input, &mut outputs);
        self.placed += outputs
            .events
            .iter()
            .filter(|e| matches!(e, Event::Placed { .. }))
            .count() as u32;
        outputs
    }

    /// The start-up gyro bias: measured on the IMU samples while the robot waits for the
    /// part list, concluded at the latest when the round starts.
    fn bring_up(&mut self, input: &Input, outputs: &mut Outputs) {
        if self.gyro_bias.is_done() {
            return;
        }
        let outcome = if self.brain.phase() != Phase::WaitingForPartList || self.stopped {
            self.gyro_bias.finish()
        } else if let Input::Imu(sample) = input {
            self.gyro_bias.on_sample(sample)
        } else {
            None
        };
        match outcome {
            Some(BiasOutcome::Measured {
                bias_rad_s,
                std_rad_s,
            }) => {
                self.robot.set_gyro_bias(bias_rad_s, std_rad_s);
                outputs.events.push(Event::GyroBiasMeasured { bias_rad_s });
            }
            Some(BiasOutcome::Refused(reason)) => outputs.events.push(Event::GyroBiasRefused {
                reason: reason.to_string(),
            }),
            None => {}
        }
    }

    fn on_tick(&mut self, now_us: u64, outputs: &mut Outputs) {
        if !self.lidar_started {
            self.lidar_started = true;
            outputs.lidar = Some(LidarCommand::StartScan);
        }
        // Bring-up: nothing drives before the Mega has spoken (its `r` or a telemetry
        // batch), so odometry and the switch are real before the first move.
        let counts = self.robot.input_counts();
        let mega_heard = counts.mega_resets + counts.wheel_batches > 0;
        // A held robot's mission stands with its clock stopped (`mission`, "Held").
        let hold = self.silence.check(now_us, &mut outputs.events);
        let scan = self.robot.localisation_health().last_scan;
        if let Some(agreed) = scan.beacons_fix {
            self.brain.observe_fix(BeaconFix {
                reference_time_us: scan.reference_time_us,
                agreed,
            });
        }
        let tick = self.brain.tick(
            now_us,
            self.robot.pose(),
            self.robot.switch_pressed(),
            mega_heard,
            hold,
            &mut outputs.events,
        );
        outputs.referee = tick.request;
        let mut open_loop_pwm = None;
        // Only the mission's own drive arms the Mega's stop on the switch: a stop, a hold or
        // the operator's hand leaves the wheels to the host.
        let mut stop_on_switch = false;
        if self.stopped {
            self.robot.command_motion(BodyTwist::default());
            self.robot.command_solenoid(false);
        } else if hold.wheels {
            self.robot.command_motion(BodyTwist::default());
            self.robot
                .command_solenoid(tick.solenoid_on && !hold.magnet);
        } else if let Some(manual) = self.manual {
            let fresh = now_us <= manual.until_us && mega_heard;
            match manual.motion {
                ManualMotion::Twist(twist) if fresh => self.robot.command_motion(twist),
                ManualMotion::Pwm(pwm) if fresh => {
                    self.robot.command_motion(BodyTwist::default());
                    open_loop_pwm = Some(pwm);
                }
                _ => self.robot.command_motion(BodyTwist::default()),
            }
            self.robot.command_solenoid(tick.solenoid_on);
        } else {
            self.robot.command_motion(tick.twist);
            self.robot.command_solenoid(tick.solenoid_on);
            stop_on_switch = tick.stop_on_switch;
        }
        let wheels = self.robot.tick(now_us);
        outputs.wheels = Some(WheelCommand {
            wheel_speeds_rad_s: wheels.wheel_speeds_rad_s,
            solenoid_on: wheels.solenoid_on,
            stop_on_switch,
            twist_scale: wheels.twist_scale,
            open_loop_pwm,
        });
    }

    fn on_operator(&mut self, now_us: u64, command: &OperatorCommand, outputs: &mut Outputs) {
        match command {
            OperatorCommand::ForceStart { parts } => {
                self.brain.force_start(now_us, *parts, &mut outputs.events)
            }
            OperatorCommand::Stop => {
                self.stopped = true;
                outputs.wheels = Some(WheelCommand::STOP);
                outputs.events.push(Event::Stopped);
            }
            OperatorCommand::Resume => {
                self.stopped = false;
                self.manual = None;
                outputs.events.push(Event::Resumed);
            }
            OperatorCommand::Drive { twist } => {
                self.take_wheels(now_us, ManualMotion::Twist(*twist), outputs)
            }
            OperatorCommand::OpenLoop { pwm } => {
                self.take_wheels(now_us, ManualMotion::Pwm(*pwm), outputs)
            }
            OperatorCommand::SetPose { pose } => {
                self.robot.reset_pose(*pose, now_us);
                outputs.events.push(Event::PoseSet { pose: *pose });
            }
        }
    }

    /// The operator moves the wheels with `motion` until the deadman lapses.
    fn take_wheels(&mut self, now_us: u64, motion: ManualMotion, outputs: &mut Outputs) {
        if self.manual.is_none() {
            outputs.events.push(Event::ManualDrive);
        }
        self.manual = Some(ManualDrive {
            motion,
            until_us: now_us + MANUAL_DEADMAN_US,
        });
    }

    /// The estimation and the wheel kinematics (pose, odometry, health).
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The competition brain (phase, planner).
    pub fn brain(&self) -> &Brain {
        &self.brain
    }

    /// The pose estimate, world frame.
    pub fn pose(&self) -> Pose2 {
        self.robot.pose()
    }

    /// The estimator's health.
    pub fn localisation_health(&self) -> Health {
        self.robot.localisation_health()
    }

    /// What a display shows now.
    pub fn status(&self) -> Status {
        let health = self.robot.localisation_health();
        Status {
            time: self.time,
            pose: self.robot.pose(),
            pose_std: (health.position_std_m, health.heading_std_rad),
            phase: self.brain.phase(),
            started: self.brain.started_at_us().map(Timestamp::from_us),
            stopped: self.stopped,
            manual: self.manual.is_some(),
            placed: self.placed,
            switch_pressed: self.robot.switch_pressed(),
            inputs: self.robot.input_counts(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Field, PartColor};
    use crate::referee::protocol::Request;
    use crate::runtime::{DeviceKind, MAGNET_OFF_AFTER_US};

    const BLUE: Option<PartColor> = Some(PartColor::Blue);

    fn at(ms: u64, input: Input) -> Stamped {
        Stamped::new(Timestamp::from_us(ms * 1_000), input)
    }

    fn core() -> Core {
        Core::new(&Config::default(), Field::competition().start_pose()).unwrap()
    }

    fn moving(outputs: &Outputs) -> bool {
        outputs
            .wheels
            .is_some_and(|w| w.wheel_speeds_rad_s.iter().any(|s| *s != 0.0))
    }

    #[test]
    fn the_first_tick_starts_the_lidar_and_asks_for_the_part_list() {
        let mut core = core();
        let first = core.step(&at(7, Input::HostTick));
        assert_eq!(first.lidar, Some(LidarCommand::StartScan));
        assert_eq!(first.referee, Some(Request::IncomingWarehouse));
        assert!(first.wheels.is_some() && !moving(&first));
        let second = core.step(&at(27, Input::HostTick));
        assert_eq!(second.lidar, None, "the start command goes once");
    }

    #[test]
    fn nothing_drives_before_the_mega_has_spoken_and_an_operator_stop_holds() {
        let mut core = core();
        let started = core.step(&at(
            10,
            Input::Operator(OperatorCommand::ForceStart { parts: [BLUE; 4] }),
        ));
        assert!(
            matches!(
                started.events.as_slice(),
                [
                    Event::PartList { forced: true, .. },
                    Event::GyroBiasRefused { .. }
                ]
            ),
            "{:?}",
            started.events
        );
        for k in 0..20 {
            let out = core.step(&at(27 + 20 * k, Input::HostTick));
            assert!(!moving(&out), "drove without the Mega at tick {k}");
        }
        core.step(&at(430, Input::MegaReset));
        let drives = (0..20).any(|k| moving(&core.step(&at(447 + 20 * k, Input::HostTick))));
        assert!(drives, "the mission never moved once the Mega was heard");
        let stop = core.step(&at(900, Input::Operator(OperatorCommand::Stop)));
        assert_eq!(stop.wheels, Some(WheelCommand::STOP));
        assert_eq!(stop.events, [Event::Stopped]);
        for k in 0..10 {
            let out = core.step(&at(907 + 20 * k, Input::HostTick));
            assert!(!moving(&out) && !out.wheels.unwrap().solenoid_on);
        }
        assert!(core.status().stopped);
        core.step(&at(1200, Input::Operator(OperatorCommand::Resume)));
        let drives = (0..10).any(|k| moving(&core.step(&at(1207 + 20 * k, Input::HostTick))));
        assert!(drives, "resume lets the mission drive again");
    }

    #[test]
    fn the_operator_drives_until_the_deadman_lapses_a_stop_wins_and_resume_hands_back() {
        let mut core = core();
        core.step(&at(5, Input::MegaReset));
        let forward = Input::Operator(OperatorCommand::Drive {
            twist: BodyTwist::new(0.2, 0.0, 0.0),
        });
        assert_eq!(
            core.step(&at(10, forward.clone())).events,
            [Event::ManualDrive]
        );
        let driving = core.step(&at(27, Input::HostTick));
        let speeds = driving.wheels.unwrap().wheel_speeds_rad_s;
        // Forward: every wheel turns.
        assert!(speeds.iter().all(|s| s.abs() > 1.0), "{speeds:?}");
        assert!(core.status().manual);
        // Half a second after the last command the robot stands still, still in manual.
        assert!(moving(&core.step(&at(507, Input::HostTick))));
        assert!(!moving(&core.step(&at(527, Input::HostTick))));
        assert!(core.step(&at(540, forward.clone())).events.is_empty());
        assert!(moving(&core.step(&at(547, Input::HostTick))));
        core.step(&at(550, Input::Operator(OperatorCommand::Stop)));
        core.step(&at(555, forward));
        assert!(
            !moving(&core.step(&at(567, Input::HostTick))),
            "a stop wins"
        );
        core.step(&at(600, Input::Operator(OperatorCommand::Resume)));
        assert!(!core.status().manual && !core.status().stopped);
        // Back with the mission, which has no part list: it stands still.
        assert!(!moving(&core.step(&at(607, Input::HostTick))));
    }

    #[test]
    fn open_loop_pwm_reaches_the_mega_until_the_deadman_lapses_and_a_stop_wins() {
        let pwm_of = |out: &Outputs| out.wheels.and_then(|w| w.open_loop_pwm);
        let mut core = core();
        let step = Input::Operator(OperatorCommand::OpenLoop {
            pwm: [30, -30, 30, -30],
        });
        core.step(&at(10, step.clone()));
        assert_eq!(
            pwm_of(&core.step(&at(27, Input::HostTick))),
            None,
            "nothing drives before the Mega has spoken"
        );
        core.step(&at(30, Input::MegaReset));
        let held = core.step(&at(47, Input::HostTick)).wheels.unwrap();
        assert_eq!(held.open_loop_pwm, Some([30, -30, 30, -30]));
        assert_eq!(
            held.wheel_speeds_rad_s, [0.0; 4],
            "the references stand still"
        );
        assert!(held.drives() && core.status().manual);
        assert!(pwm_of(&core.step(&at(507, Input::HostTick))).is_some());
        let lapsed = core.step(&at(527, Input::HostTick)).wheels.unwrap();
        assert_eq!(lapsed.open_loop_pwm, None, "the deadman lapsed");
        assert!(!lapsed.drives());
        core.step(&at(540, step.clone()));
        core.step(&at(550, Input::Operator(OperatorCommand::Stop)));
        core.step(&at(555, step.clone()));
        assert_eq!(
            pwm_of(&core.step(&at(567, Input::HostTick))),
            None,
            "a stop wins"
        );
        core.step(&at(600, Input::Operator(OperatorCommand::Resume)));
        core.step(&at(610, step));
        core.step(&at(
            620,
            Input::DeviceFault {
                device: super::super::DeviceKind::Mega,
                message: "port gone".into(),
                reconnecting: false,
            },
        ));
        assert_eq!(
            pwm_of(&core.step(&at(627, Input::HostTick))),
            None,
            "a fault wins"
        );
    }

    #[test]
    fn a_device_fault_stops_the_robot() {
        let mut core = core();
        core.step(&at(5, Input::MegaReset));
        core.step(&at(
            10,
            Input::Operator(OperatorCommand::ForceStart { parts: [BLUE; 4] }),
        ));
        let fault = core.step(&at(
            30,
            Input::DeviceFault {
                device: super::super::DeviceKind::Lidar,
                message: "port gone".into(),
                reconnecting: false,
            },
        ));
        assert_eq!(fault.wheels, Some(WheelCommand::STOP));
        for k in 0..10 {
            assert!(!moving(&core.step(&at(47 + 20 * k, Input::HostTick))));
        }
        // Not a port being reopened (a health error): data flowing again does not undo it.
        for k in 0..10 {
            let ms = 250 + 20 * k;
            core.step(&telemetry(ms));
            core.step(&scan(ms, 100));
            assert!(!moving(&core.step(&at(ms + 4, Input::HostTick))));
        }
        assert!(core.status().stopped);
    }

    /// Issue 17, a USB unplug and replug: a device whose thread reports its port lost and
    /// reopens it held the robot for good (an operator stop nobody lifts in `ratf run`).
    /// Now the robot holds still from the fault (wheels at the next tick, the magnet
    /// [`MAGNET_OFF_AFTER_US`] later) until the device speaks again, then the mission drives
    /// on; the Mega is back with its telemetry, not its reset frame alone.
    #[test]
    fn a_lost_port_holds_the_robot_until_its_device_speaks_again() {
        for lost in [DeviceKind::Mega, DeviceKind::Lidar] {
            let mut core = driving_until_400_ms(lost);
            let fault = core.step(&at(
                400,
                Input::DeviceFault {
                    device: lost,
                    message: "port gone".into(),
                    reconnecting: true,
                },
            ));
            assert!(
                matches!(
                    fault.events.as_slice(),
                    [Event::DeviceFault {
                        reconnecting: true,
                        ..
                    }]
                ),
                "{lost}: {:?}",
                fault.events
            );
            // Away for a second: the other device keeps streaming, the lost one says nothing.
            let mut events = Vec::new();
            for k in 20..70u64 {
                let ms = 20 * k + 13;
                if lost != DeviceKind::Mega {
                    core.step(&telemetry(ms));
                }
                if lost != DeviceKind::Lidar && k % 7 == 0 {
                    core.step(&scan(ms, 100));
                }
                let out = core.step(&at(ms + 4, Input::HostTick));
                events.extend(out.events.iter().cloned());
                assert!(
                    !moving(&out),
                    "{lost}: drove {} ms after the fault",
                    ms - 396
                );
                if ms + 4 >= 400 + 20 + 100 {
                    assert!(
                        !out.wheels.unwrap().solenoid_on,
                        "{lost}: magnet at {ms} ms"
                    );
                }
            }
            assert!(
                !events
                    .iter()
                    .any(|e| matches!(e, Event::DeviceSilent { .. } | Event::DeviceBack { .. })),
                "{lost}: the fault is the event, and it is not back: {events:?}"
            );
            assert!(!core.status().stopped, "the hold is not an operator stop");
            // Back: the Mega resets and streams, the lidar is started again and scans.
            if lost == DeviceKind::Mega {
                core.step(&at(1_410, Input::MegaReset));
                let out = core.step(&at(1_417, Input::HostTick));
                assert!(!moving(&out) && out.events.is_empty(), "{:?}", out.events);
            }
            let mut back = Vec::new();
            let mut drives = false;
            for k in 71..90u64 {
                let ms = 20 * k + 13;
                core.step(&telemetry(ms));
                if k % 7 == 0 {
                    core.step(&scan(ms, 100));
                }
                let out = core.step(&at(ms + 4, Input::HostTick));
                back.extend(out.events.iter().cloned());
                drives |= moving(&out);
            }
            assert!(
                back.contains(&Event::DeviceBack { device: lost }),
                "{lost}: {back:?}"
            );
            assert!(drives, "{lost}: the mission did not go on");
        }
    }

    /// Issue 17: while the core held the robot (the Mega's port lost), the mission's clock ran
    /// on and its timeouts ran out on a robot that could not move: a drive "timed out" and
    /// was retried, a back-out after a drop "ran out" against the part and the part counted
    /// as stuck. Held, the mission stands with its clock stopped: away 30 s, longer than the
    /// drive's 25 s timeout, the drive goes on as the first attempt when the Mega is back.
    #[test]
    fn the_missions_clock_stops_while_a_lost_port_holds_the_robot() {
        let mut core = driving_until_400_ms("held");
        core.step(&at(
            400,
            Input::DeviceFault {
                device: DeviceKind::Mega,
                message: "port gone".into(),
                reconnecting: true,
            },
        ));
        let mut events = Vec::new();
        let mut drives = false;
        for k in 20..1_650u64 {
            let ms = 20 * k + 13;
            // The Mega is away until 30.4 s, then resets and streams again.
            if ms >= 30_400 {
                if ms < 30_420 {
                    core.step(&at(ms - 5, Input::MegaReset));
                }
                core.step(&telemetry(ms));
            }
            if k % 7 == 0 {
                core.step(&scan(ms, 100));
            }
            let out = core.step(&at(ms + 4, Input::HostTick));
            drives |= ms >= 30_400 && moving(&out);
            events.extend(out.events);
        }
        assert!(
            !events
                .iter()
                .any(|e| matches!(e, Event::ActionStarted { .. } | Event::Skipped { .. })),
            "the mission gave up or began again: {events:?}"
        );
        assert!(events.contains(&Event::DeviceBack {
            device: DeviceKind::Mega
        }));
        assert!(drives, "the drive did not go on");
    }

    /// A core whose round started (four blue parts) and whose Mega and lidar streamed until
    /// 400 ms, the mission driving by then.
    fn driving_until_400_ms(label: impl std::fmt::Display) -> Core {
        let mut core = core();
        core.step(&at(5, Input::MegaReset));
        core.step(&at(
            10,
            Input::Operator(OperatorCommand::ForceStart { parts: [BLUE; 4] }),
        ));
        let mut drove = false;
        for k in 0..20u64 {
            let ms = 20 * k + 13;
            core.step(&telemetry(ms));
            if k % 7 == 0 {
                core.step(&scan(ms, 100));
            }
            drove |= moving(&core.step(&at(ms + 4, Input::HostTick)));
        }
        assert!(drove, "{label}: the mission never moved");
        core
    }

    fn telemetry(ms: u64) -> Stamped {
        at(
            ms,
            Input::Wheels(crate::drivers::mega_link::WheelTelemetry {
                deltas_ticks: Some([0; 4]),
                ..crate::drivers::mega_link::WheelTelemetry::for_test([0; 4], false, ms * 1_000)
            }),
        )
    }

    fn scan(ms: u64, points: usize) -> Stamped {
        at(
            ms,
            Input::Scan(crate::drivers::x4::scan::Scan::points_at_one_metre(
                (ms * 1_000) as f64,
                points,
            )),
        )
    }

    /// Issue 17: a lidar or a Mega that stops sending while plugged in (or a lidar whose
    /// revolutions come empty) reached the core only as silence, and the core drove on
    /// (blind, on odometry) until a device thread gave up seconds later, or for ever in the
    /// simulator. Now it holds still within the guard's limit and one tick, the Mega's
    /// silence with the magnet off [`MAGNET_OFF_AFTER_US`] later (the lidar's keeps a held
    /// part, see `silence`'s tests), and goes on when the data flows again.
    #[test]
    fn a_silent_lidar_or_mega_holds_the_robot_until_it_speaks_again() {
        for (silent, empty) in [
            (DeviceKind::Lidar, false),
            (DeviceKind::Lidar, true),
            (DeviceKind::Mega, false),
        ] {
            // Both devices stream until 400 ms; the mission drives.
            let mut core = driving_until_400_ms(silent);
            // From 400 ms on, one of them says nothing.
            let limit_ms = match silent {
                DeviceKind::Lidar => 286,
                _ => 60,
            };
            let last_ms = match silent {
                DeviceKind::Lidar => 7 * 20 * 2 + 13,
                _ => 393,
            };
            let mut events = Vec::new();
            for k in 20..60u64 {
                let ms = 20 * k + 13;
                if silent != DeviceKind::Mega {
                    core.step(&telemetry(ms));
                }
                if k % 7 == 0 {
                    if silent != DeviceKind::Lidar {
                        core.step(&scan(ms, 100));
                    } else if empty {
                        core.step(&scan(ms, 0));
                    }
                }
                let out = core.step(&at(ms + 4, Input::HostTick));
                events.extend(out.events.iter().cloned());
                let wheels = out.wheels.unwrap();
                if ms + 4 > last_ms + limit_ms + 20 {
                    assert!(
                        !moving(&out),
                        "{silent}: drove {} ms after",
                        ms + 4 - last_ms
                    );
                }
                if silent == DeviceKind::Mega
                    && ms + 4 > last_ms + limit_ms + 20 + MAGNET_OFF_AFTER_US / 1_000
                {
                    assert!(
                        !moving(&out) && !wheels.solenoid_on,
                        "{silent}: drove {} ms after its last data",
                        ms + 4 - last_ms
                    );
                }
            }
            assert!(
                events
                    .iter()
                    .any(|e| matches!(e, Event::DeviceSilent { device, .. } if *device == silent)),
                "{silent}: {events:?}"
            );
            // It speaks again: the hold ends.
            let mut back = Vec::new();
            for k in 60..80u64 {
                let ms = 20 * k + 13;
                core.step(&telemetry(ms));
                if k % 7 == 0 {
                    core.step(&scan(ms, 100));
                }
                back.extend(core.step(&at(ms + 4, Input::HostTick)).events);
            }
            assert!(
                back.contains(&Event::DeviceBack { device: silent }),
                "{silent}: {back:?}"
            );
            assert!(!core.status().stopped, "the hold is not an operator stop");
        }
    }
}
