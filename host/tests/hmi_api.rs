//! The HMI's server side, in process, over real HTTP on loopback: the stream's messages
//! against the snapshot's schema, controls without the token refused (401), with it carried
//! out, and bad input refused (400) with a message that says what to send.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ratf_core::config::{Config, Policy};
use ratf_core::runtime::{Devices, Input, OperatorCommand, Outputs, Stamped};
use ratf_host::apps::round::{Live, RoundEvent, RoundOptions, run_live};
use ratf_host::devices::operator::{WithOperator, operator_channel};
use ratf_host::hmi::auth::Token;
use ratf_host::hmi::floor::Floor;
use ratf_host::hmi::hub::Hub;
use ratf_host::hmi::server::{Controls, HmiServer, Info, serve};
use ratf_host::hmi::tap::HmiTap;
use serde_json::Value;

const TOKEN: &str = "0123456789abcdef";

/// Devices with nothing of their own: only the operator's commands come through.
struct Idle;

impl Devices for Idle {
    type Error = std::convert::Infallible;
    fn next_input(&mut self) -> Result<Option<Stamped>, Self::Error> {
        Ok(None)
    }
    fn apply(&mut self, _: &Stamped, _: &Outputs) -> Result<(), Self::Error> {
        Ok(())
    }
}

type Loop = WithOperator<Idle>;

fn start(hub: Arc<Hub>) -> (HmiServer, Loop) {
    let config = Config::default();
    let (sender, receiver) = operator_channel();
    let controls = Controls {
        operator: Some(Arc::new(Mutex::new(Some(sender)))),
        ..Default::default()
    };
    let info = Info {
        mode: "robot",
        controls: vec!["force-start", "stop", "resume", "set-pose"],
        duration_s: None,
        timeline: Vec::new(),
        round: None,
    };
    let server = serve(
        "127.0.0.1:0",
        Token::from_text(TOKEN),
        hub,
        &Floor::new(&config),
        config.field.field(),
        &info,
        controls,
    )
    .unwrap();
    (server, WithOperator::new(Idle, receiver))
}

/// One request; the status and the body.
fn request(
    at: SocketAddr,
    method: &str,
    path: &str,
    token: Option<&str>,
    body: &str,
) -> (u16, String) {
    let mut stream = TcpStream::connect(at).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .unwrap();
    let auth = token.map_or_else(String::new, |t| format!("Authorization: Bearer {t}\r\n"));
    write!(
        stream,
        "{method} {path} HTTP/1.1\r\nHost: ratf\r\nConnection: close\r\n{auth}\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut answer = String::new();
    stream.read_to_string(&mut answer).unwrap();
    let status = answer
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let body = answer
        .split_once("\r\n\r\n")
        .map_or(String::new(), |(_, b)| b.to_owned());
    (status, body)
}

fn error_of(body: &str) -> String {
    let value: Value = serde_json::from_str(body).unwrap_or(Value::Null);
    value["error"].as_str().unwrap_or_default().to_owned()
}

/// The next command the loop gets, waiting up to 10 s.
fn received(devices: &mut Loop) -> Option<OperatorCommand> {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let Ok(input) = devices.next_input();
        if let Some(Stamped {
            input: Input::Operator(command),
            ..
        }) = input
        {
            return Some(command);
        }
        if Instant::now() > deadline {
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn a_control_without_the_token_is_refused_and_with_it_reaches_the_loop() {
    let (server, mut receiver) = start(Hub::new());
    let at = server.address();
    let (status, body) = request(at, "POST", "/api/stop", None, "{}");
    assert_eq!(status, 401, "{body}");
    assert!(error_of(&body).contains("token"), "{body}");
    let (status, _) = request(at, "POST", "/api/stop", Some("0123456789abcdeX"), "{}");
    assert_eq!(status, 401);
    let (status, _) = request(at, "POST", &format!("/api/stop?token={TOKEN}1"), None, "{}");
    assert_eq!(status, 401);
    let Ok(nothing) = receiver.next_input();
    assert_eq!(nothing, None, "a refused control reached the loop");

    let (status, body) = request(at, "POST", "/api/stop", Some(TOKEN), "{}");
    assert_eq!(status, 200, "{body}");
    assert_eq!(received(&mut receiver), Some(OperatorCommand::Stop));
    let (status, _) = request(
        at,
        "POST",
        "/api/force-start",
        Some(TOKEN),
        r#"{"parts": "rggx"}"#,
    );
    assert_eq!(status, 200);
    let Some(OperatorCommand::ForceStart { parts }) = received(&mut receiver) else {
        panic!("no force start");
    };
    assert_eq!(parts[3], None);
    let (status, _) = request(
        at,
        "POST",
        &format!("/api/set-pose?token={TOKEN}"),
        None,
        r#"{"x": -0.6, "y": 0.1, "yaw_deg": 90}"#,
    );
    assert_eq!(status, 200);
    let Some(OperatorCommand::SetPose { pose }) = received(&mut receiver) else {
        panic!("no set pose");
    };
    assert!((pose.yaw_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    // Viewing is open.
    let (status, page) = request(at, "GET", "/", None, "");
    assert_eq!(status, 200);
    assert!(page.contains("<canvas id=\"map\""));
}

#[test]
fn bad_input_is_refused_with_a_message_and_nothing_reaches_the_loop() {
    let (server, mut receiver) = start(Hub::new());
    let at = server.address();
    for (path, body, status, says) in [
        (
            "/api/force-start",
            r#"{"parts": "RGGY"}"#,
            400,
            "four letters of R, G, B or X",
        ),
        (
            "/api/force-start",
            r#"{"parts": "RGB"}"#,
            400,
            "four letters",
        ),
        ("/api/force-start", "{parts", 400, "not the JSON expected"),
        ("/api/force-start", "{}", 400, "missing field `parts`"),
        (
            "/api/set-pose",
            r#"{"x": 2.5, "y": 0}"#,
            400,
            "off the floor",
        ),
        (
            "/api/set-pose",
            r#"{"x": "left", "y": 0}"#,
            400,
            "not the JSON expected",
        ),
        ("/api/round", r#"{"round": 2}"#, 409, "only the simulator"),
        ("/api/replay/seek", r#"{"t_s": 3}"#, 409, "only ratf replay"),
        ("/api/jump", "{}", 404, "no control named"),
    ] {
        let (got, answer) = request(at, "POST", path, Some(TOKEN), body);
        assert_eq!(got, status, "{path} {body}: {answer}");
        assert!(error_of(&answer).contains(says), "{path} {body}: {answer}");
    }
    let long = format!(r#"{{"parts": "{}"}}"#, "R".repeat(5000));
    let (got, answer) = request(at, "POST", "/api/force-start", Some(TOKEN), &long);
    assert_eq!(got, 400, "{answer}");
    let Ok(nothing) = receiver.next_input();
    assert_eq!(nothing, None, "a refused control reached the loop");
}

/// JSON types a snapshot's fields must have: `/pointer` → type.
const SCHEMA: &[(&str, &str)] = &[
    ("/mode", "string"),
    ("/time_s", "number"),
    ("/phase", "string"),
    ("/stopped", "bool"),
    ("/manual", "bool"),
    ("/placed", "number"),
    ("/points", "number"),
    ("/pose/x", "number"),
    ("/pose/y", "number"),
    ("/pose/yaw_rad", "number"),
    ("/covariance_m2", "array"),
    ("/heading_std_rad", "number"),
    ("/truth/x", "number"),
    ("/scan", "array"),
    ("/beacons/used", "number"),
    ("/beacons/seen", "array"),
    ("/parts", "array"),
    ("/path", "array"),
    ("/target/name", "string"),
    ("/magnet", "bool"),
    ("/switch_pressed", "bool"),
    ("/wheels/reference_rad_s", "array"),
    ("/wheels/measured_rad_s", "array"),
    ("/health/wheel_hz", "number"),
    ("/health/scan_hz", "number"),
    ("/health/imu_hz", "number"),
    ("/health/lost", "bool"),
    ("/health/faults", "array"),
    ("/events", "array"),
    ("/events/0/t_s", "number"),
    ("/events/0/kind", "string"),
    ("/events/0/text", "string"),
];

fn kind(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "bool",
        Value::Number(_) => "number",
        Value::String(_) => "string",
        Value::Array(_) => "array",
        Value::Object(_) => "object",
    }
}

#[test]
fn the_stream_carries_snapshots_of_a_simulated_round_that_match_the_schema() {
    let hub = Hub::new();
    let (server, _receiver) = start(hub.clone());
    let config = Config::default();
    let mut tap = HmiTap::new(hub.clone(), "sim", &config);
    // Four simulated seconds of round 1: the part list comes at 1 s, the robot sets off.
    let enough = AtomicBool::new(false);
    let abort = || enough.load(Ordering::Relaxed);
    let live = Live {
        abort: Some(&abort),
        ..Live::default()
    };
    run_live(
        &config,
        &config,
        &RoundOptions::new(1, 1, Policy::Ours),
        &mut [&mut tap],
        live,
        |event| {
            if let RoundEvent::Tick { time, .. } = event {
                enough.store(time.as_secs_f64() >= 4.0, Ordering::Relaxed);
            }
        },
    )
    .unwrap();

    let mut stream = TcpStream::connect(server.address()).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .unwrap();
    write!(stream, "GET /api/stream HTTP/1.1\r\nHost: ratf\r\n\r\n").unwrap();
    let mut lines = BufReader::new(stream).lines();
    let status = lines.next().unwrap().unwrap();
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
    let data = lines
        .map_while(Result::ok)
        .find_map(|l| l.strip_prefix("data: ").map(str::to_owned))
        .expect("a data line");
    let snapshot: Value = serde_json::from_str(&data).unwrap();
    for (pointer, expected) in SCHEMA {
        let value = snapshot.pointer(pointer).unwrap_or(&Value::Null);
        assert_eq!(kind(value), *expected, "{pointer} in {data}");
    }
    assert_eq!(snapshot["mode"], "sim");
    assert_eq!(snapshot["phase"], "running");
    assert_eq!(snapshot["covariance_m2"].as_array().unwrap().len(), 3);
    assert_eq!(
        snapshot["wheels"]["reference_rad_s"]
            .as_array()
            .unwrap()
            .len(),
        4
    );
    assert!(
        snapshot["scan"].as_array().unwrap().len() > 50,
        "a lidar revolution"
    );
    for point in snapshot["scan"].as_array().unwrap() {
        let xy = point.as_array().unwrap();
        assert!(xy.len() == 2 && xy.iter().all(|v| v.as_f64().unwrap().abs() < 3.0));
    }
    let events = snapshot["events"].as_array().unwrap();
    assert!(
        events.iter().any(|e| e["kind"] == "start"),
        "the part list is on the timeline: {events:?}"
    );
    // The same message as the one-shot state.
    let (status, state) = request(server.address(), "GET", "/api/state", None, "");
    assert_eq!(status, 200);
    assert_eq!(
        serde_json::from_str::<Value>(&state).unwrap()["time_s"],
        snapshot["time_s"]
    );
    // The floor the page draws.
    let (_, floor) = request(server.address(), "GET", "/api/floor", None, "");
    let floor: Value = serde_json::from_str(&floor).unwrap();
    assert_eq!(floor["beacons"].as_array().unwrap().len(), 4);
    assert_eq!(floor["slots"].as_array().unwrap().len(), 16);
}
