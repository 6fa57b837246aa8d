//! Runs an emulated base in its own thread on a wire (a pty the daemon opens
//! exactly like a device), stepping the kinematics on the injected clock and
//! applying injected faults: a silent link, corrupted bytes either way, a
//! bumper hit, a wheel drop, an unplugged cable.

use std::io;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use nalgebra::Point2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::base_emu::create2::Create2Device;
use crate::base_emu::roboclaw::RoboClawDevice;
use crate::base_emu::{BaseDevice, BodyState, DeviceStats};
use crate::clock::SharedClock;
use crate::config::Config;
use crate::geom::Pose;
use crate::kinematics::{DiffDriveSim, KinematicsParams};
use crate::motor::odometry::counts_per_metre;
use crate::motor::{BaseKind, MotorParams, Sides, WheelSpeeds};
use crate::walker::{lock_crowd, Body, Crowd};
use crate::world::World;

/// The emulator's end of the link.
pub trait EmuWire: Send {
    /// Reads what the host sent, waiting briefly; `TimedOut`/`WouldBlock` when
    /// nothing came.
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize>;
    /// Sends bytes to the host.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Pulls the cable: the host sees the device vanish. False if unsupported.
    fn unplug(&mut self) -> bool {
        false
    }
    /// Plugs the cable back in.
    fn replug(&mut self) -> io::Result<()> {
        Ok(())
    }
    /// The path the host opens, if the wire has one.
    fn client_path(&self) -> Option<PathBuf>;
}

impl EmuWire for std::os::unix::net::UnixStream {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        io::Read::read(self, buf)
    }
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        io::Write::write_all(self, bytes)
    }
    fn client_path(&self) -> Option<PathBuf> {
        None
    }
}

/// A fault to inject.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fault {
    /// The link carries nothing either way for `secs` seconds (clock time).
    Silence {
        /// Duration (s).
        secs: f64,
    },
    /// The next `bytes` bytes sent to the host get a bit flipped.
    CorruptOut {
        /// How many bytes.
        bytes: u32,
    },
    /// The next `bytes` bytes from the host get a bit flipped.
    CorruptIn {
        /// How many bytes.
        bytes: u32,
    },
    /// Both bumpers closed for `secs` seconds (as if something hit the robot).
    Bump {
        /// Duration (s).
        secs: f64,
    },
    /// Both wheels dropped (robot lifted) for `secs` seconds.
    WheelDrop {
        /// Duration (s).
        secs: f64,
    },
    /// Cable pulled for `secs` seconds (needs a wire that supports it).
    Unplug {
        /// Duration (s).
        secs: f64,
    },
    /// For `secs` seconds each wheel covers this share less floor than its
    /// encoder counts (a slip burst on a rug or a wet patch).
    Slip {
        /// Duration (s).
        secs: f64,
        /// Share of the left wheel's travel lost, 0..=1.
        left: f64,
        /// Share of the right wheel's travel lost, 0..=1.
        right: f64,
    },
    /// The body is moved `dx` ahead and `dy` left and turned by `turn`
    /// (rad) at once, the encoders counting nothing: a person lifting the
    /// robot and putting it down elsewhere, or (no move) a knock that
    /// turns it (see [`crate::kinematics::DiffDriveSim::displace`]).
    Displace {
        /// Ahead (m, robot frame).
        dx: f64,
        /// To the left (m, robot frame).
        dy: f64,
        /// Turn (rad, counter-clockwise).
        turn: f64,
    },
}

/// Counters of a running emulator.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EmuStats {
    /// The device core's counters.
    pub device: DeviceStats,
    /// Bytes corrupted by fault injection (both directions).
    pub corrupted_bytes: u64,
    /// Bytes swallowed by a silence fault (both directions).
    pub(crate) silenced_bytes: u64,
    /// Bumper closures (contact or injected).
    pub bumps: u64,
    /// Kinematics steps refused by a collision.
    pub(crate) blocked_steps: u64,
    /// Times the cable was pulled.
    pub unplugs: u64,
}

/// Why an emulator could not start.
#[derive(Debug, thiserror::Error)]
pub enum EmuError {
    /// The wire (pty) could not be created.
    #[error("cannot create the emulator's port: {0}")]
    Wire(String),
    /// The emulator thread could not be started.
    #[error("cannot start the emulator thread: {0}")]
    Thread(io::Error),
}

/// What to emulate and how.
#[derive(Clone)]
pub struct EmulatorConfig {
    /// Which protocol.
    pub kind: BaseKind,
    /// Link settings the daemon uses (address, counts per revolution).
    pub motor: MotorParams,
    /// Wheel radius (m), for counts per metre.
    pub wheel_radius: f64,
    /// Kinematics and noise.
    pub kinematics: KinematicsParams,
    /// Where the robot starts.
    pub start: Pose,
    /// What the body collides with (may contain obstacles the scanner's world
    /// lacks); `None` for open floor.
    pub world: Option<Arc<World>>,
    /// People walking through the room: stepped on the emulator's clock
    /// with the robot's true pose, run into by the body (and closing the
    /// bumper); `None` for nobody. Shared with the scanner emulator's scene.
    pub(crate) crowd: Option<Arc<Mutex<Crowd>>>,
    /// Kinematics step (s of clock time).
    pub step: f64,
    /// Seed of the fault-injection generator.
    pub seed: u64,
    /// Refuse and count what the device's manual does not allow, rather than
    /// answer it as the device would (RoboClaw: see
    /// [`RoboClawDevice::strict`]; Create 2: out-of-range values refused
    /// rather than clamped, counted as rejected either way). On by default,
    /// so that a driver drifting from the manual fails its tests.
    pub strict: bool,
}

impl EmulatorConfig {
    /// An emulator of `kind` matching the daemon's configuration `cfg`.
    pub fn from_config(cfg: &Config, kind: BaseKind) -> Self {
        Self {
            kind,
            motor: MotorParams {
                kind,
                ..cfg.motor.clone()
            },
            wheel_radius: cfg.robot.wheel_radius,
            kinematics: KinematicsParams {
                wheel_base: cfg.robot.wheel_base,
                body_radius: cfg.robot.radius,
                ..KinematicsParams::default()
            },
            start: Pose::identity(),
            world: None,
            crowd: None,
            step: 0.005,
            seed: 1,
            strict: true,
        }
    }

    /// The same emulator placed in `world`: it starts at the world's start
    /// pose and collides with its walls and obstacles.
    pub fn in_world(mut self, world: Arc<World>) -> Self {
        self.start = world.start;
        self.world = Some(world);
        self
    }

    /// The device core this configuration describes.
    pub fn device(&self) -> Box<dyn BaseDevice> {
        let per_metre = |counts_per_rev| counts_per_metre(counts_per_rev, self.wheel_radius);
        match self.kind {
            BaseKind::Roboclaw => Box::new(
                RoboClawDevice::new(
                    self.motor.roboclaw.address,
                    per_metre(self.motor.roboclaw.counts_per_rev),
                    self.motor.roboclaw.m1_is_left,
                )
                .with_motors(self.kinematics.max_wheel_speed, self.kinematics.max_accel)
                .strict(self.strict),
            ),
            BaseKind::Create2 => Box::new(Create2Device::new(
                per_metre(self.motor.create2.counts_per_rev),
                self.kinematics.wheel_base,
                self.strict,
            )),
        }
    }
}

#[derive(Default)]
struct Faults {
    silent_until: f64,
    corrupt_out: u32,
    corrupt_in: u32,
    bump_until: f64,
    drop_until: f64,
    unplug_for: Option<f64>,
    slip_until: f64,
    slip: (f64, f64),
    displace: Option<(f64, f64, f64)>,
}

/// How far back (s) the emulator keeps the robot's true poses: longer than
/// a scanner's revolution, whose steps are looked up after it ends.
const TRUTH_HISTORY: f64 = 0.5;

struct Shared {
    truth: Pose,
    /// The true poses of the last [`TRUTH_HISTORY`] seconds, oldest first,
    /// with the clock time each was reached.
    history: std::collections::VecDeque<(f64, Pose)>,
    wheels: WheelSpeeds,
    targets: WheelSpeeds,
    stats: EmuStats,
    faults: Faults,
    now: f64,
}

/// A running emulator; stops its thread when dropped.
pub struct EmulatorHandle {
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    path: Option<PathBuf>,
}

impl EmulatorHandle {
    /// The path the daemon opens as its wheel-base device.
    pub fn path(&self) -> Option<PathBuf> {
        self.path.clone()
    }

    fn with<T>(&self, f: impl FnOnce(&mut Shared) -> T) -> T {
        let mut g = match self.shared.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        f(&mut g)
    }

    /// The robot's true pose.
    pub fn truth(&self) -> Pose {
        self.with(|s| s.truth)
    }

    /// The robot's true pose with the clock time it was reached (s), for
    /// pose-error evaluation against timestamped estimates.
    pub(crate) fn truth_stamped(&self) -> (f64, Pose) {
        self.with(|s| (s.now, s.truth))
    }

    /// Fills `out` with the true poses reached from just before clock time
    /// `from` on (with their times, oldest first; at most the last
    /// half second): where the robot was while a scanner swept.
    pub(crate) fn truth_since(&self, from: f64, out: &mut Vec<(f64, Pose)>) {
        out.clear();
        self.with(|s| {
            let first = s.history.partition_point(|h| h.0 <= from).saturating_sub(1);
            out.extend(s.history.range(first..).copied());
        });
    }

    /// One human-readable status line: true pose, wheel speeds, counters.
    pub fn status_line(&self) -> String {
        self.with(|s| {
            let t = s.truth;
            let d = s.stats.device;
            format!(
                "t={:.1}s pose=({:.3} m, {:.3} m, {:.1} deg) wheels=({:+.3}, {:+.3}) m/s packets ok={} rejected={} cut={} frames={} device-timeouts={} bumps={} corrupted={} silenced={} unplugs={}",
                s.now,
                t.translation.x,
                t.translation.y,
                t.rotation.angle().to_degrees(),
                s.wheels.left,
                s.wheels.right,
                d.packets_ok,
                d.packets_rejected,
                d.packets_cut,
                d.frames_out,
                d.device_timeouts,
                s.stats.bumps,
                s.stats.corrupted_bytes,
                s.stats.silenced_bytes,
                s.stats.unplugs
            )
        })
    }

    /// The wheel speeds the motors currently run at (m/s).
    pub fn wheels(&self) -> WheelSpeeds {
        self.with(|s| s.wheels)
    }

    /// The wheel set-points the controller currently drives the motors at
    /// (m/s); differs from [`EmulatorHandle::wheels`] while accelerating,
    /// stalled against an obstacle or lifted.
    pub fn motor_targets(&self) -> WheelSpeeds {
        self.with(|s| s.targets)
    }

    /// The emulator's counters.
    pub fn stats(&self) -> EmuStats {
        self.with(|s| s.stats)
    }

    /// Injects a fault, timed from the emulator's current clock time.
    pub fn inject(&self, fault: Fault) {
        self.with(|s| {
            let now = s.now;
            let f = &mut s.faults;
            match fault {
                Fault::Silence { secs } => f.silent_until = now + secs,
                Fault::CorruptOut { bytes } => f.corrupt_out += bytes,
                Fault::CorruptIn { bytes } => f.corrupt_in += bytes,
                Fault::Bump { secs } => f.bump_until = now + secs,
                Fault::WheelDrop { secs } => f.drop_until = now + secs,
                Fault::Unplug { secs } => f.unplug_for = Some(secs),
                Fault::Slip { secs, left, right } => {
                    f.slip_until = now + secs;
                    f.slip = (left, right);
                }
                Fault::Displace { dx, dy, turn } => f.displace = Some((dx, dy, turn)),
            }
        });
    }

    /// Stops the emulator and waits for its thread.
    pub fn shutdown(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for EmulatorHandle {
    fn drop(&mut self) {
        self.halt();
    }
}

/// Starts the emulator described by `cfg` on `wire`, timed by `clock`.
pub fn spawn(
    cfg: EmulatorConfig,
    mut wire: Box<dyn EmuWire>,
    clock: SharedClock,
) -> Result<EmulatorHandle, EmuError> {
    let path = wire.client_path();
    let shared = Arc::new(Mutex::new(Shared {
        truth: cfg.start,
        history: std::collections::VecDeque::new(),
        wheels: WheelSpeeds::STOP,
        targets: WheelSpeeds::STOP,
        stats: EmuStats::default(),
        faults: Faults::default(),
        now: clock.now(),
    }));
    let stop = Arc::new(AtomicBool::new(false));
    let (sh, st) = (shared.clone(), stop.clone());
    let name = match cfg.kind {
        BaseKind::Roboclaw => "emu-roboclaw",
        BaseKind::Create2 => "emu-create2",
    };
    let thread = std::thread::Builder::new()
        .name(name.into())
        .spawn(move || run(cfg, &mut *wire, clock, sh, st))
        .map_err(EmuError::Thread)?;
    Ok(EmulatorHandle {
        shared,
        stop,
        thread: Some(thread),
        path,
    })
}

fn lock(m: &Mutex<Shared>) -> std::sync::MutexGuard<'_, Shared> {
    match m.lock() {
        Ok(g) => g,
        Err(p) => p.into_inner(),
    }
}

fn run(
    cfg: EmulatorConfig,
    wire: &mut dyn EmuWire,
    clock: SharedClock,
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
) {
    let mut device = cfg.device();
    let mut sim = DiffDriveSim::new(cfg.kinematics.clone(), cfg.start);
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let world = cfg.world.clone();
    let step = if cfg.step > 0.0 { cfg.step } else { 0.005 };
    let mut target = WheelSpeeds::STOP;
    let mut last = clock.now();
    let mut inbuf = [0u8; 512];
    let mut out: Vec<u8> = Vec::with_capacity(1024);
    let mut was_bumped = false;
    let mut unplugged_until: Option<f64> = None;
    let mut bodies: Vec<Body> = Vec::new();
    while !stop.load(Ordering::SeqCst) {
        // Cable pulled: nothing flows, the robot coasts to a stop on its own
        // controller (RoboClaw timeout) or keeps going (Create 2).
        if let Some(until) = unplugged_until {
            if clock.now() >= until {
                if wire.replug().is_ok() {
                    unplugged_until = None;
                }
            } else {
                std::thread::sleep(std::time::Duration::from_millis(2));
            }
        }
        let before_read = clock.now();
        let n = if unplugged_until.is_none() {
            // Timeout, or the host has not opened the port yet: nothing read.
            wire.read(&mut inbuf).unwrap_or_default()
        } else {
            0
        };
        if n == 0 {
            device.line_silent(before_read);
        }
        let now = clock.now();
        let (silent, mut corrupt_in, bump, lifted, unplug, slip, displace) = {
            let mut s = lock(&shared);
            s.now = now;
            let f = &mut s.faults;
            let r = (
                now < f.silent_until,
                f.corrupt_in,
                now < f.bump_until,
                now < f.drop_until,
                f.unplug_for.take(),
                if now < f.slip_until {
                    f.slip
                } else {
                    (0.0, 0.0)
                },
                f.displace.take(),
            );
            f.corrupt_in = 0;
            r
        };
        sim.set_slip_loss(slip);
        if let Some((dx, dy, turn)) = displace {
            let from = sim.pose();
            match sim.displace(dx, dy, turn, world.as_deref()) {
                Some((mx, my)) => log::info!(
                    "emulated base displaced by ({mx:.2}, {my:.2}) m and {:.0}° from ({:.2}, {:.2}) m, {:.0}°",
                    turn.to_degrees(),
                    from.translation.x,
                    from.translation.y,
                    crate::geom::heading(&from).to_degrees()
                ),
                None => log::warn!(
                    "emulated base not displaced: no free spot {:.2} m from ({:.2}, {:.2}) m",
                    dx.hypot(dy),
                    from.translation.x,
                    from.translation.y
                ),
            }
        }
        if let Some(secs) = unplug {
            if wire.unplug() {
                unplugged_until = Some(now + secs);
                lock(&shared).stats.unplugs += 1;
            }
        }
        // Kinematics up to now, people moved on first.
        let mut dt = (now - last).clamp(0.0, 0.2);
        last = now;
        if let Some(c) = &cfg.crowd {
            let mut c = lock_crowd(c);
            let at = Point2::from(sim.pose().translation.vector);
            c.step(dt, &at, cfg.kinematics.body_radius);
            bodies.clear();
            bodies.extend_from_slice(c.bodies());
        }
        let mut blocked = 0u64;
        while dt > 1e-12 {
            let h = dt.min(step);
            if !lifted {
                let o = sim.step_among(target, h, world.as_deref(), &bodies);
                blocked += u64::from(o.blocked);
            }
            dt -= h;
        }
        let contact = sim.bumper();
        let body = BodyState {
            encoder: sim.encoder_travel(),
            bumper: Sides {
                left: contact.left || bump,
                right: contact.right || bump,
            },
            wheel_drop: Sides {
                left: lifted,
                right: lifted,
            },
            wheels: sim.wheel_speeds(),
            cliff: [false; 4],
        };
        out.clear();
        let mut silenced = 0u64;
        let mut corrupted = 0u64;
        if n > 0 {
            let bytes = &mut inbuf[..n];
            if silent {
                silenced += n as u64;
            } else {
                for b in bytes.iter_mut() {
                    if corrupt_in > 0 {
                        *b ^= 1 << rng.random_range(0..8);
                        corrupt_in -= 1;
                        corrupted += 1;
                    }
                }
                device.on_bytes(bytes, now, &body, &mut out);
            }
        }
        target = device.tick(now, &body, &mut out);
        let mut s = lock(&shared);
        // Unused corruption budget carries over to the next bytes.
        s.faults.corrupt_in += corrupt_in;
        if !out.is_empty() {
            if silent || unplugged_until.is_some() {
                silenced += out.len() as u64;
                out.clear();
            } else {
                for b in out.iter_mut() {
                    if s.faults.corrupt_out > 0 {
                        *b ^= 1 << rng.random_range(0..8);
                        s.faults.corrupt_out -= 1;
                        corrupted += 1;
                    }
                }
            }
        }
        if body.bumper.any() && !was_bumped {
            s.stats.bumps += 1;
            let (p, w) = (sim.pose(), sim.wheel_speeds());
            log::debug!(
                "emulated bumper closed ({:?}) at t={now:.2} s, true pose ({:.3}, {:.3}) m {:.0}°, wheels ({:+.2}, {:+.2}) m/s",
                body.bumper,
                p.translation.x,
                p.translation.y,
                crate::geom::heading(&p).to_degrees(),
                w.left,
                w.right,
            );
        }
        was_bumped = body.bumper.any();
        s.truth = sim.pose();
        let (t, p) = (s.now, s.truth);
        s.history.push_back((t, p));
        while s.history.front().is_some_and(|h| h.0 < t - TRUTH_HISTORY) {
            s.history.pop_front();
        }
        s.wheels = sim.wheel_speeds();
        s.targets = target;
        s.stats.device = device.stats();
        s.stats.silenced_bytes += silenced;
        s.stats.corrupted_bytes += corrupted;
        s.stats.blocked_steps += blocked;
        drop(s);
        if !out.is_empty() {
            // A host that does not read loses the bytes, as with real hardware.
            let _ = wire.write_all(&out);
        }
    }
}
