//! An in-process link to the emulated sensor, without a pty or a thread:
//! the driver's writes go straight to [`Sensor::on_line`] and its reads
//! return the sensor's replies; when nothing is pending, reading moves a
//! shared [`ManualClock`] to the next scan. Deterministic and lock-step: for
//! the time-scaled simulator, benchmarks and allocation tests. (Tests of the
//! byte path use the real pty instead.)

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::sync::Arc;
use std::time::Duration;

use super::sensor::Sensor;
use crate::clock::{Clock, ManualClock};
use crate::scip::{LineEvent, LineFramer};
use crate::serial::Port;

/// The sensor behind a [`Port`].
pub struct SensorLink {
    sensor: Sensor,
    clock: Arc<ManualClock>,
    framer: LineFramer,
    line: Vec<u8>,
    inbox: VecDeque<u8>,
    out: Vec<u8>,
    read_timeout: f64,
}

impl SensorLink {
    /// Wraps `sensor`, whose time is `clock` (shared with the driver).
    pub fn new(sensor: Sensor, clock: Arc<ManualClock>) -> Self {
        Self {
            sensor,
            clock,
            framer: LineFramer::new(),
            line: Vec::with_capacity(256),
            inbox: VecDeque::with_capacity(16 * 1024),
            out: Vec::with_capacity(16 * 1024),
            read_timeout: 0.01,
        }
    }

    /// The sensor.
    pub fn sensor(&mut self) -> &mut Sensor {
        &mut self.sensor
    }

    fn pull(&mut self) {
        self.sensor.poll(self.clock.now(), &mut self.out);
        self.inbox.extend(self.out.iter().copied());
        self.out.clear();
    }
}

impl Read for SensorLink {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.inbox.is_empty() {
            self.pull();
        }
        if self.inbox.is_empty() {
            let now = self.clock.now();
            match self.sensor.next_due() {
                Some(t) if t <= now + self.read_timeout => {
                    self.clock.set(t);
                    self.pull();
                }
                _ => {
                    self.clock.advance(self.read_timeout);
                    return Err(io::ErrorKind::TimedOut.into());
                }
            }
        }
        let (a, b) = self.inbox.as_slices();
        let src = if a.is_empty() { b } else { a };
        let n = buf.len().min(src.len());
        buf[..n].copy_from_slice(&src[..n]);
        self.inbox.drain(..n);
        Ok(n)
    }
}

impl Write for SensorLink {
    fn write(&mut self, data: &[u8]) -> io::Result<usize> {
        let now = self.clock.now();
        for &b in data {
            if let Some(LineEvent::Line(l)) = self.framer.push(b) {
                self.line.clear();
                self.line.extend_from_slice(l);
                self.sensor.on_line(&self.line, now, &mut self.out);
            }
        }
        self.inbox.extend(self.out.iter().copied());
        self.out.clear();
        Ok(data.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Port for SensorLink {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.read_timeout = timeout.as_secs_f64();
        Ok(())
    }
    fn discard_input(&mut self) -> io::Result<()> {
        self.inbox.clear();
        Ok(())
    }
    fn describe(&self) -> String {
        "emulated URG (in-process link)".to_string()
    }
}
