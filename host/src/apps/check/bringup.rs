//! The steps with a person or with motion: each wheel turned by hand and the switch
//! pressed (interactive only), each motor turned open loop, the magnet toggled.

use std::time::Duration;

use serde_json::json;

use super::report::DeviceReport;
use super::session::Asked;
use super::wheels::{self, Drive, WHEEL_NAMES};
use super::{Check, HOLD_MARGIN_US, MAGNET_ON, SETTLE, bounded};
use crate::devices::open_loop::OpenLoopHold;

/// Why a step that needs a person was skipped when standard input closed.
const NO_ANSWER: &str = "nobody answered (standard input closed; --yes skips the questions)";

impl Check<'_, '_> {
    /// Each wheel turned by hand, then the switch (interactive only).
    pub(super) fn by_hand(&mut self) -> Option<()> {
        if !self.operator.interactive() {
            let why = "needs a person (run without --yes)".to_owned();
            self.devices
                .push(DeviceReport::skipped("encoders", why.clone()));
            self.devices.push(DeviceReport::skipped("switch", why));
            return Some(());
        }
        let moved = wheels::moved_ticks(self.config.robot.ticks_per_wheel_rev);
        let mut problems = Vec::new();
        let mut data = Vec::new();
        for (k, name) in WHEEL_NAMES.iter().enumerate() {
            self.session.restart_mega_window();
            let prompt = format!(
                "turn the {name} wheel (motor {k}) by hand so that it rolls forward, then \
                 press Enter (s + Enter: skip):"
            );
            let Some(line) = self.session.wait_enter(&mut *self.operator, &prompt)? else {
                self.devices
                    .push(DeviceReport::skipped("encoders", NO_ANSWER.to_owned()));
                self.devices
                    .push(DeviceReport::skipped("switch", NO_ANSWER.to_owned()));
                return Some(());
            };
            if line.eq_ignore_ascii_case("s") {
                continue;
            }
            let forward_sign = self.config.robot.wheel_forward_sign[k];
            let drive = Drive::ByHand { forward_sign };
            let ticks = self.session.mega_window.ticks();
            let verdict = wheels::judge(k, drive, ticks, moved);
            let text = wheels::describe(k, drive, &verdict);
            self.say(&format!("  wheel {k} ({name}): {text}"));
            if !verdict.is_ok() {
                problems.push(format!("wheel {k} ({name}) by hand: {text}"));
            }
            data.push(json!({"wheel": k, "name": name, "ticks": ticks, "result": verdict}));
        }
        let seen = format!("{} wheel(s) turned by hand", data.len());
        self.devices.push(DeviceReport::checked(
            "encoders",
            seen,
            problems,
            json!(data),
        ));
        self.session.restart_mega_window();
        let prompt = "press and release the box switch, then press Enter (s + Enter: skip):";
        let Some(line) = self.session.wait_enter(&mut *self.operator, prompt)? else {
            self.devices
                .push(DeviceReport::skipped("switch", NO_ANSWER.to_owned()));
            return Some(());
        };
        if line.eq_ignore_ascii_case("s") {
            self.devices.push(DeviceReport::skipped(
                "switch",
                "skipped by the operator".to_owned(),
            ));
            return Some(());
        }
        let changes = self.session.mega_window.switch_changes();
        let problems = if changes >= 2 {
            Vec::new()
        } else {
            vec![format!(
                "the switch changed {changes} time(s) (expected pressed, then released): check \
                 its wires on pin 53 and ground"
            )]
        };
        let seen = format!("{changes} changes");
        self.devices.push(DeviceReport::checked(
            "switch",
            seen,
            problems,
            json!({"changes": changes}),
        ));
        Some(())
    }

    /// Each motor in turn, open loop.
    pub(super) fn bring_up(&mut self) -> Option<()> {
        if self.operator.interactive() {
            let question = format!(
                "wheels off the ground? each will turn for {:.1} s [y/N]",
                self.options.spin_s
            );
            let why = match self.session.ask(&mut *self.operator, &question)? {
                Asked::Yes => None,
                Asked::NoAnswer => Some(NO_ANSWER),
                Asked::No | Asked::Unknown => Some("the wheels were not off the ground"),
            };
            if let Some(why) = why {
                self.devices
                    .push(DeviceReport::skipped("wheels", why.to_owned()));
                return Some(());
            }
        }
        let pwm_max = f64::from(self.config.mega.pwm_max);
        let pwm = (bounded(self.options.pwm_percent, 1.0, 100.0) / 100.0 * pwm_max).round() as i16;
        let spin = Duration::from_secs_f64(bounded(self.options.spin_s, 0.1, 10.0));
        let moved = wheels::moved_ticks(self.config.robot.ticks_per_wheel_rev);
        let mut problems = Vec::new();
        let mut data = Vec::new();
        for (k, name) in WHEEL_NAMES.iter().enumerate() {
            self.say(&format!(
                "turning the {name} wheel (motor {k}) at PWM {pwm:+} for {:.1} s: watch which \
                 way it turns",
                spin.as_secs_f64()
            ));
            self.session.restart_mega_window();
            let mut pwms = [0; 4];
            pwms[k] = pwm;
            self.session.hold(OpenLoopHold {
                pwm: pwms,
                solenoid_on: false,
                until_us: self.session.now_us() + spin.as_micros() as u64 + HOLD_MARGIN_US,
            });
            let spun = self.session.pump(spin);
            self.session.hold(OpenLoopHold::COAST);
            if !spun || !self.session.pump(SETTLE) {
                return None;
            }
            let ticks = self.session.mega_window.ticks();
            let seen_clockwise = if self.operator.interactive() {
                let rolling = if self.config.robot.wheel_forward_sign[k] > 0 {
                    "forward"
                } else {
                    "backward"
                };
                let question = format!(
                    "did it turn clockwise seen from outside the robot (its rim rolling \
                     {rolling})? [y/n, ? if unsure]"
                );
                match self.session.ask(&mut *self.operator, &question)? {
                    Asked::Yes => Some(true),
                    Asked::No => Some(false),
                    Asked::Unknown | Asked::NoAnswer => None,
                }
            } else {
                None
            };
            let drive = Drive::OpenLoop {
                pwm_sign: 1,
                seen_clockwise,
            };
            let verdict = wheels::judge(k, drive, ticks, moved);
            let text = wheels::describe(k, drive, &verdict);
            self.say(&format!("  wheel {k} ({name}): {text}"));
            if !verdict.is_ok() {
                problems.push(format!("wheel {k} ({name}): {text}"));
            }
            data.push(json!({
                "wheel": k,
                "name": name,
                "pwm": pwm,
                "ticks": ticks,
                "seen_clockwise": seen_clockwise,
                "result": verdict,
            }));
        }
        let turned: Vec<String> = data
            .iter()
            .filter_map(|d| {
                let k = d["wheel"].as_u64()? as usize;
                Some(format!("{:+}", d["ticks"][k].as_i64()?))
            })
            .collect();
        let seen = format!(
            "each motor at PWM {pwm:+} for {:.1} s: its own wheel's ticks {}",
            spin.as_secs_f64(),
            turned.join(", ")
        );
        self.devices.push(DeviceReport::checked(
            "wheels",
            seen,
            problems,
            json!({"pwm": pwm, "spin_s": spin.as_secs_f64(), "wheels": data}),
        ));
        Some(())
    }

    /// The magnet on for a moment, then off.
    pub(super) fn magnet(&mut self) -> Option<()> {
        self.say("magnet on for 0.5 s, then off: listen for the click");
        let before = self.session.mega.held_batches_written();
        self.session.hold(OpenLoopHold {
            solenoid_on: true,
            until_us: self.session.now_us() + MAGNET_ON.as_micros() as u64 + HOLD_MARGIN_US,
            ..OpenLoopHold::COAST
        });
        let held = self.session.pump(MAGNET_ON);
        self.session.hold(OpenLoopHold::COAST);
        if !held || !self.session.pump(Duration::from_millis(100)) {
            return None;
        }
        let after = self.session.mega.held_batches_written();
        let on_batches = after.1 - before.1;
        let off_batches = (after.0 - before.0) - on_batches;
        let mut problems = Vec::new();
        if on_batches == 0 || off_batches == 0 {
            problems.push(format!(
                "the Mega's port took {on_batches} batches with the magnet on and \
                 {off_batches} with it off: the link is not writable (see the mega line)"
            ));
        }
        let asked = if self.operator.interactive() {
            self.session.ask(
                &mut *self.operator,
                "did the magnet click on and then off? [y/N]",
            )?
        } else {
            Asked::NoAnswer
        };
        let confirmed = match asked {
            Asked::Yes => Some(true),
            Asked::No | Asked::Unknown => Some(false),
            Asked::NoAnswer => None,
        };
        if confirmed == Some(false) {
            problems.push(
                "the magnet did not respond: check its signal wire on pin 30 (PC7), its supply \
                 and ground"
                    .to_owned(),
            );
        }
        let seen = format!(
            "on for {:.1} s ({on_batches} batches with L = 1), then off{}",
            MAGNET_ON.as_secs_f64(),
            if confirmed.is_some() {
                ""
            } else {
                " (not observable on the wire: confirm by ear, without --yes)"
            }
        );
        self.devices.push(DeviceReport::checked(
            "magnet",
            seen,
            problems,
            json!({"on_batches": on_batches, "off_batches": off_batches, "confirmed": confirmed}),
        ));
        Some(())
    }
}
