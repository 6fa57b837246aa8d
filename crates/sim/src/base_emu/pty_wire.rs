//! The emulator's wire as a pseudo-terminal: the daemon opens the slave path
//! (or a symlink to it) exactly like a real `/dev/ttyACM0`; unplugging closes
//! the pty and removes the symlink, replugging makes a new one.

use std::io::{self, Read, Write};
use std::path::PathBuf;
use std::time::Duration;

use crate::base_emu::runner::EmuWire;
use crate::serial::{PtyError, PtyHost};

/// How long one emulator read waits for host bytes (wall time).
const READ_WAIT: Duration = Duration::from_millis(1);

/// A [`PtyHost`] as an emulator wire.
pub(crate) struct PtyWire {
    host: PtyHost,
}

impl PtyWire {
    /// Creates the pty, and the symlink `link` to it if given.
    pub fn new(link: Option<PathBuf>) -> Result<PtyWire, PtyError> {
        let mut host = PtyHost::new(link)?;
        if let Some(p) = host.pty() {
            p.set_read_timeout(READ_WAIT);
            p.set_write_timeout(Duration::from_millis(50));
        }
        Ok(PtyWire { host })
    }
}

impl EmuWire for PtyWire {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self.host.pty() {
            Some(p) => p.read(buf),
            None => Err(io::Error::new(io::ErrorKind::NotConnected, "unplugged")),
        }
    }
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        match self.host.pty() {
            Some(p) => crate::serial::write_chunked(p, bytes, 256).and_then(|_| p.flush()),
            None => Err(io::Error::new(io::ErrorKind::NotConnected, "unplugged")),
        }
    }
    fn unplug(&mut self) -> bool {
        self.host.unplug();
        true
    }
    fn replug(&mut self) -> io::Result<()> {
        self.host
            .replug()
            .map_err(|e| io::Error::other(e.to_string()))?;
        if let Some(p) = self.host.pty() {
            p.set_read_timeout(READ_WAIT);
            p.set_write_timeout(Duration::from_millis(50));
        }
        Ok(())
    }
    fn client_path(&self) -> Option<PathBuf> {
        self.host.client_path()
    }
}
