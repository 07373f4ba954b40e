//! The panic drill: proof, in CI and on the robot, that a panicking device thread stops it.
//!
//! With `RATF_PANIC_DRILL=<thread>` (`mega`, `lidar`, `imu` or `referee`) in its
//! environment, `ratf run` makes that device's thread panic at its next report to the loop
//! (the Mega's: within its 5 ms read timeout) after the process receives SIGUSR1. The run
//! must then end as after any panic: zero references and magnet off to the Mega, exit code
//! 4. Without the variable nothing changes (SIGUSR1 keeps its default action).
//!
//! Not `#[cfg(test)]`, by design: the end-to-end test drives the real `ratf` binary, which
//! is built without `cfg(test)`, and no input from a device can make a device thread panic
//! (the parsers take any bytes); a team can run the same drill on its robot.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

/// The environment variable that arms the drill.
pub const PANIC_DRILL_VAR: &str = "RATF_PANIC_DRILL";

/// The device threads' names (as spawned), which the variable may name.
const THREADS: [&str; 4] = ["mega", "lidar", "imu", "referee"];

/// The armed drill: which thread, and whether SIGUSR1 has come.
#[derive(Debug)]
struct Drill {
    thread: &'static str,
    fired: Arc<AtomicBool>,
}

static DRILL: OnceLock<Option<Drill>> = OnceLock::new();

/// Arm the drill if the environment asks for it (once per process; later calls repeat the
/// first answer): `Ok(None)` when the variable is not set, `Ok(Some(thread))` when armed,
/// `Err` (what to do) when it names no device thread or SIGUSR1 cannot be caught.
pub fn arm() -> Result<Option<&'static str>, String> {
    let mut problem = None;
    let drill = DRILL.get_or_init(|| {
        let wanted = std::env::var(PANIC_DRILL_VAR).ok()?;
        let Some(thread) = THREADS.into_iter().find(|t| *t == wanted) else {
            problem = Some(format!(
                "{PANIC_DRILL_VAR}={wanted:?}: not a device thread; use one of {THREADS:?}, \
                 or unset it"
            ));
            return None;
        };
        let fired = Arc::new(AtomicBool::new(false));
        if let Err(e) =
            signal_hook::flag::register(signal_hook::consts::SIGUSR1, Arc::clone(&fired))
        {
            problem = Some(format!("{PANIC_DRILL_VAR}: cannot catch SIGUSR1: {e}"));
            return None;
        }
        Some(Drill { thread, fired })
    });
    match problem {
        Some(problem) => Err(problem),
        None => Ok(drill.as_ref().map(|d| d.thread)),
    }
}

/// Panic if the drill is armed for the calling thread and SIGUSR1 has come.
pub(crate) fn check() {
    let Some(Some(drill)) = DRILL.get() else {
        return;
    };
    if drill.fired.load(Ordering::SeqCst) && std::thread::current().name() == Some(drill.thread) {
        panic!(
            "panic drill: the {} thread panics, as {PANIC_DRILL_VAR} asked on SIGUSR1",
            drill.thread
        );
    }
}
