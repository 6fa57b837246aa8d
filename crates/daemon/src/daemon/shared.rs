//! State the daemon's stages share outside the edges: the wheel odometry
//! (written by the motor stage, read by the scanner and control stages), the
//! follower's progress (control → plan), and the live status the supervisor
//! and the simulator read. Each is a short critical section, never held
//! across I/O or an algorithm.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;

use crate::daemon::messages::MOTION_WINDOW;
use crate::geom::{carried, heading, interpolate, pose, Pose};

/// How many odometry samples are kept for looking up the pose at a scan's time.
const ODOM_HISTORY: usize = 256;

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    match m.lock() {
        Ok(g) => g,
        Err(p) => p.into_inner(),
    }
}

/// The integrated wheel odometry: an absolute pose in the odometry frame,
/// with a short history so a scan can be paired with the odometry at its own
/// time rather than at its arrival.
#[derive(Debug)]
pub struct OdomLog {
    inner: Mutex<VecDeque<(f64, Pose)>>,
}

impl Default for OdomLog {
    fn default() -> Self {
        let mut q = VecDeque::with_capacity(ODOM_HISTORY);
        q.push_back((f64::NEG_INFINITY, Pose::identity()));
        Self {
            inner: Mutex::new(q),
        }
    }
}

impl OdomLog {
    /// Appends the increment `delta` (base frame of the previous reading),
    /// read at clock time `t`.
    pub fn push(&self, t: f64, delta: &Pose) {
        let mut q = lock(&self.inner);
        let last = q.back().map(|s| s.1).unwrap_or_else(Pose::identity);
        let next = last * delta;
        let next = pose(next.translation.x, next.translation.y, heading(&next));
        if q.len() == ODOM_HISTORY {
            q.pop_front();
        }
        q.push_back((t, next));
    }

    /// The newest odometry pose.
    pub fn latest(&self) -> Pose {
        lock(&self.inner)
            .back()
            .map(|s| s.1)
            .unwrap_or_else(Pose::identity)
    }

    /// The odometry pose at clock time `t`, interpolated between the two
    /// readings around it (the oldest or newest one outside the history).
    pub fn at(&self, t: f64) -> Pose {
        pose_at(&lock(&self.inner), t)
    }

    /// The odometry paired with a scan stamped `stamp` whose last beam came
    /// at `sweep_end`, read under one lock so that its parts agree (a
    /// reading arriving between two reads could otherwise mark a held pose
    /// as measured).
    pub(crate) fn for_scan(&self, stamp: f64, sweep_end: f64) -> ScanOdometry {
        let q = lock(&self.inner);
        ScanOdometry {
            pose: pose_at(&q, stamp),
            current: covers(&q, stamp),
            motion: motion_until(&q, sweep_end),
        }
    }
}

/// The odometry a scan is paired with ([`OdomLog::for_scan`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ScanOdometry {
    /// The odometry pose at the scan's time, interpolated between the two
    /// readings around it (the newest reading when none came after it).
    pub pose: Pose,
    /// Whether a reading came at or after the scan's time, so that `pose`
    /// is interpolated rather than held at the newest reading. Only then
    /// does a pose that did not change between two scans say the robot stood
    /// still: odometry late or stopped says nothing of the motion since.
    pub current: bool,
    /// The robot's motion over the [`MOTION_WINDOW`] that ends with the
    /// sweep, or at the newest reading if that is earlier (in its frame at
    /// the window's start): its velocity then. The identity when the newest
    /// reading is a whole window older than the sweep's end: odometry that
    /// stopped coming says nothing of the motion since (and with the motor
    /// link gone the wheels stop).
    pub motion: Pose,
}

/// Clock time of the newest reading (-∞ before the first).
fn newest_time(q: &VecDeque<(f64, Pose)>) -> f64 {
    q.back().map_or(f64::NEG_INFINITY, |s| s.0)
}

/// See [`ScanOdometry::current`].
fn covers(q: &VecDeque<(f64, Pose)>, t: f64) -> bool {
    let newest = newest_time(q);
    newest.is_finite() && t.is_finite() && newest >= t
}

/// See [`ScanOdometry::motion`].
fn motion_until(q: &VecDeque<(f64, Pose)>, end: f64) -> Pose {
    let newest = newest_time(q);
    if !(newest.is_finite() && end.is_finite()) || newest < end - MOTION_WINDOW {
        return Pose::identity();
    }
    let end = end.min(newest);
    pose_at(q, end - MOTION_WINDOW).inverse() * pose_at(q, end)
}

/// See [`OdomLog::at`].
fn pose_at(q: &VecDeque<(f64, Pose)>, t: f64) -> Pose {
    let Some(&(tn, pn)) = q.back() else {
        return Pose::identity();
    };
    if t >= tn || !t.is_finite() {
        return pn;
    }
    let mut after = (tn, pn);
    for &(ts, ps) in q.iter().rev() {
        if ts <= t {
            let span = after.0 - ts;
            if !(span.is_finite() && span > 0.0) {
                return ps;
            }
            return interpolate(&ps, &after.1, (t - ts) / span);
        }
        after = (ts, ps);
    }
    after.1
}

/// Where the follower is on which path, for the planner.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    /// Sequence number of the path being followed.
    pub path_seq: u64,
    /// Index of the waypoint driven to; `None` when the path is finished.
    pub next: Option<usize>,
}

/// What the whole daemon knows now, for status lines, checkpoints and the
/// simulator's pose-error measurement.
#[derive(Clone, Debug)]
pub struct LiveStatus {
    /// The control stage's current pose estimate (last ICP pose composed with
    /// the odometry since).
    pub pose: Pose,
    /// Clock time of that estimate (s).
    pub pose_time: f64,
    /// The estimate rests on a matched scan of this process (before that it
    /// is the start or checkpointed pose).
    pub localised: bool,
    /// Floor the planner records as swept (m²).
    pub covered_area: f64,
    /// Scans localised so far.
    pub scans: u64,
    /// Scans whose match was rejected or failed (odometry used instead).
    pub fallbacks: u64,
    /// How often the scan tracker's correlative search ran and found the
    /// pose (see [`crate::icp::CorrelativeSearch`]).
    pub searches: crate::icp::SearchCounts,
    /// CPU time of the localise steps in which it ran: sum and largest (s).
    pub search_cpu: (f64, f64),
    /// Path driven according to the pose estimate (m).
    pub path_length: f64,
    /// What the planner is doing, in words.
    pub task: String,
    /// The newest decomposition.
    pub decomposition: Option<std::sync::Arc<crate::decomp::Decomposition>>,
    /// How the drive back to the start ended (set when coverage finishes).
    pub home_outcome: Option<crate::plan::HomeOutcome>,
    /// The map stage's snapshot: the newest grid (the map the planner
    /// works on) and the bumper contact marks (checkpointed).
    pub map: crate::daemon::MapStageSnapshot,
    /// The plan stage's snapshot: the planner's records and the places
    /// contact marks were tried (checkpointed).
    pub plan: crate::daemon::PlanStageSnapshot,
    /// The localise stage's snapshot: the scan tracker's keyframes as of
    /// its newest one (published only when checkpoints are written) and
    /// the scanner mount the checks refitted, if they did (checkpointed).
    pub localise: crate::daemon::LocaliseSnapshot,
    /// Rotation (rad) the start heading was turned by to lay the map frame
    /// along the walls (see [`super::align`]); `None` until decided, and
    /// for a resumed run.
    pub frame_turn: Option<f64>,
    /// The turn of the scans' walls over the wheels' over the first quarter
    /// turn (see [`super::turn_check`]); `None` until then.
    pub turn_ratio: Option<f64>,
    /// The scans' travel against the wheels' over the first metre driven
    /// straight (see [`super::travel_check`]); `None` until then.
    pub travel_fit: Option<super::travel_check::TravelFit>,
    /// The scanner offset fitted from the first half turn in place (see
    /// [`super::offset_check`]); `None` until then.
    pub offset_fit: Option<super::offset_check::OffsetFit>,
    /// The newest path's motions (what the robot does towards each
    /// waypoint), with its sequence number and the planner's task count:
    /// with [`Progress`], what the robot is doing now, for the simulator's
    /// overlap breakdown.
    pub path_motions: Option<PathMotions>,
    /// The newest planned path: its sequence number and waypoints (map
    /// frame), for the live view.
    pub path: Option<(u64, std::sync::Arc<[nalgebra::Point2<f64>]>)>,
    /// The planner's counters as of its newest path, or its end.
    pub plan_stats: crate::plan::planner::PlanStats,
}

/// The motions of one planned path (see [`LiveStatus::path_motions`]).
#[derive(Clone, Debug)]
pub struct PathMotions {
    /// The path's sequence number ([`Progress::path_seq`]).
    pub seq: u64,
    /// Tasks the planner had planned when it made the path.
    pub task: u32,
    /// The motion towards each waypoint (see
    /// [`crate::plan::CoveragePlanner::motions`]).
    pub motions: std::sync::Arc<[crate::plan::Motion]>,
}

impl Default for LiveStatus {
    fn default() -> Self {
        Self {
            pose: Pose::identity(),
            pose_time: 0.0,
            localised: false,
            covered_area: 0.0,
            scans: 0,
            fallbacks: 0,
            searches: Default::default(),
            search_cpu: (0.0, 0.0),
            path_length: 0.0,
            task: "starting".into(),
            decomposition: None,
            home_outcome: None,
            map: Default::default(),
            plan: Default::default(),
            localise: Default::default(),
            frame_turn: None,
            turn_ratio: None,
            travel_fit: None,
            offset_fit: None,
            path_motions: None,
            path: None,
            plan_stats: crate::plan::planner::PlanStats::default(),
        }
    }
}

/// Everything shared between stages besides the edges.
#[derive(Debug, Default)]
pub struct Shared {
    /// Integrated wheel odometry.
    pub odom: OdomLog,
    /// The follower's progress.
    pub progress: Mutex<Progress>,
    /// Live status.
    pub status: Mutex<LiveStatus>,
    /// Set when coverage is finished (the planner has nothing left).
    pub done: AtomicBool,
    /// Set on shutdown: control sends only stops from now on.
    pub halt: AtomicBool,
    /// Bumper or wheel-drop latched: clock time (f64 bits) of the last event.
    pub(crate) bumped_at: AtomicU64,
    /// The bumper is closed now (set on a bumper event, cleared when the
    /// base reports it released): the gate lets the wheels only reverse.
    pub(crate) bumper_closed: AtomicBool,
    /// Paths the control stage gave up for lack of headway.
    pub stuck_paths: AtomicU64,
    /// Times the control stage held the wheels for lack of scans.
    pub scan_holds: AtomicU64,
    /// The localise stage has lost the robot: for `daemon.lost_after` no
    /// scan matched, and it searches the whole map while the control stage
    /// holds the wheels (see [`crate::daemon::stages::LocaliseStage`]).
    pub lost: AtomicBool,
    /// Times the robot was lost, and found again by the whole-map search.
    pub relocalisations: AtomicU64,
    /// The newest scan's end points in the robot frame with the odometry
    /// pose they were seen from (localise writes, control reads: the
    /// protective field, see [`crate::control::guard`]).
    pub ahead: Mutex<crate::control::guard::ObstaclePoints>,
    /// Times the control stage slowed or stopped short of something the
    /// scan showed ahead that the path did not expect.
    pub guard_stops: AtomicU64,
    /// Bumper contact marks the map stage took out because they walled off
    /// floor (see [`super::stages::MarkProbe`]).
    pub marks_taken_out: AtomicU64,
    /// Safety events seen (bumper, wheel drop, dead-man, link lost).
    pub safety_events: AtomicU64,
    /// The wheel-base link counters, copied by the motor stage.
    pub base_health: Mutex<crate::motor::LinkHealth>,
    /// Every localised robot pose with its scan time (clock s), kept when
    /// [`Shared::keep_fixes`] is set (the simulator scores them).
    pub fixes: Mutex<Vec<(f64, Pose)>>,
    /// Whether to keep [`Shared::fixes`].
    pub keep_fixes: AtomicBool,
    /// Told the stamp of every scan the localise stage is through with,
    /// and infinity when it stops (the simulator paces its clock by it).
    pub scan_done: ScanObserver,
    /// The pipeline's counters and histograms, taken by the supervisor
    /// once a second (none before the first), for the live view.
    pub metrics: Mutex<Option<std::sync::Arc<crate::pipeline::metrics::MetricsSnapshot>>>,
}

/// A callback for every scan through localisation, set at most once.
#[derive(Default)]
pub struct ScanObserver(std::sync::OnceLock<Box<dyn Fn(f64) + Send + Sync>>);

impl ScanObserver {
    /// Sets the callback; false if one was set before.
    pub fn set(&self, f: Box<dyn Fn(f64) + Send + Sync>) -> bool {
        self.0.set(f).is_ok()
    }

    /// Tells the callback, if any, that the scan stamped `stamp` is done.
    pub fn notify(&self, stamp: f64) {
        if let Some(f) = self.0.get() {
            f(stamp);
        }
    }
}

impl std::fmt::Debug for ScanObserver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.get().is_some() {
            "ScanObserver(set)"
        } else {
            "ScanObserver(none)"
        })
    }
}

impl Shared {
    /// Runs `f` on the newest scan's points ahead (the protective field).
    pub(crate) fn with_ahead<T>(
        &self,
        f: impl FnOnce(&mut crate::control::guard::ObstaclePoints) -> T,
    ) -> T {
        f(&mut lock(&self.ahead))
    }

    /// Runs `f` on the live status.
    pub fn with_status<T>(&self, f: impl FnOnce(&mut LiveStatus) -> T) -> T {
        f(&mut lock(&self.status))
    }

    /// The follower's progress.
    pub fn progress(&self) -> Progress {
        *lock(&self.progress)
    }

    /// Sets the follower's progress.
    pub(crate) fn set_progress(&self, p: Progress) {
        *lock(&self.progress) = p;
    }

    /// The wheel-base link counters.
    pub fn base_health(&self) -> crate::motor::LinkHealth {
        *lock(&self.base_health)
    }

    /// Stores the wheel-base link counters.
    pub(crate) fn set_base_health(&self, h: crate::motor::LinkHealth) {
        *lock(&self.base_health) = h;
    }

    /// Records a localised pose (when asked to keep them).
    pub(crate) fn note_fix(&self, stamp: f64, p: Pose) {
        if self.keep_fixes.load(Ordering::Relaxed) {
            lock(&self.fixes).push((stamp, p));
        }
    }

    /// The kept localised poses.
    pub fn fixes(&self) -> Vec<(f64, Pose)> {
        lock(&self.fixes).clone()
    }

    /// The control stage's last pose carried on by the odometry read since
    /// (the control stage may not have run for a while on a loaded host),
    /// and whether it rests on a matched scan.
    pub(crate) fn pose_now(&self) -> (Pose, bool) {
        let (p, t, localised) = self.with_status(|s| (s.pose, s.pose_time, s.localised));
        (
            carried(&p, &self.odom.at(t), &self.odom.latest()),
            localised,
        )
    }

    /// Records a bumper or wheel-drop event at clock time `t`.
    pub(crate) fn note_bump(&self, t: f64) {
        self.bumped_at.store(t.to_bits(), Ordering::Relaxed);
    }

    /// Clock time of the last bump (−∞ when none).
    pub(crate) fn last_bump(&self) -> f64 {
        let b = self.bumped_at.load(Ordering::Relaxed);
        if b == 0 {
            f64::NEG_INFINITY
        } else {
            f64::from_bits(b)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn odometry_integrates_and_interpolates() {
        let log = OdomLog::default();
        log.push(0.0, &Pose::identity());
        log.push(1.0, &pose(1.0, 0.0, std::f64::consts::FRAC_PI_2));
        log.push(2.0, &pose(1.0, 0.0, 0.0));
        let p = log.latest();
        assert!((p.translation.x - 1.0).abs() < 1e-9 && (p.translation.y - 1.0).abs() < 1e-9);
        let at = |t: f64| log.for_scan(t, t);
        let mid = at(0.5).pose;
        assert!((mid.translation.x - 0.5).abs() < 1e-9, "{mid:?}");
        assert!((heading(&mid) - std::f64::consts::FRAC_PI_4).abs() < 1e-9);
        assert_eq!(at(5.0).pose, log.latest());
        assert_eq!(at(f64::NAN).pose, log.latest());
        // Up to the newest reading the pose is measured; past it, held.
        assert!(at(0.5).current && at(2.0).current);
        assert!(!at(2.01).current && !at(f64::NAN).current);
        assert!(
            !OdomLog::default().for_scan(0.0, 0.0).current,
            "no reading yet"
        );
    }

    #[test]
    fn the_motion_of_a_sweep_is_the_odometry_over_the_window_that_ends_with_it() {
        let log = OdomLog::default();
        let motion_until = |end: f64| log.for_scan(end - 0.1, end).motion;
        assert_eq!(motion_until(1.0), Pose::identity(), "no odometry yet");
        // Turning in place at 0.5 rad/s, a reading every 20 ms up to 1.0 s.
        for k in 0..=50 {
            log.push(k as f64 * 0.02, &pose(0.0, 0.0, 0.01));
        }
        let turn = |m: Pose| heading(&m) / MOTION_WINDOW;
        assert!((turn(motion_until(0.9)) - 0.5).abs() < 1e-9);
        // The sweep ends after the newest reading: the window ends there.
        assert!((turn(motion_until(1.05)) - 0.5).abs() < 1e-9);
        // Odometry a whole window stale: no motion assumed.
        assert_eq!(motion_until(1.2), Pose::identity());
        assert_eq!(motion_until(f64::NAN), Pose::identity());
    }

    #[test]
    fn bump_time_round_trips() {
        let s = Shared::default();
        assert_eq!(s.last_bump(), f64::NEG_INFINITY);
        s.note_bump(12.5);
        assert_eq!(s.last_bump(), 12.5);
    }
}
