//! The Mega's device thread over a pseudo-terminal against the Mega's own logic
//! (`protocol::mcu`): both watchdogs, unplug and replug, line noise.

use std::time::{Duration, Instant};

use ratf_core::runtime::{DeviceKind, Input, WheelCommand};

use super::fake_mega::{CONTROL_PERIOD, HostBatch};
use super::mega_bench::{MegaBench, tuned_controller};
use crate::devices::{LinkState, Message};

/// What the core commands while it drives: 4 rad/s on every wheel, magnet on.
const DRIVE: WheelCommand = WheelCommand {
    wheel_speeds_rad_s: [4.0; 4],
    solenoid_on: true,
    stop_on_switch: false,
    twist_scale: 1.0,
    open_loop_pwm: None,
};

/// Wait for the Mega's `r`, the link up and a few telemetry batches.
fn synchronise(bench: &mut MegaBench) {
    let since = Instant::now() - Duration::from_secs(60);
    bench.wait_for(
        Duration::from_secs(5),
        None,
        "the Mega's r and its telemetry",
        |b| {
            b.link() == Some(LinkState::Up)
                && b.inputs_since(since).any(|i| *i == Input::MegaReset)
                && b.telemetry_since(since) >= 3
        },
    );
}

/// The Mega's last tick drives every wheel forward with the magnet on.
fn assert_driving(bench: &MegaBench) {
    let tick = bench.mega.ticks.last().expect("ticks");
    assert!(
        tick.pwm.iter().all(|&p| p > 0) && tick.solenoid_on && !tick.timed_out,
        "the Mega should drive: {tick:?}"
    );
}

#[test]
fn the_host_writes_nothing_before_the_megas_r_then_references_drive_the_wheels() {
    let mut bench = MegaBench::start("mega-sync");
    synchronise(&mut bench);
    assert_eq!(
        bench.mega.before_boot,
        [Vec::<u8>::new()],
        "the host wrote while the board was resetting"
    );
    let first = bench
        .inputs_since(Instant::now() - Duration::from_secs(60))
        .find_map(|i| match i {
            Input::Wheels(t) => Some(*t),
            _ => None,
        })
        .expect("telemetry");
    assert_eq!(
        first.deltas_ticks, None,
        "no deltas across the Mega's reset"
    );
    assert!(first.verified, "the Mega's batches carry checksums");
    bench.run_for(Duration::from_millis(300), Some(DRIVE));
    assert_driving(&bench);
    assert!(
        bench
            .mega
            .batches
            .iter()
            .rev()
            .take(5)
            .all(|b| b.is(4.0, true))
    );
}

#[test]
fn a_stalled_core_gets_zero_references_from_the_host_watchdog_until_it_speaks_again() {
    let mut bench = MegaBench::start("mega-host-watchdog");
    synchronise(&mut bench);
    bench.run_for(Duration::from_millis(300), Some(DRIVE));
    assert_driving(&bench);
    // Zeros went out while no core spoke (since the link came up); none while it speaks.
    let watchdog = bench.handle.batches_written().1;
    bench.run_for(Duration::from_millis(200), Some(DRIVE));
    assert_eq!(
        bench.handle.batches_written().1,
        watchdog,
        "a live core is not overridden"
    );

    // The core stalls: nothing calls send_references any more.
    let last_sent = bench.last_sent.expect("references were sent");
    bench.wait_for(
        Duration::from_secs(2),
        None,
        "a stop batch from the host watchdog",
        |b| b.mega.batches_since(last_sent).any(HostBatch::is_stop),
    );
    let first_stop = *bench
        .mega
        .batches_since(last_sent)
        .find(|b| b.is_stop())
        .expect("a stop batch");
    assert!(
        first_stop.at >= last_sent + Duration::from_millis(200),
        "the watchdog fired {:?} after the core's last references, before its 200 ms",
        first_stop.at - last_sent
    );
    assert!(
        bench
            .mega
            .batches_since(last_sent)
            .take_while(|b| !b.is_stop())
            .all(|b| b.is(4.0, true)),
        "only the core's references before the stop"
    );
    bench.wait_for(
        Duration::from_secs(1),
        None,
        "the wheels at rest and the magnet off",
        |b| b.mega.ticks.last().is_some_and(|t| t.stopped()),
    );

    // Stalled on: zeros every control period, never faster.
    let from = Instant::now();
    let span = Duration::from_millis(300);
    bench.run_for(span, None);
    let stops: Vec<&HostBatch> = bench.mega.batches_since(from).collect();
    assert!(stops.iter().all(|b| b.is_stop()), "{stops:?}");
    let most = (span.as_millis() / CONTROL_PERIOD.as_millis()) as usize + 1;
    assert!(
        !stops.is_empty() && stops.len() <= most,
        "{} stop batches in {span:?}",
        stops.len()
    );
    assert!(bench.mega.ticks_since(from).all(|t| t.stopped()));
    let watchdog = bench.handle.batches_written().1;
    assert!(
        watchdog >= stops.len() as u64,
        "watchdog batches {watchdog}"
    );

    // The core speaks again: its references, and the watchdog quiet.
    let resumed = Instant::now();
    bench.wait_for(
        Duration::from_secs(1),
        Some(DRIVE),
        "the core's references again",
        |b| b.mega.batches_since(resumed).any(|x| x.is(4.0, true)),
    );
    let watchdog = bench.handle.batches_written().1;
    bench.run_for(Duration::from_millis(300), Some(DRIVE));
    assert_eq!(bench.handle.batches_written().1, watchdog);
    assert_driving(&bench);
}

#[test]
fn the_megas_own_watchdog_stops_the_wheels_when_the_host_goes_quiet() {
    let mut bench = MegaBench::start("mega-own-watchdog");
    synchronise(&mut bench);
    bench.run_for(Duration::from_millis(300), Some(DRIVE));
    assert_driving(&bench);

    // The host goes quiet: its Mega thread ends and closes the port (as when `ratf` is
    // killed), so nothing writes at all; the board runs on.
    bench.stop_thread();
    let quiet = Instant::now();
    let last_batch = bench.mega.batches.last().expect("batches").at;
    bench.wait_for(Duration::from_secs(1), None, "the Mega's watchdog", |b| {
        b.mega.ticks_since(quiet).any(|t| t.timed_out)
    });
    let trip = *bench
        .mega
        .ticks_since(quiet)
        .find(|t| t.timed_out)
        .expect("a timed-out tick");
    // The wheels stop at once; the solenoid holds the part while they coast down.
    assert_eq!(trip.pwm, [0; 4], "{trip:?}");
    assert!(
        trip.at > last_batch + Duration::from_millis(100),
        "the Mega's watchdog fired {:?} after the last batch, before its 100 ms",
        trip.at - last_batch
    );
    bench.run_for(Duration::from_millis(450), None);
    assert!(
        bench
            .mega
            .ticks_since(trip.at)
            .all(|t| t.pwm == [0; 4] && t.timed_out)
    );
    // The solenoid lets go `SOLENOID_HOLD_AFTER_STOP_US` after the stop (a tick of slack for
    // the wall clock the emulated Mega runs on).
    let hold = Duration::from_micros(u64::from(ratf_protocol::mcu::SOLENOID_HOLD_AFTER_STOP_US));
    let released = trip.at + hold + Duration::from_millis(20);
    assert!(bench.mega.ticks_since(released).count() > 0);
    assert!(bench.mega.ticks_since(released).all(|t| t.stopped()));
    assert_eq!(bench.mega.batches.last().map(|b| b.at), Some(last_batch));
}

#[test]
fn an_unplugged_mega_is_reopened_and_resynchronised_without_restarting() {
    let mut bench = MegaBench::start("mega-replug");
    let port = bench.mega.pty.path();
    synchronise(&mut bench);
    bench.run_for(Duration::from_millis(200), Some(DRIVE));
    assert_driving(&bench);
    assert_eq!(bench.mega.mcu_config(), tuned_controller());
    assert_eq!(
        bench.handle.settings_state(),
        (1, true),
        "sent once, confirmed"
    );

    let unplugged = Instant::now();
    bench.mega.pty.unplug();
    bench.wait_for(
        Duration::from_secs(2),
        None,
        "a device fault naming the port",
        |b| {
            b.link() == Some(LinkState::Reconnecting)
                && b.inputs_since(unplugged).any(|i| {
                    matches!(i, Input::DeviceFault { device: DeviceKind::Mega, message, reconnecting: true }
                        if message.starts_with(&format!("{port}: ")) && message.ends_with("reconnecting"))
                })
        },
    );
    assert!(
        !bench.handle.send_references(&DRIVE, bench.clock.now()),
        "nothing to write to while unplugged"
    );
    // Away for a while: the thread keeps trying, quietly.
    bench.run_for(Duration::from_millis(300), None);
    assert!(bench.thread_running());
    let faults = bench
        .inputs_since(unplugged)
        .filter(|i| matches!(i, Input::DeviceFault { .. }))
        .count();
    assert_eq!(faults, 1, "one fault per loss, not one per retry");

    let replugged = Instant::now();
    bench.mega.pty.replug();
    bench.wait_for(
        Duration::from_secs(3),
        None,
        "the reopened Mega's r and telemetry",
        |b| {
            b.mega.boots.len() == 2
                && b.link() == Some(LinkState::Up)
                && b.inputs_since(replugged).any(|i| *i == Input::MegaReset)
                && b.telemetry_since(replugged) >= 3
        },
    );
    assert_eq!(
        bench.mega.before_boot.len(),
        2,
        "the port was opened once per plug"
    );
    assert!(
        bench.mega.before_boot[1].is_empty(),
        "the host wrote {} byte(s) while the reopened board was resetting",
        bench.mega.before_boot[1].len()
    );
    let links: Vec<LinkState> = bench
        .messages
        .iter()
        .filter(|(at, _)| *at >= unplugged)
        .filter_map(|(_, m)| match m {
            Message::Link(DeviceKind::Mega, state) => Some(*state),
            _ => None,
        })
        .collect();
    assert_eq!(
        links,
        [LinkState::Reconnecting, LinkState::Syncing, LinkState::Up]
    );
    let first = bench
        .inputs_since(replugged)
        .find_map(|i| match i {
            Input::Wheels(t) => Some(*t),
            _ => None,
        })
        .expect("telemetry");
    assert_eq!(first.deltas_ticks, None, "no deltas across the reset");

    let rebooted = bench.mega.boots[1];
    bench.run_for(Duration::from_millis(300), Some(DRIVE));
    assert!(
        bench
            .mega
            .batches_since(rebooted)
            .filter(|b| b.is(4.0, true))
            .count()
            >= 5
    );
    assert_driving(&bench);
    // The reset Mega came back with its compiled defaults; the host sent its settings again.
    assert_eq!(bench.mega.mcu_config(), tuned_controller());
    let (sends, confirmed) = bench.handle.settings_state();
    assert!(
        confirmed && sends >= 2,
        "{sends} settings batches, confirmed {confirmed}"
    );
    assert!(bench.thread_running());
    assert!(
        !bench
            .messages
            .iter()
            .any(|(_, m)| matches!(m, Message::Gone { .. }))
    );
}

#[test]
fn line_noise_both_ways_costs_a_few_batches_and_the_mega_counts_what_it_dropped() {
    let mut bench = MegaBench::start("mega-noise");
    synchronise(&mut bench);
    bench.mega.noisy(7);
    let before = bench.mega.link_stats();
    let from = Instant::now();
    bench.run_for(Duration::from_secs(2), Some(DRIVE));
    let sent = bench.mega.ticks_since(from).count();
    let received = bench.telemetry_since(from);
    println!("line noise: {received} of {sent} telemetry batches received");
    assert!(
        received * 10 >= sent * 8 && received <= sent,
        "{received} of {sent} telemetry batches received"
    );
    // The Mega's side: the host's batches through noise.
    let after = bench.mega.link_stats();
    let accepted = after.batches_ok - before.batches_ok;
    let discarded = after.batches_discarded() - before.batches_discarded();
    let written = bench.mega.batches_since(from).count() as u32;
    println!(
        "line noise: the Mega accepted {accepted} and discarded {discarded} of {written} host \
         batches"
    );
    assert!(discarded > 0, "{after:?}");
    assert!(accepted * 10 >= written * 6, "{after:?}");
    // ... and reported to the host in its `x` frame.
    let faults = bench
        .inputs_since(from)
        .filter_map(|i| match i {
            Input::Wheels(t) => t.faults,
            _ => None,
        })
        .last()
        .expect("the Mega's fault counters");
    assert!(faults.rx_batches_discarded > 0, "{faults:?}");
    let driving = bench
        .mega
        .ticks_since(from)
        .filter(|t| !t.timed_out)
        .count();
    assert!(
        driving * 10 >= sent * 9,
        "driving {driving} of {sent} ticks"
    );
}

#[test]
fn a_run_that_quits_can_still_stop_the_robot() {
    let mut bench = MegaBench::start("mega-quit");
    synchronise(&mut bench);
    bench.run_for(Duration::from_millis(200), Some(DRIVE));
    assert_driving(&bench);
    // Ctrl-C, SIGTERM or a panic elsewhere: every thread is asked to quit, and the Mega's
    // thread ends first (it looks every 5 ms; the loop within a tick).
    bench.stop_thread();
    let quit = Instant::now();
    assert!(
        bench.handle.stop(bench.clock.now()),
        "the way out could not write to the Mega"
    );
    bench.wait_for(
        Duration::from_secs(1),
        None,
        "zero references and magnet off",
        |b| b.mega.batches_since(quit).any(HostBatch::is_stop),
    );
}
