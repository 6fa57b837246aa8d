//! sweepline: an onboard coverage daemon for a differential-drive robot with a
//! Hokuyo URG-04LX laser scanner.
//!
//! The crate is layered as `../shared/DESIGN.md` describes; lower layers never
//! depend on higher ones:
//!
//! 1. codecs (sans-IO): the `sweepline-wire` crate (`crates/wire`):
//!    [`scip`] and the wheel bases' codecs, re-exported here;
//! 2. drivers: the `sweepline-io` crate (`crates/io`): [`urg`], [`motor`]
//!    drivers, over [`serial`] ports and ptys, and the [`clock`], re-exported
//!    here;
//! 3. algorithms: the `sweepline-core` crate (`crates/core`): [`icp`],
//!    [`map`], [`decomp`], [`plan`], [`control`], over plain data ([`geom`],
//!    [`scan`], [`grid`], [`robot`]), re-exported here; each table of
//!    parameters checks itself with [`param_check`], so none of them
//!    depends on [`config`], which only aggregates the tables;
//! 4. the daemon: the `sweepline-daemon` crate (`crates/daemon`): the
//!    [`pipeline`] (the only layer that owns threads), the [`daemon`]'s
//!    stages, its [`config`] (which only aggregates the tables) and
//!    [`report`], re-exported here;
//! 5. simulation: the `sweepline-sim` crate (`crates/sim`), re-exported as
//!    [`sim`]: worlds, kinematics, device emulators, log replay;
//! 6. front: [`cli`] (the `sweepline` binary).

#![forbid(unsafe_code)]

pub mod capacity;
pub mod cli;
pub mod testdata;

/// Worlds, emulators, lock-step and closed-loop runs, replay and
/// evaluation, from the `sweepline-sim` crate.
pub use sweepline_sim as sim;

/// The live view, the recorder and recordings read back, from the
/// `sweepline-live` crate.
pub use sweepline_live as live;

/// The pipeline, the stages, the configuration and the report, from the
/// `sweepline-daemon` crate.
pub use sweepline_daemon::{config, daemon, pipeline, report};

/// The SCIP 2.0 codec, from the `sweepline-wire` crate.
pub use sweepline_wire::scip;

/// The drivers and the clock, from the `sweepline-io` crate.
pub use sweepline_io::{clock, motor, serial, urg};

/// The algorithms and their plain data, from the `sweepline-core` crate.
pub use sweepline_core::{
    base, check_keys, checks, control, decomp, geom, grid, icp, map, param_check, plan, robot,
    scan, svg_canvas,
};
