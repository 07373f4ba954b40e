//! `ratf referee`: the mock server for practice, driven from its terminal.
//!
//! The operator starts the run with Enter or `start`, stops it with `stop`, prints the state
//! with `status`, reports part movements as the referees would (`place MAP 1 R`,
//! `take IWP 2`; machines then process as configured) and leaves with `quit`; `--start-after-s` starts it without a terminal (CI
//! has no stdin: the command reader then simply ends and only the timer can start the run).
//! Every request and reply is printed as it is handled.

use std::io::{self, Write};
use std::net::SocketAddr;
use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use super::server::MockServer;
use ratf_core::field::PartColor;
use ratf_core::referee::protocol::letters_to_string;
use ratf_sim::referee::{Area, MockReferee, MockSettings, Phase, ServerSlot};

/// How long one wait for a datagram lasts, so commands and timers are seen promptly.
const SERVE_SLICE: Duration = Duration::from_millis(20);

/// A line typed on the mock's terminal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConsoleCommand {
    /// Start the run (an empty line, i.e. Enter, or `start`).
    Start,
    /// Stop the run (`stop`).
    Stop,
    /// Print the phase, clock and slots (`status`).
    Status,
    /// Leave (`quit` or `exit`).
    Quit,
    /// A referee put a part in a slot: `place <IWP|OWP|MAP|MBP> <1-4> <B|G|R>`.
    Place(ServerSlot, PartColor),
    /// A referee (or the robot) took the part in a slot: `take <IWP|OWP|MAP|MBP> <1-4>`.
    Take(ServerSlot),
}

impl ConsoleCommand {
    /// Parse one typed line (trimmed, any case); `None` if unknown. Slots are numbered
    /// 1–4 as in the rules (machines: `1 2 / 3 4`, inputs 1 and 3).
    pub fn parse(line: &str) -> Option<Self> {
        let line = line.trim().to_ascii_uppercase();
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] | ["START"] => Some(Self::Start),
            ["STOP"] => Some(Self::Stop),
            ["STATUS"] => Some(Self::Status),
            ["QUIT"] | ["EXIT"] => Some(Self::Quit),
            ["PLACE", area, slot, color] => {
                let mut letters = color.chars();
                let color =
                    PartColor::from_letter(letters.next()?).filter(|_| letters.next().is_none())?;
                Some(Self::Place(parse_slot(area, slot)?, color))
            }
            ["TAKE", area, slot] => Some(Self::Take(parse_slot(area, slot)?)),
            _ => None,
        }
    }
}

/// A slot named by its request (`IWP`, `OWP`, `MAP`, `MBP`) and number 1–4.
fn parse_slot(area: &str, number: &str) -> Option<ServerSlot> {
    let area = match area {
        "IWP" => Area::Incoming,
        "OWP" => Area::Outgoing,
        "MAP" => Area::MachineA,
        "MBP" => Area::MachineB,
        _ => return None,
    };
    let index = number
        .parse::<usize>()
        .ok()?
        .checked_sub(1)
        .filter(|&i| i < 4)?;
    Some(ServerSlot { area, index })
}

/// How to run the practice server.
#[derive(Clone, Debug, PartialEq)]
pub struct PracticeOptions {
    /// Address to bind (port 0 = ephemeral).
    pub bind: SocketAddr,
    /// Parts, machine delay and machine rules.
    pub settings: MockSettings,
    /// Start by itself this long after launch, if set.
    pub start_after: Option<Duration>,
    /// Leave this long after launch, if set (for scripts and tests).
    pub exit_after: Option<Duration>,
}

/// One line describing the mock's state at `now_us`.
pub fn status_line(referee: &mut MockReferee, now_us: u64) -> String {
    let phase = match referee.phase() {
        Phase::Waiting => "waiting",
        Phase::Running { .. } => "running",
        Phase::Stopped { .. } => "stopped",
    };
    let [iw, ow, ma, mb] = Area::ALL.map(|a| letters_to_string(&referee.letters(a, now_us)));
    format!(
        "{phase}, T{} s left; IWP {iw} OWP {ow} MAP {ma} MBP {mb}",
        referee.time_left_s(now_us)
    )
}

/// The practice server, bound and ready to run.
#[derive(Debug)]
pub struct Practice {
    options: PracticeOptions,
    server: MockServer,
}

impl Practice {
    /// Bind the socket (fails if the port is taken).
    pub fn bind(options: PracticeOptions) -> io::Result<Self> {
        let server = MockServer::bind(options.bind, MockReferee::new(options.settings))?;
        Ok(Self { options, server })
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.server.local_addr()
    }

    /// Run until `quit` or `exit_after`, reading operator lines from `commands` (a closed
    /// channel means no terminal) and printing to `out`.
    pub fn run(self, commands: &Receiver<String>, out: &mut impl Write) -> io::Result<()> {
        run_practice(&self.options, self.server, commands, out)
    }
}

fn run_practice(
    options: &PracticeOptions,
    mut server: MockServer,
    commands: &Receiver<String>,
    out: &mut impl Write,
) -> io::Result<()> {
    let epoch = Instant::now();
    let now_us = || u64::try_from(epoch.elapsed().as_micros()).unwrap_or(u64::MAX);
    writeln!(
        out,
        "mock referee on {}: parts {}, machine delay {:.1} s; Enter or `start` starts; `stop`, `status`, `place MAP 1 R`, `take IWP 2`, `quit`",
        server.local_addr()?,
        letters_to_string(&options.settings.incoming),
        options.settings.machine_delay_us as f64 / 1e6,
    )?;
    let mut terminal_open = true;
    loop {
        let elapsed = epoch.elapsed();
        if options.exit_after.is_some_and(|t| elapsed >= t) {
            writeln!(out, "exiting after {:.1} s", elapsed.as_secs_f64())?;
            return Ok(());
        }
        let timer_start = options.start_after.is_some_and(|t| elapsed >= t);
        if timer_start && server.referee().phase() == Phase::Waiting {
            start(&mut server, now_us(), out)?;
        }
        while terminal_open {
            let line = match commands.try_recv() {
                Ok(line) => line,
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    terminal_open = false;
                    break;
                }
            };
            let now = now_us();
            match ConsoleCommand::parse(&line) {
                Some(ConsoleCommand::Start) => start(&mut server, now, out)?,
                Some(ConsoleCommand::Stop) => {
                    server.referee_mut().stop(now);
                    writeln!(out, "{} stopped", stamp(now))?;
                }
                Some(ConsoleCommand::Status) => {
                    let line = status_line(server.referee_mut(), now);
                    writeln!(out, "{} {line}", stamp(now))?;
                }
                Some(ConsoleCommand::Quit) => return Ok(()),
                Some(ConsoleCommand::Place(slot, color)) => {
                    match server.referee_mut().place(slot, color, now) {
                        Ok(()) => writeln!(out, "{} placed {color} in {slot}", stamp(now))?,
                        Err(e) => writeln!(out, "{} cannot place: {e}", stamp(now))?,
                    }
                }
                Some(ConsoleCommand::Take(slot)) => match server.referee_mut().take(slot, now) {
                    Ok(color) => writeln!(out, "{} took {color} from {slot}", stamp(now))?,
                    Err(e) => writeln!(out, "{} cannot take: {e}", stamp(now))?,
                },
                None => writeln!(
                    out,
                    "unknown command {line:?}: start, stop, status, quit, \
                     place <IWP|OWP|MAP|MBP> <1-4> <B|G|R>, take <IWP|OWP|MAP|MBP> <1-4>"
                )?,
            }
        }
        if let Some(x) = server.wait_and_serve(SERVE_SLICE, now_us)? {
            let reply = x.reply.as_deref().unwrap_or("(no reply: not a request)");
            writeln!(
                out,
                "{} {} {:?} -> {reply}",
                stamp(x.at_us),
                x.from,
                x.request
            )?;
        }
    }
}

fn start(server: &mut MockServer, now_us: u64, out: &mut impl Write) -> io::Result<()> {
    let was_waiting = server.referee().phase() == Phase::Waiting;
    server.referee_mut().start(now_us);
    if was_waiting {
        writeln!(out, "{} started: the 10-minute clock runs", stamp(now_us))
    } else {
        writeln!(out, "{} already started", stamp(now_us))
    }
}

fn stamp(now_us: u64) -> String {
    format!("[{:9.3} s]", now_us as f64 / 1e6)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::referee::client::RefereeClient;
    use ratf_core::referee::protocol::{Reply, Request};
    use ratf_core::referee::tracker::RetryPolicy;
    use std::sync::mpsc;

    #[test]
    fn console_lines() {
        assert_eq!(ConsoleCommand::parse("\n"), Some(ConsoleCommand::Start));
        assert_eq!(
            ConsoleCommand::parse(" START "),
            Some(ConsoleCommand::Start)
        );
        assert_eq!(ConsoleCommand::parse("stop"), Some(ConsoleCommand::Stop));
        assert_eq!(
            ConsoleCommand::parse("status"),
            Some(ConsoleCommand::Status)
        );
        assert_eq!(ConsoleCommand::parse("exit"), Some(ConsoleCommand::Quit));
        assert_eq!(ConsoleCommand::parse("go"), None);
        let a3 = ServerSlot {
            area: Area::MachineA,
            index: 2,
        };
        assert_eq!(
            ConsoleCommand::parse("place map 3 r"),
            Some(ConsoleCommand::Place(a3, PartColor::Red))
        );
        assert_eq!(
            ConsoleCommand::parse("TAKE MAP 3"),
            Some(ConsoleCommand::Take(a3))
        );
        for bad in [
            "place map 5 r",
            "place map 0 r",
            "place xyz 1 r",
            "place map 1 rg",
            "take iwp",
        ] {
            assert_eq!(ConsoleCommand::parse(bad), None, "{bad}");
        }
    }

    #[test]
    fn without_a_terminal_only_the_timer_starts_and_the_run_ends_on_time() {
        let options = PracticeOptions {
            bind: ([127, 0, 0, 1], 0).into(),
            settings: MockSettings::for_round(3, 7, None, 0).unwrap(),
            start_after: Some(Duration::from_millis(300)),
            exit_after: Some(Duration::from_millis(900)),
        };
        let practice = Practice::bind(options).unwrap();
        let addr = practice.local_addr().unwrap();
        let (tx, rx) = mpsc::channel::<String>();
        drop(tx); // no terminal
        let runner = std::thread::spawn(move || {
            let mut out = Vec::new();
            practice.run(&rx, &mut out).map(|()| out)
        });
        std::thread::sleep(Duration::from_millis(100));
        let policy = RetryPolicy {
            first_timeout_us: 100_000,
            max_tries: 3,
        };
        let mut client = RefereeClient::new(addr, 0, policy).unwrap();
        assert_eq!(
            client.request(Request::IncomingWarehouse).unwrap(),
            (Reply::Stop)
        );
        std::thread::sleep(Duration::from_millis(300));
        assert!(matches!(
            client.request(Request::IncomingWarehouse),
            Ok(Reply::Slots(_))
        ));
        let out = String::from_utf8(runner.join().unwrap().unwrap()).unwrap();
        assert!(out.contains("started"), "{out}");
        assert!(out.contains("\"IWP\" -> STOP"), "{out}");
        assert!(out.contains("exiting after"), "{out}");
    }

    #[test]
    fn terminal_commands_start_report_and_quit() {
        let options = PracticeOptions {
            bind: ([127, 0, 0, 1], 0).into(),
            settings: MockSettings::for_round(1, 0, None, 0).unwrap(),
            start_after: None,
            exit_after: Some(Duration::from_secs(5)),
        };
        let practice = Practice::bind(options).unwrap();
        let (tx, rx) = mpsc::channel::<String>();
        for line in [
            "status",
            "",
            "bogus",
            "take iwp 1",
            "place map 1 b",
            "status",
            "stop",
            "quit",
        ] {
            tx.send(line.to_owned()).unwrap();
        }
        let mut out = Vec::new();
        practice.run(&rx, &mut out).unwrap();
        let out = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = out.lines().skip(1).collect();
        assert_eq!(lines.len(), 7, "{out}");
        assert!(lines[0].ends_with("waiting, T600 s left; IWP BBBB OWP XXXX MAP XXXX MBP XXXX"));
        assert!(lines[1].ends_with("started: the 10-minute clock runs"));
        assert!(lines[2].starts_with("unknown command \"bogus\""));
        assert!(lines[3].ends_with("took blue from Incoming[0]"));
        assert!(lines[4].ends_with("placed blue in MachineA[0]"));
        assert!(lines[5].contains("running, T"));
        assert!(
            lines[5].ends_with("IWP XBBB OWP XXXX MAP BXXX MBP XXXX"),
            "{}",
            lines[5]
        );
        assert!(lines[6].ends_with("stopped"));
    }
}
