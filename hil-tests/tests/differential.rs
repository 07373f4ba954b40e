//! Differential test: the ELF against `ratf_protocol::mcu::Mcu` on the host.
//!
//! The firmware runs a scripted 20-period session: command batches (speed references,
//! `K`, `L`, the stop on the switch `U` armed across a press and disarmed, the controller
//! settings `M`..`T` with one refused value), garbage, a
//! corrupted batch, a silence long enough to trip the watchdog and a
//! resume, encoder edges and skipped transitions, and switch presses. The host `Mcu` gets
//! the same bytes at the same times (on the firmware's clock), the same encoder deltas per
//! control tick, the same switch level and the same invalid-transition counts. Then:
//!
//! - every byte the firmware sent equals what the host `Mcu` produced (boot batch and each
//!   telemetry batch, checksums included);
//! - after every tick, the motor PWMs on the simulated PCA9685 and the solenoid pin equal
//!   the host's `Actuation`.
//!
//! Timing: batch n's first byte is at cycle B(n). The firmware closes control window n
//! some time L before B(n) (measured ≈ 5.5 ms with the firmware of 2026-11-21: the tick's
//! computation comes before the first byte) and B(n) jitters by up to ±1.5 ms, so every
//! event of period n is placed in B(n) + 2.5 ms … B(n) + 10.5 ms, which lies between the
//! same two window closes for the firmware and the host as long as 0 < L < 8 ms.
//! The host's tick times are the firmware's own clock: T(n) = T(n−1) + the period `k` the
//! firmware reported in batch n (the Mega's clock is an input of `Mcu`, like the encoder
//! deltas); a byte chunk sent at B(n) + d reaches the host `Mcu` at T(n) + d + its
//! transmission time.

use ratf_hil_tests::host_link::{HostLink, wheel_speeds};
use ratf_hil_tests::shield::signed_pwms;
use ratf_hil_tests::sim::{CYCLES_PER_MS, CYCLES_PER_US, Hil, UART_BYTE_CYCLES};
use ratf_hil_tests::telemetry::TelemetryBatch;
use ratf_protocol::mcu::{Actuation, Mcu, McuConfig, TickInputs};
use ratf_protocol::messages::{Command, Wheel};
use ratf_protocol::settings::Setting;

const PERIODS: usize = 20;

/// What happens during one control period of the script.
#[derive(Default)]
struct Period {
    /// Byte chunks sent at +3 ms and +6 ms (each ≤ 45 bytes ≈ 4.2 ms on the line).
    sends: Vec<Vec<u8>>,
    /// Net edges per wheel (from +4 ms, 100 µs apart, at most 20: done by +6 ms).
    edges: [i64; 4],
    /// Skipped transitions per wheel (after the edges).
    skips: [u32; 4],
    /// New switch level at +10.5 ms.
    switch_pressed: Option<bool>,
}

fn script() -> Vec<Period> {
    let mut host = HostLink::new(true);
    let mut periods: Vec<Period> = (0..PERIODS)
        .map(|n| Period {
            edges: std::array::from_fn(|k| ((n * 7 + k * 13) % 41) as i64 - 20),
            ..Period::default()
        })
        .collect();
    let refs = [1.5, -2.0, 3.0, -4.0];
    let mut with_solenoid = wheel_speeds(refs);
    with_solenoid.push(Command::Solenoid { on: true });
    periods[1].sends.push(host.batch(&with_solenoid));
    periods[2].sends.push(host.batch(&wheel_speeds(refs)));
    let mut with_k = wheel_speeds(refs);
    with_k.push(Command::MotorPwm {
        wheel: Wheel::FrontRight,
        pwm: -80,
    });
    periods[3].sends.push(host.batch(&with_k));
    periods[4].sends.push(b"xyzq\x00\xffG12 ".to_vec());
    // The stop on the switch armed before the press below, disarmed two periods later.
    let mut armed = wheel_speeds(refs);
    armed.push(Command::StopOnSwitch { armed: true });
    periods[4].sends.push(host.batch(&armed));
    periods[4].skips = [0, 2, 0, 1];
    periods[4].switch_pressed = Some(true);
    let mut corrupted = host.batch(&[Command::MotorPwm {
        wheel: Wheel::BackRight,
        pwm: 200,
    }]);
    corrupted[6] = b'7';
    periods[5].sends.push(corrupted);
    // The settings in two batches of four (45 bytes each, within the period's window),
    // each after the period's references (batches are made in sending order: each carries
    // the next sequence number); the voltage limit above the new battery is refused.
    let setting = |setting, value| Command::Setting { setting, value };
    let mut disarmed = wheel_speeds(refs);
    disarmed.push(Command::StopOnSwitch { armed: false });
    periods[6].sends.push(host.batch(&disarmed));
    periods[6].sends.push(host.batch(&[
        setting(Setting::Kc, 0.7),
        setting(Setting::Ki, 6.5),
        setting(Setting::Kf, 0.05),
        setting(Setting::DeadZoneV0, 0.2),
    ]));
    periods[7].sends.push(host.batch(&wheel_speeds(refs)));
    periods[7].sends.push(host.batch(&[
        setting(Setting::DeadZoneVd, 0.1),
        setting(Setting::BatteryVoltage, 12.0),
        setting(Setting::VoltageLimit, 12.5),
        setting(Setting::TicksPerWheelRev, 1401.6),
    ]));
    periods[9].switch_pressed = Some(false);
    periods[10].skips = [1, 0, 0, 0];
    // Periods 8..=14: silence; the watchdog trips. Period 15 resumes.
    for period in &mut periods[15..] {
        period.sends.push(host.batch(&wheel_speeds([2.0; 4])));
    }
    periods[16].sends.push(b"L00000001".to_vec());
    periods
}

/// Run until the `index`-th (0-based) `g` byte, i.e. the start of telemetry batch `index`;
/// returns its cycle.
fn run_until_batch_start(hil: &mut Hil, index: usize) -> u64 {
    let mut seen = 0;
    let mut scanned = 0;
    let mut at = None;
    let found = hil.run_until_rx(60 * CYCLES_PER_MS, |rx| {
        for byte in &rx[scanned..] {
            if byte.byte == b'g' {
                if seen == index {
                    at = Some(byte.cycle);
                }
                seen += 1;
            }
        }
        scanned = rx.len();
        at.is_some()
    });
    assert!(found, "telemetry batch {index} never started");
    at.unwrap_or(0)
}

/// A host chunk: bytes and when (µs after the period's batch start) they were delivered.
struct Delivery {
    offset_us: u32,
    bytes: Vec<u8>,
}

#[test]
fn firmware_transcript_equals_the_host_mcu() {
    let mut hil = Hil::boot_or_panic();
    let periods = script();
    let mut deliveries: Vec<Vec<Delivery>> = Vec::new();
    // The firmware sends a tick's telemetry before it runs the controllers and writes the
    // shield, so a tick's PWMs are certain to be on the shield only just before the next
    // batch starts; the solenoid follows at once and is read 2.5 ms into the batch.
    let mut pwms_by_tick: Vec<[i16; 4]> = Vec::new();
    let mut solenoid_by_tick: Vec<bool> = Vec::new();
    let mut starts = Vec::new();
    for (n, period) in periods.iter().enumerate() {
        let start = run_until_batch_start(&mut hil, n);
        if n > 0 {
            pwms_by_tick.push(signed_pwms(&hil.shield()));
        }
        starts.push(start);
        let at = |ms_x10: u64| start + ms_x10 * CYCLES_PER_MS / 10;
        hil.run_until(at(25));
        solenoid_by_tick.push(hil.solenoid_on());
        let mut delivered = Vec::new();
        for (i, bytes) in period.sends.iter().enumerate() {
            let send_at = at(30 + 30 * i as u64);
            hil.run_until(send_at);
            hil.send(bytes);
            let done = hil.cycle() + bytes.len() as u64 * UART_BYTE_CYCLES;
            delivered.push(Delivery {
                offset_us: ((done - start) / CYCLES_PER_US) as u32,
                bytes: bytes.clone(),
            });
        }
        deliveries.push(delivered);
        hil.run_until(at(40));
        let longest = period
            .edges
            .iter()
            .map(|e| e.unsigned_abs())
            .max()
            .unwrap_or(0);
        for i in 0..longest {
            hil.run_for_us(100);
            hil.update_lines(|lines| {
                for (wheel, &e) in period.edges.iter().enumerate() {
                    if i < e.unsigned_abs() {
                        lines.step(wheel, e > 0);
                    }
                }
            });
        }
        for (wheel, &skips) in period.skips.iter().enumerate() {
            for _ in 0..skips {
                hil.run_for_us(100);
                hil.update_lines(|lines| lines.skip(wheel));
            }
        }
        hil.run_until(at(105));
        if let Some(pressed) = period.switch_pressed {
            hil.set_switch_pressed(pressed);
        }
    }
    // Let the last batch finish; the last tick's PWMs are on the shield by the next batch.
    run_until_batch_start(&mut hil, PERIODS);
    pwms_by_tick.push(signed_pwms(&hil.shield()));
    let sampled: Vec<([i16; 4], bool)> = pwms_by_tick.into_iter().zip(solenoid_by_tick).collect();

    // The host side, period by period.
    let firmware_batches = hil.batches();
    let mut mcu = Mcu::new(McuConfig::default());
    let mut expected: Vec<Vec<u8>> = vec![mcu.boot().as_bytes().to_vec()];
    let mut actuations: Vec<(Actuation, bool)> = Vec::new();
    let mut stopped_on_switch = Vec::new();
    let mut now_us: u32 = 0;
    let mut switch_pressed = false;
    let mut skips_total = [0u8; 4];
    for n in 0..PERIODS {
        let fw = TelemetryBatch::parse(&firmware_batches[n + 1])
            .unwrap_or_else(|e| panic!("firmware batch {n}: {e}"));
        if n > 0 {
            now_us = now_us.wrapping_add(fw.period_us);
        }
        let inputs = TickInputs {
            encoder_deltas: if n == 0 {
                [0; 4]
            } else {
                periods[n - 1].edges.map(|e| e as i16)
            },
            switch_pressed,
            quadrature_errors: skips_total,
            i2c_faults: 0,
            serial_bytes_dropped: 0,
        };
        let out = mcu.control_tick(now_us, &inputs);
        expected.push(out.telemetry.as_bytes().to_vec());
        actuations.push((out.actuation, mcu.solenoid_on()));
        stopped_on_switch.push(mcu.stopped_on_switch());
        for d in &deliveries[n] {
            mcu.receive(&d.bytes, now_us.wrapping_add(d.offset_us));
        }
        if let Some(pressed) = periods[n].switch_pressed {
            switch_pressed = pressed;
        }
        for (total, &s) in skips_total.iter_mut().zip(&periods[n].skips) {
            *total = total.wrapping_add(s as u8);
        }
    }

    for (i, expected_bytes) in expected.iter().enumerate() {
        let got: Vec<u8> = firmware_batches[i]
            .frames
            .iter()
            .flat_map(|f| f.encode())
            .collect();
        assert_eq!(
            String::from_utf8_lossy(&got),
            String::from_utf8_lossy(expected_bytes),
            "batch {i} (0 = boot) differs from the host Mcu's"
        );
    }
    for (n, ((pwms, solenoid), (actuation, host_solenoid))) in
        sampled.iter().zip(&actuations).enumerate()
    {
        assert_eq!(
            (*pwms, *solenoid),
            (actuation.pwm, *host_solenoid),
            "after tick {n}: shield PWMs / solenoid differ from the host Mcu's"
        );
    }
    // The script did exercise what it claims: motors driven, K applied (wheel 2 has a
    // positive reference, so only K can make it negative), watchdog tripped.
    for (n, (a, solenoid)) in actuations.iter().enumerate() {
        println!("tick {n}: pwm {:?} solenoid {solenoid}", a.pwm);
    }
    assert!(actuations.iter().any(|(a, _)| a.pwm[2] < 0));
    assert!(actuations[12..15].iter().any(|(a, _)| a.pwm == [0; 4]));
    assert!(actuations[PERIODS - 1].0.pwm.iter().all(|&p| p > 0));
    assert!(actuations.iter().any(|(_, s)| *s));
    assert!(stopped_on_switch[5] && !stopped_on_switch[PERIODS - 1]);
    let last = TelemetryBatch::parse(&firmware_batches[PERIODS])
        .unwrap_or_else(|e| panic!("last firmware batch: {e}"));
    let limit = Setting::VoltageLimit.bit();
    assert_eq!(
        (last.settings_ack.applied, last.settings_ack.refused),
        (!limit, limit),
        "seven settings applied, the limit above the battery refused"
    );
    assert_eq!(mcu.config().pi.gains.kc_v_per_rad_s, 0.7);
}
