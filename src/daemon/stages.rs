//! The six stages of the data path, each a [`Stage`] run on its own thread by
//! the pipeline: scanner, localise, map, plan, control, motor. Every stage
//! reads time only through the injected clock; edge waits are converted to
//! wall time with [`crate::clock::Clock::to_wall`].

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Point2;

use super::align::{AlignStep, MAX_ALIGN_SCANS, MIN_AGREEMENT, MIN_WALL_EVIDENCE};
use super::contact::{
    mapped_touch, turn_in_place, BodyTrack, ContactMark, ContactParams, HeldContact, Known,
    MotionMemory,
};
use super::messages::{CmdMsg, MapMsg, MapSnapshot, PathMsg, PoseFix, ScanMsg};
use super::offset_check::{OffsetFit, OFFSET_FIT_MAX, OFFSET_STOP_UNFITTED, OFFSET_TOLERANCE};
use super::shared::{Progress, Shared};
use super::stuck::ProgressWatch;
use super::travel_check::{TravelFit, SCALE_WARN, YAW_FIT_MAX, YAW_STOP_UNFITTED, YAW_TOLERANCE};
use super::turn_check::{fitting_wheel_base, TurnVerdict, SCALE_WARN as TURN_SCALE_WARN};
use crate::clock::SharedClock;
use crate::control::guard::{StopCounter, StopEvent};
use crate::control::PathFollower;
use crate::decomp::Decomposer;
use crate::geom::{carried, heading, IPoint, Pose};
use crate::grid::Grid;
use crate::icp::{Outcome, Tracker};
use crate::motor::{DiffDriveBase, SafetyEvent, Sides, WheelSpeeds};
use crate::pipeline::checkpoint::{ContactArc, ContactArcs, TriedPlaces};
use crate::pipeline::clock::Stamp;
use crate::pipeline::supervisor::Control;
use crate::pipeline::{Poll, Recv, Rx, Stage, StageCtx, StageFault, Tx};
use crate::plan::{CoveragePlanner, PlanStatus, Task};
use crate::urg::UrgDriver;

/// The fault of a send to a stage that has gone: expected while shutting
/// down, fatal otherwise.
fn gone(shared: &Shared, what: &str) -> Result<(), StageFault> {
    if shared.halt.load(Ordering::Relaxed) {
        Ok(())
    } else {
        Err(StageFault::Fatal(format!("the {what} stage is gone")))
    }
}

/// Wall time until clock time `at`, at most `cap`.
fn wall_until(clock: &SharedClock, at: f64, cap: Duration) -> Duration {
    clock.to_wall((at - clock.now()).max(0.0)).min(cap)
}

/// The scanner stage: forwards the URG driver's scans (the driver runs its
/// own reader thread and channel), stamped on arrival and paired with the
/// odometry at the scan's time.
pub struct ScannerStage {
    /// The driver; taken on stop to send QT and join its thread.
    pub driver: Option<UrgDriver>,
    /// Scans out (newest wins).
    pub tx: Tx<ScanMsg>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// The scanner is mounted upside down: its scans are mirrored.
    pub upside_down: bool,
}

impl Stage for ScannerStage {
    type Work = crate::urg::UrgScan;

    fn wait(&mut self, timeout: Duration) -> Poll<Self::Work> {
        let Some(d) = &self.driver else {
            return Poll::Done;
        };
        match d.scans().recv_timeout(timeout) {
            Ok(s) => Poll::Work(s),
            Err(crossbeam_channel::RecvTimeoutError::Timeout) => Poll::Idle,
            Err(crossbeam_channel::RecvTimeoutError::Disconnected) => Poll::Done,
        }
    }

    fn process(&mut self, mut work: Self::Work, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        let t0 = Stamp::now();
        if self.upside_down {
            work.scan.mirror();
        }
        let odom = self.shared.odom.at(work.scan.stamp);
        let msg = ScanMsg {
            t0,
            stamp: work.scan.stamp,
            odom,
            interval: work.interval,
            scan: work.scan,
        };
        ctx.hand_off();
        self.tx
            .send(msg)
            .map_or_else(|_| gone(&self.shared, "localise"), |_| Ok(()))
    }

    fn on_stop(&mut self) {
        if let Some(d) = self.driver.take() {
            d.shutdown();
        }
    }
}

/// The localise stage: intensity-ICP of each newest scan against the
/// tracker's local map with the odometry prior; a rejected or failed match
/// falls back to the odometry prediction (counted) and is kept out of the map.
pub struct LocaliseStage {
    /// The scan-to-map tracker (scanner poses).
    pub tracker: Tracker,
    /// Scans in.
    pub rx: Rx<ScanMsg>,
    /// Pose fixes to control.
    pub to_control: Tx<PoseFix>,
    /// Registered scans to the map.
    pub to_map: Tx<MapMsg>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// Pose of the scanner in the robot frame: the configured (or resumed)
    /// one, refitted by the offset and travel checks (see
    /// [`super::offset_check`], [`super::travel_check`]).
    pub mount: Pose,
    /// Distance between the wheels (m, `robot.wheel_base`), for the
    /// turn check's warning.
    pub wheel_base: f64,
    /// Wheel radius (m, `robot.wheel_radius`), for the travel check's
    /// warning.
    pub wheel_radius: f64,
    /// Whether offset and yaw errors the checks measure are taken into the
    /// mount for the rest of the run (`daemon.fit_scanner_mount`).
    pub fit_mount: bool,
    /// Reused point buffer.
    pub points: Vec<IPoint>,
    /// The restored map of a resumed run: the first scan is laid onto it
    /// (see [`super::relocalise`]) before tracking starts.
    pub relocalise_on: Option<Arc<Grid>>,
    /// Whether to publish the tracker's keyframes for checkpoints (each
    /// time one is added).
    pub publish_keyframes: bool,
    /// Stamp of the previous scan localised (s).
    pub last_stamp: Option<f64>,
    /// At a fresh start, until decided: turns the map frame to the walls
    /// of the first scans before tracking starts (see [`super::align`]).
    pub align: Option<super::align::WallAlign>,
    /// Whether the scans turn with the wheels (a wrong scanner mount).
    pub turn_check: super::turn_check::TurnCheck,
    /// Whether the scans move along the robot's heading (a wrong yaw).
    pub travel_check: super::travel_check::TravelCheck,
    /// Whether the scanner circles the axle at its configured offset when
    /// the robot turns in place (a wrong offset).
    pub offset_check: super::offset_check::OffsetCheck,
    /// The mount's offset was refitted by the offset check (in this run, or
    /// before the checkpoint it resumed from).
    pub offset_fitted: bool,
}

impl LocaliseStage {
    /// Drives with `mount` from now on (a check refitted it); returns the
    /// robot's pose under it, the scanner at `scanner`. The scanner's
    /// odometry jumps with the mount: the motion prior starts over.
    fn refit_mount(&mut self, mount: Pose, scanner: &Pose) -> Pose {
        self.mount = mount;
        self.tracker.set_pose(*scanner);
        self.shared.with_status(|s| s.refitted_mount = Some(mount));
        scanner * mount.inverse()
    }
}

/// A scan further than this many scan intervals after the previous one
/// follows a gap (lost or skipped scans).
const GAP_INTERVALS: f64 = 1.5;

/// A gap at least this long (s) is logged.
const GAP_LOGGED: f64 = 1.0;

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
        ctx.note_age(msg.t0);
        msg.scan.points_into(&mut self.points);
        self.shared
            .with_ahead(|a| a.load_scan(&msg.scan, &self.mount, msg.odom));
        let resuming = self.relocalise_on.is_some();
        if let Some(grid) = self.relocalise_on.take() {
            let guess = self.tracker.pose();
            use super::relocalise::{judge, relocalise, ResumeFit, MIN_FIT};
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
                    super::relocalise::SEARCH_TRANSLATION,
                    super::relocalise::SEARCH_ROTATION.to_degrees(),
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
        // The keyframe (a k-d tree rebuild) is added after the pose is handed on.
        let step = self
            .tracker
            .step_deferred(&self.points, Some(&(robot_odom * self.mount)));
        let matched = matches!(step.outcome, Outcome::First | Outcome::Matched(_));
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
            .step(matched.then_some(&step.pose), &robot_odom)
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
            .step(matched.then_some(&robot), &robot_odom)
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
        self.shared.with_status(|s| {
            s.scans += 1;
            if !matched {
                s.fallbacks += 1;
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
            let kf = Arc::new(self.tracker.state());
            self.shared.with_status(|s| s.keyframes = Some(kf));
        }
        Ok(())
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
/// [`super::offset_check`]) against the `mount` driven with: logs it, and
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
/// [`super::travel_check`]): logs it, warns of a wheel scale off (the
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

/// The map stage: merges registered scans into the explored-area grid and
/// publishes immutable `Arc` snapshots for the planner.
pub struct MapStage {
    /// The map.
    pub grid: Grid,
    /// Registered scans and bumper contacts in.
    pub rx: Rx<MapMsg>,
    /// Snapshots out (newest wins).
    pub tx: Tx<MapSnapshot>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// Longest range merged (m); farther echoes are too uncertain.
    pub max_range: f64,
    /// Bumper contacts: obstacles the scanner cannot see, kept occupied
    /// even when later rays pass over them.
    pub contacts: Vec<ContactMark>,
    /// Contacts that were new (not a repeat of a marked one).
    pub new_contacts: u64,
    /// A contact this close to a marked one is a repeat of it (m).
    pub same_contact: f64,
    /// Requests to take a mark out handled (see [`MapSnapshot::retired`]).
    pub retired: u64,
}

/// The checkpoint section of contact `marks`.
pub fn contact_arcs(marks: &[ContactMark]) -> ContactArcs {
    ContactArcs {
        arcs: marks.iter().map(ContactArc::from).collect(),
    }
}

impl MapStage {
    /// A map stage on `grid` with the contact marks `contacts` (restored
    /// from a checkpoint) marked in it at once.
    pub fn new(
        grid: Grid,
        rx: Rx<MapMsg>,
        tx: Tx<MapSnapshot>,
        shared: Arc<Shared>,
        max_range: f64,
        contacts: Vec<ContactMark>,
        same_contact: f64,
    ) -> Self {
        let mut s = Self {
            grid,
            rx,
            tx,
            shared,
            max_range,
            contacts,
            new_contacts: 0,
            same_contact,
            retired: 0,
        };
        if !s.contacts.is_empty() {
            let arcs = Arc::new(contact_arcs(&s.contacts));
            s.shared.with_status(|st| st.contacts = Some(arcs));
        }
        s.mark_contacts();
        s
    }

    /// Merges a registered scan or a bumper contact into the grid; the
    /// contact marks are occupied again afterwards, whatever the rays
    /// crossed.
    pub fn merge(&mut self, msg: MapMsg) {
        match msg {
            MapMsg::Scan { pose: p, scan } => {
                let o: Point2<f64> = p.translation.vector.into();
                for b in scan.beams.iter() {
                    if !(b.valid && b.range.is_finite() && b.angle.is_finite()) {
                        continue;
                    }
                    let r = b.range.min(self.max_range);
                    let (s, c) = b.angle.sin_cos();
                    let end = p * Point2::new(r * c, r * s);
                    self.grid.integrate_ray(&o, &end, r >= b.range);
                }
            }
            MapMsg::Contact(mark) => {
                if !self
                    .contacts
                    .iter()
                    .any(|c| c.same_as(&mark, self.same_contact))
                {
                    self.contacts.push(mark);
                    self.new_contacts += 1;
                    let arcs = Arc::new(contact_arcs(&self.contacts));
                    self.shared.with_status(|s| s.contacts = Some(arcs));
                }
            }
            MapMsg::Retire(at) => {
                self.retired += 1;
                let (gone, kept): (Vec<ContactMark>, Vec<ContactMark>) = self
                    .contacts
                    .iter()
                    .partition(|c| (c.at - at).norm() <= self.same_contact);
                if !gone.is_empty() {
                    self.contacts = kept;
                    self.shared.marks_taken_out.fetch_add(1, Ordering::Relaxed);
                    // Unknown, not free: a mark beside a wall must not open
                    // a hole in it; the next scan sees what is there.
                    for c in &gone {
                        set_arc(&mut self.grid, c, crate::grid::CellState::Unknown);
                    }
                    let arcs = Arc::new(contact_arcs(&self.contacts));
                    self.shared.with_status(|s| s.contacts = Some(arcs));
                    log::info!(
                        "map: contact mark at ({:.2}, {:.2}) m taken out; {} mark(s) left",
                        at.x,
                        at.y,
                        self.contacts.len()
                    );
                }
            }
        }
        self.mark_contacts();
    }

    fn mark_contacts(&mut self) {
        for c in &self.contacts {
            set_arc(&mut self.grid, c, crate::grid::CellState::Occupied);
        }
    }
}

/// Sets every cell of `grid` the arc of `mark` lies in to `state`.
fn set_arc(grid: &mut Grid, mark: &ContactMark, state: crate::grid::CellState) {
    for cell in mark.cells(grid) {
        grid.set_state(cell, state);
    }
}

impl Stage for MapStage {
    type Work = MapMsg;

    fn wait(&mut self, timeout: Duration) -> Poll<MapMsg> {
        match self.rx.recv_timeout(timeout) {
            Recv::Msg(m) => Poll::Work(m),
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }

    fn process(&mut self, msg: MapMsg, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        self.merge(msg);
        let snap = Arc::new(self.grid.clone());
        self.shared.with_status(|s| s.grid = Some(snap.clone()));
        let msg = MapSnapshot {
            grid: snap,
            contacts: self.new_contacts,
            retired: self.retired,
        };
        ctx.hand_off();
        self.tx
            .send(msg)
            .map_or_else(|_| gone(&self.shared, "plan"), |_| Ok(()))
    }
}

/// A planner record to publish: `get`'s, when its `generation` differs
/// from the one `published` last (which it then becomes); `None` when
/// unchanged, so the record (a scan of the whole grid) is copied out only
/// when it changed.
fn changed<T>(
    generation: u64,
    published: &mut u64,
    get: impl FnOnce() -> Option<T>,
) -> Option<Arc<T>> {
    if generation == *published {
        return None;
    }
    let record = get().map(Arc::new);
    if record.is_some() {
        *published = generation;
    }
    record
}

/// The plan stage: online cell decomposition and the coverage planner on
/// each new map snapshot, rate-limited (more so when degraded); tells the
/// supervisor when nothing reachable is left.
pub struct PlanStage {
    /// The decomposer.
    pub decomposer: Decomposer,
    /// The planner.
    pub planner: CoveragePlanner,
    /// Map snapshots in.
    pub rx: Rx<MapSnapshot>,
    /// Executed poses in (the tool swept the floor there).
    pub poses: Rx<Pose>,
    /// Paths out.
    pub tx: Tx<PathMsg>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// Asks the supervisor to stop when coverage is done.
    pub control: Control,
    /// The injected clock.
    pub clock: SharedClock,
    /// Shortest time between two planning updates (clock s).
    pub min_interval: f64,
    /// Clock time of the last update.
    pub last: f64,
    /// Sequence number of the last path sent.
    pub seq: u64,
    /// Updates so far.
    pub updates: u64,
    /// The planner's tries generation last published (see
    /// [`CoveragePlanner::tries_generation`]).
    pub tries_published: u64,
    /// The planner's reach generation last published (see
    /// [`CoveragePlanner::reach_generation`]).
    pub reach_published: u64,
    /// New bumper contacts the planner has been told of.
    pub contacts_seen: u64,
    /// Clock time of the last bump whose contact the planner has seen.
    pub bump_handled: f64,
    /// Longest a plan update waits for a bump's contact to reach the map
    /// (clock s).
    pub contact_settle: f64,
    /// Contact marks that wall off floor, taken out once at the end.
    pub probe: MarkProbe,
}

/// The plan stage's second look at bumper contact marks when coverage is
/// otherwise done (see [`MarkProbe::walled_floor`]).
pub struct MarkProbe {
    /// Requests to take a contact mark out go to the map stage here.
    pub to_map: Tx<MapMsg>,
    /// Whether marks that wall off floor are taken out at all.
    pub on: bool,
    /// Least floor a mark must wall off to be taken out (m²): as much as
    /// the planner sends a lane for (`plan.min_lane_area`).
    pub least: f64,
    /// A mark this close to one taken out before stays (m): the floor
    /// behind it has had its try.
    pub spacing: f64,
    /// Where marks were taken out.
    pub probed: Vec<Point2<f64>>,
    /// Requests to take a mark out sent so far.
    pub sent: u64,
    /// Clock time of the last such request.
    pub sent_at: f64,
}

impl Stage for PlanStage {
    type Work = MapSnapshot;

    fn wait(&mut self, timeout: Duration) -> Poll<MapSnapshot> {
        if self.shared.done.load(Ordering::Relaxed) {
            std::thread::sleep(timeout);
            return Poll::Idle;
        }
        let due = self.last + self.min_interval;
        if self.clock.now() < due {
            std::thread::sleep(wall_until(&self.clock, due, timeout));
            return Poll::Idle;
        }
        match self.rx.recv_timeout(timeout) {
            Recv::Msg(g) => match self.rx.try_recv_newest() {
                Recv::Msg(newer) => Poll::Work(newer),
                _ => Poll::Work(g),
            },
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }

    fn process(&mut self, snap: MapSnapshot, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        self.last = self.clock.now() + self.min_interval * f64::from(ctx.degrade());
        while let Recv::Msg(p) = self.poses.try_recv() {
            self.planner.record_pose(&p);
        }
        let grid = snap.grid;
        let bump = self.shared.last_bump();
        if snap.contacts > self.contacts_seen {
            // The path ran into an obstacle the map did not show; the map
            // has it now: plan again, the floor it was after is not at fault.
            self.contacts_seen = snap.contacts;
            self.bump_handled = bump;
            self.planner.interrupt();
        } else if bump > self.bump_handled {
            if self.clock.now() - bump < self.contact_settle {
                // A bump whose contact is not in this snapshot yet: wait
                // for the one that has it rather than plan without it.
                return Ok(());
            }
            // A repeat of a marked contact: nothing new to plan around.
            self.bump_handled = bump;
        }
        if snap.retired < self.probe.sent
            && self.clock.now() - self.probe.sent_at < self.contact_settle
        {
            // A mark was taken out: plan on the map without it.
            return Ok(());
        }
        let decomp = self.decomposer.update(&grid, &[]);
        let progress = self.shared.progress();
        let progress = if progress.path_seq == self.seq {
            progress.next
        } else {
            Some(0)
        };
        let here = self.shared.with_status(|s| s.pose);
        self.planner.set_time(self.clock.now());
        let status = self
            .planner
            .update(&grid, decomp, &here, progress)
            .map_err(|e| StageFault::Transient(format!("planner: {e}")))?;
        self.updates += 1;
        let res = self.planner.cspace().frame.res;
        let covered = self.planner.covered().iter().filter(|c| **c).count() as f64 * res * res;
        let snapshot = (self.updates % 5 == 1).then(|| Arc::new(decomp.clone()));
        let task = match status {
            PlanStatus::Working { task, .. } => format!("{task:?}"),
            PlanStatus::Done(_) => "Done".into(),
        };
        let swept = self.planner.swept().map(Arc::new);
        let lattice = self.planner.lattice();
        let home = self.planner.home();
        let planner = &self.planner;
        let tries = changed(
            planner.tries_generation(),
            &mut self.tries_published,
            || planner.tries(),
        );
        let reach = changed(
            planner.reach_generation(),
            &mut self.reach_published,
            || planner.reach(),
        );
        self.shared.with_status(|s| {
            if tries.is_some() {
                s.tries = tries;
            }
            if reach.is_some() {
                s.reach = reach;
            }
            s.covered_area = covered;
            if swept.is_some() {
                s.swept = swept;
            }
            if lattice != crate::plan::LatticePhase::default() {
                s.lattice = Some(lattice);
            }
            if home.is_some() {
                s.home = home;
            }
            s.task = task;
            if let Some(d) = snapshot {
                s.decomposition = Some(d);
            }
        });
        // Coverage just done, the way back planned but not yet sent: a
        // bumper mark walling off floor is taken out before the robot
        // leaves (after, it would drive back out again).
        let just_done = match status {
            PlanStatus::Done(_) => true,
            PlanStatus::Working {
                task: Task::Home,
                new_path: true,
            } => self.planner.home_plans() == 1,
            _ => false,
        };
        match status {
            _ if just_done
                && self.probe.walled_floor(
                    &mut self.planner,
                    &self.shared,
                    self.clock.now(),
                    &grid,
                    &here,
                ) => {}
            PlanStatus::Done(r) => {
                let stats = self.planner.stats();
                self.shared.with_status(|s| {
                    s.decomposition = Some(Arc::new(decomp.clone()));
                    s.plan_stats = stats;
                });
                self.shared.done.store(true, Ordering::Relaxed);
                log::info!(
                    "coverage finished: {:.2} m² swept, {:.2} m² unreachable, {:.2} m² behind passages tighter than the clearance, {:.2} m² abandoned, {:.2} m² of leftovers declined, {:.2} m of frontier left unexplored; drive back to the start: {} ({:.2} m from it)",
                    r.covered_area,
                    r.unreachable_area,
                    r.behind_tight_passages,
                    r.abandoned_area,
                    r.declined_area,
                    r.unexplored_frontier,
                    r.home.describe(),
                    r.home_distance
                );
                self.shared.with_status(|s| s.home_outcome = Some(r.home));
                self.control.stop("coverage finished");
            }
            PlanStatus::Working { new_path: true, .. } => {
                self.seq += 1;
                let (points, final_heading) = self.planner.path();
                let motions = super::shared::PathMotions {
                    seq: self.seq,
                    task: u32::try_from(self.planner.stats().tasks).unwrap_or(u32::MAX),
                    motions: self.planner.motions().into(),
                };
                let stats = self.planner.stats();
                self.shared.with_status(|s| {
                    s.path_motions = Some(motions);
                    s.plan_stats = stats;
                });
                let msg = PathMsg {
                    seq: self.seq,
                    points: points.to_vec(),
                    final_heading,
                };
                ctx.hand_off();
                if self.tx.send(msg).is_err() {
                    return gone(&self.shared, "control");
                }
            }
            PlanStatus::Working { .. } => {}
        }
        Ok(())
    }
}

impl MarkProbe {
    /// A probe sending its requests on `to_map`, with the places `tried`
    /// before a restart (published at once for the next checkpoint).
    pub fn new(
        to_map: Tx<MapMsg>,
        on: bool,
        least: f64,
        spacing: f64,
        tried: Vec<Point2<f64>>,
        shared: &Shared,
    ) -> Self {
        if !tried.is_empty() {
            log::info!(
                "resume: {} place(s) where contact marks were tried restored; marks near them stay",
                tried.len()
            );
        }
        let probe = Self {
            to_map,
            on,
            least,
            spacing,
            probed: tried,
            sent: 0,
            sent_at: f64::NEG_INFINITY,
        };
        probe.publish(shared);
        probe
    }

    /// Hands the tried places to the checkpoint (none yet: nothing).
    fn publish(&self, shared: &Shared) {
        if self.probed.is_empty() {
            return;
        }
        let tried = Arc::new(TriedPlaces {
            places: self.probed.clone(),
        });
        shared.with_status(|s| s.contacts_tried = Some(tried));
    }

    /// At the end of coverage (the `planner` is done): takes out the
    /// bumper contact mark that walls off the most unswept floor, if that is
    /// at least `least` and no mark was taken out near it before; reopens
    /// the planner and returns true (coverage goes on). A one-bit bumper cannot tell where on its arc it
    /// closed; its mark is a guess that can stand in open floor and shut a
    /// passage the robot fits through. Tried again, the floor is swept, or
    /// the bumper closes again and marks the obstacle from a new bearing
    /// (that mark stays). Marks on an unseen obstacle wall off floor too
    /// (the obstacle's own, free in the map): one mark per end of coverage,
    /// the one walling off the most, and none within `spacing` of a place
    /// tried before, so an obstacle costs at most one more bump.
    pub fn walled_floor(
        &mut self,
        planner: &mut CoveragePlanner,
        shared: &Shared,
        now: f64,
        grid: &Grid,
        here: &Pose,
    ) -> bool {
        if !self.on {
            return false;
        }
        let Some(arcs) = shared.with_status(|s| s.contacts.clone()) else {
            return false;
        };
        let robot: Point2<f64> = here.translation.vector.into();
        let mut best: Option<(Point2<f64>, f64)> = None;
        for m in arcs.arcs.iter().map(|&a| ContactMark::from(a)) {
            if self
                .probed
                .iter()
                .any(|p| (p - m.at).norm() <= self.spacing)
            {
                continue;
            }
            let cells: Vec<_> = m.cells(grid).collect();
            let area = planner.floor_walled_off(grid, &cells, &robot);
            log::debug!(
                "plan: the contact mark at ({:.2}, {:.2}) m walls off {area:.3} m² of unswept floor",
                m.at.x,
                m.at.y
            );
            if area + 1e-9 >= self.least && best.is_none_or(|(_, a)| area > a) {
                best = Some((m.at, area));
            }
        }
        let Some((at, area)) = best else {
            return false;
        };
        log::warn!(
            "plan: the contact mark at ({:.2}, {:.2}) m walls off {:.3} m² of unswept floor; a bumper's mark is a guess at where it closed, so it is taken out and that floor tried once more",
            at.x,
            at.y,
            area
        );
        // Tried before the request goes: a checkpoint between the two keeps
        // the mark and the place, and the resumed run leaves the mark.
        self.probed.push(at);
        self.publish(shared);
        if self.to_map.send(MapMsg::Retire(at)).is_err() {
            return false;
        }
        self.sent += 1;
        self.sent_at = now;
        planner.reopen(&[at], self.spacing);
        true
    }
}

/// What wakes the control stage.
#[derive(Debug)]
pub enum ControlWork {
    /// A new path.
    Path(PathMsg),
    /// A new pose fix: a command goes out at once (end-to-end latency).
    Fix(PoseFix),
    /// The 20 Hz tick.
    Tick,
}

/// The control stage: path following at a fixed rate on the latest pose
/// (last ICP pose composed with the odometry since), plus one immediate
/// command per new pose fix. Stops on shutdown or when done; backs off after
/// a bumper contact.
pub struct ControlStage {
    /// The path follower.
    pub follower: PathFollower,
    /// Paths in.
    pub paths: Rx<PathMsg>,
    /// Pose fixes in.
    pub fixes: Rx<PoseFix>,
    /// Wheel commands out.
    pub tx: Tx<CmdMsg>,
    /// Executed poses out, for the planner's swept-floor record.
    pub poses: Tx<Pose>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// The injected clock.
    pub clock: SharedClock,
    /// Control period (clock s).
    pub period: f64,
    /// Clock time of the next tick.
    pub next_tick: f64,
    /// Clock time of the last command.
    pub last_cmd: f64,
    /// The newest pose fix.
    pub fix: Option<PoseFix>,
    /// Where the robot started (used before the first fix).
    pub start: Pose,
    /// Sequence number of the path followed.
    pub path_seq: u64,
    /// Wheel base (m).
    pub wheel_base: f64,
    /// Reversing time after a bumper contact (clock s).
    pub backoff: f64,
    /// Last pose estimate (for the path length).
    pub last_pose: Option<Pose>,
    /// Clock time of the last bump handled.
    pub bump_seen: f64,
    /// Headway on the current path.
    pub watch: ProgressWatch,
    /// Clock seconds without a new scan after which the wheels are held.
    pub scan_timeout: f64,
    /// Clock time since which the wheels are held for lack of scans.
    pub held_since: Option<f64>,
    /// The protective field's stops.
    pub guard: StopCounter,
    /// Whether the log has said that the scans do not span the way ahead.
    pub blind_ahead_told: bool,
}

impl ControlStage {
    /// The current pose estimate.
    fn estimate(&self) -> Pose {
        let odom = self.shared.odom.latest();
        match &self.fix {
            Some(f) => carried(&f.pose, &f.odom, &odom),
            None => carried(&self.start, &Pose::identity(), &odom),
        }
    }

    /// Gives the path up when the follower has made no headway for
    /// `daemon.stuck_after` seconds (see [`ProgressWatch`]):
    /// the planner then hears the path ended and plans again.
    fn watch_headway(&mut self, now: f64, est: &Pose) {
        if self.follower.is_done() {
            self.watch.reset();
            return;
        }
        let next = self.follower.next_index();
        let here: Point2<f64> = est.translation.vector.into();
        let distance = self.follower.path().get(next).map(|g| (g - here).norm());
        if self.watch.stuck(now, self.path_seq, next, distance) {
            log::warn!(
                "control: no headway towards waypoint {next} of path {} for {:.0} s (at {:.2}, {:.2}); path given up",
                self.path_seq,
                self.watch.after(),
                here.x,
                here.y
            );
            self.shared.stuck_paths.fetch_add(1, Ordering::Relaxed);
            self.follower.set_path(&[], None);
            self.watch.reset();
        }
    }

    /// Whether the newest scan is older than `scan_timeout` (the scanner
    /// is gone or stalled), logging when the hold starts and ends. Before
    /// the first scan nothing moves the robot anyway.
    fn lacks_scans(&mut self, now: f64) -> bool {
        let Some(age) = self.fix.map(|f| now - f.stamp) else {
            return false;
        };
        let blind = age > self.scan_timeout;
        match (blind, self.held_since) {
            (true, None) => {
                self.held_since = Some(now);
                self.shared.scan_holds.fetch_add(1, Ordering::Relaxed);
                log::warn!(
                    "control: no scan for {age:.1} s (more than daemon.scan_timeout); wheels held until scans return"
                );
            }
            (false, Some(t)) => {
                self.held_since = None;
                log::info!(
                    "control: scans are back; wheels were held for {:.1} s",
                    now - t
                );
            }
            _ => {}
        }
        blind
    }

    /// Counts and logs the follower's stops short of something unplanned
    /// ahead (the protective field).
    fn note_guard(&mut self, now: f64, est: &Pose) {
        if !self.blind_ahead_told {
            let covers = self.shared.with_ahead(|a| a.covers_ahead);
            if covers == Some(false) && self.follower.guards() {
                self.blind_ahead_told = true;
                log::warn!(
                    "control: the scans do not span straight ahead of the robot (robot.scanner_yaw?); the protective field (control.guard) watches nothing"
                );
            }
        }
        let (x, y) = (est.translation.x, est.translation.y);
        match self.guard.note(self.follower.held_short(), now) {
            Some(StopEvent::Began) => {
                self.shared.guard_stops.fetch_add(1, Ordering::Relaxed);
                log::info!(
                    "control: something the path does not expect is straight ahead of the robot at ({x:.2}, {y:.2}); slowing to stop control.guard_gap short of it"
                );
            }
            Some(StopEvent::Ended) => {
                log::info!("control: the way ahead is clear again at ({x:.2}, {y:.2})")
            }
            None => {}
        }
    }

    /// The wheel speeds for the estimate `est` at clock time `now`, `dt`
    /// after the last command: stop when halted or done, reverse after a
    /// bump, hold without scans, else follow the path (with the protective
    /// field on the newest scan's points).
    fn wheels(&mut self, now: f64, dt: f64, est: &Pose) -> WheelSpeeds {
        let blind = self.lacks_scans(now);
        if self.shared.halt.load(Ordering::Relaxed) || self.shared.done.load(Ordering::Relaxed) {
            WheelSpeeds::STOP
        } else if now - self.shared.last_bump() < self.backoff
            || (self.shared.bumper_closed.load(Ordering::Relaxed)
                && now - self.shared.last_bump() < super::BUMP_BACKOFF_MAX)
        {
            if self.shared.last_bump() != self.bump_seen {
                // The path runs into something the map did not show: drop
                // it; the planner plans again around the contact.
                self.bump_seen = self.shared.last_bump();
                self.follower.set_path(&[], None);
            }
            WheelSpeeds::from_body(-0.05, 0.0, self.wheel_base)
        } else if blind {
            self.watch.reset();
            WheelSpeeds::STOP
        } else {
            self.watch_headway(now, est);
            let odom = self.shared.odom.latest();
            let (_, w) = self
                .shared
                .with_ahead(|a| self.follower.step_guarded(est, dt, Some((a, &odom))));
            self.note_guard(now, est);
            WheelSpeeds {
                left: w.left,
                right: w.right,
            }
        }
    }

    /// Computes and sends the wheel command for the newest estimate; `t0`
    /// is the scan's last byte when a pose fix triggered it.
    fn command(&mut self, t0: Option<Stamp>, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        let now = self.clock.now();
        let dt = (now - self.last_cmd).clamp(1e-3, 4.0 * self.period);
        self.last_cmd = now;
        let est = self.estimate();
        let wheels = self.wheels(now, dt, &est);
        let d = self
            .last_pose
            .map(|p| (p.translation.vector - est.translation.vector).norm())
            .unwrap_or(0.0);
        self.last_pose = Some(est);
        let matched = self.fix.is_some_and(|f| f.matched);
        self.shared.with_status(|s| {
            s.pose = est;
            s.pose_time = now;
            s.localised |= matched;
            s.path_length += d;
        });
        self.shared.set_progress(Progress {
            path_seq: self.path_seq,
            next: (!self.follower.is_done()).then(|| self.follower.next_index()),
        });
        ctx.hand_off();
        let _ = self.poses.send(est);
        match self.tx.send(CmdMsg { wheels, t0 }) {
            Ok(_) => Ok(()),
            Err(_) if self.shared.halt.load(Ordering::Relaxed) => Ok(()),
            Err(_) => Err(StageFault::Fatal("the motor stage is gone".into())),
        }
    }
}

impl Stage for ControlStage {
    type Work = ControlWork;

    fn wait(&mut self, timeout: Duration) -> Poll<ControlWork> {
        if let Recv::Msg(p) = self.paths.try_recv_newest() {
            return Poll::Work(ControlWork::Path(p));
        }
        let now = self.clock.now();
        if now >= self.next_tick {
            self.next_tick = (self.next_tick + self.period).max(now);
            return Poll::Work(ControlWork::Tick);
        }
        match self
            .fixes
            .recv_timeout(wall_until(&self.clock, self.next_tick, timeout))
        {
            Recv::Msg(f) => Poll::Work(ControlWork::Fix(f)),
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }

    fn process(&mut self, work: ControlWork, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        match work {
            ControlWork::Path(p) => {
                self.follower.set_path(&p.points, p.final_heading);
                self.path_seq = p.seq;
                self.shared.set_progress(Progress {
                    path_seq: p.seq,
                    next: (!self.follower.is_done()).then(|| self.follower.next_index()),
                });
                Ok(())
            }
            ControlWork::Fix(f) => {
                ctx.note_age(f.t0);
                let t0 = f.t0;
                self.fix = Some(f);
                self.command(Some(t0), ctx)
            }
            ControlWork::Tick => self.command(None, ctx),
        }
    }
}

/// What wakes the motor stage.
#[derive(Debug)]
pub enum MotorWork {
    /// A wheel command.
    Cmd(CmdMsg),
    /// Time to read the encoders and sensors.
    Poll,
}

/// The motor stage: owns the wheel-base driver; commands out, encoder
/// odometry and safety events in; stops the wheels when it ends.
pub struct MotorStage {
    /// The base driver.
    pub base: Box<dyn DiffDriveBase>,
    /// Commands in.
    pub rx: Rx<CmdMsg>,
    /// Bumper contacts to the map.
    pub to_map: Tx<MapMsg>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// The injected clock.
    pub clock: SharedClock,
    /// Encoder polling period (clock s).
    pub period: f64,
    /// Clock time of the next poll.
    pub next_poll: f64,
    /// Robot radius (m): where a bumper contact is.
    pub radius: f64,
    /// Wheel base (m).
    pub wheel_base: f64,
    /// The last wheel speeds commanded.
    pub last_wheels: WheelSpeeds,
    /// The wheels' measured motion: what a contact interrupted.
    pub motion: MotionMemory,
    /// Where the body has been (rules out contact bearings).
    pub track: BodyTrack,
    /// Where contact marks go.
    pub contact: ContactParams,
    /// A contact closed before the pose was known.
    pub held: HeldContact,
}

impl MotorStage {
    /// Marks a contact closed on `sides` (`None`: the bumper cannot tell)
    /// with the robot at `at` commanded to `wheels`: to the map first, so
    /// the snapshot that makes the planner plan again already holds it.
    fn mark(&mut self, what: &str, at: &Pose, sides: Option<Sides>, wheels: WheelSpeeds) {
        let (known, grid) = self
            .shared
            .with_status(|s| (s.contacts.clone(), s.grid.clone()));
        let explained = known.as_deref().and_then(|k| {
            k.arcs
                .iter()
                .map(|&a| ContactMark::from(a))
                .find(|m| m.explains(&self.contact, at, sides, self.radius))
        });
        let touched = explained.map(|m| ("the contact marked", m.at)).or_else(|| {
            let (turning, _) = turn_in_place(&self.contact, wheels, self.radius, self.wheel_base);
            let grid = grid.as_deref()?;
            turning
                .then(|| mapped_touch(grid, &self.contact, at, sides, self.radius))
                .flatten()
                .map(|p| ("the mapped wall", p))
        });
        if let Some((what_is_there, p)) = touched {
            log::warn!(
                "safety: {what}: robot at ({:.2}, {:.2}) m {:.0}° touches {what_is_there} at ({:.2}, {:.2}) m: nothing new marked",
                at.translation.x,
                at.translation.y,
                heading(at).to_degrees(),
                p.x,
                p.y,
            );
            return;
        }
        let centre: Point2<f64> = at.translation.vector.into();
        let near = known.as_deref().and_then(|k| {
            k.arcs
                .iter()
                .map(|a| a.at)
                .filter(|q| (q - centre).norm() <= self.contact.prior_reach(self.radius))
                .min_by(|a, b| (a - centre).norm().total_cmp(&(b - centre).norm()))
        });
        let mark = ContactMark::estimate(
            &self.contact,
            at,
            sides,
            wheels,
            self.radius,
            self.wheel_base,
            Known {
                track: Some(&self.track),
                near,
            },
        );
        let _ = self.to_map.send(MapMsg::Contact(mark));
        log::warn!(
            "safety: {what}: contact at ({:.2}, {:.2}) m, robot at ({:.2}, {:.2}) m {:.0}°, wheels ({:+.2}, {:+.2}) m/s",
            mark.at.x,
            mark.at.y,
            at.translation.x,
            at.translation.y,
            heading(at).to_degrees(),
            wheels.left,
            wheels.right,
        );
    }

    fn poll(&mut self) -> Result<(), StageFault> {
        let fb = self.base.poll();
        self.shared.set_base_health(self.base.health());
        let fb = fb.map_err(|e| StageFault::Transient(e.to_string()))?;
        if let Some(o) = fb.odometry {
            self.shared.odom.push(o.t1, &o.delta);
            self.held.moved(&o.delta);
            self.motion.note(&o);
        }
        // After this poll's odometry: the pose a contact closed at.
        let (here, localised) = self.shared.pose_now();
        if localised {
            self.track
                .stamp(&here.translation.vector.into(), self.radius);
        }
        if let Some((sides, wheels, at)) = self.held.release(localised, &here) {
            self.mark("contact held until the pose was known", &at, sides, wheels);
        }
        for e in fb.events.iter() {
            match e {
                SafetyEvent::Bumper(sides) | SafetyEvent::WheelDrop(sides) => {
                    if matches!(e, SafetyEvent::Bumper(_)) {
                        self.shared.bumper_closed.store(true, Ordering::Relaxed);
                    }
                    let sides = self.base.bumper_sides().then_some(*sides);
                    let wheels = self.motion.interrupted(self.clock.now(), self.last_wheels);
                    match self.held.closed(localised, sides, wheels) {
                        Some((sides, wheels)) => self.mark(&format!("{e:?}"), &here, sides, wheels),
                        None => log::warn!(
                            "safety: {e:?} before the first matched scan: the contact is marked once the pose is known"
                        ),
                    }
                    self.shared.note_bump(self.clock.now());
                    self.shared.safety_events.fetch_add(1, Ordering::Relaxed);
                }
                SafetyEvent::BumperReleased => {
                    self.shared.bumper_closed.store(false, Ordering::Relaxed);
                }
                SafetyEvent::DeadMan | SafetyEvent::LinkLost => {
                    self.shared.safety_events.fetch_add(1, Ordering::Relaxed);
                    log::warn!("wheel base: {e:?}");
                }
                _ => {}
            }
        }
        Ok(())
    }
}

impl Stage for MotorStage {
    type Work = MotorWork;

    fn wait(&mut self, timeout: Duration) -> Poll<MotorWork> {
        if self.clock.now() >= self.next_poll {
            self.next_poll = (self.next_poll + self.period).max(self.clock.now());
            return Poll::Work(MotorWork::Poll);
        }
        match self
            .rx
            .recv_timeout(wall_until(&self.clock, self.next_poll, timeout))
        {
            Recv::Msg(c) => Poll::Work(MotorWork::Cmd(c)),
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }

    fn process(&mut self, work: MotorWork, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        match work {
            MotorWork::Cmd(c) => {
                let wheels = if self.shared.halt.load(Ordering::Relaxed) {
                    WheelSpeeds::STOP
                } else {
                    c.wheels
                };
                self.last_wheels = wheels;
                let r = self.base.set_wheels(wheels);
                if let Some(t0) = c.t0 {
                    ctx.end_to_end(t0);
                }
                r.map_err(|e| StageFault::Transient(e.to_string()))
            }
            MotorWork::Poll => self.poll(),
        }
    }

    fn on_stop(&mut self) {
        if let Err(e) = self.base.stop() {
            log::warn!("could not stop the wheels on shutdown: {e}");
        }
        self.shared.set_base_health(self.base.health());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decomp::Decomposition;
    use crate::grid::CellState;
    use crate::pipeline::{queue, Overflow, Recv};

    /// The walled room (3 m × 2 m) split at x = 1.5 m by a wall with a
    /// 0.6 m passage at the top, a bumper's mark standing in the passage;
    /// the planner has seen it once from (0.4, 0.4).
    fn passage_shut_by_a_mark() -> (Grid, CoveragePlanner, Shared, Point2<f64>) {
        let mut g = crate::plan::test_support::walled_room();
        for y in 0..27 {
            g.set_state((30, y), CellState::Occupied);
        }
        g.set_state((30, 33), CellState::Occupied);
        let at = g.centre_of((30, 33));
        let mut p = crate::plan::test_support::planner();
        p.update(
            &g,
            &Decomposition::default(),
            &crate::geom::pose(0.4, 0.4, 0.0),
            None,
        )
        .unwrap();
        let shared = Shared::default();
        let arc = ContactArc {
            centre: at - nalgebra::Vector2::new(0.18, 0.0),
            at,
            half_length: 0.02,
        };
        let arcs = Arc::new(ContactArcs { arcs: vec![arc] });
        shared.with_status(|s| s.contacts = Some(arcs));
        (g, p, shared, at)
    }

    /// A control stage at the map origin facing +x, a pose fix just in,
    /// following a 3 m lane along +x; its channels lead nowhere.
    fn control_stage(shared: Arc<Shared>) -> ControlStage {
        let robot = crate::config::RobotParams::default();
        let mut follower =
            PathFollower::new(&crate::control::ControlParams::default(), &robot).unwrap();
        follower.set_path(&[Point2::new(3.0, 0.0)], None);
        let clock: SharedClock = Arc::new(crate::clock::ScaledClock::new(1.0));
        let now = clock.now();
        let (_, paths) = queue::<PathMsg>("paths", 1, Overflow::DropOldest);
        let (_, fixes) = queue::<PoseFix>("fixes", 1, Overflow::DropOldest);
        let (tx, _) = queue::<CmdMsg>("cmds", 1, Overflow::DropOldest);
        let (poses, _) = queue::<Pose>("poses", 1, Overflow::DropOldest);
        ControlStage {
            follower,
            paths,
            fixes,
            tx,
            poses,
            shared,
            clock,
            period: 0.05,
            next_tick: now,
            last_cmd: now,
            fix: Some(PoseFix {
                t0: Stamp::now(),
                stamp: now,
                pose: Pose::identity(),
                odom: Pose::identity(),
                matched: true,
            }),
            start: Pose::identity(),
            path_seq: 1,
            wheel_base: robot.wheel_base,
            backoff: super::super::BUMP_BACKOFF,
            last_pose: None,
            bump_seen: f64::NEG_INFINITY,
            watch: crate::daemon::stuck::ProgressWatch::new(20.0),
            scan_timeout: 1.0,
            held_since: None,
            guard: StopCounter::default(),
            blind_ahead_told: false,
        }
    }

    #[test]
    fn the_control_stage_stops_short_of_what_the_localised_scan_shows_ahead() {
        let shared = Arc::new(Shared::default());
        let mut c = control_stage(shared.clone());
        let now = c.clock.now();
        let here = Pose::identity();
        // Nothing seen yet: the robot sets off along the lane.
        let w = c.wheels(now, 0.05, &here);
        assert!(w.left > 0.0 && w.right > 0.0, "{w:?}");
        // The localise stage loads a scan from a scanner 0.1 m ahead of the
        // axle: a person's legs 0.12 m in front of it, 0.22 m from the axle,
        // just clear of the 0.17 m body. The robot stands.
        let mut scan = crate::scan::LaserScan::default();
        for k in -5..=5 {
            let _ = scan.beams.push(crate::scan::Beam {
                angle: 0.05 * f64::from(k),
                range: 0.12,
                intensity: 0.0,
                valid: true,
            });
        }
        let mount = crate::geom::pose(0.1, 0.0, 0.0);
        shared.with_ahead(|a| a.load_scan(&scan, &mount, Pose::identity()));
        for k in 1..=3 {
            let w = c.wheels(now + 0.05 * f64::from(k), 0.05, &here);
            assert_eq!((w.left, w.right), (0.0, 0.0), "step {k}");
        }
        assert_eq!(shared.guard_stops.load(Ordering::Relaxed), 1);
        // The next scan shows the way clear: the robot drives on.
        let mut clear = scan.clone();
        for b in clear.beams.iter_mut() {
            b.range = 3.0;
        }
        shared.with_ahead(|a| a.load_scan(&clear, &mount, Pose::identity()));
        let w = c.wheels(now + 0.25, 0.05, &here);
        assert!(w.left > 0.0 && w.right > 0.0, "{w:?}");
        assert!(!c.blind_ahead_told);
        // A scanner turned to face backwards: said once in the log.
        let back = crate::geom::pose(0.0, 0.0, std::f64::consts::PI);
        shared.with_ahead(|a| a.load_scan(&scan, &back, Pose::identity()));
        c.wheels(now + 0.3, 0.05, &here);
        assert!(c.blind_ahead_told);
    }

    #[test]
    fn a_mark_is_taken_out_once_and_the_place_tried_outlives_a_restart() {
        let (g, mut p, shared, at) = passage_shut_by_a_mark();
        let here = crate::geom::pose(0.4, 0.4, 0.0);
        let (tx, rx) = queue("map_msgs", 8, Overflow::DropOldest);
        let mut probe = MarkProbe::new(tx.clone(), true, 0.05, 0.34, Vec::new(), &shared);
        assert!(shared.with_status(|s| s.contacts_tried.is_none()));
        assert!(probe.walled_floor(&mut p, &shared, 1.0, &g, &here));
        assert!(matches!(rx.try_recv(), Recv::Msg(MapMsg::Retire(q)) if q == at));
        // The place is handed to the checkpoint, and not tried again.
        let saved = shared.with_status(|s| s.contacts_tried.clone()).unwrap();
        assert_eq!(saved.places, vec![at]);
        assert!(!probe.walled_floor(&mut p, &shared, 2.0, &g, &here));
        assert_eq!(probe.sent, 1);

        // A resumed run with the checkpoint's places leaves the mark, and
        // its next checkpoint still holds them.
        let (g, mut p, shared, _) = passage_shut_by_a_mark();
        let mut resumed = MarkProbe::new(tx, true, 0.05, 0.34, saved.places.clone(), &shared);
        let kept = shared.with_status(|s| s.contacts_tried.clone()).unwrap();
        assert_eq!(kept.places, vec![at]);
        assert!(!resumed.walled_floor(&mut p, &shared, 1.0, &g, &here));
        assert_eq!(resumed.sent, 0);
        assert!(matches!(rx.try_recv(), Recv::Empty));
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
