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
//!
//! Every OS call is `rustix`'s (safe, typed): `posix_openpt`, `grantpt`,
//! `unlockpt`, `ptsname` and the slave's `open` in place of glibc's
//! `openpty`, which rustix leaves out; `tcgetattr` / `tcsetattr` with
//! `cfmakeraw`, `fcntl`, `poll`, `read` and `write`. No `unsafe` is left.

use std::io::{self, Read, Write};
use std::os::fd::{AsFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rustix::event::{PollFd, PollFlags};
use rustix::fs::{Mode, OFlags};
use rustix::pty::OpenptFlags;

/// Largest single write to the master.
pub const WRITE_CHUNK: usize = 4096;

/// Why a pty or its symlink could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum PtyError {
    /// The pty, its termios or its flags could not be set up.
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
    slave: OwnedFd,
    slave_path: PathBuf,
    read_timeout: Duration,
    write_timeout: Duration,
}

/// Waits for `events` on `fd` up to `timeout`; Ok(true) when ready,
/// Ok(false) on timeout, Err on hang-up or error. EINTR counts as "not yet".
fn poll_fd(fd: impl AsFd, events: PollFlags, timeout: Duration) -> io::Result<bool> {
    let mut p = [PollFd::new(&fd, events)];
    let r = match rustix::event::poll(&mut p, Some(&super::poll_timeout(timeout))) {
        Ok(r) => r,
        Err(rustix::io::Errno::INTR) => return Ok(false),
        Err(e) => return Err(e.into()),
    };
    if r == 0 {
        return Ok(false);
    }
    let revents = p[0].revents();
    if revents.intersects(events) {
        return Ok(true);
    }
    if revents.intersects(PollFlags::HUP | PollFlags::ERR | PollFlags::NVAL) {
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
        Self::open_pair().map_err(PtyError::Create)
    }

    /// `openpty` from its parts: master and slave not the controlling
    /// terminal, as glibc's `openpty` opens them, and close-on-exec from
    /// the start (set afterwards when this was `openpty`).
    fn open_pair() -> io::Result<Pty> {
        let master =
            rustix::pty::openpt(OpenptFlags::RDWR | OpenptFlags::NOCTTY | OpenptFlags::CLOEXEC)?;
        rustix::pty::grantpt(&master)?;
        rustix::pty::unlockpt(&master)?;
        let name = rustix::pty::ptsname(&master, Vec::new())?;
        let slave = rustix::fs::open(
            name.as_c_str(),
            OFlags::RDWR | OFlags::NOCTTY | OFlags::CLOEXEC,
            Mode::empty(),
        )?;
        let mut t = rustix::termios::tcgetattr(&slave)?;
        t.make_raw();
        rustix::termios::tcsetattr(&slave, rustix::termios::OptionalActions::Now, &t)?;
        let fl = rustix::fs::fcntl_getfl(&master)?;
        rustix::fs::fcntl_setfl(&master, fl | OFlags::NONBLOCK)?;
        Ok(Pty {
            master,
            slave,
            slave_path: PathBuf::from(name.to_string_lossy().into_owned()),
            read_timeout: Duration::from_millis(10),
            write_timeout: Duration::from_secs(1),
        })
    }

    /// The slave device path (`/dev/pts/N`) a client opens.
    pub fn slave_path(&self) -> &Path {
        &self.slave_path
    }

    /// Bytes written to the client that it has not read yet (the slave's
    /// input queue): an emulator that pulls the plug waits for 0, as a
    /// real sensor's last reply has left the cable before the plug does.
    pub fn unread_by_client(&self) -> io::Result<u64> {
        Ok(rustix::io::ioctl_fionread(&self.slave)?)
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
        if !poll_fd(&self.master, PollFlags::IN, self.read_timeout)? {
            return Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "no bytes from the client",
            ));
        }
        match rustix::io::read(&self.master, buf) {
            Ok(n) => Ok(n),
            Err(rustix::io::Errno::AGAIN) => Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "no bytes from the client",
            )),
            Err(e) => Err(e.into()),
        }
    }
}

impl Write for Pty {
    /// Writes up to [`WRITE_CHUNK`] bytes, waiting up to the write timeout
    /// for room.
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = buf.len().min(WRITE_CHUNK);
        let deadline = Instant::now() + self.write_timeout;
        loop {
            let e = match rustix::io::write(&self.master, &buf[..n]) {
                Ok(r) => return Ok(r),
                Err(e) => io::Error::from(e),
            };
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
                    poll_fd(&self.master, PollFlags::OUT, deadline - now)?;
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
