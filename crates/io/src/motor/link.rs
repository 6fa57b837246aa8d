//! The port under a wheel-base driver: opened through a [`LinkOpener`] (a tty,
//! an emulator's pty, a socket: anything `Read + Write`), closed when the
//! device goes away and re-opened at most once per reconnect interval.

use std::io::{self, Read, Write};
use std::time::Duration;

/// A byte link to the base. `read` returns `TimedOut`/`WouldBlock` when no byte
/// came within the port's read timeout; any other error, or `Ok(0)`, means the
/// device is gone.
pub trait ByteLink: Read + Write + Send {}

impl<T: Read + Write + Send + ?Sized> ByteLink for T {}

/// Opens (and re-opens) the base's port.
pub trait LinkOpener: Send {
    /// Opens the port with `read_timeout` (wall time) per read.
    fn open(&mut self, read_timeout: Duration) -> io::Result<Box<dyn ByteLink>>;
    /// The device's name for logs and errors.
    fn describe(&self) -> String;
}

/// A [`crate::serial::Connector`] (a tty path, a pty, a TCP socket) as the
/// wheel base's opener: the port is opened raw and exclusive, and re-opened
/// after the device went away.
pub struct ConnectorOpener(pub Box<dyn crate::serial::Connector>);

impl LinkOpener for ConnectorOpener {
    fn open(&mut self, read_timeout: Duration) -> io::Result<Box<dyn ByteLink>> {
        Ok(Box::new(self.0.open(read_timeout)?))
    }
    fn describe(&self) -> String {
        self.0.describe()
    }
}

/// What one read gave.
#[derive(Debug)]
pub enum ReadOutcome {
    /// This many bytes were read.
    Data(usize),
    /// Nothing arrived within the read timeout.
    Timeout,
    /// The device is gone; the port was closed.
    Gone,
}

/// A port that may be closed, with its reconnect schedule.
pub struct Link {
    opener: Box<dyn LinkOpener>,
    port: Option<Box<dyn ByteLink>>,
    read_timeout: Duration,
    reconnect_interval: f64,
    next_attempt: f64,
    last_open_error: Option<String>,
}

impl Link {
    /// A closed link; `reconnect_interval` (clock seconds) spaces open attempts.
    pub fn new(
        opener: Box<dyn LinkOpener>,
        read_timeout: Duration,
        reconnect_interval: f64,
    ) -> Self {
        Self {
            opener,
            port: None,
            read_timeout,
            reconnect_interval,
            next_attempt: f64::NEG_INFINITY,
            last_open_error: None,
        }
    }

    /// The device name.
    pub fn describe(&self) -> String {
        self.opener.describe()
    }

    /// Whether the port is open.
    pub(crate) fn is_open(&self) -> bool {
        self.port.is_some()
    }

    /// `Ok` when the port is open, else [`crate::motor::MotorError::NotConnected`]
    /// naming the device.
    pub(crate) fn require_open(&self) -> Result<(), crate::motor::MotorError> {
        if self.is_open() {
            Ok(())
        } else {
            Err(crate::motor::MotorError::NotConnected {
                device: self.describe(),
            })
        }
    }

    /// Opens the port if it is closed and an attempt is due at `now`; true
    /// when it was opened by this call.
    pub(crate) fn ensure_open(&mut self, now: f64) -> bool {
        if self.port.is_some() || now < self.next_attempt {
            return false;
        }
        self.next_attempt = now + self.reconnect_interval;
        match self.opener.open(self.read_timeout) {
            Ok(p) => {
                self.port = Some(p);
                self.last_open_error = None;
                log::info!("wheel base: opened {}", self.opener.describe());
                true
            }
            Err(e) => {
                let msg = e.to_string();
                if self.last_open_error.as_deref() != Some(&msg) {
                    log::warn!(
                        "wheel base: {msg}; retrying every {:.1} s",
                        self.reconnect_interval
                    );
                    self.last_open_error = Some(msg);
                }
                false
            }
        }
    }

    /// Closes the port (the device went away).
    pub fn close(&mut self) {
        if self.port.take().is_some() {
            log::warn!(
                "wheel base: {} went away; will re-open it",
                self.opener.describe()
            );
        }
    }

    /// Writes all of `bytes`; closes the port if the device is gone.
    pub fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let Some(p) = self.port.as_mut() else {
            return Err(io::Error::new(io::ErrorKind::NotConnected, "port closed"));
        };
        let r = p.write_all(bytes).and_then(|_| p.flush());
        if let Err(e) = &r {
            if gone(e) {
                self.close();
            }
        }
        r
    }

    /// Reads what is available (waiting at most the read timeout).
    pub fn read(&mut self, buf: &mut [u8]) -> ReadOutcome {
        let Some(p) = self.port.as_mut() else {
            return ReadOutcome::Gone;
        };
        loop {
            match p.read(buf) {
                Ok(0) => {
                    self.close();
                    return ReadOutcome::Gone;
                }
                Ok(n) => return ReadOutcome::Data(n),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) if !gone(&e) => return ReadOutcome::Timeout,
                Err(_) => {
                    self.close();
                    return ReadOutcome::Gone;
                }
            }
        }
    }

    /// Reads and throws away everything pending; returns how many bytes.
    pub fn drain(&mut self) -> u64 {
        let mut buf = [0u8; 64];
        let mut n = 0u64;
        for _ in 0..64 {
            match self.read(&mut buf) {
                ReadOutcome::Data(k) => n += k as u64,
                _ => break,
            }
        }
        n
    }
}

/// Whether an I/O error means the device is gone (not a mere timeout).
pub fn gone(e: &io::Error) -> bool {
    !matches!(
        e.kind(),
        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
    )
}
