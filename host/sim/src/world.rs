//! The simulated world: the robot's body, motors, Mega, lidar, IMU and the parts on the floor,
//! advanced in fixed steps of simulated time.
//!
//! The host talks to it only through the devices' own interfaces: bytes on the Mega's serial
//! line ([`World::send_to_mega`], [`World::receive_from_mega`]), bytes from the lidar
//! ([`World::receive_from_lidar`]) and the IMU's I2C bus ([`World::imu_bus`]). Ground truth
//! ([`World::body`], [`World::shop`]) is for the simulator's own reports and the benchmarks,
//! never for the robot's software.
//!
//! One step (`sim.time_step_us`, 1 ms by default):
//!
//! 1. bytes that finished arriving on the host → Mega line go to the Mega's logic
//!    ([`ratf_protocol::mcu::Mcu`]), and the solenoid follows it at once;
//! 2. on the Mega's 20 ms tick: encoder counts since the previous tick (from the wheels'
//!    true angles, floored to whole ticks) and the switch go in; PWMs come out and the
//!    telemetry batch starts down the Mega → host line after the firmware's measured
//!    latency (`mega.telemetry_latency_us`);
//! 3. each motor gets PWM/255 of the battery voltage; the body moves with the traction limit;
//!    contact keeps it (and the part it carries) out of walls, dividers, beacon poles and
//!    parts, and pushes the free parts it runs into (see [`World::footprint`], `contact`);
//! 4. the lidar takes the samples due in the step; the IMU sees the body's yaw rate;
//! 5. the magnet and the machines act on the parts; with contact, a part the magnet takes up
//!    turns and moves flat onto its face only as far as what stands beside it lets it.
//!
//! Contact is a rigid-body projection, no dynamics: the robot's true outline (the truth's
//! footprint, off the wheels' centre by its offset) is moved out of what it entered along the
//! minimum translation and loses its velocity into it, while the wheels turn on and the
//! encoders count (slip). A part the robot (or the part it carries) runs into is pushed along,
//! without turning, until a wall, a pole or another part stops it; then the robot stops too.
//! Each new contact of the robot or its carried part is a [`Collision`], except the carried
//! part touching the slot it is being placed in or picked from (the magnet presses it there
//! by design), and a part the magnet has just let go of, until the body has moved clear of
//! it (it stood against the magnet's face, which stands proud of the body). The `ideal`
//! world keeps today's simulator for regression: no contact, the body passes through and
//! each overlap deeper than 2 mm counts as a collision; its parts stand exactly centred, also
//! where the robot released them.

use std::cell::RefCell;
use std::rc::Rc;

use ratf_protocol::mcu::{Actuation, Mcu, TickInputs};

use crate::body::{Body, Ground, TractionLimits};
use crate::contact::{Shape, push_out};
use crate::imu::{SimErrors, SimMotion, SimMpu9255};
use crate::lidar::{LidarScene, SimLidar, Solid};
use crate::motor::{Battery, ELECTRONICS_CURRENT_A, Motor};
use crate::parts::{Gripper, PartEvent, PartPlace, Shop};
use crate::serial::SerialLine;
use crate::truth::WorldTruth;
use ratf_core::config::{Config, MotorConfig, WorldProfile};
use ratf_core::field::Field;
use ratf_core::field::OrientedRect;
use ratf_core::field::PartColor;
use ratf_core::field::WaypointId;
use ratf_core::field::geometry::{Pose2, Vec2, wrap_angle};
use ratf_core::field::{PART_DEPTH_M, PART_WIDTH_M};
use ratf_core::kinematics::Mecanum;
use ratf_core::rng::SimRng;

/// What is on the floor at the start and how the world behaves, beyond the robot's config.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// The robot's true pose at the start.
    pub start_pose: Pose2,
    /// Parts in the incoming slots 0..3 (`None` = empty).
    pub incoming: [Option<PartColor>; 4],
    /// Machine processing time, µs.
    pub machine_delay_us: u64,
    /// Machine A also turns green into blue (round 2, where greens may use either machine).
    pub green_to_blue_at_a: bool,
    /// Things around the field the lidar may see (people, tables).
    pub clutter: Vec<Solid>,
    /// The simulated gyro's z bias, rad/s. 0.005: assumption, a typical MEMS turn-on bias
    /// (the original measured 0.13 rad/s on its own chip, original-system.md §3.3, but that
    /// was before its ×0.25 fudge; the driver estimates the bias at start-up anyway).
    pub gyro_bias_rad_s: f64,
}

impl Scenario {
    /// The robot at the field's start pose, no parts, the clutter of `config.sim`.
    pub fn new(config: &Config) -> Self {
        let clutter = config.sim.clutter.iter().map(Solid::from).collect();
        Self {
            start_pose: Field::competition().start_pose(),
            incoming: [None; 4],
            machine_delay_us: 0,
            green_to_blue_at_a: false,
            clutter,
            gyro_bias_rad_s: 0.005,
        }
    }
}

/// The simulated IMU's I2C bus, shared by the world (which sets what the chip measures) and
/// the host's driver (which reads it).
#[derive(Clone, Debug)]
pub struct SimImuBus(Rc<RefCell<SimMpu9255>>);

impl embedded_hal::i2c::ErrorType for SimImuBus {
    type Error = <SimMpu9255 as embedded_hal::i2c::ErrorType>::Error;
}

impl embedded_hal::i2c::I2c for SimImuBus {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [embedded_hal::i2c::Operation<'_>],
    ) -> Result<(), Self::Error> {
        self.0.borrow_mut().transaction(address, operations)
    }
}

/// A collision: the robot (or the part it carries) ran into something.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Collision {
    /// Simulated time, µs.
    pub time_us: u64,
    /// What was hit.
    pub with: Obstruction,
    /// The robot's true pose then.
    pub pose: Pose2,
}

/// Something the robot can run into.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Obstruction {
    /// A wall or divider (index into `Field::obstacles()`).
    Wall(usize),
    /// A beacon pole (index B0..B3).
    Beacon(usize),
    /// A part not held by the magnet (index into the shop's parts).
    Part(usize),
}

/// Counters over the run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WorldStats {
    /// Steps in which the wheels slipped.
    pub slip_steps: u64,
    /// Largest slip speed seen, m/s.
    pub max_slip_speed_m_s: f64,
    /// Collisions (each new contact counts once, see [`Collision`]).
    pub collisions: u32,
    /// Steps in which contact pushed the robot back out of something.
    pub contact_steps: u64,
    /// Mega control ticks run.
    pub mega_ticks: u64,
    /// Bytes the host sent to the Mega that found the line's buffer full and were dropped
    /// (the host → Mega line holds [`HOST_TX_CAPACITY_BYTES`]).
    pub to_mega_bytes_dropped: u64,
    /// Telemetry bytes that did not fit the Mega's transmit ring and were dropped; the Mega
    /// also reports them on its `x` frame, as the firmware does.
    pub from_mega_bytes_dropped: u64,
    /// Lidar bytes that found the X4's buffer full and were dropped (the host's parser then
    /// counts the damaged packets).
    pub from_lidar_bytes_dropped: u64,
}

/// The host's transmit buffer towards the Mega, bytes: 4 KiB, the order of a serial write
/// buffer on the host (assumption), 75 reference batches. Bytes beyond it (a robot over
/// `ratf sim --serve-pty` writing faster than 115 200 baud) are dropped and counted.
pub const HOST_TX_CAPACITY_BYTES: usize = 4096;

/// The Mega's transmit ring, bytes: `firmware-mega` `hw::usart::TX_CAPACITY`. Telemetry
/// that does not fit is dropped and counted, as on the board.
pub const MEGA_TX_CAPACITY_BYTES: usize = 256;

/// The simulated X4's transmit buffer, bytes: 4 KiB, two and a half revolutions at 7 Hz
/// (assumption: the X4's own buffer is not documented). Its stream fits its line whenever
/// the configuration validates (`[lidar]`), so this holds only under a fault.
pub const LIDAR_TX_CAPACITY_BYTES: usize = 4096;

/// The simulated world: see the module documentation.
#[derive(Debug)]
pub struct World {
    /// The world's own constants (the truth applied to the robot's configuration).
    config: Config,
    field: Field,
    now_ns: u64,
    step_ns: u64,
    body: Body,
    motors: [Motor; 4],
    battery: Battery,
    mecanum: Mecanum,
    limits: TractionLimits,
    mcu: Mcu,
    actuation: Actuation,
    next_tick_ns: u64,
    ticks_at_last_tick: [i64; 4],
    to_mega: SerialLine,
    from_mega: SerialLine,
    from_lidar: SerialLine,
    lidar: SimLidar,
    scene: LidarScene,
    imu: Rc<RefCell<SimMpu9255>>,
    shop: Shop,
    obstacles: Vec<OrientedRect>,
    /// The robot frame's pose of the body's outline (its centre off the wheels' centre).
    body_offset: Pose2,
    /// What the robot (or its carried part) is in contact with (overlaps, in the ideal world).
    in_contact: Vec<Obstruction>,
    /// Parts the magnet let go of that still stand within its face's reach of the body
    /// (see [`World::forget_released_parts_left_behind`]).
    released_at_face: Vec<usize>,
    /// Contact physics on: every world but `ideal`, which stays today's for regression.
    contact: bool,
    /// The walls, dividers and beacon poles as contact shapes (they never move).
    fixed_solids: Vec<(Shape, Obstruction)>,
    collisions: Vec<Collision>,
    part_events: Vec<(u64, PartEvent)>,
    tick_poses: Vec<Pose2>,
    grip: f64,
    stats: WorldStats,
    truth: WorldTruth,
    /// Fault injection: the Mega is off until this time, ns (`u64::MAX`: for good).
    mega_down_until_ns: Option<u64>,
}

impl World {
    /// A world at time 0, the Mega just booted (its reset frame already on the line).
    pub fn new(config: &Config, scenario: &Scenario) -> Self {
        // The robot's beliefs are `config`; the world is built from its own truth.
        let truth = WorldTruth::draw(config, scenario.gyro_bias_rad_s);
        let world = truth.true_config(config);
        let field = truth.true_field(config);
        let rng = SimRng::new(config.sim.seed);
        let mut mcu = Mcu::new(config.mega.to_mcu_config(
            config.robot.ticks_per_wheel_rev,
            config.motor.battery_voltage_v,
        ));
        let mut from_mega =
            SerialLine::with_capacity(config.link.mega_baud, MEGA_TX_CAPACITY_BYTES)
                .with_usb(truth.mega_usb, rng.fork("usb-from-mega"));
        from_mega.send(mcu.boot().as_bytes(), 0);
        let mut imu = SimMpu9255::new(rng.fork("imu").next_u64());
        let imu_rate_hz = 200.0;
        imu.set_errors(SimErrors {
            gyro_bias_rad_s: [0.0, 0.0, truth.gyro_bias_rad_s],
            gyro_noise_std_rad_s: config.robot.imu.gyro_noise_density_rad_s_sqrt_hz
                * (imu_rate_hz / 2.0f64).sqrt(),
            accel_noise_std_m_s2: 0.02,
        });
        let body_offset = Pose2::new(truth.body_offset_m[0], truth.body_offset_m[1], 0.0);
        let gripper = Gripper::new(world.robot.footprint_length_m / 2.0 + body_offset.x);
        let mut shop = Shop::new(
            &field,
            scenario.incoming,
            scenario.machine_delay_us,
            scenario.green_to_blue_at_a,
            gripper,
        );
        shop.seat_incoming(&truth.part_seats);
        shop.set_standing_where_released(truth.profile != WorldProfile::Ideal);
        let mut built = Self {
            step_ns: u64::from(config.sim.time_step_us) * 1000,
            body: Body::at_rest(scenario.start_pose),
            motors: std::array::from_fn(|k| {
                Motor::new(&MotorConfig {
                    gain_rad_s_per_v: world.motor.gain_rad_s_per_v * truth.motor_gain_scale[k],
                    ..world.motor.clone()
                })
                .with_load(truth.wheel_load_torque_nm[k])
            }),
            battery: Battery::new(
                world.motor.battery_voltage_v,
                truth.battery_resistance_ohm,
                truth.battery_drop_v_per_ah,
            ),
            mecanum: Mecanum::rigid(&world.robot),
            limits: TractionLimits::new(&world.traction, &world.robot),
            mcu,
            actuation: Actuation::default(),
            next_tick_ns: u64::from(config.mega.control_period_us) * 1000,
            ticks_at_last_tick: [0; 4],
            to_mega: SerialLine::with_capacity(config.link.mega_baud, HOST_TX_CAPACITY_BYTES)
                .with_usb(truth.host_usb, rng.fork("usb-to-mega")),
            from_mega,
            from_lidar: SerialLine::with_capacity(config.link.lidar_baud, LIDAR_TX_CAPACITY_BYTES)
                .with_usb(truth.lidar_usb, rng.fork("usb-from-lidar")),
            lidar: {
                let lidar = SimLidar::new(&world.lidar, &world.robot, rng.fork("lidar"))
                    .with_range_errors(
                        truth.lidar_range_scale,
                        truth.lidar_range_offset_m,
                        truth.lidar_noise_per_m,
                    );
                match truth.lidar_rotation() {
                    Some(rotation) => lidar.with_rotation(rotation),
                    None => lidar,
                }
            },
            scene: LidarScene::new(&field, &scenario.clutter, world.robot.lidar_height_m),
            imu: Rc::new(RefCell::new(imu)),
            shop,
            obstacles: field
                .obstacles()
                .iter()
                .map(|o| OrientedRect::from_rect(o.rect))
                .collect(),
            body_offset,
            in_contact: Vec::new(),
            released_at_face: Vec::new(),
            contact: truth.profile != WorldProfile::Ideal,
            fixed_solids: fixed_solids(&field),
            collisions: Vec::new(),
            part_events: Vec::new(),
            tick_poses: Vec::new(),
            grip: 1.0,
            stats: WorldStats::default(),
            now_ns: 0,
            field,
            config: world,
            truth,
            mega_down_until_ns: None,
        };
        // A part drawn into a divider or the wall stands clear of it.
        for part in 0..built.shop.parts().len() {
            built.settle_part(part);
        }
        if built.contact {
            // The team sets the robot down clear of everything: a body whose true outline
            // overlaps a pole at the scenario's start pose stands just clear of it (a few
            // millimetres off the pose the robot believes), no collision. It stands in
            // contact with the pole from then on, until it moves off it.
            built.resolve_contacts(0);
            built.collisions.clear();
            built.stats = WorldStats::default();
        }
        built
    }

    /// The world's truth (what the robot's configuration gets wrong).
    pub fn truth(&self) -> &WorldTruth {
        &self.truth
    }

    /// Ground truth: the battery (its voltage now and the charge drawn).
    pub fn battery(&self) -> &Battery {
        &self.battery
    }

    /// Ground truth: the lidar's head (its true rate now).
    pub fn lidar(&self) -> &SimLidar {
        &self.lidar
    }

    /// Simulated time, ns.
    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.now_ns / 1000
    }

    /// The floor.
    pub fn field(&self) -> &Field {
        &self.field
    }

    /// Ground truth: the body.
    pub fn body(&self) -> &Body {
        &self.body
    }

    /// Ground truth: the parts and machines.
    pub fn shop(&self) -> &Shop {
        &self.shop
    }

    /// The Mega's current outputs.
    pub fn actuation(&self) -> Actuation {
        self.actuation
    }

    /// Counters.
    pub fn stats(&self) -> WorldStats {
        WorldStats {
            to_mega_bytes_dropped: self.to_mega.bytes_dropped(),
            from_mega_bytes_dropped: self.from_mega.bytes_dropped(),
            from_lidar_bytes_dropped: self.from_lidar.bytes_dropped(),
            ..self.stats
        }
    }

    /// Every collision so far.
    pub fn collisions(&self) -> &[Collision] {
        &self.collisions
    }

    /// Part events so far, with their times (µs).
    pub fn part_events(&self) -> &[(u64, PartEvent)] {
        &self.part_events
    }

    /// The true pose at each Mega control tick so far: entry n (0-based) is the pose when the
    /// Mega counted the encoders for its n-th telemetry batch, the ground truth that batch's
    /// odometry should match.
    pub fn tick_poses(&self) -> &[Pose2] {
        &self.tick_poses
    }

    /// Fault injection: the fraction of the wheels' motion the floor passes on to the body
    /// from now on (1 = normal; e.g. 0.7 for a slip burst, see `Body::step`).
    pub fn set_grip(&mut self, grip: f64) {
        self.grip = grip.clamp(0.0, 1.0);
    }

    /// Turn contact off (or back on, in a world that has it): the body passes through walls,
    /// poles and parts, and overlaps are counted as in the ideal world. For drives scripted
    /// on the true pose that are not contact-aware (the localisation bench's tour docks
    /// heading first and cuts corners): there a stuck body would measure the script, not the
    /// estimator. The world's other draws stay as they are.
    pub fn set_contact(&mut self, on: bool) {
        self.contact = on && self.truth.profile != WorldProfile::Ideal;
        self.in_contact.clear();
        self.released_at_face.clear();
    }

    /// Fault injection: the Mega resets now and is back `boot_us` later (its bootloader's
    /// wait), sending its `r` frame and counting from zero; `None`: it is gone for good (its
    /// USB cable out, the board dead). While it is off the motors get no PWM and the magnet
    /// no current, and what the host sends is lost.
    pub fn reset_mega(&mut self, boot_us: Option<u64>) {
        self.mega_down_until_ns = Some(boot_us.map_or(u64::MAX, |us| self.now_ns + us * 1000));
        self.actuation = Actuation::default();
    }

    /// True while the Mega is off ([`Self::reset_mega`]).
    pub fn mega_is_down(&mut self) -> bool {
        match self.mega_down_until_ns {
            Some(until) if self.now_ns >= until => {
                // Booted: a fresh Mega with the same settings, counting from the wheels'
                // angles now.
                self.mega_down_until_ns = None;
                self.mcu = Mcu::new(*self.mcu.config());
                self.from_mega.send(self.mcu.boot().as_bytes(), self.now_ns);
                let ticks_per_rad = self.config.robot.ticks_per_wheel_rev / std::f64::consts::TAU;
                for (k, angle) in self.body.wheel_angles_rad.iter().enumerate() {
                    self.ticks_at_last_tick[k] = (angle * ticks_per_rad).floor() as i64;
                }
                false
            }
            Some(_) => true,
            None => false,
        }
    }

    /// Fault injection: `bytes` of line noise arrive on the Mega → host line now, into the
    /// host's decoder among the telemetry (dropped and counted beyond the Mega's ring, as
    /// any burst is).
    pub fn inject_from_mega(&mut self, bytes: &[u8]) {
        self.from_mega.send(bytes, self.now_ns);
    }

    /// Fault injection: every IMU transaction fails from now on (`false` heals the bus).
    pub fn fail_imu(&mut self, failing: bool) {
        self.imu.borrow_mut().fail_with(failing.then_some(
            embedded_hal::i2c::ErrorKind::NoAcknowledge(
                embedded_hal::i2c::NoAcknowledgeSource::Address,
            ),
        ));
    }

    /// Fault injection: part `part` lands on the floor at `pose` (knocked out of its slot, or
    /// slipped off the magnet). In a world with contact it comes to rest out of the walls,
    /// dividers, poles and other parts it would overlap there: a part that slips off as the
    /// robot backs out of a slot lands against the slot's back wall, not inside it.
    pub fn put_part_on_floor(&mut self, part: usize, pose: Pose2) {
        self.shop.put_on_floor(part, pose);
        if self.contact {
            self.settle_part(part);
        }
    }

    /// Fault injection: replace what stands around the field (what the lidar can see).
    pub fn set_clutter(&mut self, clutter: &[Solid]) {
        let height = self.config.robot.lidar_height_m;
        self.scene = LidarScene::new(&self.field, clutter, height);
    }

    /// What the lidar can see now (the field and the clutter, a walking person included).
    pub fn lidar_scene(&self) -> &LidarScene {
        &self.scene
    }

    /// The lidar, to inject faults (e.g. switch it off for a while).
    pub fn lidar_mut(&mut self) -> &mut SimLidar {
        &mut self.lidar
    }

    /// The IMU's bus, for the host's driver.
    pub fn imu_bus(&self) -> SimImuBus {
        SimImuBus(Rc::clone(&self.imu))
    }

    /// Queue bytes from the host to the Mega, starting now. Bytes beyond the host's
    /// [`HOST_TX_CAPACITY_BYTES`] not yet sent are dropped and counted
    /// ([`WorldStats::to_mega_bytes_dropped`]).
    pub fn send_to_mega(&mut self, bytes: &[u8]) {
        self.to_mega.send(bytes, self.now_ns);
    }

    /// Bytes from the Mega that have fully arrived by now.
    pub fn receive_from_mega(&mut self) -> Vec<u8> {
        self.from_mega.receive(self.now_ns)
    }

    /// Bytes from the lidar that have fully arrived by now.
    pub fn receive_from_lidar(&mut self) -> Vec<u8> {
        self.from_lidar.receive(self.now_ns)
    }

    /// Advance one time step.
    pub fn step(&mut self) {
        let from_ns = self.now_ns;
        let from_pose = self.body.pose;
        self.now_ns += self.step_ns;
        let now_us = self.now_us();
        // The Mega's clock is a wrapping 32-bit microsecond counter.
        let mega_now_us = now_us as u32;

        let received = self.to_mega.receive(self.now_ns);
        if self.mega_is_down() {
            // Off: the motor shield gets no PWM and the magnet no current; bytes are lost.
            self.actuation = Actuation::default();
        } else if !received.is_empty() {
            self.mcu.receive(&received, mega_now_us);
            self.actuation.solenoid_on = self.mcu.solenoid_on();
        }
        if self.mega_is_down() {
            self.next_tick_ns = self.now_ns + u64::from(self.config.mega.control_period_us) * 1000;
        } else if self.now_ns >= self.next_tick_ns {
            self.mega_tick(mega_now_us);
            self.next_tick_ns += u64::from(self.config.mega.control_period_us) * 1000;
        }

        let dt_s = self.step_ns as f64 * 1e-9;
        let pwm_max = f64::from(self.config.mega.pwm_max);
        let volts_per_pwm = self.battery.voltage_v() / pwm_max;
        for (motor, &pwm) in self.motors.iter_mut().zip(&self.actuation.pwm) {
            motor.step(f64::from(pwm) * volts_per_pwm, dt_s);
        }
        if !self.battery.is_stiff() {
            // The bridges pass each motor's current at its PWM duty.
            let motors_a: f64 = self
                .motors
                .iter()
                .zip(&self.actuation.pwm)
                .map(|(m, &pwm)| m.current_a() * f64::from(pwm).abs() / pwm_max)
                .sum();
            self.battery.draw(ELECTRONICS_CURRENT_A + motors_a, dt_s);
        }
        let wheel_speeds = self.motors.each_ref().map(|m| m.speed_rad_s());
        let ground = Ground {
            wheel_radius_spread: self.truth.wheel_radius_spread(),
            lateral_factor: self.truth.lateral_factor,
        };
        let slip = self.body.step(
            wheel_speeds,
            &self.mecanum,
            &self.limits,
            &ground,
            self.grip,
            dt_s,
        );
        if self.contact {
            self.resolve_contacts(now_us);
        }
        if slip.slipped || self.grip < 1.0 {
            self.stats.slip_steps += 1;
        }
        self.stats.max_slip_speed_m_s = self.stats.max_slip_speed_m_s.max(slip.slip_speed_m_s);

        self.lidar.advance(
            from_ns,
            from_pose,
            self.now_ns,
            self.body.pose,
            &self.scene,
            &mut self.from_lidar,
        );
        self.imu.borrow_mut().set_motion(SimMotion {
            rate_rad_s: [
                0.0,
                0.0,
                self.body.twist.omega_rad_s * self.truth.gyro_scale,
            ],
            ..SimMotion::default()
        });

        // Where the part the magnet may take up stands before it does.
        let before_grip = (self.contact && self.shop.carried().is_none())
            .then(|| self.shop.switch_contact(self.body.pose))
            .flatten()
            .map(|part| (part, self.shop.footprint(part, self.body.pose).pose));
        for event in self
            .shop
            .step(now_us, self.body.pose, self.actuation.solenoid_on)
        {
            if let (PartEvent::Picked { part, .. }, Some((found, stood))) = (event, before_grip)
                && part == found
            {
                self.pull_flat_as_far_as_free(part, stood);
            }
            if let PartEvent::Placed { part, .. } | PartEvent::Dropped { part } = event
                && self.contact
            {
                self.released_at_face.push(part);
            }
            self.part_events.push((now_us, event));
        }
        if !self.contact {
            self.check_collisions(now_us);
        }
    }

    fn mega_tick(&mut self, mega_now_us: u32) {
        let ticks_per_rad = self.config.robot.ticks_per_wheel_rev / std::f64::consts::TAU;
        let mut deltas = [0i16; 4];
        for (k, angle) in self.body.wheel_angles_rad.iter().enumerate() {
            let ticks = (angle * ticks_per_rad).floor() as i64;
            let delta = ticks - self.ticks_at_last_tick[k];
            deltas[k] = delta.clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16;
            self.ticks_at_last_tick[k] = ticks;
        }
        let inputs = TickInputs {
            encoder_deltas: deltas,
            switch_pressed: self.shop.switch_contact(self.body.pose).is_some(),
            // The firmware's count is a wrapping byte.
            serial_bytes_dropped: self.from_mega.bytes_dropped() as u8,
            ..TickInputs::default()
        };
        self.tick_poses.push(self.body.pose);
        let out = self.mcu.control_tick(mega_now_us, &inputs);
        self.actuation = out.actuation;
        // The firmware's measured delay from its tick to the first telemetry byte.
        let latency_ns = u64::from(self.config.mega.telemetry_latency_us) * 1000;
        self.from_mega
            .send(out.telemetry.as_bytes(), self.now_ns + latency_ns);
        self.stats.mega_ticks += 1;
    }

    /// The robot's true outline at its true pose (the truth's length, width and offset).
    pub fn footprint(&self) -> OrientedRect {
        let r = &self.config.robot;
        OrientedRect::new(
            self.body.pose.compose(self.body_offset),
            r.footprint_length_m,
            r.footprint_width_m,
        )
    }

    /// The picks the parts' places crowd: (slot, part) for each part not held that the
    /// robot's true outline, grown by `margin_m` on every side, would overlap as it reaches
    /// the part in `slot` — square on the slot's centre line (the robot cannot see where a
    /// part stands across its slot), its magnet's face on the part's nearest point. A
    /// neighbour standing out of its slot further than the body's front reaches there
    /// (margin 0) is touched by any robot of this outline picking that slot square; the harsh
    /// world draws such places (parts up to 15 mm off the back wall and 8° turned,
    /// real-world-errors.md §9), and so does a part knocked out of its slot onto the floor
    /// (the fault bench's knocked part: 10–30 mm out, up to 8° turned). Taken where the parts
    /// stand now.
    pub fn crowded_picks(&self, margin_m: f64) -> Vec<(WaypointId, usize)> {
        let parts = self.shop.parts();
        let footprint = |part: usize| self.shop.footprint(part, self.body.pose);
        let standing: Vec<(usize, WaypointId, OrientedRect)> = (0..parts.len())
            .filter_map(|part| match parts[part].place {
                PartPlace::Slot(slot) => Some((part, slot, footprint(part))),
                _ => None,
            })
            .collect();
        let not_held: Vec<(usize, OrientedRect)> = (0..parts.len())
            .filter(|&part| !matches!(parts[part].place, PartPlace::Carried(_)))
            .map(|part| (part, footprint(part)))
            .collect();
        let magnet_m = self.shop.gripper().magnet_m;
        let r = &self.config.robot;
        let mut crowded = Vec::new();
        for &(target, slot_id, rect) in &standing {
            let Some(slot) = self.field.slot_for_waypoint(slot_id) else {
                continue;
            };
            let line = slot.pick_pose;
            let ahead = Vec2::from_angle(line.yaw_rad);
            let nearest = rect
                .corners()
                .into_iter()
                .map(|c| (c - line.position()).dot(ahead))
                .fold(f64::INFINITY, f64::min);
            let at = line.position() + ahead * (nearest - magnet_m);
            let robot = Pose2::new(at.x, at.y, line.yaw_rad);
            let body = OrientedRect::new(
                robot.compose(self.body_offset),
                r.footprint_length_m + 2.0 * margin_m,
                r.footprint_width_m + 2.0 * margin_m,
            );
            crowded.extend(
                not_held
                    .iter()
                    .filter(|&&(other, other_rect)| {
                        other != target && push_out(&body, &Shape::Rect(other_rect)).is_some()
                    })
                    .map(|&(other, _)| (slot_id, other)),
            );
        }
        crowded
    }

    /// Gap (m) within which a contact lasts: a robot pressed against a wall, whose controller
    /// backs off and pushes again, stays in the same contact (one collision) until it moves
    /// this far away. 2 mm: an assumption, well below anything a referee would see.
    const CONTACT_TOLERANCE_M: f64 = 0.002;

    /// Rounds of projection per step: a part pushed against a wall pushes back on the
    /// robot, which may then touch something else. Four: more than a corner needs.
    const CONTACT_ROUNDS: usize = 4;

    /// The ideal world's collisions (today's world, kept for regression): no contact, the
    /// body passes through; each new overlap deeper than the tolerance counts once.
    fn check_collisions(&mut self, now_us: u64) {
        let robot = self.footprint();
        let carried = self.shop.carried();
        let mut bodies = vec![robot];
        if let Some(part) = carried {
            // A carried part inside a slot is being picked or placed: it rests against that
            // slot's wall and dividers by design (no contact physics holds it back), so only
            // the robot's body counts there.
            let footprint = self.shop.footprint(part, self.body.pose);
            if self.shop.slot_at(footprint.pose).is_none() {
                bodies.push(footprint);
            }
        }
        let mut now_overlapping = Vec::new();
        for (i, wall) in self.obstacles.iter().enumerate() {
            if bodies
                .iter()
                .any(|b| b.penetrates(wall, Self::CONTACT_TOLERANCE_M))
            {
                now_overlapping.push(Obstruction::Wall(i));
            }
        }
        for beacon in self.field.beacons() {
            if bodies.iter().any(|b| {
                circle_overlaps(
                    b,
                    beacon.circle.center,
                    beacon.circle.radius_m - Self::CONTACT_TOLERANCE_M,
                )
            }) {
                now_overlapping.push(Obstruction::Beacon(beacon.index));
            }
        }
        for part in 0..self.shop.parts().len() {
            if Some(part) == carried {
                continue;
            }
            let rect = self.shop.footprint(part, self.body.pose);
            if bodies
                .iter()
                .any(|b| b.penetrates(&rect, Self::CONTACT_TOLERANCE_M))
            {
                now_overlapping.push(Obstruction::Part(part));
            }
        }
        for &with in &now_overlapping {
            if !self.in_contact.contains(&with) {
                self.collisions.push(Collision {
                    time_us: now_us,
                    with,
                    pose: self.body.pose,
                });
                self.stats.collisions += 1;
            }
        }
        self.in_contact = now_overlapping;
    }

    /// The robot's solids: its body, and the part it carries. `true` for the carried part.
    fn robot_solids(&self) -> impl Iterator<Item = (OrientedRect, bool)> + use<> {
        let carried = self
            .shop
            .carried()
            .map(|part| (self.shop.footprint(part, self.body.pose), true));
        std::iter::once((self.footprint(), false)).chain(carried)
    }

    /// What stands on the floor: walls and dividers, beacon poles, and the parts not carried.
    fn floor_solids(&self) -> Vec<(Shape, Obstruction)> {
        let carried = self.shop.carried();
        let parts = (0..self.shop.parts().len())
            .filter(|&part| Some(part) != carried)
            .map(|part| {
                (
                    Shape::Rect(self.shop.footprint(part, self.body.pose)),
                    Obstruction::Part(part),
                )
            });
        self.fixed_solids.iter().copied().chain(parts).collect()
    }

    /// Push standing part `part` out of the walls, the poles and the other parts.
    fn settle_part(&mut self, part: usize) {
        if self.shop.carried() == Some(part) {
            return;
        }
        for _ in 0..Self::CONTACT_ROUNDS {
            let rect = self.shop.footprint(part, self.body.pose);
            let push = self
                .floor_solids()
                .iter()
                .filter(|(_, what)| *what != Obstruction::Part(part))
                .find_map(|(shape, _)| push_out(&rect, shape));
            match push {
                Some(by) => self.shop.push(part, by),
                None => break,
            }
        }
    }

    /// Contact after the body's step: the robot pushes the free parts it entered (which stop
    /// at walls, poles and other parts), then is pushed out of everything it still
    /// overlaps. New contacts are collisions (see the module documentation).
    fn resolve_contacts(&mut self, now_us: u64) {
        let mut touched: Vec<Obstruction> = Vec::new();
        let mut pushed_back = false;
        let carried = self.shop.carried();
        for _ in 0..Self::CONTACT_ROUNDS {
            for part in 0..self.shop.parts().len() {
                if Some(part) == carried {
                    continue;
                }
                for (solid, is_carried) in self.robot_solids() {
                    let rect = self.shop.footprint(part, self.body.pose);
                    if let Some(by) = push_out(&rect, &Shape::Rect(solid)) {
                        self.shop.push(part, by);
                        self.note_contact(&mut touched, Obstruction::Part(part), is_carried);
                        self.settle_part(part);
                    }
                }
            }
            let mut moved = false;
            for (shape, what) in self.floor_solids() {
                for (solid, is_carried) in self.robot_solids() {
                    if let Some(by) = push_out(&solid, &shape) {
                        self.body.push(by);
                        moved = true;
                        self.note_contact(&mut touched, what, is_carried);
                    }
                }
            }
            pushed_back |= moved;
            if !moved {
                break;
            }
        }
        if pushed_back {
            self.stats.contact_steps += 1;
        }
        self.forget_released_parts_left_behind();
        // A contact lasts while the robot stays within the tolerance of it.
        let lasting: Vec<Obstruction> = if self.in_contact.is_empty() {
            Vec::new()
        } else {
            let near = self.robot_solids_inflated(Self::CONTACT_TOLERANCE_M);
            self.floor_solids()
                .into_iter()
                .filter(|(shape, what)| {
                    self.in_contact.contains(what)
                        && !touched.contains(what)
                        && near.iter().any(|r| push_out(r, shape).is_some())
                })
                .map(|(_, what)| what)
                .collect()
        };
        for &with in &touched {
            let held_until_now = matches!(with, Obstruction::Part(part)
                if self.released_at_face.contains(&part));
            if !self.in_contact.contains(&with) && !held_until_now {
                self.collisions.push(Collision {
                    time_us: now_us,
                    with,
                    pose: self.body.pose,
                });
                self.stats.collisions += 1;
            }
        }
        touched.extend(lasting);
        self.in_contact = touched;
    }

    /// Steps of the search for how far the magnet pulls a part flat: 2⁻¹² of the way.
    const FLATTEN_STEPS: usize = 12;

    /// The magnet pulls the plate of part `part`, which stood at `stood`, flat against its
    /// face ([`Shop::step`] puts it there at once): here it moves and turns only as far along
    /// that way as the walls, the poles and the other parts let it, and stays there, held as
    /// far as it got. Without this the part was put flat through a divider or a neighbour it
    /// stood against (a part fallen off the magnet and lying turned beside a slot), and the
    /// next step's contact pushed the robot off it as if the robot had driven into it. The
    /// walls of the slot the part stands in do not stop it: the magnet presses a part there
    /// by design, and [`Self::note_contact`] does not count those.
    fn pull_flat_as_far_as_free(&mut self, part: usize, stood: Pose2) {
        let robot = self.body.pose;
        let Some(flat) = self.shop.held_at(part) else {
            return;
        };
        let found = robot.relative(stood);
        let at = |t: f64| {
            Pose2::new(
                found.x + (flat.x - found.x) * t,
                found.y + (flat.y - found.y) * t,
                found.yaw_rad + wrap_angle(flat.yaw_rad - found.yaw_rad) * t,
            )
        };
        let solids = self.floor_solids();
        let is_free = |local: Pose2| {
            let world = robot.compose(local);
            let in_its_slot = self.shop.slot_at(world).is_some();
            let rect = OrientedRect::new(world, PART_DEPTH_M, PART_WIDTH_M);
            solids.iter().all(|(shape, what)| {
                (in_its_slot && matches!(what, Obstruction::Wall(_)))
                    || push_out(&rect, shape).is_none()
            })
        };
        if is_free(flat) {
            return;
        }
        let (mut free, mut blocked) = (0.0, 1.0);
        for _ in 0..Self::FLATTEN_STEPS {
            let mid = (free + blocked) / 2.0;
            if is_free(at(mid)) {
                free = mid;
            } else {
                blocked = mid;
            }
        }
        self.shop.hold_at(part, at(free));
    }

    /// Record a contact of the robot (or, `by_carried`, its carried part) with `what`. The
    /// carried part touching the walls of the slot it stands in is being picked or placed:
    /// the magnet presses it there by design, no collision.
    fn note_contact(&self, touched: &mut Vec<Obstruction>, what: Obstruction, by_carried: bool) {
        if by_carried
            && matches!(what, Obstruction::Wall(_))
            && self.shop.carried().is_some_and(|part| {
                let at = self.shop.footprint(part, self.body.pose).pose;
                self.shop.slot_at(at).is_some()
            })
        {
            return;
        }
        if !touched.contains(&what) {
            touched.push(what);
        }
    }

    /// Forgets the parts the magnet let go of that the body has moved clear of. Such a part
    /// stood against the magnet's face, which stands proud of the body
    /// ([`crate::parts::Gripper::magnet_m`]) and is no solid here. Until the body has moved
    /// clear of it, touching it is the contact the magnet had, going on: a robot coasting on
    /// after its magnet lets go (a Mega reset cuts the solenoid with the wheels still
    /// turning) pushes the part it held, it does not run into it.
    fn forget_released_parts_left_behind(&mut self) {
        if self.released_at_face.is_empty() {
            return;
        }
        let gripper = self.shop.gripper();
        let reach = gripper.magnet_m - gripper.front_m + Self::CONTACT_TOLERANCE_M;
        let near = self.robot_solids_inflated(reach);
        let carried = self.shop.carried();
        let shop = &self.shop;
        let pose = self.body.pose;
        self.released_at_face.retain(|&part| {
            let rect = shop.footprint(part, pose);
            Some(part) != carried
                && near
                    .iter()
                    .any(|r| push_out(r, &Shape::Rect(rect)).is_some())
        });
    }

    /// The robot's solids grown by `margin_m` on every side.
    fn robot_solids_inflated(&self, margin_m: f64) -> Vec<OrientedRect> {
        self.robot_solids()
            .map(|(r, _)| OrientedRect {
                half_x_m: r.half_x_m + margin_m,
                half_y_m: r.half_y_m + margin_m,
                ..r
            })
            .collect()
    }
}

/// The field's walls, dividers and beacon poles as contact shapes, in `Obstruction` order.
fn fixed_solids(field: &Field) -> Vec<(Shape, Obstruction)> {
    let walls = field.obstacles().into_iter().enumerate().map(|(i, wall)| {
        (
            Shape::Rect(OrientedRect::from_rect(wall.rect)),
            Obstruction::Wall(i),
        )
    });
    let beacons = field.beacons().iter().map(|b| {
        (
            Shape::Circle(b.circle.center, b.circle.radius_m),
            Obstruction::Beacon(b.index),
        )
    });
    walls.chain(beacons).collect()
}

/// True when the circle (`center`, `radius_m`) overlaps the rectangle's interior.
fn circle_overlaps(rect: &OrientedRect, center: Vec2, radius_m: f64) -> bool {
    let local = rect.pose.inverse_transform_point(center);
    let nearest = Vec2::new(
        local.x.clamp(-rect.half_x_m, rect.half_x_m),
        local.y.clamp(-rect.half_y_m, rect.half_y_m),
    );
    nearest.distance(local) < radius_m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parts::PartPlace;
    use ratf_core::drivers::mega_link::{MegaEvent, MegaLink};

    /// A world with the ideal profile: these tests check exact geometry and timing.
    fn world(pose: Pose2) -> World {
        let config = Config::default().in_world(WorldProfile::Ideal);
        World::new(
            &config,
            &Scenario {
                start_pose: pose,
                ..Scenario::new(&config)
            },
        )
    }

    #[test]
    fn the_mega_boots_and_streams_telemetry_every_20_ms() {
        let mut world = world(Field::competition().start_pose());
        let mut link = MegaLink::default();
        let mut resets = 0;
        let mut batches = Vec::new();
        for _ in 0..100 {
            world.step();
            let bytes = world.receive_from_mega();
            link.feed(&bytes, world.now_us(), |e| match e {
                MegaEvent::Reset { .. } => resets += 1,
                MegaEvent::Telemetry(t) => batches.push(t),
            });
        }
        assert_eq!(resets, 1);
        assert_eq!(
            batches.len(),
            4,
            "ticks at 20, 40, 60, 80 ms; the 100 ms batch is in flight"
        );
        assert!(
            batches
                .iter()
                .all(|b| b.period_us == 20_000 && b.verified || b.deltas_ticks.is_none())
        );
    }

    #[test]
    fn wheel_references_make_the_robot_drive_and_the_watchdog_stops_it() {
        let mut world = world(Pose2::new(-0.64, -0.42, std::f64::consts::FRAC_PI_2));
        let mut link = MegaLink::default();
        let mecanum = Mecanum::new(&Config::default().robot);
        let wheels = mecanum
            .inverse(ratf_core::kinematics::BodyTwist::new(0.2, 0.0, 0.0))
            .map(|w| w as f32);
        for step in 0..1000 {
            if step % 20 == 0 {
                let bytes = link.encode_references(wheels, false, false).unwrap();
                world.send_to_mega(&bytes);
            }
            world.step();
        }
        let moved = world.body().pose.y + 0.42;
        assert!(
            (moved - 0.19).abs() < 0.03,
            "moved {moved} m in 1 s at 0.2 m/s"
        );
        // The host goes silent: the Mega's watchdog stops the wheels within ~120 ms, then
        // the motors spin down with their 0.1 s time constant.
        for _ in 0..800 {
            world.step();
        }
        assert_eq!(world.actuation().pwm, [0; 4]);
        assert!(world.body().twist.vx_m_s.abs() < 1e-3);
        assert_eq!(world.stats().collisions, 0);
    }

    /// Drive `world` with a constant body twist for `steps` steps, the magnet off. (The
    /// contact tests switch contact on in the ideal world, to keep its exact geometry.)
    fn drive(world: &mut World, twist: ratf_core::kinematics::BodyTwist, steps: usize) {
        drive_until(world, twist, false, steps, |_| false);
    }

    /// Drive with the magnet as `solenoid` until `done` or `steps` steps.
    fn drive_until(
        world: &mut World,
        twist: ratf_core::kinematics::BodyTwist,
        solenoid: bool,
        steps: usize,
        done: impl Fn(&World) -> bool,
    ) {
        let mut link = MegaLink::default();
        let mecanum = Mecanum::new(&Config::default().robot);
        let wheels = mecanum.inverse(twist).map(|w| w as f32);
        for step in 0..steps {
            if step % 20 == 0 {
                let bytes = link.encode_references(wheels, solenoid, false).unwrap();
                world.send_to_mega(&bytes);
            }
            world.step();
            if done(world) {
                return;
            }
        }
    }

    #[test]
    fn a_body_driven_into_a_wall_stops_at_it_its_wheels_slip_and_it_counts_once() {
        // Facing the machine A block from the left, 5 cm away, driving into it at 0.2 m/s
        // for 1.5 s: 30 cm of wheel travel.
        let mut world = world(Pose2::new(-0.4275 - 0.15 - 0.05, -0.075, 0.0));
        world.contact = true;
        drive(
            &mut world,
            ratf_core::kinematics::BodyTwist::new(0.2, 0.0, 0.0),
            1500,
        );
        let pose = world.body().pose;
        // The front face stands at the dividers' tips (x = −0.4275), not beyond.
        // (Within 0.1 mm: the body turns a fraction of a milliradian as its wheels slip.)
        assert!(
            (pose.x + 0.4275 + 0.15).abs() < 1e-4,
            "stopped at x = {}",
            pose.x
        );
        assert!((pose.y + 0.075).abs() < 1e-4 && pose.yaw_rad.abs() < 1e-3);
        // The wheels turned on: the encoders saw far more than the 5 cm the body moved.
        let rolled_m = world.body().wheel_angles_rad[0].abs() * 0.03;
        assert!(rolled_m > 0.2, "wheels rolled {rolled_m} m");
        let stats = world.stats();
        assert!(stats.slip_steps > 500, "{stats:?}");
        assert!(stats.contact_steps > 500, "{stats:?}");
        // One collision per obstruction touched, with when and where.
        let collisions = world.collisions();
        assert!(!collisions.is_empty());
        assert!(
            collisions
                .iter()
                .all(|c| matches!(c.with, Obstruction::Wall(_)))
        );
        let mut distinct: Vec<Obstruction> = collisions.iter().map(|c| c.with).collect();
        distinct.sort();
        distinct.dedup();
        assert_eq!(distinct.len(), collisions.len(), "{collisions:?}");
        assert_eq!(stats.collisions as usize, collisions.len());
        let first = collisions[0];
        // 5 cm at up to 0.2 m/s after the first telemetry tick: between 0.25 and 0.6 s.
        assert!((250_000..600_000).contains(&first.time_us), "{first:?}");
        assert!((first.pose.x + 0.5775).abs() < 0.002, "{first:?}");
    }

    #[test]
    fn a_wall_deflects_a_body_driven_at_it_at_an_angle() {
        // Driving +x and −y at once into the same block: the front is stopped, the sideways
        // motion goes on along the dividers' tips.
        let mut world = world(Pose2::new(-0.4275 - 0.15 - 0.02, 0.0, 0.0));
        world.contact = true;
        drive(
            &mut world,
            ratf_core::kinematics::BodyTwist::new(0.2, -0.1, 0.0),
            1000,
        );
        let pose = world.body().pose;
        assert!((pose.x + 0.5775).abs() < 1e-4, "{pose:?}");
        assert!(pose.y < -0.05, "slid along the block: {pose:?}");
    }

    /// A world of one blue part (in incoming slot 1), the robot at (−0.8, 0) facing +x, with
    /// contact on.
    fn one_part_world_with_contact() -> World {
        let config = Config::default().in_world(WorldProfile::Ideal);
        let mut world = World::new(
            &config,
            &Scenario {
                start_pose: Pose2::new(-0.8, 0.0, 0.0),
                incoming: [Some(PartColor::Blue), None, None, None],
                ..Scenario::new(&config)
            },
        );
        world.contact = true;
        world
    }

    /// The bug this guards: a part that slipped off the magnet as the robot backed out of a
    /// slot was put 2–5 cm further on, into the slot's back wall, and stayed there, so the
    /// search reached for a plate a centimetre deeper than any slot holds one and pressed the
    /// body onto the dividers' tips.
    #[test]
    fn a_part_that_lands_in_a_wall_rests_against_it() {
        let mut world = one_part_world_with_contact();
        let field = Field::competition();
        let slot = field.incoming_slot(2).expect("slot 3");
        // 8 mm deeper than the slot's seat, its plate facing out: into the back wall.
        let deep = slot.box_center + Vec2::new(0.0, 0.008);
        let plate_out = -std::f64::consts::FRAC_PI_2;
        world.put_part_on_floor(0, Pose2::new(deep.x, deep.y, plate_out));
        let part = world.shop().footprint(0, world.body().pose);
        let wall = field
            .warehouse(ratf_core::field::WarehouseKind::Incoming)
            .wall
            .rect;
        let wall = OrientedRect::from_rect(wall);
        assert!(!part.penetrates(&wall, 1e-6), "{part:?}");
        // Against it: moved back out by the 8 mm, not further.
        assert!((part.pose.y - slot.box_center.y).abs() < 1e-6, "{part:?}");
    }

    #[test]
    fn a_free_part_is_pushed_along_in_front_of_the_robot() {
        let mut world = one_part_world_with_contact();
        // The part on the floor 5 cm ahead of the front face, its plate facing the robot,
        // on the line of machine A's upper input slot (y = 0, between two dividers).
        let part_at = Pose2::new(-0.8 + 0.15 + 0.05 + 0.03, 0.0, std::f64::consts::PI);
        world.put_part_on_floor(0, part_at);
        drive(
            &mut world,
            ratf_core::kinematics::BodyTwist::new(0.2, 0.0, 0.0),
            1600,
        );
        let part = world.shop().footprint(0, world.body().pose);
        let robot = world.footprint();
        // The robot stopped with its front on the dividers' tips (x = −0.4275); the part,
        // pushed 17 cm without turning, stands against its front, inside the slot's mouth.
        assert!((robot.pose.x + 0.4275 + 0.15).abs() < 1e-3, "{robot:?}");
        assert!((part.pose.x - (-0.4275 + 0.03)).abs() < 1e-3, "{part:?}");
        assert!(part.pose.y.abs() < 1e-3 && part.pose.yaw_rad == std::f64::consts::PI);
        assert!(!robot.overlaps(&part));
        // A push never puts a part into a slot: only a release does.
        assert!(matches!(world.shop().parts()[0].place, PartPlace::Floor(_)));
        let with: Vec<Obstruction> = world.collisions().iter().map(|c| c.with).collect();
        assert_eq!(with.first(), Some(&Obstruction::Part(0)), "{with:?}");
        assert!(with[1..].iter().all(|w| matches!(w, Obstruction::Wall(_))));
        assert_eq!(
            with.iter().filter(|&&w| w == Obstruction::Part(0)).count(),
            1
        );
    }

    /// The bug this guards: a Mega reset cuts the magnet with the wheels still turning, and
    /// the robot coasting on into the part it had just held counted a collision with it
    /// (seeds 61–70 of the fault bench: 6 of the Mega reset's 7 collisions).
    #[test]
    fn a_part_let_go_while_moving_is_pushed_on_without_a_collision() {
        let mut world = one_part_world_with_contact();
        let part_at = Pose2::new(-0.8 + 0.15 + 0.05 + 0.03, 0.0, std::f64::consts::PI);
        world.put_part_on_floor(0, part_at);
        let creep = ratf_core::kinematics::BodyTwist::new(0.05, 0.0, 0.0);
        drive_until(&mut world, creep, true, 1500, |w| {
            w.shop().carried().is_some()
        });
        assert_eq!(world.shop().carried(), Some(0), "{:?}", world.part_events());
        let ahead = ratf_core::kinematics::BodyTwist::new(0.2, 0.0, 0.0);
        drive(&mut world, ahead, 300);
        let robot_x = world.footprint().pose.x;
        assert_eq!(world.shop().carried(), None);
        assert!(
            world
                .part_events()
                .iter()
                .any(|(_, e)| matches!(e, PartEvent::Dropped { part: 0 })),
            "{:?}",
            world.part_events()
        );
        // It went on pushing the part it let go of, and ran into nothing.
        assert!(robot_x > -0.8 + 0.04, "{robot_x}");
        let part = world.shop().footprint(0, world.body().pose);
        assert!(
            (part.pose.x - (robot_x + 0.15 + 0.03)).abs() < 0.003,
            "{part:?}"
        );
        assert_eq!(world.collisions(), &[]);
        // Backed clear of it and driven into it again, the robot does run into it.
        let back = ratf_core::kinematics::BodyTwist::new(-0.1, 0.0, 0.0);
        drive(&mut world, back, 500);
        drive(&mut world, ahead, 600);
        let with: Vec<Obstruction> = world.collisions().iter().map(|c| c.with).collect();
        assert_eq!(with.first(), Some(&Obstruction::Part(0)), "{with:?}");
    }

    #[test]
    fn a_robot_set_down_into_a_pole_starts_against_it_without_a_collision() {
        let mut config = Config::default();
        config.sim.world = ratf_core::config::WorldProfile::Realistic;
        // Its left side 3 cm into beacon 3's pole (believed at (−0.888, −0.538)).
        let start = Pose2::new(-0.888 + 0.045 + 0.15 - 0.03, -0.538, 0.0);
        let world = World::new(
            &config,
            &Scenario {
                start_pose: start,
                ..Scenario::new(&config)
            },
        );
        let pole = world.field().beacons()[3].circle;
        let body = world.footprint();
        assert!(push_out(&body, &Shape::Circle(pole.center, pole.radius_m)).is_none());
        assert!(world.body().pose.position().distance(start.position()) < 0.05);
        assert_eq!((world.collisions().len(), world.stats().collisions), (0, 0));
        // It has stood against the pole since it was set down: pressing on it is that same
        // contact (seed 38's robot, set down a tenth of a millimetre into a pole, counted a
        // collision as its wheels began to turn), and so is driving away.
        let mut world = world;
        let back = ratf_core::kinematics::BodyTwist::new(-0.05, 0.0, 0.0);
        drive(&mut world, back, 200);
        let away = ratf_core::kinematics::BodyTwist::new(0.1, 0.0, 0.0);
        drive(&mut world, away, 1000);
        assert!(
            world.body().pose.x > start.x + 0.03,
            "{:?}",
            world.body().pose
        );
        assert_eq!(world.collisions(), &[]);
    }

    #[test]
    fn a_robot_creeping_onto_an_off_centre_part_picks_it_without_a_collision() {
        // Realistic worlds: each part off centre in its slot, the body's outline off the
        // config's. The robot creeps at 0.05 m/s from 2 cm short of the nominal pick pose
        // with the magnet on, as the mission's docking does.
        for seed in 1..=5 {
            let mut config = Config::default();
            config.sim.world = ratf_core::config::WorldProfile::Realistic;
            config.sim.seed = seed;
            let slot = *Field::competition().incoming_slot(2).unwrap();
            let mut world = World::new(
                &config,
                &Scenario {
                    start_pose: slot.pose_at_standoff(0.185),
                    incoming: [Some(PartColor::Red); 4],
                    ..Scenario::new(&config)
                },
            );
            let seat = world.truth().part_seats[2];
            assert!(seat.across_m != 0.0 && seat.yaw_deg != 0.0);
            drive_until(
                &mut world,
                ratf_core::kinematics::BodyTwist::new(0.05, 0.0, 0.0),
                true,
                1500,
                |w| w.shop().carried().is_some(),
            );
            assert!(
                world.part_events().iter().any(|(_, e)| matches!(
                    e,
                    PartEvent::Picked {
                        part: 2,
                        from: Some(_)
                    }
                )),
                "seed {seed}: {seat:?} {:?}",
                world.part_events()
            );
            assert!(
                world.collisions().is_empty(),
                "seed {seed}: {:?}",
                world.collisions()
            );
        }
    }

    /// A robot standing still at `start` whose magnet takes up part 0 lying turned 14° on
    /// the floor in front of it, its plate against the magnet's face, with part 1 (if
    /// `blocked`) square behind part 0's far corner, where pulling part 0 flat swings it.
    /// Returns the world once the part is held (or after 100 steps).
    fn grip_turned_part(blocked: bool) -> World {
        let config = Config::default().in_world(WorldProfile::Ideal);
        let start = Pose2::new(-0.8, 0.0, 0.0);
        let mut world = World::new(
            &config,
            &Scenario {
                start_pose: start,
                incoming: [Some(PartColor::Blue), Some(PartColor::Blue), None, None],
                ..Scenario::new(&config)
            },
        );
        world.contact = true;
        let gripper = world.shop().gripper();
        // Where part 0 is held flat, in the world; the part lies there turned 14°.
        let flat = start.compose(Pose2::new(
            gripper.magnet_m + PART_DEPTH_M / 2.0,
            0.0,
            std::f64::consts::PI,
        ));
        let turned = Pose2::new(flat.x, flat.y, flat.yaw_rad + 14f64.to_radians());
        world.put_part_on_floor(0, turned);
        world.put_part_on_floor(1, Pose2::new(flat.x + 0.07, flat.y + 0.2, 0.0));
        if blocked {
            // Its corner 50 mm from part 0's centre at 240° in part 0's flat frame: outside
            // the part turned, 5 mm inside it flat.
            let corner = Vec2::new(-0.025, -0.0433);
            let centre = corner - Vec2::new(PART_DEPTH_M / 2.0, PART_WIDTH_M / 2.0);
            world.put_part_on_floor(1, flat.compose(Pose2::new(centre.x, centre.y, 0.0)));
        }
        drive_until(
            &mut world,
            ratf_core::kinematics::BodyTwist::new(0.0, 0.0, 0.0),
            true,
            100,
            |w| w.shop().carried().is_some(),
        );
        world
    }

    /// The bug this guards: the magnet put a part it took up flat against its face at once,
    /// through whatever stood beside it, and the next step's contact pushed the robot off
    /// that as a collision (a part fallen off the magnet and lying turned beside a slot,
    /// gripped again: about a sixth of the part slip and knocked part rows' collisions on
    /// the fault bench's seeds 61–85).
    #[test]
    fn a_part_the_magnet_pulls_flat_stops_turning_where_a_neighbour_blocks_it() {
        let free = grip_turned_part(false);
        let held = free.shop().held_at(0).expect("gripped");
        assert!(
            wrap_angle(held.yaw_rad - std::f64::consts::PI).abs() < 1e-9,
            "{held:?}"
        );
        let blocked = grip_turned_part(true);
        let held = blocked.shop().held_at(0).expect("gripped");
        let left_turned = wrap_angle(held.yaw_rad - std::f64::consts::PI).abs();
        assert!(
            (1f64.to_radians()..14f64.to_radians()).contains(&left_turned),
            "{held:?}"
        );
        assert!(
            blocked.collisions().is_empty(),
            "{:?}",
            blocked.collisions()
        );
        let part = blocked.shop().footprint(0, blocked.body().pose);
        let neighbour = blocked.shop().footprint(1, blocked.body().pose);
        assert!(push_out(&part, &Shape::Rect(neighbour)).is_none());
    }

    #[test]
    fn the_ideal_world_has_no_contact_and_counts_a_wall_driven_through_once() {
        // Facing the machine A block from the left, 5 cm away, driving into it.
        let mut world = world(Pose2::new(-0.4275 - 0.15 - 0.05, -0.075, 0.0));
        let mut link = MegaLink::default();
        let mecanum = Mecanum::new(&Config::default().robot);
        let wheels = mecanum
            .inverse(ratf_core::kinematics::BodyTwist::new(0.2, 0.0, 0.0))
            .map(|w| w as f32);
        for step in 0..800 {
            if step % 20 == 0 {
                let bytes = link.encode_references(wheels, false, false).unwrap();
                world.send_to_mega(&bytes);
            }
            world.step();
        }
        let collisions = world.collisions();
        assert!(!collisions.is_empty());
        assert!(
            collisions
                .iter()
                .all(|c| matches!(c.with, Obstruction::Wall(_)))
        );
        // With no contact physics it drives on through the block's dividers and wall; each
        // obstruction counts once while the overlap lasts, not once per step.
        let mut distinct: Vec<Obstruction> = collisions.iter().map(|c| c.with).collect();
        distinct.sort();
        distinct.dedup();
        assert_eq!(distinct.len(), collisions.len(), "{collisions:?}");
    }

    #[test]
    fn every_serial_line_is_bounded_and_counts_what_it_drops() {
        // Issue 13: `[mega] control_period_us = 1` (with a 1 µs step) grew the Mega → host
        // line without bound. Unvalidated here, on purpose: the world itself stays bounded.
        let mut config = Config::default();
        config.mega.control_period_us = 1;
        config.sim.time_step_us = 1;
        let mut world = World::new(&config, &Scenario::new(&config));
        for _ in 0..200_000 {
            world.step();
            world.receive_from_mega();
            assert!(world.from_mega.pending() <= MEGA_TX_CAPACITY_BYTES);
        }
        let stats = world.stats();
        assert!(stats.from_mega_bytes_dropped > 100_000, "{stats:?}");
        // The host flooding the Mega's line: 4 KiB kept, the rest counted.
        world.send_to_mega(&[b'0'; 10_000]);
        assert_eq!(world.to_mega.pending(), HOST_TX_CAPACITY_BYTES);
        assert_eq!(
            world.stats().to_mega_bytes_dropped,
            10_000 - HOST_TX_CAPACITY_BYTES as u64
        );
    }

    #[test]
    fn the_mega_reports_telemetry_its_ring_dropped_on_x() {
        let mut world = world(Field::competition().start_pose());
        let mut link = MegaLink::default();
        let mut reported = Vec::new();
        for step in 0..400 {
            if step == 100 {
                // A burst the ring cannot hold (spaces, which the host's decoder skips).
                let now_ns = world.now_ns();
                world.from_mega.send(&[b' '; 300], now_ns);
            }
            world.step();
            link.feed(&world.receive_from_mega(), world.now_us(), |e| {
                if let MegaEvent::Telemetry(t) = e {
                    reported.extend(t.faults.map(|f| f.serial_bytes_dropped));
                }
            });
        }
        let dropped = world.stats().from_mega_bytes_dropped;
        assert!(dropped > 0);
        assert_eq!(
            reported.last().copied(),
            Some(dropped as u8),
            "{reported:?}"
        );
    }

    #[test]
    fn a_lidar_faster_than_its_line_is_bounded_and_counted() {
        // Issue 13: `[lidar] scan_rate_hz = 65535` grew the X4 → host line without bound.
        let mut config = Config::default();
        config.lidar.scan_rate_hz = 65_535.0;
        let mut world = World::new(&config, &Scenario::new(&config));
        for _ in 0..3 {
            world.step();
            assert!(world.from_lidar.pending() <= LIDAR_TX_CAPACITY_BYTES);
        }
        assert!(world.stats().from_lidar_bytes_dropped > 300_000);
    }

    #[test]
    fn the_default_world_drops_nothing() {
        let mut world = world(Field::competition().start_pose());
        for _ in 0..2_000 {
            world.step();
            world.receive_from_mega();
            world.receive_from_lidar();
        }
        let stats = world.stats();
        assert_eq!(
            (
                stats.to_mega_bytes_dropped,
                stats.from_mega_bytes_dropped,
                stats.from_lidar_bytes_dropped
            ),
            (0, 0, 0)
        );
    }

    #[test]
    fn beacon_overlap_uses_the_circle() {
        let rect = OrientedRect::new(Pose2::new(0.0, 0.0, 0.0), 0.3, 0.3);
        assert!(circle_overlaps(&rect, Vec2::new(0.19, 0.0), 0.045));
        assert!(!circle_overlaps(&rect, Vec2::new(0.2, 0.0), 0.045));
        // Near a corner the circle must reach the corner itself (0.042 m vs 0.057 m away).
        assert!(circle_overlaps(&rect, Vec2::new(0.18, 0.18), 0.045));
        assert!(!circle_overlaps(&rect, Vec2::new(0.19, 0.19), 0.045));
    }

    /// Incoming slot 1's part against the back wall, square; slot 2's `out_m` off the wall
    /// and turned `yaw_deg`; the rest centred.
    fn seated_world(out_m: f64, yaw_deg: f64) -> World {
        let config = Config::default().in_world(WorldProfile::Ideal);
        let mut world = World::new(
            &config,
            &Scenario {
                incoming: [Some(PartColor::Blue); 4],
                ..Scenario::new(&config)
            },
        );
        let mut seats = [crate::truth::PartSeat::default(); 4];
        seats[1] = crate::truth::PartSeat {
            across_m: 0.0,
            gap_m: out_m,
            yaw_deg,
        };
        world.shop.seat_incoming(&seats);
        world
    }

    #[test]
    fn a_neighbour_standing_out_further_than_the_body_reaches_crowds_the_pick() {
        // Centred against the wall: no pick is crowded.
        assert_eq!(seated_world(0.0, 0.0).crowded_picks(0.0), vec![]);
        // 5 mm off the wall, square: slot 1's body front (15 mm behind its plate) is clear.
        assert_eq!(seated_world(0.005, 0.0).crowded_picks(0.0), vec![]);
        // 15 mm off and turned 8° (the harsh world's limits): its corner stands 21 mm out,
        // into the body of a robot picking slot 1 or slot 3, not slot 4 (beyond reach).
        let crowded = seated_world(0.015, 8.0).crowded_picks(0.0);
        assert_eq!(crowded, vec![(WaypointId(50), 1), (WaypointId(52), 1)]);
        // Square 5 mm off the wall it leaves the body 10 mm: crowded only within a margin
        // beyond that.
        assert_eq!(seated_world(0.005, 0.0).crowded_picks(0.009), vec![]);
        let within = seated_world(0.005, 0.0).crowded_picks(0.011);
        assert_eq!(within, vec![(WaypointId(50), 1), (WaypointId(52), 1)]);
    }

    /// The fault bench's knocked part lies on the floor, no longer in its slot: it crowded
    /// no pick, and the knocked-part row counted none of its 45 contacts as crowded.
    #[test]
    fn a_part_knocked_onto_the_floor_crowds_the_picks_beside_it() {
        let mut world = seated_world(0.0, 0.0);
        let seat = world.shop.footprint(1, world.body.pose).pose;
        // The plate faces out of the slot along the part's +x: 25 mm out, turned 5°.
        world.put_part_on_floor(1, seat.compose(Pose2::new(0.025, 0.0, 0.087)));
        assert_eq!(
            world.crowded_picks(0.0),
            vec![(WaypointId(50), 1), (WaypointId(52), 1)]
        );
        // Knocked 5 mm out, square, it leaves the body 10 mm.
        world.put_part_on_floor(1, seat.compose(Pose2::new(0.005, 0.0, 0.0)));
        assert_eq!(world.crowded_picks(0.0), vec![]);
    }
}
