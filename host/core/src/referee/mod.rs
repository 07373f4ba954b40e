//! The organisers' server (competition.md §3): its datagram protocol, the request/reply
//! tracker, and the snapshot cycle that reads `IWP`/`OWP`/`MAP`/`MBP` while driving. Pure:
//! the socket is the host's.

pub mod protocol;
pub mod snapshot;
pub mod tracker;
