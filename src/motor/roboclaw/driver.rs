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

    fn send_speeds(&mut self, w: WheelSpeeds) -> Result<(), TxError> {
        let (m1, m2) = self.counts(w);
        let retries = self.retries + 1;
        self.transact(&Command::DriveSpeeds { m1, m2 }, retries)
            .map(|_| ())
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
        if self.initialise().is_ok() {
            self.up = true;
            self.last_ok = self.clock.now();
            if self.ever_up {
                log::info!("wheel base {}: link restored", self.link.describe());
                self.push(SafetyEvent::LinkRestored);
            } else {
                log::info!(
                    "wheel base {}: RoboClaw at address {} answers; serial timeout armed at {:.1} s",
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
            match self.transact(&Command::ReadEncoders, self.retries + 1) {
                Ok(Reply::Encoders { m1, m2 }) => {
                    let (l, r) = if self.m1_is_left { (m1, m2) } else { (m2, m1) };
                    match self.odo.update(l, r, self.clock.now()) {
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
        self.send_speeds(WheelSpeeds::STOP)
            .map_err(|e| MotorError::Io {
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
