//! The closed-loop simulation behind `sweepline sim`: the emulated URG-04LX
//! and wheel base on pseudo-terminals, the daemon opening both pty paths as
//! it would open `/dev/ttyACM0`, all on one scaled clock.
//!
//! The base emulator integrates the kinematics (the ground truth); the
//! scanner emulator ray-casts the world at that true pose; the daemon only
//! sees bytes. A sampler on the same clock records the true trajectory (for
//! the coverage metric, the same code as the lock-step simulation) and the
//! daemon's pose estimate beside it (for the pose error).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use nalgebra::Point2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::base_emu::{self, EmuStats, EmulatorHandle, Fault};
use crate::clock::{PaceStats, PacedClock, ScaledClock, SharedClock};
use crate::config::Config;
use crate::control::{integrate, Twist, WheelCmd};
use crate::coverage_metrics::{CoverageMetrics, CoverageTracker, MetricsError};
use crate::daemon::{Daemon, DaemonSetup, MapFrame};
use crate::geom::{heading, interpolate, pose_error, wrap_angle, Pose};
use crate::motor::{BaseKind, LinkHealth};
use crate::pipeline::metrics::MetricsSnapshot;
use crate::pipeline::supervisor::StopReason;
use crate::report::run_folder::RunFolderHooks;
use crate::serial::DeviceConnector;
use crate::urg::HealthSnapshot;
use crate::urg_emu::{self, Echo, Scene};
use crate::walker::{cast_ray_among, lock_crowd, touches, Body, Crowd};
use crate::world::World;

/// Sampling period of the truth and the estimate (clock s).
pub const SAMPLE_PERIOD: f64 = 0.05;
/// Shortest dead-man time in wall seconds under time scaling.
pub const DEADMAN_WALL: f64 = 0.05;
/// Longest range the emulated URG-04LX reports (m).
pub(crate) const URG_RANGE: f64 = 5.6;

/// Why a simulation could not run.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The world's start pose is not free.
    #[error("world: {0}")]
    Start(#[from] MetricsError),
    /// An emulator could not start.
    #[error("emulator: {0}")]
    Emulator(String),
    /// The daemon could not start.
    #[error("daemon: {0}")]
    Daemon(#[from] crate::daemon::DaemonError),
    /// A bad option.
    #[error("{0}")]
    BadOption(String),
    /// The report could not be written.
    #[error("cannot write the report into {dir}: {source}")]
    Report {
        /// The folder.
        dir: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}

/// A fault injected at a given simulated time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimedFault {
    /// Simulated time (s from the start).
    pub at: f64,
    /// The fault, on the wheel-base link.
    pub fault: Fault,
}

/// How long after a motion fault its recovery is watched (s).
pub const FAULT_HORIZON: f64 = 30.0;
/// Position error (m) under which the pose counts as found again.
pub const FAULT_SETTLED: f64 = 0.02;
/// How long (s) the error must stay under [`FAULT_SETTLED`], matched scans
/// never more than [`FAULT_MAX_GAP`] apart, for the pose to count as found
/// again: a turn's single spike of 2-4 cm later on (which runs without
/// faults show too) says nothing of the fault.
pub const FAULT_HOLD: f64 = 5.0;
/// Longest time between matched scans within [`FAULT_HOLD`] (s).
pub const FAULT_MAX_GAP: f64 = 1.0;

/// How the localisation came back after one injected motion fault (slip,
/// kidnap, knock), from the matched scans within [`FAULT_HORIZON`] after it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultRecovery {
    /// When it was injected (s from the start).
    pub at: f64,
    /// What it was.
    pub fault: Fault,
    /// Largest position error of a matched scan (m).
    pub peak: f64,
    /// From the fault to the first matched scan from which on the error
    /// stays under [`FAULT_SETTLED`] for [`FAULT_HOLD`] (s; `None`: not
    /// within the horizon).
    pub settled_after: Option<f64>,
    /// Longest time without a matched scan, the fault's moment included (s).
    pub longest_gap: f64,
    /// Matched scans within the horizon.
    pub scans: usize,
}

impl FaultRecovery {
    /// The recovery after the fault `fault` at clock time `at` (s), from
    /// the matched scans `pairs` (clock times); `start` is the run's start.
    pub(crate) fn of(fault: &TimedFault, start: f64, pairs: &[FixPair]) -> Self {
        let at = start + fault.at;
        let end = at + FAULT_HORIZON;
        let (mut peak, mut good_since, mut settled, mut gap, mut last, mut n) =
            (0.0f64, None::<f64>, None, 0.0f64, at, 0);
        for p in pairs.iter().filter(|p| p.t >= at && p.t <= end) {
            let e = p.position_error();
            peak = peak.max(e);
            good_since = match good_since {
                _ if e >= FAULT_SETTLED || p.t - last > FAULT_MAX_GAP => {
                    (e < FAULT_SETTLED).then_some(p.t)
                }
                None => Some(p.t),
                since => since,
            };
            if let (None, Some(since)) = (settled, good_since) {
                if p.t - since >= FAULT_HOLD {
                    settled = Some(since - at);
                }
            }
            gap = gap.max(p.t - last);
            last = p.t;
            n += 1;
        }
        Self {
            at: fault.at,
            fault: fault.fault,
            peak,
            settled_after: settled,
            longest_gap: gap.max(end.min(pairs.last().map_or(at, |p| p.t)) - last),
            scans: n,
        }
    }
}

/// How the simulated clock waits for the daemon (see [`PacedClock`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pace {
    /// Simulated seconds a scan handed out may go unprocessed before the
    /// clock stands still.
    pub lead: f64,
    /// Wall time the clock stands still for one scan at most.
    pub max_hold: Duration,
}

impl Default for Pace {
    /// A scan may be 50 ms of simulated time out before time waits for
    /// it: half a URG-04LX scan period, many times the localise stage's
    /// median time per scan (about 1 ms in `report.md`), so a daemon
    /// keeping up is never held.
    fn default() -> Self {
        Self {
            lead: 0.05,
            max_hold: Duration::from_secs(1),
        }
    }
}

/// Settings of one closed-loop run.
#[derive(Clone)]
pub struct SimOptions {
    /// The world.
    pub world: Arc<World>,
    /// The robot configuration the daemon runs with.
    pub config: Config,
    /// Time scale (simulated seconds per wall second): the most the
    /// simulated clock runs when [`SimOptions::pace`] is set.
    pub speed: f64,
    /// Hold the simulated clock while the daemon is behind with a scan
    /// (see [`PacedClock`]); `None`: a fixed time scale.
    pub pace: Option<Pace>,
    /// Report folder (none: no files).
    pub out: Option<PathBuf>,
    /// Which wheel base is emulated.
    pub base: BaseKind,
    /// Seed of the noise.
    pub seed: u64,
    /// Simulated time after which the run is stopped unfinished (s).
    pub time_cap: f64,
    /// Print progress lines.
    pub progress: bool,
    /// Faults of the scanner emulator.
    pub urg_faults: urg_emu::Faults,
    /// Faults of the base emulator, by time.
    pub base_faults: Vec<TimedFault>,
    /// Range noise of the scanner (m, standard deviation).
    pub range_noise: f64,
    /// The daemon is told a start heading this far off the true one (rad):
    /// a robot switched on at an angle to the walls, whose map frame must
    /// be laid along them. Poses are scored in the world frame through the
    /// frame the daemon chose.
    pub heading_error: f64,
    /// Each wheel covers this share more floor than its encoder counts, on
    /// top of the kinematics' own small errors (0.03: odometry 3 % short).
    pub odometry_scale_error: f64,
    /// The emulated scanner's true mount (its pose on the robot, upside
    /// down) when it differs from what `config.robot` tells the daemon: a
    /// wrongly configured robot. `None`: as configured.
    pub scanner_truth: Option<(Pose, bool)>,
    /// The emulated base's true wheel base (m) when it differs from
    /// `config.robot.wheel_base`: a wrongly configured robot. `None`: as
    /// configured.
    pub wheel_base_truth: Option<f64>,
    /// The emulated base's true wheel radius (m) when it differs from
    /// `config.robot.wheel_radius`: the wheels drive and count as wheels of
    /// this radius. `None`: as configured.
    pub wheel_radius_truth: Option<f64>,
    /// The emulated RoboClaw's motor 1 drives the other wheel than
    /// `motor.roboclaw.m1_is_left` says (motors and encoders swapped
    /// left for right).
    pub wheels_swapped: bool,
    /// Serve the live view on this address (`host:port`; none: off).
    pub live: Option<String>,
    /// Write `run.mcap` into the report folder (when there is one).
    pub record: bool,
}

impl SimOptions {
    /// The emulated scanner's true mount and whether it is upside down:
    /// [`SimOptions::scanner_truth`], or as configured.
    pub(crate) fn true_mount(&self) -> (Pose, bool) {
        let r = &self.config.robot;
        self.scanner_truth
            .unwrap_or((r.scanner_mount(), r.scanner_upside_down))
    }

    /// The emulated base's true wheel base (m):
    /// [`SimOptions::wheel_base_truth`], or as configured.
    pub(crate) fn true_wheel_base(&self) -> f64 {
        self.wheel_base_truth
            .unwrap_or(self.config.robot.wheel_base)
    }

    /// Defaults for `world`: RoboClaw base, at most ×10 paced by the
    /// daemon, 1 h cap.
    pub fn new(world: World, config: Config) -> Self {
        Self {
            world: Arc::new(world),
            config,
            speed: 10.0,
            pace: Some(Pace::default()),
            out: None,
            base: BaseKind::Roboclaw,
            seed: 1,
            time_cap: 3600.0,
            progress: false,
            urg_faults: urg_emu::Faults::default(),
            base_faults: Vec::new(),
            range_noise: 0.005,
            heading_error: 0.0,
            odometry_scale_error: 0.0,
            scanner_truth: None,
            wheel_base_truth: None,
            live: None,
            record: true,
            wheel_radius_truth: None,
            wheels_swapped: false,
        }
    }
}

/// What a run measured.
#[derive(Clone, Debug)]
pub struct SimReport {
    /// Ground-truth coverage figures.
    pub metrics: CoverageMetrics,
    /// How the localisation came back after each injected motion fault.
    pub fault_recovery: Vec<FaultRecovery>,
    /// RMS position error of the localised poses (ICP at each scan) against
    /// the true pose the scan was cast from (m).
    pub position_rmse: f64,
    /// RMS heading error of the localised poses (rad).
    pub heading_rmse: f64,
    /// Largest position error of a localised pose (m).
    pub position_max: f64,
    /// Localised poses scored.
    pub scored_fixes: usize,
    /// Shift of the scan stamps against the emulator's sampling times that
    /// fits best (s; diagnostic of the scanner's time stamping, see
    /// `best_stamp_shift`; 0 when the stamps are right).
    pub stamp_offset: f64,
    /// Rotation (rad) the daemon turned its start heading by to lay its map
    /// along the walls (`None`: not decided, or `daemon.align_to_walls` off).
    pub frame_turn: Option<f64>,
    /// The turn of the scans' walls over the wheels' over the first quarter
    /// turn (the daemon's check of the scanner's mount; `None`: not reached).
    pub turn_ratio: Option<f64>,
    /// The scans' travel against the wheels' over the first metre driven
    /// straight (the daemon's check of the scanner's yaw; `None`: not reached).
    pub travel_fit: Option<sweepline_core::checks::travel_check::TravelFit>,
    /// The scanner offset the daemon fitted from its first half turn in
    /// place (`None`: not reached).
    pub offset_fit: Option<sweepline_core::checks::offset_check::OffsetFit>,
    /// The scanner mount the daemon refitted from those checks (`None`: it
    /// drove with the configured one).
    pub refitted_mount: Option<Pose>,
    /// The daemon's map frame in the world (identity but for the frame
    /// turn and the told start heading): `map_to_world * estimate` is in the
    /// world frame.
    pub map_to_world: Pose,
    /// RMS position error of the control stage's live estimate (last fix
    /// composed with odometry) sampled every 50 ms against the truth at the
    /// same instant (m); includes up to one control period of lag.
    pub(crate) live_position_rmse: f64,
    /// RMS heading error of the live estimate (rad).
    pub(crate) live_heading_rmse: f64,
    /// Largest position error of the live estimate (m).
    pub(crate) live_position_max: f64,
    /// True when the daemon finished coverage by itself.
    pub finished: bool,
    /// True when the simulation time cap stopped the run.
    pub capped: bool,
    /// Why the daemon stopped.
    pub reason: String,
    /// Wall-clock duration of the run (s).
    pub wall: f64,
    /// Simulated duration (s).
    pub sim_time: f64,
    /// The scanner link's counters.
    pub urg: HealthSnapshot,
    /// The wheel-base link's counters (daemon side).
    pub base: LinkHealth,
    /// The base emulator's counters.
    pub base_emu: EmuStats,
    /// Scans the daemon localised and how many fell back to odometry.
    pub scans: (u64, u64),
    /// The scan tracker's correlative searches and their CPU per searching
    /// scan (sum, largest; s).
    pub searches: (sweepline_core::icp::SearchCounts, (f64, f64)),
    /// Times the daemon lost the robot and found it again over the whole
    /// map (`daemon.lost_after`), and whether it was lost at the end.
    pub relocalisations: (u64, bool),
    /// Safety events the daemon saw.
    pub safety_events: u64,
    /// Paths the daemon gave up because the robot made no headway on them.
    pub stuck_paths: u64,
    /// Times the daemon slowed or stopped short of something the scan
    /// showed ahead that its path did not expect (the protective field).
    pub guard_stops: u64,
    /// How the drive back to the start ended (`None`: coverage did not
    /// finish).
    pub home: Option<crate::plan::HomeOutcome>,
    /// Where the robot ended from where it started, by the ground truth (m).
    pub ended_from_start: f64,
    /// Bumper contact marks taken out to try the floor they walled off.
    pub marks_taken_out: u64,
    /// The daemon's planner counters at the end (tasks, plans started over).
    pub plan_stats: crate::plan::planner::PlanStats,
    /// Times the daemon held the wheels because no scan came.
    pub scan_holds: u64,
    /// What the paced clock did (`None`: a fixed time scale).
    pub pace: Option<PaceStats>,
    /// The bumper contacts marked in the map (robot centre and contact
    /// point, map frame).
    pub contacts: Vec<crate::pipeline::checkpoint::ContactArc>,
    /// The pipeline's final metrics.
    pub pipeline: MetricsSnapshot,
    /// True trajectory (one pose per sample).
    pub truth: Vec<Pose>,
    /// Estimated trajectory (same samples), in the daemon's map frame.
    pub estimate: Vec<Pose>,
    /// Every scored localised pose with its true pose (see `fix_pairs`),
    /// both in the world frame.
    pub fixes: Vec<FixPair>,
}

/// True poses at the times the emulated scanner sampled the world.
type TruthLog = Arc<std::sync::Mutex<Vec<(f64, Pose)>>>;

/// Localised poses `fixes` paired with the truth log `truth` (both sorted
/// by time): each fix with the truth sample nearest to its time shifted by
/// `offset`, within `tolerance`, as (fix time, fix, truth).
pub(crate) fn fix_pairs(
    fixes: &[(f64, Pose)],
    truth: &[(f64, Pose)],
    offset: f64,
    tolerance: f64,
) -> Vec<FixPair> {
    let mut out = Vec::with_capacity(fixes.len());
    for (t, p) in fixes {
        let ts = t + offset;
        let i = truth.partition_point(|(tt, _)| *tt < ts);
        let best = [i.wrapping_sub(1), i]
            .into_iter()
            .filter_map(|k| truth.get(k))
            .min_by(|a, b| (a.0 - ts).abs().total_cmp(&(b.0 - ts).abs()));
        if let Some((tt, q)) = best {
            if (tt - ts).abs() <= tolerance {
                out.push(FixPair {
                    t: *t,
                    fix: *p,
                    truth: *q,
                });
            }
        }
    }
    out
}

/// A localised pose and the true pose it is scored against.
#[derive(Clone, Copy, Debug)]
pub struct FixPair {
    /// Stamp of the fix (clock s).
    pub t: f64,
    /// The localised robot pose.
    pub fix: Pose,
    /// The true robot pose at the scan.
    pub truth: Pose,
}

impl FixPair {
    /// Position error (m).
    pub(crate) fn position_error(&self) -> f64 {
        pose_error(&self.fix, &self.truth).0
    }

    /// Heading error (rad, wrapped).
    pub fn heading_error(&self) -> f64 {
        pose_error(&self.fix, &self.truth).1
    }
}

/// The pose error of localised robot poses `fixes` (map frame, sorted by
/// time) against the true poses `truth` (world frame), the map lying at
/// `map_to_world`, scored as a closed-loop run's report scores them:
/// (position RMSE m, heading RMSE rad, max position error m, pairs).
pub fn score_fixes(
    fixes: &[(f64, Pose)],
    truth: &[(f64, Pose)],
    map_to_world: &Pose,
) -> (f64, f64, f64, usize) {
    let world: Vec<(f64, Pose)> = fixes.iter().map(|(t, p)| (*t, map_to_world * p)).collect();
    fix_errors(&fix_pairs(&world, truth, 0.0, FIX_TOLERANCE))
}

/// A fix is scored against the truth sample nearest its stamp within this (s).
const FIX_TOLERANCE: f64 = 0.2;

/// Pose error of the `pairs` of [`fix_pairs`]: (position RMSE, heading
/// RMSE, max position error, pairs).
pub(crate) fn fix_errors(pairs: &[FixPair]) -> (f64, f64, f64, usize) {
    let (mut sp, mut sh, mut mx) = (0.0, 0.0, 0.0f64);
    for pr in pairs {
        let (e, eh) = (pr.position_error(), pr.heading_error());
        sp += e * e;
        sh += eh * eh;
        mx = mx.max(e);
    }
    let d = pairs.len().max(1) as f64;
    ((sp / d).sqrt(), (sh / d).sqrt(), mx, pairs.len())
}

/// Largest shift [`best_stamp_shift`] tries (s).
pub(crate) const MAX_STAMP_SHIFT: f64 = 0.1;
/// Step of the shifts [`best_stamp_shift`] tries (s).
pub(crate) const STAMP_SHIFT_STEP: f64 = 0.002;

/// The true pose at time `t` from the sorted log `truth`, interpolated
/// between the two samples around it when they are at most `gap` apart.
pub(crate) fn truth_at(truth: &[(f64, Pose)], t: f64, gap: f64) -> Option<Pose> {
    let i = truth.partition_point(|(tt, _)| *tt < t);
    let (t1, b) = truth.get(i)?;
    if (t1 - t).abs() < 1e-9 {
        return Some(*b);
    }
    let (t0, a) = truth.get(i.checked_sub(1)?)?;
    if !(t1 - t0 > 0.0 && t1 - t0 <= gap) {
        return None;
    }
    Some(interpolate(a, b, (t - t0) / (t1 - t0)))
}

/// The shift of the localised poses' stamps against the truth log that
/// fits best (s, within ±[`MAX_STAMP_SHIFT`]): the truth is interpolated at
/// each shifted stamp (pairing with the nearest sample instead cannot tell
/// shifts within half a scan period apart), and the score is the mean of
/// the squared position error plus the squared heading error times 0.1 m.
/// Zero when the stamps are the times the scans were taken.
pub(crate) fn best_stamp_shift(fixes: &[(f64, Pose)], truth: &[(f64, Pose)]) -> f64 {
    let n = (MAX_STAMP_SHIFT / STAMP_SHIFT_STEP).round() as i32;
    let score = |o: f64| {
        let (mut s, mut k) = (0.0, 0usize);
        for (t, p) in fixes {
            let Some(q) = truth_at(truth, t + o, 0.25) else {
                continue;
            };
            let e = (p.translation.vector - q.translation.vector).norm_squared();
            let h = wrap_angle(heading(p) - heading(&q)) * 0.1;
            s += e + h * h;
            k += 1;
        }
        if k == 0 {
            f64::INFINITY
        } else {
            s / k as f64
        }
    };
    // Ties (no motion) resolve to the smallest shift.
    (-n..=n)
        .map(|k| f64::from(k) * STAMP_SHIFT_STEP)
        .min_by(|a, b| {
            score(*a)
                .total_cmp(&score(*b))
                .then(a.abs().total_cmp(&b.abs()))
        })
        .unwrap_or(0.0)
}

fn to_cmd(w: crate::motor::WheelSpeeds) -> WheelCmd {
    WheelCmd {
        left: w.left,
        right: w.right,
    }
}

/// The world as the emulated scanner sees it, from the true pose of the
/// emulated base.
struct WorldScene {
    world: Arc<World>,
    base: Arc<EmulatorHandle>,
    seen: TruthLog,
    wheel_base: f64,
    /// The scanner's pose on the robot.
    mount: Pose,
    /// The scanner is mounted upside down (it sweeps clockwise).
    upside_down: bool,
    noise: f64,
    rng: ChaCha8Rng,
    /// People walking through the room (stepped by the base emulator).
    crowd: Arc<Mutex<Crowd>>,
    /// The paced clock, told of every scan handed out.
    pace: Option<Arc<PacedClock>>,
    /// Scratch: where the people are for this scan.
    bodies: Vec<Body>,
    /// Scratch: the base's true poses since the scan's stamp.
    path: Vec<(f64, Pose)>,
}

impl WorldScene {
    fn gauss(&mut self) -> f64 {
        let u1: f64 = self.rng.random_range(1e-12..1.0);
        let u2: f64 = self.rng.random_range(0.0..1.0);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

impl Scene for WorldScene {
    fn sample(&mut self, t: f64, step_time: f64, angles: &[f64], out: &mut [Echo]) {
        // A revolution's steps are looked up after it ends (the sensor sends
        // it then), each at its own time: between the true poses the base
        // emulator reached meanwhile, and beyond the newest one (the two
        // emulator threads run independently) along its current motion.
        // (Taking the pose at the clock's `now` for a whole scan made every
        // scan ~40 ms older than its stamp at ×8-10.)
        let (at, truth) = self.base.truth_stamped();
        let twist = Twist::from_wheels(&to_cmd(self.base.wheels()), self.wheel_base);
        let mut path = std::mem::take(&mut self.path);
        self.base.truth_since(t, &mut path);
        let pose_at = |tau: f64| match path.partition_point(|h| h.0 <= tau) {
            n if n > 0 && n < path.len() => {
                let ((t0, p0), (t1, p1)) = (path[n - 1], path[n]);
                crate::geom::interpolate(&p0, &p1, (tau - t0) / (t1 - t0).max(1e-9))
            }
            _ => integrate(&truth, &twist, (tau - at).clamp(-0.3, 0.3)),
        };
        let p = pose_at(t);
        if let Ok(mut g) = self.seen.lock() {
            g.push((t, p));
        }
        let turn = if self.upside_down { -1.0 } else { 1.0 };
        self.bodies.clear();
        self.bodies
            .extend_from_slice(lock_crowd(&self.crowd).bodies());
        for (k, (a, e)) in angles.iter().zip(out.iter_mut()).enumerate() {
            // Each beam from where the sensor is when it is measured.
            let at_beam = pose_at(t + k as f64 * step_time);
            let sensor = at_beam * self.mount;
            let th = heading(&sensor);
            let o = Point2::from(sensor.translation.vector);
            *e = match cast_ray_among(&self.world, &self.bodies, &o, th + turn * a, URG_RANGE) {
                Some(hit) => {
                    let r = hit.range + self.noise * self.gauss();
                    Echo::Hit {
                        range: r.max(0.0),
                        reflectivity: hit.reflectivity,
                        // Never quite edge-on: a wall seen along its
                        // length still returns some light.
                        cos_incidence: hit.incidence.cos().abs().max(0.05),
                    }
                }
                None => Echo::NoReturn,
            };
        }
        self.path = path;
        if let Some(pace) = &self.pace {
            pace.pending(t);
        }
    }
}

/// The map frame the daemon gets for `world`: its bounding box plus a margin.
pub(crate) fn map_frame(world: &World) -> MapFrame {
    let g = crate::lockstep::grid_for(world, 0.05, 0.5, 0.0);
    MapFrame {
        origin: g.origin(),
        resolution: g.resolution(),
        width: g.width(),
        height: g.height(),
    }
}

/// The start pose the daemon is told: the true one with the heading off
/// by [`SimOptions::heading_error`].
fn told_start(opts: &SimOptions) -> Pose {
    opts.world.start * crate::geom::pose(0.0, 0.0, opts.heading_error)
}

/// The map frame to the world frame: the daemon's start pose of its
/// scanner (the told robot pose turned by the daemon's `frame_turn`, once
/// decided, through the configured mount) is the scanner's true start.
fn to_world(opts: &SimOptions, turn: Option<f64>) -> Pose {
    let configured = opts.config.robot.scanner_mount();
    let truth = opts.true_mount().0;
    let start = told_start(opts) * crate::geom::pose(0.0, 0.0, turn.unwrap_or(0.0)) * configured;
    opts.world.start * truth * start.inverse()
}

/// A map frame for a daemon whose frame may lie at any angle to the world:
/// a square around the start reaching the world's farthest corner.
pub(crate) fn map_frame_around_start(world: &World) -> MapFrame {
    let g = map_frame(world);
    let s = world.start.translation;
    let (w, h) = (
        g.width as f64 * g.resolution,
        g.height as f64 * g.resolution,
    );
    let reach = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
        .iter()
        .map(|(dx, dy)| {
            (Point2::new(g.origin.x + dx, g.origin.y + dy) - Point2::new(s.x, s.y)).norm()
        })
        .fold(0.0f64, f64::max);
    MapFrame::centred(Point2::new(s.x, s.y), 2.0 * reach, g.resolution)
}

/// A fresh folder for the device symlinks of one run.
fn link_dir() -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static RUN: AtomicU64 = AtomicU64::new(0);
    std::env::temp_dir().join(format!(
        "sweepline-sim-{}-{}",
        std::process::id(),
        RUN.fetch_add(1, Ordering::Relaxed)
    ))
}

fn start_emulators(
    opts: &SimOptions,
    clock: &SharedClock,
    pace: Option<Arc<PacedClock>>,
    seen: TruthLog,
    crowd: Arc<Mutex<Crowd>>,
    links: &Path,
) -> Result<(Arc<EmulatorHandle>, urg_emu::Emulator), SimError> {
    let mut ecfg = base_emu::EmulatorConfig::from_config(&opts.config, opts.base);
    ecfg.start = opts.world.start;
    ecfg.world = Some(opts.world.clone());
    ecfg.crowd = Some(crowd.clone());
    ecfg.seed = opts.seed;
    ecfg.kinematics.seed = opts.seed;
    let wheel_base = opts.true_wheel_base();
    ecfg.kinematics.wheel_base = wheel_base;
    let (el, er) = ecfg.kinematics.scale_error;
    let e = opts.odometry_scale_error;
    ecfg.kinematics.scale_error = (el + e, er + e);
    if let Some(r) = opts.wheel_radius_truth {
        ecfg.wheel_radius = r;
    }
    if opts.wheels_swapped {
        ecfg.motor.roboclaw.m1_is_left = !ecfg.motor.roboclaw.m1_is_left;
    }
    // Stable symlinks, like the udev names on the robot: they follow the
    // emulators' ptys over unplug and replug.
    std::fs::create_dir_all(links)
        .map_err(|e| SimError::Emulator(format!("cannot create {}: {e}", links.display())))?;
    let base = Arc::new(
        base_emu::spawn_on_pty(ecfg, Some(links.join("base")), clock.clone())
            .map_err(|e| SimError::Emulator(e.to_string()))?,
    );
    let (mount, upside_down) = opts.true_mount();
    let scene = WorldScene {
        world: opts.world.clone(),
        base: base.clone(),
        seen,
        wheel_base,
        mount,
        upside_down,
        noise: opts.range_noise,
        rng: ChaCha8Rng::seed_from_u64(opts.seed ^ 0x5ca1),
        crowd,
        pace,
        bodies: Vec::new(),
        path: Vec::new(),
    };
    let ucfg = urg_emu::EmulatorConfig {
        faults: opts.urg_faults.clone(),
        link: Some(links.join("urg")),
        seed: opts.seed,
        ..Default::default()
    };
    let urg = urg_emu::Emulator::spawn(ucfg, Box::new(scene), clock.clone())
        .map_err(|e| SimError::Emulator(e.to_string()))?;
    Ok((base, urg))
}

/// Starts only the two emulators of `opts` on ptys, on `clock`, with stable
/// symlinks `links/urg` and `links/base`: for a test that runs the daemon as
/// a separate `sweepline run` process (and kills it) against them.
pub fn spawn_emulators(
    opts: &SimOptions,
    clock: &SharedClock,
    links: &Path,
) -> Result<(Arc<EmulatorHandle>, urg_emu::Emulator), SimError> {
    let crowd = Arc::new(Mutex::new(Crowd::new(&opts.world.walkers)));
    start_emulators(opts, clock, None, Arc::default(), crowd, links)
}

/// Runs one closed-loop coverage of `opts.world` and writes the report
/// folder when `opts.out` is set.
pub fn run(opts: &SimOptions) -> Result<SimReport, SimError> {
    if !(opts.speed.is_finite() && opts.speed > 0.0) {
        return Err(SimError::BadOption(format!(
            "--speed must be a positive number, got {}",
            opts.speed
        )));
    }
    let robot = opts.config.robot.clone();
    // Reachable floor is what the body can reach: the free raster leaves
    // out the `low` obstacles the scanner cannot see too.
    let tracker = CoverageTracker::new(
        &opts.world,
        robot.radius,
        robot.tool_width,
        &opts.world.start,
    )?
    .with_clearance(opts.config.plan.safety_margin);
    let wall0 = Instant::now();
    let pace = opts
        .pace
        .map(|p| Arc::new(PacedClock::new(opts.speed, p.lead, p.max_hold)));
    let clock: SharedClock = match &pace {
        Some(p) => p.clone(),
        None => Arc::new(ScaledClock::new(opts.speed)),
    };
    let seen: TruthLog = Arc::default();
    let links = link_dir();
    let crowd = Arc::new(Mutex::new(Crowd::new(&opts.world.walkers)));
    let started = start_emulators(
        opts,
        &clock,
        pace.clone(),
        seen.clone(),
        crowd.clone(),
        &links,
    );
    let truth = Truth { seen, crowd, pace };
    let result =
        started.and_then(|(base, urg)| drive(opts, clock, truth, base, urg, tracker, wall0));
    let _ = std::fs::remove_dir_all(&links);
    result
}

/// The run's telemetry: `run.mcap` in the report folder, the live view
/// where asked for (none: neither).
fn start_telemetry(
    opts: &SimOptions,
    (cfg, frame): (&Config, MapFrame),
    daemon: &mut Daemon,
    clock: &SharedClock,
) -> Result<Option<crate::live::Telemetry>, SimError> {
    let record = opts
        .out
        .as_ref()
        .filter(|_| opts.record)
        .map(|o| crate::live::RecordTo::File(o.join("run.mcap")));
    let Some(taps) = daemon.take_taps() else {
        return Ok(None);
    };
    if record.is_none() && opts.live.is_none() {
        return Ok(None);
    }
    let topts = crate::live::TelemetryOptions {
        record,
        record_channels: Vec::new(),
        live: opts.live.clone(),
        mount: opts.config.robot.scanner_mount(),
        sim: true,
        setup: Some(crate::live::recording::Setup {
            config: cfg.clone(),
            start: told_start(opts),
            frame,
        }),
        scanner: Some(daemon.urg_health()),
    };
    crate::live::Telemetry::start(taps, daemon.shared(), clock.clone(), topts)
        .map(Some)
        .map_err(|e| SimError::Emulator(e.to_string()))
}

/// Hands the truth samples logged since the last call to the recorder.
fn send_truth(tx: &crossbeam_channel::Sender<(f64, Pose)>, seen: &TruthLog, sent: &mut usize) {
    let Ok(log) = seen.lock() else { return };
    for &(t, p) in log.iter().skip(*sent) {
        if tx.try_send((t, p)).is_err() {
            break;
        }
        *sent += 1;
    }
}

/// What the emulators share with the run's sampler: the true poses the
/// scans were cast from, and the people walking through.
struct Truth {
    seen: TruthLog,
    crowd: Arc<Mutex<Crowd>>,
    pace: Option<Arc<PacedClock>>,
}

fn drive(
    opts: &SimOptions,
    clock: SharedClock,
    truth: Truth,
    base: Arc<EmulatorHandle>,
    urg: urg_emu::Emulator,
    mut tracker: CoverageTracker,
    wall0: Instant,
) -> Result<SimReport, SimError> {
    let Truth { seen, crowd, pace } = truth;
    let base_path = base
        .path()
        .ok_or_else(|| SimError::Emulator("the base emulator has no pty path".into()))?;
    let urg_path = urg
        .path()
        .ok_or_else(|| SimError::Emulator("the scanner emulator has no pty path".into()))?;
    let mut cfg = opts.config.clone();
    // The daemon's clock runs `speed` times the wall: the report judges
    // the CPU per second of that clock.
    cfg.pipeline.time_scale = opts.speed;
    cfg.motor.kind = opts.base;
    cfg.motor.device = base_path.display().to_string();
    cfg.scanner.port = urg_path.display().to_string();
    // Host scheduling stalls are multiplied by the time scale: give the
    // dead-man at least 50 ms of wall time.
    cfg.motor.deadman = cfg.motor.deadman.max(DEADMAN_WALL * opts.speed);
    let driver = crate::motor::open_base(&cfg.motor, &cfg.robot, clock.clone());
    let frame = if opts.heading_error == 0.0 {
        map_frame(&opts.world)
    } else {
        map_frame_around_start(&opts.world)
    };
    let daemon = Daemon::start(DaemonSetup {
        config: cfg.clone(),
        clock: clock.clone(),
        scanner: Box::new(DeviceConnector::new(urg_path)),
        base: driver,
        start: told_start(opts),
        map: frame,
        resume: None,
        state_dir: opts.out.as_ref().map(|o| o.join("state")),
        taps: true,
    })?;
    let mut daemon = daemon;
    let shared = daemon.shared();
    let telemetry = start_telemetry(opts, (&cfg, frame), &mut daemon, &clock)?;
    let truth_tx = telemetry.as_ref().and_then(|t| t.truth());
    let mut truth_sent = 0usize;
    if let Some(p) = pace.clone() {
        shared.scan_done.set(Box::new(move |t| p.done(t)));
    }
    shared
        .keep_fixes
        .store(true, std::sync::atomic::Ordering::Relaxed);
    let control = daemon.control();
    let urg_health = daemon.urg_health();
    let out = opts.out.clone();
    let pipeline_params = cfg.pipeline.clone();
    let mut hooks = daemon.hooks();
    let runner = std::thread::Builder::new()
        .name("supervisor".into())
        .spawn(move || match &out {
            Some(dir) => {
                let mut h = RunFolderHooks::new(hooks, dir, &pipeline_params);
                daemon.run(&mut h)
            }
            None => daemon.run(&mut hooks),
        })
        .map_err(|e| SimError::Emulator(format!("cannot start the supervisor thread: {e}")))?;

    let t_start = clock.now();
    let mut faults = opts.base_faults.clone();
    faults.sort_by(|a, b| a.at.total_cmp(&b.at));
    let mut next_fault = 0;
    let (mut truth, mut estimate) = (Vec::new(), Vec::new());
    // Truth samples of the last second, for the live estimate's error.
    const RECENT: usize = 40;
    let mut recent: Vec<(f64, Pose)> = Vec::with_capacity(RECENT);
    let (mut se_pos, mut se_head, mut n_err, mut max_err) = (0.0, 0.0, 0usize, 0.0f64);
    let mut last_print = Instant::now();
    let mut capped = false;
    while !runner.is_finished() {
        clock.sleep(SAMPLE_PERIOD);
        let t = clock.now() - t_start;
        while next_fault < faults.len() && faults[next_fault].at <= t {
            log::info!("sim: injecting {:?} at {t:.1} s", faults[next_fault].fault);
            base.inject(faults[next_fault].fault);
            next_fault += 1;
        }
        let (at, p) = base.truth_stamped();
        let (est_map, est_at, turn, motions) =
            shared.with_status(|s| (s.pose, s.pose_time, s.frame_turn, s.path_motions.clone()));
        let est = to_world(opts, turn) * est_map;
        // What the robot is doing: the motion towards the waypoint the
        // control stage heads for on the newest path.
        let progress = shared.progress();
        let (motion, task) = match (motions, progress.next) {
            (Some(m), Some(next)) if m.seq == progress.path_seq => {
                (m.motions.get(next).copied().unwrap_or_default(), m.task)
            }
            (m, _) => (crate::plan::Motion::Other, m.map_or(0, |m| m.task)),
        };
        tracker.record_doing(&p, t, motion, task);
        let centre = Point2::from(p.translation.vector);
        let touching = touches(
            lock_crowd(&crowd).bodies(),
            &centre,
            opts.config.robot.radius,
        );
        tracker.record_contact(touching, &centre, t);
        // The truth at the estimate's own time (both threads run
        // independently): from the recent truth samples when the estimate
        // is older, carried forward along the current motion when newer.
        if recent.last().is_none_or(|(t0, _)| at > *t0) {
            if recent.len() == RECENT {
                recent.remove(0);
            }
            recent.push((at, p));
        }
        let q = match truth_at(&recent, est_at, 0.25) {
            Some(q) if est_at <= at => q,
            _ => {
                let twist = Twist::from_wheels(&to_cmd(base.wheels()), opts.true_wheel_base());
                integrate(&p, &twist, (est_at - at).clamp(-0.3, 0.3))
            }
        };
        let (e, eh) = pose_error(&q, &est);
        se_pos += e * e;
        se_head += eh * eh;
        n_err += 1;
        max_err = max_err.max(e);
        truth.push(p);
        estimate.push(est_map);
        if let Some(tx) = &truth_tx {
            send_truth(tx, &seen, &mut truth_sent);
        }
        if opts.progress && last_print.elapsed().as_secs_f64() >= 2.0 {
            last_print = Instant::now();
            println!(
                "  {:5.1} s wall  {:6.1} s sim  coverage {:5.1} %  pose error {:.3} m  task {}",
                wall0.elapsed().as_secs_f64(),
                t,
                tracker.metrics().coverage * 100.0,
                e,
                shared.with_status(|s| s.task.clone()),
            );
        }
        if t > opts.time_cap && !capped {
            capped = true;
            control.stop("simulation time cap reached");
        }
    }
    let outcome = runner
        .join()
        .map_err(|_| SimError::Emulator("the supervisor thread panicked".into()))?;
    let sim_time = clock.now() - t_start;
    let seen_by_urg = urg.log();
    log::info!(
        "scanner emulator: {} of {} steps sent as error codes ({:.1} %)",
        seen_by_urg.error_steps,
        seen_by_urg.steps,
        100.0 * seen_by_urg.error_share()
    );
    drop(urg);
    let base_emu = base.stats();
    let n = n_err.max(1) as f64;
    let seen = seen.lock().map(|g| g.clone()).unwrap_or_default();
    let frame_turn = shared.with_status(|s| s.frame_turn);
    let to_w = to_world(opts, frame_turn);
    let fixes: Vec<(f64, Pose)> = shared
        .fixes()
        .into_iter()
        .map(|(t, p)| (t, to_w * p))
        .collect();
    if let Some(t) = telemetry {
        let p = &to_w;
        let pairs = vec![
            ("x".to_string(), p.translation.vector.x.to_string()),
            ("y".to_string(), p.translation.vector.y.to_string()),
            ("theta".to_string(), p.rotation.angle().to_string()),
        ];
        let stats = t.finish(vec![(
            crate::live::topics::MAP_TO_WORLD.to_string(),
            pairs.into_iter().collect(),
        )]);
        log::info!(
            "telemetry: {} scans, {} poses, {} truth samples; recording {} bytes",
            stats.scans,
            stats.poses,
            stats.truth,
            stats.recorded_bytes
        );
    }
    let fix_pairs = fix_pairs(&fixes, &seen, 0.0, FIX_TOLERANCE);
    let (pos, head, pmax, pairs) = fix_errors(&fix_pairs);
    let best_offset = best_stamp_shift(&fixes, &seen);
    let (turn_ratio, travel_fit, offset_fit, refitted_mount) = shared.with_status(|s| {
        let refitted = s.localise.mount.map(|m| m.refitted);
        (s.turn_ratio, s.travel_fit, s.offset_fit, refitted)
    });
    let fault_recovery = opts
        .base_faults
        .iter()
        .filter(|f| matches!(f.fault, Fault::Slip { .. } | Fault::Displace { .. }))
        .map(|f| FaultRecovery::of(f, t_start, &fix_pairs))
        .collect();
    let report = SimReport {
        metrics: tracker.metrics(),
        fault_recovery,
        position_rmse: pos,
        heading_rmse: head,
        position_max: pmax,
        scored_fixes: pairs,
        stamp_offset: best_offset,
        frame_turn,
        turn_ratio,
        travel_fit,
        offset_fit,
        refitted_mount,
        map_to_world: to_w,
        live_position_rmse: (se_pos / n).sqrt(),
        live_heading_rmse: (se_head / n).sqrt(),
        live_position_max: max_err,
        finished: matches!(&outcome.reason, StopReason::Requested(w) if w == "coverage finished"),
        capped,
        reason: outcome.reason.to_string(),
        wall: wall0.elapsed().as_secs_f64(),
        sim_time,
        urg: urg_health.snapshot(),
        base: shared.base_health(),
        base_emu,
        scans: shared.with_status(|s| (s.scans, s.fallbacks)),
        searches: shared.with_status(|s| (s.searches, s.search_cpu)),
        relocalisations: (
            shared
                .relocalisations
                .load(std::sync::atomic::Ordering::Relaxed),
            shared.lost.load(std::sync::atomic::Ordering::Relaxed),
        ),
        safety_events: shared
            .safety_events
            .load(std::sync::atomic::Ordering::Relaxed),
        scan_holds: shared.scan_holds.load(std::sync::atomic::Ordering::Relaxed),
        pace: pace.as_ref().map(|p| p.stats()),
        contacts: shared.with_status(|s| {
            s.map
                .contacts
                .as_deref()
                .map(|c| c.arcs.clone())
                .unwrap_or_default()
        }),
        marks_taken_out: shared
            .marks_taken_out
            .load(std::sync::atomic::Ordering::Relaxed),
        plan_stats: shared.with_status(|s| s.plan_stats),
        stuck_paths: shared
            .stuck_paths
            .load(std::sync::atomic::Ordering::Relaxed),
        home: shared.with_status(|s| s.home_outcome),
        ended_from_start: match (truth.first(), truth.last()) {
            (Some(a), Some(b)) => (b.translation.vector - a.translation.vector).norm(),
            _ => 0.0,
        },
        guard_stops: shared
            .guard_stops
            .load(std::sync::atomic::Ordering::Relaxed),
        pipeline: outcome.snapshot,
        truth,
        estimate,
        fixes: fix_pairs,
    };
    if let Some(dir) = &opts.out {
        super::sim_report::write(dir, opts, &report, &tracker, &shared).map_err(|source| {
            SimError::Report {
                dir: dir.clone(),
                source,
            }
        })?;
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    /// A robot driving a curve at 0.2 m/s, 0.5 rad/s: its pose at `t`.
    fn at(t: f64) -> Pose {
        integrate(&pose(1.0, 1.0, 0.0), &Twist { v: 0.2, w: 0.5 }, t)
    }

    /// Matched scans at 10 Hz from the run's start: error 30 mm until 2 s
    /// after a fault at 10 s, none matched from 12 to 13.5 s, 5 mm after,
    /// and one 25 mm spike at 30 s.
    #[test]
    fn a_fault_counts_as_taken_up_once_the_error_stays_low_for_five_seconds() {
        let pairs: Vec<FixPair> = (0..400)
            .map(|k| 100.0 + f64::from(k) * 0.1)
            .filter(|t| !(112.0..113.5).contains(t))
            .map(|t| {
                let e = match t - 100.0 {
                    x if (10.0..12.0).contains(&x) => 0.03,
                    x if (29.95..30.05).contains(&x) => 0.025,
                    _ => 0.005,
                };
                FixPair {
                    t,
                    fix: pose(e, 0.0, 0.0),
                    truth: Pose::identity(),
                }
            })
            .collect();
        let fault = TimedFault {
            at: 10.0,
            fault: Fault::Displace {
                dx: 1.0,
                dy: 0.0,
                turn: 0.0,
            },
        };
        let r = FaultRecovery::of(&fault, 100.0, &pairs);
        assert!((r.peak - 0.03).abs() < 1e-9);
        // From the first scan after the gap (13.5 s), not the one before it.
        let settled = r.settled_after.unwrap();
        assert!((settled - 3.5).abs() < 0.06, "{r:?}");
        assert!((r.longest_gap - 1.6).abs() < 0.06, "{r:?}");
        // The spike 20 s after the fault does not undo it.
        let never = FixPair {
            t: 112.05,
            fix: pose(0.03, 0.0, 0.0),
            truth: Pose::identity(),
        };
        let gapless: Vec<FixPair> = pairs
            .iter()
            .copied()
            .filter(|p| p.t < 112.0)
            .chain([never])
            .collect();
        assert_eq!(
            FaultRecovery::of(&fault, 100.0, &gapless).settled_after,
            None
        );
    }

    #[test]
    fn the_stamp_shift_is_found_between_scan_samples() {
        // Truth sampled at the scan times (10 Hz).
        let truth: Vec<_> = (0..100)
            .map(|k| (k as f64 * 0.1, at(k as f64 * 0.1)))
            .collect();
        // Exact stamps: no shift.
        let exact: Vec<_> = (5..90)
            .map(|k| (k as f64 * 0.1, at(k as f64 * 0.1)))
            .collect();
        assert_eq!(best_stamp_shift(&exact, &truth), 0.0);
        // Stamps 30 ms late (each pose taken 30 ms before its stamp): a
        // shift of -30 ms, though it is under half a scan period.
        let late: Vec<_> = (5..90)
            .map(|k| (k as f64 * 0.1 + 0.03, at(k as f64 * 0.1)))
            .collect();
        let s = best_stamp_shift(&late, &truth);
        assert!((s + 0.03).abs() <= STAMP_SHIFT_STEP, "{s}");
        // Interpolation: halfway between two samples.
        let q = truth_at(&truth, 0.25, 0.2).unwrap();
        let m = at(0.25);
        assert!((q.translation.vector - m.translation.vector).norm() < 1e-3);
        assert!(truth_at(&truth, 50.0, 0.2).is_none());
    }
}
