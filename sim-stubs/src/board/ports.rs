//! The board's pseudo-terminals: making them, and writing, reading and watching them
//! without blocking the run loop for long.

use std::os::fd::AsRawFd;

use nix::poll::{poll, PollFd, PollFlags};
use serialport::{SerialPort, TTYPort};

use super::TICK;
use crate::serve::ServeError;

/// A pseudo-terminal: our master end and, when kept, the other end held open.
pub(super) struct Pty {
    pub(super) master: TTYPort,
    pub(super) _slave: Option<TTYPort>,
    pub(super) path: String,
}

pub(super) fn pty(keep_slave: bool) -> Result<Pty, ServeError> {
    let (mut master, slave) =
        TTYPort::pair().map_err(|e| ServeError::Io(std::io::Error::other(e.to_string())))?;
    let path = slave.name().unwrap_or_default();
    master
        .set_timeout(TICK)
        .map_err(|e| ServeError::Io(std::io::Error::other(e.to_string())))?;
    Ok(Pty {
        master,
        _slave: keep_slave.then_some(slave),
        path,
    })
}

/// Write all of `bytes` unless the other side stops reading for [`TICK`]; returns how many
/// were written.
pub(super) fn write_some(port: &mut TTYPort, bytes: &[u8]) -> usize {
    let mut done = 0;
    while done < bytes.len() {
        match std::io::Write::write(port, &bytes[done..]) {
            Ok(0) | Err(_) => break,
            Ok(n) => done += n,
        }
    }
    done
}

/// Read what is there (the port is known readable); `None` when the other side is closed.
pub(super) fn read_now(port: &TTYPort, buf: &mut [u8]) -> Option<usize> {
    match nix::unistd::read(port.as_raw_fd(), buf) {
        Ok(n) => Some(n),
        Err(nix::errno::Errno::EAGAIN) | Err(nix::errno::Errno::EINTR) => Some(0),
        Err(_) => None,
    }
}

/// Whether a host has the host end open (no hang-up on our master).
pub(super) fn host_present(port: &TTYPort) -> bool {
    let mut fds = [PollFd::new(port.as_raw_fd(), PollFlags::POLLIN)];
    match poll(&mut fds, 0) {
        Ok(_) => !fds[0]
            .revents()
            .is_some_and(|r| r.contains(PollFlags::POLLHUP)),
        Err(_) => false,
    }
}

pub(super) struct Ports {
    pub(super) board_host: Pty,
    /// The plant lines (servo bus, base) while plugged; a robot without a base has none.
    pub(super) lines: [Option<Pty>; 2],
    pub(super) clock: Pty,
    pub(super) host: Pty,
}

/// The line rate the other end of `port` has set, bit/s (a PTY master reads its slave's
/// settings).
pub(super) fn line_baud(port: &TTYPort) -> Option<u32> {
    port.baud_rate().ok()
}

/// Point the symlink `link` at `target`, replacing the symlink it was.
pub(super) fn relink(link: &std::path::Path, target: &str) -> std::io::Result<()> {
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(target, link)
}
