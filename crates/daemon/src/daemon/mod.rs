//! The daemon: the real stages of the DESIGN data path wired into the
//! pipeline machinery. One thread per stage — scanner (the URG driver's own
//! reader thread behind it), localise, map, plan, control, motor — joined by
//! newest-wins edges, watched by the supervisor (metrics, watchdog, status,
//! periodic checkpoints, ordered shutdown).
//!
//! The daemon opens its two devices through [`crate::serial::Connector`]s and
//! reads time only through the injected [`crate::clock::Clock`]: `sweepline
//! run` hands it `/dev/...` paths and the monotonic clock, `sweepline sim`
//! hands it pty paths and a scaled clock; nothing in here knows which.

pub(crate) mod events_report;
pub mod hooks;
pub mod messages;
pub(crate) mod mount_report;
pub mod params;
pub mod replay;
pub mod resume;
pub mod shared;
pub mod snapshot;
pub mod stages;
pub mod taps;

#[cfg(test)]
mod contacts_resume_tests;

// The checks beside the stages (mount, alignment, contact marks,
// relocalisation, stuck watch), from `sweepline-core`, by their short names.
pub(crate) use crate::checks::{
    align, consistency, contact, offset_check, relocalise, stuck, travel_check, turn_check,
};

use std::path::PathBuf;
use std::sync::Arc;

use nalgebra::Point2;

use crate::clock::SharedClock;
use crate::config::Config;
use crate::control::PathFollower;
use crate::decomp::Decomposer;
use crate::geom::{heading, Pose};
use crate::grid::Grid;
use crate::icp::Tracker;
use crate::motor::DiffDriveBase;
use crate::pipeline::checkpoint::{ResumeEntry, RunProgress};
use crate::pipeline::supervisor::{Control, Hooks, Outcome, Supervisor};
use crate::pipeline::{latest, queue, Overflow, Pipeline};
use crate::plan::{CoveragePlanner, PlanSnapshot};
use crate::serial::Connector;
use crate::urg::{UrgDriver, UrgHealth};

pub use hooks::DaemonHooks;
pub use params::DaemonParams;
pub use shared::{LiveStatus, Shared};
pub use snapshot::{LocaliseSnapshot, MapStageSnapshot, PlanStageSnapshot, RunSnapshot};
pub use taps::{SensorScan, TapScan, Taps};

/// Control period (s): the follower runs at 20 Hz.
pub(crate) const CONTROL_PERIOD: f64 = 0.05;
/// Encoder polling period (s).
pub(crate) const MOTOR_POLL_PERIOD: f64 = 0.02;
/// Time the robot reverses after a bumper contact (s).
pub(crate) const BUMP_BACKOFF: f64 = 1.0;
/// Longest time it keeps reversing while the bumper stays closed (s): a
/// contact far to the side is not freed by the first 5 cm straight back, and
/// the bumper gate lets the wheels do nothing but reverse until it is.
pub(crate) const BUMP_BACKOFF_MAX: f64 = 6.0;
/// Longest range merged into the map (m).
pub(crate) const MAP_MAX_RANGE: f64 = 5.0;

/// Why the daemon could not start.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    /// A module refused its settings.
    #[error("configuration: {0}")]
    Config(String),
    /// A thread could not be started.
    #[error("cannot start the pipeline: {0}")]
    Pipeline(#[from] crate::pipeline::PipelineError),
    /// The scanner driver could not start.
    #[error("scanner: {0}")]
    Scanner(#[from] crate::urg::UrgError),
}

/// The extent of the explored-area grid (map frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapFrame {
    /// Lower-left corner (m).
    pub origin: Point2<f64>,
    /// Cell size (m).
    pub resolution: f64,
    /// Cells along x.
    pub width: usize,
    /// Cells along y.
    pub height: usize,
}

impl MapFrame {
    /// A square of `extent` metres centred on `centre`.
    pub fn centred(centre: Point2<f64>, extent: f64, resolution: f64) -> Self {
        let n = (extent / resolution).ceil().max(1.0) as usize;
        Self {
            origin: Point2::new(centre.x - extent / 2.0, centre.y - extent / 2.0),
            resolution,
            width: n,
            height: n,
        }
    }

    pub(crate) fn grid(&self) -> Grid {
        Grid::new(self.origin, self.resolution, self.width, self.height)
    }
}

/// Where a resumed run picks up: the run's own part and each stage's
/// snapshot as the checkpoint held them (see [`snapshot`]).
#[derive(Clone, Debug)]
pub struct Resume {
    /// Progress and pose at the checkpoint (never finished: a finished run
    /// is not resumed).
    pub run: RunSnapshot,
    /// The map stage's grid (always set) and contact marks.
    pub map: MapStageSnapshot,
    /// The planner's records and the places contact marks were tried.
    pub plan: PlanStageSnapshot,
    /// The scan tracker's keyframes and the refitted scanner mount.
    pub localise: LocaliseSnapshot,
    /// What the restart lost, for the run's report.
    pub entry: ResumeEntry,
}

/// Everything the daemon needs to start.
pub struct DaemonSetup {
    /// The configuration.
    pub config: Config,
    /// The clock every stage and driver reads.
    pub clock: SharedClock,
    /// Opens the scanner's port.
    pub scanner: Box<dyn Connector>,
    /// The wheel-base driver.
    pub base: Box<dyn DiffDriveBase>,
    /// Robot pose at start in the map frame.
    pub start: Pose,
    /// Extent of the map.
    pub map: MapFrame,
    /// Resume from a checkpoint.
    pub resume: Option<Resume>,
    /// Folder for checkpoints (none: no checkpoints).
    pub state_dir: Option<PathBuf>,
    /// Copy every scan and pose onto taps for a live view or a recorder
    /// (see [`Daemon::take_taps`]).
    pub taps: bool,
}

/// A daemon whose stages are running, not yet supervised.
pub struct Daemon {
    pipeline: Pipeline,
    supervisor: Supervisor,
    shared: Arc<Shared>,
    urg_health: Arc<UrgHealth>,
    clock: SharedClock,
    resume: Option<RunProgress>,
    state_dir: Option<PathBuf>,
    checkpoint_period: f64,
    heartbeat_period: f64,
    resume_entry: Option<ResumeEntry>,
    /// The robot as configured (for the run folder's `mount.toml`).
    robot: crate::robot::RobotParams,
    /// The consumer ends of the taps, until taken.
    taps: Option<Taps>,
}

impl Daemon {
    /// Builds every stage, restores each from its snapshot when the run is
    /// resumed, and starts its thread.
    pub fn start(setup: DaemonSetup) -> Result<Daemon, DaemonError> {
        let cfg = setup.config;
        let clock = setup.clock;
        let robot = cfg.robot.clone();
        let resume = setup.resume;
        let supervisor = Supervisor::new(&cfg.pipeline, clock.clone());
        let mut pipeline = Pipeline::new(&cfg.pipeline);
        let shared = Arc::new(Shared::default());

        // The run's own part: the pose every stage starts from and the path
        // driven so far (the hooks go on with the other counters).
        let start = resume.as_ref().map_or(setup.start, |r| r.run.pose);
        shared.with_status(|s| {
            s.pose = start;
            if let Some(r) = &resume {
                s.path_length = r.run.progress.path_length;
            }
        });

        let (scan_tx, scan_rx) = latest("scans");
        let (fix_tx, fix_rx) = latest("pose_fixes");
        let (map_tx, map_rx) = queue("registered_scans", 8, Overflow::DropOldest);
        let (snap_tx, snap_rx) = latest("map_snapshots");
        let (path_tx, path_rx) = queue("paths", 4, Overflow::DropOldest);
        let (pose_tx, pose_rx) = queue("swept_poses", 1024, Overflow::DropOldest);
        let (cmd_tx, cmd_rx) = latest("wheel_commands");
        pipeline.register_edge(&scan_tx);
        pipeline.register_edge(&fix_tx);
        pipeline.register_edge(&map_tx);
        pipeline.register_edge(&snap_tx);
        pipeline.register_edge(&path_tx);
        pipeline.register_edge(&pose_tx);
        pipeline.register_edge(&cmd_tx);
        let (tap_tx, taps) = if setup.taps {
            let (tx, rx) = taps::taps();
            pipeline.register_edge(&tx.scans);
            pipeline.register_edge(&tx.fixes);
            pipeline.register_edge(&tx.odometry);
            (Some(tx), Some(rx))
        } else {
            (None, None)
        };

        let decomposer = Decomposer::new(&cfg.decomp, robot.radius)
            .map_err(|e| DaemonError::Config(e.to_string()))?;
        let planner = CoveragePlanner::new(&cfg.plan, &robot)
            .map_err(|e| DaemonError::Config(e.to_string()))?;
        let mut plan = stages::PlanStage {
            decomposer,
            planner,
            rx: snap_rx,
            poses: pose_rx,
            tx: path_tx,
            shared: shared.clone(),
            control: supervisor.control(),
            clock: clock.clone(),
            min_interval: cfg.daemon.plan_interval,
            last: f64::NEG_INFINITY,
            seq: 0,
            updates: 0,
            records: PlanSnapshot::default(),
            contacts_seen: 0,
            bump_handled: f64::NEG_INFINITY,
            contact_settle: cfg.daemon.contact.settle,
            probe: stages::MarkProbe::new(
                map_tx.clone(),
                cfg.daemon.contact.retry_walled_floor,
                cfg.plan.min_lane_area,
                2.0 * robot.radius,
            ),
        };
        if let Some(r) = &resume {
            plan.restore(r.plan.clone(), cfg.plan.return_home);
        }
        plan.planner.record_pose(&start);
        let follower = PathFollower::new(&cfg.control, &robot)
            .map_err(|e| DaemonError::Config(e.to_string()))?
            .with_command_horizon(cfg.motor.deadman);
        let mut map = stages::MapStage::new(
            setup.map.grid(),
            map_rx,
            snap_tx,
            shared.clone(),
            MAP_MAX_RANGE,
            cfg.daemon.contact.same_contact,
        )
        .with_map_kind(&cfg.map, &start)
        .map_err(|e| DaemonError::Config(e.to_string()))?;
        if let Some(r) = &resume {
            map.restore(r.map.clone());
        }
        let mut localise = localise_stage(
            &cfg,
            start,
            LocaliseEdges {
                rx: scan_rx,
                to_control: fix_tx,
                to_map: map_tx.clone(),
                tap: tap_tx.as_ref().map(|t| t.fixes.clone()),
            },
            shared.clone(),
            setup.state_dir.is_some(),
        )?;
        if let Some(r) = &resume {
            localise
                .restore(r.localise.clone(), &start, r.map.grid.clone())
                .map_err(DaemonError::Config)?;
        }

        let driver = UrgDriver::start(setup.scanner, cfg.scanner.clone(), clock.clone())?;
        let urg_health = driver.health();
        let now = clock.now();

        pipeline.spawn(
            "motor",
            stages::MotorStage {
                base: setup.base,
                rx: cmd_rx,
                to_map: map_tx,
                shared: shared.clone(),
                clock: clock.clone(),
                period: MOTOR_POLL_PERIOD,
                next_poll: now,
                radius: robot.radius,
                wheel_base: robot.wheel_base,
                last_wheels: crate::motor::WheelSpeeds::STOP,
                motion: contact::MotionMemory::default(),
                contact: cfg.daemon.contact.clone(),
                held: contact::HeldContact::default(),
                track: contact::BodyTrack::new(
                    setup.map.origin,
                    setup.map.width as f64 * setup.map.resolution,
                    setup.map.height as f64 * setup.map.resolution,
                ),
                tap: tap_tx.as_ref().map(|t| t.odometry.clone()),
            },
        )?;
        pipeline.spawn(
            "control",
            stages::ControlStage {
                follower,
                paths: path_rx,
                fixes: fix_rx,
                tx: cmd_tx,
                poses: pose_tx,
                shared: shared.clone(),
                clock: clock.clone(),
                period: CONTROL_PERIOD,
                next_tick: now,
                last_cmd: now,
                fix: None,
                start,
                path_seq: 0,
                wheel_base: robot.wheel_base,
                backoff: BUMP_BACKOFF,
                last_pose: None,
                bump_seen: f64::NEG_INFINITY,
                watch: stuck::ProgressWatch::new(cfg.daemon.stuck_after),
                scan_timeout: cfg.daemon.scan_timeout,
                held_since: None,
                guard: Default::default(),
                blind_ahead_told: false,
            },
        )?;
        pipeline.spawn("plan", plan)?;
        pipeline.spawn("map", map)?;
        pipeline.spawn("localise", localise)?;
        pipeline.spawn(
            "scanner",
            stages::ScannerStage {
                driver: Some(driver),
                tx: scan_tx,
                shared: shared.clone(),
                upside_down: robot.scanner_upside_down,
                tap: tap_tx.map(|t| t.scans),
            },
        )?;
        Ok(Daemon {
            pipeline,
            supervisor,
            shared,
            urg_health,
            clock,
            resume_entry: resume.as_ref().map(|r| r.entry.clone()),
            resume: resume.map(|r| r.run.progress),
            state_dir: setup.state_dir,
            checkpoint_period: cfg.pipeline.checkpoint_period,
            heartbeat_period: cfg.pipeline.heartbeat_period,
            robot: cfg.robot.clone(),
            taps,
        })
    }

    /// The taps' consumer ends (once; none unless [`DaemonSetup::taps`]).
    pub fn take_taps(&mut self) -> Option<Taps> {
        self.taps.take()
    }

    /// A handle to ask for a stop or signal readiness.
    pub fn control(&self) -> Control {
        self.supervisor.control()
    }

    /// The state shared by the stages (live status, odometry, flags).
    pub fn shared(&self) -> Arc<Shared> {
        self.shared.clone()
    }

    /// The scanner link's counters.
    pub fn urg_health(&self) -> Arc<UrgHealth> {
        self.urg_health.clone()
    }

    /// The daemon's own hooks (status line, checkpoints, ordered shutdown).
    pub fn hooks(&self) -> DaemonHooks {
        DaemonHooks::new(
            self.shared.clone(),
            self.clock.clone(),
            self.state_dir.as_deref(),
            self.checkpoint_period,
            self.heartbeat_period,
            self.resume,
        )
        .with_robot(self.robot.clone())
    }

    /// What the resume this daemon started from lost (none: a fresh start),
    /// for the run folder's report.
    pub fn resume_entry(&self) -> Option<ResumeEntry> {
        self.resume_entry.clone()
    }

    /// Supervises the stages until coverage is done, a signal, a stop request
    /// or a failed stage; then shuts down in order and reports.
    pub fn run(self, hooks: &mut dyn Hooks) -> Outcome {
        self.supervisor.control().ready();
        self.supervisor.run(self.pipeline, hooks)
    }
}

/// The localise stage's edges.
pub(crate) struct LocaliseEdges {
    /// Scans in.
    pub(crate) rx: crate::pipeline::Rx<messages::ScanMsg>,
    /// Pose fixes out to the control stage.
    pub(crate) to_control: crate::pipeline::Tx<messages::PoseFix>,
    /// Registered scans out to the map stage.
    pub(crate) to_map: crate::pipeline::Tx<messages::MapMsg>,
    /// A copy of every pose fix (none: no tap).
    pub(crate) tap: Option<crate::pipeline::Tx<messages::PoseFix>>,
}

/// The localise stage of a robot told it starts at `start`, as `cfg`
/// sets it up (the daemon's and the recording replay's alike); it hands
/// its keyframes to the checkpoints when `publish_keyframes`.
pub(crate) fn localise_stage(
    cfg: &Config,
    start: Pose,
    edges: LocaliseEdges,
    shared: Arc<Shared>,
    publish_keyframes: bool,
) -> Result<stages::LocaliseStage, DaemonError> {
    let robot = &cfg.robot;
    let configured_mount = robot.scanner_mount();
    let tracker = Tracker::new(cfg.icp.clone(), start * configured_mount)
        .map_err(|e| DaemonError::Config(e.to_string()))?;
    Ok(stages::LocaliseStage {
        tracker,
        rx: edges.rx,
        to_control: edges.to_control,
        to_map: edges.to_map,
        shared: shared.clone(),
        mount: configured_mount,
        configured_mount,
        mount_refitted: false,
        wheel_base: robot.wheel_base,
        wheel_radius: robot.wheel_radius,
        fit_mount: cfg.daemon.fit_scanner_mount,
        check_min_information: cfg.icp.degeneracy_threshold * stages::CHECK_INFORMATION_FACTOR,
        deskew: cfg.daemon.deskew_scans,
        intensity_scale: 1.0 / cfg.scanner.intensity_unit,
        points: Vec::with_capacity(crate::capacity::MAX_BEAMS),
        relocalise_on: None,
        publish_keyframes,
        keyframes: None,
        last_stamp: None,
        unmatched_run: 0,
        align: cfg.daemon.align_to_walls.then(align::WallAlign::new),
        turn_check: turn_check::TurnCheck::default(),
        travel_check: travel_check::TravelCheck::new(heading(&configured_mount)),
        offset_check: offset_check::OffsetCheck::new(heading(&configured_mount)),
        offset_fitted: false,
        lost: stages::Lost::new(
            cfg.daemon.lost_after,
            cfg.daemon.relocalise_radius,
            &cfg.icp.search,
        ),
        tap: edges.tap,
    })
}
