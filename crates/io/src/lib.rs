//! sweepline's drivers: the devices' ports and the clock they are read by.
//!
//! * [`serial`]: serial devices (`/dev/ttyACM0` as a robot has it), ptys
//!   (the emulators' side) and TCP, with the timeouts and reconnection the
//!   drivers need;
//! * [`urg`]: the Hokuyo URG driver over the SCIP codec: robust open,
//!   streaming, clock sync, recovery from timeouts, garbage and a vanished
//!   device;
//! * [`motor`]: the wheel-base drivers (RoboClaw, Create 2) over their
//!   codecs, the `DiffDriveBase` trait, odometry and safety events;
//! * [`clock`]: the one clock trait every driver and stage reads (real,
//!   scaled, manual, paced by the daemon);
//! * [`os`]: safe wrappers for the other OS calls the daemon needs (the
//!   monotonic clock, thread and process CPU time, real-time scheduling,
//!   clock ticks).
//!
//! The only sweepline crate that talks to the operating system (ports,
//! ptys, `poll`, clocks, scheduling) and the only one with `unsafe`: the
//! others `#![forbid(unsafe_code)]`. It sits on `sweepline-wire` (the codecs) and
//! `sweepline-core` (the plain data) and cannot name the pipeline, the
//! daemon or the simulator.

#![warn(missing_docs)]

// The layers below, by the names they have in `sweepline`, so that paths
// such as `crate::scan::LaserScan` read the same in every crate.
use sweepline_core::{base, capacity, check_keys, geom, param_check, robot, scan};
use sweepline_wire::scip;

pub mod clock;
pub mod motor;
pub mod os;
pub mod serial;
pub mod urg;
