//! The RoboClaw driver: owns the port, runs the [`codec`](super::codec),
//! enforces the dead-man and the bumper gate, and detects and recovers a
//! silent, garbled or vanished link.
//!
//! Every poll sends the current (possibly overridden) velocity set-point,
//! reads both encoders in one packet (78) and the status word (90, whose E-Stop
//! bit carries the bumper switch). On connect it arms the controller's own
//! serial timeout (14), so the wheels stop without help if the daemon dies.

use std::time::Duration;

use crate::clock::SharedClock;
use crate::config::RobotParams;
use crate::motor::link::{Link, LinkOpener, ReadOutcome};
use crate::motor::odometry::{CounterWidth, Odometer};
use crate::motor::params::MotorParams;
use crate::motor::roboclaw::codec::{
    encode_command, Command, Reply, ReplyDecoder, ReplyError, STATUS_ESTOP,
};
use crate::motor::safety::{DeadMan, SafetyGate};
use crate::motor::{
    BaseFeedback, DiffDriveBase, LinkHealth, MotorError, Odometry, SafetyEvent, Sides, WheelSpeeds,
};

/// Polls between two main-battery readings.
const BATTERY_EVERY: u64 = 20;

/// Why one request failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum TxError {
    /// No (complete) reply in time.
    Timeout,
    /// The reply was invalid.
    Bad(ReplyError),
    /// The port is closed.
    Closed,
}

/// A RoboClaw driven over packet serial.
pub struct RoboClawDriver {
    link: Link,
    clock: SharedClock,
    address: u8,
    timeout_tenths: u8,
    retries: u32,
    m1_is_left: bool,
    counts_per_metre: f64,
    max_wheel_speed: f64,
    reply_timeout: f64,
    link_timeout: f64,
    probe_interval: f64,
    odo: Odometer,
    deadman: DeadMan,
    deadman_time: f64,
    gate: SafetyGate,
    health: LinkHealth,
    requested: WheelSpeeds,
    up: bool,
    ever_up: bool,
    last_ok: f64,
    fail_streak: u32,
    silent_warned: bool,
    battery: Option<f64>,
    polls: u64,
    accel_counts: u32,
    stopping: bool,
    next_probe: f64,
    pending: heapless::Vec<SafetyEvent, 8>,
}

impl RoboClawDriver {
    /// A driver for the base described by `p` and `robot`, opening its port
    /// through `opener`, timed by `clock`. Nothing is opened until the first
    /// [`DiffDriveBase::poll`].
    pub fn new(
        p: &MotorParams,
        robot: &RobotParams,
        opener: Box<dyn LinkOpener>,
        clock: SharedClock,
    ) -> Self {
        let read_timeout = clock
            .to_wall(p.roboclaw.reply_timeout)
            .max(Duration::from_millis(10));
        let counts_per_metre =
            p.roboclaw.counts_per_rev / (2.0 * std::f64::consts::PI * robot.wheel_radius);
        Self {
            link: Link::new(opener, read_timeout, p.reconnect_interval),
            clock,
            address: p.roboclaw.address,
            timeout_tenths: p.roboclaw_timeout_tenths(),
            retries: p.roboclaw.retries,
            m1_is_left: p.roboclaw.m1_is_left,
            counts_per_metre,
            max_wheel_speed: p.max_wheel_speed,
            reply_timeout: p.roboclaw.reply_timeout,
            link_timeout: p.link_timeout,
            probe_interval: p.reconnect_interval,
            odo: Odometer::new(
                CounterWidth::Bits32,
                counts_per_metre,
                robot.wheel_base,
                p.max_wheel_speed,
            ),
            deadman: DeadMan::new(p.deadman),
            deadman_time: p.deadman,
            gate: SafetyGate::new(),
            health: LinkHealth::default(),
            requested: WheelSpeeds::STOP,
            up: false,
            ever_up: false,
            last_ok: 0.0,
            fail_streak: 0,
            silent_warned: false,
            battery: None,
            polls: 0,
            accel_counts: (p.roboclaw.accel * counts_per_metre)
                .round()
                .clamp(0.0, u32::MAX as f64) as u32,
            stopping: false,
            next_probe: f64::NEG_INFINITY,
            pending: heapless::Vec::new(),
        }
    }

    /// Whether the controller currently answers.
    pub fn link_up(&self) -> bool {
        self.up
    }

    /// One request/reply exchange, with retries.
    fn transact(&mut self, cmd: &Command, attempts: u32) -> Result<Reply, TxError> {
        let packet = encode_command(self.address, cmd);
        let mut last = TxError::Timeout;
        for attempt in 0..attempts.max(1) {
            if attempt > 0 {
                // Stale bytes of a garbled reply must not prefix the next one.
                self.health.discarded_bytes += self.link.drain();
            }
            if self.link.write_all(&packet).is_err() {
                return Err(TxError::Closed);
            }
            self.health.sent += 1;
            match self.read_reply(cmd) {
                Ok(r) => {
                    self.health.received += 1;
                    self.last_ok = self.clock.now();
                    self.fail_streak = 0;
                    return Ok(r);
                }
                Err(TxError::Closed) => return Err(TxError::Closed),
                Err(e) => {
                    match e {
                        TxError::Timeout => self.health.timeouts += 1,
                        TxError::Bad(ReplyError::NotAck(_)) => self.health.nacks += 1,
                        TxError::Bad(_) => self.health.checksum_errors += 1,
                        TxError::Closed => {}
                    }
                    last = e;
                }
            }
        }
        self.fail_streak += 1;
        Err(last)
    }

    fn read_reply(&mut self, cmd: &Command) -> Result<Reply, TxError> {
        let mut dec = ReplyDecoder::new(self.address, cmd);
        let mut buf = [0u8; 64];
        loop {
            match self.link.read(&mut buf) {
                ReadOutcome::Gone => return Err(TxError::Closed),
                ReadOutcome::Timeout => return Err(TxError::Timeout),
                ReadOutcome::Data(n) => {
                    for (i, &b) in buf[..n].iter().enumerate() {
                        match dec.push(b) {
                            Ok(None) => {}
                            Ok(Some(r)) => {
                                self.health.discarded_bytes += (n - i - 1) as u64;
                                return Ok(r);
                            }
                            Err(e) => {
                                self.health.discarded_bytes += (n - i - 1) as u64;
                                return Err(TxError::Bad(e));
                            }
                        }
                    }
                }
            }
        }
    }

    /// Set-points in counts/s for (M1, M2).
    fn counts(&self, w: WheelSpeeds) -> (i32, i32) {
        let c = |v: f64| (v * self.counts_per_metre).round() as i32;
        if self.m1_is_left {
            (c(w.left), c(w.right))
        } else {
            (c(w.right), c(w.left))
        }
    }

    /// The set-point that may be sent now.
    fn effective(&self) -> WheelSpeeds {
        if self.deadman.tripped() {
            WheelSpeeds::STOP
        } else {
            self.gate.filter(self.requested)
        }
    }

    /// Sends set-points: ramped at the configured acceleration (command 40)
    /// in normal driving; at once (command 37, the PID's full authority) for
    /// safety stops and when no acceleration is configured.
    fn send_speeds(&mut self, w: WheelSpeeds) -> Result<(), TxError> {
        let (m1, m2) = self.counts(w);
        let retries = self.retries + 1;
        let urgent = self.deadman.tripped() || self.gate.active() || self.stopping;
        let cmd = if self.accel_counts > 0 && !urgent {
            Command::DriveSpeedsAccel {
                accel: self.accel_counts,
                m1,
                m2,
            }
        } else {
            Command::DriveSpeeds { m1, m2 }
        };
        self.transact(&cmd, retries).map(|_| ())
    }

    /// Arms the controller timeout and takes an encoder baseline.
    fn initialise(&mut self) -> Result<(), TxError> {
        let tenths = self.timeout_tenths;
        self.transact(&Command::SetSerialTimeout { tenths }, 2)?;
        self.send_speeds(self.effective())?;
        self.odo.rebase();
        Ok(())
    }

    fn push(&mut self, e: SafetyEvent) {
        let _ = self.pending.push(e);
    }

    fn declare_lost(&mut self, why: &str) {
        if !self.up {
            return;
        }
        self.up = false;
        self.health.link_losses += 1;
        log::warn!(
            "wheel base {}: link lost ({why}); wheels commanded to stop, the controller's own {:.1} s timeout backs that up",
            self.link.describe(),
            self.timeout_tenths as f64 / 10.0
        );
        // Best effort: if the link is only garbled, a stop may still get through.
        let _ = self.transact(&Command::DriveSpeeds { m1: 0, m2: 0 }, 1);
        self.push(SafetyEvent::LinkLost);
    }

    /// Tries to bring the link (back) up.
    fn try_restore(&mut self, now: f64) {
        if !self.link.is_open() {
            if !self.link.ensure_open(now) {
                return;
            }
            self.health.reconnects += 1;
        } else if now < self.next_probe {
            return;
        }
        self.next_probe = now + self.probe_interval;
        self.health.discarded_bytes += self.link.drain();
        let ok = self.initialise().is_ok();
        if !ok && !self.silent_warned {
            self.silent_warned = true;
            log::warn!(
                "wheel base {}: no valid answer from a RoboClaw at address {} (check the address, the baud rate and that packet serial mode is set); retrying every {:.1} s",
                self.link.describe(),
                self.address,
                self.probe_interval
            );
        }
        if ok {
            self.silent_warned = false;
            self.up = true;
            self.last_ok = self.clock.now();
            if self.ever_up {
                log::info!("wheel base {}: link restored", self.link.describe());
                self.push(SafetyEvent::LinkRestored);
            } else {
                let version = match self.transact(&Command::ReadVersion, 2) {
                    Ok(Reply::Version(v)) => String::from_utf8_lossy(&v).into_owned(),
                    _ => "version unknown".into(),
                };
                log::info!(
                    "wheel base {}: RoboClaw at address {} answers ({version}); serial timeout armed at {:.1} s",
                    self.link.describe(),
                    self.address,
                    self.timeout_tenths as f64 / 10.0
                );
            }
            self.ever_up = true;
        }
    }

    fn apply_bumper(&mut self, s: Sides) {
        if let Some(e) = self.gate.set_bumper(s) {
            if matches!(e, SafetyEvent::Bumper(_)) {
                self.health.safety_stops += 1;
                log::warn!("wheel base: bumper closed ({s:?}); wheels stopped");
                let w = self.effective();
                let _ = self.send_speeds(w);
            }
            self.push(e);
        }
    }
}

impl DiffDriveBase for RoboClawDriver {
    fn set_wheels(&mut self, cmd: WheelSpeeds) -> Result<(), MotorError> {
        if !cmd.is_finite() {
            return Err(MotorError::BadCommand {
                left: cmd.left,
                right: cmd.right,
            });
        }
        let m = self.max_wheel_speed;
        self.requested = WheelSpeeds {
            left: cmd.left.clamp(-m, m),
            right: cmd.right.clamp(-m, m),
        };
        self.deadman.feed(self.clock.now());
        if self.up {
            let w = self.effective();
            if self.send_speeds(w) == Err(TxError::Closed) {
                self.declare_lost("device went away");
            }
        }
        Ok(())
    }

    fn poll(&mut self) -> Result<BaseFeedback, MotorError> {
        let now = self.clock.now();
        if self.deadman.check(now) {
            self.health.deadman_stops += 1;
            log::warn!(
                "wheel base: no wheel command for more than the dead-man time; wheels stopped"
            );
            self.push(SafetyEvent::DeadMan);
        }
        let mut odometry: Option<Odometry> = None;
        if !self.up {
            self.try_restore(now);
        }
        if self.up {
            let w = self.effective();
            let mut closed = self.send_speeds(w) == Err(TxError::Closed);
            let asked = self.clock.now();
            match self.transact(&Command::ReadEncoders, self.retries + 1) {
                Ok(Reply::Encoders { m1, m2 }) => {
                    let (l, r) = if self.m1_is_left { (m1, m2) } else { (m2, m1) };
                    // The counters were latched somewhere between request and
                    // reply: stamp the reading with the midpoint. (A retried
                    // request widens the window; the last attempt is what
                    // counts, so use the reply time minus half the last RTT.)
                    let answered = self.clock.now();
                    let stamp = answered - 0.5 * (answered - asked).min(self.reply_timeout);
                    match self.odo.update(l, r, stamp) {
                        Ok(o) => odometry = o,
                        Err(g) => {
                            self.health.odometry_glitches += 1;
                            log::warn!("wheel base: {g}");
                        }
                    }
                }
                Ok(_) => {}
                Err(e) => closed |= e == TxError::Closed,
            }
            match self.transact(&Command::ReadStatus, self.retries + 1) {
                Ok(Reply::Status(s)) => {
                    let pressed = s & STATUS_ESTOP != 0;
                    self.apply_bumper(Sides {
                        left: pressed,
                        right: pressed,
                    });
                }
                Ok(_) => {}
                Err(e) => closed |= e == TxError::Closed,
            }
            // The battery changes slowly: once every BATTERY_EVERY polls.
            if self.polls.is_multiple_of(BATTERY_EVERY) {
                match self.transact(&Command::ReadMainBattery, 1) {
                    Ok(Reply::MainBattery(dv)) => self.battery = Some(dv as f64 / 10.0),
                    Ok(_) => {}
                    Err(e) => closed |= e == TxError::Closed,
                }
            }
            self.polls += 1;
            if closed {
                self.declare_lost("device went away");
            } else if self.fail_streak >= 2 && self.clock.now() - self.last_ok > self.link_timeout {
                // Both conditions: a slow poll under a time-scaled clock is not
                // a dead link; two failed requests in a row past the timeout are.
                self.declare_lost("no valid reply");
            }
        }
        let mut fb = BaseFeedback {
            odometry,
            events: heapless::Vec::new(),
            link_up: self.up,
            battery: self.battery,
        };
        for e in self.pending.iter() {
            fb.push_event(*e);
        }
        self.pending.clear();
        Ok(fb)
    }

    fn stop(&mut self) -> Result<(), MotorError> {
        self.requested = WheelSpeeds::STOP;
        self.deadman = DeadMan::new(self.deadman_time);
        if !self.link.is_open() {
            return Err(MotorError::NotConnected {
                device: self.link.describe(),
            });
        }
        self.stopping = true;
        let r = self.send_speeds(WheelSpeeds::STOP);
        self.stopping = false;
        r.map_err(|e| MotorError::Io {
            device: self.link.describe(),
            source: std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!("stop command not acknowledged ({e:?})"),
            ),
        })
    }

    fn health(&self) -> LinkHealth {
        self.health
    }
}

impl Drop for RoboClawDriver {
    /// Leaves the wheels stopped: a zero set-point is written (without waiting
    /// for the ACK); the controller's serial timeout is the backstop.
    fn drop(&mut self) {
        if self.link.is_open() {
            let p = encode_command(self.address, &Command::DriveSpeeds { m1: 0, m2: 0 });
            let _ = self.link.write_all(&p);
        }
    }
}
