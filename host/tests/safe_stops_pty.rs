//! `ratf run`'s safe stops seen on the Mega's wire: SIGINT, and a panicking device thread
//! (the panic drill, `ratf_host::devices::drill`). The robot drives the served world
//! (`ratf sim --serve-pty`, real time) through a tap: a pseudo-terminal the robot opens as
//! its Mega, whose bytes the test forwards to the world's Mega and decodes, stamping each
//! batch on arrival. Once the robot carries a part (magnet on, wheels turning) the test
//! signals it and measures, on a monotonic clock, how long the wire takes to carry zero
//! references and magnet off: at most 50 ms (issue 13). SIGTERM is `run_pty.rs`'s.
//!
//! Both programs run in their own process groups, killed on drop (`common`); every wait
//! has a deadline.

mod common;

use std::fs::{File, OpenOptions};
use std::io::{ErrorKind, Read, Write};
use std::os::fd::AsFd;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use common::{Spawned, TempDir, one_at_a_time, read, serve};

use nix::poll::{PollFd, PollFlags, PollTimeout};
use nix::sys::signal::Signal;
use ratf_protocol::integrity::{BatchReceiver, HOST_CHECKSUM_CHANNEL};
use ratf_protocol::messages::{Command as MegaCommand, WHEEL_COUNT};

/// The bound of issue 13: signal (or panic) to zero references and magnet off on the wire.
const STOP_BOUND: Duration = Duration::from_millis(50);

/// One batch the robot wrote to its Mega (`G H I J L`; the `U` after it is not kept), stamped
/// when the tap read it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Batch {
    at: Instant,
    speeds: [Option<f32>; WHEEL_COUNT],
    solenoid: Option<bool>,
}

impl Batch {
    fn is_stop(&self) -> bool {
        self.speeds.iter().all(|s| *s == Some(0.0)) && self.solenoid == Some(false)
    }

    fn carrying(&self) -> bool {
        self.solenoid == Some(true) && self.speeds.iter().flatten().any(|s| s.abs() > 0.5)
    }
}

/// The tap on the Mega's wire: see the module documentation.
struct MegaTap {
    link: PathBuf,
    batches: Arc<Mutex<Vec<Batch>>>,
    quit: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl MegaTap {
    /// A pseudo-terminal at `link` for the robot, forwarding to the world's Mega at `world`
    /// (opened when the robot opens the tap, as the world powers up when its port opens).
    fn start(link: &Path, world: &Path) -> Self {
        let (master, slave) = ratf_host::pty::open_raw().expect("a pseudo-terminal");
        std::os::unix::fs::symlink(slave, link).expect("symlink");
        let batches = Arc::new(Mutex::new(Vec::new()));
        let quit = Arc::new(AtomicBool::new(false));
        let thread = {
            let (batches, quit, world) =
                (Arc::clone(&batches), Arc::clone(&quit), world.to_owned());
            std::thread::spawn(move || forward(master, &world, &batches, &quit))
        };
        Self {
            link: link.to_owned(),
            batches,
            quit,
            thread: Some(thread),
        }
    }

    fn batches(&self) -> Vec<Batch> {
        self.batches
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Wait until a batch satisfies `matches`; the first such, within `timeout`.
    fn wait_batch(&self, timeout: Duration, what: &str, matches: impl Fn(&Batch) -> bool) -> Batch {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(batch) = self.batches().into_iter().find(|b| matches(b)) {
                return batch;
            }
            assert!(
                Instant::now() < deadline,
                "{what}: not within {timeout:?}; last batches {:?}",
                self.batches().iter().rev().take(5).collect::<Vec<_>>()
            );
            std::thread::park_timeout(Duration::from_millis(1));
        }
    }
}

impl Drop for MegaTap {
    fn drop(&mut self) {
        self.quit.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// The tap's thread: wait for the robot, open the world's Mega, then copy both ways,
/// decoding and stamping the robot's batches, until the robot hangs up or `quit`.
fn forward(mut master: File, world: &Path, batches: &Mutex<Vec<Batch>>, quit: &AtomicBool) {
    let hung_up = |master: &File| {
        let mut fds = [PollFd::new(master.as_fd(), PollFlags::POLLIN)];
        nix::poll::poll(&mut fds, PollTimeout::ZERO).is_ok()
            && fds[0]
                .revents()
                .is_some_and(|r| r.contains(PollFlags::POLLHUP) && !r.contains(PollFlags::POLLIN))
    };
    while hung_up(&master) {
        if quit.load(Ordering::SeqCst) {
            return;
        }
        std::thread::park_timeout(Duration::from_millis(2));
    }
    let mut world = OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(nix::fcntl::OFlag::O_NOCTTY.bits() | nix::fcntl::OFlag::O_NONBLOCK.bits())
        .open(world)
        .expect("the world's Mega opens");
    let mut decoder = BatchReceiver::<8>::new(HOST_CHECKSUM_CHANNEL);
    let mut current = Batch {
        at: Instant::now(),
        speeds: [None; WHEEL_COUNT],
        solenoid: None,
    };
    let mut buf = [0u8; 4096];
    while !quit.load(Ordering::SeqCst) {
        let (from_robot, from_world) = {
            let mut fds = [
                PollFd::new(master.as_fd(), PollFlags::POLLIN),
                PollFd::new(world.as_fd(), PollFlags::POLLIN),
            ];
            if nix::poll::poll(&mut fds, PollTimeout::from(5u16)).is_err() {
                continue;
            }
            let flags = |k: usize| fds[k].revents().unwrap_or(PollFlags::empty());
            if flags(0).contains(PollFlags::POLLHUP) && !flags(0).contains(PollFlags::POLLIN) {
                // The robot hung up: hang up on the world too, so its serve ends.
                return;
            }
            (
                flags(0).contains(PollFlags::POLLIN),
                flags(1).contains(PollFlags::POLLIN),
            )
        };
        if from_robot && let Ok(n) = master.read(&mut buf) {
            let at = Instant::now();
            let mut done = Vec::new();
            decoder.feed(&buf[..n], |frame| match MegaCommand::from_frame(frame) {
                Ok(MegaCommand::WheelSpeed { wheel, speed_rad_s }) => {
                    current.speeds[wheel.index()] = Some(speed_rad_s);
                }
                Ok(MegaCommand::Solenoid { on }) => {
                    current.solenoid = Some(on);
                    current.at = at;
                    done.push(current);
                    current.speeds = [None; WHEEL_COUNT];
                    current.solenoid = None;
                }
                Ok(
                    MegaCommand::MotorPwm { .. }
                    | MegaCommand::Setting { .. }
                    | MegaCommand::StopOnSwitch { .. },
                )
                | Err(_) => {}
            });
            batches
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .extend(done);
            write_all(&mut world, &buf[..n]);
        }
        if from_world && let Ok(n) = world.read(&mut buf) {
            write_all(&mut master, &buf[..n]);
        }
    }
}

/// Write all of `bytes` to a non-blocking terminal (within a second).
fn write_all(file: &mut File, mut bytes: &[u8]) {
    let deadline = Instant::now() + Duration::from_secs(1);
    while !bytes.is_empty() && Instant::now() < deadline {
        match file.write(bytes) {
            Ok(n) => bytes = &bytes[n..],
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::Interrupted) => {
                std::thread::park_timeout(Duration::from_micros(200));
            }
            Err(_) => return,
        }
    }
}

/// The served world (round 1, `seed`), the tap in front of its Mega, and `ratf run` on
/// them with `env`; returns once the robot carries a part.
struct Round {
    _world: Spawned,
    tap: MegaTap,
    robot: Spawned,
    dir: TempDir,
}

impl Round {
    fn until_carrying(name: &str, seed: &str, env: &[(&str, &str)]) -> Self {
        let dir = TempDir::new(name);
        let dev = dir.0.join("dev");
        let (world, port) = serve(&dir.0, seed, &[]);
        let tap = MegaTap::start(&dir.0.join("tap-mega"), &dev.join("mega"));
        let config = dir.0.join("robot.toml");
        std::fs::write(
            &config,
            format!(
                "[link]\nmega_port = \"{}\"\nlidar_port = \"{}\"\nimu = \"none\"\n\n\
                 [referee]\nserver_port = {port}\n",
                tap.link.display(),
                dev.join("lidar").display()
            ),
        )
        .expect("the robot's configuration");
        let robot = Spawned::start_with_env(
            &[
                "run",
                "--config",
                config.to_str().expect("a UTF-8 path"),
                "--out",
                dir.0.join("out").to_str().expect("a UTF-8 path"),
                "--status-hz",
                "0",
            ],
            env,
            &dir.0.join("run.err"),
        );
        // The part list comes a second after the robot connects; the first pick follows.
        let mut round = Self {
            _world: world,
            tap,
            robot,
            dir,
        };
        let deadline = Instant::now() + Duration::from_secs(60);
        while !round.tap.batches().iter().any(Batch::carrying) {
            assert!(
                Instant::now() < deadline,
                "the robot never carried a part\n{}",
                round.output()
            );
            if let Ok(Some(status)) = round.robot.child.try_wait() {
                panic!("ratf run ended early: {status:?}\n{}", round.output());
            }
            std::thread::park_timeout(Duration::from_millis(5));
        }
        round
    }

    /// What the robot printed, both streams, for failure messages.
    fn output(&self) -> String {
        format!(
            "stdout:\n{}\nstderr:\n{}",
            self.robot.seen.join("\n"),
            read(&self.dir.0.join("run.err"))
        )
    }

    /// Send `signal` to the robot; the first stop batch on the wire after it and how long
    /// after the signal it came.
    fn stop_with(&mut self, signal: Signal) -> (Batch, Duration) {
        let sent = Instant::now();
        nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(self.robot.child.id() as i32),
            signal,
        )
        .expect("the signal is sent");
        let stop = self.tap.wait_batch(
            Duration::from_secs(5),
            "zero references and magnet off",
            |b| b.at >= sent && b.is_stop(),
        );
        (stop, stop.at - sent)
    }

    /// Every batch from `stop` on is a stop: nothing moved the robot afterwards.
    fn assert_nothing_after(&self, stop: &Batch) {
        let after: Vec<Batch> = self
            .tap
            .batches()
            .into_iter()
            .filter(|b| b.at >= stop.at)
            .collect();
        assert!(after.iter().all(Batch::is_stop), "{after:?}");
    }
}

#[test]
fn sigint_puts_zero_references_and_magnet_off_on_the_megas_wire_within_50_ms() {
    let _serial = one_at_a_time();
    let mut round = Round::until_carrying("stop-sigint", "1", &[]);
    let (stop, elapsed) = round.stop_with(Signal::SIGINT);
    println!("SIGINT: zero references and magnet off on the Mega's wire {elapsed:?} after it");
    assert!(
        elapsed <= STOP_BOUND,
        "{elapsed:?} from SIGINT to the stop on the wire"
    );
    let status = round.robot.wait_exit(Duration::from_secs(10));
    assert_eq!(status.code(), Some(130), "{}", round.output());
    assert!(
        round
            .robot
            .seen
            .iter()
            .any(|l| l.starts_with("ratf run: interrupted"))
            && round
                .robot
                .seen
                .iter()
                .any(|l| l == "the robot was sent zero references and magnet off"),
        "{}",
        round.output()
    );
    round.assert_nothing_after(&stop);
}

#[test]
fn a_panicking_device_thread_puts_zero_references_and_magnet_off_on_the_wire_within_50_ms() {
    let _serial = one_at_a_time();
    // No backtrace: its symbols, printed by the panic hook, would compete for the CPU with
    // the loop stopping the robot (a debug build on a shared machine), as they need not on
    // the robot.
    let env = [("RATF_PANIC_DRILL", "mega"), ("RUST_BACKTRACE", "0")];
    let mut round = Round::until_carrying("stop-panic", "1", &env);
    // SIGUSR1 makes the Mega's own thread panic within its 5 ms read timeout.
    let (stop, elapsed) = round.stop_with(Signal::SIGUSR1);
    println!(
        "a panicking Mega thread: zero references and magnet off on the Mega's wire {elapsed:?} \
         after SIGUSR1 (the panic was no earlier)"
    );
    assert!(
        elapsed <= STOP_BOUND,
        "{elapsed:?} from the drill's signal to the stop on the wire"
    );
    let status = round.robot.wait_exit(Duration::from_secs(10));
    let output = round.output();
    assert_eq!(status.code(), Some(4), "{output}");
    assert!(
        output.contains("panic drill: the mega thread panics")
            && round
                .robot
                .seen
                .iter()
                .any(|l| l.starts_with("ratf run: a thread panicked"))
            && round
                .robot
                .seen
                .iter()
                .any(|l| l == "the robot was sent zero references and magnet off"),
        "{output}"
    );
    round.assert_nothing_after(&stop);
}
