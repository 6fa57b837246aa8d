//! The plain data a wheel base exchanges with the rest of the daemon:
//! wheel set-points, odometry increments, safety events, link health, and
//! the [`DiffDriveBase`] trait every base driver implements.

/// The wheel set-points, odometry increments and sides a base exchanges,
/// plain data of `sweepline-core` (the algorithms take them too).
pub use crate::base::{Odometry, Sides, WheelSpeeds};

/// Something the base or the link did that the planner must know about.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SafetyEvent {
    /// A bumper closed: the wheels were stopped at once; only reversing is
    /// accepted while it stays closed.
    Bumper(Sides),
    /// A bumper opened again.
    BumperReleased,
    /// A wheel dropped (robot lifted or over an edge): wheels stopped, no motion
    /// accepted until it is back on the floor.
    WheelDrop(Sides),
    /// The wheels are back on the floor.
    WheelDropCleared,
    /// No fresh wheel command arrived within the dead-man time: wheels stopped.
    DeadMan,
    /// The link went silent, garbled or away; the base was stopped where possible.
    LinkLost,
    /// The link answers again and the base was re-initialised.
    LinkRestored,
}

impl std::fmt::Display for SafetyEvent {
    /// The event in plain words, as the log shows it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let side = |s: &Sides| match (s.left, s.right) {
            (true, true) => "both sides",
            (true, false) => "left",
            (false, true) => "right",
            (false, false) => "no side",
        };
        match self {
            SafetyEvent::Bumper(s) => write!(f, "bumper closed ({}): wheels stopped", side(s)),
            SafetyEvent::BumperReleased => f.write_str("bumper open again"),
            SafetyEvent::WheelDrop(s) => write!(f, "wheel dropped ({}): wheels stopped", side(s)),
            SafetyEvent::WheelDropCleared => f.write_str("wheels back on the floor"),
            SafetyEvent::DeadMan => {
                f.write_str("no wheel command within the dead-man time: wheels stopped")
            }
            SafetyEvent::LinkLost => f.write_str("link lost: wheels stopped"),
            SafetyEvent::LinkRestored => f.write_str("link restored"),
        }
    }
}

/// Counters of the wheel-base link, for the health report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkHealth {
    /// Packets or frames sent.
    pub sent: u64,
    /// Valid replies or frames received.
    pub received: u64,
    /// Replies or frames rejected for a bad CRC or checksum.
    pub checksum_errors: u64,
    /// Bytes thrown away while looking for the next frame or reply.
    pub discarded_bytes: u64,
    /// Requests that got no (complete) reply in time.
    pub timeouts: u64,
    /// Write commands the controller did not acknowledge.
    pub nacks: u64,
    /// Times the link was declared lost.
    pub link_losses: u64,
    /// Times the port was (re)opened successfully.
    pub reconnects: u64,
    /// Times the dead-man timer stopped the wheels.
    pub deadman_stops: u64,
    /// Bumper or wheel-drop stops.
    pub safety_stops: u64,
    /// Encoder readings rejected as physically implausible jumps.
    pub odometry_glitches: u64,
    /// Times odometry re-based on a jump the next reading confirmed (the
    /// encoder counters were reset, e.g. by a controller reboot).
    pub odometry_rebases: u64,
}

/// Why a wheel-base operation failed.
#[derive(Debug, thiserror::Error)]
pub enum MotorError {
    /// A wheel command was NaN or infinite.
    #[error("wheel command is not a finite number (left {left}, right {right} m/s)")]
    BadCommand {
        /// Left speed given.
        left: f64,
        /// Right speed given.
        right: f64,
    },
    /// The port is not open (device missing, or being re-opened).
    #[error("wheel base {device} is not connected")]
    NotConnected {
        /// The device name.
        device: String,
    },
    /// The port failed.
    #[error("wheel base {device}: {source}")]
    Io {
        /// The device name.
        device: String,
        /// The OS error.
        source: std::io::Error,
    },
}

/// What one [`DiffDriveBase::poll`] produced.
#[derive(Clone, Debug, Default)]
pub struct BaseFeedback {
    /// Encoder odometry since the previous poll, if the encoders were read.
    pub odometry: Option<Odometry>,
    /// Safety events raised during this poll, oldest first.
    pub events: heapless::Vec<SafetyEvent, 8>,
    /// Whether the link currently answers.
    pub link_up: bool,
    /// Latest main battery voltage (V), when the base reports one.
    pub battery: Option<f64>,
}

/// A differential-drive base: wheel velocity set-points in, encoder odometry and
/// safety events out.
///
/// Time is passed in: the caller (the motor stage's thread, which owns the
/// daemon's one clock) reads its [`crate::clock::Clock`] once and hands
/// `now` (s) to every call that decides by time (the dead-man, link
/// timeouts, reconnect and probe intervals). A driver keeps the clock only
/// to turn its reply timeout into a wall-clock OS wait and to stamp what
/// arrives from a blocking read (odometry is stamped when the counters
/// were read, which a `now` taken before the read cannot say). Timestamps
/// are seconds on that same clock.
pub trait DiffDriveBase: Send {
    /// Sets the wheel velocities (m/s) at clock time `now` (s). This also
    /// feeds the dead-man timer; safety latches (bumper, wheel drop) may
    /// override the command with a stop.
    fn set_wheels(&mut self, cmd: WheelSpeeds, now: f64) -> Result<(), MotorError>;

    /// Runs one I/O cycle at clock time `now` (s): reads encoders and
    /// sensors, enforces the dead-man, detects a silent or garbled link and
    /// re-establishes it.
    fn poll(&mut self, now: f64) -> Result<BaseFeedback, MotorError>;

    /// Stops the wheels now (best effort) and leaves the base safe, e.g. on
    /// shutdown.
    fn stop(&mut self) -> Result<(), MotorError>;

    /// The link counters.
    fn health(&self) -> LinkHealth;

    /// Whether the bumper tells its left side from its right: then both
    /// sides closed means a contact near the middle of the front. A one-bit
    /// bumper (a RoboClaw E-stop input) reports both sides on every contact.
    fn bumper_sides(&self) -> bool {
        false
    }
}
