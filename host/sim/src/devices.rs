//! The simulated world as the runtime's devices: what the robot's ports would deliver, as
//! the core's timestamped inputs, and the core's outputs carried back into the world.
//!
//! Per world step (1 ms): bytes that arrived from the Mega go through the core's
//! [`MegaLink`], bytes from the lidar through its [`X4Driver`], and the IMU is read through
//! its driver at 200 Hz on the simulated I2C bus (a lidar stream silent for
//! [`LIDAR_PACKET_SILENCE_US`] reported as `ratf run`'s lidar thread does); then, on the host's own 50 Hz timer
//! (offset from the Mega's tick by [`HOST_TICK_PHASE_US`], as two free-running clocks would
//! be), a [`Input::HostTick`]. The inputs of one step are handed out in that order; the
//! world steps again only when they are all consumed ([`SimDevices::step_complete`]).
//!
//! Bring-up is the robot's: the X4 sends nothing until the core's start command.

use std::collections::VecDeque;

use ratf_core::config::Config;
use ratf_core::drivers::imu::{ImuError, Mpu9255};
use ratf_core::drivers::mega_link::{MegaEvent, MegaLink, MegaLinkConfig};
use ratf_core::drivers::x4::X4Driver;
use ratf_core::drivers::x4::scan::ScanConfig;
use ratf_core::rng::SimRng;
use ratf_core::runtime::{
    DeviceKind, Devices, Input, LIDAR_PACKET_SILENCE_US, LidarCommand, Outputs, PacketWatch,
    Stamped, Timestamp,
};

use crate::faults::MEGA_BOOT_US;
use crate::world::{Scenario, SimImuBus, World};

/// Period of the host's reference timer, µs (50 Hz, the Mega's control rate).
pub const HOST_TICK_PERIOD_US: u64 = 20_000;
/// Offset of the host's timer from the Mega's tick, µs: an arbitrary 7 ms, so the two clocks
/// are not artificially in phase.
pub const HOST_TICK_PHASE_US: u64 = 7_000;
/// IMU read period, µs (200 Hz, the rate the driver configures).
pub const IMU_PERIOD_US: u64 = 5_000;

/// A device's USB cable, as its thread in `ratf run` lives an unplug and replug
/// ([`SimDevices::unplug`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cable {
    In,
    /// Out since `since_us`: the thread tries to reopen the port every
    /// `[link] reconnect_period_ms` from then.
    Out {
        since_us: u64,
    },
    /// Back in; the thread's next try, at `reopen_us`, opens the port.
    Back {
        reopen_us: u64,
    },
}

/// The simulated robot's devices.
#[derive(Debug)]
pub struct SimDevices {
    world: World,
    mega: MegaLink,
    lidar: X4Driver,
    lidar_scan: ScanConfig,
    lidar_watch: PacketWatch,
    mega_cable: Cable,
    /// False from a reopening of the Mega's port until its `r`: as `ratf run`'s thread, the
    /// telemetry before it was sent before the reset and is dropped, and nothing is written.
    mega_synced: bool,
    lidar_cable: Cable,
    reconnect_period_us: u64,
    imu: Mpu9255<SimImuBus>,
    imu_yaw_rad: f64,
    next_host_tick_us: u64,
    next_imu_us: u64,
    pending: VecDeque<Stamped>,
    scan_drop: Option<(f64, SimRng)>,
    wheel_batches: usize,
    lidar_streaming: bool,
    lidar_cut: bool,
    imu_failures: u32,
}

impl SimDevices {
    /// Build the world of `scenario` and the device drivers of `config`.
    pub fn new(config: &Config, scenario: &Scenario) -> Result<Self, ImuError> {
        let world = World::new(config, scenario);
        let lidar_scan = ScanConfig {
            range_min_m: config.lidar.min_range_m,
            range_max_m: config.lidar.max_range_m,
            ..ScanConfig::default()
        };
        let imu = Mpu9255::new(world.imu_bus(), config.robot.imu.driver_config())?;
        Ok(Self {
            mega: MegaLink::new(MegaLinkConfig {
                send_checksums: config.mega.send_checksums,
                baud: config.link.mega_baud,
                telemetry_latency_us: config.mega.telemetry_latency_us,
            }),
            lidar: X4Driver::new(lidar_scan),
            lidar_scan,
            lidar_watch: PacketWatch::new(LIDAR_PACKET_SILENCE_US),
            mega_cable: Cable::In,
            mega_synced: true,
            lidar_cable: Cable::In,
            reconnect_period_us: u64::from(config.link.reconnect_period_ms.max(1)) * 1_000,
            imu,
            imu_yaw_rad: config.robot.imu.yaw_deg.to_radians(),
            next_host_tick_us: HOST_TICK_PHASE_US,
            next_imu_us: IMU_PERIOD_US,
            pending: VecDeque::new(),
            scan_drop: None,
            wheel_batches: 0,
            lidar_streaming: false,
            lidar_cut: false,
            imu_failures: 0,
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

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.world.now_us()
    }

    /// Fault injection: drop each completed lidar scan with probability `probability`
    /// (drawn from `seed`) before it reaches the core, as a USB hiccup would.
    pub fn drop_scans(&mut self, probability: f64, seed: u64) {
        self.scan_drop = Some((probability, SimRng::new(seed).fork("scan-drop")));
    }

    /// Fault injection: the lidar's line carries nothing from now on (`true`), as when the
    /// X4 stops for good while its port stays open; `false` restores it.
    pub fn cut_lidar(&mut self, cut: bool) {
        self.lidar_cut = cut;
    }

    /// Fault injection: `device`'s USB cable comes out now (the Mega or the lidar; nothing
    /// for the others). As `ratf sim --serve-pty --unplug` does it to `ratf run`: its thread
    /// reports the port lost ([`Input::DeviceFault`] with `reconnecting`), nothing passes
    /// either way, the Mega runs on from the battery (its watchdog stops the wheels without
    /// the host's references) and the X4 stops.
    pub fn unplug(&mut self, device: DeviceKind) {
        let now_us = self.now_us();
        let (cable, name) = match device {
            DeviceKind::Mega => (&mut self.mega_cable, "the simulated Mega"),
            DeviceKind::Lidar => (&mut self.lidar_cable, "the simulated X4"),
            DeviceKind::Imu | DeviceKind::Referee => return,
        };
        *cable = Cable::Out { since_us: now_us };
        let fault = Input::DeviceFault {
            device,
            message: format!("{name}'s port: unplugged; reconnecting"),
            reconnecting: true,
        };
        self.pending
            .push_back(Stamped::new(Timestamp::from_us(now_us), fault));
    }

    /// Fault injection: `device`'s cable goes back in now. Its thread opens the port at its
    /// next try (every `[link] reconnect_period_ms` from the unplug) with a fresh driver;
    /// opening the Mega's port resets the board (DTR), which is back [`MEGA_BOOT_US`] later;
    /// the lidar's thread sends the start command again if the core had asked for scans.
    pub fn replug(&mut self, device: DeviceKind) {
        let now_us = self.now_us();
        let period_us = self.reconnect_period_us;
        let cable = match device {
            DeviceKind::Mega => &mut self.mega_cable,
            DeviceKind::Lidar => &mut self.lidar_cable,
            DeviceKind::Imu | DeviceKind::Referee => return,
        };
        if let Cable::Out { since_us } = *cable {
            let tries = (now_us - since_us).div_ceil(period_us).max(1);
            *cable = Cable::Back {
                reopen_us: since_us + tries * period_us,
            };
        }
    }

    /// Ports the threads reopen at `now_us`.
    fn reopen_ports(&mut self, now_us: u64) {
        let due = |cable: Cable| matches!(cable, Cable::Back { reopen_us } if now_us >= reopen_us);
        if due(self.mega_cable) {
            self.mega_cable = Cable::In;
            self.mega_synced = false;
            self.mega.reset();
            self.world.reset_mega(Some(MEGA_BOOT_US));
        }
        if due(self.lidar_cable) {
            self.lidar_cable = Cable::In;
            self.lidar = X4Driver::new(self.lidar_scan);
            self.lidar_watch = PacketWatch::new(LIDAR_PACKET_SILENCE_US);
        }
    }

    /// IMU reads that failed so far (skipped, as the robot's IMU thread does).
    pub fn imu_failures(&self) -> u32 {
        self.imu_failures
    }

    /// True when every input of the last world step has been handed out: the next
    /// [`Self::pop_input`] finds none and the world must [`Self::advance`].
    pub fn step_complete(&self) -> bool {
        self.pending.is_empty()
    }

    /// Telemetry batches handed out so far.
    pub fn wheel_batches(&self) -> usize {
        self.wheel_batches
    }

    /// The true pose when the Mega counted the encoders for the last telemetry batch handed
    /// out: the ground truth the core's odometry refers to, without the telemetry's time in
    /// flight. `None` before the first batch.
    pub fn truth_at_last_telemetry(&self) -> Option<ratf_core::field::geometry::Pose2> {
        self.wheel_batches
            .checked_sub(1)
            .and_then(|i| self.world.tick_poses().get(i).copied())
    }

    /// The next input of the current world step, if any is left.
    pub fn pop_input(&mut self) -> Option<Stamped> {
        let input = self.pending.pop_front()?;
        if matches!(input.input, Input::Wheels(_)) {
            self.wheel_batches += 1;
        }
        Some(input)
    }

    /// Step the world once and queue what the devices delivered in that step.
    pub fn advance(&mut self) -> Result<(), ImuError> {
        self.world.step();
        let now_us = self.world.now_us();
        let time = Timestamp::from_us(now_us);
        self.reopen_ports(now_us);
        let pending = &mut self.pending;
        let mut bytes = self.world.receive_from_mega();
        if self.mega_cable != Cable::In {
            bytes.clear();
        }
        let synced = &mut self.mega_synced;
        self.mega.feed(&bytes, now_us, |event| {
            let input = match event {
                MegaEvent::Telemetry(_) if !*synced => return,
                MegaEvent::Telemetry(telemetry) => Input::Wheels(telemetry),
                MegaEvent::Reset { .. } => {
                    *synced = true;
                    Input::MegaReset
                }
            };
            pending.push_back(Stamped::new(time, input));
        });
        // The X4's motor spins from power-up, but it sends nothing until told to scan.
        let mut bytes = self.world.receive_from_lidar();
        if !self.lidar_streaming || self.lidar_cut || self.lidar_cable != Cable::In {
            bytes.clear();
        }
        let scan_drop = &mut self.scan_drop;
        self.lidar.feed(&bytes, now_us, |scan| {
            let dropped = scan_drop
                .as_mut()
                .is_some_and(|(probability, rng)| rng.chance(*probability));
            if !dropped {
                pending.push_back(Stamped::new(time, Input::Scan(scan)));
            }
        });
        // As `ratf run`'s lidar thread: a stream that stopped is reported long before two
        // revolutions are missed (a lost port is reported as such, not as a silence).
        if self.lidar_cable == Cable::In
            && self
                .lidar_watch
                .fell_silent(self.lidar.last_packet_us(), now_us)
        {
            let fault = Input::DeviceFault {
                device: DeviceKind::Lidar,
                message: self.lidar_watch.message("the simulated X4"),
                reconnecting: true,
            };
            self.pending.push_back(Stamped::new(time, fault));
        }
        if now_us >= self.next_imu_us {
            // A failed read is skipped, as `ratf run`'s IMU thread does: the core just gets
            // no sample.
            match self.imu.read_sample(now_us) {
                Ok(sample) => self.pending.push_back(Stamped::new(
                    time,
                    Input::Imu(sample.rotated_about_z(self.imu_yaw_rad)),
                )),
                Err(_) => self.imu_failures += 1,
            }
            self.next_imu_us += IMU_PERIOD_US;
        }
        if now_us >= self.next_host_tick_us {
            self.next_host_tick_us += HOST_TICK_PERIOD_US;
            self.pending.push_back(Stamped::new(time, Input::HostTick));
        }
        Ok(())
    }

    /// Carry the core's outputs into the world: the wheel references (or the open-loop PWM)
    /// and the magnet to the Mega as a `G H I J L U` (or `K K K K L`) batch, and the lidar's
    /// start command (its data flows from the next step on).
    pub fn apply_outputs(&mut self, outputs: &Outputs) {
        if outputs.lidar == Some(LidarCommand::StartScan) {
            self.lidar_streaming = true;
        }
        // The core's references are finite by construction (limited inverse kinematics of a
        // finite twist); a non-finite one is a bug upstream and is not sent.
        if let Some(wheels) = outputs.wheels
            && self.mega_cable == Cable::In
            && self.mega_synced
            && let Ok(bytes) = wheels.encode(&mut self.mega)
        {
            self.world.send_to_mega(&bytes);
        }
    }
}

impl Devices for SimDevices {
    type Error = ImuError;

    fn next_input(&mut self) -> Result<Option<Stamped>, ImuError> {
        loop {
            if let Some(input) = self.pop_input() {
                return Ok(Some(input));
            }
            self.advance()?;
        }
    }

    fn apply(&mut self, _input: &Stamped, outputs: &Outputs) -> Result<(), ImuError> {
        self.apply_outputs(outputs);
        Ok(())
    }

    fn ground_truth(&self) -> Option<ratf_core::field::geometry::Pose2> {
        Some(self.world.body().pose)
    }
}
