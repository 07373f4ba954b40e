//! The controller settings channels `M`..`T` on the firmware ELF: invalid values are
//! refused and reported on `y`, valid ones are acknowledged, and the firmware's speed loop
//! then behaves as `protocol::mcu::Mcu` predicts with those settings.
//!
//! The settings are the original firmware's gains ([`PiGains::ORIGINAL`]: half the Kc and
//! Ki, plus a 0.456 V/(rad/s) feed-forward), which on the simulated motor overshoot a
//! 10 rad/s step by about 16 % where the compiled defaults do not overshoot at all, so the
//! step response tells the two apart. The plant and the host's 20 ms resend are those of
//! `tests/closed_loop.rs`.

use ratf_hil_tests::closed_loop::{PlantLoop, SettlingMeter, reference_settling};
use ratf_hil_tests::host_link::{HostLink, wheel_speeds};
use ratf_hil_tests::sim::{CLOCK_HZ, CYCLES_PER_MS, Hil};
use ratf_protocol::mcu::McuConfig;
use ratf_protocol::messages::Command;
use ratf_protocol::pi::PiGains;
use ratf_protocol::settings::{Setting, SettingsAck};

const RUN_S: f64 = 1.5;
const REFERENCE_RAD_S: f32 = 10.0;
/// Three control periods, as in `tests/closed_loop.rs` (see its module documentation).
const SETTLE_TOLERANCE_S: f64 = 0.060;
/// How far the firmware's peak may be from the reference Mcu's, rad/s (the command's
/// landing time within the period differs, as for the settling time).
const PEAK_TOLERANCE_RAD_S: f64 = 0.3;

/// Run until `count` more telemetry batches arrived; the latest batch's `y`.
fn ack_after(hil: &mut Hil, count: usize) -> SettingsAck {
    let seen = hil.telemetry_batches().len();
    assert!(
        hil.run_until_telemetry_batches(seen + count, (count as u64 + 2) * 20 * CYCLES_PER_MS),
        "telemetry stopped"
    );
    hil.latest_telemetry().expect("a batch").settings_ack
}

#[test]
fn settings_are_refused_or_acknowledged_and_change_the_step_response_as_predicted() {
    let mut tuned = McuConfig::default();
    tuned.pi.gains = PiGains::ORIGINAL;
    let mut hil = Hil::boot_or_panic();
    let mut host = HostLink::new(true);
    let defaults = ack_after(&mut hil, 1);
    assert_eq!((defaults.applied, defaults.refused), (0, 0));

    let setting = |setting, value| Command::Setting { setting, value };
    hil.send(&host.batch(&[
        setting(Setting::Kc, f32::NAN),
        setting(Setting::Ki, -1.0),
        setting(Setting::VoltageLimit, 12.0),
    ]));
    let refused = ack_after(&mut hil, 2);
    let refused_bits = Setting::Kc.bit() | Setting::Ki.bit() | Setting::VoltageLimit.bit();
    assert_eq!((refused.applied, refused.refused), (0, refused_bits));
    assert_eq!(
        refused.fingerprint, defaults.fingerprint,
        "a refused value was applied"
    );
    assert_eq!(
        hil.latest_telemetry()
            .expect("a batch")
            .faults
            .rx_bad_messages,
        3
    );

    hil.send(&host.batch(&tuned.setting_commands()));
    let ack = ack_after(&mut hil, 2);
    assert!(ack.confirms(&tuned.setting_values()), "{ack:?}");

    let (last_batch_cycle, _) = *hil.telemetry_batches().last().expect("a batch");
    let start = last_batch_cycle + 5 * CYCLES_PER_MS;
    let mut plants = PlantLoop::new();
    plants.run_until(&mut hil, start, |_, _| {});
    let to_s = |cycle: u64| cycle as f64 / CLOCK_HZ as f64;
    let mut meter = SettlingMeter::new(f64::from(REFERENCE_RAD_S), 0.05, to_s(start));
    let end = start + (RUN_S * CLOCK_HZ as f64) as u64;
    let mut next_send = start;
    while hil.cycle() < end {
        if hil.cycle() >= next_send {
            hil.send(&host.batch(&wheel_speeds([REFERENCE_RAD_S, 0.0, 0.0, 0.0])));
            next_send += 20 * CYCLES_PER_MS;
        }
        plants.step(&mut hil);
        meter.sample(to_s(hil.cycle()), plants.speeds_rad_s()[0]);
    }
    let firmware = meter.settling();
    let predicted = reference_settling(tuned, REFERENCE_RAD_S, RUN_S);
    let with_defaults = reference_settling(McuConfig::default(), REFERENCE_RAD_S, RUN_S);
    println!(
        "10 rad/s step with the original gains sent over the wire: firmware {firmware:?}, \
         predicted {predicted:?}; with the compiled defaults {with_defaults:?}"
    );
    assert!(
        predicted.peak_rad_s > with_defaults.peak_rad_s + 1.0,
        "the test needs settings whose response differs from the defaults'"
    );
    assert!(
        (firmware.peak_rad_s - predicted.peak_rad_s).abs() <= PEAK_TOLERANCE_RAD_S,
        "peak {:.2} rad/s, predicted {:.2} (defaults: {:.2})",
        firmware.peak_rad_s,
        predicted.peak_rad_s,
        with_defaults.peak_rad_s
    );
    let settle_s = firmware.settle_s.expect("the wheel settles");
    let predicted_s = predicted.settle_s.expect("the prediction settles");
    assert!(
        (settle_s - predicted_s).abs() <= SETTLE_TOLERANCE_S,
        "settled after {:.0} ms, predicted {:.0} ms",
        settle_s * 1e3,
        predicted_s * 1e3
    );
}
