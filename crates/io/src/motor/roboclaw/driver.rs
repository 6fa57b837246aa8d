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
use crate::motor::command::WheelCommand;
use crate::motor::link::{Link, LinkOpener, ReadOutcome};
use crate::motor::odometry::{counts_per_metre, Accepted, CounterWidth, Odometer, DEFAULT_LATENCY};
use crate::motor::params::MotorParams;
use crate::motor::roboclaw::codec::{
    encode_command, Command, Query, Reply, ReplyDecoder, ReplyError, STATUS_ESTOP,
};
use crate::motor::{
    BaseFeedback, DiffDriveBase, LinkHealth, MotorError, Odometry, SafetyEvent, Sides, WheelSpeeds,
};
use crate::robot::RobotParams;

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
///
/// Time comes in as `now` with every [`DiffDriveBase`] call: the dead-man,
/// the link timeout (measured from the `now` of the last call a reply came
/// in) and the probe interval decide on it. The driver keeps its clock for
/// two things only: turning the reply timeout into the wall-clock wait of
/// the blocking serial read (once, when built), and timing the encoder
/// read's round trip, whose midpoint stamps the odometry. That stamp is a
/// measurement: the counters are latched while the read blocks, after the
/// caller's `now`, by a time no caller can know (the set-point's exchange
/// and any retries come first); stamping with `now` would date every
/// reading early by that much.
pub struct RoboClawDriver {
    link: Link,
    clock: SharedClock,
    address: u8,
    timeout_tenths: u8,
    retries: u32,
    m1_is_left: bool,
    counts_per_metre: f64,
    reply_timeout: f64,
    link_timeout: f64,
    probe_interval: f64,
    odo: Odometer,
    cmd: WheelCommand,
    health: LinkHealth,
    up: bool,
    ever_up: bool,
    /// The `now` of the last call in which a reply came in.
    last_ok: f64,
    fail_streak: u32,
    silent_warned: bool,
    battery: Option<f64>,
    polls: u64,
    accel_counts: u32,
    stopping: bool,
    next_probe: f64,
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
        let counts_per_metre = counts_per_metre(p.roboclaw.counts_per_rev, robot.wheel_radius);
        Self {
            link: Link::new(opener, read_timeout, p.reconnect_interval),
            clock,
            address: p.roboclaw.address,
            timeout_tenths: p.roboclaw_timeout_tenths(),
            retries: p.roboclaw.retries,
            m1_is_left: p.roboclaw.m1_is_left,
            counts_per_metre,
            reply_timeout: p.roboclaw.reply_timeout,
            link_timeout: p.link_timeout,
            probe_interval: p.reconnect_interval,
            odo: Odometer::new(
                CounterWidth::Bits32,
                counts_per_metre,
                robot.wheel_base,
                p.max_wheel_speed,
            )
            // The counters are latched somewhere within a request's
            // round trip, which the odometer is told; plus one reply
            // timeout of slack for the controller's own latching.
            .with_latency(DEFAULT_LATENCY + p.roboclaw.reply_timeout),
            cmd: WheelCommand::new(p.max_wheel_speed, p.deadman),
            health: LinkHealth::default(),
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

    /// Sends set-points: ramped at the configured acceleration (command 40)
    /// in normal driving; at once (command 37, the PID's full authority) for
    /// safety stops and when no acceleration is configured.
    fn send_speeds(&mut self, w: WheelSpeeds) -> Result<(), TxError> {
        let (m1, m2) = self.counts(w);
        let retries = self.retries + 1;
        let urgent = self.cmd.deadman.tripped() || self.cmd.gate.active() || self.stopping;
        let cmd = if self.accel_counts > 0 && !urgent {
            Command::speeds_accel(self.accel_counts, m1, m2)
        } else {
            Command::speeds(m1, m2)
        };
        self.transact(&cmd, retries).map(|_| ())
    }

    /// Arms the controller timeout and takes an encoder baseline.
    fn initialise(&mut self) -> Result<(), TxError> {
        let tenths = self.timeout_tenths;
        self.transact(&Command::SetSerialTimeout { tenths }, 2)?;
        self.send_speeds(self.cmd.effective())?;
        self.odo.rebase();
        Ok(())
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
        let _ = self.transact(&Command::speeds(0, 0), 1);
        self.cmd.push(SafetyEvent::LinkLost);
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
            self.last_ok = now;
            if self.ever_up {
                log::info!("wheel base {}: link restored", self.link.describe());
                self.cmd.push(SafetyEvent::LinkRestored);
            } else {
                let version = match self.transact(&Command::Query(Query::Version), 2) {
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

    /// The poll's reads: both encoders (odometry), the status word (the
    /// bumper) and, every [`BATTERY_EVERY`] polls, the battery. Returns
    /// whether the port closed, and the odometry if a reading was taken.
    fn read_state(&mut self) -> (bool, Option<Odometry>) {
        let mut closed = false;
        let mut odometry: Option<Odometry> = None;
        let asked = self.clock.now();
        match self.transact(&Command::Query(Query::Encoders), self.retries + 1) {
            Ok(Reply::Pair32(m1, m2)) => {
                let (l, r) = if self.m1_is_left { (m1, m2) } else { (m2, m1) };
                // The counters were latched somewhere between request and
                // reply: stamp the reading with the midpoint. (A retried
                // request widens the window; the last attempt is what
                // counts, so use the reply time minus half the last RTT.)
                let answered = self.clock.now();
                let stamp = answered - 0.5 * (answered - asked).min(self.reply_timeout);
                match self.odo.update_within(l, r, stamp, (asked, answered)) {
                    Ok(Accepted::Rebased(o)) => {
                        self.health.odometry_rebases += 1;
                        log::warn!(
                            "wheel base: encoder counters continue from the jump rejected before (reset by the controller?); odometry re-based there, the jump itself not counted as travel"
                        );
                        odometry = Some(o);
                    }
                    Ok(a) => odometry = a.odometry(),
                    Err(g) => {
                        self.health.odometry_glitches += 1;
                        log::warn!("wheel base: {g}");
                    }
                }
            }
            Ok(_) => {}
            Err(e) => closed |= e == TxError::Closed,
        }
        match self.transact(&Command::Query(Query::Status), self.retries + 1) {
            Ok(Reply::U32(s)) => {
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
            match self.transact(&Command::Query(Query::MainBattery), 1) {
                Ok(Reply::U16(dv)) => self.battery = Some(dv as f64 / 10.0),
                Ok(_) => {}
                Err(e) => closed |= e == TxError::Closed,
            }
        }
        (closed, odometry)
    }

    /// Notes `now` as the time of the last reply when one came in since the
    /// link's reply count read `received`.
    fn note_replies(&mut self, received: u64, now: f64) {
        if self.health.received > received {
            self.last_ok = now;
        }
    }

    fn apply_bumper(&mut self, s: Sides) {
        if self.cmd.set_bumper(s, &mut self.health) {
            let w = self.cmd.effective();
            let _ = self.send_speeds(w);
        }
    }
}

impl DiffDriveBase for RoboClawDriver {
    fn set_wheels(&mut self, cmd: WheelSpeeds, now: f64) -> Result<(), MotorError> {
        self.cmd.accept(cmd, now)?;
        if self.up {
            let w = self.cmd.effective();
            let received = self.health.received;
            let sent = self.send_speeds(w);
            self.note_replies(received, now);
            if sent == Err(TxError::Closed) {
                self.declare_lost("device went away");
            }
        }
        Ok(())
    }

    fn poll(&mut self, now: f64) -> Result<BaseFeedback, MotorError> {
        self.cmd.check_deadman(now, &mut self.health);
        let mut odometry: Option<Odometry> = None;
        if !self.up {
            self.try_restore(now);
        }
        if self.up {
            let received = self.health.received;
            let w = self.cmd.effective();
            let sent = self.send_speeds(w);
            let mut closed = sent == Err(TxError::Closed);
            // A set-point unanswered through all its retries means a silent
            // link: the reads would only wait out their own timeouts and
            // put off noticing it by a whole poll.
            if sent != Err(TxError::Timeout) {
                let (c, o) = self.read_state();
                closed |= c;
                odometry = o;
            }
            self.polls += 1;
            self.note_replies(received, now);
            if closed {
                self.declare_lost("device went away");
            } else if self.fail_streak >= 2 && now - self.last_ok > self.link_timeout {
                // Both conditions: a slow poll under a time-scaled clock is not
                // a dead link; two failed requests in a row past the timeout are.
                self.declare_lost("no valid reply");
            }
        }
        Ok(self.cmd.feedback(odometry, self.up, self.battery))
    }

    fn stop(&mut self) -> Result<(), MotorError> {
        self.cmd.halt();
        self.link.require_open()?;
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
            let p = encode_command(self.address, &Command::speeds(0, 0));
            let _ = self.link.write_all(&p);
        }
    }
}
