//! Health counters of the scanner driver, shared lock-free (atomics in an
//! `Arc`) with the rest of the daemon, plus a plain snapshot for printing.

use std::fmt;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};

/// Live counters, updated by the driver thread, read by anyone.
#[derive(Debug, Default)]
pub struct UrgHealth {
    /// Scans delivered.
    pub scans: AtomicU64,
    /// Lines whose checksum did not match.
    pub checksum_errors: AtomicU64,
    /// Framing losses (unexpected line, overlong line, wrong echo).
    pub desyncs: AtomicU64,
    /// Scan replies received but thrown away (bad checksum, wrong value count).
    pub discarded_scans: AtomicU64,
    /// Scans the sensor measured but we never received (timestamp gaps).
    pub dropped_scans: AtomicU64,
    /// Times the sensor clock repeated or went backwards (stuck clock).
    pub stuck_clock: AtomicU64,
    /// Read timeouts that triggered "QT, drain, restart".
    pub timeouts: AtomicU64,
    /// Stream restarts.
    pub restarts: AtomicU64,
    /// RS resets sent after repeated failures.
    pub resets: AtomicU64,
    /// Re-opens of the port after it went away or was reset.
    pub reconnects: AtomicU64,
    /// Reboots (RB RB) sent as the last resort.
    pub reboots: AtomicU64,
    /// Scans dropped because the consumer was slow (newest wins).
    pub(crate) queue_overflows: AtomicU64,
    /// Last non-OK status code from the sensor, as two ASCII bytes (0 = none).
    pub last_status: AtomicU64,
    /// Whether the port is open and streaming.
    pub streaming: AtomicBool,
    /// Sensor-minus-host clock offset (s), f64 bits.
    pub(crate) clock_offset: AtomicU64,
    /// Sensor clock rate error relative to the host (ppm), f64 bits.
    pub clock_drift_ppm: AtomicU64,
}

impl UrgHealth {
    /// Adds one to a counter.
    pub fn bump(c: &AtomicU64) {
        c.fetch_add(1, Relaxed);
    }

    /// Records a non-OK status code (two ASCII characters).
    pub(crate) fn set_status(&self, code: [u8; 2]) {
        self.last_status
            .store(u64::from(code[0]) << 8 | u64::from(code[1]), Relaxed);
    }

    /// Records the current clock model.
    pub(crate) fn set_clock(&self, offset: f64, drift_ppm: f64) {
        self.clock_offset.store(offset.to_bits(), Relaxed);
        self.clock_drift_ppm.store(drift_ppm.to_bits(), Relaxed);
    }

    /// A consistent-enough copy of every counter.
    pub fn snapshot(&self) -> HealthSnapshot {
        let s = self.last_status.load(Relaxed);
        HealthSnapshot {
            scans: self.scans.load(Relaxed),
            checksum_errors: self.checksum_errors.load(Relaxed),
            desyncs: self.desyncs.load(Relaxed),
            discarded_scans: self.discarded_scans.load(Relaxed),
            dropped_scans: self.dropped_scans.load(Relaxed),
            stuck_clock: self.stuck_clock.load(Relaxed),
            timeouts: self.timeouts.load(Relaxed),
            restarts: self.restarts.load(Relaxed),
            resets: self.resets.load(Relaxed),
            reconnects: self.reconnects.load(Relaxed),
            reboots: self.reboots.load(Relaxed),
            queue_overflows: self.queue_overflows.load(Relaxed),
            last_status: (s != 0).then_some([(s >> 8) as u8, s as u8]),
            streaming: self.streaming.load(Relaxed),
            clock_offset: f64::from_bits(self.clock_offset.load(Relaxed)),
            clock_drift_ppm: f64::from_bits(self.clock_drift_ppm.load(Relaxed)),
        }
    }
}

/// A copy of [`UrgHealth`] at one moment.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HealthSnapshot {
    /// Scans delivered.
    pub scans: u64,
    /// Lines with a bad checksum.
    pub checksum_errors: u64,
    /// Framing losses.
    pub desyncs: u64,
    /// Scan replies thrown away.
    pub discarded_scans: u64,
    /// Scans missing from the timestamp sequence.
    pub dropped_scans: u64,
    /// Repeated or backwards sensor timestamps.
    pub stuck_clock: u64,
    /// Read timeouts.
    pub timeouts: u64,
    /// Stream restarts.
    pub restarts: u64,
    /// RS resets.
    pub resets: u64,
    /// Port re-opens.
    pub reconnects: u64,
    /// Reboots (RB RB).
    pub reboots: u64,
    /// Scans dropped for a slow consumer.
    pub(crate) queue_overflows: u64,
    /// Last non-OK status code.
    pub last_status: Option<[u8; 2]>,
    /// Port open and streaming.
    pub streaming: bool,
    /// Sensor-minus-host clock offset (s).
    pub(crate) clock_offset: f64,
    /// Sensor clock rate error (ppm).
    pub clock_drift_ppm: f64,
}

impl fmt::Display for HealthSnapshot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "scans delivered      {}", self.scans)?;
        writeln!(f, "checksum errors      {}", self.checksum_errors)?;
        writeln!(f, "desyncs              {}", self.desyncs)?;
        writeln!(f, "discarded scans      {}", self.discarded_scans)?;
        writeln!(f, "dropped scans (gaps) {}", self.dropped_scans)?;
        writeln!(f, "stuck-clock events   {}", self.stuck_clock)?;
        writeln!(f, "timeouts             {}", self.timeouts)?;
        writeln!(f, "stream restarts      {}", self.restarts)?;
        writeln!(f, "resets (RS)          {}", self.resets)?;
        writeln!(f, "reconnects           {}", self.reconnects)?;
        writeln!(f, "reboots (RB RB)      {}", self.reboots)?;
        writeln!(f, "queue overflows      {}", self.queue_overflows)?;
        match self.last_status {
            Some(c) => writeln!(
                f,
                "last bad status      {}{} ({})",
                c[0] as char,
                c[1] as char,
                super::status_meaning(c)
            )?,
            None => writeln!(f, "last bad status      none")?,
        }
        write!(
            f,
            "clock                sensor - host = {:.4} s, drift {:.1} ppm",
            self.clock_offset, self.clock_drift_ppm
        )
    }
}
