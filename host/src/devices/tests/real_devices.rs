//! [`RealDevices`], the loop's side of the device threads, on the way out.

use std::sync::mpsc;
use std::time::Duration;

use ratf_core::drivers::mega_link::MegaLinkConfig;
use ratf_core::runtime::{Devices, Input};
use ratf_protocol::mcu::McuConfig;

use crate::devices::lidar::LidarHandle;
use crate::devices::mega::MegaHandle;
use crate::devices::{Clock, DeviceError, RealDevices, Shared, Writers, referee};
use crate::referee::client::RefereeLink;

/// Ctrl-C, SIGTERM or a panic sets the quit flag, and every device thread ends when it sees
/// it, dropping its end of the channel, often while the loop waits for the next tick. That
/// is a quit, not "every device thread ended" (a device failure, exit code 3).
#[test]
fn threads_ending_because_the_run_quits_are_not_a_device_failure() {
    let clock = Clock::start();
    // A server link for the writers (nothing is sent): its own thread, channel and flags.
    let referee_shared = Shared::new();
    let (referee_tx, _referee_rx) = crate::devices::inbox(&referee_shared);
    let link = RefereeLink::connect(([127, 0, 0, 1], 9).into(), 0).expect("a UDP socket");
    let (referee, referee_thread) =
        referee::spawn(link, clock, referee_tx, referee_shared.clone()).expect("a thread");
    // Several times: the loop must be waiting in the channel when the flag and the hang-up
    // come, which it is for all but a few microseconds of every 20 ms tick.
    for _ in 0..5 {
        let shared = Shared::new();
        let (tx, rx) = crate::devices::inbox(&shared);
        let writers = Writers {
            mega: MegaHandle::new(MegaLinkConfig::default(), McuConfig::default()),
            lidar: LidarHandle::new(),
            referee: referee.clone(),
        };
        let mut devices = RealDevices::new(clock, rx, writers, shared.clone(), Vec::new());
        let (ticked, on_tick) = mpsc::channel();
        let looping = std::thread::spawn(move || {
            loop {
                match devices.next_input() {
                    Ok(Some(stamped)) => {
                        if stamped.input == Input::HostTick {
                            let _ = ticked.send(());
                        }
                    }
                    Ok(None) => return Ok(()),
                    Err(e) => return Err(e),
                }
            }
        });
        // Right after a tick the loop waits ~20 ms for the next one.
        on_tick
            .recv_timeout(Duration::from_secs(2))
            .expect("a host tick");
        shared.request_quit();
        drop(tx);
        let ended: Result<(), DeviceError> = looping.join().expect("no panic");
        assert_eq!(ended, Ok(()), "a quitting run reported a device failure");
    }
    referee_shared.request_quit();
    referee_thread.join().expect("no panic");
}

/// The inbox from the device threads to the loop holds at most [`INBOX_CAPACITY`]
/// messages: inputs beyond it are dropped and counted, never queued without bound, and a
/// loop that has gone ends the sender.
#[test]
fn a_loop_that_falls_behind_loses_counted_inputs_not_memory() {
    use crate::devices::{INBOX_CAPACITY, Message, inbox, report};
    use ratf_core::runtime::{Stamped, Timestamp};
    let shared = Shared::new();
    let (tx, rx) = inbox(&shared);
    let tick =
        |k: usize| Message::Input(Stamped::new(Timestamp::from_us(k as u64), Input::HostTick));
    for k in 0..INBOX_CAPACITY + 5 {
        assert!(report(&tx, tick(k)), "the loop is still there");
    }
    assert_eq!(shared.inputs_dropped(), 5);
    assert_eq!(rx.try_iter().count(), INBOX_CAPACITY);
    assert!(report(&tx, tick(0)));
    drop(rx);
    assert!(!report(&tx, tick(1)), "the loop has gone");
}
