//! The controls (`POST /api/<command>`, JSON body) and what each becomes: an
//! [`OperatorCommand`] for the core, a round choice for the simulator, or a request to the
//! replay player. Bad input is refused with a message that says what to send instead.

use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::Duration;

use serde::Deserialize;
use serde::de::DeserializeOwned;

use ratf_core::field::geometry::Pose2;
use ratf_core::field::{Field, PartColor};
use ratf_core::runtime::OperatorCommand;

/// The controls, as `POST /api/<name>`.
pub const CONTROL_NAMES: [&str; 9] = [
    "force-start",
    "stop",
    "resume",
    "set-pose",
    "round",
    "replay/seek",
    "replay/play",
    "replay/pause",
    "replay/speed",
];

/// Slowest and fastest replay speeds, robot seconds per wall second.
pub const REPLAY_SPEEDS: (f64, f64) = (0.1, 50.0);

/// A request to the replay player.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReplayRequest {
    /// Show the robot at this robot time, s.
    Seek(f64),
    /// Play on from here.
    Play,
    /// Hold.
    Pause,
    /// Play at this many robot seconds per wall second.
    Speed(f64),
}

/// What a control asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum Control {
    /// A command for the core.
    Operator(OperatorCommand),
    /// Restart the simulated round with this round and seed.
    Round {
        /// 1, 2 or 3.
        round: u8,
        /// The simulator's seed.
        seed: u64,
    },
    /// A request to the replay player.
    Replay(ReplayRequest),
}

/// Why a control was refused: the HTTP status and a message for the page.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct Refusal {
    /// 400 (bad input), 404 (no such control), 409 (not in this mode), 503 (loop busy).
    pub status: u16,
    /// What was wrong and what to send instead.
    pub message: String,
}

impl Refusal {
    /// Bad input (400).
    pub fn bad(message: impl Into<String>) -> Self {
        Self {
            status: 400,
            message: message.into(),
        }
    }
}

/// A part list: four of R, G, B, X (`X` = empty slot), incoming slots 1–4.
pub fn parse_parts(text: &str) -> Result<[Option<PartColor>; 4], Refusal> {
    let refuse = || {
        Refusal::bad(format!(
            "part list {text:?}: give four letters of R, G, B or X (empty), one per incoming \
             slot 1-4, e.g. \"RGGB\""
        ))
    };
    let letters: Vec<char> = text.trim().chars().collect();
    if letters.len() != 4 {
        return Err(refuse());
    }
    let mut parts = [None; 4];
    for (part, letter) in parts.iter_mut().zip(letters) {
        *part = match letter.to_ascii_uppercase() {
            'X' => None,
            l => Some(PartColor::from_letter(l).ok_or_else(refuse)?),
        };
    }
    Ok(parts)
}

fn json<T: DeserializeOwned>(command: &str, body: &[u8], example: &str) -> Result<T, Refusal> {
    serde_json::from_slice(body).map_err(|e| {
        Refusal::bad(format!(
            "{command}: the body is not the JSON expected ({e}); send e.g. {example}"
        ))
    })
}

#[derive(Deserialize)]
struct PartsBody {
    parts: String,
}

#[derive(Deserialize)]
struct PoseBody {
    x: f64,
    y: f64,
    #[serde(default)]
    yaw_deg: f64,
}

#[derive(Deserialize)]
struct RoundBody {
    round: u8,
    #[serde(default = "first_seed")]
    seed: u64,
}

fn first_seed() -> u64 {
    1
}

#[derive(Deserialize)]
struct SeekBody {
    t_s: f64,
}

#[derive(Deserialize)]
struct SpeedBody {
    speed: f64,
}

/// The control `command` with `body`, checked against `field` (a pose must be on the floor).
pub fn parse(command: &str, body: &[u8], field: &Field) -> Result<Control, Refusal> {
    Ok(match command {
        "force-start" => {
            let body: PartsBody = json(command, body, r#"{"parts": "RGGB"}"#)?;
            Control::Operator(OperatorCommand::ForceStart {
                parts: parse_parts(&body.parts)?,
            })
        }
        "stop" => Control::Operator(OperatorCommand::Stop),
        "resume" => Control::Operator(OperatorCommand::Resume),
        "set-pose" => {
            let body: PoseBody = json(command, body, r#"{"x": -0.6, "y": 0.0, "yaw_deg": 0}"#)?;
            let floor = field.printed_area();
            let finite = body.x.is_finite() && body.y.is_finite() && body.yaw_deg.is_finite();
            let pose = Pose2::new(body.x, body.y, body.yaw_deg.to_radians());
            if !finite || !floor.contains(pose.position()) {
                return Err(Refusal::bad(format!(
                    "set-pose: ({}, {}) m is off the floor: x must be within [{:.3}, {:.3}] m \
                     and y within [{:.3}, {:.3}] m (world frame, origin at the centre)",
                    body.x, body.y, floor.min.x, floor.max.x, floor.min.y, floor.max.y
                )));
            }
            Control::Operator(OperatorCommand::SetPose { pose })
        }
        "round" => {
            let body: RoundBody = json(command, body, r#"{"round": 3, "seed": 1}"#)?;
            if !(1..=3).contains(&body.round) {
                return Err(Refusal::bad(format!(
                    "round: there is no round {}; choose 1, 2 or 3",
                    body.round
                )));
            }
            Control::Round {
                round: body.round,
                seed: body.seed,
            }
        }
        "replay/seek" => {
            let body: SeekBody = json(command, body, r#"{"t_s": 12.5}"#)?;
            if !body.t_s.is_finite() || body.t_s < 0.0 {
                return Err(Refusal::bad(format!(
                    "replay/seek: {} s is not a time in the recording; give seconds from 0",
                    body.t_s
                )));
            }
            Control::Replay(ReplayRequest::Seek(body.t_s))
        }
        "replay/play" => Control::Replay(ReplayRequest::Play),
        "replay/pause" => Control::Replay(ReplayRequest::Pause),
        "replay/speed" => {
            let body: SpeedBody = json(command, body, r#"{"speed": 2}"#)?;
            let (slow, fast) = REPLAY_SPEEDS;
            if !(slow..=fast).contains(&body.speed) {
                return Err(Refusal::bad(format!(
                    "replay/speed: {} is out of range; give {slow} to {fast} (× real time)",
                    body.speed
                )));
            }
            Control::Replay(ReplayRequest::Speed(body.speed))
        }
        other => {
            return Err(Refusal {
                status: 404,
                message: format!(
                    "no control named {other:?}; the controls are {}",
                    CONTROL_NAMES.join(", ")
                ),
            });
        }
    })
}

/// A round and seed chosen on the page, with the signal that one came.
type Chosen = (Mutex<Option<(u8, u64)>>, Condvar);

/// The simulator's round choice from the page: the server sets it, the simulator takes it.
#[derive(Clone, Debug, Default)]
pub struct RoundChoice(Arc<Chosen>);

impl RoundChoice {
    /// Ask for round `round` with `seed`.
    pub fn choose(&self, round: u8, seed: u64) {
        let (choice, changed) = &*self.0;
        *choice.lock().unwrap_or_else(PoisonError::into_inner) = Some((round, seed));
        changed.notify_all();
    }

    /// True when a choice waits (the running round should end).
    pub fn pending(&self) -> bool {
        self.0
            .0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .is_some()
    }

    /// Take the choice, waiting at most `timeout` for one.
    pub fn take(&self, timeout: Duration) -> Option<(u8, u64)> {
        let (choice, changed) = &*self.0;
        let guard = choice.lock().unwrap_or_else(PoisonError::into_inner);
        let (mut guard, _) = changed
            .wait_timeout_while(guard, timeout, |c| c.is_none())
            .unwrap_or_else(PoisonError::into_inner);
        guard.take()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn part_lists_are_four_of_r_g_b_x() {
        use PartColor::*;
        assert_eq!(
            parse_parts("RGGB").unwrap(),
            [Some(Red), Some(Green), Some(Green), Some(Blue)]
        );
        assert_eq!(parse_parts("xbxb").unwrap()[0], None);
        for bad in ["", "RGG", "RGGBB", "RGGY", "R GB"] {
            let refusal = parse_parts(bad).unwrap_err();
            assert_eq!(refusal.status, 400);
            assert!(refusal.message.contains("four letters"), "{refusal}");
        }
    }

    #[test]
    fn controls_parse_or_say_what_to_send() {
        let field = Field::competition();
        assert_eq!(
            parse("stop", b"", &field).unwrap(),
            Control::Operator(OperatorCommand::Stop)
        );
        let pose = parse(
            "set-pose",
            br#"{"x": -0.6, "y": 0.1, "yaw_deg": 90}"#,
            &field,
        );
        assert!(matches!(
            pose,
            Ok(Control::Operator(OperatorCommand::SetPose { .. }))
        ));
        let off = parse("set-pose", br#"{"x": 3.0, "y": 0.0}"#, &field).unwrap_err();
        assert!(off.message.contains("off the floor"), "{off}");
        let json = parse("force-start", b"{parts", &field).unwrap_err();
        assert!(json.message.contains("RGGB"), "{json}");
        assert_eq!(parse("fly", b"", &field).unwrap_err().status, 404);
        assert_eq!(
            parse("round", br#"{"round": 4}"#, &field)
                .unwrap_err()
                .status,
            400
        );
        assert_eq!(
            parse("replay/speed", br#"{"speed": 1000}"#, &field)
                .unwrap_err()
                .status,
            400
        );
    }

    #[test]
    fn a_round_choice_is_taken_once() {
        let choice = RoundChoice::default();
        assert!(!choice.pending());
        choice.choose(2, 7);
        assert!(choice.pending());
        assert_eq!(choice.take(Duration::ZERO), Some((2, 7)));
        assert_eq!(choice.take(Duration::ZERO), None);
    }
}
