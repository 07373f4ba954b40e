//! The organisers' server over UDP: the existing [`RefereeLink`] (a socket connected to the
//! configured address, so the OS drops datagrams from anyone else), read by a thread that
//! stamps each datagram at arrival; the loop sends requests through a [`RefereeHandle`].

use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use ratf_core::referee::protocol::Request;
use ratf_core::runtime::{DeviceKind, Input, Stamped};

use super::{Clock, DeviceSender, LinkState, Message, Shared, report};
use crate::referee::client::RefereeLink;

/// How long the thread blocks for a datagram before looking at the quit flag.
const POLL: Duration = Duration::from_millis(20);

/// The loop's side of the server link.
#[derive(Clone, Debug)]
pub struct RefereeHandle {
    link: Arc<RefereeLink>,
}

impl RefereeHandle {
    /// Send `request` (a lost datagram is the core's tracker's to retry; a socket that
    /// cannot send is reported as a fault by the next receive, so this only tells).
    pub fn send(&self, request: Request) -> bool {
        self.link.send(request).is_ok()
    }

    /// The server's address.
    pub fn server(&self) -> std::net::SocketAddr {
        self.link.server()
    }
}

/// Run the server's thread on `link`; the handle sends on the same socket.
pub fn spawn(
    link: RefereeLink,
    clock: Clock,
    tx: DeviceSender,
    shared: Shared,
) -> std::io::Result<(RefereeHandle, JoinHandle<()>)> {
    let link = Arc::new(link);
    let handle = RefereeHandle {
        link: Arc::clone(&link),
    };
    let thread = std::thread::Builder::new()
        .name("referee".to_owned())
        .spawn(move || {
            report(&tx, Message::Link(DeviceKind::Referee, LinkState::Up));
            while !shared.quitting() {
                link.wait_readable(POLL);
                for datagram in link.receive() {
                    let input = Stamped::new(clock.now(), Input::Referee { datagram });
                    if !report(&tx, Message::Input(input)) {
                        return;
                    }
                }
            }
        })?;
    Ok((handle, thread))
}
