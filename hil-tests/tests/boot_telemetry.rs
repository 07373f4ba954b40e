//! Boot and telemetry cadence: the firmware sends `r00000000` (+ checksum) at boot, then one
//! telemetry batch `g h i j k s q x z` every 20 ms (±1 %), measured in simulated cycles.

use ratf_hil_tests::sim::{CYCLES_PER_MS, Hil};
use ratf_hil_tests::telemetry::checksum;

/// 20 ms control period (original-system.md §2.2) in cycles at 16 MHz.
const PERIOD_CYCLES: u64 = 20 * CYCLES_PER_MS;
/// ±1 % of the period.
const TOLERANCE_CYCLES: u64 = PERIOD_CYCLES / 100;

#[test]
fn boot_sends_the_reset_frame_first() {
    let mut hil = Hil::boot_or_panic();
    let got_z = hil.run_until_rx(50 * CYCLES_PER_MS, |rx| {
        rx.iter().filter(|b| b.byte == b'z').count() >= 1 && rx.len() >= 18
    });
    assert!(got_z, "no boot batch within 50 ms; received {:?}", hil.rx());
    let first: Vec<u8> = hil.rx()[..9].iter().map(|b| b.byte).collect();
    assert_eq!(
        first, b"r00000000",
        "the first frame must be the reset frame"
    );
    let batches = hil.batches();
    assert_eq!(batches[0].letters(), b"rz");
    assert_eq!(
        checksum(&batches[0]),
        Some((0, true)),
        "boot batch checksum"
    );
}

#[test]
fn one_telemetry_batch_every_20_ms() {
    let mut hil = Hil::boot_or_panic();
    let wanted = 16;
    assert!(
        hil.run_until_telemetry_batches(wanted, (wanted as u64 + 3) * PERIOD_CYCLES),
        "fewer than {wanted} telemetry batches in {} ms: got {}",
        (wanted + 3) * 20,
        hil.telemetry_batches().len()
    );
    let batches = hil.batches();
    // Every batch after the boot batch is a complete, intact telemetry batch, in sequence.
    assert_eq!(batches[0].letters(), b"rz");
    let mut expected_seq = 1u8;
    for batch in &batches[1..] {
        assert!(
            batch.is_telemetry(),
            "batch at cycle {} has letters {:?}",
            batch.cycle,
            String::from_utf8_lossy(&batch.letters())
        );
        assert_eq!(checksum(batch), Some((expected_seq, true)));
        expected_seq = expected_seq.wrapping_add(1);
    }
    let telemetry = hil.telemetry_batches();
    let intervals: Vec<u64> = telemetry.windows(2).map(|w| w[1].0 - w[0].0).collect();
    println!("batch intervals (cycles): {intervals:?}");
    for (i, &interval) in intervals.iter().enumerate() {
        assert!(
            interval.abs_diff(PERIOD_CYCLES) <= TOLERANCE_CYCLES,
            "interval {i} is {interval} cycles ({:.1} µs), not 20 ms ± 1 %",
            interval as f64 / 16.0
        );
    }
    // The period the firmware measures and reports on `k` agrees with the simulator's.
    for (cycle, batch) in &telemetry[1..] {
        assert!(
            u64::from(batch.period_us).abs_diff(20_000) <= 200,
            "k = {} µs at cycle {cycle}",
            batch.period_us
        );
    }
}

#[test]
fn cadence_while_the_host_drives_the_wheels() {
    use ratf_hil_tests::host_link::{HostLink, wheel_speeds};
    let mut hil = Hil::boot_or_panic();
    assert!(hil.run_until_telemetry_batches(1, 60 * CYCLES_PER_MS));
    let from = hil.cycle();
    let mut host = HostLink::new(true);
    // 30 periods of commands (speed references varying every period), then silence: the
    // watchdog trips and the load drops.
    for i in 0..30 {
        let s = (i % 7) as f32 - 3.0;
        hil.send(&host.batch(&wheel_speeds([s, -s, 2.0 * s, 1.0])));
        hil.run_for_ms(20);
    }
    hil.run_for_ms(200);
    let starts: Vec<u64> = hil
        .telemetry_batches()
        .iter()
        .map(|(c, _)| *c)
        .filter(|&c| c > from)
        .collect();
    let intervals: Vec<u64> = starts.windows(2).map(|w| w[1] - w[0]).collect();
    let min = intervals.iter().min().copied().unwrap_or(0);
    let max = intervals.iter().max().copied().unwrap_or(0);
    println!(
        "batch intervals under load: min {:.3} ms, max {:.3} ms over {} intervals",
        min as f64 / CYCLES_PER_MS as f64,
        max as f64 / CYCLES_PER_MS as f64,
        intervals.len()
    );
    assert!(
        intervals.len() >= 38,
        "batches missing: {}",
        intervals.len()
    );
    for (i, &interval) in intervals.iter().enumerate() {
        assert!(
            interval.abs_diff(PERIOD_CYCLES) <= TOLERANCE_CYCLES,
            "interval {i} is {:.3} ms, not 20 ms ± 1 %",
            interval as f64 / CYCLES_PER_MS as f64
        );
    }
}
