//! sweepline's algorithms and the plain data they work on: no ports, no
//! threads, no clocks of their own, deterministic for the same input.
//!
//! * plain data: [`geom`] (poses, points, segments), [`scan`] (a laser
//!   scan's beams and timing), [`grid`] (the explored-area evidence grid),
//!   [`robot`] (the robot's body, wheels and scanner mount);
//! * [`icp`]: the intensity-ICP matcher and the keyframe tracker;
//! * [`map`]: the paper's point map, merge rule, line features and
//!   segment correction;
//! * [`decomp`]: the online boustrophedon cell decomposition;
//! * [`plan`]: lanes, the cell tour, transits, the configuration space,
//!   the coverage planner;
//! * [`control`]: the path follower and the protective field;
//! * [`param_check`]: the checks each `*Params` table makes of itself.
//!
//! It sits above `sweepline-wire` (the codecs) and below the drivers, the
//! pipeline and the daemon (the `sweepline` crate), and depends on neither:
//! the crate graph keeps DESIGN.md's rule that no layer calls upward.

pub mod capacity;
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
pub mod svg_canvas;
