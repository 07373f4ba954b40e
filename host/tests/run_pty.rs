//! `ratf run` end to end with no hardware: against `ratf sim --serve-pty` (the simulated
//! Mega and X4 behind pseudo-terminals, the mock server on UDP, the world in real time).
//!
//! The round runs in real time: round 1 takes about 40 s of wall time. Every wait has a
//! deadline, and both programs run in their own process groups, killed on drop.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use std::os::unix::process::CommandExt;
use std::sync::{Mutex, MutexGuard, PoisonError};

/// The tests run one at a time: each runs a world and a robot in real time, and two pairs
/// side by side on a 2-core machine would starve each other's 50 Hz loops.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

fn one_at_a_time() -> MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A child in its own process group, killed (the whole group) on drop; its stdout lines
/// arrive on a channel.
struct Spawned {
    child: Child,
    lines: Receiver<String>,
    seen: Vec<String>,
}

impl Spawned {
    fn start(args: &[&str], stderr_to: &Path) -> Self {
        let stderr = std::fs::File::create(stderr_to).expect("stderr file");
        let mut child = Command::new(env!("CARGO_BIN_EXE_ratf"))
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(stderr)
            .process_group(0)
            .spawn()
            .expect("ratf starts");
        let stdout = child.stdout.take().expect("piped stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self {
            child,
            lines,
            seen: Vec::new(),
        }
    }

    /// The first line (from now on) that `matches`, within `timeout`.
    fn wait_line(&mut self, timeout: Duration, matches: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.seen.push(line.clone());
                    if matches(&line) {
                        return line;
                    }
                }
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => {
                    panic!(
                        "no such line within {timeout:?}; saw:\n{}",
                        self.seen.join("\n")
                    )
                }
            }
        }
    }

    /// Its exit status within `timeout`.
    fn wait_exit(&mut self, timeout: Duration) -> ExitStatus {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                // Whatever it printed last.
                while let Ok(line) = self.lines.recv_timeout(Duration::from_millis(200)) {
                    self.seen.push(line);
                }
                return status;
            }
            assert!(
                Instant::now() < deadline,
                "still running after {timeout:?}; saw:\n{}",
                self.seen.join("\n")
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Spawned {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let group = nix::unistd::Pid::from_raw(self.child.id() as i32);
            let _ = nix::sys::signal::killpg(group, nix::sys::signal::Signal::SIGKILL);
        }
        let _ = self.child.wait();
    }
}

/// A fresh directory under the system's temporary one, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let dir = std::env::temp_dir().join(format!("ratf-{name}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn robot_config(dir: &Path, port: u16) -> PathBuf {
    let path = dir.join("robot.toml");
    let text = format!(
        "[link]\nmega_port = \"{}\"\nlidar_port = \"{}\"\nimu = \"none\"\n\n[referee]\nserver_port = {port}\n",
        dir.join("dev/mega").display(),
        dir.join("dev/lidar").display()
    );
    std::fs::write(&path, text).expect("config");
    path
}

fn read(path: &Path) -> String {
    let mut text = String::new();
    if let Ok(mut file) = std::fs::File::open(path) {
        let _ = file.read_to_string(&mut text);
    }
    text
}

#[test]
fn ratf_run_completes_round_1_with_full_score_against_the_served_world() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("run-pty");
    let dir = &tmp.0;
    let dev = dir.join("dev");
    let mut world = Spawned::start(
        &[
            "sim",
            "--round",
            "1",
            "--seed",
            "1",
            "--wait-for-robot-s",
            "60",
            "--serve-pty",
            dev.to_str().expect("utf-8 path"),
        ],
        &dir.join("serve.err"),
    );
    let port_line = world.wait_line(Duration::from_secs(30), |l| l.starts_with("server port "));
    let port: u16 = port_line["server port ".len()..]
        .trim()
        .parse()
        .expect("a port");
    let config = robot_config(dir, port);
    let mut robot = Spawned::start(
        &[
            "run",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--out",
            dir.join("out").to_str().expect("utf-8 path"),
            "--status-hz",
            "0",
        ],
        &dir.join("run.err"),
    );
    // Round 1 takes about 40 s of robot time, in real time.
    let status = robot.wait_exit(Duration::from_secs(150));
    assert_eq!(
        status.code(),
        Some(0),
        "ratf run: {status:?}\n{}\nstderr:\n{}",
        robot.seen.join("\n"),
        read(&dir.join("run.err"))
    );
    let summary = robot
        .seen
        .iter()
        .find(|l| l.starts_with("ratf run: finished: placed 4 part(s)"));
    assert!(summary.is_some(), "{}", robot.seen.join("\n"));
    assert!(
        robot
            .seen
            .iter()
            .any(|l| l == "the robot was sent zero references and magnet off"),
        "{}",
        robot.seen.join("\n")
    );
    // The world's referee scored it: the robot hung up, so the serve ends and tells.
    let end = world.wait_line(Duration::from_secs(30), |l| l.starts_with("round 1: "));
    assert!(end.starts_with("round 1: 4 points"), "{end}");
    assert_eq!(world.wait_exit(Duration::from_secs(10)).code(), Some(0));
}

#[test]
fn a_missing_device_is_named_with_where_it_looked_and_what_to_do() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("run-missing");
    let config = robot_config(&tmp.0, 39_899);
    let mut robot = Spawned::start(
        &[
            "run",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--out",
            tmp.0.join("out").to_str().expect("utf-8 path"),
        ],
        &tmp.0.join("run.err"),
    );
    let status = robot.wait_exit(Duration::from_secs(20));
    let stderr = read(&tmp.0.join("run.err"));
    assert_eq!(status.code(), Some(1), "{stderr}");
    let mega = tmp.0.join("dev/mega");
    assert!(
        stderr.contains(&format!("mega: {}: no such device", mega.display()))
            && stderr.contains("set [link] mega_port"),
        "{stderr}"
    );
}

#[test]
fn sigterm_stops_the_robot_and_exits_130() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("run-sigterm");
    let dir = &tmp.0;
    let dev = dir.join("dev");
    let mut world = Spawned::start(
        &[
            "sim",
            "--round",
            "1",
            "--seed",
            "2",
            "--serve-pty",
            dev.to_str().expect("utf-8 path"),
        ],
        &dir.join("serve.err"),
    );
    let port_line = world.wait_line(Duration::from_secs(30), |l| l.starts_with("server port "));
    let port: u16 = port_line["server port ".len()..]
        .trim()
        .parse()
        .expect("a port");
    let config = robot_config(dir, port);
    let mut robot = Spawned::start(
        &[
            "run",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--out",
            dir.join("out").to_str().expect("utf-8 path"),
            "--force-start",
            "BBBB",
            "--status-hz",
            "0",
        ],
        &dir.join("run.err"),
    );
    // The operator's forced start: the robot drives at once.
    robot.wait_line(Duration::from_secs(20), |l| l.contains("going for"));
    let pid = nix::unistd::Pid::from_raw(robot.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).expect("signal");
    let status = robot.wait_exit(Duration::from_secs(5));
    assert_eq!(
        status.code(),
        Some(130),
        "{}\n{}",
        robot.seen.join("\n"),
        read(&dir.join("run.err"))
    );
    assert!(
        robot
            .seen
            .iter()
            .any(|l| l.starts_with("ratf run: interrupted"))
            && robot
                .seen
                .iter()
                .any(|l| l == "the robot was sent zero references and magnet off"),
        "{}",
        robot.seen.join("\n")
    );
}
