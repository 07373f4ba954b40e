//! What the end-to-end tests over pseudo-terminals share: `ratf` children in their own
//! process groups with deadlines on every wait, temporary folders, the served world
//! (`ratf sim --serve-pty`) and a robot configuration pointing at it.
#![allow(dead_code)]

use std::ffi::OsStr;
use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use serde_json::Value;

/// The tests of one binary run one at a time: each runs a world and a robot in real time,
/// and two pairs side by side on a 2-core machine would starve each other's 50 Hz loops.
pub static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Hold this for the whole test.
pub fn one_at_a_time() -> MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A child in its own process group, killed (the whole group) on drop; its stdout lines
/// arrive on a channel.
pub struct Spawned {
    /// The process.
    pub child: Child,
    lines: Receiver<String>,
    /// Every stdout line read so far.
    pub seen: Vec<String>,
}

impl Spawned {
    /// Start `ratf ARGS`, its stderr to `stderr_to`.
    pub fn start(args: &[&str], stderr_to: &Path) -> Self {
        Self::start_with_env(args, &[], stderr_to)
    }

    /// Start `ratf ARGS` with the environment variables `env` added, its stderr to
    /// `stderr_to`.
    pub fn start_with_env(args: &[&str], env: &[(&str, &str)], stderr_to: &Path) -> Self {
        let stderr = std::fs::File::create(stderr_to).expect("stderr file");
        let mut child = Command::new(env!("CARGO_BIN_EXE_ratf"))
            .args(args)
            .envs(env.iter().copied())
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
    pub fn wait_line(&mut self, timeout: Duration, matches: impl Fn(&str) -> bool) -> String {
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
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => panic!(
                    "no such line within {timeout:?}; saw:\n{}",
                    self.seen.join("\n")
                ),
            }
        }
    }

    /// Its exit status within `timeout`, with everything it printed in `seen`.
    pub fn wait_exit(&mut self, timeout: Duration) -> ExitStatus {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
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

    /// The last line, parsed as JSON.
    pub fn json(&self) -> Value {
        let last = self.seen.last().map(String::as_str).unwrap_or("");
        serde_json::from_str(last)
            .unwrap_or_else(|e| panic!("last line is not JSON ({e}):\n{}", self.seen.join("\n")))
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
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// `ratf-NAME-…` under the temporary folder.
    pub fn new(name: &str) -> Self {
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

/// The file's text, or nothing.
pub fn read(path: &Path) -> String {
    let mut text = String::new();
    if let Ok(mut file) = std::fs::File::open(path) {
        let _ = file.read_to_string(&mut text);
    }
    text
}

/// The served world (round 1 at `seed`, waiting 60 s for a robot; `extra` arguments added)
/// under `dir/dev`, and its server's port.
pub fn serve(dir: &Path, seed: &str, extra: &[&str]) -> (Spawned, u16) {
    let dev = dir.join("dev");
    let mut args = vec![
        "sim",
        "--round",
        "1",
        "--seed",
        seed,
        "--wait-for-robot-s",
        "60",
        "--serve-pty",
        dev.to_str().expect("utf-8 path"),
    ];
    args.extend_from_slice(extra);
    let mut world = Spawned::start(&args, &dir.join("serve.err"));
    let line = world.wait_line(Duration::from_secs(30), |l| l.starts_with("server port "));
    let port = line["server port ".len()..].trim().parse().expect("a port");
    (world, port)
}

/// `dir/robot.toml`: the served Mega and `lidar`, no IMU, the served server's `port`.
pub fn robot_config(dir: &Path, lidar: &Path, port: u16) -> PathBuf {
    let path = dir.join("robot.toml");
    let text = format!(
        "[link]\nmega_port = \"{}\"\nlidar_port = \"{}\"\nimu = \"none\"\n\n[referee]\nserver_port = {port}\n",
        dir.join("dev/mega").display(),
        lidar.display()
    );
    std::fs::write(&path, text).expect("config");
    path
}

/// `ratf ARGS` run to its end, its output captured.
pub fn ratf<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ratf"))
        .args(args)
        .output()
        .expect("ratf runs")
}

/// `ratf ARGS` run to its end, which must exit 0 (the test fails with its stderr); its
/// output.
pub fn ratf_ok<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> Output {
    let args: Vec<S> = args.into_iter().collect();
    let output = ratf(&args);
    assert!(
        output.status.success(),
        "ratf {:?}: {}",
        args.iter().map(|a| a.as_ref()).collect::<Vec<_>>(),
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

/// `ratf ARGS` to its end within `timeout`, which must be 0; what it printed.
pub fn run_ok(args: &[&str], stderr: &Path, timeout: Duration) -> Spawned {
    let mut child = Spawned::start(args, stderr);
    let status = child.wait_exit(timeout);
    assert_eq!(
        status.code(),
        Some(0),
        "ratf {}\n{}\nstderr:\n{}",
        args.join(" "),
        child.seen.join("\n"),
        read(stderr)
    );
    child
}

/// The number at `key` of a JSON object (a test fails when it is not one).
pub fn float(value: &Value, key: &str) -> f64 {
    value[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} in {value}"))
}
