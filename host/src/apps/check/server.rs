//! Is the organisers' server reachable: `PING` from an unconnected UDP socket, so that a
//! reply from another address is seen (and named) instead of silently dropped by the OS
//! as `ratf run`'s connected socket does. [`probe`] is the I/O; [`judge`] is pure.

use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use ratf_core::config::RefereeConfig;
use ratf_core::referee::protocol::{Reply, Request, parse_reply};
use serde::Serialize;

use crate::referee::client::MAX_DATAGRAM_BYTES;

/// One datagram that came back.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Datagram {
    /// Who sent it.
    pub from: SocketAddr,
    /// Its text (lossy).
    pub text: String,
    /// After the first try was sent, ms.
    pub after_ms: f64,
    /// The try it answered (1-based: the last sent before it came).
    pub try_number: u32,
}

/// What the probe saw.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Probe {
    /// The configured server.
    pub server: SocketAddr,
    /// Tries sent.
    pub tries: u32,
    /// Each try's timeout, ms (`[referee] request_timeout_ms`).
    pub timeout_ms: u32,
    /// Every datagram received.
    pub datagrams: Vec<Datagram>,
}

/// Send `PING` to `[referee] server_address:server_port` from `local_port`, up to
/// `max_tries` times, each waiting `request_timeout_ms`, stopping at the first valid answer
/// from the server or when `quit()` says so. An error when the socket cannot be set up
/// (names the address and the key to set).
pub fn probe(config: &RefereeConfig, quit: impl Fn() -> bool) -> Result<Probe, String> {
    let key = "set [referee] server_address and server_port";
    let target = format!("{}:{}", config.server_address, config.server_port);
    let server = (config.server_address.as_str(), config.server_port)
        .to_socket_addrs()
        .map_err(|e| format!("{target}: cannot resolve it ({e}); {key}"))?
        .next()
        .ok_or_else(|| format!("{target}: no address; {key}"))?;
    let local: SocketAddr = if server.is_ipv4() {
        ([0, 0, 0, 0], config.local_port).into()
    } else {
        ([0u16; 8], config.local_port).into()
    };
    let socket = UdpSocket::bind(local).map_err(|e| {
        format!("binding {local}: {e}; another program holds the port? set [referee] local_port")
    })?;
    let timeout = Duration::from_millis(config.request_timeout_ms.into());
    let mut probe = Probe {
        server,
        tries: 0,
        timeout_ms: config.request_timeout_ms,
        datagrams: Vec::new(),
    };
    let started = Instant::now();
    let mut buf = [0u8; MAX_DATAGRAM_BYTES];
    while probe.tries < config.max_tries.max(1) && !quit() {
        probe.tries += 1;
        socket
            .send_to(Request::Ping.as_str().as_bytes(), server)
            .map_err(|e| format!("{target}: sending PING: {e}; is the network up? {key}"))?;
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() || quit() {
                break;
            }
            // Wake now and then to see `quit`.
            let wait = left.min(Duration::from_millis(50));
            if socket.set_read_timeout(Some(wait)).is_err() {
                break;
            }
            if let Ok((n, from)) = socket.recv_from(&mut buf) {
                probe.datagrams.push(Datagram {
                    from,
                    text: String::from_utf8_lossy(&buf[..n]).into_owned(),
                    after_ms: started.elapsed().as_secs_f64() * 1e3,
                    try_number: probe.tries,
                });
                if from == server && parse_reply(Request::Ping, &buf[..n]).is_ok() {
                    return Ok(probe);
                }
            }
        }
    }
    Ok(probe)
}

/// The verdict on a probe: `Ok(what was seen)` when the server answered, else what to do.
/// Datagrams from other addresses are named either way (`ratf run` ignores them).
pub fn judge(probe: &Probe) -> Result<String, String> {
    let others: Vec<String> = probe
        .datagrams
        .iter()
        .filter(|d| d.from != probe.server)
        .map(|d| format!("{:?} from {}", d.text, d.from))
        .collect();
    let others_note = if others.is_empty() {
        String::new()
    } else {
        format!(
            "; ignored (not from the configured address): {}",
            others.join(", ")
        )
    };
    let from_server: Vec<&Datagram> = probe
        .datagrams
        .iter()
        .filter(|d| d.from == probe.server)
        .collect();
    let good = from_server.iter().find_map(|d| {
        parse_reply(Request::Ping, d.text.as_bytes())
            .ok()
            .map(|r| (d, r))
    });
    if let Some((d, reply)) = good {
        let word = if reply == Reply::Stop { "STOP" } else { "PONG" };
        return Ok(format!(
            "{} answered {word} in {:.0} ms (try {} of {}, timeout {} ms){others_note}",
            probe.server, d.after_ms, d.try_number, probe.tries, probe.timeout_ms
        ));
    }
    if let Some(bad) = from_server.first() {
        return Err(format!(
            "{} answered PING with {:?}, not PONG: is that the organisers' server? check \
             [referee] server_port{others_note}",
            probe.server, bad.text
        ));
    }
    if !others.is_empty() {
        return Err(format!(
            "no reply from {} in {} tries of {} ms, but {}: if that is the server, set \
             [referee] server_address and server_port to it (replies are accepted only from \
             the configured address)",
            probe.server,
            probe.tries,
            probe.timeout_ms,
            others.join(", ")
        ));
    }
    Err(format!(
        "no reply from {} in {} tries of {} ms: is the server running and the Pi on its \
         network? set [referee] server_address and server_port (or raise \
         request_timeout_ms)",
        probe.server, probe.tries, probe.timeout_ms
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn probe_with(datagrams: &[(&str, &str)]) -> Probe {
        Probe {
            server: "10.0.0.5:39899".parse().unwrap(),
            tries: 2,
            timeout_ms: 400,
            datagrams: datagrams
                .iter()
                .map(|&(from, text)| Datagram {
                    from: from.parse().unwrap(),
                    text: text.to_owned(),
                    after_ms: 3.0,
                    try_number: 2,
                })
                .collect(),
        }
    }

    #[test]
    fn a_pong_from_the_server_is_ok_and_strangers_are_named() {
        let seen = judge(&probe_with(&[
            ("10.0.0.9:39899", "PONG"),
            ("10.0.0.5:39899", "PONG"),
        ]))
        .unwrap();
        assert!(
            seen.starts_with("10.0.0.5:39899 answered PONG in 3 ms (try 2 of 2"),
            "{seen}"
        );
        assert!(seen.contains("\"PONG\" from 10.0.0.9:39899"), "{seen}");
    }

    #[test]
    fn replies_only_from_elsewhere_say_which_address_answered() {
        let e = judge(&probe_with(&[("10.0.0.9:39899", "PONG")])).unwrap_err();
        assert!(e.contains("no reply from 10.0.0.5:39899"), "{e}");
        assert!(e.contains("but \"PONG\" from 10.0.0.9:39899"), "{e}");
        assert!(e.contains("[referee] server_address"), "{e}");
    }

    #[test]
    fn silence_and_garbage_are_problems() {
        let e = judge(&probe_with(&[])).unwrap_err();
        assert!(e.contains("in 2 tries of 400 ms"), "{e}");
        let e = judge(&probe_with(&[("10.0.0.5:39899", "HELLO")])).unwrap_err();
        assert!(e.contains("with \"HELLO\", not PONG"), "{e}");
    }

    #[test]
    fn a_real_server_on_loopback_answers_and_a_silent_one_times_out() {
        let server = UdpSocket::bind("127.0.0.1:0").unwrap();
        let port = server.local_addr().unwrap().port();
        let answering = std::thread::spawn(move || {
            let mut buf = [0u8; 16];
            let (n, from) = server.recv_from(&mut buf).unwrap();
            assert_eq!(&buf[..n], b"PING");
            server.send_to(b"PONG", from).unwrap();
        });
        let config = RefereeConfig {
            server_address: "127.0.0.1".to_owned(),
            server_port: port,
            request_timeout_ms: 2_000,
            ..RefereeConfig::default()
        };
        let seen = probe(&config, || false).unwrap();
        answering.join().unwrap();
        assert_eq!(seen.tries, 1);
        assert!(judge(&seen).is_ok(), "{seen:?}");
        let silent = UdpSocket::bind("127.0.0.1:0").unwrap();
        let config = RefereeConfig {
            server_port: silent.local_addr().unwrap().port(),
            request_timeout_ms: 20,
            max_tries: 2,
            ..config
        };
        let seen = probe(&config, || false).unwrap();
        assert_eq!(seen.tries, 2);
        assert!(seen.datagrams.is_empty());
    }
}
