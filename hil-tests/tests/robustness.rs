//! Bad input never crashes or stalls the firmware: random garbage, truncated frames and
//! back-to-back batches at the full line rate (simavr paces bytes at 115 200 baud), and in
//! strict mode a corrupted batch is not applied.
//!
//! "Never stalls" is checked as: no telemetry batch is missing or late (every gap between
//! batch starts is 20 ms ± 2.5 ms) throughout, and a valid command afterwards is obeyed.
//! (The ±1 % cadence itself is `boot_telemetry`'s subject; here the load changes with the
//! input, and the batch start moves with the tick's computation time.)

use ratf_hil_tests::host_link::{HostLink, command_all_wheels, wheel_speeds};
use ratf_hil_tests::shield::signed_pwms;
use ratf_hil_tests::sim::{CYCLES_PER_MS, Hil};
use ratf_protocol::messages::{Command, Wheel};

const PERIOD_CYCLES: u64 = 20 * CYCLES_PER_MS;
/// Gap tolerance: an eighth of a period, far below a missing batch (20 ms).
const STALL_TOLERANCE_CYCLES: u64 = PERIOD_CYCLES / 8;

/// xorshift32: deterministic garbage without a dependency.
fn garbage(len: usize, mut state: u32) -> Vec<u8> {
    const ALPHABET: &[u8] = b"GHIJKLZghijz0123456789ABCDEFabcdef\r\n+ ";
    (0..len)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            // Half protocol-looking bytes (so frames start, run and abort), half any byte.
            if state & 0x100 != 0 {
                ALPHABET[(state >> 16) as usize % ALPHABET.len()]
            } else {
                (state >> 24) as u8
            }
        })
        .collect()
}

/// Every telemetry batch after `from_cycle` came 20 ms ± 2.5 ms after the previous one (no
/// batch missing, none stuck), and at least `min_batches` arrived.
fn assert_cadence(hil: &Hil, from_cycle: u64, min_batches: usize) {
    let batches: Vec<u64> = hil
        .telemetry_batches()
        .iter()
        .map(|(c, _)| *c)
        .filter(|&c| c >= from_cycle)
        .collect();
    assert!(
        batches.len() >= min_batches,
        "only {} telemetry batches since cycle {from_cycle}",
        batches.len()
    );
    for w in batches.windows(2) {
        let gap = w[1] - w[0];
        assert!(
            gap.abs_diff(PERIOD_CYCLES) <= STALL_TOLERANCE_CYCLES,
            "telemetry gap of {:.2} ms at cycle {}",
            gap as f64 / CYCLES_PER_MS as f64,
            w[1]
        );
    }
}

/// Send `G` = 10 rad/s to all wheels for three periods and check every motor is driven.
fn assert_obeys_a_g(hil: &mut Hil) {
    let pwms = command_all_wheels(hil, 10.0, 3);
    assert!(
        pwms.iter().all(|&p| p > 0),
        "a valid G was not obeyed: {pwms:?}"
    );
}

#[test]
fn garbage_at_full_line_rate_neither_crashes_nor_stalls() {
    let mut hil = Hil::booted();
    let from = hil.cycle();
    // 3000 bytes ≈ 280 ms of continuous line traffic.
    hil.send(&garbage(3000, 0x1234_5678));
    hil.run_for_ms(320);
    assert_cadence(&hil, from, 15);
    // Garbage may have closed a batch in any state; a space aborts any partial frame.
    hil.send(b" ");
    assert_obeys_a_g(&mut hil);
}

#[test]
fn truncated_frames_are_dropped_and_the_next_frame_is_obeyed() {
    let mut hil = Hil::booted();
    // Original-protocol host (no checksums): a truncated G, a truncated K, then a space
    // (a non-hex byte aborts a frame and is consumed) and a complete K.
    let mut bytes = b"G3F80K020".to_vec();
    bytes.push(b' ');
    bytes.extend_from_slice(
        &Command::MotorPwm {
            wheel: Wheel::BackLeft,
            pwm: 60,
        }
        .to_frame()
        .encode(),
    );
    hil.send(&bytes);
    hil.run_for_ms(80);
    assert_eq!(signed_pwms(&hil.shield()), [0, 60, 0, 0]);
    let t = hil.latest_telemetry().expect("no telemetry batch");
    assert_eq!(t.faults.rx_bad_messages, 0, "a truncated frame was applied");
}

/// `count` batches `G H I J L Z` (54 bytes each) with no idle time between them; the last
/// one (`count` odd) sets the solenoid off, all set positive references.
fn burst(count: usize) -> Vec<u8> {
    let mut host = HostLink::new(true);
    let mut bytes = Vec::new();
    for i in 0..count {
        let mut commands = wheel_speeds([(i + 1) as f32 * 0.1; 4]);
        commands.push(Command::Solenoid { on: i % 2 == 0 });
        bytes.extend(host.batch(&commands));
    }
    bytes
}

#[test]
fn a_burst_of_10_batches_at_full_line_rate_is_received_whole() {
    let mut hil = Hil::booted();
    // 540 bytes ≈ 50 ms of continuous line traffic: 2.5 control periods.
    hil.send(&burst(10));
    hil.run_for_ms(100);
    let t = hil.latest_telemetry().expect("no telemetry batch");
    assert_eq!(
        t.faults.serial_bytes_dropped, 0,
        "the firmware's receive buffer overflowed during a 10-batch burst"
    );
    assert_eq!(
        t.faults.rx_batches_discarded, 0,
        "the firmware lost or rejected batches of a 10-batch burst"
    );
    assert_eq!(t.faults.rx_bad_messages, 0);
    assert!(
        !hil.solenoid_on(),
        "the burst's last batch (L0) was not applied"
    );
    assert!(signed_pwms(&hil.shield()).iter().all(|&p| p > 0));
}

#[test]
fn a_250_ms_burst_at_full_line_rate_neither_crashes_nor_stalls() {
    let mut hil = Hil::booted();
    let from = hil.cycle();
    // 50 batches: 2700 bytes ≈ 250 ms with no idle time on the line.
    hil.send(&burst(50));
    hil.run_for_ms(300);
    assert_cadence(&hil, from, 14);
    let t = hil.latest_telemetry().expect("no telemetry batch");
    println!(
        "250 ms burst: {} of 50 batches discarded, {} bad messages, {} bytes dropped",
        t.faults.rx_batches_discarded, t.faults.rx_bad_messages, t.faults.serial_bytes_dropped
    );
    // Issue 3: no byte lost with both directions at full line rate (telemetry flows all along).
    assert_eq!(t.faults.serial_bytes_dropped, 0);
    assert_eq!(t.faults.rx_batches_discarded, 0);
    assert_eq!(t.faults.rx_bad_messages, 0);
    assert_obeys_a_g(&mut hil);
}

#[test]
fn a_corrupted_batch_is_not_applied_in_strict_mode() {
    let mut hil = Hil::booted();
    let mut host = HostLink::new(true);
    // A first valid batch switches the firmware's receiver to strict mode.
    hil.send(&host.batch(&wheel_speeds([0.0; 4])));
    hil.run_for_ms(20);
    let mut corrupted = host.batch(&[Command::MotorPwm {
        wheel: Wheel::BackRight,
        pwm: 80,
    }]);
    // K00000050 -> K00009050: still a well-formed K (PWM 0x9050 clamps to -255), but the
    // CRC no longer matches.
    corrupted[5] = b'9';
    hil.send(&corrupted);
    // Two control periods later, still well inside the watchdog's 100 ms from the G.
    hil.run_for_ms(45);
    assert_eq!(
        signed_pwms(&hil.shield()),
        [0; 4],
        "the corrupted K was applied"
    );
    let t = hil.latest_telemetry().expect("no telemetry batch");
    assert_eq!(t.faults.rx_batches_discarded, 1);
    // Valid batches are obeyed again afterwards.
    assert_obeys_a_g(&mut hil);
}
