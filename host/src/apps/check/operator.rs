//! The person at the robot: what the check tells and asks. Answers are polled, never
//! waited for with the devices unattended, so the check keeps reading telemetry (and
//! noticing Ctrl-C) while a question is open.

use std::io::{BufRead, Write};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::Duration;

/// Where an answer stands.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Answer {
    /// A line typed (without its newline).
    Line(String),
    /// Nothing yet.
    Pending,
    /// Nobody will answer (standard input closed).
    Closed,
}

/// Someone (or no one) at the robot.
pub trait Operator {
    /// True if someone answers questions (turns wheels by hand, watches them); false with
    /// `--yes`, when every question that asks for permission is taken as yes and those
    /// that ask what was seen are skipped.
    fn interactive(&self) -> bool;
    /// Tell a line.
    fn say(&mut self, line: &str);
    /// Ask: print `question` (no newline), then poll [`Operator::poll`].
    fn ask(&mut self, question: &str);
    /// The answer to the last question, waiting at most `wait`.
    fn poll(&mut self, wait: Duration) -> Answer;
}

/// `--yes`: nobody answers; lines go to standard output.
#[derive(Debug, Default)]
pub struct Unattended;

impl Operator for Unattended {
    fn interactive(&self) -> bool {
        false
    }

    fn say(&mut self, line: &str) {
        print_line(line);
    }

    fn ask(&mut self, question: &str) {
        print_line(question);
    }

    fn poll(&mut self, _wait: Duration) -> Answer {
        Answer::Closed
    }
}

/// A person on the terminal: questions on standard output, answers read from standard
/// input by a thread (started at the first question).
#[derive(Debug, Default)]
pub struct Terminal {
    lines: Option<Receiver<String>>,
}

impl Operator for Terminal {
    fn interactive(&self) -> bool {
        true
    }

    fn say(&mut self, line: &str) {
        print_line(line);
    }

    fn ask(&mut self, question: &str) {
        let mut out = std::io::stdout().lock();
        let _ = write!(out, "{question} ");
        let _ = out.flush();
        if self.lines.is_none() {
            let (tx, rx) = mpsc::channel();
            let spawned = std::thread::Builder::new()
                .name("stdin".to_owned())
                .spawn(move || {
                    for line in std::io::stdin().lock().lines() {
                        let Ok(line) = line else { break };
                        if tx.send(line).is_err() {
                            break;
                        }
                    }
                });
            // Without the thread nobody can answer: every question then reads as closed.
            if spawned.is_ok() {
                self.lines = Some(rx);
            }
        }
    }

    fn poll(&mut self, wait: Duration) -> Answer {
        let Some(lines) = &self.lines else {
            return Answer::Closed;
        };
        match lines.recv_timeout(wait) {
            Ok(line) => Answer::Line(line.trim().to_owned()),
            Err(RecvTimeoutError::Timeout) => Answer::Pending,
            Err(RecvTimeoutError::Disconnected) => Answer::Closed,
        }
    }
}

/// Print a line; a closed standard output is not the check's failure.
fn print_line(line: &str) {
    let _ = writeln!(std::io::stdout().lock(), "{line}");
}

/// A yes/no answer: `y`/`yes` is yes, `n`/`no`/empty is no, anything else unknown.
pub fn yes_no(line: &str) -> Option<bool> {
    match line.trim().to_ascii_lowercase().as_str() {
        "y" | "yes" => Some(true),
        "" | "n" | "no" => Some(false),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_read_as_yes_no_or_unknown() {
        assert_eq!(yes_no("Y"), Some(true));
        assert_eq!(yes_no(" yes "), Some(true));
        assert_eq!(yes_no(""), Some(false));
        assert_eq!(yes_no("no"), Some(false));
        assert_eq!(yes_no("?"), None);
    }

    #[test]
    fn nobody_answers_when_unattended() {
        let mut op = Unattended;
        assert!(!op.interactive());
        assert_eq!(op.poll(Duration::ZERO), Answer::Closed);
    }
}
