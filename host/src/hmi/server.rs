//! The HMI's HTTP server: blocking `tiny_http` on its own threads, so no async runtime
//! enters the robot's process.
//!
//! | request | answer |
//! |---|---|
//! | `GET /` (`/app.js`, `/style.css`) | the page, embedded in the binary (works offline) |
//! | `GET /api/info` | the mode, the controls it takes, a replay's length and timeline |
//! | `GET /api/floor` | the shop floor ([`Floor`]) |
//! | `GET /api/state` | the latest [`Snapshot`](super::snapshot::Snapshot) |
//! | `GET /api/stream` | Server-Sent Events: one snapshot per `data:` line, ≥ 10 a second |
//! | `POST /api/<control>` | a control ([`super::commands`]); needs the token |
//!
//! Viewing is open; a control needs the token (header `Authorization: Bearer TOKEN`, or
//! `X-Ratf-Token`, or `?token=` in the URL): 401 without it, 400 with a message for bad
//! input. Every control taken is logged on stderr; the core's commands are recorded too.

use std::io::{Read, Write};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use serde::Serialize;
use tiny_http::{Header, Method, Request, Response, Server};

use ratf_core::field::Field;

use super::auth::Token;
use super::commands::{Control, Refusal, ReplayRequest, RoundChoice, parse};
use super::floor::Floor;
use super::hub::Hub;
use super::snapshot::EventLine;
use crate::devices::operator::OperatorSender;

const INDEX_HTML: &str = include_str!("assets/index.html");
const APP_JS: &str = include_str!("assets/app.js");
const STYLE_CSS: &str = include_str!("assets/style.css");

/// Streams open at once (phones and laptops of one team, with margin).
pub const MAX_STREAMS: usize = 16;
/// Largest control body taken, bytes.
const MAX_BODY: u64 = 4096;
/// A stream with nothing new sends a comment this often, so a dead client is noticed.
const KEEPALIVE: Duration = Duration::from_secs(2);

/// The sender to the running core's loop, replaced when the simulator restarts a round
/// (`None` between rounds).
pub type OperatorSlot = Arc<Mutex<Option<OperatorSender>>>;

/// Where the controls go.
#[derive(Clone, Debug, Default)]
pub struct Controls {
    /// The core's commands (`sim`, `robot`).
    pub operator: Option<OperatorSlot>,
    /// The simulator's round choice.
    pub rounds: Option<RoundChoice>,
    /// The replay player.
    pub replay: Option<Sender<ReplayRequest>>,
}

/// What the page learns once (`GET /api/info`).
#[derive(Clone, Debug, Serialize)]
pub struct Info {
    /// `sim`, `robot` or `replay`.
    pub mode: &'static str,
    /// The controls this run takes.
    pub controls: Vec<&'static str>,
    /// A replay's length, s.
    pub duration_s: Option<f64>,
    /// A replay's whole timeline, to jump to.
    pub timeline: Vec<EventLine>,
    /// The round and seed being simulated.
    pub round: Option<(u8, u64)>,
}

/// Why the server did not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The address is not `HOST:PORT`.
    #[error("--hmi {0}: not an address; give HOST:PORT, e.g. 127.0.0.1:8080 or 0.0.0.0:8080")]
    Address(String),
    /// The port could not be opened.
    #[error(
        "--hmi {address}: cannot listen there ({message}); choose a free port or another address"
    )]
    Bind {
        /// The address.
        address: String,
        /// The system's words.
        message: String,
    },
    /// A thread could not start.
    #[error("the HMI server's thread did not start: {0}")]
    Thread(std::io::Error),
}

/// The running server; it serves until the process ends.
#[derive(Debug)]
pub struct HmiServer {
    address: SocketAddr,
    token: Token,
    _thread: JoinHandle<()>,
}

impl HmiServer {
    /// Where it listens (the port chosen when 0 was asked).
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// The page's URL with the control token, as `ratf` prints it. An unspecified address
    /// (0.0.0.0) is shown as `ROBOT-ADDRESS`: use the robot's address on the Wi-Fi.
    pub fn control_url(&self) -> String {
        let host = if self.address.ip().is_unspecified() {
            "ROBOT-ADDRESS".to_owned()
        } else {
            self.address.ip().to_string()
        };
        format!(
            "http://{host}:{}/?token={}",
            self.address.port(),
            self.token.as_str()
        )
    }
}

struct Site {
    hub: Arc<Hub>,
    token: Token,
    info: String,
    floor: String,
    field: Field,
    controls: Controls,
    streams: Arc<AtomicUsize>,
}

/// Serve the HMI on `address` (`HOST:PORT`; port 0 picks a free one).
pub fn serve(
    address: &str,
    token: Token,
    hub: Arc<Hub>,
    floor: &Floor,
    field: Field,
    info: &Info,
    controls: Controls,
) -> Result<HmiServer, ServeError> {
    let parsed: SocketAddr = address
        .parse()
        .map_err(|_| ServeError::Address(address.to_owned()))?;
    let server = Server::http(parsed).map_err(|e| ServeError::Bind {
        address: address.to_owned(),
        message: e.to_string(),
    })?;
    let bound = server.server_addr().to_ip().unwrap_or(parsed);
    let site = Site {
        hub,
        token: token.clone(),
        info: serde_json::to_string(info).unwrap_or_else(|_| "{}".into()),
        floor: serde_json::to_string(floor).unwrap_or_else(|_| "{}".into()),
        field,
        controls,
        streams: Arc::new(AtomicUsize::new(0)),
    };
    let thread = std::thread::Builder::new()
        .name("hmi".into())
        .spawn(move || {
            for request in server.incoming_requests() {
                site.handle(request);
            }
        })
        .map_err(ServeError::Thread)?;
    Ok(HmiServer {
        address: bound,
        token,
        _thread: thread,
    })
}

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes())
        .unwrap_or_else(|()| Header::from_bytes(&b"X-Invalid"[..], &b"1"[..]).expect("ASCII"))
}

fn reply(request: Request, status: u16, content_type: &str, body: String) {
    let response = Response::from_string(body)
        .with_status_code(status)
        .with_header(header("Content-Type", content_type))
        .with_header(header("Cache-Control", "no-store"));
    // A client that went away needs no answer.
    let _ = request.respond(response);
}

fn reply_json(request: Request, status: u16, body: serde_json::Value) {
    reply(request, status, "application/json", body.to_string());
}

fn refuse(request: Request, refusal: &Refusal) {
    reply_json(
        request,
        refusal.status,
        serde_json::json!({ "error": refusal.message }),
    );
}

/// The token offered with `request`, if any.
fn offered_token(request: &Request) -> Option<String> {
    for h in request.headers() {
        if h.field.equiv("Authorization")
            && let Some(rest) = h.value.as_str().strip_prefix("Bearer ")
        {
            return Some(rest.trim().to_owned());
        }
        if h.field.equiv("X-Ratf-Token") {
            return Some(h.value.as_str().trim().to_owned());
        }
    }
    let query = request.url().split_once('?')?.1;
    query
        .split('&')
        .find_map(|pair| pair.strip_prefix("token="))
        .map(str::to_owned)
}

impl Site {
    fn handle(&self, mut request: Request) {
        let path = request.url().split('?').next().unwrap_or("/").to_owned();
        match (request.method(), path.as_str()) {
            (Method::Get, "/" | "/index.html") => {
                reply(request, 200, "text/html; charset=utf-8", INDEX_HTML.into())
            }
            (Method::Get, "/app.js") => reply(
                request,
                200,
                "text/javascript; charset=utf-8",
                APP_JS.into(),
            ),
            (Method::Get, "/style.css") => {
                reply(request, 200, "text/css; charset=utf-8", STYLE_CSS.into())
            }
            (Method::Get, "/api/info") => {
                reply(request, 200, "application/json", self.info.clone())
            }
            (Method::Get, "/api/floor") => {
                reply(request, 200, "application/json", self.floor.clone())
            }
            (Method::Get, "/api/state") => {
                let (_, json) = self.hub.latest();
                let body = if json.is_empty() {
                    "null".to_owned()
                } else {
                    json.to_string()
                };
                reply(request, 200, "application/json", body)
            }
            (Method::Get, "/api/stream") => self.stream(request),
            (Method::Post, p) if p.starts_with("/api/") => {
                let command = p.trim_start_matches("/api/").to_owned();
                match self.control(&mut request, &command) {
                    Ok((status, body)) => reply_json(request, status, body),
                    Err(refusal) => refuse(request, &refusal),
                }
            }
            _ => reply_json(
                request,
                404,
                serde_json::json!({ "error": format!("nothing at {path}; the page is at /") }),
            ),
        }
    }

    /// Check the token, parse the control and carry it out: the status and JSON answer.
    fn control(
        &self,
        request: &mut Request,
        command: &str,
    ) -> Result<(u16, serde_json::Value), Refusal> {
        let allowed = offered_token(request).is_some_and(|t| self.token.matches(&t));
        if !allowed {
            return Err(Refusal {
                status: 401,
                message: "control refused: no valid token. Open the page with the URL ratf \
                          printed at start-up (it ends in ?token=…)"
                    .into(),
            });
        }
        let mut body = Vec::new();
        request
            .as_reader()
            .take(MAX_BODY + 1)
            .read_to_end(&mut body)
            .map_err(|e| Refusal::bad(format!("{command}: the body could not be read: {e}")))?;
        if body.len() as u64 > MAX_BODY {
            return Err(Refusal::bad(format!(
                "{command}: the body is over {MAX_BODY} bytes; a control is a small JSON object"
            )));
        }
        let control = parse(command, &body, &self.field)?;
        let unavailable = |what: &str| Refusal {
            status: 409,
            message: format!("{command}: {what}"),
        };
        let peer = request
            .remote_addr()
            .map_or_else(|| "?".to_owned(), ToString::to_string);
        match &control {
            Control::Operator(operator) => {
                let slot = self.controls.operator.as_ref().ok_or_else(|| {
                    unavailable("a replay cannot be driven; use the replay controls")
                })?;
                let sender = slot
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .clone()
                    .ok_or_else(|| unavailable("no round is running; restart one first"))?;
                sender.send(operator.clone()).map_err(|e| Refusal {
                    status: 503,
                    message: format!("{command}: {e}"),
                })?;
            }
            Control::Round { round, seed } => {
                let rounds = self.controls.rounds.as_ref().ok_or_else(|| {
                    unavailable("only the simulator chooses rounds (ratf sim --hmi)")
                })?;
                rounds.choose(*round, *seed);
            }
            Control::Replay(replay) => {
                let player = self
                    .controls
                    .replay
                    .as_ref()
                    .ok_or_else(|| unavailable("only ratf replay --hmi has a replay player"))?;
                player.send(*replay).map_err(|_| Refusal {
                    status: 503,
                    message: format!("{command}: the replay player has stopped"),
                })?;
            }
        }
        eprintln!("hmi: {peer}: {command}: {control:?}");
        Ok((
            200,
            serde_json::json!({ "ok": true, "message": format!("{command}: sent") }),
        ))
    }

    /// Server-Sent Events: each new snapshot as a `data:` line, on a thread of its own.
    fn stream(&self, request: Request) {
        if self.streams.fetch_add(1, Ordering::SeqCst) >= MAX_STREAMS {
            self.streams.fetch_sub(1, Ordering::SeqCst);
            reply_json(
                request,
                503,
                serde_json::json!({ "error": format!(
                    "{MAX_STREAMS} pages are already watching; close one and reload"
                ) }),
            );
            return;
        }
        let hub = self.hub.clone();
        let streams = self.streams.clone();
        let spawned = std::thread::Builder::new()
            .name("hmi-stream".into())
            .spawn(move || {
                let mut writer = request.into_writer();
                let _ = send_events(&hub, &mut writer);
                streams.fetch_sub(1, Ordering::SeqCst);
            });
        if spawned.is_err() {
            self.streams.fetch_sub(1, Ordering::SeqCst);
        }
    }
}

/// Write the stream until the client goes away or the hub closes.
fn send_events(hub: &Hub, writer: &mut dyn Write) -> std::io::Result<()> {
    writer.write_all(
        b"HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\n\
          Connection: close\r\n\r\n",
    )?;
    writer.flush()?;
    let mut seen = 0;
    loop {
        match hub.next_after(seen, KEEPALIVE) {
            Some((sequence, json)) => {
                seen = sequence;
                writer.write_all(b"data: ")?;
                writer.write_all(json.as_bytes())?;
                writer.write_all(b"\n\n")?;
            }
            None if hub.is_closed() => return Ok(()),
            None => writer.write_all(b": waiting\n\n")?,
        }
        writer.flush()?;
    }
}
