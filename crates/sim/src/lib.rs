//! sweepline's simulator: worlds, ray casting, robot kinematics, device
//! emulators on ptys, lock-step and closed-loop runs, replay of recorded
//! logs and trajectory evaluation.
//!
//! It sits on the daemon (`sweepline-daemon`), which it runs unchanged
//! against emulated devices, and on the drivers, algorithms and codecs
//! below; only the command line (the `sweepline` crate) sits above it.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

// The layers below, by the names they have in `sweepline`, so that paths
// such as `crate::config::Config` read the same in every crate.
use sweepline_core::{capacity, control, decomp, geom, grid, map, plan, scan, svg_canvas};
use sweepline_daemon::{config, daemon, pipeline, report};
use sweepline_io::{clock, motor, serial, urg};
use sweepline_live as live;
use sweepline_wire::scip;

pub mod base_emu;
pub mod carmen;
pub mod closed_loop;
pub mod coverage_metrics;
pub mod coverage_svg;
pub mod eval;
pub mod floorplan;
pub mod kinematics;
pub mod lockstep;
pub mod noise;
pub mod ros_map;
pub mod sim_report;
pub mod urg_emu;
pub mod walker;
pub mod world;
