//! Sessions of the Mega's thread, run by the test itself (the host's link counters live in
//! the thread): on a noisy line, and with a batch from before the reset waiting in the port.

use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use ratf_core::runtime::Input;
use serialport::SerialPort;

use super::{MegaHandle, MegaThread, open_port};
use crate::devices::tests::fake_mega::FakeMega;
use crate::devices::tests::mega_bench::{BOOT_DELAY, settings};
use crate::devices::tests::pty::{Pty, TempDir};
use crate::devices::{Clock, Message, Shared};

/// A Mega's thread for a fresh pseudo-terminal, its session not started: the folder (kept for
/// the test's life), the pty, the run's quit flag, the loop's inbox, the thread and its port.
fn session_on_a_pty(
    name: &str,
) -> (
    TempDir,
    Pty,
    Shared,
    Receiver<Message>,
    MegaThread,
    Box<dyn SerialPort>,
) {
    let dir = TempDir::new(name);
    let pty = Pty::open(&dir.0.join("mega"));
    let settings = settings(pty.path());
    let port = open_port(&settings.port, settings.baud).expect("the pty opens");
    let shared = Shared::new();
    let (tx, rx) = crate::devices::inbox(&shared);
    let handle = MegaHandle::new(settings.link, settings.controller);
    let thread = MegaThread::new(settings, Clock::start(), tx, handle, shared.clone());
    (dir, pty, shared, rx, thread, port)
}

#[test]
fn noise_from_the_mega_is_counted_by_the_hosts_link_and_telemetry_flows_on() {
    let (_dir, pty, shared, rx, mut thread, port) = session_on_a_pty("mega-session");
    let session = std::thread::spawn(move || {
        let reason = thread.session(port);
        (reason, thread.link.stats())
    });
    let mut mega = FakeMega::new(pty, BOOT_DELAY);
    mega.noisy(11);
    let mut telemetry = 0;
    let deadline = Instant::now() + Duration::from_secs(10);
    while telemetry < 100 {
        assert!(
            Instant::now() < deadline,
            "{telemetry} telemetry batches of {} sent",
            mega.ticks.len()
        );
        mega.service(Instant::now() + Duration::from_millis(2));
        while let Ok(message) = rx.try_recv() {
            if matches!(message, Message::Input(ref s) if matches!(s.input, Input::Wheels(_))) {
                telemetry += 1;
            }
        }
    }
    shared.request_quit();
    let (reason, stats) = session.join().expect("no panic");
    while let Ok(message) = rx.try_recv() {
        if matches!(message, Message::Input(ref s) if matches!(s.input, Input::Wheels(_))) {
            telemetry += 1;
        }
    }
    assert_eq!(reason, "quit");
    let sent = mega.ticks.len() as u32;
    let lost = stats.link.batches_discarded() + stats.incomplete_batches;
    println!(
        "noise from the Mega: {} of {sent} batches delivered, {lost} counted as lost ({:?})",
        stats.batches, stats.link
    );
    assert_eq!(
        stats.batches, telemetry,
        "every batch counted was delivered"
    );
    assert!(lost > 0, "{stats:?}");
    assert!(
        stats.batches + lost <= sent && stats.batches + lost + 2 >= sent,
        "every batch sent is delivered or counted as lost, but for the last in flight: \
         {} + {lost} of {sent}",
        stats.batches
    );
}

#[test]
fn telemetry_from_before_the_reset_is_dropped_and_the_reset_comes_first() {
    let (_dir, pty, shared, rx, mut thread, port) = session_on_a_pty("mega-session-stale");
    let session = std::thread::spawn(move || thread.session(port));
    let mut mega = FakeMega::new(pty, BOOT_DELAY);
    mega.stale_batch_on_open = true;
    let mut inputs = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    while inputs
        .iter()
        .filter(|i| matches!(i, Input::Wheels(_)))
        .count()
        < 5
    {
        assert!(Instant::now() < deadline, "inputs so far: {inputs:?}");
        mega.service(Instant::now() + Duration::from_millis(2));
        while let Ok(message) = rx.try_recv() {
            if let Message::Input(stamped) = message {
                inputs.push(stamped.input);
            }
        }
    }
    shared.request_quit();
    assert_eq!(session.join().expect("no panic"), "quit");
    assert!(
        matches!(inputs.first(), Some(Input::MegaReset)),
        "the first input is the reset, not the batch from before it: {inputs:?}"
    );
}
