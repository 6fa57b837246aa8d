//! The telemetry thread: the daemon's taps and live status onto Foxglove
//! channels, recorded to MCAP and served to live viewers.
//!
//! Rates are sized for a person: every scan and pose (10 Hz), the status
//! at 2 Hz, the grids at 1 Hz, the cells and the path when they change.
//! Nothing here can slow a stage: the taps drop copies when this thread
//! falls behind (counted in the report), the WebSocket sink drops frames
//! for a client that does not read, and the disk is written from here.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crossbeam_channel::{Receiver, Sender};
use foxglove::schemas::{
    packed_element_field::NumericType, FrameTransform, LaserScan, PoseInFrame, SceneEntityDeletion,
    SceneUpdate,
};
use foxglove::{Context, PartialMetadata};
use sweepline_daemon::daemon::taps::{OdometryRecord, ScanRecord};
use sweepline_daemon::daemon::{Shared, Taps};
use sweepline_daemon::pipeline::Recv;
use sweepline_io::clock::SharedClock;

use crate::channels::Channels;
use crate::convert;
use crate::geom::Pose;

/// How often the recording is flushed to the file (s of the daemon's clock).
const FLUSH_PERIOD: f64 = 1.0;
/// How often the status is logged (s).
const STATUS_PERIOD: f64 = 0.5;
/// Longest the thread sleeps waiting for a scan (wall time).
const WAIT: Duration = Duration::from_millis(50);
/// How often the grids are logged (s).
const GRID_PERIOD: f64 = 1.0;

/// What the telemetry thread does.
#[derive(Clone, Debug)]
pub struct TelemetryOptions {
    /// Where the recording goes (none: no recording).
    pub record: Option<crate::recorder::RecordTo>,
    /// The topics recorded (empty: all).
    pub record_channels: Vec<String>,
    /// Serve the live view on this address, e.g. `127.0.0.1:8765` (none: off).
    pub live: Option<String>,
    /// The scanner's mount on the robot (for the scan's pose in `base_link`).
    pub mount: Pose,
    /// The run is simulated: the truth channel exists.
    pub sim: bool,
    /// What the daemon was started with, recorded for a replay.
    pub setup: Option<crate::recording::Setup>,
    /// The scanner link's counters, for the status.
    pub scanner: Option<Arc<sweepline_io::urg::UrgHealth>>,
}

/// Why telemetry could not start.
#[derive(Debug, thiserror::Error)]
pub enum TelemetryError {
    /// The recording could not be created.
    #[error("cannot start the {0}")]
    Record(#[from] crate::recorder::RecordError),
    /// The thread could not be started.
    #[error("cannot start the telemetry thread: {0}")]
    Thread(std::io::Error),
}

/// What the telemetry thread did, for the run's report.
#[derive(Clone, Debug, Default)]
pub struct TelemetryStats {
    /// Scans logged.
    pub scans: u64,
    /// Pose fixes logged.
    pub poses: u64,
    /// Wheel odometry readings logged.
    pub odometry: u64,
    /// Status messages logged.
    pub statuses: u64,
    /// Evidence grids logged.
    pub maps: u64,
    /// Truth samples logged (`sim`).
    pub truth: u64,
    /// Bytes of the recording (0: none).
    pub recorded_bytes: u64,
    /// Errors writing the recording (the recording stopped at the first).
    pub record_errors: u64,
}

/// Metadata records: name, key-value pairs.
pub type MetadataRecords = Vec<(String, BTreeMap<String, String>)>;

/// The running telemetry thread.
pub struct Telemetry {
    finish: Sender<MetadataRecords>,
    truth: Option<Sender<(f64, Pose)>>,
    thread: Option<JoinHandle<TelemetryStats>>,
    live: Option<crate::server::LiveServer>,
}

impl Telemetry {
    /// Starts the thread on the daemon's `taps` and `shared` status, with
    /// stamps of `clock` mapped onto the wall clock of now.
    pub fn start(
        taps: Taps,
        shared: Arc<Shared>,
        clock: SharedClock,
        opts: TelemetryOptions,
    ) -> Result<Telemetry, TelemetryError> {
        let ctx = Context::new();
        let clock_map = ClockMap::now(clock.now());
        let recorder = match &opts.record {
            Some(to) => Some(crate::recorder::Recorder::open(
                &ctx,
                to.clone(),
                opts.record_channels.clone(),
                clock_map.metadata(),
                opts.setup.as_ref(),
            )?),
            None => None,
        };
        if let Some(r) = &recorder {
            log::info!("recording to {}", r.path().display());
        }
        // A live view that cannot be served (the port taken) is told and
        // left out: the robot goes on cleaning, the recording goes on.
        let live = opts.live.as_ref().and_then(|addr| {
            crate::server::LiveServer::start(&ctx, addr)
                .map_err(|why| log::warn!("live view not served on {addr}: {why}"))
                .ok()
        });
        let (truth_tx, truth_rx) = crossbeam_channel::bounded(4096);
        let (finish, finish_rx) = crossbeam_channel::bounded(1);
        let mut worker = Worker::new(&ctx, taps, shared, opts.clone(), truth_rx, clock_map);
        worker.recorder = recorder;
        let thread = std::thread::Builder::new()
            .name("telemetry".into())
            .spawn(move || worker.run(&finish_rx, clock))
            .map_err(TelemetryError::Thread)?;
        Ok(Telemetry {
            finish,
            truth: opts.sim.then_some(truth_tx),
            thread: Some(thread),
            live,
        })
    }

    /// Where the simulator sends the true poses (none outside `sim`).
    pub fn truth(&self) -> Option<Sender<(f64, Pose)>> {
        self.truth.clone()
    }

    /// The address the live view listens on (none: off).
    pub fn live_addr(&self) -> Option<std::net::SocketAddr> {
        self.live.as_ref().map(|l| l.addr())
    }

    /// Stops the thread once the taps are drained, writes `metadata` into
    /// the recording and closes it.
    pub fn finish(mut self, metadata: MetadataRecords) -> TelemetryStats {
        let _ = self.finish.send(metadata);
        let stats = self
            .thread
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        if let Some(l) = self.live.take() {
            l.stop();
        }
        stats
    }
}

/// Daemon-clock seconds to nanoseconds since the Unix epoch: the clock's
/// `now` at start is the wall clock's now.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ClockMap {
    start: f64,
    wall_ns: u64,
}

impl ClockMap {
    /// As the recording's `clock` metadata.
    fn metadata(&self) -> BTreeMap<String, String> {
        [
            ("start".to_string(), self.start.to_string()),
            ("wall_ns".to_string(), self.wall_ns.to_string()),
        ]
        .into_iter()
        .collect()
    }

    fn now(start: f64) -> Self {
        let wall_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        Self { start, wall_ns }
    }

    fn ns(&self, t: f64) -> u64 {
        let d = ((t - self.start) * 1e9).round();
        (self.wall_ns as f64 + d).max(0.0) as u64
    }
}

/// The thread's state: the channels, reused buffers and what was last sent.
struct Worker {
    /// The context the channels and sinks live in (channels close with it).
    _ctx: Arc<Context>,
    ch: Channels,
    taps: Taps,
    shared: Arc<Shared>,
    opts: TelemetryOptions,
    truth: Receiver<(f64, Pose)>,
    logs: crate::logs::Listener,
    clock: ClockMap,
    recorder: Option<crate::recorder::Recorder>,
    record: ScanRecord,
    /// The beam angles last recorded in the current file.
    last_angles: Vec<f64>,
    /// An empty list swapped in for angles that did not change.
    spare: Vec<f64>,
    json: Vec<u8>,
    laser: LaserScan,
    bytes: Vec<u8>,
    last_grid: Option<Arc<crate::grid::Grid>>,
    last_swept: Option<Arc<sweepline_core::plan::SweptFloor>>,
    last_cells: Option<Arc<crate::decomp::Decomposition>>,
    last_path: u64,
    next_status: f64,
    next_grid: f64,
    next_flush: f64,
    stats: TelemetryStats,
}

impl Worker {
    fn new(
        ctx: &Arc<Context>,
        taps: Taps,
        shared: Arc<Shared>,
        opts: TelemetryOptions,
        truth: Receiver<(f64, Pose)>,
        clock: ClockMap,
    ) -> Self {
        Self {
            _ctx: ctx.clone(),
            ch: Channels::new(ctx, opts.sim),
            taps,
            shared,
            opts,
            truth,
            logs: crate::logs::Listener::join(),
            clock,
            recorder: None,
            record: ScanRecord::default(),
            last_angles: Vec::new(),
            spare: Vec::new(),
            json: Vec::with_capacity(64 * 1024),
            laser: LaserScan::default(),
            bytes: Vec::new(),
            last_grid: None,
            last_swept: None,
            last_cells: None,
            last_path: u64::MAX,
            next_status: f64::NEG_INFINITY,
            next_grid: f64::NEG_INFINITY,
            next_flush: f64::NEG_INFINITY,
            stats: TelemetryStats::default(),
        }
    }

    fn meta(&self, t: f64) -> PartialMetadata {
        PartialMetadata {
            log_time: Some(self.clock.ns(t)),
        }
    }

    /// Until told to finish: scans and poses as they come, the rest on
    /// their periods; then the taps drained and the recording closed.
    fn run(mut self, finish: &Receiver<MetadataRecords>, clock: SharedClock) -> TelemetryStats {
        crate::background();
        loop {
            let done = finish.try_recv().ok();
            // Asleep until a scan comes (or the periodic work is due).
            if done.is_none() {
                if let Recv::Msg(s) = self.taps.scans.recv_timeout(WAIT) {
                    self.scan(&s);
                }
            }
            while let Recv::Msg(s) = self.taps.scans.try_recv() {
                self.scan(&s);
            }
            while let Recv::Msg(o) = self.taps.odometry.try_recv() {
                self.odometry(&o);
            }
            while let Recv::Msg(f) = self.taps.fixes.try_recv() {
                self.fix(&f);
            }
            while let Ok((t, p)) = self.truth.try_recv() {
                self.truth(t, &p);
            }
            let now = clock.now();
            while let Ok(line) = self.logs.rx.try_recv() {
                self.log(now, line);
            }
            self.periodic(now);
            if let Some(metadata) = done {
                self.close(&metadata);
                break;
            }
        }
        self.stats
    }

    /// Closes the recording with `metadata`.
    fn close(&mut self, metadata: &MetadataRecords) {
        if let Some(mut r) = self.recorder.take() {
            if let Err(e) = r.close(metadata) {
                log::warn!("{e}");
                self.stats.record_errors += 1;
            }
            self.stats.recorded_bytes = r.closed_bytes();
        }
    }

    fn scan(&mut self, tap: &sweepline_daemon::daemon::TapScan) {
        let t = tap.msg.stamp;
        self.stats.scans += 1;
        self.record.fill_from(tap);
        // Angles only when they change (the first scan of a file has them).
        let same = self.record.angles == self.last_angles;
        if same {
            std::mem::swap(&mut self.record.angles, &mut self.spare);
        } else {
            self.last_angles.clone_from(&self.record.angles);
        }
        self.json.clear();
        let written = serde_json::to_writer(&mut self.json, &self.record);
        if same {
            std::mem::swap(&mut self.record.angles, &mut self.spare);
        }
        if written.is_ok() {
            self.ch.scan_input.log_with_meta(&self.json, self.meta(t));
        }
        let s = &tap.msg.scan;
        let l = &mut self.laser;
        l.timestamp = Some(convert::timestamp(self.clock.ns(t)));
        l.frame_id.clear();
        l.frame_id.push_str("base_link");
        l.pose = Some(convert::pose(&self.opts.mount));
        l.start_angle = s.beams.first().map_or(0.0, |b| b.angle);
        l.end_angle = s.beams.last().map_or(0.0, |b| b.angle);
        l.ranges.clear();
        l.intensities.clear();
        for b in &s.beams {
            l.ranges.push(if b.valid { b.range } else { f64::NAN });
            l.intensities.push(b.intensity);
        }
        self.ch.scan.log_with_meta(&self.laser, self.meta(t));
    }

    fn odometry(&mut self, o: &sweepline_core::base::Odometry) {
        self.stats.odometry += 1;
        self.json.clear();
        if serde_json::to_writer(&mut self.json, &OdometryRecord::of(o)).is_ok() {
            self.ch
                .odometry_input
                .log_with_meta(&self.json, self.meta(o.t1));
        }
    }

    fn fix(&mut self, f: &sweepline_daemon::daemon::messages::PoseFix) {
        self.stats.poses += 1;
        let ns = self.clock.ns(f.stamp);
        let meta = self.meta(f.stamp);
        let framed = |frame: &str, p: &Pose| PoseInFrame {
            timestamp: Some(convert::timestamp(ns)),
            frame_id: frame.into(),
            pose: Some(convert::pose(p)),
        };
        self.ch.pose.log_with_meta(&framed("map", &f.pose), meta);
        self.ch.odom.log_with_meta(&framed("odom", &f.odom), meta);
        let p = convert::pose(&f.pose);
        self.ch.tf.log_with_meta(
            &FrameTransform {
                timestamp: Some(convert::timestamp(ns)),
                parent_frame_id: "map".into(),
                child_frame_id: "base_link".into(),
                translation: p.position,
                rotation: p.orientation,
            },
            meta,
        );
    }

    fn log(&mut self, now: f64, l: crate::logs::LogLine) {
        use foxglove::schemas::log::Level;
        let level = match l.level {
            log::Level::Error => Level::Error,
            log::Level::Warn => Level::Warning,
            log::Level::Info => Level::Info,
            log::Level::Debug | log::Level::Trace => Level::Debug,
        };
        let msg = foxglove::schemas::Log {
            timestamp: Some(convert::timestamp(self.clock.ns(now))),
            level: level as i32,
            message: l.message,
            name: l.target,
            file: l.file,
            line: l.line,
        };
        self.ch.log.log_with_meta(&msg, self.meta(now));
    }

    fn truth(&mut self, t: f64, p: &Pose) {
        if let Some(c) = &self.ch.truth {
            self.stats.truth += 1;
            let ns = self.clock.ns(t);
            c.log_with_meta(
                &PoseInFrame {
                    timestamp: Some(convert::timestamp(ns)),
                    frame_id: "world".into(),
                    pose: Some(convert::pose(p)),
                },
                self.meta(t),
            );
        }
    }

    fn periodic(&mut self, now: f64) {
        if now >= self.next_status {
            self.next_status = now + STATUS_PERIOD;
            self.status(now);
        }
        if now >= self.next_grid {
            self.next_grid = now + GRID_PERIOD;
            self.grids(now);
        }
        self.plan(now);
        if now >= self.next_flush {
            self.next_flush = now + FLUSH_PERIOD;
            self.flush();
        }
    }

    /// Writes the recording out; a full file of a rotating recording is
    /// followed by a new one starting where the robot is now.
    fn flush(&mut self) {
        let Some(r) = &mut self.recorder else { return };
        let (setup, shared) = (&self.opts.setup, &self.shared);
        let now_setup = || {
            setup.clone().map(|mut s| {
                s.start = shared.with_status(|st| st.pose);
                s
            })
        };
        let before = r.path().to_path_buf();
        let ticked = r.tick(now_setup);
        if r.path() != before {
            // A new file: its first scan carries the angles again.
            self.last_angles.clear();
        }
        if let Err(e) = ticked {
            // The robot goes on; the recording stops at the first error.
            log::warn!("{e}; recording stopped");
            self.stats.record_errors += 1;
            self.recorder = None;
        }
    }

    fn status(&mut self, now: f64) {
        self.json.clear();
        let urg = self.opts.scanner.as_deref();
        if crate::status::write(&self.shared, urg, now, &mut self.json).is_ok() {
            self.stats.statuses += 1;
            self.ch.status.log_with_meta(&self.json, self.meta(now));
        }
    }

    fn grids(&mut self, now: f64) {
        let (grid, swept) = self
            .shared
            .with_status(|s| (s.map.grid.clone(), s.plan.planner.swept.clone()));
        let ns = self.clock.ns(now);
        if let Some(g) = grid.filter(|g| !same(&self.last_grid, g)) {
            convert::occupancy(&g, &mut self.bytes);
            let msg = convert::grid(
                ns,
                g.origin(),
                g.resolution(),
                g.width(),
                "occupancy",
                NumericType::Int8,
                std::mem::take(&mut self.bytes),
            );
            self.ch.map.log_with_meta(&msg, self.meta(now));
            self.stats.maps += 1;
            self.last_grid = Some(g);
        }
        if let Some(s) = swept.filter(|s| !same(&self.last_swept, s)) {
            let data = s.covered.iter().map(|&c| u8::from(c)).collect();
            let f = &s.frame;
            let msg = convert::grid(ns, f.origin, f.res, f.w, "swept", NumericType::Uint8, data);
            self.ch.swept.log_with_meta(&msg, self.meta(now));
            self.last_swept = Some(s);
        }
    }

    fn plan(&mut self, now: f64) {
        let (cells, path) = self
            .shared
            .with_status(|s| (s.decomposition.clone(), s.path.clone()));
        let new_cells = cells.filter(|c| !same(&self.last_cells, c));
        let new_path = path.clone().filter(|p| p.0 != self.last_path);
        if new_cells.is_none() && new_path.is_none() {
            return;
        }
        let ns = self.clock.ns(now);
        let mut update = SceneUpdate::default();
        if let Some(c) = new_cells {
            // Cells come and go: clear the old ones first.
            update.deletions.push(SceneEntityDeletion {
                timestamp: Some(convert::timestamp(ns)),
                r#type: foxglove::schemas::scene_entity_deletion::Type::All as i32,
                id: String::new(),
            });
            update.entities.extend(convert::cells(ns, &c));
            self.last_cells = Some(c);
            if let Some((_, p)) = path.clone() {
                update.entities.push(convert::path(ns, &p));
            }
        }
        if let Some((seq, p)) = new_path {
            if !update.entities.iter().any(|e| e.id == "path") {
                update.entities.push(convert::path(ns, &p));
            }
            self.last_path = seq;
        }
        self.ch.plan.log_with_meta(&update, self.meta(now));
    }
}

/// Whether `new` is the very value last sent.
fn same<T>(last: &Option<Arc<T>>, new: &Arc<T>) -> bool {
    last.as_ref().is_some_and(|l| Arc::ptr_eq(l, new))
}
