//! The host's real stack on the simulated devices, driven by a script instead of the
//! competition brain: the velocity scripts (`ratf drive`) and the localisation and
//! navigation benchmarks command the body twist themselves.
//!
//! Each world step, [`SimDevices`] hands over what the ports delivered; the sensor inputs go
//! to the core's [`Robot`] (estimation), and at each host tick the caller's `control` hook
//! decides the motion, whose wheel references go back to the Mega. A whole round goes
//! through [`ratf_core::runtime::run`] instead, with the same devices.

use ratf_core::config::Config;
use ratf_core::drivers::imu::ImuError;
use ratf_core::field::geometry::Pose2;
use ratf_core::robot::{Output, Robot};
use ratf_core::runtime::{Input, LidarCommand, Outputs, Stamped, WheelCommand};

use crate::devices::SimDevices;
use crate::world::{Scenario, World};

/// The simulated robot: world + host stack.
#[derive(Debug)]
pub struct SimulatedRobot {
    devices: SimDevices,
    robot: Robot,
    last_output: Option<Output>,
}

impl SimulatedRobot {
    /// Build the world and the host stack. The core believes the robot starts at
    /// `believed_start` (the scenario's true start unless testing a wrong initial pose).
    pub fn new(
        config: &Config,
        scenario: &Scenario,
        believed_start: Pose2,
    ) -> Result<Self, ImuError> {
        Self::in_world(config, config, scenario, believed_start)
    }

    /// The same, with the world drawn around `world` (the configuration the team wrote,
    /// plus the seed's errors) and a robot that believes `robot` (e.g. `world` after
    /// `ratf calibrate`: calibrating changes what the robot believes, not the hall).
    pub fn in_world(
        world: &Config,
        robot: &Config,
        scenario: &Scenario,
        believed_start: Pose2,
    ) -> Result<Self, ImuError> {
        Ok(Self {
            devices: SimDevices::new(world, scenario)?,
            robot: Robot::new(robot, believed_start),
            last_output: None,
        })
    }

    /// The world (ground truth, for reports).
    pub fn world(&self) -> &World {
        self.devices.world()
    }

    /// The world, to inject faults.
    pub fn world_mut(&mut self) -> &mut World {
        self.devices.world_mut()
    }

    /// The core.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The true pose when the Mega counted the encoders for the last telemetry batch the
    /// core received: the ground truth its odometry (and so its estimate) refers to, without
    /// the telemetry's time in flight. `None` before the first batch.
    pub fn truth_at_last_telemetry(&self) -> Option<Pose2> {
        self.devices.truth_at_last_telemetry()
    }

    /// The core's output at the last host tick.
    pub fn last_output(&self) -> Option<Output> {
        self.last_output
    }

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.devices.now_us()
    }

    /// Fault injection: drop each completed lidar scan with probability `probability`
    /// (drawn from the scenario's seed) before it reaches the core, as a USB hiccup would.
    pub fn drop_scans(&mut self, probability: f64, seed: u64) {
        self.devices.drop_scans(probability, seed);
    }

    /// Advance one world step; `control` runs before each host tick with the core and the
    /// time (µs). Returns true when a host tick happened in this step.
    pub fn step(&mut self, control: impl FnMut(&mut Robot, u64)) -> Result<bool, ImuError> {
        self.step_observed(control, |_| {})
    }

    /// [`SimulatedRobot::step`], with `observe` seeing every sensor input the core gets,
    /// just before it does (e.g. to feed a second estimator side by side).
    pub fn step_observed(
        &mut self,
        mut control: impl FnMut(&mut Robot, u64),
        mut observe: impl FnMut(&Stamped),
    ) -> Result<bool, ImuError> {
        self.devices.advance()?;
        let mut ticked = false;
        while let Some(stamped) = self.devices.pop_input() {
            if stamped.input != Input::HostTick {
                observe(&stamped);
                self.robot.handle(&stamped);
                continue;
            }
            let now_us = stamped.time.as_us();
            control(&mut self.robot, now_us);
            let output = self.robot.tick(now_us);
            self.devices.apply_outputs(&Outputs {
                wheels: Some(WheelCommand {
                    wheel_speeds_rad_s: output.wheel_speeds_rad_s,
                    solenoid_on: output.solenoid_on,
                    stop_on_switch: false,
                    twist_scale: output.twist_scale,
                    open_loop_pwm: None,
                }),
                // Scripts bring the lidar up at their first tick, as the core does.
                lidar: self
                    .last_output
                    .is_none()
                    .then_some(LidarCommand::StartScan),
                ..Outputs::default()
            });
            self.last_output = Some(output);
            ticked = true;
        }
        Ok(ticked)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_core::config::WorldProfile;
    use ratf_core::field::geometry::Pose2;
    use ratf_core::kinematics::BodyTwist;

    /// The ideal world: the odometry's exactness and the telemetry's timing, without the
    /// realistic world's slip and USB jitter.
    fn run(twist: BodyTwist, seconds: f64) -> SimulatedRobot {
        let config = Config::default().in_world(WorldProfile::Ideal);
        let start = Pose2::new(-0.64, -0.42, std::f64::consts::FRAC_PI_2);
        let scenario = Scenario {
            start_pose: start,
            ..Scenario::new(&config)
        };
        let mut sim = SimulatedRobot::new(&config, &scenario, start).unwrap();
        while (sim.now_us() as f64) < seconds * 1e6 {
            sim.step(|robot, _| robot.command_motion(twist)).unwrap();
        }
        sim
    }

    #[test]
    fn every_device_feeds_the_core() {
        let sim = run(BodyTwist::default(), 1.0);
        let counts = sim.robot().input_counts();
        assert_eq!(counts.mega_resets, 1);
        assert!((48..=50).contains(&counts.wheel_batches), "{counts:?}");
        assert!((199..=200).contains(&counts.imu_samples), "{counts:?}");
        assert!((5..=7).contains(&counts.scans), "{counts:?}");
    }

    #[test]
    fn without_slip_odometry_matches_ground_truth_up_to_quantisation() {
        // A gentle sideways-and-turning motion: the PI and motor lags make the start and
        // stop smooth enough that the body never exceeds the traction limit.
        let sim = run(BodyTwist::new(0.05, 0.05, 0.2), 2.0);
        assert_eq!(sim.world().stats().slip_steps, 0);
        let truth = sim.world().body().pose;
        let odom = sim.robot().pose();
        // Odometry lags by the telemetry in flight (< 21 ms), and each wheel is quantised
        // to one tick (0.067 mm): allow for one control period of motion.
        assert!(
            (truth.x - odom.x).hypot(truth.y - odom.y) < 0.0025,
            "truth {truth:?} odometry {odom:?}"
        );
    }

    #[test]
    fn telemetry_is_timed_at_the_megas_tick() {
        let config = Config::default().in_world(WorldProfile::Ideal);
        let scenario = Scenario::new(&config);
        let mut sim = SimulatedRobot::new(&config, &scenario, scenario.start_pose).unwrap();
        let mut sampled = Vec::new();
        while sim.now_us() < 500_000 {
            sim.step_observed(
                |_, _| {},
                |stamped| {
                    if let Input::Wheels(t) = &stamped.input {
                        sampled.push((t.sampled_at_us, t.received_at_us));
                    }
                },
            )
            .unwrap();
        }
        assert!(sampled.len() >= 20);
        for (sampled_at, received_at) in sampled {
            // The Mega ticks every 20 ms from 20 ms; the host sees bytes at 1 ms steps.
            let tick = (sampled_at + 10_000) / 20_000 * 20_000;
            assert!(
                sampled_at >= tick && sampled_at - tick < 1_000,
                "sampled at {sampled_at} µs, tick {tick}"
            );
            assert!(
                received_at - sampled_at > 9_000,
                "transmission and firmware latency"
            );
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_run() {
        let a = run(BodyTwist::new(0.2, 0.0, 0.5), 0.5);
        let b = run(BodyTwist::new(0.2, 0.0, 0.5), 0.5);
        assert_eq!(a.world().body(), b.world().body());
        assert_eq!(a.robot().pose(), b.robot().pose());
    }
}
