//! One open connection to a URG, used synchronously by one thread: robust
//! open, identity (PP, VV, II once), TM clock sync, MD streaming, scan
//! decoding and stamping. Every byte goes through the sans-IO
//! [`crate::scip::Decoder`]; any valid scan that arrives, whatever the session
//! is waiting for (a QT echo, a TM reply), is decoded and handed to the sink,
//! so recovery never throws good scans away.
//!
//! The session blocks in its reads, so it reads the injected clock itself,
//! for three things only: a reply or scan deadline turned into the read's
//! wall-clock timeout, the arrival time that stamps a reply or a scan, and
//! the TM round trips of the clock sync. Each is a measurement of the link
//! that a `now` handed in before the read could not give. It runs on the
//! driver's reader thread, whose loop is that thread's edge.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use super::driver::UrgScan;
use super::fill::fill_laser_scan;
use super::health::UrgHealth;
use super::timesync::{continuity, ClockModel, Continuity, SyncHistory, TimeSample};
use super::UrgParams;
use crate::clock::Clock;
use crate::scip::{
    ClockUnwrapper, Cluster, Command, CommandKind, DataKind, Decoder, DecoderOptions, Event,
    FrameError, RawReply, ReplyBody, ScanRequest, SensorInfo, SensorParams, Status, StatusCode,
    StreamRequest, TaggedCommand, VersionInfo,
};
use crate::serial::{is_link_gone, write_chunked, Port};

/// What the sensor said about itself, asked once per driver.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionInfo {
    /// VV: vendor, product, firmware, protocol, serial.
    pub version: VersionInfo,
    /// PP: model, ranges, step geometry, speed.
    pub params: SensorParams,
    /// II: laser, modes, clock, state (asked at most once; `None` if refused).
    pub info: Option<SensorInfo>,
}

/// Why the session failed; the driver's recovery ladder branches on it.
#[derive(Debug, thiserror::Error)]
pub enum UrgError {
    /// The link failed (device unplugged, hang-up, EIO): close and re-open.
    #[error("scanner link {port}: {source}")]
    Io {
        /// The port.
        port: String,
        /// The OS error.
        source: io::Error,
    },
    /// No reply to a command within the reply timeout.
    #[error("no reply to {command} within {timeout:.2} s")]
    NoResponse {
        /// The command line sent.
        command: String,
        /// The wait (s).
        timeout: f64,
    },
    /// The sensor refused a command.
    #[error("{command} refused with status {status} ({meaning})")]
    Refused {
        /// The command line sent.
        command: String,
        /// The status code.
        status: String,
        /// What it means.
        meaning: &'static str,
    },
    /// A reply arrived intact but its content is unusable.
    #[error("bad reply to {command}: {reason}")]
    BadReply {
        /// The command line sent.
        command: String,
        /// What was wrong.
        reason: String,
    },
    /// No scan arrived in time while streaming.
    #[error("no scan for {waited:.2} s (expected one every {interval:.3} s)")]
    ScanTimeout {
        /// How long we waited (s).
        waited: f64,
        /// Expected interval (s).
        interval: f64,
    },
    /// The sensor still speaks SCIP 1.1 after the switch.
    #[error("sensor did not switch to SCIP 2.0")]
    NotScip2,
    /// Shutdown was requested.
    #[error("driver is shutting down")]
    Stopped,
    /// A `[scanner]` setting is out of range.
    #[error("bad scanner setting: {0}")]
    Config(String),
}

impl UrgError {
    /// Whether the device is gone and must be re-opened (rung 3 of the ladder).
    pub(crate) fn link_gone(&self) -> bool {
        matches!(self, UrgError::Io { .. })
    }
}

#[derive(Clone, Debug)]
enum Body {
    Empty,
    Version(VersionInfo),
    Params(SensorParams),
    Info(SensorInfo),
    Time(u32),
}

#[derive(Clone, Debug)]
struct Got {
    status: Status,
    body: Result<Body, String>,
    at: f64,
}

/// State that event handling touches (kept apart from the decoder so both
/// can be borrowed at once).
struct Core {
    clock: Arc<dyn Clock>,
    health: Arc<UrgHealth>,
    params: UrgParams,
    info: Option<Arc<SessionInfo>>,
    expect: Vec<u8>,
    waiting: bool,
    got: Option<Got>,
    unwrap: ClockUnwrapper,
    prev_ms: Option<u64>,
    model: Option<ClockModel>,
    history: SyncHistory,
    seq: u64,
    epoch: u32,
    scan: Box<UrgScan>,
    new_scan: bool,
    last_scan_at: f64,
    streaming: Option<StreamRequest>,
    dropped_seen: u64,
    /// The sensor refused its intensity mode: plain distances from then on.
    no_intensity: bool,
    sink: Box<dyn FnMut(&UrgScan) + Send>,
}

/// An open, identified connection to one sensor.
pub struct UrgSession {
    port: Box<dyn Port>,
    name: String,
    dec: Decoder,
    core: Core,
    stop: Arc<AtomicBool>,
    buf: Box<[u8; 4096]>,
    tx: Vec<u8>,
    in_adjust: bool,
    closing: bool,
    read_timeout_ms: u64,
    tm_tag: u32,
    last_sync: f64,
}

impl UrgSession {
    /// Opens a session on `port`: flush, LF, QT (switching a SCIP 1.1 sensor
    /// to 2.0, leaving time-adjust mode, draining a running stream), then
    /// PP, VV and II unless `known` already holds them, then a TM clock sync.
    /// Scans that arrive meanwhile go to `sink` once PP is known.
    pub fn open(
        mut port: Box<dyn Port>,
        params: UrgParams,
        clock: Arc<dyn Clock>,
        health: Arc<UrgHealth>,
        stop: Arc<AtomicBool>,
        known: Option<Arc<SessionInfo>>,
        sink: Box<dyn FnMut(&UrgScan) + Send>,
    ) -> Result<UrgSession, UrgError> {
        let name = port.describe();
        let poll = std::time::Duration::from_secs_f64(params.poll.clamp(0.001, 1.0));
        port.set_read_timeout(poll).map_err(|source| UrgError::Io {
            port: name.clone(),
            source,
        })?;
        let now = clock.now();
        let mut s = UrgSession {
            port,
            name,
            dec: Decoder::new(DecoderOptions {
                lenient_kv: params.lenient_info,
            }),
            core: Core {
                clock,
                health,
                params,
                info: known,
                expect: Vec::with_capacity(64),
                waiting: false,
                got: None,
                unwrap: ClockUnwrapper::new(),
                prev_ms: None,
                model: None,
                history: SyncHistory::default(),
                seq: 0,
                epoch: 0,
                scan: Box::default(),
                new_scan: false,
                last_scan_at: now,
                streaming: None,
                dropped_seen: 0,
                no_intensity: false,
                sink,
            },
            stop,
            buf: Box::new([0u8; 4096]),
            tx: Vec::with_capacity(64),
            in_adjust: false,
            closing: false,
            read_timeout_ms: 0,
            tm_tag: 0,
            last_sync: now,
        };
        s.handshake()?;
        if s.core.info.is_none() {
            s.identify()?;
        }
        if s.core.params.time_sync_samples > 0 {
            s.sync_clock()?;
        }
        Ok(s)
    }

    /// What the sensor is (PP, VV, II).
    pub fn info(&self) -> Option<Arc<SessionInfo>> {
        self.core.info.clone()
    }

    /// The current sensor-to-host clock model, if synced.
    pub fn clock_model(&self) -> Option<ClockModel> {
        self.core.model
    }

    /// Host time of the last clock sync (s).
    pub(crate) fn last_sync(&self) -> f64 {
        self.last_sync
    }

    /// Whether an MD/ME stream is running.
    pub fn streaming(&self) -> bool {
        self.core.streaming.is_some()
    }

    /// Sensor clock epoch: increases after RS (the clock restarted at 0).
    pub fn epoch(&self) -> u32 {
        self.core.epoch
    }

    /// Sets the first epoch (the driver keeps counting over re-opens).
    pub(crate) fn set_epoch(&mut self, epoch: u32) {
        self.core.epoch = epoch;
    }

    fn io_err(&self, source: io::Error) -> UrgError {
        UrgError::Io {
            port: self.name.clone(),
            source,
        }
    }

    fn write_line(&mut self, line: &[u8]) -> Result<(), UrgError> {
        self.tx.clear();
        self.tx.extend_from_slice(line);
        self.tx.push(b'\n');
        loop {
            match write_chunked(&mut *self.port, &self.tx, 64) {
                Ok(()) => return Ok(()),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) if !is_link_gone(&e) => {
                    return Err(UrgError::NoResponse {
                        command: String::from_utf8_lossy(line).into_owned(),
                        timeout: self.core.params.reply_timeout,
                    })
                }
                Err(e) => return Err(self.io_err(e)),
            }
        }
    }

    /// Reads and decodes until `done` holds or the clock passes `deadline`;
    /// Ok(true) if `done` held.
    fn pump(&mut self, deadline: f64, done: fn(&Core) -> bool) -> Result<bool, UrgError> {
        loop {
            if done(&self.core) {
                return Ok(true);
            }
            if !self.closing && self.stop.load(Ordering::Relaxed) {
                return Err(UrgError::Stopped);
            }
            let now = self.core.clock.now();
            if now >= deadline {
                return Ok(false);
            }
            // Sleep in the read until the deadline, but wake at least every
            // `poll` seconds to notice a shutdown request.
            let rate = self.core.clock.speed().max(1e-9);
            let wait =
                ((deadline - now) / rate).clamp(0.001, self.core.params.poll.clamp(0.001, 1.0));
            let wait_ms = (wait * 1e3).ceil() as u64;
            if wait_ms != self.read_timeout_ms {
                self.read_timeout_ms = wait_ms;
                let _ = self
                    .port
                    .set_read_timeout(std::time::Duration::from_millis(wait_ms));
            }
            match self.port.read(&mut self.buf[..]) {
                Ok(0) => {
                    return Err(self.io_err(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "device closed the link",
                    )))
                }
                Ok(n) => {
                    let mut rest = &self.buf[..n];
                    while !rest.is_empty() {
                        let (used, ev) = self.dec.feed(rest);
                        rest = &rest[used..];
                        if let Some(ev) = ev {
                            self.core.on_event(ev);
                            // A reply the decoder dropped while streaming is
                            // a scan we lost (noise between replies is not).
                            let dropped = self.dec.stats().dropped_replies;
                            let new = dropped - self.core.dropped_seen.min(dropped);
                            self.core.dropped_seen = dropped;
                            if new > 0 && self.core.streaming.is_some() {
                                self.core
                                    .health
                                    .discarded_scans
                                    .fetch_add(new, Ordering::Relaxed);
                            }
                        }
                    }
                }
                Err(e) if !is_link_gone(&e) => {}
                Err(e) => return Err(self.io_err(e)),
            }
        }
    }

    /// Reads and throws away input until the line is quiet for `quiet` s
    /// (at most `max` s), then forgets any partial reply.
    fn drain_quiet(&mut self, quiet: f64, max: f64) -> Result<(), UrgError> {
        let start = self.core.clock.now();
        let mut last = start;
        loop {
            if self.stop.load(Ordering::Relaxed) {
                return Err(UrgError::Stopped);
            }
            let now = self.core.clock.now();
            if now - last >= quiet || now - start >= max {
                break;
            }
            match self.port.read(&mut self.buf[..]) {
                Ok(0) => {
                    return Err(self.io_err(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "device closed the link",
                    )))
                }
                Ok(_) => last = self.core.clock.now(),
                Err(e) if !is_link_gone(&e) => {}
                Err(e) => return Err(self.io_err(e)),
            }
        }
        self.dec.reset();
        Ok(())
    }

    /// Sends one command line and waits for its reply (matched by exact echo).
    fn command(&mut self, line: &[u8]) -> Result<(Status, Result<Body, String>, f64), UrgError> {
        self.core.expect.clear();
        self.core.expect.extend_from_slice(line);
        self.core.got = None;
        self.core.waiting = true;
        self.write_line(line)?;
        let timeout = self.core.params.reply_timeout;
        let deadline = self.core.clock.now() + timeout;
        let r = self.pump(deadline, |c| c.got.is_some());
        self.core.waiting = false;
        r?;
        match self.core.got.take() {
            Some(g) => Ok((g.status, g.body, g.at)),
            None => Err(UrgError::NoResponse {
                command: String::from_utf8_lossy(line).into_owned(),
                timeout,
            }),
        }
    }

    fn refused(line: &[u8], status: Status, kind: CommandKind) -> UrgError {
        UrgError::Refused {
            command: String::from_utf8_lossy(line).into_owned(),
            status: match status {
                Status::Scip2(c) => c.as_str().to_string(),
                Status::Scip1(b) => (b as char).to_string(),
            },
            meaning: status.meaning(kind),
        }
    }

    /// Sends a command that must succeed and carries no data.
    fn simple(&mut self, line: &[u8], kind: CommandKind) -> Result<Status, UrgError> {
        let (status, _, _) = self.command(line)?;
        if let Status::Scip2(c) = status {
            if !c.is_success(kind) {
                self.core.health.set_status(c.0);
                return Err(Self::refused(line, status, kind));
            }
        }
        Ok(status)
    }

    /// LF, then QT until the sensor answers `00` in SCIP 2.0.
    fn handshake(&mut self) -> Result<(), UrgError> {
        let _ = self.port.discard_input();
        self.write_line(b"")?;
        self.drain_quiet(0.05, 0.3)?;
        let mut switched = false;
        for _ in 0..5 {
            match self.command(b"QT") {
                Ok((Status::Scip2(StatusCode::OK), _, _)) => return Ok(()),
                Ok((Status::Scip1(_), _, _)) => {
                    if switched {
                        return Err(UrgError::NotScip2);
                    }
                    log::info!(
                        "{}: sensor speaks SCIP 1.1, switching to SCIP 2.0",
                        self.name
                    );
                    switched = true;
                    let _ = self.command(b"SCIP2.0")?;
                }
                Ok((Status::Scip2(StatusCode::UNDEFINED), _, _)) => {
                    log::info!(
                        "{}: sensor is in time-adjust mode, leaving it (TM2)",
                        self.name
                    );
                    let _ = self.command(b"TM2")?;
                }
                Ok((Status::Scip2(c), _, _)) => {
                    self.core.health.set_status(c.0);
                    log::warn!(
                        "{}: QT answered {} ({})",
                        self.name,
                        c.as_str(),
                        c.meaning(CommandKind::Qt)
                    );
                }
                Err(UrgError::NoResponse { .. }) => {
                    // A stream still pouring, or a desync: drain and retry.
                    self.drain_quiet(0.05, 0.3)?;
                }
                Err(e) => return Err(e),
            }
        }
        // Before giving up: RS stops everything and resets the sensor's
        // modes (as hokuyo_node does), then one more QT.
        log::warn!("{}: no answer to QT, trying RS", self.name);
        UrgHealth::bump(&self.core.health.resets);
        self.drain_quiet(0.05, 0.3)?;
        if self.quiet_command(b"RS")? && self.quiet_command(b"QT")? {
            return Ok(());
        }
        // Last resort: RB twice within a second reboots the sensor (the
        // only cure for firmware that stops answering, urg_c #9).
        if self.core.params.reboot_last_resort {
            log::warn!(
                "{}: no answer to RS either, rebooting the sensor (RB RB)",
                self.name
            );
            UrgHealth::bump(&self.core.health.reboots);
            let _ = self.quiet_command(b"RB")?;
            let _ = self.quiet_command(b"RB")?;
            let wait = self.core.params.reboot_wait;
            self.drain_quiet(wait, wait)?;
            if self.quiet_command(b"QT")? {
                return Ok(());
            }
        }
        Err(UrgError::NoResponse {
            command: "QT".into(),
            timeout: self.core.params.reply_timeout,
        })
    }

    /// Sends a command; Ok(true) if it was answered with success, Ok(false)
    /// if unanswered or refused; Err only for a gone link or shutdown.
    fn quiet_command(&mut self, line: &[u8]) -> Result<bool, UrgError> {
        match self.command(line) {
            Ok((status, _, _)) => Ok(match status {
                Status::Scip2(c) => c == StatusCode::OK || (line == b"RB" && c.0 == *b"01"),
                Status::Scip1(_) => false,
            }),
            Err(e) if e.link_gone() || matches!(e, UrgError::Stopped) => Err(e),
            Err(_) => Ok(false),
        }
    }

    /// PP (required, validated), VV, and II once.
    fn identify(&mut self) -> Result<(), UrgError> {
        let params = match self.command(b"PP")? {
            (s, _, _) if !s.is_success(CommandKind::Pp) => {
                return Err(Self::refused(b"PP", s, CommandKind::Pp))
            }
            (_, Ok(Body::Params(p)), _) => p,
            (_, Err(reason), _) => {
                return Err(UrgError::BadReply {
                    command: "PP".into(),
                    reason,
                })
            }
            _ => {
                return Err(UrgError::BadReply {
                    command: "PP".into(),
                    reason: "no parameters".into(),
                })
            }
        };
        let version = match self.command(b"VV")? {
            (_, Ok(Body::Version(v)), _) => v,
            (s, Err(reason), _) if s.is_success(CommandKind::Vv) => {
                return Err(UrgError::BadReply {
                    command: "VV".into(),
                    reason,
                })
            }
            (s, _, _) => return Err(Self::refused(b"VV", s, CommandKind::Vv)),
        };
        let info = match self.command(b"II") {
            Ok((_, Ok(Body::Info(i)), _)) => Some(i),
            Ok(_) => None,
            Err(e) if e.link_gone() || matches!(e, UrgError::Stopped) => return Err(e),
            Err(_) => None,
        };
        self.core.info = Some(Arc::new(SessionInfo {
            version,
            params,
            info,
        }));
        Ok(())
    }

    /// TM0, `time_sync_samples` × TM1 (tagged, so a late reply is never
    /// matched to a later request), TM2; fits the clock model.
    pub(crate) fn sync_clock(&mut self) -> Result<Option<ClockModel>, UrgError> {
        let n = self.core.params.time_sync_samples.min(64) as usize;
        if n == 0 {
            return Ok(None);
        }
        match self.command(b"TM0")? {
            (Status::Scip2(StatusCode::OK), _, _) => {}
            (Status::Scip2(c), _, _) if c.0 == *b"02" => {}
            (Status::Scip2(StatusCode::DENIED), _, _) => {
                // Still measuring: stop, then enter.
                self.simple(b"QT", CommandKind::Qt)?;
                self.core.streaming = None;
                self.simple(b"TM0", CommandKind::Tm)?;
            }
            (s, _, _) => return Err(Self::refused(b"TM0", s, CommandKind::Tm)),
        }
        self.in_adjust = true;
        let mut samples: heapless::Vec<TimeSample, 64> = heapless::Vec::new();
        let mut line = Vec::with_capacity(16);
        for _ in 0..n {
            self.tm_tag = self.tm_tag.wrapping_add(1) % 10_000;
            line.clear();
            line.extend_from_slice(format!("TM1;t{}", self.tm_tag).as_bytes());
            let host_send = self.core.clock.now();
            match self.command(&line) {
                Ok((_, Ok(Body::Time(t)), at)) => {
                    let ms = self.core.unwrap.unwrap(t);
                    let _ = samples.push(TimeSample {
                        host_send,
                        host_recv: at,
                        sensor: ms as f64 / 1000.0,
                    });
                }
                Ok((s, _, _)) => {
                    if let Status::Scip2(c) = s {
                        self.core.health.set_status(c.0);
                    }
                }
                Err(UrgError::NoResponse { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        self.simple(b"TM2", CommandKind::Tm)?;
        self.in_adjust = false;
        self.last_sync = self.core.clock.now();
        let model = self.core.history.add_round(&samples);
        if let Some(m) = model {
            self.core.model = Some(m);
            self.core.health.set_clock(m.offset(), m.drift_ppm());
            log::debug!(
                "{}: clock sensor-host {:.4} s, drift {:.1} ppm, best rtt {:.1} ms",
                self.name,
                m.offset(),
                m.drift_ppm(),
                m.rtt * 1e3
            );
        }
        Ok(model)
    }

    /// The stream request the parameters ask for, given the sensor.
    pub(crate) fn stream_request(&self) -> Option<StreamRequest> {
        let info = self.core.info.as_ref()?;
        let p = &info.params;
        let fam = p.family();
        let intensity = self.core.params.intensity && !self.core.no_intensity;
        let (kind, cluster) = if intensity && fam.supports_ff_intensity() {
            (DataKind::Distance, Cluster::UrgIntensity)
        } else if intensity && fam.supports_me() {
            (
                DataKind::DistanceIntensity,
                Cluster::Steps(self.core.params.cluster),
            )
        } else {
            (DataKind::Distance, Cluster::Steps(self.core.params.cluster))
        };
        Some(StreamRequest {
            scan: ScanRequest {
                kind,
                start: p.amin.min(u32::from(u16::MAX)) as u16,
                end: p.amax.min(u32::from(u16::MAX)) as u16,
                cluster,
            },
            skip: self.core.params.skip,
            count: 0,
        })
    }

    /// Starts the continuous MD (or FF/ME) stream. A sensor that refuses
    /// the intensity mode (a URG-04LX firmware without `FF`), or has none,
    /// streams plain distances instead, said in one log line: the match
    /// then uses geometry alone.
    pub fn start_stream(&mut self) -> Result<(), UrgError> {
        let req = self.stream_request().ok_or_else(|| UrgError::BadReply {
            command: "PP".into(),
            reason: "sensor parameters unknown".into(),
        })?;
        let wants = self.core.params.intensity && !self.core.no_intensity;
        let asks = req.scan.kind == DataKind::DistanceIntensity
            || req.scan.cluster == Cluster::UrgIntensity;
        if wants && !asks {
            self.core.no_intensity = true;
            log::warn!(
                "{}: scanner.intensity is on but this model has no intensity mode (neither FF nor ME): streaming plain distances, the scan match uses geometry alone",
                self.name
            );
        }
        match self.start_request(req) {
            Err(UrgError::Refused {
                command, status, ..
            }) if asks => {
                self.core.no_intensity = true;
                log::warn!(
                    "{}: the scanner refused its intensity mode ({} answered {status}): streaming plain distances (MD), the scan match uses geometry alone; set scanner.intensity = false to skip the attempt",
                    self.name,
                    command.get(..2).unwrap_or(&command)
                );
                let plain = self.stream_request().ok_or_else(|| UrgError::BadReply {
                    command: "PP".into(),
                    reason: "sensor parameters unknown".into(),
                })?;
                self.start_request(plain)
            }
            r => r,
        }
    }

    /// Starts a stream of `req` (count 0 = until QT).
    pub(crate) fn start_request(&mut self, req: StreamRequest) -> Result<(), UrgError> {
        let mut line = Vec::with_capacity(24);
        let _ = TaggedCommand::new(Command::Stream(req)).encode_line(&mut line);
        let kind = TaggedCommand::new(Command::Stream(req)).command.kind();
        self.simple(&line, kind)?;
        // Revolutions skipped while the stream was deliberately stopped are
        // not lost scans: gaps are judged within one stream only.
        self.core.prev_ms = None;
        self.core.streaming = Some(req);
        self.core.last_scan_at = self.core.clock.now();
        self.core.health.streaming.store(true, Ordering::Relaxed);
        Ok(())
    }

    /// Expected time between two delivered scans (s).
    pub(crate) fn scan_interval(&self) -> f64 {
        let period = self
            .core
            .info
            .as_ref()
            .map(|i| i.params.scan_period())
            .unwrap_or(0.1);
        let skip = self
            .core
            .streaming
            .map(|s| s.skip)
            .unwrap_or(self.core.params.skip);
        period * f64::from(skip + 1)
    }

    /// Waits for the next scan of the stream (delivered to the sink); a
    /// timeout is `scan_timeout_periods` scan intervals after the last scan.
    pub fn next_scan(&mut self) -> Result<(), UrgError> {
        let interval = self.scan_interval();
        let deadline = self.core.last_scan_at + interval * self.core.params.scan_timeout_periods;
        self.core.new_scan = false;
        if self.pump(deadline, |c| c.new_scan)? {
            Ok(())
        } else {
            Err(UrgError::ScanTimeout {
                waited: self.core.clock.now() - self.core.last_scan_at,
                interval,
            })
        }
    }

    /// Stops the stream: QT, draining (and still delivering) the scans in
    /// flight until the QT echo.
    pub(crate) fn stop_stream(&mut self) -> Result<(), UrgError> {
        self.core.streaming = None;
        self.core.health.streaming.store(false, Ordering::Relaxed);
        match self.simple(b"QT", CommandKind::Qt) {
            Ok(_) => Ok(()),
            Err(UrgError::NoResponse { .. }) => {
                self.drain_quiet(0.05, 0.5)?;
                self.simple(b"QT", CommandKind::Qt).map(|_| ())
            }
            Err(e) => Err(e),
        }
    }

    /// Rung 1 of the recovery ladder: QT, drain, restart the stream.
    pub(crate) fn restart_stream(&mut self) -> Result<(), UrgError> {
        let req = self.core.streaming.or_else(|| self.stream_request());
        self.stop_stream()?;
        match req {
            Some(r) => self.start_request(r),
            None => self.start_stream(),
        }
    }

    /// Periodic clock re-sync while streaming: QT, TM0/TM1/TM2, MD again.
    pub fn resync(&mut self) -> Result<(), UrgError> {
        let req = self.core.streaming;
        self.stop_stream()?;
        self.sync_clock()?;
        match req {
            Some(r) => self.start_request(r),
            None => Ok(()),
        }
    }

    /// Rung 2: RS (stops everything, resets the sensor clock to 0).
    pub fn reset(&mut self) -> Result<(), UrgError> {
        self.core.streaming = None;
        self.core.health.streaming.store(false, Ordering::Relaxed);
        let r = self.simple(b"RS", CommandKind::Rs);
        self.core.unwrap.reset();
        self.core.prev_ms = None;
        self.core.history.clear();
        self.core.model = None;
        self.core.epoch += 1;
        r.map(|_| ())
    }

    /// Takes one scan with a finite MD request (`MD…01`: the laser goes on by
    /// itself, the stream ends by itself).
    pub fn single_scan(&mut self) -> Result<(), UrgError> {
        let mut req = self.stream_request().ok_or_else(|| UrgError::BadReply {
            command: "PP".into(),
            reason: "sensor parameters unknown".into(),
        })?;
        req.count = 1;
        self.start_request(req)?;
        let r = self.next_scan();
        self.core.streaming = None;
        self.core.health.streaming.store(false, Ordering::Relaxed);
        r
    }

    /// Clean shutdown: QT (stream off, laser off), TM2 if in time-adjust
    /// mode. Errors are ignored: the port closes anyway.
    pub fn shutdown(mut self) {
        // The stop flag may already be set (that is why we are here): let
        // the last commands through regardless.
        self.closing = true;
        if self.in_adjust {
            let _ = self.command(b"TM2");
        }
        let _ = self.command(b"QT");
        self.core.streaming = None;
        self.core.health.streaming.store(false, Ordering::Relaxed);
    }
}

impl Core {
    fn on_event(&mut self, ev: Event<'_>) {
        match ev {
            Event::Reply(raw) => self.on_reply(raw),
            Event::Error(e) => {
                let h = &self.health;
                match e {
                    FrameError::StatusChecksum(_)
                    | FrameError::DataChecksum { .. }
                    | FrameError::KvChecksum { .. } => UrgHealth::bump(&h.checksum_errors),
                    _ => UrgHealth::bump(&h.desyncs),
                }
                log::debug!("scanner: {e}");
            }
        }
    }

    fn on_reply(&mut self, raw: RawReply<'_>) {
        let now = self.clock.now();
        let is_data = raw.status == Status::Scip2(StatusCode::DATA);
        if !is_data && self.waiting && self.got.is_none() && raw.echo == self.expect.as_slice() {
            let body = match raw.decode() {
                Ok(r) => Ok(match r.body {
                    ReplyBody::Version(v) => Body::Version(v),
                    ReplyBody::Params(p) => match p.validate() {
                        Ok(()) => Body::Params(p),
                        Err(e) => {
                            self.got = Some(Got {
                                status: raw.status,
                                body: Err(e.to_string()),
                                at: now,
                            });
                            return;
                        }
                    },
                    ReplyBody::Info(i) => Body::Info(i),
                    ReplyBody::Time(t) => Body::Time(t),
                    _ => Body::Empty,
                }),
                Err(e) => Err(e.to_string()),
            };
            self.got = Some(Got {
                status: raw.status,
                body,
                at: now,
            });
            return;
        }
        let kind = raw.kind();
        if is_data
            && matches!(
                kind,
                Some(CommandKind::Md | CommandKind::Ms | CommandKind::Me)
            )
        {
            self.on_scan(raw, now);
            return;
        }
        if let (Status::Scip2(c), Some(k)) = (raw.status, kind) {
            if k.is_stream() && self.streaming.is_some() {
                // An error status in place of a scan.
                self.health.set_status(c.0);
                log::warn!("scanner: stream status {} ({})", c.as_str(), c.meaning(k));
                return;
            }
        }
        log::debug!(
            "scanner: ignoring unsolicited reply to {}",
            String::from_utf8_lossy(raw.echo)
        );
    }

    fn on_scan(&mut self, raw: RawReply<'_>, now: f64) {
        let Some(info) = self.info.clone() else {
            return;
        };
        let data = match raw.decode() {
            Ok(r) => match r.body {
                ReplyBody::Scan(d) => d,
                _ => return,
            },
            Err(e) => {
                UrgHealth::bump(&self.health.discarded_scans);
                log::debug!("scanner: scan discarded: {e}");
                return;
            }
        };
        let p = &info.params;
        let ms = self.unwrap.unwrap(data.timestamp);
        let skip = self.streaming.map(|s| s.skip).unwrap_or(self.params.skip);
        let interval_ms = p.scan_period() * 1000.0 * f64::from(skip + 1);
        let mut dropped = 0;
        match continuity(self.prev_ms, ms, interval_ms) {
            Continuity::Ok => {}
            Continuity::Dropped(n) => {
                dropped = n;
                self.health.dropped_scans.fetch_add(n, Ordering::Relaxed);
            }
            Continuity::Stuck => {
                UrgHealth::bump(&self.health.stuck_clock);
                log::warn!("scanner: sensor clock stuck or went back ({ms} ms)");
            }
        }
        self.prev_ms = Some(ms);
        let stamp = match &self.model {
            Some(m) => m.host_of(ms as f64 / 1000.0),
            None => now,
        };
        self.seq += 1;
        let scan = &mut *self.scan;
        if let Err(e) = fill_laser_scan(&data, p, stamp, self.seq, &mut scan.scan) {
            UrgHealth::bump(&self.health.discarded_scans);
            log::debug!("scanner: scan discarded: {e}");
            return;
        }
        scan.readings.clear();
        for (_, r) in data.readings(p) {
            if scan.readings.push(r).is_err() {
                break;
            }
        }
        scan.raw_stamp = data.timestamp;
        scan.sensor_ms = ms;
        scan.epoch = self.epoch;
        scan.dropped_before = dropped;
        scan.time_per_step = p.time_per_step();
        scan.interval = interval_ms / 1000.0;
        scan.family = p.family();
        UrgHealth::bump(&self.health.scans);
        self.new_scan = true;
        self.last_scan_at = now;
        (self.sink)(scan);
    }
}
