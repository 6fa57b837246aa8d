//! The control stage: path following on the latest pose, wheel commands out.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Point2;

use super::wall_until;
use crate::clock::SharedClock;
use crate::control::guard::{StopCounter, StopEvent};
use crate::control::PathFollower;
use crate::daemon::messages::{CmdMsg, PathMsg, PoseFix};
use crate::daemon::shared::{Progress, Shared};
use crate::daemon::stuck::ProgressWatch;
use crate::geom::{carried, Pose};
use crate::motor::WheelSpeeds;
use crate::pipeline::clock::Stamp;
use crate::pipeline::{Poll, Recv, Rx, Stage, StageCtx, StageFault, Tx};

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
    pub(crate) next_tick: f64,
    /// Clock time of the last command.
    pub(crate) last_cmd: f64,
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
    pub(crate) bump_seen: f64,
    /// Headway on the current path.
    pub watch: ProgressWatch,
    /// Clock seconds without a new scan after which the wheels are held.
    pub scan_timeout: f64,
    /// Clock time since which the wheels are held for lack of scans.
    pub held_since: Option<f64>,
    /// The protective field's stops.
    pub guard: StopCounter,
    /// Whether the log has said that the scans do not span the way ahead.
    pub(crate) blind_ahead_told: bool,
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
                && now - self.shared.last_bump() < crate::daemon::BUMP_BACKOFF_MAX)
        {
            if self.shared.last_bump() != self.bump_seen {
                // The path runs into something the map did not show: drop
                // it; the planner plans again around the contact.
                self.bump_seen = self.shared.last_bump();
                self.follower.set_path(&[], None);
            }
            WheelSpeeds::from_body(-0.05, 0.0, self.wheel_base)
        } else if blind || self.shared.lost.load(Ordering::Relaxed) {
            // Lost: the path was planned from a pose the scans no longer
            // confirm; the planner plans again once the robot is found.
            if !blind && !self.follower.is_done() {
                self.follower.set_path(&[], None);
            }
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
            .recv_timeout(wall_until(&self.clock, now, self.next_tick, timeout))
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

#[cfg(test)]
mod tests {
    use super::*;

    use crate::pipeline::{queue, Overflow};

    /// A control stage at the map origin facing +x, a pose fix just in,
    /// following a 3 m lane along +x; its channels lead nowhere.
    fn control_stage(shared: Arc<Shared>) -> ControlStage {
        let robot = crate::robot::RobotParams::default();
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
            backoff: crate::daemon::BUMP_BACKOFF,
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
}
