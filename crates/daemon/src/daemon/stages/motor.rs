//! The motor stage: the wheel-base driver, odometry and safety events.
//!
//! The stage's thread owns the clock: `wait` and `process` each read it
//! once and pass that `now` to the driver and to what decides by time.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Point2;

use super::wall_until;
use crate::clock::SharedClock;
use crate::daemon::contact::{
    mapped_touch, turn_in_place, BodyTrack, ContactMark, ContactParams, HeldContact, Known,
    MotionMemory,
};
use crate::daemon::messages::{CmdMsg, MapMsg};
use crate::daemon::shared::Shared;
use crate::geom::{heading, Pose};
use crate::motor::{DiffDriveBase, SafetyEvent, Sides, WheelSpeeds};
use crate::pipeline::{Poll, Recv, Rx, Stage, StageCtx, StageFault, Tx};

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
    pub(crate) to_map: Tx<MapMsg>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// The injected clock.
    pub clock: SharedClock,
    /// Encoder polling period (clock s).
    pub period: f64,
    /// Clock time of the next poll.
    pub(crate) next_poll: f64,
    /// Robot radius (m): where a bumper contact is.
    pub radius: f64,
    /// Wheel base (m).
    pub wheel_base: f64,
    /// The last wheel speeds commanded.
    pub(crate) last_wheels: WheelSpeeds,
    /// The wheels' measured motion: what a contact interrupted.
    pub motion: MotionMemory,
    /// Where the body has been (rules out contact bearings).
    pub track: BodyTrack,
    /// Where contact marks go.
    pub contact: ContactParams,
    /// A contact closed before the pose was known.
    pub held: HeldContact,
    /// A copy of every odometry reading (none: no tap).
    pub(crate) tap: Option<Tx<crate::motor::Odometry>>,
}

impl MotorStage {
    /// Marks a contact closed on `sides` (`None`: the bumper cannot tell)
    /// with the robot at `at` commanded to `wheels`: to the map first, so
    /// the snapshot that makes the planner plan again already holds it.
    fn mark(&mut self, what: &str, at: &Pose, sides: Option<Sides>, wheels: WheelSpeeds) {
        let (known, grid) = self
            .shared
            .with_status(|s| (s.map.contacts.clone(), s.map.grid.clone()));
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

    /// Polls the base at clock time `now` (s): odometry into the shared log,
    /// safety events into contact marks.
    fn poll(&mut self, now: f64) -> Result<(), StageFault> {
        let fb = self.base.poll(now);
        self.shared.set_base_health(self.base.health());
        let fb = fb.map_err(|e| StageFault::Transient(e.to_string()))?;
        if let Some(o) = fb.odometry {
            self.shared.odom.push(o.t1, &o.delta);
            if let Some(tap) = &self.tap {
                let _ = tap.send(o);
            }
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
                    let wheels = self.motion.interrupted(now, self.last_wheels);
                    match self.held.closed(localised, sides, wheels) {
                        Some((sides, wheels)) => self.mark(&format!("{e:?}"), &here, sides, wheels),
                        None => log::warn!(
                            "safety: {e:?} before the first matched scan: the contact is marked once the pose is known"
                        ),
                    }
                    self.shared.note_bump(now);
                    self.shared.safety_events.fetch_add(1, Ordering::Relaxed);
                }
                SafetyEvent::BumperReleased => {
                    self.shared.bumper_closed.store(false, Ordering::Relaxed);
                }
                SafetyEvent::DeadMan | SafetyEvent::LinkLost => {
                    self.shared.safety_events.fetch_add(1, Ordering::Relaxed);
                    log::warn!("wheel base: {e}");
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
        let now = self.clock.now();
        if now >= self.next_poll {
            self.next_poll = (self.next_poll + self.period).max(now);
            return Poll::Work(MotorWork::Poll);
        }
        match self
            .rx
            .recv_timeout(wall_until(&self.clock, now, self.next_poll, timeout))
        {
            Recv::Msg(c) => Poll::Work(MotorWork::Cmd(c)),
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }

    fn process(&mut self, work: MotorWork, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        let now = self.clock.now();
        match work {
            MotorWork::Cmd(c) => {
                let wheels = if self.shared.halt.load(Ordering::Relaxed) {
                    WheelSpeeds::STOP
                } else {
                    c.wheels
                };
                self.last_wheels = wheels;
                let r = self.base.set_wheels(wheels, now);
                if let Some(t0) = c.t0 {
                    ctx.end_to_end(t0);
                }
                r.map_err(|e| StageFault::Transient(e.to_string()))
            }
            MotorWork::Poll => self.poll(now),
        }
    }

    fn on_stop(&mut self) {
        if let Err(e) = self.base.stop() {
            log::warn!("could not stop the wheels on shutdown: {e}");
        }
        self.shared.set_base_health(self.base.health());
    }
}
