//! The serial line as the bus sees it ([`SerialPort`]): non-blocking reads and writes of
//! bytes, and a reopen for the operator's reset. [`TtyPort`] is the real one (a tty or pty);
//! tests drive the bus over an in-memory port instead, like the CAN master over its
//! [`CanPort`](crate::canopen::CanPort).

use std::io::{self, Read, Write};
use std::os::fd::AsRawFd;
use std::time::Duration;

use serialport::TTYPort;

use super::SerialError;

/// The line hung up or failed: the bus closes the port and reports the link down.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkDown;

/// A serial line seen by [`SerialBus`](super::SerialBus). `try_read` and `write` must neither
/// block nor allocate (they run in the real-time tick); `reopen` may do both (it runs only on
/// the operator's reset).
pub trait SerialPort: Send {
    /// Bytes that arrived, without waiting: `Ok(0)` when nothing is waiting.
    fn try_read(&mut self, buf: &mut [u8]) -> Result<usize, LinkDown>;
    /// Writes one frame. A frame that does not fit is dropped (the missing reply shows it).
    fn write(&mut self, frame: &[u8]) -> Result<(), LinkDown>;
    /// Closes the line after a [`LinkDown`].
    fn close(&mut self);
    /// Opens the line again after [`SerialPort::close`].
    fn reopen(&mut self) -> Result<(), SerialError>;
}

/// A tty (USB adapter, UART, pty) opened non-blocking.
pub struct TtyPort {
    path: String,
    baud: u32,
    tty: Option<TTYPort>,
}

impl TtyPort {
    /// Opens `path` at `baud`, with zero timeout (a read never waits).
    pub fn open(path: &str, baud: u32) -> Result<TtyPort, SerialError> {
        let mut port = TtyPort {
            path: path.to_owned(),
            baud,
            tty: None,
        };
        port.reopen()?;
        Ok(port)
    }
}

enum Ready {
    Nothing,
    Data,
    HungUp,
}

/// Whether the port has bytes (or an end-of-file) to read, without waiting.
fn readiness(port: &TTYPort) -> Ready {
    let mut fd = libc::pollfd {
        fd: port.as_raw_fd(),
        events: libc::POLLIN,
        revents: 0,
    };
    // SAFETY: one valid pollfd, zero timeout.
    let n = unsafe { libc::poll(&mut fd, 1, 0) };
    if n < 0 {
        // EINTR: try again next tick.
        return Ready::Nothing;
    }
    if fd.revents & libc::POLLIN != 0 {
        Ready::Data
    } else if fd.revents & (libc::POLLHUP | libc::POLLERR | libc::POLLNVAL) != 0 {
        Ready::HungUp
    } else {
        Ready::Nothing
    }
}

fn would_block(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
    )
}

impl SerialPort for TtyPort {
    fn try_read(&mut self, buf: &mut [u8]) -> Result<usize, LinkDown> {
        let Some(tty) = self.tty.as_mut() else {
            return Err(LinkDown);
        };
        // Poll first: serialport reports "nothing to read" as an allocated error, which the
        // tick must not cause every time.
        match readiness(tty) {
            Ready::Nothing => return Ok(0),
            Ready::HungUp => return Err(LinkDown),
            Ready::Data => {}
        }
        // Interrupted reads are retried once; a second interruption waits for the next tick.
        for _ in 0..2 {
            match tty.read(buf) {
                // Readable but end of file: the other side hung up.
                Ok(0) => return Err(LinkDown),
                Ok(n) => return Ok(n),
                Err(e) if would_block(&e) => return Ok(0),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(_) => return Err(LinkDown),
            }
        }
        Ok(0)
    }

    fn write(&mut self, frame: &[u8]) -> Result<(), LinkDown> {
        let Some(tty) = self.tty.as_mut() else {
            return Err(LinkDown);
        };
        // A frame is far smaller than any tty buffer; a short write means the line is stuck,
        // which the missing reply reports.
        match tty.write(frame) {
            Ok(_) => Ok(()),
            Err(e) if would_block(&e) => Ok(()),
            Err(_) => Err(LinkDown),
        }
    }

    fn close(&mut self) {
        self.tty = None;
    }

    fn reopen(&mut self) -> Result<(), SerialError> {
        let tty = serialport::new(&self.path, self.baud)
            .timeout(Duration::ZERO)
            .open_native()
            .map_err(|e| SerialError::Open {
                path: self.path.clone(),
                reason: e.to_string(),
            })?;
        self.tty = Some(tty);
        Ok(())
    }
}
