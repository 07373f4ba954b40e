//! `ratf check` end to end with no hardware: against `ratf sim --serve-pty` (the simulated
//! Mega and X4 behind pseudo-terminals, the mock server on UDP, the world in real time).
//!
//! Each test takes a few seconds of real time. Every wait has a deadline; both programs run
//! in their own process groups, killed on drop; the tests run one at a time (two real-time
//! worlds side by side starve each other on 2 cores).

use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use serde_json::Value;

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
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => panic!(
                    "no such line within {timeout:?}; saw:\n{}",
                    self.seen.join("\n")
                ),
            }
        }
    }

    /// Its exit status within `timeout`, with everything it printed in `seen`.
    fn wait_exit(&mut self, timeout: Duration) -> ExitStatus {
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
    fn json(&self) -> Value {
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

fn read(path: &Path) -> String {
    let mut text = String::new();
    if let Ok(mut file) = std::fs::File::open(path) {
        let _ = file.read_to_string(&mut text);
    }
    text
}

/// The served world (round 1, seed 1) and its server's port.
fn serve(dir: &Path) -> (Spawned, u16) {
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
    let line = world.wait_line(Duration::from_secs(30), |l| l.starts_with("server port "));
    let port = line["server port ".len()..].trim().parse().expect("a port");
    (world, port)
}

fn robot_config(dir: &Path, lidar: &Path, port: u16) -> PathBuf {
    let path = dir.join("robot.toml");
    let text = format!(
        "[link]\nmega_port = \"{}\"\nlidar_port = \"{}\"\nimu = \"none\"\n\n[referee]\nserver_port = {port}\n",
        dir.join("dev/mega").display(),
        lidar.display()
    );
    std::fs::write(&path, text).expect("config");
    path
}

fn device<'a>(json: &'a Value, name: &str) -> &'a Value {
    json["devices"]
        .as_array()
        .and_then(|d| d.iter().find(|d| d["device"] == name))
        .unwrap_or_else(|| panic!("no {name} in {json}"))
}

#[test]
fn ratf_check_finds_every_served_device_ok_and_each_wheel_turning_its_own_way() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("check-pty");
    let dir = &tmp.0;
    let (_world, port) = serve(dir);
    let config = robot_config(dir, &dir.join("dev/lidar"), port);
    let mut check = Spawned::start(
        &[
            "check",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--yes",
            "--json",
        ],
        &dir.join("check.err"),
    );
    let status = check.wait_exit(Duration::from_secs(60));
    let json = check.json();
    assert_eq!(
        status.code(),
        Some(0),
        "{}\nstderr:\n{}",
        check.seen.join("\n"),
        read(&dir.join("check.err"))
    );
    for name in ["mega", "lidar", "server", "wheels", "magnet"] {
        assert_eq!(device(&json, name)["ok"], true, "{name}: {json}");
    }
    let mega = &device(&json, "mega")["data"];
    assert!(
        (mega["batches_per_s"].as_f64().unwrap() - 50.0).abs() < 5.0,
        "{mega}"
    );
    assert_eq!(mega["host_integrity_errors"], 0, "{mega}");
    assert_eq!(mega["resets"], 0, "{mega}");
    let lidar = &device(&json, "lidar")["data"];
    assert!(
        (lidar["rotation_hz"].as_f64().unwrap() - 7.0).abs() < 1.0,
        "{lidar}"
    );
    // From the start pose, every configured beacon is where the world put it.
    for beacon in lidar["beacons"].as_array().unwrap() {
        assert!(beacon["found_fraction"].as_f64().unwrap() >= 0.9, "{lidar}");
    }
    assert_eq!(device(&json, "imu")["skipped"], "[link] imu = \"none\"");
    // Each motor at 20 % open loop for 1 s turned its own wheel forwards, alone; the hold
    // was resent every tick (a single `K` would stop after 100 ms: a few dozen ticks).
    let wheels = device(&json, "wheels")["data"]["wheels"]
        .as_array()
        .unwrap();
    assert_eq!(wheels.len(), 4);
    for (k, wheel) in wheels.iter().enumerate() {
        assert_eq!(wheel["result"]["verdict"], "ok", "{wheel}");
        let ticks: Vec<i64> = wheel["ticks"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t.as_i64().unwrap())
            .collect();
        assert!(ticks[k] > 1000, "wheel {k}: {ticks:?}");
        for (j, &t) in ticks.iter().enumerate() {
            if j != k {
                assert!(t.abs() < 56, "wheel {k}: {ticks:?}");
            }
        }
    }
    // The magnet cannot be seen on the wire; what the Mega was sent can.
    let magnet = &device(&json, "magnet")["data"];
    assert!(magnet["on_batches"].as_u64().unwrap() >= 15, "{magnet}");
    assert!(magnet["off_batches"].as_u64().unwrap() >= 1, "{magnet}");
    assert!(
        check.seen.iter().any(|l| l.starts_with("  server   ok: ")),
        "{}",
        check.seen.join("\n")
    );
}

#[test]
fn a_missing_lidar_is_named_with_where_it_looked_and_the_check_carries_on() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("check-missing");
    let dir = &tmp.0;
    let (_world, port) = serve(dir);
    let nowhere = dir.join("dev/no-lidar");
    let config = robot_config(dir, &nowhere, port);
    let mut check = Spawned::start(
        &[
            "check",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--yes",
            "--json",
            "--observe-s",
            "1",
            "--spin-s",
            "0.3",
        ],
        &dir.join("check.err"),
    );
    let status = check.wait_exit(Duration::from_secs(60));
    assert_eq!(status.code(), Some(3), "{}", check.seen.join("\n"));
    let json = check.json();
    let lidar = device(&json, "lidar");
    assert_eq!(lidar["ok"], false);
    let problem = lidar["problems"][0].as_str().unwrap();
    assert!(
        problem.starts_with(&format!("lidar: {}: no such device", nowhere.display()))
            && problem.contains("set [link] lidar_port"),
        "{problem}"
    );
    for name in ["mega", "server", "wheels"] {
        assert_eq!(device(&json, name)["ok"], true, "{name}: {json}");
    }
}

#[test]
fn sigint_during_the_bring_up_stops_the_robot_and_exits_130() {
    let _serial = one_at_a_time();
    let tmp = TempDir::new("check-sigint");
    let dir = &tmp.0;
    let (_world, port) = serve(dir);
    let config = robot_config(dir, &dir.join("dev/lidar"), port);
    let mut check = Spawned::start(
        &[
            "check",
            "--config",
            config.to_str().expect("utf-8 path"),
            "--yes",
            "--observe-s",
            "1",
        ],
        &dir.join("check.err"),
    );
    check.wait_line(Duration::from_secs(30), |l| {
        l.starts_with("turning the back-left wheel")
    });
    let pid = nix::unistd::Pid::from_raw(check.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).expect("signal");
    let status = check.wait_exit(Duration::from_secs(5));
    assert_eq!(status.code(), Some(130), "{}", check.seen.join("\n"));
    let stderr = read(&dir.join("check.err"));
    assert!(
        stderr
            .contains("ratf check: interrupted; the robot was sent zero references and magnet off"),
        "{stderr}"
    );
    // Wheel 0's verdict came before the signal; the bring-up stopped at wheel 1.
    assert!(
        !check
            .seen
            .iter()
            .any(|l| l.contains("wheel 1 (back-left):")),
        "{}",
        check.seen.join("\n")
    );
}
