//! The localise stage: intensity-ICP of each scan, and the mount and wheel
//! checks of the first drive.

use std::sync::Arc;
use std::time::Duration;

use super::gone;
use crate::daemon::align::{AlignStep, MAX_ALIGN_SCANS, MIN_AGREEMENT, MIN_WALL_EVIDENCE};
use crate::daemon::messages::{MapMsg, PoseFix, ScanMsg, MOTION_WINDOW};
use crate::daemon::offset_check::{
    OffsetFit, OFFSET_FIT_MAX, OFFSET_STOP_UNFITTED, OFFSET_TOLERANCE,
};
use crate::daemon::shared::Shared;
use crate::daemon::snapshot::LocaliseSnapshot;
use crate::daemon::travel_check::{
    TravelFit, SCALE_WARN, YAW_FIT_MAX, YAW_STOP_UNFITTED, YAW_TOLERANCE,
};
use crate::daemon::turn_check::{fitting_wheel_base, TurnVerdict, SCALE_WARN as TURN_SCALE_WARN};
use crate::geom::{heading, IPoint, Pose};
use crate::grid::Grid;
use crate::icp::{Outcome, Tracker, TrackerState};
use crate::pipeline::checkpoint::MountRecord;
use crate::pipeline::{Poll, Recv, Rx, Stage, StageCtx, StageFault, Tx};
use crate::scan::LaserScan;

/// The localise stage: intensity-ICP of each newest scan against the
/// tracker's local map with the odometry prior; a rejected or failed match
/// falls back to the odometry prediction (counted) and is kept out of the map.
pub struct LocaliseStage {
    /// The scan-to-map tracker (scanner poses).
    pub tracker: Tracker,
    /// Scans in.
    pub rx: Rx<ScanMsg>,
    /// Pose fixes to control.
    pub(crate) to_control: Tx<PoseFix>,
    /// Registered scans to the map.
    pub(crate) to_map: Tx<MapMsg>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// Pose of the scanner in the robot frame: the configured (or resumed)
    /// one, refitted by the offset and travel checks (see
    /// [`crate::daemon::offset_check`], [`crate::daemon::travel_check`]).
    pub mount: Pose,
    /// The mount `[robot]` configures: a refitted [`Self::mount`] is
    /// checkpointed with it, and resumed only while it is unchanged.
    pub(crate) configured_mount: Pose,
    /// [`Self::mount`] was refitted by a check (in this run, or before the
    /// checkpoint it resumed from).
    pub(crate) mount_refitted: bool,
    /// Distance between the wheels (m, `robot.wheel_base`), for the
    /// turn check's warning.
    pub wheel_base: f64,
    /// Wheel radius (m, `robot.wheel_radius`), for the travel check's
    /// warning.
    pub wheel_radius: f64,
    /// Whether offset and yaw errors the checks measure are taken into the
    /// mount for the rest of the run (`daemon.fit_scanner_mount`).
    pub(crate) fit_mount: bool,
    /// Least information a match's weakest direction must hold
    /// ([`crate::icp::Quality::min_eigenvalue`]) for its scan to count in
    /// the offset and yaw checks (see [`pins_the_pose`]).
    pub(crate) check_min_information: f64,
    /// Whether scans are deskewed by the odometry's motion before use
    /// (`daemon.deskew_scans`).
    pub deskew: bool,
    /// Factor taking the sensor's raw intensities to wall units
    /// (`1 / scanner.intensity_unit`): a matt light wall at 1 m is 1.
    pub(crate) intensity_scale: f64,
    /// Reused point buffer.
    pub points: Vec<IPoint>,
    /// The restored map of a resumed run: the first scan is laid onto it
    /// (see [`crate::daemon::relocalise`]) before tracking starts.
    pub(crate) relocalise_on: Option<Arc<Grid>>,
    /// Whether to publish the tracker's keyframes for checkpoints (each
    /// time one is added).
    pub(crate) publish_keyframes: bool,
    /// The tracker's keyframes as of its newest one, for the snapshot
    /// (kept rather than taken at each snapshot: a copy of every keyframe);
    /// those restored until then.
    pub(crate) keyframes: Option<Arc<TrackerState>>,
    /// Stamp of the previous scan localised (s).
    pub last_stamp: Option<f64>,
    /// Scans in a row whose match was not accepted (the pose followed the
    /// odometry), for the warning that names why.
    pub(crate) unmatched_run: u32,
    /// At a fresh start, until decided: turns the map frame to the walls
    /// of the first scans before tracking starts (see [`crate::daemon::align`]).
    pub align: Option<crate::daemon::align::WallAlign>,
    /// Whether the scans turn with the wheels (a wrong scanner mount).
    pub turn_check: crate::daemon::turn_check::TurnCheck,
    /// Whether the scans move along the robot's heading (a wrong yaw).
    pub travel_check: crate::daemon::travel_check::TravelCheck,
    /// Whether the scanner circles the axle at its configured offset when
    /// the robot turns in place (a wrong offset).
    pub offset_check: crate::daemon::offset_check::OffsetCheck,
    /// The mount's offset was refitted by the offset check (in this run, or
    /// before the checkpoint it resumed from).
    pub(crate) offset_fitted: bool,
    /// When the robot counts as lost, and how the whole map is searched
    /// then (see [`Lost`]).
    pub(crate) lost: Lost,
    /// A copy of every pose fix for the recorder and the live view.
    pub(crate) tap: Option<Tx<PoseFix>>,
}

/// Losing and finding the robot: after `daemon.lost_after` without an
/// accepted match the robot is lost, the control stage holds the wheels
/// (`Shared::lost`), and each scan is searched for over the whole map
/// ([`Tracker::relocalise`]) until it fits; the keyframes taken at the
/// wheels' pose meanwhile are forgotten first.
#[derive(Debug)]
pub(crate) struct Lost {
    /// `daemon.lost_after` (clock s; 0 = never).
    pub(crate) after: f64,
    /// The whole-map search: `[icp.search]` widened to
    /// `daemon.relocalise_radius` and a full turn.
    pub(crate) search: crate::icp::SearchParams,
    /// Stamp of the first scan of the current unmatched run.
    pub(crate) unmatched_since: Option<f64>,
    /// Stamp since which the robot is lost, and of the last log line.
    pub(crate) since: Option<(f64, f64)>,
    /// Matches in a row that contradicted the map.
    pub(crate) contradicted: u32,
}

/// A lost robot's log line is repeated this often (clock s).
const LOST_TOLD_EVERY: f64 = 10.0;

/// Least mean likelihood of the whole-map search's candidate: stricter
/// than the local search's, as a whole map holds more look-alikes.
const RELOCALISE_MIN_SCORE: f64 = 0.5;

impl Lost {
    /// The policy of `daemon.lost_after` with the whole-map search built
    /// from `search` (`[icp.search]`) out to `radius` (m).
    pub(crate) fn new(after: f64, radius: f64, search: &crate::icp::SearchParams) -> Self {
        Self {
            after,
            search: crate::icp::SearchParams {
                window: radius,
                window_angle: std::f64::consts::PI,
                levels: search.levels.max(6),
                min_score: search.min_score.max(RELOCALISE_MIN_SCORE),
                ..search.clone()
            },
            unmatched_since: None,
            since: None,
            contradicted: 0,
        }
    }
}

impl LocaliseStage {
    /// Drives with `mount` from now on (a check refitted it); returns the
    /// robot's pose under it, the scanner at `scanner`. The scanner's
    /// odometry jumps with the mount: the motion prior starts over.
    fn refit_mount(&mut self, mount: Pose, scanner: &Pose) -> Pose {
        self.mount = mount;
        self.mount_refitted = true;
        self.tracker.set_pose(*scanner);
        self.publish();
        scanner * mount.inverse()
    }

    /// Whether the match of `step` puts the scan where the map has seen
    /// free floor (see [`crate::daemon::consistency`]): then it is no match
    /// (the pose follows the wheels, the scan stays out of the map and its
    /// keyframe is dropped), and a run of them makes the robot lost.
    fn contradicts_map(&mut self, step: &crate::icp::Step) -> bool {
        use crate::daemon::consistency::{free_share, CONTRADICTION};
        if !matches!(step.outcome, Outcome::Matched(_)) {
            return false;
        }
        let Some(grid) = self.shared.with_status(|s| s.map.grid.clone()) else {
            return false;
        };
        match free_share(&grid, &self.points, &step.pose) {
            Some(share) if share > CONTRADICTION => {
                self.tracker.discard_pending_keyframe();
                if self.lost.contradicted == 0 {
                    log::warn!(
                        "localise: a match puts {:.0} % of the scan on floor the map has seen free; taken as no match",
                        share * 100.0
                    );
                }
                self.lost.contradicted += 1;
                true
            }
            _ => {
                self.lost.contradicted = 0;
                false
            }
        }
    }

    /// Keeps [`Lost`] up to date after a scan at `stamp` that `matched` or
    /// not, the estimate moved from `before` to `after`: declares the robot
    /// lost (wheels held, unconfirmed keyframes forgotten) or found again.
    fn watch_lost(&mut self, matched: bool, stamp: f64, before: &Pose, after: &Pose) {
        use std::sync::atomic::Ordering;
        if matched {
            self.lost.unmatched_since = None;
            if let Some((since, _)) = self.lost.since.take() {
                let d = before.inverse() * after;
                log::info!(
                    "localise: found again by the whole-map search after {:.1} s, {:.2} m and {:.0}° from where the wheels had it; driving on",
                    stamp - since,
                    d.translation.vector.norm(),
                    d.rotation.angle().to_degrees()
                );
                self.shared.relocalisations.fetch_add(1, Ordering::Relaxed);
                self.shared.lost.store(false, Ordering::Relaxed);
            }
            return;
        }
        let first = *self.lost.unmatched_since.get_or_insert(stamp);
        match self.lost.since {
            None if self.lost.after > 0.0 && stamp - first >= self.lost.after => {
                let forgotten = self.tracker.forget_unconfirmed();
                log::warn!(
                    "localise: lost: no scan matched for {:.1} s (daemon.lost_after), not even after a search around the prediction; wheels held while each scan is searched for over the whole map ({forgotten} keyframe(s) taken meanwhile forgotten)",
                    stamp - first
                );
                self.lost.since = Some((stamp, stamp));
                self.shared.lost.store(true, Ordering::Relaxed);
            }
            Some((since, told)) if stamp - told >= LOST_TOLD_EVERY => {
                log::warn!(
                    "localise: still lost after {:.0} s: the scans fit nowhere within daemon.relocalise_radius of the last estimate; wheels held. Put the robot back where it was, or restart with `sweepline run --fresh`",
                    stamp - since
                );
                self.lost.since = Some((since, stamp));
            }
            _ => {}
        }
    }

    /// What a restart needs of this stage: the keyframes as of the newest
    /// one and the refitted mount, if any.
    pub fn snapshot(&self) -> LocaliseSnapshot {
        LocaliseSnapshot {
            keyframes: self.keyframes.clone(),
            mount: self.mount_refitted.then_some(MountRecord {
                configured: self.configured_mount,
                refitted: self.mount,
            }),
        }
    }

    /// Hands [`Self::snapshot`] to the checkpoint (through the live status).
    fn publish(&self) {
        let snapshot = self.snapshot();
        self.shared.with_status(|s| s.localise = snapshot);
    }

    /// Picks up a resumed run, the robot at `pose` on the restored `map`:
    /// drives with the mount refitted before the checkpoint while the
    /// configured one is unchanged (see `crate::daemon::resume::resumed_mount`),
    /// tracks against the restored keyframes, and lays the first scan onto
    /// `map` before tracking (the frame is the crashed run's: no turn to
    /// the walls). The error: the tracker's settings are refused.
    pub fn restore(
        &mut self,
        snapshot: LocaliseSnapshot,
        pose: &Pose,
        map: Option<Arc<Grid>>,
    ) -> Result<(), String> {
        use crate::daemon::resume::{offset_was_fitted, resumed_mount};
        let mount = resumed_mount(self.configured_mount, snapshot.mount.as_ref());
        let restored = snapshot.keyframes.as_deref();
        let (tracker, refused) = Tracker::restore(
            self.tracker.params().clone(),
            *pose * mount,
            restored.unwrap_or(&TrackerState::default()),
        )
        .map_err(|e| e.to_string())?;
        match (restored, refused) {
            (Some(k), None) => log::info!(
                "resume: scan tracker restored with {} keyframe(s)",
                k.keyframes.len()
            ),
            (Some(_), Some(e)) => {
                log::warn!("resume: checkpointed keyframes unusable ({e}); new local map")
            }
            (None, _) => log::info!("resume: no keyframes checkpointed; new local map"),
        }
        self.tracker = tracker;
        self.mount = mount;
        self.mount_refitted = mount != self.configured_mount;
        self.travel_check = crate::daemon::travel_check::TravelCheck::new(heading(&mount));
        self.offset_check = crate::daemon::offset_check::OffsetCheck::new(heading(&mount));
        self.offset_fitted = offset_was_fitted(&self.configured_mount, &mount);
        self.relocalise_on = map;
        self.align = None;
        // Until the tracker's next keyframe, the checkpointed ones stand.
        self.keyframes = snapshot.keyframes;
        self.publish();
        Ok(())
    }
}

/// A scan further than this many scan intervals after the previous one
/// follows a gap (lost or skipped scans).
const GAP_INTERVALS: f64 = 1.5;

/// A gap at least this long (s) is logged.
const GAP_LOGGED: f64 = 1.0;

/// Unmatched scans in a row after which (and after each further as many)
/// a warning names the last reason: ten seconds of a URG-04LX's scans.
const UNMATCHED_WARN: u32 = 100;

impl Stage for LocaliseStage {
    type Work = ScanMsg;

    fn wait(&mut self, timeout: Duration) -> Poll<ScanMsg> {
        match self.rx.recv_timeout(timeout) {
            Recv::Msg(m) => match self.rx.try_recv_newest() {
                Recv::Msg(newer) => Poll::Work(newer),
                _ => Poll::Work(m),
            },
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }

    fn process(&mut self, msg: ScanMsg, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        let stamp = msg.stamp;
        let r = self.localise(msg, ctx);
        self.shared.scan_done.notify(stamp);
        r
    }

    fn on_stop(&mut self) {
        // No scan will be processed any more: nobody should wait for one.
        self.shared.scan_done.notify(f64::INFINITY);
    }
}

impl LocaliseStage {
    /// One scan: deskewed, matched against the map (or aligned, or laid
    /// onto a restored map), its pose handed to the control and map stages.
    fn localise(&mut self, mut msg: ScanMsg, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        ctx.note_age(msg.t0);
        if self.deskew {
            deskew(&mut msg.scan, &msg.motion, &self.mount);
        }
        msg.scan.points_into(&mut self.points);
        for p in &mut self.points {
            p.intensity *= self.intensity_scale;
        }
        self.shared
            .with_ahead(|a| a.load_scan(&msg.scan, &self.mount, msg.odom));
        let resuming = self.relocalise_on.is_some();
        if let Some(grid) = self.relocalise_on.take() {
            let guess = self.tracker.pose();
            use crate::daemon::relocalise::{judge, relocalise, ResumeFit, MIN_FIT};
            match judge(relocalise(&grid, &self.points, &guess)) {
                ResumeFit::Moved(r) => {
                    let moved = (r.pose.translation.vector - guess.translation.vector).norm();
                    log::info!(
                        "resume: first scan laid onto the restored map {moved:.3} m from the checkpointed pose ({:.0} % of points on walls there, {:.0} % before)",
                        r.score * 100.0,
                        r.guess_score * 100.0
                    );
                    if self.tracker.map().is_empty() {
                        self.tracker = Tracker::new(self.tracker.params().clone(), r.pose)
                            .map_err(|e| StageFault::Fatal(format!("tracker: {e}")))?;
                    } else {
                        // The restored keyframes stay: the first scan is
                        // matched against them from here.
                        self.tracker.set_pose(r.pose);
                    }
                }
                ResumeFit::InPlace(score) => log::info!(
                    "resume: first scan fits the restored map at the checkpointed pose ({:.0} % of points on walls)",
                    score * 100.0
                ),
                ResumeFit::NoFit(r) => log::warn!(
                    "resume: the first scan fits the restored map nowhere within {} m and {:.0}° of the checkpointed pose ({}; {:.0} % needed). Was the robot moved while the daemon was down? Driving on from the checkpointed pose; if it was moved, stop the daemon and put the robot back where it stopped, or start a new run with `sweepline run --fresh`",
                    crate::daemon::relocalise::SEARCH_TRANSLATION,
                    crate::daemon::relocalise::SEARCH_ROTATION.to_degrees(),
                    r.map_or("nothing to match".to_string(), |r| format!(
                        "at best {:.0} % of its points on walls",
                        r.score * 100.0
                    )),
                    MIN_FIT * 100.0
                ),
            }
        }
        if let Some(al) = self.align.as_mut() {
            let scanner = self.tracker.pose();
            match al.step(&self.points, heading(&scanner)) {
                // Nothing is tracked (the robot waits for a plan) until the
                // frame is decided: at most MAX_ALIGN_SCANS scans.
                AlignStep::NotYet => return Ok(()),
                AlignStep::GiveUp => {
                    log::warn!(
                        "map frame: the first {MAX_ALIGN_SCANS} scans show no rectilinear walls (not {MIN_WALL_EVIDENCE} m of wall lines, {:.0} % of all, along one pair of axes); the frame stays the start pose, lanes may cross the walls at an angle",
                        MIN_AGREEMENT * 100.0
                    );
                    self.shared.with_status(|s| s.frame_turn = Some(0.0));
                }
                AlignStep::Turn {
                    turn,
                    evidence,
                    agreement,
                } => {
                    // Turned about the robot's own position.
                    let turned = scanner * self.mount.inverse() * crate::geom::pose(0.0, 0.0, turn);
                    self.tracker = Tracker::new(self.tracker.params().clone(), turned * self.mount)
                        .map_err(|e| StageFault::Fatal(format!("tracker: {e}")))?;
                    log::info!(
                        "map frame turned {:+.1}° to lie along the walls ({evidence:.1} m of wall lines along the axes in the first scan, {:.0} % of all); start heading {:.1}°",
                        turn.to_degrees(),
                        agreement * 100.0,
                        heading(&turned).to_degrees()
                    );
                    self.shared.with_status(|s| {
                        s.frame_turn = Some(turn);
                        s.pose = turned;
                    });
                }
            }
            self.align = None;
        }
        if let Some(prev) = self.last_stamp {
            let gap = msg.stamp - prev;
            if msg.interval > 0.0 && gap > GAP_INTERVALS * msg.interval {
                self.tracker.note_gap();
                if gap >= GAP_LOGGED {
                    log::info!(
                        "localise: {gap:.1} s since the previous scan; the odometry carries the pose across"
                    );
                }
            }
        }
        self.last_stamp = Some(msg.stamp);
        let before = self.tracker.pose();
        let restored = self.tracker.map().len();
        let robot_odom = msg.odom;
        if msg.odom_current {
            self.tracker.note_live_odometry();
        }
        // The keyframe (a k-d tree rebuild) is added after the pose is handed on.
        let cpu0 = crate::pipeline::clock::thread_cpu_time();
        let step = if self.lost.since.is_some() {
            self.tracker.relocalise(&self.points, &self.lost.search)
        } else {
            self.tracker
                .step_deferred(&self.points, Some(&(robot_odom * self.mount)))
        };
        let search_cpu = step
            .searched
            .then(|| (crate::pipeline::clock::thread_cpu_time() - cpu0).as_secs_f64());
        if step.searched && matches!(step.outcome, Outcome::Matched(_)) {
            let d = before.inverse() * step.pose;
            log::info!(
                "localise: the correlative search found the pose the match from the prediction missed ({:.2} m, {:.1}° from the previous pose)",
                d.translation.vector.norm(),
                d.rotation.angle().to_degrees()
            );
        }
        let matched = matches!(step.outcome, Outcome::First | Outcome::Matched(_))
            && !self.contradicts_map(&step);
        self.watch_lost(matched, msg.stamp, &before, &step.pose);
        self.unmatched_run = if matched {
            if self.unmatched_run >= UNMATCHED_WARN {
                log::info!(
                    "localise: scans match again after {} that did not",
                    self.unmatched_run
                );
            }
            0
        } else {
            self.unmatched_run.saturating_add(1)
        };
        if self.unmatched_run > 0 && self.unmatched_run.is_multiple_of(UNMATCHED_WARN) {
            let why = match step.outcome {
                Outcome::Failed(e) => e.to_string(),
                Outcome::Rejected(r, _) => format!("rejected: {r}"),
                _ => String::new(),
            };
            log::warn!(
                "localise: {} scans in a row not matched, the pose follows the wheels and the scans stay out of the map (last: {why})",
                self.unmatched_run
            );
        }
        let pinned = pins_the_pose(&step.outcome, self.check_min_information);
        if resuming {
            let how = match step.outcome {
                Outcome::Matched(q) => format!(
                    "matched ({} pairs, residual {:.1} mm)",
                    q.pairs,
                    q.residual_rms * 1e3
                ),
                Outcome::First => "(none) started a new local map".into(),
                Outcome::Failed(e) => format!("failed ({e})"),
                Outcome::Rejected(r, _) => format!("rejected ({r:?})"),
            };
            log::info!(
                "resume: first scan against {restored} restored keyframe(s) {how}, {:.3} m from its start pose",
                (step.pose.translation.vector - before.translation.vector).norm()
            );
        }
        let mut robot = step.pose * self.mount.inverse();
        match self.turn_check.step(&self.points, &robot_odom) {
            TurnVerdict::Undecided => {}
            TurnVerdict::Agree { ratio } => {
                log::info!(
                    "scans and wheels agree on the first quarter turn (the scans turned {:.0} % of the wheels' turn)",
                    ratio * 100.0
                );
                if !(TURN_SCALE_WARN.0..=TURN_SCALE_WARN.1).contains(&ratio) {
                    log::warn!(
                        "the wheels' turn is off: the scans turned {:.0} % of it; robot.wheel_base is {:.3} m, the scans fit {:.3} m if robot.wheel_radius is right (see the first metre's scale; or the wheels slip when turning)",
                        ratio * 100.0,
                        self.wheel_base,
                        fitting_wheel_base(ratio, self.wheel_base)
                    );
                }
                self.shared.with_status(|s| s.turn_ratio = Some(ratio));
            }
            TurnVerdict::Disagree { scans, wheels } => {
                self.shared
                    .with_status(|s| s.turn_ratio = Some(scans / wheels));
                // Mapping on, with the pose turning the wrong way, would
                // build a map of nothing and drive blind: stop instead.
                return Err(StageFault::Fatal(format!(
                    "scans and wheels disagree: over the first quarter turn the wheels turned {:+.0}° and the walls in the scans {:+.0}°; is the scanner mounted upside down (robot.scanner_upside_down), or are the left and right wheels swapped (motor.roboclaw.m1_is_left)? Stopping: the pose cannot be trusted",
                    wheels.to_degrees(),
                    scans.to_degrees()
                )));
            }
        }
        if let Some(fit) = self
            .offset_check
            .step(pinned.then_some(&step.pose), &robot_odom)
        {
            self.shared.with_status(|s| s.offset_fit = Some(fit));
            if check_offset(&fit, &self.mount, self.fit_mount)? {
                let yaw = heading(&self.mount);
                robot = self.refit_mount(
                    crate::geom::pose(fit.offset.x, fit.offset.y, yaw),
                    &step.pose,
                );
                self.offset_fitted = true;
            }
        }
        if let Some(fit) = self
            .travel_check
            // Odometry held at its newest reading (none came after the
            // scan) breaks the chain: see `TravelCheck::step`.
            .step((pinned && msg.odom_current).then_some(&robot), &robot_odom)
        {
            self.shared.with_status(|s| s.travel_fit = Some(fit));
            if check_travel(&fit, self.wheel_radius, self.fit_mount)? {
                // Turned about the scanner's own position: the scans (and
                // the map) stay; the robot's heading in it moves. An
                // offset fitted under the old yaw was turned by the error
                // too (see `offset_check`): it turns back.
                let m = self.mount;
                let t = if self.offset_fitted {
                    nalgebra::Rotation2::new(-fit.angle) * m.translation.vector
                } else {
                    m.translation.vector
                };
                let refitted = crate::geom::pose(t.x, t.y, heading(&m) - fit.angle);
                robot = self.refit_mount(refitted, &step.pose);
            }
        }
        let searches = self.tracker.search_counts();
        self.shared.with_status(|s| {
            s.scans += 1;
            if !matched {
                s.fallbacks += 1;
            }
            s.searches = searches;
            if let Some(c) = search_cpu {
                s.search_cpu = (s.search_cpu.0 + c, s.search_cpu.1.max(c));
            }
        });
        if matched {
            self.shared.note_fix(msg.stamp, robot);
        }
        let fix = PoseFix {
            t0: msg.t0,
            stamp: msg.stamp,
            pose: robot,
            odom: robot_odom,
            matched,
        };
        if let Some(tap) = &self.tap {
            let _ = tap.send(fix);
        }
        ctx.hand_off();
        if self.to_control.send(fix).is_err() {
            return gone(&self.shared, "control");
        }
        if matched {
            let _ = self.to_map.send(MapMsg::Scan {
                pose: step.pose,
                scan: msg.scan,
            });
        }
        self.tracker.finish_keyframe();
        if step.keyframe && self.publish_keyframes {
            self.keyframes = Some(Arc::new(self.tracker.state()));
            self.publish();
        }
        Ok(())
    }
}

/// Moves the beams of `scan` to where the scanner was at its stamp, for a
/// robot that moved by `motion` over a `MOTION_WINDOW` (its odometry
/// over the window ending with the sweep, [`ScanMsg::motion`]) at a steady
/// velocity, with the scanner at `mount` on it.
pub fn deskew(scan: &mut LaserScan, motion: &Pose, mount: &Pose) {
    scan.deskew_steady(motion, MOTION_WINDOW, mount);
}

/// How many times the information the matcher calls degenerate
/// (`icp.degeneracy_threshold`) a match's weakest direction must hold for
/// its scan to count in the mount checks. In the middle of a large room,
/// with two walls beyond the scanner's 5.6 m, matches that are not
/// degenerate (0.05-0.09 at the default 0.02) still let the position
/// slide a few centimetres along their weak direction: the first metre
/// read up to 3.9° of yaw error and 2 cm of offset on a scanner mounted
/// right, so the daemon refitted a good mount or stopped. In the
/// floor-plan rooms and the bench room matches hold 0.15 or more.
pub const CHECK_INFORMATION_FACTOR: f64 = 6.0;

/// Whether the scan of `outcome` counts in the mount checks: the first
/// scan (the start pose itself), or a match whose weakest direction holds
/// at least `min_information`. Other scans break the checks' chains (as
/// unmatched scans do), so a check is made only over scans that pin the
/// pose down: later in the run, nearer the walls, where the start does not.
pub fn pins_the_pose(outcome: &Outcome, min_information: f64) -> bool {
    match outcome {
        Outcome::First => true,
        Outcome::Matched(q) => q.min_eigenvalue >= min_information,
        Outcome::Failed(_) | Outcome::Rejected(..) => false,
    }
}

/// What a mount check's measured error calls for.
#[derive(Clone, Copy, Debug, PartialEq)]
enum MountCall {
    /// Within the check's tolerance: the mount stands.
    Agrees,
    /// Off, and the mount may be refitted: refit it (with a warning).
    Refit,
    /// Off, the fit turned off: warn only.
    Warn,
    /// Too far off to drive by: stop the daemon.
    Stop,
}

/// The call for a mount error `error` against a check's `tolerance`, the
/// largest error it refits (`fit_max`) and the largest it lets pass with
/// the fit off (`stop_unfitted`); `may_fit` is `daemon.fit_scanner_mount`.
fn mount_call(
    error: f64,
    tolerance: f64,
    fit_max: f64,
    stop_unfitted: f64,
    may_fit: bool,
) -> MountCall {
    let limit = if may_fit { fit_max } else { stop_unfitted };
    if error <= tolerance {
        MountCall::Agrees
    } else if error > limit {
        MountCall::Stop
    } else if may_fit {
        MountCall::Refit
    } else {
        MountCall::Warn
    }
}

/// Judges the scanner offset fitted from turning in place (see
/// [`crate::daemon::offset_check`]) against the `mount` driven with: logs it, and
/// says whether the offset is to be refitted (`may_fit`: allowed to), or
/// stops the daemon when it is too far off to drive by.
fn check_offset(fit: &OffsetFit, mount: &Pose, may_fit: bool) -> Result<bool, StageFault> {
    let (t, c) = (fit.offset, mount.translation.vector);
    let error = (t - c).norm();
    let what = format!(
        "turning in place over {:.0}° the scanner circled the axle at ({:.3}, {:.3}) m (ahead, left)",
        fit.turned.to_degrees(),
        t.x,
        t.y
    );
    let fix = format!(
        "robot.scanner_offset_x, robot.scanner_offset_y are ({:.3}, {:.3}) m, {:.1} cm off",
        c.x,
        c.y,
        error * 100.0
    );
    let call = mount_call(
        error,
        OFFSET_TOLERANCE,
        OFFSET_FIT_MAX,
        OFFSET_STOP_UNFITTED,
        may_fit,
    );
    match call {
        MountCall::Agrees => log::info!(
            "scanner offset agrees: {what}, {:.1} cm from the configured one",
            error * 100.0
        ),
        MountCall::Stop => {
            return Err(StageFault::Fatal(format!(
                "the scanner is not where the configuration says: {what}; {fix}{}. Stopping: the position cannot be trusted",
                if may_fit {
                    ", too far off to be a measuring error"
                } else {
                    ""
                }
            )))
        }
        MountCall::Refit => log::warn!(
            "{what}; {fix}: driving with the fitted offset for this run (set it in the configuration)"
        ),
        MountCall::Warn => log::warn!("{what}; {fix} (daemon.fit_scanner_mount is off)"),
    }
    Ok(call == MountCall::Refit)
}

/// A travel direction (rad) off the heading by more than this is driving
/// backward: the scanner faces backward, or the odometry counts backward.
const BACKWARD: f64 = 3.0 * std::f64::consts::FRAC_PI_4;

/// Judges the scans' travel against the wheels' (see
/// [`crate::daemon::travel_check`]): logs it, warns of a wheel scale off (the
/// configured `wheel_radius` beside the one that fits), and says whether
/// the mount's yaw is to be refitted (`may_fit`: allowed to), or stops the
/// daemon when the yaw is too far off to drive by.
fn check_travel(fit: &TravelFit, wheel_radius: f64, may_fit: bool) -> Result<bool, StageFault> {
    let (deg, dist) = (fit.angle.to_degrees(), fit.driven);
    let what = format!(
        "over the first {dist:.1} m driven straight the scans moved {deg:+.1}° off the robot's heading and {:.0} % of the wheels' distance",
        fit.scale * 100.0
    );
    if !(SCALE_WARN.0..=SCALE_WARN.1).contains(&fit.scale) {
        log::warn!(
            "{what}: the wheel odometry's scale is off; robot.wheel_radius is {wheel_radius:.4} m, the scans fit {:.4} m (or the encoder counts per revolution are off, or the wheels slip)",
            wheel_radius * fit.scale
        );
    }
    let error = fit.angle.abs();
    let suggest = fit.fitting_yaw();
    let fix = format!(
        "the robot drives with robot.scanner_yaw = {:.3} rad ({:+.1}°), the scans fit {suggest:.3} rad ({:+.1}°)",
        fit.yaw,
        fit.yaw.to_degrees(),
        suggest.to_degrees()
    );
    let call = mount_call(
        error,
        YAW_TOLERANCE,
        YAW_FIT_MAX,
        YAW_STOP_UNFITTED,
        may_fit,
    );
    match call {
        MountCall::Agrees => {
            log::info!("scans and wheels agree on the direction of travel: {what}")
        }
        MountCall::Stop => {
            // Steering by a heading that far off drives the body crabwise
            // along every lane, into the walls the margins assume clear.
            let why = if error > BACKWARD {
                // Odometry counting backward looks the same as a scanner
                // facing backward: both make the scans move against the wheels.
                ", or the wheel odometry counts backward (encoder polarity)"
            } else if may_fit {
                ", too far off to be a mounting tolerance"
            } else {
                ""
            };
            return Err(StageFault::Fatal(format!(
                "scans and wheels disagree on the direction of travel: {what}; {fix}{why}. Stopping: the heading cannot be trusted"
            )));
        }
        MountCall::Refit => log::warn!(
            "{what}: the scanner's mount yaw is off; {fix}: driving with {suggest:.3} rad for this run (set it in the configuration)"
        ),
        MountCall::Warn => log::warn!(
            "{what}: the scanner's mount yaw is off; {fix} (daemon.fit_scanner_mount is off)"
        ),
    }
    Ok(call == MountCall::Refit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scan_swept_while_turning_in_place_is_moved_to_the_stamp_through_the_mount() {
        use crate::scan::Beam;
        // Scanner 0.12 m ahead of the axle, the robot turning in place at
        // 0.78 rad/s; beams 97.7 µs apart over 67 ms.
        let mount = crate::geom::pose(0.12, 0.0, 0.0);
        let w = 0.78;
        let robot_at = |tau: f64| crate::geom::pose(0.0, 0.0, w * tau);
        let dt = 0.1 / 1024.0;
        // A square room 4 m across around the axle, in the robot's frame at
        // the stamp: from inside, a ray leaves it through the nearest of the
        // four walls ahead.
        let leave = |o: nalgebra::Vector2<f64>, d: nalgebra::Vector2<f64>| {
            [(o.x, d.x), (o.y, d.y)]
                .iter()
                .flat_map(|&(p, v)| [(2.0 - p) / v, (-2.0 - p) / v])
                .filter(|t| *t > 0.0)
                .fold(f64::INFINITY, f64::min)
        };
        let mut scan = LaserScan {
            beam_interval: dt,
            ..LaserScan::default()
        };
        let mut truth = Vec::new();
        for k in 0..682 {
            let tau = k as f64 * dt;
            let sensor = robot_at(tau) * mount;
            // The beam's direction in the world, then where it hits.
            let a = -2.08 + k as f64 * (std::f64::consts::TAU / 1024.0);
            let origin = sensor.translation.vector;
            let dir = sensor.rotation * nalgebra::Vector2::new(a.cos(), a.sin());
            let r = leave(origin, dir);
            let hit = nalgebra::Point2::from(origin + dir * r);
            truth.push(mount.inverse() * hit);
            scan.beams.push(Beam::hit(a, r)).unwrap();
        }
        let worst = |s: &LaserScan| {
            let mut pts = Vec::new();
            s.points_into(&mut pts);
            pts.iter()
                .zip(&truth)
                .map(|(p, t)| (p.xy() - t).norm())
                .fold(0.0, f64::max)
        };
        assert!(worst(&scan) > 0.08, "{}", worst(&scan));
        // The odometry's motion over the window: a tenth of a second of the turn.
        deskew(&mut scan, &robot_at(MOTION_WINDOW), &mount);
        assert!(worst(&scan) < 1e-6, "{}", worst(&scan));
    }

    #[test]
    fn only_the_start_and_matches_that_pin_the_pose_down_count_in_the_mount_checks() {
        let q = |min_eigenvalue: f64| crate::icp::Quality {
            pairs: 200,
            inlier_ratio: 1.0,
            residual_rms: 0.002,
            iterations: 5,
            converged: true,
            min_eigenvalue,
            degenerate: false,
            weak_direction: nalgebra::Vector3::y(),
            covariance: None,
            correction_translation: 0.0,
            correction_rotation: 0.0,
            edge_pairs: 0,
        };
        let least = 0.02 * CHECK_INFORMATION_FACTOR;
        assert!(pins_the_pose(&Outcome::First, least));
        // The bench and floor-plan rooms' matches (0.15-0.28) count; the
        // middle of the large room's (0.05-0.09, not degenerate) do not.
        assert!(pins_the_pose(&Outcome::Matched(q(0.18)), least));
        assert!(!pins_the_pose(&Outcome::Matched(q(0.07)), least));
        let low = crate::icp::Rejection::LowInlierRatio {
            ratio: 0.2,
            min: 0.5,
        };
        assert!(!pins_the_pose(&Outcome::Rejected(low, q(0.3)), least));
        let failed = crate::icp::IcpError::EmptyScan;
        assert!(!pins_the_pose(&Outcome::Failed(failed), least));
    }

    fn fit(deg: f64) -> TravelFit {
        TravelFit {
            angle: deg.to_radians(),
            scale: 1.0,
            driven: 1.0,
            yaw: 0.2,
        }
    }

    #[test]
    fn a_yaw_error_is_refitted_when_allowed_and_stops_the_daemon_beyond_the_limits() {
        // Within the measurement's noise: nothing to do, fitting or not.
        assert_eq!(check_travel(&fit(0.8), 0.036, true), Ok(false));
        assert_eq!(check_travel(&fit(-0.8), 0.036, false), Ok(false));
        // A mounting tolerance: refitted, or (not allowed) a warning up to 3°.
        assert_eq!(check_travel(&fit(4.0), 0.036, true), Ok(true));
        assert_eq!(check_travel(&fit(-19.0), 0.036, true), Ok(true));
        assert_eq!(check_travel(&fit(2.5), 0.036, false), Ok(false));
        // Too far off: the daemon stops, naming the key and the value that fits.
        for (deg, may_fit) in [(4.0, false), (-25.0, true), (90.0, true), (179.0, true)] {
            match check_travel(&fit(deg), 0.036, may_fit) {
                Err(StageFault::Fatal(m)) => {
                    let yaw = crate::geom::wrap_angle(0.2 - deg.to_radians());
                    let want = format!("the scans fit {yaw:.3} rad");
                    assert!(m.contains("robot.scanner_yaw") && m.contains(&want), "{m}");
                    // Travel against the wheels may be the odometry's sign.
                    assert_eq!(m.contains("counts backward"), deg > 135.0, "{m}");
                }
                r => panic!("{deg}° (fit {may_fit}): {r:?}"),
            }
        }
    }
}
