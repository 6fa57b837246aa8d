//! A device path (e.g. `/dev/ttyACM0`, a udev symlink, or a pty slave) opened
//! exactly as a real scanner is: raw 8N1, exclusive (TIOCEXCL + flock, so a
//! second opener is refused), with a read timeout. The bit rate is set but
//! ignored by USB-CDC devices and ptys.

use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use serialport::{ClearBuffer, SerialPort, TTYPort};

use super::{Connector, Port};

/// An open tty device.
pub struct DevicePort {
    tty: TTYPort,
    name: String,
    timeout: Duration,
}

/// Opens `path` raw and exclusive at `baud` with the given read timeout.
///
/// Errors name the path and say why (missing, busy, permission).
pub fn open_device(path: &Path, baud: u32, read_timeout: Duration) -> io::Result<DevicePort> {
    let name = path.display().to_string();
    let tty = serialport::new(name.clone(), baud)
        .timeout(read_timeout)
        .exclusive(true)
        .open_native()
        .map_err(|e| {
            let kind = match e.kind() {
                serialport::ErrorKind::NoDevice => io::ErrorKind::NotFound,
                serialport::ErrorKind::Io(k) => k,
                _ => io::ErrorKind::Other,
            };
            io::Error::new(kind, format!("cannot open {name}: {e}"))
        })?;
    Ok(DevicePort {
        tty,
        name,
        timeout: read_timeout,
    })
}

impl Drop for DevicePort {
    fn drop(&mut self) {
        use std::os::fd::AsRawFd;
        // The kernel keeps a tty exclusive until its *last* close; an
        // emulator holding its own slave fd would then refuse our re-open.
        // Give the exclusivity back explicitly (the flock goes with the fd).
        // SAFETY: TIOCNXCL takes no argument and the fd is open until the
        // TTYPort field drops after this.
        unsafe {
            libc::ioctl(self.tty.as_raw_fd(), libc::TIOCNXCL);
        }
    }
}

impl Read for DevicePort {
    /// Waits up to the read timeout for bytes, then reads what is there.
    /// Our own poll + read (rather than the serialport crate's) so that a
    /// timeout or EINTR costs no allocation on the scan path: errors are
    /// built from their kind only.
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        use std::os::fd::AsRawFd;
        let fd = self.tty.as_raw_fd();
        let mut p = libc::pollfd {
            fd,
            events: libc::POLLIN,
            revents: 0,
        };
        let ms = self.timeout.as_millis().min(i32::MAX as u128) as libc::c_int;
        // SAFETY: one valid pollfd for the duration of the call.
        let r = unsafe { libc::poll(&mut p, 1, ms) };
        if r < 0 {
            return Err(io::Error::last_os_error());
        }
        if r == 0 {
            return Err(io::ErrorKind::TimedOut.into());
        }
        if p.revents & libc::POLLIN == 0 {
            if p.revents & (libc::POLLHUP | libc::POLLERR | libc::POLLNVAL) != 0 {
                return Err(io::ErrorKind::BrokenPipe.into());
            }
            return Err(io::ErrorKind::TimedOut.into());
        }
        // SAFETY: buf is valid for buf.len() bytes; the fd is open.
        let n = unsafe { libc::read(fd, buf.as_mut_ptr().cast(), buf.len()) };
        if n < 0 {
            let e = io::Error::last_os_error();
            if e.kind() == io::ErrorKind::WouldBlock {
                return Err(io::ErrorKind::TimedOut.into());
            }
            return Err(e);
        }
        Ok(n as usize)
    }
}

impl Write for DevicePort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.tty.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.tty.flush()
    }
}

impl Port for DevicePort {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.timeout = timeout;
        self.tty
            .set_timeout(timeout)
            .map_err(|e| io::Error::other(format!("{}: {e}", self.name)))
    }
    fn discard_input(&mut self) -> io::Result<()> {
        self.tty
            .clear(ClearBuffer::Input)
            .map_err(|e| io::Error::other(format!("{}: {e}", self.name)))
    }
    fn describe(&self) -> String {
        self.name.clone()
    }
}

/// Opens a device by path, again after every unplug; the path may be a
/// udev or emulator symlink that disappears and comes back.
#[derive(Clone, Debug)]
pub struct DeviceConnector {
    /// The device path.
    pub path: PathBuf,
    /// Bit rate to request (ignored by USB-CDC and ptys).
    pub baud: u32,
}

impl DeviceConnector {
    /// A connector for `path` at 115200 bit/s.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            baud: 115_200,
        }
    }
}

impl Connector for DeviceConnector {
    fn open(&mut self, read_timeout: Duration) -> io::Result<Box<dyn Port>> {
        Ok(Box::new(open_device(&self.path, self.baud, read_timeout)?))
    }
    fn present(&self) -> bool {
        self.path.exists()
    }
    fn describe(&self) -> String {
        self.path.display().to_string()
    }
}
