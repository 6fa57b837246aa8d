//! sweepline's algorithms and the plain data they work on: no ports, no
//! threads, no clocks of their own, deterministic for the same input.
//!
//! * plain data: [`geom`] (poses, points, segments), [`scan`] (a laser
//!   scan's beams and timing), [`grid`] (the explored-area evidence grid),
//!   [`robot`] (the robot's body, wheels and scanner mount), [`base`]
//!   (wheel set-points, odometry increments, bumper sides);
//! * [`icp`]: the intensity-ICP matcher and the keyframe tracker;
//! * [`map`]: the paper's point map, merge rule, line features and
//!   segment correction;
//! * [`decomp`]: the online boustrophedon cell decomposition;
//! * [`plan`]: lanes, the cell tour, transits, the configuration space,
//!   the coverage planner;
//! * [`control`]: the path follower and the protective field;
//! * [`checks`]: what the daemon checks beside its stages (the scanner's
//!   mount, the frame's alignment, contact marks, relocalisation, the
//!   stuck watch);
//! * [`param_check`]: the checks each `*Params` table makes of itself;
//! * [`stored`]: compact serde forms for the state a daemon checkpoints.
//!
//! It uses no other sweepline crate: the drivers (`sweepline-io`), the
//! daemon (`sweepline-daemon`) and the simulator sit above it, and the
//! codecs (`sweepline-wire`) beside it, so the crate graph keeps DESIGN.md's
//! rule that no layer calls upward.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod base;
pub mod capacity;
pub mod checks;
pub mod control;
pub mod decomp;
pub mod geom;
pub mod grid;
pub mod icp;
pub mod map;
pub mod param_check;
pub mod plan;
pub mod robot;
pub mod scan;
pub mod stored;
pub mod svg_canvas;
