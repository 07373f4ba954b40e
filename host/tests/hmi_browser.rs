//! The operator's page in a real browser: Debian's `chromium` driven through
//! `chromedriver` by `fantoccini`, against the `ratf` binary serving `--hmi`.
//!
//! These need `chromium` and `chromium-driver` installed, so they are ignored by a plain
//! `cargo test`; `.ci/run` installs both and runs them with
//! `cargo test -p ratf-host --test hmi_browser -- --ignored`. chromedriver and `ratf` run in
//! process groups of their own, killed when the test ends however it ends, so a failing test
//! leaves no browser behind. Screenshots go to `target/tmp/hmi-screenshots/`.

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use fantoccini::{Client, ClientBuilder, Locator};
use hyper_util::client::legacy::connect::HttpConnector;
use nix::sys::signal::{Signal, killpg};
use nix::unistd::Pid;
use serde_json::Value;

/// A child process in its own process group; the whole group is killed on drop.
struct Group(Child);

impl Group {
    fn spawn(command: &mut Command) -> Self {
        let child = command
            .process_group(0)
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {command:?}: {e}"));
        Self(child)
    }
}

impl Drop for Group {
    fn drop(&mut self) {
        if let Ok(pid) = i32::try_from(self.0.id()) {
            let _ = killpg(Pid::from_raw(pid), Signal::SIGKILL);
        }
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port on loopback")
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("hmi-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `ratf` with `args`, serving the HMI; its page URL with the token, read off stdout.
fn serve_ratf(args: &[&str]) -> (Group, String) {
    let mut child = Group::spawn(
        Command::new(env!("CARGO_BIN_EXE_ratf"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    let stdout = child.0.stdout.take().expect("piped stdout");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        // Keep reading to the end so `ratf` never finds its stdout closed.
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(rest) = line.strip_prefix("HMI: ") {
                let url = rest
                    .split_whitespace()
                    .next()
                    .unwrap_or_default()
                    .to_owned();
                let _ = tx.send(url);
            }
        }
    });
    let url = rx
        .recv_timeout(Duration::from_secs(60))
        .expect("ratf printed no 'HMI: <url>' line within 60 s");
    (child, url)
}

/// chromedriver on a free port, and a headless Chromium session through it.
async fn browser(profile: &Path) -> (Group, Client) {
    let port = free_port();
    let driver = Group::spawn(
        Command::new("chromedriver")
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    let mut capabilities = serde_json::Map::new();
    capabilities.insert(
        "goog:chromeOptions".into(),
        serde_json::json!({
            "args": [
                "--headless=new",
                "--no-sandbox",
                "--disable-dev-shm-usage",
                "--disable-gpu",
                "--hide-scrollbars",
                "--window-size=1366,900",
                format!("--user-data-dir={}", profile.display()),
            ]
        }),
    );
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let connected = ClientBuilder::new(HttpConnector::new())
            .capabilities(capabilities.clone())
            .connect(&format!("http://127.0.0.1:{port}"))
            .await;
        match connected {
            Ok(client) => return (driver, client),
            Err(e) if Instant::now() > deadline => panic!("no WebDriver session in 60 s: {e}"),
            Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
        }
    }
}

/// Poll the JavaScript expression `expression` until it is truthy; its last value.
async fn wait_for(client: &Client, expression: &str, what: &str, timeout_s: u64) -> Value {
    let deadline = Instant::now() + Duration::from_secs(timeout_s);
    let script = format!("try {{ return ({expression}); }} catch (e) {{ return null; }}");
    loop {
        let value = client.execute(&script, vec![]).await.expect("execute");
        let truthy = match &value {
            Value::Null => false,
            Value::Bool(b) => *b,
            Value::Number(n) => n.as_f64() != Some(0.0),
            Value::String(s) => !s.is_empty(),
            _ => true,
        };
        if truthy {
            return value;
        }
        if Instant::now() > deadline {
            let last = client
                .execute("return window.ratf && window.ratf.last;", vec![])
                .await
                .unwrap_or(Value::Null);
            panic!("{what}: not within {timeout_s} s ({expression}); last snapshot: {last}");
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

async fn screenshot(client: &Client, name: &str) {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("hmi-screenshots");
    std::fs::create_dir_all(&dir).unwrap();
    let png = client.screenshot().await.expect("screenshot");
    let path = dir.join(name);
    std::fs::write(&path, png).unwrap();
    eprintln!("screenshot: {}", path.display());
}

const LOADED: &str = "window.ratf.floor && window.ratf.last";

#[tokio::test]
#[ignore = "needs chromium and chromium-driver: .ci/run's browser step runs it"]
async fn a_simulated_round_is_watched_started_stopped_and_refused_without_the_token() {
    let dir = scratch("sim");
    let out = dir.join("out");
    let (_ratf, url) = serve_ratf(&[
        "sim",
        "--round",
        "3",
        "--realtime",
        "--silent-server",
        "--hmi",
        "127.0.0.1:0",
        "--out",
        out.to_str().unwrap(),
    ]);
    let (_driver, client) = browser(&dir.join("profile")).await;
    client.goto(&url).await.expect("open the page");

    // The page loads and shows the simulator waiting for a part list (the server is silent).
    wait_for(&client, LOADED, "the page loads", 30).await;
    let mode = client.find(Locator::Id("mode")).await.unwrap();
    assert_eq!(mode.text().await.unwrap(), "simulator · round 3 · seed 1");
    wait_for(
        &client,
        "window.ratf.last.phase === 'waiting_for_part_list' && window.ratf.last.time_s > 0.5",
        "the round waits for its part list",
        30,
    )
    .await;
    let start = wait_for(&client, "window.ratf.last.pose", "a pose", 5).await;

    // Force start with a part list starts the round.
    let parts = client.find(Locator::Id("parts")).await.unwrap();
    parts.clear().await.unwrap();
    parts.send_keys("RGGB").await.unwrap();
    client
        .find(Locator::Id("force-start"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    wait_for(
        &client,
        "window.ratf.last.phase === 'running' && window.ratf.last.events.some(e => e.text.includes('RGGB, forced'))",
        "force start begins the round",
        20,
    )
    .await;

    // The robot moves.
    let moved = format!(
        "Math.hypot(window.ratf.last.pose.x - {}, window.ratf.last.pose.y - {}) > 0.10",
        start["x"], start["y"]
    );
    wait_for(&client, &moved, "the robot moves 10 cm", 60).await;
    // Mid-round for the screenshots: the first part on the magnet.
    wait_for(
        &client,
        "window.ratf.last.carrying !== null",
        "the first pick",
        60,
    )
    .await;
    screenshot(&client, "hmi-laptop.png").await;
    client.set_window_size(390, 844).await.unwrap();
    wait_for(
        &client,
        "document.documentElement.clientWidth <= 400",
        "phone width",
        10,
    )
    .await;
    // One more snapshot drawn at the new size.
    let seen = wait_for(&client, "window.ratf.last.time_s", "a snapshot", 5).await;
    wait_for(
        &client,
        &format!("window.ratf.last.time_s > {seen}"),
        "a newer snapshot",
        10,
    )
    .await;
    screenshot(&client, "hmi-phone.png").await;
    client.set_window_size(1366, 900).await.unwrap();

    // Stop halts it: the core's references are zero and the magnet off.
    client
        .find(Locator::Id("stop"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    wait_for(
        &client,
        "window.ratf.last.stopped && window.ratf.last.wheels.reference_rad_s.every(r => r === 0) && !window.ratf.last.magnet",
        "stop zeroes the references",
        20,
    )
    .await;
    let phase = client.find(Locator::Id("phase")).await.unwrap();
    assert!(phase.text().await.unwrap().starts_with("STOPPED"));

    // Set the pose by dragging on the map: press at (0.2, -0.1) m, drag towards +y. The map
    // draws 1.9 m across its width, at the same scale on both axes, from (-0.95, 0.75) m.
    client
        .find(Locator::Id("set-pose"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    client
        .execute(
            "const c = document.getElementById('map'), r = c.getBoundingClientRect(); \
             const at = (x, y) => ({ clientX: r.left + (x + 0.95) / 1.9 * r.width, \
               clientY: r.top + (0.75 - y) / 1.9 * r.width, pointerId: 1, bubbles: true }); \
             c.dispatchEvent(new PointerEvent('pointerdown', at(0.2, -0.1))); \
             c.dispatchEvent(new PointerEvent('pointermove', at(0.2, 0.1))); \
             c.dispatchEvent(new PointerEvent('pointerup', at(0.2, 0.1)));",
            vec![],
        )
        .await
        .unwrap();
    let pose_set = wait_for(
        &client,
        "window.ratf.last.events.find(e => e.text.startsWith('pose set by the operator'))",
        "a drag on the map sets the pose",
        20,
    )
    .await;
    let text = pose_set["text"].as_str().unwrap();
    assert!(text.contains("(0.200, -0.100) m, 90.0°"), "{text}");

    // Without the token a control is refused, and the page says so.
    let base = url.split('?').next().unwrap().to_owned();
    client.goto(&base).await.unwrap();
    wait_for(&client, LOADED, "the page loads without the token", 30).await;
    let access = client.find(Locator::Id("access")).await.unwrap();
    assert_eq!(access.text().await.unwrap(), "view only");
    client
        .find(Locator::Id("resume"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    let message = wait_for(
        &client,
        "document.getElementById('message').textContent.startsWith('refused') && document.getElementById('message').textContent",
        "the page says the control was refused",
        10,
    )
    .await;
    assert!(message.as_str().unwrap().contains("token"), "{message}");
    // The robot stays stopped.
    wait_for(&client, "window.ratf.last.stopped", "still stopped", 5).await;
    client.close().await.unwrap();
}

#[tokio::test]
#[ignore = "needs chromium and chromium-driver: .ci/run's browser step runs it"]
async fn the_replay_slider_moves_the_robot_to_a_recorded_time() {
    let dir = scratch("replay");
    let out = dir.join("out");
    let status = Command::new(env!("CARGO_BIN_EXE_ratf"))
        .args(["sim", "--round", "1", "--out", out.to_str().unwrap()])
        .stdout(Stdio::null())
        .status()
        .expect("ratf sim");
    assert!(status.success());
    let recording = out.join("sim-round1-seed1-ours.mcap");
    let (_ratf, url) = serve_ratf(&[
        "replay",
        recording.to_str().unwrap(),
        "--hmi",
        "127.0.0.1:0",
    ]);
    let (_driver, client) = browser(&dir.join("profile")).await;
    client.goto(&url).await.expect("open the page");
    wait_for(&client, LOADED, "the replay page loads", 30).await;
    let start = wait_for(
        &client,
        "window.ratf.last.time_s === 0 && window.ratf.last.pose",
        "the replay starts at time 0",
        10,
    )
    .await;
    let duration = wait_for(
        &client,
        "window.ratf.last.replay.duration_s",
        "the replay's length",
        5,
    )
    .await
    .as_f64()
    .unwrap();
    assert!(duration > 5.0, "{duration}");

    // Slide to the middle: the robot is shown where it was then, away from the start.
    let target = (duration / 2.0 * 10.0).round() / 10.0;
    client
        .execute(
            &format!(
                "const s = document.getElementById('slider'); s.value = '{target}'; \
                 s.dispatchEvent(new Event('input')); s.dispatchEvent(new Event('change'));"
            ),
            vec![],
        )
        .await
        .unwrap();
    let moved = format!(
        "Math.abs(window.ratf.last.time_s - {target}) < 0.1 && \
         Math.hypot(window.ratf.last.pose.x - {}, window.ratf.last.pose.y - {}) > 0.10",
        start["x"], start["y"]
    );
    wait_for(&client, &moved, "the slider moves the robot", 30).await;
    assert_eq!(
        client
            .find(Locator::Id("slider"))
            .await
            .unwrap()
            .prop("value")
            .await
            .unwrap()
            .map(|v| v.parse::<f64>().unwrap()),
        Some(target)
    );

    // Jump to the first pick on the timeline, back in time.
    let pick = client
        .find(Locator::XPath(
            "//ol[@id='timeline']/li[.//span[contains(@class,'k-pick')]][last()]",
        ))
        .await
        .expect("a pick on the timeline");
    let pick_text = pick.text().await.unwrap();
    pick.click().await.unwrap();
    wait_for(
        &client,
        "window.ratf.last.carrying !== null && window.ratf.last.time_s > 0",
        "a jump to the pick shows the part on the magnet",
        30,
    )
    .await;
    assert!(pick_text.contains("picked"), "{pick_text}");
    client.close().await.unwrap();
}
