//! Serial ports and pseudo-terminals: opening a device path exactly as a
//! real /dev/ttyACM0 is opened, and creating ptys for the emulators.
//!
//! Drivers (`urg`, `motor`) never open anything themselves: they are given a
//! [`Connector`], which (re)opens a [`Port`] on demand. That is what lets one
//! driver talk to a USB-CDC tty, a pty made by an emulator or a TCP socket,
//! and re-open it after the device went away and came back.
//!
//! * [`device`]: a tty path opened raw, exclusive, with a read timeout
//!   (serialport crate), plus [`DeviceConnector`] that waits for the path.
//! * [`tcp`]: Ethernet sensors (UTM/UST) over TCP.
//! * [`pty`]: the emulator side: a pty master with its slave path, an
//!   optional symlink updated atomically, and unplug/replug.

pub mod device;
pub mod pty;
pub mod tcp;

use std::io::{self, Read, Write};
use std::time::Duration;

pub use device::{open_device, DeviceConnector};
pub use pty::{Pty, PtyError, PtyHost};
pub use tcp::TcpConnector;

/// A byte link to a device: what a driver reads and writes.
///
/// `read` returns `ErrorKind::TimedOut` (or `WouldBlock`) when no byte
/// arrived within the read timeout; any other error, or `Ok(0)`, means the
/// link is broken (see `is_link_gone`).
pub trait Port: Read + Write + Send {
    /// Sets how long one `read` waits for the first byte.
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()>;
    /// Throws away bytes received but not yet read (tcflush on a tty).
    fn discard_input(&mut self) -> io::Result<()>;
    /// A short human-readable name (device path or address) for logs.
    fn describe(&self) -> String;
}

/// Opens (and re-opens) the link to one device.
pub trait Connector: Send {
    /// Opens the port; `read_timeout` is the per-read wait.
    fn open(&mut self, read_timeout: Duration) -> io::Result<Box<dyn Port>>;
    /// Whether the device looks present (its path exists); used to wait for
    /// a replugged device before trying to open it again.
    fn present(&self) -> bool;
    /// The device's name (path or address) for logs and errors.
    fn describe(&self) -> String;
}

/// `timeout` as `poll` takes it, whole milliseconds as before the move to
/// rustix (below 1 ms: return at once), at most `i32::MAX` ms.
pub(crate) fn poll_timeout(timeout: Duration) -> rustix::event::Timespec {
    let ms = timeout.as_millis().min(i32::MAX as u128) as i64;
    rustix::event::Timespec {
        tv_sec: ms / 1000,
        tv_nsec: (ms % 1000) * 1_000_000,
    }
}

/// Classifies a read/write error: true when the device is gone (hang-up,
/// EIO, ENODEV, broken pipe, EOF) and the port must be closed and re-opened;
/// false for timeouts and interruptions, after which the same port is usable.
pub(crate) fn is_link_gone(e: &io::Error) -> bool {
    !matches!(
        e.kind(),
        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
    )
}

/// Writes all of `data`, in chunks of at most `chunk` bytes, retrying on
/// EINTR and on short writes. Large blocking tty writes ignore the port's
/// timeout, so emulators and drivers write in chunks.
pub fn write_chunked(w: &mut dyn Write, data: &[u8], chunk: usize) -> io::Result<()> {
    let chunk = chunk.max(1);
    let mut rest = data;
    while !rest.is_empty() {
        let n = rest.len().min(chunk);
        match w.write(&rest[..n]) {
            Ok(0) => {
                return Err(io::Error::new(
                    io::ErrorKind::WriteZero,
                    "device accepted no bytes",
                ))
            }
            Ok(k) => rest = &rest[k..],
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// The connector for a scanner named as the user names it: `HOST:PORT` (an
/// Ethernet model, e.g. 192.168.0.10:10940) over TCP, anything else a serial
/// device path opened at `baud`. `sweepline run` and `probe` both take it.
pub fn scanner_connector(name: &str, baud: u32) -> Box<dyn Connector> {
    match name.parse::<std::net::SocketAddr>() {
        Ok(addr) => Box::new(TcpConnector {
            addr,
            connect_timeout: std::time::Duration::from_secs(2),
        }),
        Err(_) => {
            let mut c = DeviceConnector::new(name);
            c.baud = baud;
            Box::new(c)
        }
    }
}

/// Whether a scanner name is a network address (`HOST:PORT`) rather than
/// a device path.
pub fn is_network_address(name: &str) -> bool {
    name.parse::<std::net::SocketAddr>().is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn link_gone_classification() {
        assert!(!is_link_gone(&io::Error::from(io::ErrorKind::TimedOut)));
        assert!(!is_link_gone(&io::Error::from(io::ErrorKind::Interrupted)));
        assert!(is_link_gone(&io::Error::from(io::ErrorKind::BrokenPipe)));
        assert!(is_link_gone(&io::Error::from_raw_os_error(libc::EIO)));
    }

    #[test]
    fn chunked_write_splits_and_survives_eintr() {
        struct W {
            got: Vec<usize>,
            interrupt_next: bool,
        }
        impl Write for W {
            fn write(&mut self, b: &[u8]) -> io::Result<usize> {
                if self.interrupt_next {
                    self.interrupt_next = false;
                    return Err(io::Error::from(io::ErrorKind::Interrupted));
                }
                self.interrupt_next = true;
                self.got.push(b.len());
                Ok(b.len())
            }
            fn flush(&mut self) -> io::Result<()> {
                Ok(())
            }
        }
        let mut w = W {
            got: vec![],
            interrupt_next: true,
        };
        write_chunked(&mut w, &[0u8; 10], 4).unwrap();
        assert_eq!(w.got, vec![4, 4, 2]);
    }
}
