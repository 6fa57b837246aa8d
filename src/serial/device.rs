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
    Ok(DevicePort { tty, name })
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
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.tty.read(buf)
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
