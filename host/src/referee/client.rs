//! The organisers' server over UDP: [`RefereeLink`], the socket as one of the robot's
//! devices, and [`RefereeClient`], a blocking client for tools and tests.
//!
//! The request logic (one outstanding request, retries with backoff, validated replies,
//! late answers discarded) is the core's pure [`RequestTracker`]; here is only the socket.
//! Nothing here exits or panics because the server is silent: the caller gets
//! [`ClientError::Timeout`] and decides.

use std::io::ErrorKind;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use ratf_core::config::RefereeConfig;
use ratf_core::referee::protocol::{Reply, Request};
use ratf_core::referee::tracker::{ClientError, RequestTracker, RetryPolicy, Step};

/// Largest datagram read, bytes (replies are at most a handful of letters; anything longer
/// is garbage and is cut, then rejected by the parser).
pub const MAX_DATAGRAM_BYTES: usize = 512;

/// Most datagrams one [`RefereeLink::receive`] hands over. The server answers one request at
/// a time with one datagram, so a handful is the most a robot ever sees between two calls;
/// a server (or anything on the venue's network sending from its address) flooding the
/// link leaves the rest in the operating system's socket buffer for the next call instead
/// of keeping this one looping and its list growing.
pub const MAX_DATAGRAMS_PER_RECEIVE: usize = 64;

/// The socket to the server could not be set up or used.
#[derive(Debug, thiserror::Error)]
#[error("referee link: {what}: {source}")]
pub struct LinkError {
    /// What was being done (names the address).
    pub what: String,
    /// The operating system's error.
    #[source]
    pub source: std::io::Error,
}

impl LinkError {
    fn new(what: impl Into<String>, source: std::io::Error) -> Self {
        Self {
            what: what.into(),
            source,
        }
    }
}

/// The organisers' server as a device: a non-blocking UDP socket connected to the server,
/// so the OS drops datagrams from any other address. Sends requests, hands over what
/// arrived; the request logic is the core's ([`RequestTracker`]).
#[derive(Debug)]
pub struct RefereeLink {
    socket: UdpSocket,
    server: SocketAddr,
}

impl RefereeLink {
    /// Resolve `[referee] server_address:server_port` and connect from `local_port`.
    pub fn from_config(config: &RefereeConfig) -> Result<Self, LinkError> {
        let target = (config.server_address.as_str(), config.server_port);
        let resolving = || format!("resolving {}", config.server_address);
        let server = target
            .to_socket_addrs()
            .map_err(|e| LinkError::new(resolving(), e))?
            .next()
            .ok_or_else(|| {
                LinkError::new(
                    resolving(),
                    std::io::Error::new(ErrorKind::NotFound, "no address"),
                )
            })?;
        Self::connect(server, config.local_port)
    }

    /// A link to `server`, bound to `local_port` (0 = any) on all interfaces.
    pub fn connect(server: SocketAddr, local_port: u16) -> Result<Self, LinkError> {
        let local: SocketAddr = if server.is_ipv4() {
            ([0, 0, 0, 0], local_port).into()
        } else {
            ([0u16; 8], local_port).into()
        };
        let socket =
            UdpSocket::bind(local).map_err(|e| LinkError::new(format!("binding {local}"), e))?;
        socket
            .connect(server)
            .map_err(|e| LinkError::new(format!("connecting to {server}"), e))?;
        socket
            .set_nonblocking(true)
            .map_err(|e| LinkError::new("non-blocking mode", e))?;
        Ok(Self { socket, server })
    }

    /// The server's address.
    pub fn server(&self) -> SocketAddr {
        self.server
    }

    /// Send `request`'s text. No server listening (an ICMP "port unreachable") and a full
    /// send buffer count as a lost datagram, which the tracker's retries cover.
    pub fn send(&self, request: Request) -> Result<(), LinkError> {
        match self.socket.send(request.as_str().as_bytes()) {
            Ok(_) => Ok(()),
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::ConnectionRefused | ErrorKind::WouldBlock
                ) =>
            {
                Ok(())
            }
            Err(e) => Err(LinkError::new(format!("sending {request}"), e)),
        }
    }

    /// The datagrams that have arrived, in order, at most [`MAX_DATAGRAMS_PER_RECEIVE`] (the
    /// rest wait for the next call), each cut at [`MAX_DATAGRAM_BYTES`].
    pub fn receive(&self) -> Vec<Vec<u8>> {
        let mut buf = [0u8; MAX_DATAGRAM_BYTES];
        let mut datagrams = Vec::new();
        while datagrams.len() < MAX_DATAGRAMS_PER_RECEIVE {
            match self.socket.recv(&mut buf) {
                Ok(n) => datagrams.push(buf[..n].to_vec()),
                // An ICMP "port unreachable" from an earlier send: no server there yet, the
                // same as silence.
                Err(e) if e.kind() == ErrorKind::ConnectionRefused => {}
                Err(_) => break,
            }
        }
        datagrams
    }

    /// Block until a datagram may be readable or `timeout` passes (peeks, reads nothing).
    pub fn wait_readable(&self, timeout: Duration) {
        let mut probe = [0u8; 1];
        let blocking = self.socket.set_nonblocking(false).is_ok()
            && self.socket.set_read_timeout(Some(timeout)).is_ok();
        if blocking {
            let _ = self.socket.peek(&mut probe);
        } else {
            std::thread::sleep(timeout.min(Duration::from_millis(5)));
        }
        let _ = self.socket.set_nonblocking(true);
    }
}

/// Why a blocking request produced no reply.
#[derive(Debug, thiserror::Error)]
pub enum RequestError {
    /// The exchange failed (timeout, bad replies, busy).
    #[error(transparent)]
    Exchange(#[from] ClientError),
    /// The socket failed.
    #[error(transparent)]
    Link(#[from] LinkError),
}

/// A blocking client for tools and tests (`ratf referee`, the practice server's checks):
/// the core's [`RequestTracker`] on a [`RefereeLink`], on the wall clock. The robot's own
/// loop does not use it: its core tracks requests and the link is one of its devices.
#[derive(Debug)]
pub struct RefereeClient {
    link: RefereeLink,
    tracker: RequestTracker,
    epoch: Instant,
}

impl RefereeClient {
    /// A client for `[referee]`.
    pub fn from_config(config: &RefereeConfig) -> Result<Self, LinkError> {
        Ok(Self {
            link: RefereeLink::from_config(config)?,
            tracker: RequestTracker::new(RetryPolicy::from_config(config)),
            epoch: Instant::now(),
        })
    }

    /// A client for `server`, bound to `local_port` (0 = any) on all interfaces.
    pub fn new(
        server: SocketAddr,
        local_port: u16,
        policy: RetryPolicy,
    ) -> Result<Self, LinkError> {
        Ok(Self {
            link: RefereeLink::connect(server, local_port)?,
            tracker: RequestTracker::new(policy),
            epoch: Instant::now(),
        })
    }

    /// The server's address.
    pub fn server(&self) -> SocketAddr {
        self.link.server()
    }

    /// Send `request` and wait for its reply or failure (at most the sum of every try's
    /// timeout, after any late answers to the previous request), on the wall clock.
    pub fn request(&mut self, request: Request) -> Result<Reply, RequestError> {
        while !self.tracker.ready(self.now_us()) {
            for datagram in self.link.receive() {
                let now_us = self.now_us();
                self.tracker.on_datagram(now_us, &datagram);
            }
            self.link.wait_readable(Duration::from_millis(5));
        }
        self.tracker.start(request, self.now_us())?;
        self.link.send(request)?;
        loop {
            for datagram in self.link.receive() {
                let now_us = self.now_us();
                if let Some(reply) = self.tracker.on_datagram(now_us, &datagram) {
                    return Ok(reply);
                }
            }
            match self.tracker.step(self.now_us()) {
                Step::Send(request) => self.link.send(request)?,
                Step::Done(result) => return Ok(result?),
                Step::Idle | Step::Waiting { .. } => {}
            }
            if let Some(deadline_us) = self.tracker.deadline_us() {
                let wait_us = deadline_us.saturating_sub(self.now_us()).max(1_000);
                self.link.wait_readable(Duration::from_micros(wait_us));
            }
        }
    }

    fn now_us(&self) -> u64 {
        u64::try_from(self.epoch.elapsed().as_micros()).unwrap_or(u64::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn silent_server() -> UdpSocket {
        UdpSocket::bind("127.0.0.1:0").unwrap()
    }

    #[test]
    fn a_silent_server_gives_a_timeout_after_every_try_over_udp() {
        let server = silent_server();
        let policy = RetryPolicy {
            first_timeout_us: 20_000,
            max_tries: 3,
        };
        let mut client = RefereeClient::new(server.local_addr().unwrap(), 0, policy).unwrap();
        let started = Instant::now();
        let e = client.request(Request::IncomingWarehouse).unwrap_err();
        let waited = started.elapsed();
        assert!(
            matches!(
                e,
                RequestError::Exchange(ClientError::Timeout {
                    request: Request::IncomingWarehouse,
                    tries: 3
                })
            ),
            "{e}"
        );
        // The three tries each reached the server.
        server
            .set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
        let mut buf = [0u8; 16];
        for _ in 0..3 {
            let (n, _) = server.recv_from(&mut buf).unwrap();
            assert_eq!(&buf[..n], b"IWP");
        }
        // 20 + 40 + 80 ms of timeouts at least.
        assert!(waited >= Duration::from_millis(140), "{waited:?}");
    }

    #[test]
    fn replies_from_anyone_but_the_configured_server_are_never_read() {
        let server = silent_server();
        let stranger = silent_server();
        let link = RefereeLink::connect(server.local_addr().unwrap(), 0).unwrap();
        let to = link.socket.local_addr().unwrap();
        let to = SocketAddr::from(([127, 0, 0, 1], to.port()));
        // A stranger on the same host answers first, then the server.
        stranger.send_to(b"BGRX", to).unwrap();
        stranger.send_to(b"STOP", to).unwrap();
        server.send_to(b"RRRR", to).unwrap();
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut received = Vec::new();
        while received.is_empty() && Instant::now() < deadline {
            link.wait_readable(Duration::from_millis(10));
            received.extend(link.receive());
        }
        assert_eq!(received, vec![b"RRRR".to_vec()]);
        // The stranger's datagrams never show up later either: the socket is connected.
        stranger.send_to(b"GGGG", to).unwrap();
        server.send_to(b"PONG", to).unwrap();
        let mut later = Vec::new();
        while later.is_empty() && Instant::now() < deadline {
            link.wait_readable(Duration::from_millis(10));
            later.extend(link.receive());
        }
        assert_eq!(later, vec![b"PONG".to_vec()]);
    }

    #[test]
    fn a_flooding_server_is_read_at_most_64_datagrams_a_call_and_nothing_is_lost() {
        let server = silent_server();
        let link = RefereeLink::connect(server.local_addr().unwrap(), 0).unwrap();
        let to = link.socket.local_addr().unwrap();
        for k in 0..100u8 {
            server.send_to(&[b'A' + k % 26], to).unwrap();
        }
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut sizes = Vec::new();
        let mut received = Vec::new();
        while received.len() < 100 && Instant::now() < deadline {
            let datagrams = link.receive();
            if datagrams.is_empty() {
                link.wait_readable(Duration::from_millis(10));
                continue;
            }
            sizes.push(datagrams.len());
            received.extend(datagrams);
        }
        assert_eq!(received.len(), 100, "{sizes:?}");
        assert!(
            sizes.iter().all(|&n| n <= MAX_DATAGRAMS_PER_RECEIVE),
            "{sizes:?}"
        );
        // In order, none lost: the rest of a flood waits in the socket's buffer.
        let expected: Vec<Vec<u8>> = (0..100u8).map(|k| vec![b'A' + k % 26]).collect();
        assert_eq!(received, expected);
    }

    #[test]
    fn no_listener_at_all_is_a_timeout_not_an_error() {
        let addr = silent_server().local_addr().unwrap(); // socket dropped: port closed
        let policy = RetryPolicy {
            first_timeout_us: 10_000,
            max_tries: 2,
        };
        let mut client = RefereeClient::new(addr, 0, policy).unwrap();
        assert!(matches!(
            client.request(Request::Ping),
            Err(RequestError::Exchange(ClientError::Timeout {
                tries: 2,
                ..
            }))
        ));
    }

    #[test]
    fn garbage_from_the_server_is_rejected_with_the_text_over_udp() {
        let server = silent_server();
        let addr = server.local_addr().unwrap();
        let echo = std::thread::spawn(move || {
            server
                .set_read_timeout(Some(Duration::from_secs(2)))
                .unwrap();
            let mut buf = [0u8; 16];
            for _ in 0..2 {
                let (_, from) = server.recv_from(&mut buf).unwrap();
                server.send_to(b"BGYR", from).unwrap();
            }
        });
        let policy = RetryPolicy {
            first_timeout_us: 30_000,
            max_tries: 2,
        };
        let mut client = RefereeClient::new(addr, 0, policy).unwrap();
        let e = client.request(Request::MachineA).unwrap_err();
        echo.join().unwrap();
        assert!(
            matches!(
                e,
                RequestError::Exchange(ClientError::BadReply { tries: 2, .. })
            ),
            "{e}"
        );
        assert!(
            e.to_string().contains("BGYR") && e.to_string().contains("MAP"),
            "{e}"
        );
    }
}
