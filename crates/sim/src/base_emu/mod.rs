//! Emulated wheel bases: a RoboClaw and a Create 2 answering their real byte
//! protocols, driving the simulated kinematics, with fault injection.
//!
//! Each device is a sans-IO core ([`BaseDevice`]: bytes in, bytes and wheel
//! set-points out); [`spawn`] runs one on a wire (a pty the daemon opens as
//! its device) in a thread, stepping [`crate::kinematics::DiffDriveSim`] on the injected clock.
//!
//! The daemon's motor thread, in short (here against an emulated RoboClaw on
//! a pty, exactly as against `/dev/sweepline-base`):
//!
//! ```
//! use std::sync::Arc;
//! use sweepline_io::clock::{Clock, MonotonicClock, SharedClock};
//! use sweepline_daemon::config::Config;
//! use sweepline_io::motor::{self, odometry::OdometryTrack, BaseKind, WheelSpeeds};
//! use sweepline_sim::base_emu::{spawn_on_pty, EmulatorConfig};
//!
//! let clock: SharedClock = Arc::new(MonotonicClock::new());
//! let mut cfg = Config::default();
//! let emu = spawn_on_pty(EmulatorConfig::from_config(&cfg, BaseKind::Roboclaw), None, clock.clone())?;
//! cfg.motor.device = emu.path().unwrap().display().to_string();
//!
//! let mut base = motor::open_base(&cfg.motor, &cfg.robot, clock.clone());
//! let mut track = OdometryTrack::new();
//! for _ in 0..20 {
//!     let now = clock.now(); // one reading per cycle, passed to the driver
//!     base.set_wheels(WheelSpeeds::from_body(0.1, 0.0, cfg.robot.wheel_base), now)?;
//!     let fb = base.poll(now)?;
//!     if let Some(o) = fb.odometry {
//!         track.push(&o); // the localiser asks track.pose_at(scan_time)
//!     }
//!     for e in &fb.events {
//!         eprintln!("wheel base: {e:?}"); // to the planner
//!     }
//!     clock.sleep(0.05);
//! }
//! base.stop()?;
//! assert!(track.latest().is_some());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod create2;
pub mod faults;
// The driver against its emulator in one thread, lock-step: a test harness.
#[cfg(test)]
mod loopback;
pub(crate) mod pty_wire;
pub mod roboclaw;
pub mod runner;

use crate::motor::{Sides, WheelSpeeds};

pub use runner::{spawn, EmuError, EmuStats, EmuWire, EmulatorConfig, EmulatorHandle, Fault};

/// Starts the emulator `cfg` on a new pty (with the symlink `link`, if given,
/// pointing at it), timed by `clock`. The daemon opens
/// [`EmulatorHandle::path`] as its wheel-base device. This is what
/// `sweepline emulate roboclaw|create2` and the simulator call.
pub fn spawn_on_pty(
    cfg: EmulatorConfig,
    link: Option<std::path::PathBuf>,
    clock: crate::clock::SharedClock,
) -> Result<EmulatorHandle, EmuError> {
    let wire = pty_wire::PtyWire::new(link).map_err(|e| EmuError::Wire(e.to_string()))?;
    spawn(cfg, Box::new(wire), clock)
}

/// What the device electronics sense of the body.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BodyState {
    /// Wheel travel the encoders counted since start (m, left and right).
    pub encoder: (f64, f64),
    /// Front bumper switches.
    pub bumper: Sides,
    /// Wheel-drop switches.
    pub wheel_drop: Sides,
    /// The speeds the wheels turn at (m/s): an encoder counts nothing while
    /// its wheel stands still.
    pub wheels: WheelSpeeds,
    /// Cliff sensors (left, front left, front right, right): floor missing
    /// under them. The simulated worlds have no drop-offs, so only tests set
    /// these.
    pub cliff: [bool; 4],
}

/// Counters of an emulated device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceStats {
    /// Bytes received from the host.
    pub(crate) bytes_in: u64,
    /// Bytes skipped while looking for a packet start or known opcode.
    pub bytes_skipped: u64,
    /// Valid packets or commands handled.
    pub packets_ok: u64,
    /// Packets rejected (bad CRC, unknown command, not allowed in this mode).
    pub packets_rejected: u64,
    /// Partial packets dropped because the next byte came later than the
    /// controller's inter-byte gap (RoboClaw: 10 ms). A real controller
    /// drops them too. A client that writes a packet byte by byte and is
    /// paused by its host loses such packets and must retry; a driver
    /// that sends stray bytes (a CRC after a read) shows here as well.
    pub packets_cut: u64,
    /// Of those, commands valid in themselves that arrived in a mode not
    /// taking them (Create 2: a drive command in Passive). A driver can race
    /// the robot here: the robot leaves Safe mode on its own (wheel drop)
    /// while a drive command is on the wire.
    pub refused_in_mode: u64,
    /// Sensor-stream frames sent.
    pub frames_out: u64,
    /// Times the controller's own serial timeout stopped the motors.
    pub device_timeouts: u64,
}

/// A device core: the protocol side of an emulated wheel base.
pub trait BaseDevice: Send {
    /// Handles bytes from the host received at `now`; replies go to `out`.
    fn on_bytes(&mut self, bytes: &[u8], now: f64, body: &BodyState, out: &mut Vec<u8>);
    /// The host sent nothing from its last bytes up to `until`: a device
    /// whose packets die in an inter-byte gap drops a partial one here.
    ///
    /// Silence is told apart from bytes arriving late so that an emulator
    /// kept off the CPU, which finds a whole packet's tail waiting when it
    /// reads again, never blames the host for its own lateness: the wire
    /// calls this only after a read that found nothing, with a time taken
    /// before that read began.
    fn line_silent(&mut self, until: f64) {
        let _ = until;
    }
    /// Lets time pass to `now`: returns the wheel set-points the motors follow;
    /// unsolicited bytes (a sensor stream) go to `out`.
    fn tick(&mut self, now: f64, body: &BodyState, out: &mut Vec<u8>) -> WheelSpeeds;
    /// The device's counters.
    fn stats(&self) -> DeviceStats;
}

/// Keeps an emulator running until `stop` is set, handing its status line to
/// `report` every `every` seconds of clock time; for `sweepline emulate`,
/// whose `main` owns the signal handling.
pub fn serve(
    handle: &EmulatorHandle,
    clock: &dyn crate::clock::Clock,
    stop: &std::sync::atomic::AtomicBool,
    every: f64,
    mut report: impl FnMut(&str),
) {
    let mut next = clock.now();
    while !stop.load(std::sync::atomic::Ordering::SeqCst) {
        let now = clock.now();
        if now >= next {
            report(&handle.status_line());
            next = now + every.max(0.01);
        }
        clock.sleep(0.05_f64.min(every.max(0.01)));
    }
}
