//! Faults injected into the simulated world and its devices, never into the robot's core
//! (issue 17): a [`FaultPlan`] of timed [`FaultEvent`]s drawn from a seed, and a
//! [`FaultInjector`] that applies them to a [`SimDevices`] as simulated time passes.
//!
//! The server's faults (silent, late, duplicating, garbage) are in the plan too, but the
//! organisers' server is not part of the world: the round that runs the server asks
//! [`FaultPlan::server_fault`] what to do with each answer.
//!
//! Magnitudes are assumptions, chosen to be what a team meets on the day (issue 17 gives the
//! dropout length, 0.5–3 s); each is named where it is drawn.

use ratf_core::field::geometry::{Pose2, Vec2};
use ratf_core::rng::SimRng;
use ratf_core::runtime::DeviceKind;

use crate::devices::SimDevices;
use crate::lidar::{Solid, person};

/// One kind of fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// The lidar returns no points for 0.5–3 s (its revolutions still arrive, empty).
    LidarDropout,
    /// A person walks past a beacon, just outside the field, at 0.6 m/s.
    Person,
    /// Three bursts of 0.3–1 s in which the floor passes on only 50–80 % of the wheels'
    /// motion.
    WheelSlip,
    /// The carried part slips off the magnet (the next carry out of a slot after the fault's
    /// time) and comes to rest 20–50 mm in front of it.
    PartSlip,
    /// A part standing in an incoming slot is knocked 10–30 mm out of it, turned up to 8°.
    PartKnocked,
    /// The server answers nothing for 2–8 s.
    ServerSilent,
    /// For 2–8 s the server's answers arrive 0.2–1 s late.
    ServerLate,
    /// For 2–8 s every answer of the server arrives twice.
    ServerDuplicate,
    /// For 2–8 s the server's answers are replaced by 1–40 random bytes.
    ServerGarbage,
    /// Three bursts of 16–200 random bytes on the Mega → host line.
    SerialGarbage,
    /// The Mega resets and is back 0.5 s later.
    MegaReset,
    /// The Mega's USB cable is out for 0.5–2 s ([`SimDevices::unplug`]): its port is lost,
    /// then reopened at the thread's next try, which resets the board.
    MegaReplug,
    /// The lidar's USB cable is out for 0.5–2 s: its port is lost, the X4 stops, then the
    /// port is reopened at the thread's next try and the X4 started again.
    LidarReplug,
    /// Every IMU read fails from the fault on.
    ImuFailure,
    /// The lidar stops sending for good (its port stays open).
    LidarGone,
    /// The Mega is gone for good (off, or its cable out).
    MegaGone,
}

impl FaultKind {
    /// Every kind, in the order the bench reports them.
    pub const ALL: [Self; 16] = [
        Self::LidarDropout,
        Self::Person,
        Self::WheelSlip,
        Self::PartSlip,
        Self::PartKnocked,
        Self::ServerSilent,
        Self::ServerLate,
        Self::ServerDuplicate,
        Self::ServerGarbage,
        Self::SerialGarbage,
        Self::MegaReset,
        Self::MegaReplug,
        Self::LidarReplug,
        Self::ImuFailure,
        Self::LidarGone,
        Self::MegaGone,
    ];

    /// The kind's name in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::LidarDropout => "lidar_dropout",
            Self::Person => "person",
            Self::WheelSlip => "wheel_slip",
            Self::PartSlip => "part_slip",
            Self::PartKnocked => "part_knocked",
            Self::ServerSilent => "server_silent",
            Self::ServerLate => "server_late",
            Self::ServerDuplicate => "server_duplicate",
            Self::ServerGarbage => "server_garbage",
            Self::SerialGarbage => "serial_garbage",
            Self::MegaReset => "mega_reset",
            Self::MegaReplug => "mega_replug",
            Self::LidarReplug => "lidar_replug",
            Self::ImuFailure => "imu_failure",
            Self::LidarGone => "lidar_gone",
            Self::MegaGone => "mega_gone",
        }
    }

    /// True when a robot can still score fully through this fault; false when it must
    /// stop (motors at zero, magnet off).
    pub fn recoverable(self) -> bool {
        !matches!(self, Self::LidarGone | Self::MegaGone)
    }

    /// True for a fault of the organisers' server.
    pub fn is_server(self) -> bool {
        matches!(
            self,
            Self::ServerSilent | Self::ServerLate | Self::ServerDuplicate | Self::ServerGarbage
        )
    }

    /// How many events of this kind one run gets.
    fn bursts(self) -> usize {
        match self {
            Self::WheelSlip | Self::SerialGarbage => 3,
            _ => 1,
        }
    }
}

impl std::fmt::Display for FaultKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One fault in time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultEvent {
    /// What.
    pub kind: FaultKind,
    /// When it starts, µs of simulated time.
    pub start_us: u64,
    /// When it ends, µs (`u64::MAX`: for good; `start_us` for an instant fault).
    pub end_us: u64,
    /// The event's own draws (which part, how far, which bytes).
    pub seed: u64,
}

impl FaultEvent {
    /// True while the fault lasts at `now_us`.
    pub fn active(&self, now_us: u64) -> bool {
        (self.start_us..self.end_us).contains(&now_us)
    }
}

/// What happens to the server's answers now.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ServerFault {
    /// Lost.
    Silent,
    /// Delivered this much later, µs.
    Late(u64),
    /// Delivered twice.
    Duplicate,
    /// Replaced by random bytes drawn from this seed.
    Garbage(u64),
}

/// The faults of one run, in time order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultPlan {
    /// The events.
    pub events: Vec<FaultEvent>,
}

impl FaultPlan {
    /// No faults.
    pub fn none() -> Self {
        Self::default()
    }

    /// Each of `kinds` at a time drawn uniformly in `window_us` (simulated µs; e.g. from
    /// the round's start to the end of the fault-free run), from `seed`.
    pub fn draw(kinds: &[FaultKind], seed: u64, window_us: std::ops::Range<u64>) -> Self {
        let mut rng = SimRng::new(seed).fork("faults");
        let (lo, hi) = (
            window_us.start as f64,
            window_us.end.max(window_us.start) as f64,
        );
        let mut events = Vec::new();
        for &kind in kinds {
            for _ in 0..kind.bursts() {
                let start_us = rng.uniform_in(lo, hi) as u64;
                let s = |rng: &mut SimRng, a: f64, b: f64| (rng.uniform_in(a, b) * 1e6) as u64;
                let end_us = match kind {
                    FaultKind::LidarDropout => start_us + s(&mut rng, 0.5, 3.0),
                    FaultKind::Person => start_us + PERSON_WALK_US,
                    FaultKind::WheelSlip => start_us + s(&mut rng, 0.3, 1.0),
                    FaultKind::ServerSilent
                    | FaultKind::ServerLate
                    | FaultKind::ServerDuplicate
                    | FaultKind::ServerGarbage => start_us + s(&mut rng, 2.0, 8.0),
                    FaultKind::MegaReset => start_us + MEGA_BOOT_US,
                    FaultKind::MegaReplug | FaultKind::LidarReplug => {
                        start_us + s(&mut rng, 0.5, 2.0)
                    }
                    FaultKind::PartSlip => u64::MAX,
                    FaultKind::ImuFailure | FaultKind::LidarGone | FaultKind::MegaGone => u64::MAX,
                    FaultKind::PartKnocked | FaultKind::SerialGarbage => start_us,
                };
                events.push(FaultEvent {
                    kind,
                    start_us,
                    end_us,
                    seed: rng.next_u64(),
                });
            }
        }
        events.sort_by_key(|e| e.start_us);
        Self { events }
    }

    /// `count` distinct recoverable kinds drawn from `seed`, each as in [`Self::draw`].
    pub fn draw_mixed(count: usize, seed: u64, window_us: std::ops::Range<u64>) -> Self {
        let mut rng = SimRng::new(seed).fork("mixed-faults");
        let mut pool: Vec<FaultKind> = FaultKind::ALL
            .into_iter()
            .filter(|k| k.recoverable())
            .collect();
        let mut kinds = Vec::new();
        while kinds.len() < count && !pool.is_empty() {
            let i = ((rng.uniform() * pool.len() as f64) as usize).min(pool.len() - 1);
            kinds.push(pool.swap_remove(i));
        }
        Self::draw(&kinds, seed, window_us)
    }

    /// The first fault that must stop the robot, if any.
    pub fn first_unrecoverable(&self) -> Option<&FaultEvent> {
        self.events.iter().find(|e| !e.kind.recoverable())
    }

    /// What happens to an answer of the server sent at `now_us`, if a server fault lasts.
    pub fn server_fault(&self, now_us: u64) -> Option<ServerFault> {
        let event = self
            .events
            .iter()
            .find(|e| e.kind.is_server() && e.active(now_us))?;
        Some(match event.kind {
            FaultKind::ServerSilent => ServerFault::Silent,
            FaultKind::ServerLate => {
                let mut rng = SimRng::new(event.seed);
                ServerFault::Late((rng.uniform_in(0.2, 1.0) * 1e6) as u64)
            }
            FaultKind::ServerDuplicate => ServerFault::Duplicate,
            _ => ServerFault::Garbage(event.seed ^ now_us),
        })
    }
}

/// 1–40 random bytes from `seed`: a server answering garbage.
pub fn garbage_datagram(seed: u64) -> Vec<u8> {
    let mut rng = SimRng::new(seed).fork("garbage");
    let len = rng.uniform_in(1.0, 41.0) as usize;
    (0..len).map(|_| rng.next_u64() as u8).collect()
}

/// How long the person takes to walk past the beacon, µs: 1.6 m at 0.6 m/s (assumption, a
/// slow walk).
pub const PERSON_WALK_US: u64 = 2_666_667;
/// How long a reset Mega is silent, µs: 0.5 s (assumption: the stk500v2 bootloader's wait
/// after a reset, then the sketch's set-up).
pub const MEGA_BOOT_US: u64 = 500_000;
/// The person's path, m: 0.22 m outside the beacon's centre, 0.8 m either side of it.
const PERSON_OFFSET_M: f64 = 0.22;

/// Applies a [`FaultPlan`] to a simulated robot's world and devices.
#[derive(Clone, Debug)]
pub struct FaultInjector {
    plan: FaultPlan,
    base_clutter: Vec<Solid>,
    started: Vec<bool>,
    ended: Vec<bool>,
    injected: Vec<bool>,
}

impl FaultInjector {
    /// Inject `plan` into a world whose standing clutter is `base_clutter` (a walking person
    /// is added to it).
    pub fn new(plan: FaultPlan, base_clutter: Vec<Solid>) -> Self {
        let n = plan.events.len();
        Self {
            plan,
            base_clutter,
            started: vec![false; n],
            ended: vec![false; n],
            injected: vec![false; n],
        }
    }

    /// The plan.
    pub fn plan(&self) -> &FaultPlan {
        &self.plan
    }

    /// Per event of the plan: whether it really happened in the world (a part slip needs a
    /// carried part, a knock a part in an incoming slot; a server fault is the round's).
    pub fn injected(&self) -> &[bool] {
        &self.injected
    }

    /// Apply what is due at the world's time, before it steps.
    pub fn before_step(&mut self, sim: &mut SimDevices) {
        let now_us = sim.now_us();
        for i in 0..self.plan.events.len() {
            let event = self.plan.events[i];
            if now_us < event.start_us || self.ended[i] {
                continue;
            }
            let first = !self.started[i];
            self.started[i] = true;
            if now_us >= event.end_us && !first {
                self.end(i, sim);
                continue;
            }
            self.during(i, first, now_us, sim);
            if now_us >= event.end_us {
                self.end(i, sim);
            }
        }
    }

    fn during(&mut self, i: usize, first: bool, now_us: u64, sim: &mut SimDevices) {
        let event = self.plan.events[i];
        let mut rng = SimRng::new(event.seed);
        let world = sim.world_mut();
        match event.kind {
            FaultKind::LidarDropout if first => world.lidar_mut().enabled = false,
            // Every 20 ms is enough: 12 mm per move.
            FaultKind::Person if first || (now_us - event.start_us) % 20_000 < 1_000 => {
                let beacons = world.field().beacons();
                let beacon = beacons[(event.seed % 4) as usize].circle.center;
                let out = if beacon.x > 0.0 { 1.0 } else { -1.0 };
                let along = (now_us - event.start_us) as f64 / PERSON_WALK_US as f64 * 1.6 - 0.8;
                let at = Vec2::new(beacon.x + out * PERSON_OFFSET_M, beacon.y + along);
                let mut clutter = self.base_clutter.clone();
                clutter.extend(person(at));
                world.set_clutter(&clutter);
            }
            FaultKind::WheelSlip if first => world.set_grip(rng.uniform_in(0.5, 0.8)),
            FaultKind::PartSlip => {
                // In transit only: a part still inside a slot is being picked or placed, with
                // the robot standing.
                let in_transit = world.shop().carried().filter(|&part| {
                    let held = world.shop().footprint(part, world.body().pose).pose;
                    world.shop().slot_at(held).is_none()
                });
                if let Some(part) = in_transit {
                    let held = world.shop().footprint(part, world.body().pose).pose;
                    // Away from the magnet's face (the part's local +x, its plate, faces
                    // the robot).
                    let away = rng.uniform_in(0.020, 0.050);
                    let rest = held.compose(Pose2::new(
                        -away,
                        rng.uniform_in(-0.02, 0.02),
                        rng.uniform_in(-0.17, 0.17),
                    ));
                    world.put_part_on_floor(part, rest);
                    self.injected[i] = true;
                    self.ended[i] = true;
                }
            }
            FaultKind::PartKnocked if first => {
                let field = world.field().clone();
                let standing: Vec<(usize, Pose2)> = (0..4)
                    .filter_map(|k| field.incoming_slot(k))
                    .filter_map(|slot| {
                        let part = world.shop().part_in(slot.waypoint)?;
                        let pose = world.shop().footprint(part, world.body().pose).pose;
                        Some((part, pose))
                    })
                    .collect();
                if !standing.is_empty() {
                    let k =
                        ((rng.uniform() * standing.len() as f64) as usize).min(standing.len() - 1);
                    let (part, pose) = standing[k];
                    // The part's +x is its plate, facing out of the slot.
                    let knocked = pose.compose(Pose2::new(
                        rng.uniform_in(0.010, 0.030),
                        rng.uniform_in(-0.010, 0.010),
                        rng.uniform_in(-0.14, 0.14),
                    ));
                    world.put_part_on_floor(part, knocked);
                    self.injected[i] = true;
                }
            }
            FaultKind::SerialGarbage if first => {
                let len = rng.uniform_in(16.0, 201.0) as usize;
                let bytes: Vec<u8> = (0..len).map(|_| rng.next_u64() as u8).collect();
                world.inject_from_mega(&bytes);
                self.injected[i] = true;
            }
            FaultKind::MegaReset if first => world.reset_mega(Some(event.end_us - now_us)),
            FaultKind::MegaGone if first => world.reset_mega(None),
            FaultKind::ImuFailure if first => world.fail_imu(true),
            FaultKind::LidarGone if first => sim.cut_lidar(true),
            FaultKind::MegaReplug if first => sim.unplug(DeviceKind::Mega),
            FaultKind::LidarReplug if first => sim.unplug(DeviceKind::Lidar),
            _ => {}
        }
        if first && !matches!(event.kind, FaultKind::PartSlip | FaultKind::PartKnocked) {
            self.injected[i] = true;
        }
    }

    fn end(&mut self, i: usize, sim: &mut SimDevices) {
        self.ended[i] = true;
        let world = sim.world_mut();
        match self.plan.events[i].kind {
            FaultKind::LidarDropout => world.lidar_mut().enabled = true,
            FaultKind::Person => world.set_clutter(&self.base_clutter),
            FaultKind::WheelSlip => world.set_grip(1.0),
            FaultKind::MegaReplug => sim.replug(DeviceKind::Mega),
            FaultKind::LidarReplug => sim.replug(DeviceKind::Lidar),
            _ => {}
        }
    }
}
