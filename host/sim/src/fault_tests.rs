//! Each fault of [`crate::faults`] really happens in the world and its devices.

use ratf_core::config::{Config, WorldProfile};
use ratf_core::field::geometry::Pose2;
use ratf_core::field::{Field, PartColor};
use ratf_core::kinematics::{BodyTwist, Mecanum};
use ratf_core::runtime::{DeviceKind, Input, LidarCommand, Outputs, WheelCommand};

use crate::devices::SimDevices;
use crate::faults::{FaultEvent, FaultInjector, FaultKind, FaultPlan, ServerFault};
use crate::parts::PartPlace;
use crate::world::Scenario;

/// One event of `kind` from `start_ms` to `end_ms` (`None`: for good).
fn plan(kind: FaultKind, start_ms: u64, end_ms: Option<u64>, seed: u64) -> FaultPlan {
    FaultPlan {
        events: vec![FaultEvent {
            kind,
            start_us: start_ms * 1_000,
            end_us: end_ms.map_or(u64::MAX, |ms| ms * 1_000),
            seed,
        }],
    }
}

/// The robot standing at incoming slot 0's pick pose, a red part in every incoming slot, in
/// the ideal world (the faults' timing without USB jitter).
fn devices() -> SimDevices {
    let config = Config::default().in_world(WorldProfile::Ideal);
    let pose = Field::competition()
        .incoming_slot(0)
        .map(|s| s.pick_pose)
        .unwrap_or(Pose2::new(0.0, 0.0, 0.0));
    let scenario = Scenario {
        start_pose: pose,
        incoming: [Some(PartColor::Red); 4],
        ..Scenario::new(&config)
    };
    let mut devices = SimDevices::new(&config, &scenario).unwrap();
    devices.apply_outputs(&Outputs {
        lidar: Some(LidarCommand::StartScan),
        ..Outputs::default()
    });
    devices
}

/// Run to `until_ms` with `injector`, the magnet at `magnet` (resent every 20 ms, wheels
/// still); every input with its time, ms.
fn run(
    devices: &mut SimDevices,
    injector: &mut FaultInjector,
    until_ms: u64,
    magnet: bool,
) -> Vec<(u64, Input)> {
    let command = WheelCommand {
        solenoid_on: magnet,
        ..WheelCommand::STOP
    };
    run_with(devices, injector, until_ms, command)
}

/// [`run`] with `command` resent every 20 ms.
fn run_with(
    devices: &mut SimDevices,
    injector: &mut FaultInjector,
    until_ms: u64,
    command: WheelCommand,
) -> Vec<(u64, Input)> {
    let mut inputs = Vec::new();
    while devices.now_us() < until_ms * 1_000 {
        injector.before_step(devices);
        devices.advance().unwrap();
        if devices.now_us().is_multiple_of(20_000) {
            devices.apply_outputs(&Outputs {
                wheels: Some(command),
                ..Outputs::default()
            });
        }
        while let Some(input) = devices.pop_input() {
            inputs.push((input.time.as_us() / 1_000, input.input));
        }
    }
    inputs
}

/// The times of `inputs` that `keep` picks.
fn times(inputs: &[(u64, Input)], keep: impl Fn(&Input) -> bool) -> Vec<u64> {
    inputs
        .iter()
        .filter(|(_, i)| keep(i))
        .map(|(t, _)| *t)
        .collect()
}

fn scans(inputs: &[(u64, Input)]) -> Vec<(u64, usize)> {
    inputs
        .iter()
        .filter_map(|(t, i)| match i {
            Input::Scan(scan) => Some((*t, scan.points.len())),
            _ => None,
        })
        .collect()
}

#[test]
fn during_a_lidar_dropout_the_scans_have_no_points_and_after_it_they_do() {
    let mut devices = devices();
    let mut injector =
        FaultInjector::new(plan(FaultKind::LidarDropout, 1_000, Some(2_000), 1), vec![]);
    let scans = scans(&run(&mut devices, &mut injector, 3_000, false));
    let count = |from: u64, to: u64| scans.iter().filter(move |(t, _)| (from..to).contains(t));
    // A revolution takes 143 ms: those that ended well inside the dropout saw nothing.
    assert!(count(1_200, 2_000).count() >= 4);
    assert!(count(1_200, 2_000).all(|(_, n)| *n == 0), "{scans:?}");
    assert!(count(500, 1_000).all(|(_, n)| *n > 50), "{scans:?}");
    assert!(count(2_200, 3_000).all(|(_, n)| *n > 50), "{scans:?}");
}

#[test]
fn a_lidar_gone_for_good_sends_no_scan_again() {
    let mut devices = devices();
    let mut injector = FaultInjector::new(plan(FaultKind::LidarGone, 1_000, None, 1), vec![]);
    let inputs = run(&mut devices, &mut injector, 3_000, false);
    let scans = scans(&inputs);
    assert!(scans.iter().any(|(t, _)| *t < 1_000));
    assert!(scans.iter().all(|(t, _)| *t <= 1_000), "{scans:?}");
    // Its device reports the stream stopped 50 ms after the last packet (one every 8 ms),
    // once, as `ratf run`'s lidar thread does.
    let faults = times(&inputs, |i| {
        matches!(
            i,
            Input::DeviceFault {
                device: DeviceKind::Lidar,
                reconnecting: true,
                ..
            }
        )
    });
    assert_eq!(faults.len(), 1, "{faults:?}");
    assert!((1_043..=1_051).contains(&faults[0]), "{faults:?}");
}

#[test]
fn a_lidar_dropout_keeps_its_packets_flowing_and_reports_no_fault() {
    let mut devices = devices();
    let mut injector =
        FaultInjector::new(plan(FaultKind::LidarDropout, 1_000, Some(2_000), 1), vec![]);
    let inputs = run(&mut devices, &mut injector, 3_000, false);
    assert!(
        !inputs
            .iter()
            .any(|(_, i)| matches!(i, Input::DeviceFault { .. })),
        "empty revolutions are the core's to judge"
    );
}

#[test]
fn a_person_walks_past_a_beacon_in_the_lidars_view_and_leaves() {
    let mut devices = devices();
    let clutter = Scenario::new(&Config::default()).clutter;
    let mut injector = FaultInjector::new(plan(FaultKind::Person, 100, Some(2_766), 2), clutter);
    let base = devices.world().lidar_scene().solids().len();
    let mut legs = Vec::new();
    for until_ms in [500, 1_500] {
        run(&mut devices, &mut injector, until_ms, false);
        let solids = devices.world().lidar_scene().solids();
        assert_eq!(solids.len(), base + 2, "two legs");
        legs.push(solids[base]);
    }
    assert_ne!(legs[0], legs[1], "the person walks");
    run(&mut devices, &mut injector, 3_000, false);
    assert_eq!(devices.world().lidar_scene().solids().len(), base);
}

#[test]
fn a_wheel_slip_burst_loosens_the_grip_and_ends() {
    let mut devices = devices();
    let mut injector = FaultInjector::new(plan(FaultKind::WheelSlip, 100, Some(600), 3), vec![]);
    run(&mut devices, &mut injector, 1_000, false);
    // The world counts every step with less than full grip: the 500 ms of the burst.
    let steps = devices.world().stats().slip_steps;
    assert!((495..=505).contains(&steps), "{steps}");
}

#[test]
fn a_part_slips_off_the_magnet_out_of_its_slot_and_leaves_the_switch() {
    let mut devices = devices();
    // The magnet picks the part at the robot's face first; the slip is due at 1 s, but
    // comes only once the part is out of its slot.
    let mut injector = FaultInjector::new(plan(FaultKind::PartSlip, 1_000, None, 4), vec![]);
    run(&mut devices, &mut injector, 900, true);
    assert!(devices.world().shop().carried().is_some(), "picked");
    run(&mut devices, &mut injector, 1_200, true);
    assert_eq!(injector.injected(), [false], "not while in the slot");
    let reverse = Mecanum::new(&Config::default().robot)
        .inverse(BodyTwist::new(-0.2, 0.0, 0.0))
        .map(|w| w as f32);
    let backing_out = WheelCommand {
        wheel_speeds_rad_s: reverse,
        solenoid_on: true,
        ..WheelCommand::STOP
    };
    run_with(&mut devices, &mut injector, 2_500, backing_out);
    assert_eq!(injector.injected(), [true]);
    let world = devices.world();
    assert_eq!(world.shop().carried(), None);
    assert!(
        world
            .shop()
            .parts()
            .iter()
            .any(|p| matches!(p.place, PartPlace::Floor(_)))
    );
    assert_eq!(world.shop().switch_contact(world.body().pose), None);
}

#[test]
fn a_knocked_part_leaves_its_slot() {
    let mut devices = devices();
    let mut injector = FaultInjector::new(plan(FaultKind::PartKnocked, 100, Some(100), 5), vec![]);
    run(&mut devices, &mut injector, 200, false);
    assert_eq!(injector.injected(), [true]);
    let shop = devices.world().shop();
    let knocked: Vec<_> = shop
        .parts()
        .iter()
        .filter_map(|p| match p.place {
            PartPlace::Floor(pose) => Some(pose),
            _ => None,
        })
        .collect();
    assert_eq!(knocked.len(), 1);
    let field = Field::competition();
    let from_slot = (0..4)
        .filter_map(|k| field.incoming_slot(k))
        .map(|s| s.box_center.distance(knocked[0].position()))
        .fold(f64::INFINITY, f64::min);
    assert!((0.0099..0.035).contains(&from_slot), "{from_slot} m");
    let in_slots = shop
        .parts()
        .iter()
        .filter(|p| matches!(p.place, PartPlace::Slot(_)))
        .count();
    assert_eq!(in_slots, 3);
}

#[test]
fn a_mega_reset_goes_silent_then_reboots_and_a_gone_mega_never_speaks_again() {
    for (kind, end_ms) in [
        (FaultKind::MegaReset, Some(1_500)),
        (FaultKind::MegaGone, None),
    ] {
        let mut devices = devices();
        let mut injector = FaultInjector::new(plan(kind, 1_000, end_ms, 6), vec![]);
        let inputs = run(&mut devices, &mut injector, 2_500, true);
        let telemetry = times(&inputs, |i| matches!(i, Input::Wheels(_)));
        let resets = times(&inputs, |i| matches!(i, Input::MegaReset));
        assert!(telemetry.iter().any(|t| *t < 1_000));
        assert!(
            !telemetry.iter().any(|t| (1_015..1_500).contains(t)),
            "{kind}: {telemetry:?}"
        );
        match kind {
            FaultKind::MegaReset => {
                assert_eq!(resets.len(), 2, "boot and reboot: {resets:?}");
                assert!(telemetry.iter().any(|t| *t > 1_550), "{telemetry:?}");
            }
            _ => {
                assert_eq!(resets.len(), 1);
                assert!(telemetry.iter().all(|t| *t < 1_015), "{telemetry:?}");
                let actuation = devices.world().actuation();
                assert_eq!(actuation.pwm, [0; 4]);
                assert!(!actuation.solenoid_on, "the magnet has no current");
            }
        }
    }
}

#[test]
fn an_unplugged_mega_is_reported_then_reopened_at_the_threads_next_try_and_reset() {
    let mut devices = devices();
    // Out from 1.0 s to 1.7 s; the thread tries every 500 ms from the unplug: it reopens
    // the port at 2.0 s, which resets the board, back 0.5 s later.
    let mut injector =
        FaultInjector::new(plan(FaultKind::MegaReplug, 1_000, Some(1_700), 8), vec![]);
    let inputs = run(&mut devices, &mut injector, 3_000, true);
    let faults = times(&inputs, |i| {
        matches!(
            i,
            Input::DeviceFault {
                device: DeviceKind::Mega,
                reconnecting: true,
                ..
            }
        )
    });
    assert_eq!(faults, [1_000]);
    let telemetry = times(&inputs, |i| matches!(i, Input::Wheels(_)));
    assert!(telemetry.iter().any(|t| *t < 1_000));
    assert!(
        !telemetry.iter().any(|t| (1_001..2_500).contains(t)),
        "nothing passes the cable, nor before the reset board boots: {telemetry:?}"
    );
    assert!(telemetry.iter().any(|t| *t > 2_500), "{telemetry:?}");
    let resets = times(&inputs, |i| matches!(i, Input::MegaReset));
    assert_eq!(
        resets.len(),
        2,
        "boot, and the reset of the reopening: {resets:?}"
    );
    assert!((2_500..2_520).contains(&resets[1]), "{resets:?}");
}

#[test]
fn an_unplugged_lidar_is_reported_once_then_streams_again_after_its_port_is_reopened() {
    let mut devices = devices();
    let mut injector =
        FaultInjector::new(plan(FaultKind::LidarReplug, 1_000, Some(1_200), 9), vec![]);
    let inputs = run(&mut devices, &mut injector, 3_000, false);
    let faults = times(&inputs, |i| matches!(i, Input::DeviceFault { .. }));
    assert_eq!(faults, [1_000], "the lost port, not a silence too");
    let scans = scans(&inputs);
    assert!(scans.iter().any(|(t, _)| *t < 1_000));
    assert!(
        !scans.iter().any(|(t, _)| (1_001..1_500).contains(t)),
        "nothing until the thread's next try at 1.5 s: {scans:?}"
    );
    assert!(
        scans.iter().filter(|(t, n)| *t > 1_500 && *n > 50).count() >= 5,
        "{scans:?}"
    );
}

#[test]
fn serial_garbage_reaches_the_megas_line() {
    let mut devices = devices();
    let mut injector =
        FaultInjector::new(plan(FaultKind::SerialGarbage, 500, Some(500), 7), vec![]);
    let inputs = run(&mut devices, &mut injector, 1_000, false);
    assert_eq!(injector.injected(), [true]);
    // The link still delivers telemetry after the burst.
    assert!(
        inputs
            .iter()
            .any(|(t, i)| *t > 600 && matches!(i, Input::Wheels(_)))
    );
}

#[test]
fn line_noise_arrives_among_the_telemetry() {
    let config = Config::default();
    let mut world = crate::world::World::new(&config, &Scenario::new(&config));
    world.step();
    world.receive_from_mega();
    world.inject_from_mega(b"\xff\x00noise");
    for _ in 0..10 {
        world.step();
    }
    let bytes = world.receive_from_mega();
    assert!(bytes.windows(7).any(|w| w == b"\xff\x00noise"), "{bytes:?}");
}

#[test]
fn a_failing_imu_sends_no_sample_again() {
    let mut devices = devices();
    let mut injector = FaultInjector::new(plan(FaultKind::ImuFailure, 500, None, 8), vec![]);
    let inputs = run(&mut devices, &mut injector, 1_000, false);
    let imu: Vec<u64> = inputs
        .iter()
        .filter(|(_, i)| matches!(i, Input::Imu(_)))
        .map(|(t, _)| *t)
        .collect();
    assert!(imu.iter().any(|t| *t < 500));
    assert!(imu.iter().all(|t| *t <= 500), "{imu:?}");
    assert!(devices.imu_failures() >= 99);
}

#[test]
fn server_faults_touch_answers_only_in_their_window() {
    let at = |kind| plan(kind, 1_000, Some(2_000), 9);
    assert_eq!(at(FaultKind::ServerSilent).server_fault(999_999), None);
    assert_eq!(
        at(FaultKind::ServerSilent).server_fault(1_000_000),
        Some(ServerFault::Silent)
    );
    assert_eq!(
        at(FaultKind::ServerDuplicate).server_fault(1_500_000),
        Some(ServerFault::Duplicate)
    );
    assert!(matches!(
        at(FaultKind::ServerLate).server_fault(1_999_999),
        Some(ServerFault::Late(us)) if (200_000..=1_000_000).contains(&us)
    ));
    assert!(matches!(
        at(FaultKind::ServerGarbage).server_fault(1_500_000),
        Some(ServerFault::Garbage(_))
    ));
    assert_eq!(at(FaultKind::ServerGarbage).server_fault(2_000_000), None);
}

#[test]
fn a_plan_is_drawn_in_its_window_and_the_same_for_the_same_seed() {
    let a = FaultPlan::draw(&FaultKind::ALL, 11, 2_000_000..30_000_000);
    assert_eq!(
        a,
        FaultPlan::draw(&FaultKind::ALL, 11, 2_000_000..30_000_000)
    );
    assert_ne!(
        a,
        FaultPlan::draw(&FaultKind::ALL, 12, 2_000_000..30_000_000)
    );
    // Slip and garbage come in three bursts.
    assert_eq!(a.events.len(), FaultKind::ALL.len() + 4);
    assert!(
        a.events
            .iter()
            .all(|e| (2_000_000..30_000_000).contains(&e.start_us) && e.end_us >= e.start_us)
    );
    let dropout = a
        .events
        .iter()
        .find(|e| e.kind == FaultKind::LidarDropout)
        .unwrap();
    assert!((500_000..=3_000_000).contains(&(dropout.end_us - dropout.start_us)));
    let mixed = FaultPlan::draw_mixed(3, 11, 2_000_000..30_000_000);
    assert!(mixed.events.iter().all(|e| e.kind.recoverable()));
    assert!(mixed.first_unrecoverable().is_none());
}
