//! Byte transports for the servo bus: a trait with a read timeout, and a serial line (a tty, a
//! USB adapter such as the U2D2, or one end of a pseudo-terminal in tests).

use std::fs::File;
use std::io::{self, Read, Write};
use std::os::fd::{AsFd, OwnedFd};
use std::os::unix::fs::OpenOptionsExt;
use std::time::Duration;

use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
use nix::sys::termios::{self, BaudRate, SetArg};

use crate::error::JointError;

/// A half-duplex byte stream to the servos.
pub trait Transport: Send {
    /// Sends all of `bytes`.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Reads what is available into `buf`, waiting at most `timeout` for the first byte;
    /// `Ok(0)` means nothing came in time.
    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
    /// Drops bytes already received and not read (late replies), without waiting.
    fn discard_input(&mut self) -> io::Result<()> {
        let mut scratch = [0u8; 256];
        while self.read_timeout(&mut scratch, Duration::ZERO)? > 0 {}
        Ok(())
    }
}

/// A serial line in raw mode (8N1, no echo, no flow control).
#[derive(Debug)]
pub struct SerialPort {
    file: File,
}

/// The termios speed for a baud rate the X-series servos support.
pub fn baud_rate(baud: u32) -> Option<BaudRate> {
    Some(match baud {
        9600 => BaudRate::B9600,
        57600 => BaudRate::B57600,
        115_200 => BaudRate::B115200,
        1_000_000 => BaudRate::B1000000,
        2_000_000 => BaudRate::B2000000,
        3_000_000 => BaudRate::B3000000,
        4_000_000 => BaudRate::B4000000,
        _ => return None,
    })
}

impl SerialPort {
    /// Opens the tty at `path` and sets it raw at `baud` (one of [`baud_rate`]'s).
    pub fn open(path: &str, baud: u32) -> Result<Self, JointError> {
        let speed = baud_rate(baud)
            .ok_or_else(|| JointError::config("baud", format!("unsupported baud rate {baud}")))?;
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(nix::libc::O_NOCTTY)
            .open(path)
            .map_err(|e| JointError::Bus(format!("cannot open {path}: {e}")))?;
        let port = Self::from_fd(file.into(), Some(speed))
            .map_err(|e| JointError::Bus(format!("cannot configure {path}: {e}")))?;
        Ok(port)
    }

    /// Wraps an open terminal fd (e.g. a pty end), putting it in raw mode, with `speed` if given.
    pub fn from_fd(fd: OwnedFd, speed: Option<BaudRate>) -> io::Result<Self> {
        set_raw(&fd, speed)?;
        Ok(Self {
            file: File::from(fd),
        })
    }
}

/// Puts a terminal in raw mode (and sets its speed if given).
pub fn set_raw(fd: &impl AsFd, speed: Option<BaudRate>) -> io::Result<()> {
    let mut t = termios::tcgetattr(fd.as_fd())?;
    termios::cfmakeraw(&mut t);
    if let Some(speed) = speed {
        termios::cfsetspeed(&mut t, speed)?;
    }
    termios::tcsetattr(fd.as_fd(), SetArg::TCSANOW, &t)?;
    Ok(())
}

/// Waits up to `timeout` for `fd` to be readable.
pub(crate) fn wait_readable(fd: &impl AsFd, timeout: Duration) -> io::Result<bool> {
    let ms = u16::try_from(timeout.as_millis()).unwrap_or(u16::MAX);
    // Round a sub-millisecond wait up so that a positive timeout never busy-polls.
    let ms = if ms == 0 && !timeout.is_zero() { 1 } else { ms };
    let mut fds = [PollFd::new(fd.as_fd(), PollFlags::POLLIN)];
    loop {
        match poll(&mut fds, PollTimeout::from(ms)) {
            Ok(0) => return Ok(false),
            Ok(_) => return Ok(true),
            Err(nix::errno::Errno::EINTR) => continue,
            Err(e) => return Err(e.into()),
        }
    }
}

impl Transport for SerialPort {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.file.write_all(bytes)?;
        self.file.flush()
    }

    fn read_timeout(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if !wait_readable(&self.file, timeout)? {
            return Ok(0);
        }
        self.file.read(buf)
    }
}
