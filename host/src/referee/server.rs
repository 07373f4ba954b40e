//! The mock organisers' server on a UDP socket: every datagram gets its reply sent back to
//! the datagram's source address and port, whoever sent it (competition.md §3).
//!
//! [`MockServer`] is single-threaded: the caller drives it with its own clock, either
//! draining what has arrived ([`MockServer::poll`], for a simulation loop) or blocking for
//! the next datagram ([`MockServer::wait_and_serve`], for `ratf referee`).
//! [`BackgroundServer`] runs one on a thread with the wall clock, for tests and practice.

use std::io::{self, ErrorKind};
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ratf_sim::referee::MockReferee;

/// Largest request datagram read, bytes (requests are 3–4 letters).
const MAX_DATAGRAM_BYTES: usize = 512;

/// Most datagrams one [`MockServer::poll`] answers: a robot sends one request at a time, so
/// a handful is the most a simulation tick sees; a client flooding the server leaves the rest
/// in the operating system's socket buffer for the next poll instead of keeping this one
/// looping and its list growing.
pub const MAX_DATAGRAMS_PER_POLL: usize = 64;

/// One request the server received and what it answered.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Exchange {
    /// The sender (the reply went back there).
    pub from: SocketAddr,
    /// The received text, lossily decoded and trimmed.
    pub request: String,
    /// The reply sent, or `None` if the datagram was not a request (no reply).
    pub reply: Option<String>,
    /// When it was handled, µs (the caller's clock).
    pub at_us: u64,
}

/// The mock referee on a socket.
#[derive(Debug)]
pub struct MockServer {
    socket: UdpSocket,
    referee: MockReferee,
}

impl MockServer {
    /// Bind `addr` (port 0 = an ephemeral port) and serve `referee`.
    pub fn bind(addr: SocketAddr, referee: MockReferee) -> io::Result<Self> {
        let socket = UdpSocket::bind(addr)?;
        Ok(Self { socket, referee })
    }

    /// The bound address (with the actual port).
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// The referee state.
    pub fn referee(&self) -> &MockReferee {
        &self.referee
    }

    /// The referee state, for start/stop and part notifications.
    pub fn referee_mut(&mut self) -> &mut MockReferee {
        &mut self.referee
    }

    /// Answer the datagrams already received, at most [`MAX_DATAGRAMS_PER_POLL`] (the rest
    /// wait for the next poll), at `now_us`, without blocking.
    pub fn poll(&mut self, now_us: u64) -> io::Result<Vec<Exchange>> {
        self.socket.set_nonblocking(true)?;
        let mut handled = Vec::new();
        while handled.len() < MAX_DATAGRAMS_PER_POLL {
            let Some(exchange) = self.receive_one(|| now_us)? else {
                break;
            };
            handled.push(exchange);
        }
        Ok(handled)
    }

    /// Wait up to `wait` for one datagram and answer it at the time `now_us()` returns when
    /// it arrives. `None` if nothing came.
    pub fn wait_and_serve(
        &mut self,
        wait: Duration,
        now_us: impl FnOnce() -> u64,
    ) -> io::Result<Option<Exchange>> {
        self.socket.set_nonblocking(false)?;
        self.socket
            .set_read_timeout(Some(wait.max(Duration::from_micros(1))))?;
        self.receive_one(now_us)
    }

    fn receive_one(&mut self, now_us: impl FnOnce() -> u64) -> io::Result<Option<Exchange>> {
        let mut buf = [0u8; MAX_DATAGRAM_BYTES];
        let (n, from) = match self.socket.recv_from(&mut buf) {
            Ok(got) => got,
            Err(e) if is_no_data(&e) => return Ok(None),
            Err(e) => return Err(e),
        };
        let at_us = now_us();
        let reply = self.referee.handle_datagram(&buf[..n], at_us);
        if let Some(text) = &reply {
            // A client that went away is not the server's problem: report, don't fail.
            if let Err(e) = self.socket.send_to(text.as_bytes(), from)
                && !is_no_data(&e)
            {
                return Err(e);
            }
        }
        Ok(Some(Exchange {
            from,
            request: String::from_utf8_lossy(&buf[..n]).trim().to_owned(),
            reply,
            at_us,
        }))
    }
}

/// Errors that only mean "nothing to read now" (Linux reports a UDP read timeout as
/// `WouldBlock`, other systems as `TimedOut`; `ConnectionRefused` is an ICMP echo of an
/// earlier send to a client that has gone).
fn is_no_data(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::ConnectionRefused
    )
}

/// A [`MockServer`] answering on its own thread with the wall clock (µs since
/// [`BackgroundServer::spawn`]). Stopped and joined on drop.
#[derive(Debug)]
pub struct BackgroundServer {
    server: Arc<Mutex<MockServer>>,
    addr: SocketAddr,
    epoch: Instant,
    quit: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl BackgroundServer {
    /// Poll period of the thread: replies come within about this long, s. 1 ms.
    const PERIOD: Duration = Duration::from_millis(1);

    /// Run `server` on a thread.
    pub fn spawn(server: MockServer) -> io::Result<Self> {
        let addr = server.local_addr()?;
        let server = Arc::new(Mutex::new(server));
        let quit = Arc::new(AtomicBool::new(false));
        let epoch = Instant::now();
        let thread = {
            let (server, quit) = (Arc::clone(&server), Arc::clone(&quit));
            std::thread::spawn(move || {
                while !quit.load(Ordering::Relaxed) {
                    let now_us = micros_since(epoch);
                    let result = server
                        .lock()
                        .unwrap_or_else(PoisonError::into_inner)
                        .poll(now_us);
                    if result.is_err() {
                        break;
                    }
                    std::thread::sleep(Self::PERIOD);
                }
            })
        };
        Ok(Self {
            server,
            addr,
            epoch,
            quit,
            thread: Some(thread),
        })
    }

    /// The server's address.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The server's clock, µs since it was spawned.
    pub fn now_us(&self) -> u64 {
        micros_since(self.epoch)
    }

    /// Run `f` on the referee state at the server's current time (start, stop, notify).
    pub fn with_referee<T>(&self, f: impl FnOnce(&mut MockReferee, u64) -> T) -> T {
        let now_us = self.now_us();
        let mut server = self.server.lock().unwrap_or_else(PoisonError::into_inner);
        f(server.referee_mut(), now_us)
    }
}

impl Drop for BackgroundServer {
    fn drop(&mut self) {
        self.quit.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

fn micros_since(epoch: Instant) -> u64 {
    u64::try_from(epoch.elapsed().as_micros()).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::referee::client::RefereeClient;
    use ratf_core::referee::protocol::{Reply, Request, parse_letters};
    use ratf_core::referee::tracker::RetryPolicy;
    use ratf_sim::referee::{Area, MockSettings, ServerSlot};

    const POLICY: RetryPolicy = RetryPolicy {
        first_timeout_us: 200_000,
        max_tries: 3,
    };

    fn loopback() -> SocketAddr {
        ([127, 0, 0, 1], 0).into()
    }

    fn background(parts: &str, delay_us: u64) -> BackgroundServer {
        let settings = MockSettings {
            incoming: parse_letters(parts).unwrap(),
            machine_delay_us: delay_us,
            green_to_blue_at_a: false,
        };
        let server = MockServer::bind(loopback(), MockReferee::new(settings)).unwrap();
        BackgroundServer::spawn(server).unwrap()
    }

    fn letters(text: &str) -> Reply {
        Reply::Slots(parse_letters(text).unwrap())
    }

    #[test]
    fn every_request_over_loopback_before_and_after_the_start() {
        let server = background("BGGR", 0);
        let mut client = RefereeClient::new(server.addr(), 0, POLICY).unwrap();
        assert_eq!(client.request(Request::Ping).unwrap(), (Reply::Pong));
        for r in Request::ALL.into_iter().filter(|&r| r != Request::Ping) {
            assert_eq!(
                client.request(r).unwrap(),
                (Reply::Stop),
                "{r} before the start"
            );
        }
        server.with_referee(|m, now| m.start(now));
        assert_eq!(
            client.request(Request::IncomingWarehouse).unwrap(),
            (letters("BGGR"))
        );
        assert_eq!(
            client.request(Request::OutgoingWarehouse).unwrap(),
            (letters("XXXX"))
        );
        assert_eq!(
            client.request(Request::MachineA).unwrap(),
            (letters("XXXX"))
        );
        assert_eq!(
            client.request(Request::MachineB).unwrap(),
            (letters("XXXX"))
        );
        let Ok(Reply::TimeLeft { seconds }) = client.request(Request::TimeLeft) else {
            panic!("CTL must answer T<seconds>");
        };
        assert!((598..=600).contains(&seconds), "{seconds}");
        assert_eq!(client.request(Request::Ping).unwrap(), (Reply::Pong));
    }

    #[test]
    fn machine_processing_after_the_delay_seen_over_udp() {
        let server = background("RGGB", 150_000);
        let mut client = RefereeClient::new(server.addr(), 0, POLICY).unwrap();
        server
            .with_referee(|m, now| {
                m.start(now);
                let red = m.take(
                    ServerSlot {
                        area: Area::Incoming,
                        index: 0,
                    },
                    now,
                )?;
                m.place(
                    ServerSlot {
                        area: Area::MachineA,
                        index: 2,
                    },
                    red,
                    now,
                )
            })
            .unwrap();
        assert_eq!(
            client.request(Request::IncomingWarehouse).unwrap(),
            (letters("XGGB"))
        );
        assert_eq!(
            client.request(Request::MachineA).unwrap(),
            (letters("XXRX"))
        );
        std::thread::sleep(Duration::from_millis(200));
        assert_eq!(
            client.request(Request::MachineA).unwrap(),
            (letters("XXXG"))
        );
    }

    #[test]
    fn replies_go_to_any_client_address() {
        let server = background("BBBB", 0);
        let mut a = RefereeClient::new(server.addr(), 0, POLICY).unwrap();
        let mut b = RefereeClient::new(server.addr(), 0, POLICY).unwrap();
        assert_eq!(a.request(Request::Ping).unwrap(), (Reply::Pong));
        assert_eq!(b.request(Request::Ping).unwrap(), (Reply::Pong));
    }

    #[test]
    fn single_threaded_poll_with_the_callers_clock() {
        let settings = MockSettings::for_round(1, 0, None, 0).unwrap();
        let mut server = MockServer::bind(loopback(), MockReferee::new(settings)).unwrap();
        let link =
            crate::referee::client::RefereeLink::connect(server.local_addr().unwrap(), 0).unwrap();
        server.referee_mut().start(1_000_000);
        link.send(Request::TimeLeft).unwrap();
        let mut handled = Vec::new();
        let mut datagrams = Vec::new();
        for _ in 0..200 {
            handled.extend(server.poll(61_000_000).unwrap());
            datagrams.extend(link.receive());
            if !datagrams.is_empty() {
                break;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(datagrams, [b"T540".to_vec()]);
        assert_eq!(handled.len(), 1);
        assert_eq!(handled[0].request, "CTL");
        assert_eq!(handled[0].reply.as_deref(), Some("T540"));
    }

    #[test]
    fn a_flooding_client_is_answered_at_most_64_datagrams_a_poll_and_nothing_is_lost() {
        let settings = MockSettings::for_round(1, 0, None, 0).unwrap();
        let mut server = MockServer::bind(loopback(), MockReferee::new(settings)).unwrap();
        let client = UdpSocket::bind(loopback()).unwrap();
        for _ in 0..100 {
            client
                .send_to(b"PING", server.local_addr().unwrap())
                .unwrap();
        }
        let deadline = Instant::now() + Duration::from_secs(5);
        let (mut sizes, mut answered) = (Vec::new(), 0);
        while answered < 100 && Instant::now() < deadline {
            let handled = server.poll(0).unwrap();
            assert!(handled.iter().all(|e| e.reply.as_deref() == Some("PONG")));
            sizes.push(handled.len());
            answered += handled.len();
            if handled.is_empty() {
                // Nothing yet: block for the next datagram (answering it) instead of spinning.
                let served = server
                    .wait_and_serve(Duration::from_millis(10), || 0)
                    .unwrap();
                answered += usize::from(served.is_some());
            }
        }
        // Every one answered exactly once, and no poll answered more than its bound.
        let mut replies = 0;
        let mut buf = [0u8; 16];
        client
            .set_read_timeout(Some(Duration::from_millis(500)))
            .unwrap();
        while replies < 100 && client.recv_from(&mut buf).is_ok() {
            replies += 1;
        }
        assert_eq!(replies, 100, "{sizes:?}");
        assert!(
            sizes.iter().all(|&n| n <= MAX_DATAGRAMS_PER_POLL),
            "{sizes:?}"
        );
    }

    #[test]
    fn unknown_requests_get_no_reply_so_the_client_times_out() {
        let server = background("BBBB", 0);
        let probe = UdpSocket::bind(loopback()).unwrap();
        probe
            .set_read_timeout(Some(Duration::from_millis(100)))
            .unwrap();
        probe.send_to(b"HELLO", server.addr()).unwrap();
        let mut buf = [0u8; 16];
        assert!(probe.recv_from(&mut buf).is_err(), "no reply expected");
        let policy = RetryPolicy {
            first_timeout_us: 50_000,
            max_tries: 1,
        };
        let mut client = RefereeClient::new(server.addr(), 0, policy).unwrap();
        assert_eq!(client.request(Request::Ping).unwrap(), (Reply::Pong));
    }
}
