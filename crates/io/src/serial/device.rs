//! A device path (e.g. `/dev/ttyACM0`, a udev symlink, or a pty slave) opened
//! exactly as a real scanner is: raw 8N1, exclusive (TIOCEXCL + flock, so a
//! second opener is refused), with a read timeout. The bit rate is set but
//! ignored by USB-CDC devices and ptys.
//!
//! The OS calls are `rustix`'s (safe, typed): `poll`, `read`, `fstat`,
//! `open(O_PATH)`, `ioctl(TIOCNXCL)`. The tty itself is opened and
//! configured by the `serialport` crate, whose port gives out only a raw fd:
//! `tty_fd` borrows it, the one `unsafe` left here.

use std::io::{self, Read, Write};
use std::os::fd::{AsFd, AsRawFd, BorrowedFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use serialport::{ClearBuffer, SerialPort, TTYPort};

use super::{Connector, Port};

/// An open tty device.
pub struct DevicePort {
    tty: TTYPort,
    name: String,
    timeout: Duration,
}

/// The open fd of `tty`, borrowed for as long as `tty` is.
fn tty_fd(tty: &TTYPort) -> BorrowedFd<'_> {
    // SAFETY: the TTYPort owns this fd and keeps it open until it drops,
    // which the borrow of `tty` outlives.
    unsafe { BorrowedFd::borrow_raw(tty.as_raw_fd()) }
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
        // The kernel keeps a tty exclusive until its *last* close; an
        // emulator holding its own slave fd would then refuse our re-open.
        // Give the exclusivity back explicitly (the flock goes with the fd).
        // A failure leaves nothing to do: the fd closes right after.
        let _ = rustix::termios::ioctl_tiocnxcl(tty_fd(&self.tty));
    }
}

impl Read for DevicePort {
    /// Waits up to the read timeout for bytes, then reads what is there.
    /// Our own poll + read (rather than the serialport crate's) so that a
    /// timeout or EINTR costs no allocation on the scan path: errors are
    /// built from their kind only.
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        use rustix::event::{PollFd, PollFlags};
        let fd = tty_fd(&self.tty);
        let mut p = [PollFd::from_borrowed_fd(fd, PollFlags::IN)];
        let timeout = super::poll_timeout(self.timeout);
        let r = rustix::event::poll(&mut p, Some(&timeout))?;
        if r == 0 {
            return Err(io::ErrorKind::TimedOut.into());
        }
        let revents = p[0].revents();
        if !revents.contains(PollFlags::IN) {
            if revents.intersects(PollFlags::HUP | PollFlags::ERR | PollFlags::NVAL) {
                return Err(io::ErrorKind::BrokenPipe.into());
            }
            return Err(io::ErrorKind::TimedOut.into());
        }
        match rustix::io::read(fd, buf) {
            Ok(n) => Ok(n),
            Err(rustix::io::Errno::AGAIN) => Err(io::ErrorKind::TimedOut.into()),
            Err(e) => Err(e.into()),
        }
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
///
/// A bare pseudo-terminal path (`/dev/pts/N`) is never re-opened once the
/// pty behind it has gone: the kernel hands the number `N` to the next pty
/// created on the machine (another emulator's, or a second device's of the
/// same daemon), and a driver still retrying `/dev/pts/N` would take that
/// pty exclusively and lock its real owner out. Through a symlink, which the
/// emulator re-points on replug, re-opening is always allowed.
#[derive(Clone, Debug)]
pub struct DeviceConnector {
    /// The device path.
    pub path: PathBuf,
    /// Bit rate to request (ignored by USB-CDC and ptys).
    pub baud: u32,
    /// An `O_PATH` handle on the pty node first opened through a bare
    /// `/dev/pts/N` path: it does not open the tty, but tells when that pty
    /// is gone (its node's link count drops to 0).
    pty: Option<Arc<OwnedFd>>,
}

/// Unix98 pty slaves use character majors 136..=143 on Linux.
fn is_pty_slave(rdev: u64) -> bool {
    (136..=143).contains(&rustix::fs::major(rdev))
}

fn fstat(fd: impl AsFd) -> Option<rustix::fs::Stat> {
    rustix::fs::fstat(fd).ok()
}

/// Whether `path` itself (not through a symlink) is a pty slave node.
fn bare_pty_path(path: &Path) -> bool {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    std::fs::symlink_metadata(path)
        .is_ok_and(|m| m.file_type().is_char_device() && is_pty_slave(m.rdev()))
}

/// An `O_PATH` handle on the node `path` names, if it is the very pty
/// `port` has open.
fn pin_pty(path: &Path, port: &DevicePort) -> Option<OwnedFd> {
    use rustix::fs::{Mode, OFlags};
    let open = fstat(tty_fd(&port.tty))?;
    // O_PATH opens no device.
    let fd = rustix::fs::open(
        path,
        OFlags::PATH | OFlags::CLOEXEC | OFlags::NOFOLLOW,
        Mode::empty(),
    )
    .ok()?;
    let node = fstat(&fd)?;
    (node.st_ino == open.st_ino && node.st_dev == open.st_dev && node.st_nlink > 0).then_some(fd)
}

impl DeviceConnector {
    /// A connector for `path` at 115200 bit/s.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            baud: 115_200,
            pty: None,
        }
    }

    /// Whether `path` is a bare pty path whose first pty has gone (any node
    /// there now is another pty that got the same number).
    fn pty_gone(&self) -> bool {
        self.pty
            .as_ref()
            .is_some_and(|fd| fstat(&**fd).is_none_or(|st| st.st_nlink == 0))
    }

    fn gone_error(&self) -> io::Error {
        io::Error::new(
            io::ErrorKind::NotFound,
            format!(
                "{}: the pseudo-terminal first opened here is gone and pty numbers are \
                 reused, so this path may now name another device; open the emulator's \
                 symlink to follow a replug",
                self.path.display()
            ),
        )
    }
}

impl Connector for DeviceConnector {
    fn open(&mut self, read_timeout: Duration) -> io::Result<Box<dyn Port>> {
        if self.pty_gone() {
            return Err(self.gone_error());
        }
        let port = open_device(&self.path, self.baud, read_timeout)?;
        // Only a bare pty path is pinned: a symlink may rightly move.
        if self.pty.is_none() && bare_pty_path(&self.path) {
            self.pty = pin_pty(&self.path, &port).map(Arc::new);
        } else if self.pty_gone() {
            // The pty went away and its number was reused between the
            // check above and the open: leave that one to its owner.
            return Err(self.gone_error());
        }
        Ok(Box::new(port))
    }
    fn present(&self) -> bool {
        self.path.exists() && !self.pty_gone()
    }
    fn describe(&self) -> String {
        self.path.display().to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::{Pty, PtyHost};

    const T: Duration = Duration::from_millis(20);

    /// A new pty that got `path`'s number (the kernel gives the lowest free
    /// one; another process may hold it for a moment, so try a while).
    fn pty_numbered(path: &Path) -> Pty {
        for _ in 0..300 {
            let p = Pty::open().unwrap();
            if p.slave_path() == path {
                return p;
            }
            drop(p);
            std::thread::sleep(Duration::from_millis(10));
        }
        panic!("no new pty got the number of {}", path.display());
    }

    #[test]
    fn a_bare_pty_path_is_reopened_while_its_pty_lives() {
        let mut pty = Pty::open().unwrap();
        let mut c = DeviceConnector::new(pty.slave_path());
        for _ in 0..3 {
            assert!(c.present());
            let mut port = c.open(T).unwrap();
            port.write_all(b"QT\n").unwrap();
            port.discard_input().unwrap();
            let mut buf = [0u8; 8];
            let n = pty.read(&mut buf).unwrap();
            assert_eq!(&buf[..n], b"QT\n");
        }
    }

    #[test]
    fn a_reused_pty_number_is_left_to_its_new_owner() {
        let first = Pty::open().unwrap();
        let path = first.slave_path().to_path_buf();
        let mut c = DeviceConnector::new(&path);
        drop(c.open(T).unwrap());
        drop(first);
        assert!(!c.present(), "the pty is gone");
        let second = pty_numbered(&path);
        assert!(!c.present(), "{} is someone else's pty now", path.display());
        let e = c.open(T).err().expect("a reused number must not be opened");
        assert_eq!(e.kind(), io::ErrorKind::NotFound);
        assert!(e.to_string().contains("symlink"), "{e}");
        // The new pty's owner opens it: nobody holds it.
        let mut owner = DeviceConnector::new(second.slave_path());
        assert!(owner.open(T).is_ok());
    }

    #[test]
    fn a_symlink_follows_the_replugged_pty() {
        let dir = std::env::temp_dir().join(format!("sweepline-dev-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let link = dir.join("dev");
        let mut host = PtyHost::new(Some(link.clone())).unwrap();
        let mut c = DeviceConnector::new(&link);
        drop(c.open(T).unwrap());
        host.unplug();
        assert!(!c.present());
        host.replug().unwrap();
        assert!(c.present());
        assert!(c.open(T).is_ok());
        drop(host);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
