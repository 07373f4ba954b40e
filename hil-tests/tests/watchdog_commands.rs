//! The host's commands as the motor shield and the pins see them: the watchdog (motors off
//! 100 ms after the last `G`/`K` and the solenoid released 300 ms after that, telemetry still
//! flowing, a new `G` resumes), `K` direct PWM with its slew limit, `L` solenoid, and the
//! switch on `s`.

use ratf_hil_tests::host_link::{HostLink, command_all_wheels, wheel_speeds};
use ratf_hil_tests::shield::signed_pwms;
use ratf_hil_tests::sim::{CYCLES_PER_MS, Hil};
use ratf_hil_tests::watchdog::measure_watchdog;
use ratf_protocol::mcu::SOLENOID_HOLD_AFTER_STOP_US;
use ratf_protocol::messages::{Command, Wheel};

#[test]
fn watchdog_stops_motors_and_solenoid_and_telemetry_keeps_flowing() {
    let mut hil = Hil::booted();
    let run = measure_watchdog(&mut hil, 500);
    println!(
        "{run:?}: trip began {:?} ms, the motors were stopped {:?} ms and the solenoid released \
         {:?} ms after the last G",
        run.trip_ms(),
        run.stop_ms(),
        run.release_ms()
    );
    let trip_ms = run.trip_ms().unwrap_or(f64::INFINITY);
    let stop_ms = run
        .stop_ms()
        .expect("motors still driven 500 ms after the last G");
    let release_ms = run
        .release_ms()
        .expect("solenoid still on 500 ms after the last G");
    // The trip happens at the first control tick more than 100 ms after the last feed
    // (≤ 120 ms after it), and the I2C writes that turn the motors off follow at once.
    assert!(
        trip_ms > 100.0,
        "a motor stopped {trip_ms:.2} ms after the last G: too early"
    );
    assert!(
        stop_ms <= 125.0,
        "motors all off only {stop_ms:.2} ms after the last G, expected ≤ 125"
    );
    // The solenoid holds the part while the wheels coast down, and lets go at the tick
    // `SOLENOID_HOLD_AFTER_STOP_US` after the stop's (within the stop's I2C writes).
    let hold_ms = f64::from(SOLENOID_HOLD_AFTER_STOP_US) / 1000.0;
    assert!(
        (release_ms - trip_ms - hold_ms).abs() < 10.0,
        "the solenoid let go {release_ms:.2} ms after the last G, the motors stopped at \
         {trip_ms:.2} ms: expected {hold_ms} ms later"
    );
    assert!(run.stayed_stopped, "something restarted without a G/K");
    // 500 ms without a host is 25 control periods: telemetry never stopped.
    assert!(
        run.batches_after_feed >= 24,
        "only {} telemetry batches in the 500 ms after the last G",
        run.batches_after_feed
    );

    // A new G resumes control (the solenoid stays released until a new L).
    let pwms = command_all_wheels(&mut hil, 10.0, 3);
    assert!(
        pwms.iter().all(|&p| p > 0),
        "control did not resume after a new G: PWMs {pwms:?}"
    );
    assert!(!hil.solenoid_on(), "the solenoid came back without an L");
}

#[test]
fn k_drives_one_motor_open_loop_with_the_slew_limit() {
    let mut hil = Hil::booted();
    let mut host = HostLink::new(true);
    let (first_batch, _) = hil.telemetry_batches()[0];
    // Send mid-period, then sample the shield mid-period of each following tick.
    hil.run_until(first_batch + 5 * CYCLES_PER_MS);
    hil.send(&host.batch(&[Command::MotorPwm {
        wheel: Wheel::FrontRight,
        pwm: -250,
    }]));
    let mut seen = Vec::new();
    for n in 1..=4 {
        hil.run_until(first_batch + n * 20 * CYCLES_PER_MS + 10 * CYCLES_PER_MS);
        seen.push(signed_pwms(&hil.shield()));
    }
    println!("{seen:?}");
    // Slew limit 100 per tick (original-system.md §2.2): -100, -200, -250, -250.
    let wheel2: Vec<i16> = seen.iter().map(|p| p[2]).collect();
    assert_eq!(wheel2, [-100, -200, -250, -250]);
    for p in &seen {
        assert_eq!([p[0], p[1], p[3]], [0, 0, 0], "other motors must stay off");
    }
}

#[test]
fn l_switches_the_solenoid() {
    let mut hil = Hil::booted();
    let mut host = HostLink::new(true);
    assert!(!hil.solenoid_on(), "solenoid on at boot");
    let mut on = wheel_speeds([0.0; 4]);
    on.push(Command::Solenoid { on: true });
    hil.send(&host.batch(&on));
    hil.run_for_ms(10);
    assert!(
        hil.solenoid_on(),
        "L1 with a G did not switch the solenoid on"
    );
    let mut off = wheel_speeds([0.0; 4]);
    off.push(Command::Solenoid { on: false });
    hil.send(&host.batch(&off));
    hil.run_for_ms(10);
    assert!(!hil.solenoid_on(), "L0 did not switch the solenoid off");
}

#[test]
fn switch_level_is_reported_on_s() {
    let mut hil = Hil::booted();
    assert!(
        !hil.latest_telemetry()
            .expect("no telemetry batch")
            .switch_pressed
    );
    hil.set_switch_pressed(true);
    let n = hil.telemetry_batches().len();
    assert!(hil.run_until_telemetry_batches(n + 2, 60 * CYCLES_PER_MS));
    assert!(
        hil.latest_telemetry()
            .expect("no telemetry batch")
            .switch_pressed,
        "s: pressed not reported"
    );
    hil.set_switch_pressed(false);
    let n = hil.telemetry_batches().len();
    assert!(hil.run_until_telemetry_batches(n + 2, 60 * CYCLES_PER_MS));
    assert!(
        !hil.latest_telemetry()
            .expect("no telemetry batch")
            .switch_pressed,
        "s: release not reported"
    );
}
