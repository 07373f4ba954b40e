//! A pseudo-terminal standing in for a device's USB serial port: the test holds the master
//! end, and the device thread opens the slave end through a symlink (the stable name a udev
//! rule gives a real device, as `ratf sim --serve-pty` does). Closing the master is pulling
//! the cable; [`Pty::replug`] plugs a new device in at the same name.

use std::fs::File;
use std::io::{ErrorKind, Read, Write};
use std::os::fd::AsFd;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use nix::poll::{PollFd, PollFlags, PollTimeout};

/// A fresh directory under the system's temporary one, removed on drop.
pub(crate) struct TempDir(pub(crate) PathBuf);

impl TempDir {
    /// A new directory whose name holds `name`, the process id and a counter.
    pub(crate) fn new(name: &str) -> Self {
        static COUNTER: AtomicU32 = AtomicU32::new(0);
        let n = COUNTER.fetch_add(1, Ordering::SeqCst);
        let dir = std::env::temp_dir().join(format!("ratf-{name}-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temporary directory");
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The device's end of a pseudo-terminal, reachable at a fixed path.
pub(crate) struct Pty {
    master: Option<File>,
    link: PathBuf,
}

impl Pty {
    /// A new pseudo-terminal, raw, with `link` pointing at its slave end.
    pub(crate) fn open(link: &Path) -> Self {
        let mut pty = Self {
            master: None,
            link: link.to_owned(),
        };
        pty.replug();
        pty
    }

    /// The path the device thread opens.
    pub(crate) fn path(&self) -> String {
        self.link.to_str().expect("a UTF-8 path").to_owned()
    }

    /// Pull the cable: close the master end (the slave's reader sees a hang-up).
    pub(crate) fn unplug(&mut self) {
        self.master = None;
    }

    /// Plug a new device in at the same path: a new pseudo-terminal (the old one, if any,
    /// is closed), the link moved to it at once (rename, so the path never dangles).
    pub(crate) fn replug(&mut self) {
        self.master = None;
        let (master, slave) = crate::pty::open_raw().expect("a pseudo-terminal");
        crate::pty::set_nonblocking(&master).expect("O_NONBLOCK");
        let staged = self.link.with_extension("new");
        let _ = std::fs::remove_file(&staged);
        std::os::unix::fs::symlink(&slave, &staged).expect("symlink");
        std::fs::rename(&staged, &self.link).expect("rename the symlink");
        self.master = Some(master);
    }

    /// True while the device thread has the slave end open.
    pub(crate) fn connected(&self) -> bool {
        self.master.as_ref().is_some_and(crate::pty::slave_open)
    }

    /// Whatever the device thread wrote, waiting at most until `until` for the first byte
    /// (an empty vector if nothing came, or nobody has the slave open).
    pub(crate) fn read_until(&mut self, until: Instant) -> Vec<u8> {
        let mut out = Vec::new();
        let Some(master) = self.master.as_mut() else {
            pause_until(until);
            return out;
        };
        let wait = until.saturating_duration_since(Instant::now());
        let timeout = PollTimeout::from(wait.as_micros().div_ceil(1_000).min(1_000) as u16);
        let mut fds = [PollFd::new(master.as_fd(), PollFlags::POLLIN)];
        let ready = nix::poll::poll(&mut fds, timeout).unwrap_or(0);
        let revents = fds[0].revents().unwrap_or(PollFlags::empty());
        if ready > 0 && revents.contains(PollFlags::POLLHUP) && !revents.contains(PollFlags::POLLIN)
        {
            // Nobody on the other end: poll would return at once; wait out a millisecond.
            pause_until(until.min(Instant::now() + Duration::from_millis(1)));
            return out;
        }
        let mut buf = [0u8; 4096];
        loop {
            match master.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => out.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                // WouldBlock: nothing more; EIO: nobody on the other end.
                Err(_) => break,
            }
        }
        out
    }

    /// Send `bytes` to the device thread (dropped if nobody has the slave open, as a cable
    /// to nobody drops them).
    pub(crate) fn write(&mut self, bytes: &[u8]) {
        let Some(master) = self.master.as_mut() else {
            return;
        };
        let mut rest = bytes;
        let deadline = Instant::now() + Duration::from_secs(1);
        while !rest.is_empty() && Instant::now() < deadline {
            match master.write(rest) {
                Ok(0) => break,
                Ok(n) => rest = &rest[n..],
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                // The terminal's buffer is full: the reader is behind; let it catch up.
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    pause_until(Instant::now() + Duration::from_micros(200));
                }
                Err(_) => break,
            }
        }
    }
}

/// Block until `until` (for pacing an emulated device, never for waiting on a result).
fn pause_until(until: Instant) {
    let left = until.saturating_duration_since(Instant::now());
    if !left.is_zero() {
        std::thread::sleep(left);
    }
}
