//! Encoder counting: exact counts on all four wheels in both directions, invalid
//! (skipped) transitions reported on `q`, and no lost edge at 25 000 edges/s — more than
//! twice the motor's top speed (≈ 11 700 edges/s, avr-toolchain.md's original-firmware
//! table). The highest lossless rate itself is measured by the `hil_report` binary.

use ratf_hil_tests::edge_rate::run_trial;
use ratf_hil_tests::sim::{CYCLES_PER_MS, Hil};

/// Move wheel k by `edges[k]` edges (sign = direction), one edge per wheel every
/// `spacing_us`, then wait two control periods.
fn drive(hil: &mut Hil, edges: [i64; 4], spacing_us: u64) {
    let longest = edges.iter().map(|e| e.unsigned_abs()).max().unwrap_or(0);
    for i in 0..longest {
        hil.run_for_us(spacing_us);
        hil.update_lines(|lines| {
            for (wheel, &n) in edges.iter().enumerate() {
                if i < n.unsigned_abs() {
                    lines.step(wheel, n > 0);
                }
            }
        });
    }
    let seen = hil.telemetry_batches().len();
    assert!(hil.run_until_telemetry_batches(seen + 2, 60 * CYCLES_PER_MS));
}

#[test]
fn counts_are_exact_on_all_four_wheels_both_ways() {
    let mut hil = Hil::booted();
    let start = hil.latest_telemetry().expect("no telemetry batch");
    assert_eq!(start.ticks, [0; 4], "ticks before any edge");

    let forward = [1000, -1100, 1200, -1300];
    drive(&mut hil, forward, 40);
    let t = hil.latest_telemetry().expect("no telemetry batch");
    assert_eq!(t.ticks, [1000, -1100, 1200, -1300]);

    let back = [-1400, 1500, -1600, 1700];
    drive(&mut hil, back, 30);
    let t = hil.latest_telemetry().expect("no telemetry batch");
    assert_eq!(t.ticks, [-400, 400, -400, 400]);
    assert_eq!(
        t.quadrature_errors, [0; 4],
        "no invalid transition was driven"
    );
}

#[test]
fn skipped_transitions_are_counted_in_q_and_not_as_ticks() {
    let mut hil = Hil::booted();
    for wheel in 0..4 {
        for _ in 0..=wheel {
            hil.run_for_us(100);
            hil.update_lines(|lines| lines.skip(wheel));
        }
    }
    // A few valid edges after the skips still count.
    drive(&mut hil, [3, 3, -3, -3], 100);
    let t = hil.latest_telemetry().expect("no telemetry batch");
    assert_eq!(t.quadrature_errors, [1, 2, 3, 4]);
    assert_eq!(t.ticks, [3, 3, -3, -3]);
}

#[test]
fn no_edge_lost_at_25_000_edges_per_second() {
    let trial = run_trial(25_000.0, 2_000).unwrap_or_else(|e| panic!("{e}"));
    println!("{trial:?}");
    assert!(trial.lossless(), "lost edges at 25 kHz: {trial:?}");
    // A sanity check of the trial itself: it did drive edges.
    assert_eq!(trial.expected, [2000, -2000, 2000, -2000]);
}
