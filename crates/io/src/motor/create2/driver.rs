//! The Create 2 driver: owns the port, starts the OI in Safe (or Full) mode,
//! asks for a sensor stream of bumps/wheel drops (7), OI mode (35) and both
//! encoders (43, 44), turns it into odometry and safety events, and drives with
//! Drive Direct.
//!
//! Drive commands go out only while the robot may take them: the OI
//! specification allows them in Safe and Full mode only, and the stream
//! reports the mode (after a wheel drop Safe mode falls back to Passive).
//!
//! The Create 2 has no command timeout: it keeps driving on the last command
//! if the host dies. The host-side dead-man is therefore the only guard, and a
//! stream that stops arriving is treated as a lost link: a zero Drive Direct
//! is sent at once and the OI is re-initialised until frames come back.

use std::time::Duration;

use crate::clock::SharedClock;
use crate::motor::command::WheelCommand;
use crate::motor::create2::codec::{
    self, encode, pkt, OiCommand, OiMode, SensorFrame, StreamParser,
};
use crate::motor::link::{Link, LinkOpener, ReadOutcome};
use crate::motor::odometry::{counts_per_metre, CounterWidth, Odometer};
use crate::motor::params::MotorParams;
use crate::motor::{
    BaseFeedback, DiffDriveBase, LinkHealth, MotorError, Odometry, SafetyEvent, Sides, WheelSpeeds,
};
use crate::robot::RobotParams;

/// The Create 2 sends a stream frame every 15 ms.
pub const STREAM_PERIOD: f64 = 0.015;

/// The packets the driver streams.
pub(crate) const STREAM_IDS: [u8; 5] = [
    pkt::BUMPS_WHEEL_DROPS,
    pkt::OI_MODE,
    pkt::LEFT_ENCODER,
    pkt::RIGHT_ENCODER,
    pkt::VOLTAGE,
];

/// A Create 2 (or Roomba 600-series) over its Open Interface.
///
/// Time comes in as `now` with every call: the dead-man, the link timeout
/// (no frame since `link_timeout` before `now`), the probe interval and
/// reconnecting decide on it. The driver keeps its clock for two things
/// only: turning its short read timeout into the wall-clock wait of the
/// blocking serial read (once, when built), and stamping each sensor frame
/// when its bytes arrive. Those stamps are measurements: a poll reads for
/// as long as bytes keep coming, after the caller's `now`, and a frame's
/// odometry belongs to when it came, not to when the poll began.
pub struct Create2Driver {
    link: Link,
    clock: SharedClock,
    mode: OiMode,
    /// The mode the robot last reported (`None` until a frame says, or
    /// after the driver itself changed it).
    reported: Option<OiMode>,
    link_timeout: f64,
    probe_interval: f64,
    parser: StreamParser,
    odo: Odometer,
    cmd: WheelCommand,
    health: LinkHealth,
    up: bool,
    ever_up: bool,
    /// When the newest frame arrived (or the link was (re)started).
    last_frame: f64,
    next_probe: f64,
    mode_warned: bool,
    paused: bool,
    battery: Option<f64>,
    silent_warned: bool,
    acc: Option<Odometry>,
}

impl Create2Driver {
    /// A driver for the base described by `p` and `robot`, opening its port
    /// through `opener`, timed by `clock`. Nothing is opened until the first
    /// [`DiffDriveBase::poll`].
    pub fn new(
        p: &MotorParams,
        robot: &RobotParams,
        opener: Box<dyn LinkOpener>,
        clock: SharedClock,
    ) -> Self {
        let read_timeout = clock.to_wall(0.01).max(Duration::from_millis(5));
        let counts_per_metre = counts_per_metre(p.create2.counts_per_rev, robot.wheel_radius);
        let payload = StreamParser::payload_len(&STREAM_IDS).unwrap_or(0);
        Self {
            link: Link::new(opener, read_timeout, p.reconnect_interval),
            clock,
            mode: if p.create2.full_mode {
                OiMode::Full
            } else {
                OiMode::Safe
            },
            reported: None,
            link_timeout: p.link_timeout,
            probe_interval: p.reconnect_interval,
            parser: StreamParser::with_payload_len(payload),
            odo: Odometer::new(
                CounterWidth::Bits16,
                counts_per_metre,
                robot.wheel_base,
                p.max_wheel_speed,
            ),
            cmd: WheelCommand::new(p.max_wheel_speed.min(0.5), p.deadman),
            health: LinkHealth::default(),
            up: false,
            ever_up: false,
            last_frame: 0.0,
            next_probe: f64::NEG_INFINITY,
            mode_warned: false,
            paused: false,
            battery: None,
            silent_warned: false,
            acc: None,
        }
    }

    /// Whether sensor frames currently arrive.
    pub fn link_up(&self) -> bool {
        self.up
    }

    fn send(&mut self, c: &OiCommand) -> bool {
        let ok = self.link.write_all(&encode(c)).is_ok();
        if ok {
            self.health.sent += 1;
        }
        ok
    }

    /// Sends a drive command unless the robot reported a mode that does not
    /// take one (Off or Passive): the specification allows them in Safe
    /// and Full only, and the robot stands still otherwise anyway.
    fn send_drive(&mut self, c: &OiCommand) -> bool {
        if !self.may_drive() {
            return true;
        }
        self.send(c)
    }

    /// Whether the robot may take a drive command: not reported in a mode
    /// that refuses one.
    fn may_drive(&self) -> bool {
        self.reported.is_none_or(|m| m.drives())
    }

    fn mode_command(&self) -> OiCommand {
        if self.mode == OiMode::Full {
            OiCommand::Full
        } else {
            OiCommand::Safe
        }
    }

    /// Start, Safe/Full, and the sensor stream.
    fn initialise(&mut self) {
        let mut ids = heapless::Vec::new();
        let _ = ids.extend_from_slice(&STREAM_IDS);
        let mode = self.mode_command();
        self.reported = None;
        let _ = self.send(&OiCommand::Start)
            && self.send(&mode)
            && self.send(&OiCommand::drive_direct(0.0, 0.0))
            && self.send(&OiCommand::Stream(ids))
            && self.send(&OiCommand::StreamEnable(true));
        self.parser.reset();
        self.odo.rebase();
    }

    /// Pauses the sensor stream (opcode 150, 0) and stops the wheels: without
    /// frames there is no bumper or link supervision, so nothing may move.
    /// Silence is expected until [`Create2Driver::resume_stream`].
    pub fn pause_stream(&mut self) -> bool {
        self.paused = true;
        self.cmd.requested = WheelSpeeds::STOP;
        self.send_drive(&OiCommand::drive_direct(0.0, 0.0))
            && self.send(&OiCommand::StreamEnable(false))
    }

    /// Resumes the sensor stream (opcode 150, 1) at clock time `now` (s); the
    /// link timeout restarts and the next frame is the new odometry baseline.
    pub fn resume_stream(&mut self, now: f64) -> bool {
        self.paused = false;
        self.last_frame = self.last_frame.max(now);
        self.parser.reset();
        self.odo.rebase();
        self.send(&OiCommand::StreamEnable(true))
    }

    /// Whether the stream is paused on purpose.
    pub fn stream_paused(&self) -> bool {
        self.paused
    }

    fn send_wheels(&mut self) {
        let w = self.cmd.effective();
        self.send_drive(&OiCommand::drive_direct(w.left, w.right));
    }

    /// Takes in one sensor frame that arrived at clock time `at` (s).
    fn on_frame(&mut self, f: SensorFrame, at: f64) {
        self.health.received += 1;
        self.last_frame = at;
        if let Some(m) = f.oi_mode.and_then(OiMode::from_byte) {
            self.reported = Some(m);
        }
        if !self.up {
            self.up = true;
            self.silent_warned = false;
            if self.ever_up {
                log::info!(
                    "wheel base {}: sensor stream back; link restored",
                    self.link.describe()
                );
                self.cmd.push(SafetyEvent::LinkRestored);
            } else {
                log::info!(
                    "wheel base {}: Create 2 streaming sensors",
                    self.link.describe()
                );
            }
            self.ever_up = true;
        }
        let mut stop_now = false;
        if let Some(s) = f.wheel_drops() {
            stop_now |= self.cmd.set_wheel_drop(sides(s), &mut self.health);
        }
        if let Some(s) = f.bumps() {
            stop_now |= self.cmd.set_bumper(sides(s), &mut self.health);
        }
        if stop_now {
            self.send_wheels();
        }
        if let Some(m) = f.oi_mode.and_then(OiMode::from_byte) {
            // Safe mode falls back to Passive on a wheel drop or cliff: ask for
            // the wanted mode again once the wheels are down.
            if m != self.mode && !self.cmd.gate.active() {
                if !self.mode_warned {
                    log::warn!(
                        "wheel base: OI is in {m:?} mode, want {:?}; re-entering",
                        self.mode
                    );
                    self.mode_warned = true;
                }
                let c = self.mode_command();
                self.send(&c);
                self.reported = None;
            } else if m == self.mode {
                self.mode_warned = false;
            }
        }
        if let Some(mv) = f.voltage_mv {
            self.battery = Some(mv as f64 / 1000.0);
        }
        if let (Some(l), Some(r)) = (f.left_encoder, f.right_encoder) {
            match self.odo.update(l as u32, r as u32, at) {
                Ok(Some(d)) => {
                    self.acc = Some(match self.acc {
                        None => d,
                        Some(a) => Odometry {
                            t0: a.t0,
                            t1: d.t1,
                            delta: a.delta * d.delta,
                            left: a.left + d.left,
                            right: a.right + d.right,
                        },
                    });
                }
                Ok(None) => {}
                Err(g) => {
                    self.health.odometry_glitches += 1;
                    log::warn!("wheel base: {g}");
                }
            }
        }
    }
}

impl DiffDriveBase for Create2Driver {
    fn set_wheels(&mut self, cmd: WheelSpeeds, now: f64) -> Result<(), MotorError> {
        self.cmd.accept(cmd, now)?;
        if self.paused {
            self.cmd.requested = WheelSpeeds::STOP;
        } else if self.up {
            self.send_wheels();
        }
        Ok(())
    }

    fn poll(&mut self, now: f64) -> Result<BaseFeedback, MotorError> {
        if self.cmd.check_deadman(now, &mut self.health) {
            self.send_wheels();
        }
        if !self.link.is_open() && self.link.ensure_open(now) {
            self.health.reconnects += 1;
            self.initialise();
            self.last_frame = now;
            self.next_probe = now + self.probe_interval;
        }
        let mut buf = [0u8; 256];
        for _ in 0..8 {
            match self.link.read(&mut buf) {
                ReadOutcome::Data(n) => {
                    let mut frames: heapless::Vec<SensorFrame, 32> = heapless::Vec::new();
                    let health = &mut self.health;
                    self.parser.feed(&buf[..n], &mut |r| match r {
                        Ok(f) => {
                            let _ = frames.push(f);
                        }
                        Err(_) => health.checksum_errors += 1,
                    });
                    // Frames read together were sent one stream period apart:
                    // the last one is the newest, arrived now (measured: the
                    // read blocked since the caller's `now`).
                    let t = self.clock.now();
                    let n_frames = frames.len();
                    for (i, f) in frames.into_iter().enumerate() {
                        let age = (n_frames - 1 - i) as f64 * STREAM_PERIOD;
                        let tf = (t - age).max(self.last_frame);
                        self.on_frame(f, tf);
                    }
                    // A short read drained the port: stop here rather than wait
                    // for a read timeout (frames come every 15 ms anyway).
                    if n < buf.len() {
                        break;
                    }
                }
                ReadOutcome::Timeout | ReadOutcome::Gone => break,
            }
        }
        self.health.discarded_bytes = self.parser.discarded;
        if self.paused {
            // Deliberate silence: no supervision to do, and nothing may move.
            self.last_frame = self.last_frame.max(now);
        } else if self.up && (now - self.last_frame > self.link_timeout || !self.link.is_open()) {
            self.up = false;
            self.health.link_losses += 1;
            log::warn!(
                "wheel base {}: no valid sensor frame for {:.2} s; link lost, stop sent",
                self.link.describe(),
                now - self.last_frame
            );
            self.send_drive(&OiCommand::drive_direct(0.0, 0.0));
            self.cmd.push(SafetyEvent::LinkLost);
            self.odo.rebase();
            self.next_probe = now;
        }
        if !self.up && !self.paused && self.link.is_open() && now >= self.next_probe {
            if self.next_probe.is_finite() && !self.silent_warned {
                self.silent_warned = true;
                log::warn!(
                    "wheel base {}: no sensor stream from the Create 2 (is it awake and powered? Start, {:?} and the stream request are re-sent every {:.1} s)",
                    self.link.describe(),
                    self.mode,
                    self.probe_interval
                );
            }
            self.next_probe = now + self.probe_interval;
            self.initialise();
        }
        if self.up && !self.paused {
            self.send_wheels();
        }
        Ok(self.cmd.feedback(self.acc.take(), self.up, self.battery))
    }

    fn stop(&mut self) -> Result<(), MotorError> {
        self.cmd.halt();
        self.link.require_open()?;
        let ok = self.send_drive(&OiCommand::drive_direct(0.0, 0.0))
            && self.send(&OiCommand::StreamEnable(false))
            && self.send(&OiCommand::Stop);
        self.reported = Some(OiMode::Off);
        if ok {
            Ok(())
        } else {
            Err(MotorError::Io {
                device: self.link.describe(),
                source: std::io::Error::new(
                    std::io::ErrorKind::BrokenPipe,
                    "stop could not be sent",
                ),
            })
        }
    }

    fn health(&self) -> LinkHealth {
        self.health
    }

    fn bumper_sides(&self) -> bool {
        true
    }
}

impl Drop for Create2Driver {
    /// Leaves the robot stopped: the Create 2 has no command timeout and would
    /// otherwise keep executing its last Drive Direct.
    fn drop(&mut self) {
        if self.link.is_open() && self.may_drive() {
            let _ = self
                .link
                .write_all(&encode(&OiCommand::drive_direct(0.0, 0.0)));
        }
    }
}

/// The codec's bumper or wheel-drop pair as the daemon's.
fn sides(s: codec::Sides) -> Sides {
    Sides {
        left: s.left,
        right: s.right,
    }
}
