//! Pseudo-terminals for device emulators: the emulator owns the master side
//! and the daemon opens the slave path exactly as it would open
//! `/dev/ttyACM0`.
//!
//! Facts this module is built around (checked on Linux):
//! * the slave must be raw (no echo, no CR/LF translation) or SCIP bytes are
//!   mangled; we `cfmakeraw` it at creation;
//! * once every slave fd is closed, a master read fails at once (EIO/HUP), so
//!   an emulator that loops would spin: [`Pty`] keeps its own slave fd open;
//! * a large blocking write ignores any timeout: the master is non-blocking
//!   and [`Pty`] writes in chunks of at most [`WRITE_CHUNK`] bytes, waiting
//!   for room with `poll` up to a deadline.
//!
//! "Unplug" closes the master (the daemon's reads then fail with a hang-up,
//! as with a USB device pulled out) and removes the symlink; "replug" makes a
//! new pty and points the symlink at it atomically (see [`PtyHost`]).

use std::io::{self, Read, Write};
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Largest single write to the master.
pub const WRITE_CHUNK: usize = 4096;

/// Why a pty or its symlink could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum PtyError {
    /// openpty/termios failed.
    #[error("cannot create a pseudo-terminal: {0}")]
    Create(io::Error),
    /// The symlink could not be created or replaced.
    #[error("cannot point symlink {path} at the pty: {source}")]
    Symlink {
        /// The symlink path.
        path: PathBuf,
        /// The OS error.
        source: io::Error,
    },
}

/// One pseudo-terminal pair seen from the emulator side.
pub struct Pty {
    master: OwnedFd,
    _slave: OwnedFd,
    slave_path: PathBuf,
    read_timeout: Duration,
    write_timeout: Duration,
}

fn cvt(r: libc::c_int) -> io::Result<libc::c_int> {
    if r < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(r)
    }
}

/// Waits for `events` on `fd` up to `timeout`; Ok(true) when ready,
/// Ok(false) on timeout, Err on hang-up or error. EINTR counts as "not yet".
fn poll_fd(fd: RawFd, events: libc::c_short, timeout: Duration) -> io::Result<bool> {
    let mut p = libc::pollfd {
        fd,
        events,
        revents: 0,
    };
    let ms = timeout.as_millis().min(i32::MAX as u128) as libc::c_int;
    // SAFETY: one valid pollfd for the duration of the call.
    let r = unsafe { libc::poll(&mut p, 1, ms) };
    if r < 0 {
        let e = io::Error::last_os_error();
        if e.kind() == io::ErrorKind::Interrupted {
            return Ok(false);
        }
        return Err(e);
    }
    if r == 0 {
        return Ok(false);
    }
    if p.revents & events != 0 {
        return Ok(true);
    }
    if p.revents & (libc::POLLHUP | libc::POLLERR | libc::POLLNVAL) != 0 {
        return Err(io::Error::new(
            io::ErrorKind::BrokenPipe,
            "pseudo-terminal hung up",
        ));
    }
    Ok(false)
}

impl Pty {
    /// Creates a pty pair: raw slave, non-blocking master.
    pub fn open() -> Result<Pty, PtyError> {
        let mut m: libc::c_int = -1;
        let mut s: libc::c_int = -1;
        // SAFETY: out-pointers to two ints; the name/termios/winsize
        // arguments may be null.
        cvt(unsafe {
            libc::openpty(
                &mut m,
                &mut s,
                std::ptr::null_mut(),
                std::ptr::null(),
                std::ptr::null(),
            )
        })
        .map_err(PtyError::Create)?;
        // SAFETY: openpty succeeded, both fds are ours.
        let (master, slave) = unsafe { (OwnedFd::from_raw_fd(m), OwnedFd::from_raw_fd(s)) };
        // SAFETY: plain termios calls on an open fd with a zeroed struct
        // that tcgetattr fills in.
        unsafe {
            let mut t: libc::termios = std::mem::zeroed();
            cvt(libc::tcgetattr(slave.as_raw_fd(), &mut t)).map_err(PtyError::Create)?;
            libc::cfmakeraw(&mut t);
            cvt(libc::tcsetattr(slave.as_raw_fd(), libc::TCSANOW, &t)).map_err(PtyError::Create)?;
            let fl =
                cvt(libc::fcntl(master.as_raw_fd(), libc::F_GETFL)).map_err(PtyError::Create)?;
            cvt(libc::fcntl(
                master.as_raw_fd(),
                libc::F_SETFL,
                fl | libc::O_NONBLOCK,
            ))
            .map_err(PtyError::Create)?;
            libc::fcntl(master.as_raw_fd(), libc::F_SETFD, libc::FD_CLOEXEC);
            libc::fcntl(slave.as_raw_fd(), libc::F_SETFD, libc::FD_CLOEXEC);
        }
        let mut buf = [0 as libc::c_char; 128];
        // SAFETY: buffer and its length are valid.
        cvt(unsafe { libc::ptsname_r(master.as_raw_fd(), buf.as_mut_ptr(), buf.len()) })
            .map_err(PtyError::Create)?;
        // SAFETY: ptsname_r wrote a NUL-terminated string into buf.
        let name = unsafe { std::ffi::CStr::from_ptr(buf.as_ptr()) };
        Ok(Pty {
            master,
            _slave: slave,
            slave_path: PathBuf::from(name.to_string_lossy().into_owned()),
            read_timeout: Duration::from_millis(10),
            write_timeout: Duration::from_secs(1),
        })
    }

    /// The slave device path (`/dev/pts/N`) a client opens.
    pub fn slave_path(&self) -> &Path {
        &self.slave_path
    }

    /// Sets how long a `read` waits for the first byte before `TimedOut`.
    pub fn set_read_timeout(&mut self, t: Duration) {
        self.read_timeout = t;
    }

    /// Sets how long a `write` may wait for room before `TimedOut` (the
    /// client is not reading; a real device would lose the bytes too).
    pub fn set_write_timeout(&mut self, t: Duration) {
        self.write_timeout = t;
    }
}

impl Read for Pty {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if !poll_fd(self.master.as_raw_fd(), libc::POLLIN, self.read_timeout)? {
            return Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "no bytes from the client",
            ));
        }
        // SAFETY: buf is valid for buf.len() bytes.
        let r = unsafe { libc::read(self.master.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
        if r < 0 {
            let e = io::Error::last_os_error();
            if e.kind() == io::ErrorKind::WouldBlock {
                return Err(io::Error::new(
                    io::ErrorKind::TimedOut,
                    "no bytes from the client",
                ));
            }
            return Err(e);
        }
        Ok(r as usize)
    }
}

impl Write for Pty {
    /// Writes up to [`WRITE_CHUNK`] bytes, waiting up to the write timeout
    /// for room.
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = buf.len().min(WRITE_CHUNK);
        let deadline = Instant::now() + self.write_timeout;
        loop {
            // SAFETY: buf is valid for n bytes.
            let r = unsafe { libc::write(self.master.as_raw_fd(), buf.as_ptr().cast(), n) };
            if r >= 0 {
                return Ok(r as usize);
            }
            let e = io::Error::last_os_error();
            match e.kind() {
                io::ErrorKind::Interrupted => continue,
                io::ErrorKind::WouldBlock => {
                    let now = Instant::now();
                    if now >= deadline {
                        return Err(io::Error::new(
                            io::ErrorKind::TimedOut,
                            "client is not reading the pty",
                        ));
                    }
                    poll_fd(self.master.as_raw_fd(), libc::POLLOUT, deadline - now)?;
                }
                _ => return Err(e),
            }
        }
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// A pty that can be unplugged and replugged, with an optional symlink that
/// always names the current slave (what the daemon is configured to open).
pub struct PtyHost {
    link: Option<PathBuf>,
    pty: Option<Pty>,
}

impl PtyHost {
    /// Creates the first pty and, if `link` is given, points it there.
    pub fn new(link: Option<PathBuf>) -> Result<PtyHost, PtyError> {
        let mut h = PtyHost { link, pty: None };
        h.replug()?;
        Ok(h)
    }

    /// The path a client should open: the symlink if any, else the slave path.
    pub fn client_path(&self) -> Option<PathBuf> {
        match (&self.link, &self.pty) {
            (Some(l), _) => Some(l.clone()),
            (None, Some(p)) => Some(p.slave_path().to_path_buf()),
            (None, None) => None,
        }
    }

    /// The current slave path (`/dev/pts/N`), `None` while unplugged.
    pub fn slave_path(&self) -> Option<PathBuf> {
        self.pty.as_ref().map(|p| p.slave_path().to_path_buf())
    }

    /// The current pty, `None` while unplugged.
    pub fn pty(&mut self) -> Option<&mut Pty> {
        self.pty.as_mut()
    }

    /// Whether a pty is currently plugged in.
    pub fn plugged(&self) -> bool {
        self.pty.is_some()
    }

    /// Removes the symlink, then closes the pty (clients see a hang-up).
    /// In that order, so the link never names a freed pty number that the
    /// kernel may already have given to someone else's new pty.
    pub fn unplug(&mut self) {
        if let Some(l) = &self.link {
            let _ = std::fs::remove_file(l);
        }
        self.pty = None;
    }

    /// Creates a new pty (a new `/dev/pts/N`) and re-points the symlink at
    /// it atomically (symlink to a temporary name, then rename over); a pty
    /// still plugged in is unplugged first.
    pub fn replug(&mut self) -> Result<(), PtyError> {
        self.unplug();
        let pty = Pty::open()?;
        if let Some(l) = &self.link {
            let tmp = l.with_file_name(format!(
                ".{}.{}.tmp",
                l.file_name()
                    .map(|n| n.to_string_lossy())
                    .unwrap_or_default(),
                std::process::id()
            ));
            let _ = std::fs::remove_file(&tmp);
            std::os::unix::fs::symlink(pty.slave_path(), &tmp)
                .and_then(|_| std::fs::rename(&tmp, l))
                .map_err(|source| PtyError::Symlink {
                    path: l.clone(),
                    source,
                })?;
        }
        self.pty = Some(pty);
        Ok(())
    }
}

impl Drop for PtyHost {
    fn drop(&mut self) {
        self.unplug();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::{open_device, Port};

    #[test]
    fn slave_opens_as_a_device_and_bytes_pass_raw() {
        let mut pty = Pty::open().unwrap();
        let mut dev = open_device(pty.slave_path(), 115_200, Duration::from_millis(200)).unwrap();
        // CR, LF and control bytes must pass untouched in both directions.
        dev.write_all(b"QT\r\n\x03x").unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 64];
        while got.len() < 6 {
            let n = pty.read(&mut buf).unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, b"QT\r\n\x03x");
        pty.write_all(b"00P\r\n\n").unwrap();
        let mut got = Vec::new();
        while got.len() < 6 {
            let n = dev.read(&mut buf).unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, b"00P\r\n\n");
        // A second opener is refused while the first holds it.
        assert!(open_device(pty.slave_path(), 115_200, Duration::from_millis(10)).is_err());
        drop(dev);
        // ...and allowed again after the first closed, though the emulator
        // still holds its own slave fd.
        let dev2 = open_device(pty.slave_path(), 115_200, Duration::from_millis(10));
        assert!(dev2.is_ok(), "{:?}", dev2.err());
    }

    #[test]
    fn read_times_out_without_data() {
        let mut pty = Pty::open().unwrap();
        pty.set_read_timeout(Duration::from_millis(5));
        let mut buf = [0u8; 8];
        let e = pty.read(&mut buf).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::TimedOut);
    }

    #[test]
    fn unplug_hangs_up_the_client_and_replug_repoints_the_link() {
        let dir = std::env::temp_dir().join(format!("sweepline-pty-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let link = dir.join("urg");
        let mut host = PtyHost::new(Some(link.clone())).unwrap();
        let first = std::fs::read_link(&link).unwrap();
        let mut dev = open_device(&link, 115_200, Duration::from_millis(100)).unwrap();
        dev.discard_input().unwrap();
        host.unplug();
        assert!(!link.exists());
        let mut buf = [0u8; 8];
        let e = dev.read(&mut buf);
        assert!(
            matches!(&e, Err(e) if crate::serial::is_link_gone(e)) || matches!(e, Ok(0)),
            "{e:?}"
        );
        host.replug().unwrap();
        let second = std::fs::read_link(&link).unwrap();
        assert_ne!(first, second);
        assert!(open_device(&link, 115_200, Duration::from_millis(10)).is_ok());
        drop(host);
        assert!(!link.exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn symlink_into_a_missing_folder_is_a_typed_error() {
        let e = PtyHost::new(Some(PathBuf::from("/nonexistent-dir/x/urg")))
            .err()
            .unwrap();
        assert!(e.to_string().contains("/nonexistent-dir/x/urg"), "{e}");
    }
}
