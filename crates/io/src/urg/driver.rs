//! The scanner stage: a reader thread that owns the port, runs sessions and
//! the recovery ladder, and publishes scans into a bounded channel where the
//! newest scan wins (the oldest is dropped when the consumer lags).
//!
//! Recovery ladder:
//! 1. no scan in time (or a refused restart): QT, drain, restart the stream;
//! 2. `failures_before_reset` failures in a row: RS, close, re-open;
//! 3. the link is gone (hang-up, EIO, path vanished): close, wait for the
//!    path to come back, re-open with exponential back-off;
//!
//! EINTR is retried everywhere; shutdown sends QT (and TM2 if needed).
//!
//! The reader thread is the driver's own thread edge: it holds the injected
//! clock for its back-off pauses, the resync interval and the session's
//! blocking reads (see [`UrgSession`]). Nothing outside the thread calls
//! into it: the scanner stage only takes scans off the channel.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender, TrySendError};

use super::health::UrgHealth;
use super::session::{SessionInfo, UrgError, UrgSession};
use super::UrgParams;
use crate::capacity::MAX_BEAMS;
use crate::clock::Clock;
use crate::scan::LaserScan;
use crate::scip::{ModelFamily, Reading};
use crate::serial::Connector;

/// One scan as the driver publishes it: the algorithms' [`LaserScan`]
/// (angles from PP, metres, host-clock stamp, invalid beams flagged) plus
/// what only the scanner knows.
///
/// `scan.stamp` is the host time (injected clock, s) at which the sensor's
/// clock read `raw_stamp`, through the TM-fitted clock model (arrival time
/// if clock sync is off). Taking that as the time of the first step, beam
/// `k` was measured about `k × cluster × time_per_step` later; use it to
/// deskew scans taken while moving.
#[derive(Clone, Debug)]
pub struct UrgScan {
    /// The scan for the algorithms.
    pub scan: LaserScan,
    /// Per beam, the typed reading: a range, an error code with its meaning,
    /// or beyond DMAX (why an invalid beam is invalid).
    pub readings: heapless::Vec<Reading, MAX_BEAMS>,
    /// The 24-bit timestamp as the sensor sent it (ms).
    pub raw_stamp: u32,
    /// The sensor clock unwrapped over 2^24 ms wraps (ms, within one epoch).
    pub sensor_ms: u64,
    /// Sensor clock epoch: increases when the clock restarted (RS, replug).
    pub epoch: u32,
    /// Scans missing just before this one (timestamp gap).
    pub dropped_before: u64,
    /// Time between neighbouring steps (s), for deskewing during motion.
    pub time_per_step: f64,
    /// Time between two delivered scans (s): the sensor's scan period times
    /// (skip + 1); a longer gap between stamps means scans were lost.
    pub interval: f64,
    /// Error-code table of the sensor.
    pub family: ModelFamily,
}

impl Default for UrgScan {
    fn default() -> Self {
        Self {
            scan: LaserScan::default(),
            readings: heapless::Vec::new(),
            raw_stamp: 0,
            sensor_ms: 0,
            epoch: 0,
            dropped_before: 0,
            time_per_step: 0.0,
            interval: 0.0,
            family: ModelFamily::Unknown,
        }
    }
}

/// Sends into a bounded channel, dropping the oldest message when full
/// (newest wins); returns false when the receiver is gone.
fn send_newest(
    tx: &Sender<UrgScan>,
    rx: &Receiver<UrgScan>,
    scan: &UrgScan,
    h: &UrgHealth,
) -> bool {
    let mut msg = scan.clone();
    loop {
        match tx.try_send(msg) {
            Ok(()) => return true,
            Err(TrySendError::Full(m)) => {
                msg = m;
                if rx.try_recv().is_ok() {
                    UrgHealth::bump(&h.queue_overflows);
                }
            }
            Err(TrySendError::Disconnected(_)) => return false,
        }
    }
}

/// The running scanner stage.
pub struct UrgDriver {
    scans: Receiver<UrgScan>,
    health: Arc<UrgHealth>,
    info: Arc<Mutex<Option<Arc<SessionInfo>>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl UrgDriver {
    /// Starts the reader thread on `connector`. It opens (and keeps
    /// re-opening) the device by itself; watch [`UrgDriver::health`].
    /// Fails at once only on out-of-range `params`.
    pub fn start(
        connector: Box<dyn Connector>,
        params: UrgParams,
        clock: Arc<dyn Clock>,
    ) -> Result<UrgDriver, UrgError> {
        params.validate().map_err(UrgError::Config)?;
        let (tx, rx) = crossbeam_channel::bounded(params.queue.max(1));
        let health = Arc::new(UrgHealth::default());
        let info = Arc::new(Mutex::new(None));
        let stop = Arc::new(AtomicBool::new(false));
        let worker = Worker {
            connector,
            params,
            clock,
            health: health.clone(),
            info: info.clone(),
            stop: stop.clone(),
            tx,
            rx: rx.clone(),
        };
        let thread = std::thread::Builder::new()
            .name("scanner".into())
            .spawn(move || worker.run())
            .map_err(|source| UrgError::Io {
                port: "scanner thread".into(),
                source,
            })?;
        Ok(UrgDriver {
            scans: rx,
            health,
            info,
            stop,
            thread: Some(thread),
        })
    }

    /// The scan channel (bounded; newest wins).
    pub fn scans(&self) -> &Receiver<UrgScan> {
        &self.scans
    }

    /// The live health counters.
    pub fn health(&self) -> Arc<UrgHealth> {
        self.health.clone()
    }

    /// What the sensor is, once the first open succeeded.
    pub fn info(&self) -> Option<Arc<SessionInfo>> {
        self.info.lock().ok().and_then(|g| g.clone())
    }

    /// Stops the stream (QT), closes the port and joins the thread.
    pub fn shutdown(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for UrgDriver {
    fn drop(&mut self) {
        self.halt();
    }
}

struct Worker {
    connector: Box<dyn Connector>,
    params: UrgParams,
    clock: Arc<dyn Clock>,
    health: Arc<UrgHealth>,
    info: Arc<Mutex<Option<Arc<SessionInfo>>>>,
    stop: Arc<AtomicBool>,
    tx: Sender<UrgScan>,
    rx: Receiver<UrgScan>,
}

impl Worker {
    fn stopping(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    fn pause(&self, dt: f64) {
        let end = self.clock.now() + dt;
        while !self.stopping() && self.clock.now() < end {
            self.clock
                .sleep((end - self.clock.now()).clamp(0.0, 0.01 * self.clock.speed()));
        }
    }

    fn known(&self) -> Option<Arc<SessionInfo>> {
        self.info.lock().ok().and_then(|g| g.clone())
    }

    fn run(mut self) {
        let mut backoff = self.params.reconnect_min;
        let mut failures = 0u32;
        let mut opened_before = false;
        let mut epoch = 0u32;
        let mut reset_next = false;
        while !self.stopping() {
            if !self.connector.present() {
                self.pause(backoff);
                backoff = (backoff * 2.0).min(self.params.reconnect_max);
                continue;
            }
            let port = match self.connector.open(std::time::Duration::from_secs_f64(
                self.params.poll.clamp(0.001, 1.0),
            )) {
                Ok(p) => p,
                Err(e) => {
                    log::warn!("scanner: cannot open {}: {e}", self.connector.describe());
                    self.pause(backoff);
                    backoff = (backoff * 2.0).min(self.params.reconnect_max);
                    continue;
                }
            };
            if opened_before {
                UrgHealth::bump(&self.health.reconnects);
            }
            opened_before = true;
            let (tx, rx, h) = (self.tx.clone(), self.rx.clone(), self.health.clone());
            let sink = Box::new(move |s: &super::UrgScan| {
                send_newest(&tx, &rx, s, &h);
            });
            let mut session = match UrgSession::open(
                port,
                self.params.clone(),
                self.clock.clone(),
                self.health.clone(),
                self.stop.clone(),
                self.known(),
                sink,
            ) {
                Ok(s) => s,
                Err(UrgError::Stopped) => break,
                Err(e) => {
                    log::warn!("scanner: open failed: {e}");
                    failures += 1;
                    self.pause(backoff);
                    backoff = (backoff * 2.0).min(self.params.reconnect_max);
                    continue;
                }
            };
            // A new session means a new clock epoch (the sensor may have rebooted).
            epoch += 1;
            session.set_epoch(epoch);
            if let (Ok(mut g), Some(i)) = (self.info.lock(), session.info()) {
                if g.is_none() {
                    log::info!(
                        "scanner: {} firmware {} serial {} on {}",
                        i.version.product,
                        i.version.firmware,
                        i.version.serial,
                        self.connector.describe()
                    );
                }
                *g = Some(i);
            }
            if reset_next {
                reset_next = false;
                UrgHealth::bump(&self.health.resets);
                if let Err(e) = session
                    .reset()
                    .and_then(|_| session.sync_clock().map(|_| ()))
                {
                    log::warn!("scanner: reset failed: {e}");
                }
                epoch = session.epoch();
            }
            let r = self.stream(&mut session, &mut failures, &mut backoff);
            epoch = epoch.max(session.epoch());
            match r {
                Ok(()) => {
                    session.shutdown();
                    break;
                }
                Err(UrgError::Stopped) => {
                    session.shutdown();
                    break;
                }
                Err(e) if e.link_gone() => {
                    log::warn!("scanner: {e}; waiting for the device to come back");
                    self.health.streaming.store(false, Ordering::Relaxed);
                    drop(session);
                    self.pause(backoff);
                    backoff = (backoff * 2.0).min(self.params.reconnect_max);
                }
                Err(e) => {
                    log::warn!("scanner: {e}; resetting the sensor (RS) and re-opening");
                    self.health.streaming.store(false, Ordering::Relaxed);
                    reset_next = true;
                    failures = 0;
                    drop(session);
                }
            }
        }
        self.health.streaming.store(false, Ordering::Relaxed);
    }

    /// Streams until stopped, the link goes, or failures pile up (rung 2).
    fn stream(
        &self,
        session: &mut UrgSession,
        failures: &mut u32,
        backoff: &mut f64,
    ) -> Result<(), UrgError> {
        let mut started = session.start_stream().map(|_| true);
        loop {
            if self.stopping() {
                return Err(UrgError::Stopped);
            }
            let r = match started {
                Ok(true) => session.next_scan(),
                Ok(false) => {
                    UrgHealth::bump(&self.health.restarts);
                    session.restart_stream()
                }
                Err(e) => Err(e),
            };
            started = Ok(true);
            match r {
                Ok(()) => {
                    *failures = 0;
                    *backoff = self.params.reconnect_min;
                    if self.params.resync_interval > 0.0
                        && self.clock.now() - session.last_sync() > self.params.resync_interval
                    {
                        if let Err(e) = session.resync() {
                            started = Err(e);
                        }
                    }
                }
                Err(e) if e.link_gone() || matches!(e, UrgError::Stopped) => return Err(e),
                Err(e) => {
                    *failures += 1;
                    if matches!(e, UrgError::ScanTimeout { .. }) {
                        UrgHealth::bump(&self.health.timeouts);
                    }
                    log::warn!(
                        "scanner: {e} (failure {} of {})",
                        failures,
                        self.params.failures_before_reset
                    );
                    if *failures >= self.params.failures_before_reset {
                        return Err(e);
                    }
                    started = Ok(false);
                }
            }
        }
    }
}
