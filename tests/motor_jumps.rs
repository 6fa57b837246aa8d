//! The RoboClaw driver's encoder plausibility check, against the emulator's
//! RoboClaw protocol core in lock-step on a manual clock: a reply that comes
//! late (its counters latched long before the host stamps it) carries real
//! travel and is accepted; a reading no wheel could produce in the time the
//! counters may have been apart is rejected, and no travel is lost after it.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use sweepline::clock::ManualClock;
use sweepline::clock::{Clock, SharedClock};
use sweepline::config::Config;
use sweepline::motor::link::{ByteLink, LinkOpener};
use sweepline::motor::odometry::counts_per_metre;
use sweepline::motor::roboclaw::driver::RoboClawDriver;
use sweepline::motor::{DiffDriveBase, Sides, WheelSpeeds};
use sweepline::sim::base_emu::roboclaw::RoboClawDevice;
use sweepline::sim::base_emu::{BaseDevice, BodyState};

/// Command byte of "read both encoders".
const READ_ENCODERS: u8 = 78;
/// Both wheels' speed in the scripted motion (m/s).
const SPEED: f64 = 0.45;

/// What the test scripts into the link.
#[derive(Default)]
struct Script {
    /// The next encoder reply arrives this much clock time late.
    delay_next: Option<f64>,
    /// The next encoder reply reports the wheels this far off (m): a value
    /// that passes the CRC but no wheel produced.
    corrupt_next: Option<f64>,
}

/// A RoboClaw whose wheels both travel at [`SPEED`] since clock time 0.
struct ScriptedLink {
    device: RoboClawDevice,
    clock: Arc<ManualClock>,
    script: Arc<Mutex<Script>>,
    to_host: VecDeque<u8>,
    /// Clock time the pending reply may be read from.
    ready_at: f64,
}

impl Read for ScriptedLink {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.to_host.is_empty() {
            self.clock.advance(0.001);
            return Err(io::ErrorKind::WouldBlock.into());
        }
        let now = self.clock.now();
        if now < self.ready_at {
            // The reply is on its way: the read waits for it.
            self.clock.advance(self.ready_at - now);
        }
        let n = buf.len().min(self.to_host.len());
        for b in buf.iter_mut().take(n) {
            *b = self.to_host.pop_front().unwrap_or_default();
        }
        Ok(n)
    }
}

impl Write for ScriptedLink {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        let now = self.clock.now();
        let mut script = self.script.lock().unwrap();
        let encoders = bytes.get(1) == Some(&READ_ENCODERS);
        let off = if encoders {
            script.corrupt_next.take().unwrap_or(0.0)
        } else {
            0.0
        };
        let body = BodyState {
            encoder: (SPEED * now + off, SPEED * now),
            bumper: Sides::default(),
            wheel_drop: Sides::default(),
            ..BodyState::default()
        };
        let mut out = Vec::new();
        self.device.on_bytes(bytes, now, &body, &mut out);
        self.ready_at = now
            + if encoders {
                script.delay_next.take().unwrap_or(0.0)
            } else {
                0.0
            };
        self.to_host.extend(out);
        Ok(bytes.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

struct Opener(Option<ScriptedLink>);

impl LinkOpener for Opener {
    fn open(&mut self, _read_timeout: Duration) -> io::Result<Box<dyn ByteLink>> {
        self.0
            .take()
            .map(|l| Box::new(l) as Box<dyn ByteLink>)
            .ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, "opened once"))
    }
    fn describe(&self) -> String {
        "scripted RoboClaw".into()
    }
}

struct Rig {
    clock: Arc<ManualClock>,
    script: Arc<Mutex<Script>>,
    driver: RoboClawDriver,
    /// Left and right travel summed over the driver's increments (m).
    travel: (f64, f64),
}

impl Rig {
    fn new() -> Self {
        let cfg = Config::default();
        let clock = Arc::new(ManualClock::default());
        let script = Arc::new(Mutex::new(Script::default()));
        let cpm = counts_per_metre(cfg.motor.roboclaw.counts_per_rev, cfg.robot.wheel_radius);
        let link = ScriptedLink {
            device: RoboClawDevice::new(
                cfg.motor.roboclaw.address,
                cpm,
                cfg.motor.roboclaw.m1_is_left,
            ),
            clock: clock.clone(),
            script: script.clone(),
            to_host: VecDeque::new(),
            ready_at: 0.0,
        };
        let shared: SharedClock = clock.clone();
        let driver =
            RoboClawDriver::new(&cfg.motor, &cfg.robot, Box::new(Opener(Some(link))), shared);
        Self {
            clock,
            script,
            driver,
            travel: (0.0, 0.0),
        }
    }

    /// One 20 ms control period: a command, a poll.
    fn period(&mut self) {
        self.clock.advance(0.02);
        let now = self.clock.now();
        let _ = self
            .driver
            .set_wheels(WheelSpeeds::from_body(SPEED, 0.0, 0.235), now);
        let fb = self.driver.poll(now).expect("poll");
        if let Some(o) = fb.odometry {
            self.travel.0 += o.left;
            self.travel.1 += o.right;
        }
    }
}

#[test]
fn a_late_reply_carrying_real_travel_is_accepted() {
    let mut rig = Rig::new();
    for _ in 0..20 {
        rig.period();
    }
    assert!(rig.driver.link_up());
    let before = rig.travel;
    let t0 = rig.clock.now();
    // The host stalls on one encoder reply for 0.3 s: the counters were
    // latched when the request went out, the reading is stamped near its
    // end; the next reading, moments later by the stamps, shows the 0.135 m
    // the wheels really covered meanwhile.
    rig.script.lock().unwrap().delay_next = Some(0.3);
    for _ in 0..20 {
        rig.period();
    }
    let h = rig.driver.health();
    assert_eq!(h.odometry_glitches, 0, "{h:?}");
    // Every metre the wheels turned is in the odometry (counter rounding
    // aside), the stalled stretch included.
    let moved = SPEED * (rig.clock.now() - t0);
    let got = rig.travel.0 - before.0;
    assert!(
        (got - moved).abs() < 0.02,
        "moved {moved:.3} m, odometry {got:.3} m"
    );
}

#[test]
fn a_corrupt_reading_is_rejected_and_no_travel_is_lost() {
    let mut rig = Rig::new();
    for _ in 0..20 {
        rig.period();
    }
    let (t_first, l_first) = (rig.clock.now(), rig.travel.0);
    // A left counter 3 m off, promptly answered: impossible in 20 ms.
    rig.script.lock().unwrap().corrupt_next = Some(3.0);
    for _ in 0..20 {
        rig.period();
    }
    let h = rig.driver.health();
    assert_eq!(h.odometry_glitches, 1, "{h:?}");
    assert_eq!(h.odometry_rebases, 0, "{h:?}");
    // The reading after the corrupt one carried the travel since the last
    // good one: the odometry matches the wheels exactly.
    let moved = SPEED * (rig.clock.now() - t_first);
    let got = rig.travel.0 - l_first;
    assert!(
        (got - moved).abs() < 0.005,
        "moved {moved:.4} m, odometry {got:.4} m"
    );
    assert!(
        (rig.travel.0 - rig.travel.1).abs() < 0.005,
        "{:?}",
        rig.travel
    );
}
