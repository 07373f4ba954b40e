//! The host's real stack on the simulated devices: what runs on the Pi, minus the ports.
//!
//! Per world step: bytes that arrived from the Mega go through [`MegaLink`], bytes from the
//! lidar through [`X4Driver`], and the IMU is read through its driver at 200 Hz on the
//! simulated I2C bus; each result becomes a timestamped [`Input`] for the [`Robot`] core. On
//! the host's own 50 Hz timer (offset from the Mega's tick by [`HOST_TICK_PHASE_US`], as two
//! free-running clocks would be), the core's [`Output`] goes to the Mega as a `G H I J L`
//! batch. The caller's `control` hook runs just before each host tick: that is where a
//! script, the navigation or the mission decides what the robot does next.

use crate::world::{Scenario, SimImuBus, World};
use ratf_core::config::Config;
use ratf_core::drivers::imu::{ImuConfig as ImuDriverConfig, ImuError, Mpu9255};
use ratf_core::drivers::mega_link::{MegaEvent, MegaLink, MegaLinkConfig};
use ratf_core::drivers::x4::X4Driver;
use ratf_core::drivers::x4::scan::ScanConfig;
use ratf_core::rng::SimRng;
use ratf_core::robot::{Input, Output, Robot};

/// Period of the host's reference timer, µs (50 Hz, the Mega's control rate).
pub const HOST_TICK_PERIOD_US: u64 = 20_000;
/// Offset of the host's timer from the Mega's tick, µs: an arbitrary 7 ms, so the two clocks
/// are not artificially in phase.
pub const HOST_TICK_PHASE_US: u64 = 7_000;
/// IMU read period, µs (200 Hz, the rate the driver configures).
pub const IMU_PERIOD_US: u64 = 5_000;

/// The simulated robot: world + host stack.
#[derive(Debug)]
pub struct SimulatedRobot {
    world: World,
    robot: Robot,
    mega: MegaLink,
    lidar: X4Driver,
    imu: Mpu9255<SimImuBus>,
    next_host_tick_us: u64,
    next_imu_us: u64,
    last_output: Option<Output>,
    scan_drop: Option<(f64, SimRng)>,
}

impl SimulatedRobot {
    /// Build the world and the host stack. The core believes the robot starts at
    /// `believed_start` (the scenario's true start unless testing a wrong initial pose).
    pub fn new(
        config: &Config,
        scenario: &Scenario,
        believed_start: ratf_core::field::geometry::Pose2,
    ) -> Result<Self, ImuError> {
        let world = World::new(config, scenario);
        let imu = Mpu9255::new(world.imu_bus(), ImuDriverConfig::default())?;
        Ok(Self {
            robot: Robot::new(config, believed_start),
            mega: MegaLink::new(MegaLinkConfig {
                send_checksums: config.mega.send_checksums,
                baud: config.link.mega_baud,
                telemetry_latency_us: config.mega.telemetry_latency_us,
            }),
            lidar: X4Driver::new(ScanConfig {
                range_min_m: config.lidar.min_range_m,
                range_max_m: config.lidar.max_range_m,
                ..ScanConfig::default()
            }),
            imu,
            next_host_tick_us: HOST_TICK_PHASE_US,
            next_imu_us: IMU_PERIOD_US,
            last_output: None,
            scan_drop: None,
            world,
        })
    }

    /// The world (ground truth, for reports).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The world, to inject faults.
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// The core.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The true pose when the Mega counted the encoders for the last telemetry batch the
    /// core received: the ground truth its odometry (and so its estimate) refers to, without
    /// the telemetry's time in flight. `None` before the first batch.
    pub fn truth_at_last_telemetry(&self) -> Option<ratf_core::field::geometry::Pose2> {
        let batches = self.robot.input_counts().wheel_batches as usize;
        batches
            .checked_sub(1)
            .and_then(|i| self.world.tick_poses().get(i).copied())
    }

    /// The core's output at the last host tick.
    pub fn last_output(&self) -> Option<Output> {
        self.last_output
    }

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.world.now_us()
    }

    /// Fault injection: drop each completed lidar scan with probability `probability`
    /// (drawn from the scenario's seed) before it reaches the core, as a USB hiccup would.
    pub fn drop_scans(&mut self, probability: f64, seed: u64) {
        self.scan_drop = Some((probability, SimRng::new(seed).fork("scan-drop")));
    }

    /// Advance one world step; `control` runs before each host tick with the core and the
    /// time (µs). Returns true when a host tick happened in this step.
    pub fn step(&mut self, control: impl FnMut(&mut Robot, u64)) -> Result<bool, ImuError> {
        self.step_observed(control, |_| {})
    }

    /// [`SimulatedRobot::step`], with `observe` seeing every input the core gets, just before
    /// it does (e.g. to feed a second estimator side by side).
    pub fn step_observed(
        &mut self,
        mut control: impl FnMut(&mut Robot, u64),
        mut observe: impl FnMut(&Input),
    ) -> Result<bool, ImuError> {
        self.world.step();
        let now_us = self.world.now_us();
        let robot = &mut self.robot;
        let mut deliver = |input: Input| {
            observe(&input);
            robot.handle(&input);
        };

        let bytes = self.world.receive_from_mega();
        self.mega.feed(&bytes, now_us, |event| match event {
            MegaEvent::Telemetry(telemetry) => deliver(Input::Wheels(telemetry)),
            MegaEvent::Reset { received_at_us } => deliver(Input::MegaReset {
                time_us: received_at_us,
            }),
        });
        let bytes = self.world.receive_from_lidar();
        let scan_drop = &mut self.scan_drop;
        self.lidar.feed(&bytes, now_us, |scan| {
            let dropped = scan_drop
                .as_mut()
                .is_some_and(|(probability, rng)| rng.chance(*probability));
            if !dropped {
                deliver(Input::Scan(scan));
            }
        });
        if now_us >= self.next_imu_us {
            let sample = self.imu.read_sample(now_us)?;
            deliver(Input::Imu(sample));
            self.next_imu_us += IMU_PERIOD_US;
        }
        let robot = &mut self.robot;

        if now_us < self.next_host_tick_us {
            return Ok(false);
        }
        self.next_host_tick_us += HOST_TICK_PERIOD_US;
        control(robot, now_us);
        let output = robot.tick(now_us);
        // The core's references are finite by construction (limited inverse kinematics of a
        // finite twist); a non-finite one is a bug upstream and is not sent.
        if let Ok(bytes) = self
            .mega
            .encode_references(output.wheel_speeds_rad_s, output.solenoid_on)
        {
            self.world.send_to_mega(&bytes);
        }
        self.last_output = Some(output);
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_core::field::geometry::Pose2;
    use ratf_core::kinematics::BodyTwist;

    fn run(twist: BodyTwist, seconds: f64) -> SimulatedRobot {
        let config = Config::default();
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
        let config = Config::default();
        let scenario = Scenario::new(&config);
        let mut sim = SimulatedRobot::new(&config, &scenario, scenario.start_pose).unwrap();
        let mut sampled = Vec::new();
        while sim.now_us() < 500_000 {
            sim.step_observed(
                |_, _| {},
                |input| {
                    if let Input::Wheels(t) = input {
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
