//! Pseudo-terminals standing in for a device's USB serial port: the simulated devices of
//! `ratf sim --serve-pty` and the device tests hold the master end, and the robot's code
//! opens the slave end by its path, as it opens a real port.

use std::fs::File;
use std::os::fd::AsFd;
use std::path::PathBuf;

use nix::poll::{PollFd, PollFlags, PollTimeout};

/// A new pseudo-terminal in raw mode (no echo, no line editing, until the opener sets its
/// own modes): the master end, and the slave's path. Our slave end is closed, so the master
/// sees a hang-up until someone opens the slave.
pub fn open_raw() -> Result<(File, PathBuf), PtyError> {
    let step = |what: &'static str| move |source| PtyError { what, source };
    let pair = nix::pty::openpty(None, None).map_err(step("openpty"))?;
    let slave_path = nix::unistd::ttyname(pair.slave.as_fd()).map_err(step("ttyname"))?;
    let mut modes = nix::sys::termios::tcgetattr(pair.slave.as_fd()).map_err(step("tcgetattr"))?;
    nix::sys::termios::cfmakeraw(&mut modes);
    nix::sys::termios::tcsetattr(
        pair.slave.as_fd(),
        nix::sys::termios::SetArg::TCSANOW,
        &modes,
    )
    .map_err(step("tcsetattr"))?;
    drop(pair.slave);
    Ok((File::from(pair.master), slave_path))
}

/// Make reads and writes on `fd` return at once instead of waiting.
pub fn set_nonblocking(fd: &impl AsFd) -> Result<(), PtyError> {
    use nix::fcntl::{FcntlArg, OFlag, fcntl};
    let step = |source| PtyError {
        what: "non-blocking",
        source,
    };
    let flags = OFlag::from_bits_truncate(fcntl(fd, FcntlArg::F_GETFL).map_err(step)?);
    fcntl(fd, FcntlArg::F_SETFL(flags | OFlag::O_NONBLOCK)).map_err(step)?;
    Ok(())
}

/// True while some process has the slave end of `master` open (no hang-up).
pub fn slave_open(master: &impl AsFd) -> bool {
    let mut fds = [PollFd::new(master.as_fd(), PollFlags::POLLIN)];
    match nix::poll::poll(&mut fds, PollTimeout::ZERO) {
        Ok(_) => !fds[0]
            .revents()
            .is_some_and(|r| r.contains(PollFlags::POLLHUP)),
        Err(_) => false,
    }
}

/// A pseudo-terminal could not be made or set up.
#[derive(Debug, thiserror::Error)]
#[error("{what}: {source}")]
pub struct PtyError {
    /// The step that failed.
    pub what: &'static str,
    /// The system's error.
    #[source]
    pub source: nix::Error,
}
