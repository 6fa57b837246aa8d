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

pub mod events_report;
pub mod hooks;
pub mod messages;
pub mod mount_report;
pub mod params;
pub mod resume;
pub mod shared;
pub mod stages;

/// The checks beside the stages (mount, alignment, contact marks,
/// relocalisation, stuck watch), from `sweepline-core`.
pub use crate::checks::{
    align, contact, offset_check, relocalise, stuck, travel_check, turn_check,
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
use crate::icp::{Tracker, TrackerState};
use crate::motor::DiffDriveBase;
use crate::pipeline::checkpoint::{ResumeEntry, RunProgress};
use crate::pipeline::supervisor::{Control, Hooks, Outcome, Supervisor};
use crate::pipeline::{latest, queue, Overflow, Pipeline};
use crate::plan::{CoveragePlanner, SweptFloor};
use crate::serial::Connector;
use crate::urg::{UrgDriver, UrgHealth};

pub use hooks::DaemonHooks;
pub use params::DaemonParams;
pub use shared::{LiveStatus, Shared};

/// Control period (s): the follower runs at 20 Hz.
pub const CONTROL_PERIOD: f64 = 0.05;
/// Encoder polling period (s).
pub const MOTOR_POLL_PERIOD: f64 = 0.02;
/// Time the robot reverses after a bumper contact (s).
pub const BUMP_BACKOFF: f64 = 1.0;
/// Longest time it keeps reversing while the bumper stays closed (s): a
/// contact far to the side is not freed by the first 5 cm straight back, and
/// the bumper gate lets the wheels do nothing but reverse until it is.
pub const BUMP_BACKOFF_MAX: f64 = 6.0;
/// Longest range merged into the map (m).
pub const MAP_MAX_RANGE: f64 = 5.0;

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

    fn grid(&self) -> Grid {
        Grid::new(self.origin, self.resolution, self.width, self.height)
    }
}

/// Where a resumed run picks up.
#[derive(Clone, Debug)]
pub struct Resume {
    /// Robot pose at the checkpoint.
    pub pose: Pose,
    /// The map at the checkpoint.
    pub grid: Grid,
    /// Progress at the checkpoint.
    pub progress: RunProgress,
    /// The planner's record of swept floor at the checkpoint (none: the
    /// floor is covered again).
    pub swept: Option<SweptFloor>,
    /// The phase of the planner's lane lattice at the checkpoint (none: it
    /// is chosen again at the first cover task).
    pub lattice: Option<crate::plan::LatticePhase>,
    /// Where the robot started (none: a checkpoint written before the
    /// record existed; the robot drives back to where it was resumed).
    pub home: Option<crate::plan::HomePlace>,
    /// The planner's tries and give-ups at the checkpoint (none: floor it
    /// failed on gets all its tries again).
    pub tries: Option<crate::plan::PlanTries>,
    /// Where the planner's robot could once get to, its waits and further
    /// rounds at the checkpoint (none: counted afresh).
    pub reach: Option<crate::plan::PlanReach>,
    /// The scan tracker's keyframes at the checkpoint (none: a new local
    /// map is started at the resume pose).
    pub tracker: Option<TrackerState>,
    /// The bumper contact marks at the checkpoint, marked again in the map
    /// so that rays cannot clear them.
    pub contacts: Vec<contact::ContactMark>,
    /// Where contact marks were taken out before the checkpoint to try the
    /// floor behind them: marks near these stay.
    pub tried: Vec<nalgebra::Point2<f64>>,
    /// The scanner mount refitted before the checkpoint (none: the run
    /// drove with the configured one).
    pub mount: Option<crate::pipeline::checkpoint::MountRecord>,
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
}

impl Daemon {
    /// Builds every stage and starts its thread.
    pub fn start(setup: DaemonSetup) -> Result<Daemon, DaemonError> {
        let cfg = setup.config;
        let clock = setup.clock;
        let robot = cfg.robot.clone();
        // A resumed run drives with the mount refitted before its
        // checkpoint (while the configuration is unchanged).
        let refitted = setup.resume.as_ref().and_then(|r| r.mount);
        let mount = resume::resumed_mount(robot.scanner_mount(), refitted.as_ref());
        let supervisor = Supervisor::new(&cfg.pipeline, clock.clone());
        let mut pipeline = Pipeline::new(&cfg.pipeline);
        let shared = Arc::new(Shared::default());

        let (start, grid) = match &setup.resume {
            Some(r) => (r.pose, r.grid.clone()),
            None => (setup.start, setup.map.grid()),
        };
        shared.with_status(|s| {
            s.pose = start;
            if let Some(r) = &setup.resume {
                s.path_length = r.progress.path_length;
                // Until the planner's first update, the checkpointed record
                // stands (a checkpoint written meanwhile keeps it).
                if let Some(sw) = &r.swept {
                    s.covered_area = sw.area();
                    s.swept = Some(Arc::new(sw.clone()));
                }
                s.grid = Some(Arc::new(r.grid.clone()));
                s.keyframes = r.tracker.clone().map(Arc::new);
                s.lattice = r.lattice;
                s.home = r.home;
                s.tries = r.tries.clone().map(Arc::new);
                s.reach = r.reach.clone().map(Arc::new);
                if !r.contacts.is_empty() {
                    s.contacts = Some(Arc::new(stages::contact_arcs(&r.contacts)));
                }
                // Later checkpoints keep the refitted mount.
                s.refitted_mount = (mount != robot.scanner_mount()).then_some(mount);
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

        let restored = setup.resume.as_ref().and_then(|r| r.tracker.as_ref());
        let (tracker, refused) = Tracker::restore(
            cfg.icp.clone(),
            start * mount,
            restored.unwrap_or(&TrackerState::default()),
        )
        .map_err(|e| DaemonError::Config(e.to_string()))?;
        match (restored, refused) {
            (Some(k), None) => log::info!(
                "resume: scan tracker restored with {} keyframe(s)",
                k.keyframes.len()
            ),
            (Some(_), Some(e)) => {
                log::warn!("resume: checkpointed keyframes unusable ({e}); new local map")
            }
            (None, _) if setup.resume.is_some() => {
                log::info!("resume: no keyframes checkpointed; new local map")
            }
            _ => {}
        }
        let decomposer = Decomposer::new(&cfg.decomp, robot.radius)
            .map_err(|e| DaemonError::Config(e.to_string()))?;
        let mut planner = CoveragePlanner::new(&cfg.plan, &robot)
            .map_err(|e| DaemonError::Config(e.to_string()))?;
        if let Some(swept) = setup.resume.as_ref().and_then(|r| r.swept.clone()) {
            planner.restore_swept(swept);
        }
        if let Some(l) = setup.resume.as_ref().and_then(|r| r.lattice) {
            planner.restore_lattice(l);
        }
        match setup.resume.as_ref().map(|r| r.home) {
            Some(Some(h)) => planner.restore_home(h),
            Some(None) if cfg.plan.return_home => log::info!(
                "resume: the checkpoint holds no start (an older build wrote it); once coverage is done the robot drives back to where it was resumed"
            ),
            _ => {}
        }
        if let Some(r) = setup.resume.as_ref().and_then(|r| r.reach.clone()) {
            planner.restore_reach(r);
        }
        if let Some(t) = setup.resume.as_ref().and_then(|r| r.tries.clone()) {
            planner.restore_tries(t);
        }
        planner.record_pose(&start);
        let follower = PathFollower::new(&cfg.control, &robot)
            .map_err(|e| DaemonError::Config(e.to_string()))?
            .with_command_horizon(cfg.motor.deadman);

        let driver = UrgDriver::start(setup.scanner, cfg.scanner.clone(), clock.clone())?;
        let urg_health = driver.health();
        let now = clock.now();

        pipeline.spawn(
            "motor",
            stages::MotorStage {
                base: setup.base,
                rx: cmd_rx,
                to_map: map_tx.clone(),
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
        pipeline.spawn(
            "plan",
            stages::PlanStage {
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
                tries_published: 0,
                reach_published: 0,
                contacts_seen: 0,
                bump_handled: f64::NEG_INFINITY,
                contact_settle: cfg.daemon.contact.settle,
                probe: stages::MarkProbe::new(
                    map_tx.clone(),
                    cfg.daemon.contact.retry_walled_floor,
                    cfg.plan.min_lane_area,
                    2.0 * robot.radius,
                    setup
                        .resume
                        .as_ref()
                        .map(|r| r.tried.clone())
                        .unwrap_or_default(),
                    &shared,
                ),
            },
        )?;
        let contacts = setup
            .resume
            .as_ref()
            .map(|r| r.contacts.clone())
            .unwrap_or_default();
        if !contacts.is_empty() {
            log::info!("resume: {} bumper contact mark(s) restored", contacts.len());
        }
        pipeline.spawn(
            "map",
            stages::MapStage::new(
                grid,
                map_rx,
                snap_tx,
                shared.clone(),
                MAP_MAX_RANGE,
                contacts,
                cfg.daemon.contact.same_contact,
            ),
        )?;
        pipeline.spawn(
            "localise",
            stages::LocaliseStage {
                tracker,
                rx: scan_rx,
                to_control: fix_tx,
                to_map: map_tx,
                shared: shared.clone(),
                mount,
                wheel_base: robot.wheel_base,
                wheel_radius: robot.wheel_radius,
                fit_mount: cfg.daemon.fit_scanner_mount,
                check_min_information: cfg.icp.degeneracy_threshold
                    * stages::CHECK_INFORMATION_FACTOR,
                deskew: cfg.daemon.deskew_scans,
                points: Vec::with_capacity(crate::capacity::MAX_BEAMS),
                relocalise_on: setup.resume.as_ref().map(|r| Arc::new(r.grid.clone())),
                publish_keyframes: setup.state_dir.is_some(),
                last_stamp: None,
                unmatched_run: 0,
                align: (setup.resume.is_none() && cfg.daemon.align_to_walls)
                    .then(align::WallAlign::new),
                turn_check: turn_check::TurnCheck::default(),
                travel_check: travel_check::TravelCheck::new(heading(&mount)),
                offset_check: offset_check::OffsetCheck::new(heading(&mount)),
                offset_fitted: resume::offset_was_fitted(&robot.scanner_mount(), &mount),
            },
        )?;
        pipeline.spawn(
            "scanner",
            stages::ScannerStage {
                driver: Some(driver),
                tx: scan_tx,
                shared: shared.clone(),
                upside_down: robot.scanner_upside_down,
            },
        )?;
        Ok(Daemon {
            pipeline,
            supervisor,
            shared,
            urg_health,
            clock,
            resume_entry: setup.resume.as_ref().map(|r| r.entry.clone()),
            resume: setup.resume.map(|r| r.progress),
            state_dir: setup.state_dir,
            checkpoint_period: cfg.pipeline.checkpoint_period,
            heartbeat_period: cfg.pipeline.heartbeat_period,
            robot: cfg.robot.clone(),
        })
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
