//! Where the loop's thread leaves the latest snapshot and the server's threads pick it up:
//! the newest message only (a slow phone skips snapshots, never delays the robot).

use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::Duration;

/// The latest snapshot (JSON text) with its sequence number.
#[derive(Debug, Default)]
struct Latest {
    sequence: u64,
    json: Arc<str>,
    closed: bool,
}

/// The snapshot exchange between the loop and the server (see the module documentation).
#[derive(Debug, Default)]
pub struct Hub {
    latest: Mutex<Latest>,
    changed: Condvar,
}

impl Hub {
    /// An empty hub, shared.
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// Publish a new snapshot (JSON text); waiting readers wake.
    pub fn publish(&self, json: String) {
        let mut latest = self.latest.lock().unwrap_or_else(PoisonError::into_inner);
        latest.sequence += 1;
        latest.json = json.into();
        self.changed.notify_all();
    }

    /// The run is over: readers stop waiting for more.
    pub fn close(&self) {
        let mut latest = self.latest.lock().unwrap_or_else(PoisonError::into_inner);
        latest.closed = true;
        self.changed.notify_all();
    }

    /// True once [`Hub::close`] was called.
    pub fn is_closed(&self) -> bool {
        self.latest
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .closed
    }

    /// The latest snapshot and its sequence number (0 and empty before the first).
    pub fn latest(&self) -> (u64, Arc<str>) {
        let latest = self.latest.lock().unwrap_or_else(PoisonError::into_inner);
        (latest.sequence, latest.json.clone())
    }

    /// The first snapshot newer than `seen`, waiting at most `timeout`; `None` when none
    /// came in that time or the hub is closed.
    pub fn next_after(&self, seen: u64, timeout: Duration) -> Option<(u64, Arc<str>)> {
        let latest = self.latest.lock().unwrap_or_else(PoisonError::into_inner);
        let (latest, _) = self
            .changed
            .wait_timeout_while(latest, timeout, |l| l.sequence <= seen && !l.closed)
            .unwrap_or_else(PoisonError::into_inner);
        (latest.sequence > seen).then(|| (latest.sequence, latest.json.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reader_gets_the_newest_snapshot_and_waits_for_the_next() {
        let hub = Hub::new();
        assert_eq!(hub.latest().0, 0);
        hub.publish("{\"a\":1}".into());
        hub.publish("{\"a\":2}".into());
        let (seq, json) = hub.next_after(0, Duration::ZERO).unwrap();
        assert_eq!((seq, &*json), (2, "{\"a\":2}"));
        assert!(hub.next_after(seq, Duration::from_millis(1)).is_none());
        let writer = {
            let hub = hub.clone();
            std::thread::spawn(move || hub.publish("{\"a\":3}".into()))
        };
        let next = hub.next_after(seq, Duration::from_secs(30));
        writer.join().unwrap();
        assert_eq!(next.map(|(s, _)| s), Some(3));
        hub.close();
        assert!(hub.next_after(3, Duration::from_secs(30)).is_none());
    }
}
