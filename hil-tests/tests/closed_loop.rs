//! The firmware's wheel speed loop closed through simulated motors: the simulated PCA9685
//! gives each motor's voltage (PWM/255 × 11.1 V, sign from the H-bridge inputs), a
//! first-order motor (`ratf_hil_tests::plant`: K = 2.19 (rad/s)/V, τ = 0.1 s, 0.22 V dead
//! zone) turns it into wheel speed, and its encoder edges go back onto `PINA`. The host re-sends the references every 20 ms, 5 ms
//! after each telemetry batch, as the Pi does.
//!
//! Each scenario runs 1.5 s of simulated time once (shared by its two tests):
//! - `*_tracks_the_reference`: every wheel settles into ±5 % and stays there, at about the
//!   same time (±3 control periods) as `protocol::mcu::Mcu` on the same plant (computed on
//!   the host by `reference_settling`). The host model sends its first command at a fixed
//!   5 ms after a tick, while in simavr it lands wherever the telemetry latency puts it, up to
//!   10 ms apart; and the speed approaches the ±5 % band without overshoot, so that small
//!   shift moves the moment it enters the band by up to ~2 periods.
//! - `*_within_300_ms`: issue 3's requirement, settled within 300 ms of the first command.

use ratf_hil_tests::closed_loop::{PlantLoop, Settling, SettlingMeter, reference_settling};
use ratf_hil_tests::host_link::{HostLink, wheel_speeds};
use ratf_hil_tests::sim::{CLOCK_HZ, CYCLES_PER_MS, Hil};
use ratf_protocol::mcu::McuConfig;
use std::sync::OnceLock;

const RUN_S: f64 = 1.5;
const REQUIRED_SETTLE_S: f64 = 0.300;
/// Three control periods: how far the firmware's settling may be from the reference's (see
/// the module doc).
const REFERENCE_TOLERANCE_S: f64 = 0.060;

/// What one scenario measured.
#[derive(Clone, Debug)]
struct Outcome {
    references: [f32; 4],
    firmware: [Settling; 4],
    max_edges_per_step: u64,
}

fn run(references: [f32; 4]) -> Outcome {
    let mut hil = Hil::boot_or_panic();
    assert!(
        hil.run_until_telemetry_batches(1, 60 * CYCLES_PER_MS),
        "no telemetry within 60 ms of boot"
    );
    let (first_batch_cycle, _) = hil.telemetry_batches()[0];
    let start = first_batch_cycle + 5 * CYCLES_PER_MS;
    let mut plants = PlantLoop::new();
    plants.run_until(&mut hil, start, |_, _| {});
    let to_s = |cycle: u64| cycle as f64 / CLOCK_HZ as f64;
    let mut meters = references.map(|r| SettlingMeter::new(f64::from(r), 0.05, to_s(start)));
    let mut host = HostLink::new(true);
    let end = start + (RUN_S * CLOCK_HZ as f64) as u64;
    let mut next_send = start;
    while hil.cycle() < end {
        if hil.cycle() >= next_send {
            hil.send(&host.batch(&wheel_speeds(references)));
            next_send += 20 * CYCLES_PER_MS;
        }
        plants.step(&mut hil);
        let t_s = to_s(hil.cycle());
        for (meter, speed) in meters.iter_mut().zip(plants.speeds_rad_s()) {
            meter.sample(t_s, speed);
        }
    }
    Outcome {
        references,
        firmware: meters.map(|m| m.settling()),
        max_edges_per_step: plants.max_edges_per_step(),
    }
}

fn check_tracks_reference(outcome: &Outcome) {
    println!("{outcome:?}");
    assert!(outcome.max_edges_per_step <= 1, "plant step too coarse");
    for (wheel, (&reference, fw)) in outcome.references.iter().zip(&outcome.firmware).enumerate() {
        if reference == 0.0 {
            continue;
        }
        let expected = reference_settling(McuConfig::default(), reference, RUN_S);
        println!("wheel {wheel}: firmware {fw:?}, reference Mcu {expected:?}");
        let settle_s = fw.settle_s.unwrap_or_else(|| {
            panic!("wheel {wheel} is not within ±5 % of {reference} rad/s at the end: {fw:?}")
        });
        let expected_s = expected.settle_s.unwrap_or(f64::NAN);
        assert!(
            (settle_s - expected_s).abs() <= REFERENCE_TOLERANCE_S,
            "wheel {wheel}: settled after {:.0} ms, the reference Mcu after {:.0} ms",
            settle_s * 1e3,
            expected_s * 1e3
        );
    }
}

fn check_within_300_ms(outcome: &Outcome) {
    for (wheel, (&reference, fw)) in outcome.references.iter().zip(&outcome.firmware).enumerate() {
        if reference == 0.0 {
            continue;
        }
        let settle_s = fw.settle_s.unwrap_or(f64::INFINITY);
        let reference_s = reference_settling(McuConfig::default(), reference, RUN_S)
            .settle_s
            .unwrap_or(f64::INFINITY);
        assert!(
            settle_s <= REQUIRED_SETTLE_S,
            "wheel {wheel} ({reference} rad/s) settled into ±5 % after {:.0} ms, not within \
             300 ms (peak {:.2} rad/s); protocol::mcu's own controller on this plant takes \
             {:.0} ms",
            settle_s * 1e3,
            fw.peak_rad_s,
            reference_s * 1e3
        );
    }
}

fn forward() -> &'static Outcome {
    static OUTCOME: OnceLock<Outcome> = OnceLock::new();
    OUTCOME.get_or_init(|| run([10.0, 0.0, 0.0, 0.0]))
}

fn backward() -> &'static Outcome {
    static OUTCOME: OnceLock<Outcome> = OnceLock::new();
    OUTCOME.get_or_init(|| run([-10.0, 0.0, 0.0, 0.0]))
}

fn all_four() -> &'static Outcome {
    static OUTCOME: OnceLock<Outcome> = OnceLock::new();
    OUTCOME.get_or_init(|| run([10.0, -10.0, 10.0, -10.0]))
}

#[test]
fn forward_10_rad_s_tracks_the_reference() {
    check_tracks_reference(forward());
}

#[test]
fn forward_10_rad_s_within_300_ms() {
    check_within_300_ms(forward());
}

#[test]
fn backward_10_rad_s_tracks_the_reference() {
    check_tracks_reference(backward());
}

#[test]
fn backward_10_rad_s_within_300_ms() {
    check_within_300_ms(backward());
}

#[test]
fn all_four_wheels_track_the_reference() {
    check_tracks_reference(all_four());
}

#[test]
fn all_four_wheels_within_300_ms() {
    check_within_300_ms(all_four());
}
