//! The HMI's control parser (`ratf_host::hmi::commands::parse`) on any command name and
//! body, as a client on the venue's Wi-Fi could send them: it never panics; what it accepts
//! is within its documented ranges (a pose on the floor, finite; a round 1–3; a replay time
//! from 0, a speed within `REPLAY_SPEEDS`); what it refuses is a 400 for a known control or
//! a 404 for an unknown one, with a message.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ratf_core::field::Field;
use ratf_core::runtime::OperatorCommand;
use ratf_host::hmi::commands::{CONTROL_NAMES, Control, REPLAY_SPEEDS, ReplayRequest, parse};

fuzz_target!(|data: &[u8]| {
    // The first byte picks a control (or, past the list, takes the rest up to a NUL as a
    // name of the client's own); the rest is the body.
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let (command, body) = match CONTROL_NAMES.get(usize::from(pick)) {
        Some(name) => (name.to_string(), rest),
        None => {
            let end = rest.iter().position(|&b| b == 0).unwrap_or(rest.len());
            let (name, body) = rest.split_at(end);
            (String::from_utf8_lossy(name).into_owned(), body)
        }
    };
    let field = Field::competition();
    match parse(&command, body, &field) {
        Ok(control) => {
            assert!(
                CONTROL_NAMES.contains(&command.as_str()),
                "{command:?} accepted"
            );
            match control {
                Control::Operator(OperatorCommand::SetPose { pose }) => {
                    assert!(pose.x.is_finite() && pose.y.is_finite() && pose.yaw_rad.is_finite());
                    assert!(field.printed_area().contains(pose.position()), "{pose:?}");
                }
                Control::Round { round, .. } => assert!((1..=3).contains(&round)),
                Control::Replay(ReplayRequest::Seek(t_s)) => {
                    assert!(t_s.is_finite() && t_s >= 0.0)
                }
                Control::Replay(ReplayRequest::Speed(speed)) => {
                    assert!((REPLAY_SPEEDS.0..=REPLAY_SPEEDS.1).contains(&speed))
                }
                _ => {}
            }
        }
        Err(refusal) => {
            let expected = if CONTROL_NAMES.contains(&command.as_str()) {
                400
            } else {
                404
            };
            assert_eq!(refusal.status, expected, "{command:?}: {refusal}");
            assert!(!refusal.message.is_empty());
        }
    }
});
