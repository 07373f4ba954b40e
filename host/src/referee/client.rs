//! A client for the organisers' server: one outstanding request at a time, a per-try reply
//! timeout that doubles on every retry, validated replies, typed errors.
//!
//! The logic is [`RequestTracker`], a pure state machine with time passed in; the socket is
//! a thin wrapper, [`RefereeClient`], with a poll-style API for the 50 Hz loop
//! ([`RefereeClient::send_request`] / [`RefereeClient::poll`]) and a blocking one
//! ([`RefereeClient::request`]). There are no request ids (competition.md §3), so a reply is
//! matched to the one outstanding request; a reply that does not validate for it (garbage,
//! or a late answer to an earlier request) is remembered but does not end the request, which
//! may still get a good answer before its tries run out. Nothing here exits or panics
//! because the server is silent: the caller gets [`ClientError::Timeout`] and decides.

use std::io::ErrorKind;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use ratf_core::config::RefereeConfig;
use ratf_core::referee::protocol::{Reply, Request};
use ratf_core::referee::tracker::{ClientError, RequestTracker, RetryPolicy, Step};

/// Largest datagram the client reads, bytes (replies are at most a handful of letters).
const MAX_DATAGRAM_BYTES: usize = 512;

/// The client on a UDP socket connected to the server (datagrams from other addresses are
/// dropped by the OS).
#[derive(Debug)]
pub struct RefereeClient {
    socket: UdpSocket,
    server: SocketAddr,
    tracker: RequestTracker,
    epoch: Instant,
}

fn io_error(what: &str, e: std::io::Error) -> ClientError {
    ClientError::Io(format!("{what}: {e}"))
}

impl RefereeClient {
    /// A client for `[referee]`: resolves `server_address:server_port`, binds `local_port`.
    pub fn from_config(config: &RefereeConfig) -> Result<Self, ClientError> {
        let target = (config.server_address.as_str(), config.server_port);
        let server = target
            .to_socket_addrs()
            .map_err(|e| io_error(&format!("resolving {}", config.server_address), e))?
            .next()
            .ok_or_else(|| ClientError::Io(format!("{} has no address", config.server_address)))?;
        Self::new(server, config.local_port, RetryPolicy::from_config(config))
    }

    /// A client for `server`, bound to `local_port` (0 = any) on all interfaces.
    pub fn new(
        server: SocketAddr,
        local_port: u16,
        policy: RetryPolicy,
    ) -> Result<Self, ClientError> {
        let local: SocketAddr = if server.is_ipv4() {
            ([0, 0, 0, 0], local_port).into()
        } else {
            ([0u16; 8], local_port).into()
        };
        let socket =
            UdpSocket::bind(local).map_err(|e| io_error(&format!("binding {local}"), e))?;
        socket
            .connect(server)
            .map_err(|e| io_error(&format!("connecting to {server}"), e))?;
        socket
            .set_nonblocking(true)
            .map_err(|e| io_error("non-blocking mode", e))?;
        Ok(Self {
            socket,
            server,
            tracker: RequestTracker::new(policy),
            epoch: Instant::now(),
        })
    }

    /// The server's address.
    pub fn server(&self) -> SocketAddr {
        self.server
    }

    /// The request waiting for a reply, if any.
    pub fn outstanding(&self) -> Option<Request> {
        self.tracker.outstanding()
    }

    /// Send `request` at `now_us` (caller's clock) without waiting; collect the reply with
    /// [`Self::poll`] on the same clock.
    pub fn send_request(&mut self, request: Request, now_us: u64) -> Result<(), ClientError> {
        self.tracker.start(request, now_us)?;
        if let Err(e) = self.socket.send(request.as_str().as_bytes()) {
            // A failed first send is a lost datagram: the retry timer resends it.
            if e.kind() != ErrorKind::ConnectionRefused && e.kind() != ErrorKind::WouldBlock {
                self.tracker.cancel();
                return Err(io_error(&format!("sending {request}"), e));
            }
        }
        Ok(())
    }

    /// Read what has arrived and advance the retries at `now_us`. `Some` when the
    /// outstanding request ends (its reply, or why it failed); `None` while waiting or idle.
    pub fn poll(&mut self, now_us: u64) -> Option<Result<Reply, ClientError>> {
        let mut buf = [0u8; MAX_DATAGRAM_BYTES];
        loop {
            match self.socket.recv(&mut buf) {
                Ok(n) => {
                    if let Some(reply) = self.tracker.on_datagram(&buf[..n]) {
                        return Some(Ok(reply));
                    }
                }
                // ConnectionRefused: an ICMP "port unreachable" from an earlier send, i.e.
                // no server there yet: the same as silence.
                Err(e) if e.kind() == ErrorKind::ConnectionRefused => {}
                Err(_) => break,
            }
        }
        match self.tracker.step(now_us) {
            Step::Send(request) => {
                // Errors here are treated as a lost datagram; the next timeout retries.
                let _ = self.socket.send(request.as_str().as_bytes());
                None
            }
            Step::Done(result) => Some(result),
            Step::Idle | Step::Waiting { .. } => None,
        }
    }

    /// Send `request` and wait for its reply or failure (at most the sum of every try's
    /// timeout), on the wall clock. Fails with [`ClientError::Busy`] if a poll-style
    /// request is outstanding.
    pub fn request(&mut self, request: Request) -> Result<Reply, ClientError> {
        self.send_request(request, self.now_us())?;
        loop {
            if let Some(result) = self.poll(self.now_us()) {
                return result;
            }
            if let Some(deadline_us) = self.tracker.deadline_us() {
                let wait_us = deadline_us.saturating_sub(self.now_us()).max(1_000);
                self.wait_readable(Duration::from_micros(wait_us));
            }
        }
    }

    /// Block until a datagram may be readable or `timeout` passes (peeks, reads nothing).
    fn wait_readable(&self, timeout: Duration) {
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
        assert_eq!(
            e,
            ClientError::Timeout {
                request: Request::IncomingWarehouse,
                tries: 3
            }
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
    fn no_listener_at_all_is_a_timeout_not_an_error() {
        let addr = silent_server().local_addr().unwrap(); // socket dropped: port closed
        let policy = RetryPolicy {
            first_timeout_us: 10_000,
            max_tries: 2,
        };
        let mut client = RefereeClient::new(addr, 0, policy).unwrap();
        assert!(matches!(
            client.request(Request::Ping),
            Err(ClientError::Timeout { tries: 2, .. })
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
        assert!(matches!(e, ClientError::BadReply { tries: 2, .. }), "{e}");
        assert!(
            e.to_string().contains("BGYR") && e.to_string().contains("MAP"),
            "{e}"
        );
    }
}
