//! Lock-step emulated bases: the real driver talks its real bytes to a device
//! core in the same thread, with no pty, no thread and a manual clock. Reading
//! from an empty link lets clock time pass (the read timeout), during which
//! the kinematics step and the device streams. Runs are bit-for-bit
//! repeatable: what deterministic tests and a lock-step simulator need.

use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use crate::base_emu::{BaseDevice, BodyState, EmulatorConfig};
use crate::clock::{Clock, ManualClock, SharedClock};
use crate::geom::Pose;
use crate::kinematics::DiffDriveSim;
use crate::motor::link::{ByteLink, LinkOpener};
use crate::motor::{base_driver, DiffDriveBase, WheelSpeeds};

struct State {
    device: Box<dyn BaseDevice>,
    sim: DiffDriveSim,
    cfg: EmulatorConfig,
    clock: Arc<ManualClock>,
    last: f64,
    target: WheelSpeeds,
    to_host: VecDeque<u8>,
    out: Vec<u8>,
}

impl State {
    fn body(&self) -> BodyState {
        BodyState {
            encoder: self.sim.encoder_travel(),
            bumper: self.sim.bumper(),
            wheel_drop: Default::default(),
            wheels: self.sim.wheel_speeds(),
            cliff: [false; 4],
        }
    }

    /// Steps kinematics and device up to the clock's now.
    fn catch_up(&mut self) {
        let now = self.clock.now();
        let step = if self.cfg.step > 0.0 {
            self.cfg.step
        } else {
            0.005
        };
        while self.last + 1e-12 < now {
            let h = step.min(now - self.last);
            self.sim.step(self.target, h, self.cfg.world.as_deref());
            self.last += h;
            let body = self.body();
            self.out.clear();
            self.target = self.device.tick(self.last, &body, &mut self.out);
            self.to_host.extend(self.out.iter().copied());
        }
    }
}

/// The host end of a lock-step link.
struct Port {
    state: Arc<Mutex<State>>,
    read_timeout: f64,
}

fn lock(m: &Mutex<State>) -> MutexGuard<'_, State> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl io::Read for Port {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let mut s = lock(&self.state);
        s.catch_up();
        if s.to_host.is_empty() {
            // Nothing yet: the read waits, and clock time passes meanwhile.
            s.clock.advance(self.read_timeout);
            s.catch_up();
        }
        if s.to_host.is_empty() {
            return Err(io::Error::from(io::ErrorKind::TimedOut));
        }
        let n = buf.len().min(s.to_host.len());
        for (b, v) in buf.iter_mut().zip(s.to_host.drain(..n)) {
            *b = v;
        }
        Ok(n)
    }
}

impl io::Write for Port {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        let mut s = lock(&self.state);
        s.catch_up();
        let now = s.clock.now();
        let body = s.body();
        let mut out = std::mem::take(&mut s.out);
        out.clear();
        // Lock-step: nothing came between the host's last write and this one.
        s.device.line_silent(now);
        s.device.on_bytes(bytes, now, &body, &mut out);
        s.to_host.extend(out.iter().copied());
        s.out = out;
        Ok(bytes.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

struct Opener {
    state: Arc<Mutex<State>>,
}

impl LinkOpener for Opener {
    fn open(&mut self, read_timeout: Duration) -> io::Result<Box<dyn ByteLink>> {
        Ok(Box::new(Port {
            state: self.state.clone(),
            read_timeout: read_timeout.as_secs_f64(),
        }))
    }
    fn describe(&self) -> String {
        "lock-step emulated base".into()
    }
}

/// Ground truth of a lock-step base.
#[derive(Clone)]
pub(crate) struct LoopbackTruth {
    state: Arc<Mutex<State>>,
}

impl LoopbackTruth {
    /// The robot's true pose at the clock's current time.
    pub fn pose(&self) -> Pose {
        let mut s = lock(&self.state);
        s.catch_up();
        s.sim.pose()
    }

    /// The device core's counters (what it accepted and rejected).
    pub(crate) fn device_stats(&self) -> crate::base_emu::DeviceStats {
        lock(&self.state).device.stats()
    }
}

/// The driver `cfg.kind` selects, connected in lock-step to an emulated base
/// described by `cfg`, both timed by `clock`; plus the base's ground truth.
pub(crate) fn loopback_base(
    cfg: EmulatorConfig,
    robot: &sweepline_core::robot::RobotParams,
    clock: Arc<ManualClock>,
) -> (Box<dyn DiffDriveBase>, LoopbackTruth) {
    let state = Arc::new(Mutex::new(State {
        device: cfg.device(),
        sim: DiffDriveSim::new(cfg.kinematics.clone(), cfg.start),
        last: clock.now(),
        cfg: cfg.clone(),
        clock: clock.clone(),
        target: WheelSpeeds::STOP,
        to_host: VecDeque::with_capacity(1024),
        out: Vec::with_capacity(256),
    }));
    let opener = Box::new(Opener {
        state: state.clone(),
    });
    let shared: SharedClock = clock;
    let base = base_driver(cfg.kind, &cfg.motor, robot, opener, shared);
    (base, LoopbackTruth { state })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::geom::{heading, pose};
    use crate::motor::{BaseKind, SafetyEvent};

    fn drive(kind: BaseKind, seed: u64) -> (Vec<Pose>, Pose, Vec<SafetyEvent>) {
        let (odom, pose, events, _) = drive_counted(kind, seed);
        (odom, pose, events)
    }

    /// [`drive`], with the device's counters at the end.
    fn drive_counted(
        kind: BaseKind,
        seed: u64,
    ) -> (
        Vec<Pose>,
        Pose,
        Vec<SafetyEvent>,
        crate::base_emu::DeviceStats,
    ) {
        let cfg = Config::default();
        let mut e = EmulatorConfig::from_config(&cfg, kind);
        e.kinematics.seed = seed;
        e.start = pose(1.0, 2.0, 0.3);
        let clock = Arc::new(ManualClock::default());
        let (mut base, truth) = loopback_base(e, &cfg.robot, clock.clone());
        let mut odom = Vec::new();
        let mut events = Vec::new();
        let mut acc = Pose::identity();
        for i in 0..200 {
            let w = if i < 120 {
                WheelSpeeds {
                    left: 0.15,
                    right: 0.2,
                }
            } else {
                WheelSpeeds::STOP
            };
            let now = clock.now();
            if i < 160 {
                base.set_wheels(w, now).unwrap();
            }
            let fb = base.poll(now).unwrap();
            if let Some(o) = fb.odometry {
                acc *= o.delta;
                odom.push(acc);
            }
            events.extend(fb.events.iter().copied());
            clock.sleep(0.05);
        }
        (odom, truth.pose(), events, truth.device_stats())
    }

    #[test]
    fn the_create2_driver_sends_only_what_the_strict_emulator_takes() {
        let (_, _, _, stats) = drive_counted(BaseKind::Create2, 3);
        assert_eq!(stats.packets_rejected, 0, "{stats:?}");
        assert_eq!(stats.bytes_skipped, 0, "{stats:?}");
        assert!(stats.packets_ok > 100, "{stats:?}");
    }

    #[test]
    fn odometry_stamps_are_continuous_and_not_in_the_future() {
        for kind in [BaseKind::Roboclaw, BaseKind::Create2] {
            let cfg = Config::default();
            let clock = Arc::new(ManualClock::default());
            let e = EmulatorConfig::from_config(&cfg, kind);
            let (mut base, _truth) = loopback_base(e, &cfg.robot, clock.clone());
            let mut prev: Option<f64> = None;
            let mut n = 0;
            let ahead = WheelSpeeds {
                left: 0.1,
                right: 0.1,
            };
            for _ in 0..60 {
                let now = clock.now();
                base.set_wheels(ahead, now).unwrap();
                let fb = base.poll(now).unwrap();
                if let Some(o) = fb.odometry {
                    assert!(o.t1 > o.t0, "{kind:?}: {o:?}");
                    assert!(o.t1 <= clock.now() + 1e-12, "{kind:?}: stamp in the future");
                    if let Some(p) = prev {
                        assert!((o.t0 - p).abs() < 1e-9, "{kind:?}: gap {p} -> {}", o.t0);
                    }
                    prev = Some(o.t1);
                    n += 1;
                }
                clock.sleep(0.05);
            }
            assert!(n > 40, "{kind:?}: {n}");
        }
    }

    #[test]
    fn lock_step_runs_are_repeatable_and_odometry_tracks_truth() {
        for kind in [BaseKind::Roboclaw, BaseKind::Create2] {
            let (o1, t1, ev1) = drive(kind, 5);
            let (o2, t2, _) = drive(kind, 5);
            assert_eq!(o1, o2, "{kind:?}: not repeatable");
            assert_eq!(t1, t2);
            assert!(o1.len() > 100, "{kind:?}: {} odometry updates", o1.len());
            // Truth moved from the start along an arc; odometry (relative to the
            // start) agrees within a few centimetres.
            let start = pose(1.0, 2.0, 0.3);
            let rel = start.inverse() * t1;
            let last = *o1.last().unwrap();
            let e = (rel.translation.vector - last.translation.vector).norm();
            assert!(rel.translation.vector.norm() > 0.5, "{kind:?}: {rel}");
            assert!(e < 0.05, "{kind:?}: odometry {last} vs truth {rel}");
            assert!((heading(&rel) - heading(&last)).abs() < 0.05);
            // The dead-man fired once commands stopped.
            assert!(ev1.contains(&SafetyEvent::DeadMan), "{kind:?}: {ev1:?}");
        }
    }
}
