//! sweepline's daemon: what runs the robot, on top of the drivers and the
//! algorithms.
//!
//! * [`pipeline`]: the only layer that owns threads: stages, bounded edges
//!   with declared policies, budgets, latency/CPU metrics, the supervisor,
//!   systemd notification and the checkpoint store;
//! * [`daemon`]: the real stages (scanner, localise, map, plan, control,
//!   motor) wired into the pipeline, with the checks that run beside them
//!   (mount, frame alignment, contact marks, relocalisation, stuck watch)
//!   and resuming from a checkpoint;
//! * [`config`]: the configuration file, aggregating each layer's own
//!   `*Params` table (each checks itself);
//! * [`report`]: the latency/CPU report and the run folder's pictures.
//!
//! It sits on `sweepline-io` (drivers, clock), `sweepline-core`
//! (algorithms) and `sweepline-wire` (codecs), and cannot name the
//! simulator or the command line (the `sweepline` crate), which sit above.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

// The layers below, by the names they have in `sweepline`, so that paths
// such as `crate::icp::Tracker` read the same in every crate.
use sweepline_core::{
    capacity, check_keys, checks, control, decomp, geom, grid, icp, map, param_check, plan, robot,
    scan, svg_canvas,
};
use sweepline_io::{clock, motor, serial, urg};

pub mod config;
pub mod daemon;
pub mod pipeline;
pub mod report;
