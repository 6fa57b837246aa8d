//! Intensity-ICP scan registration (pure, deterministic, allocation-free in
//! steady state).
//!
//! The paper's error is `E = Σ dx² + dy² + w·dl²` (`../shared/paper-notes.md`
//! §1): correspondences are nearest neighbours in (x, y, √w·l) space, so a
//! point pairs with a point that is close *and* equally reflective. With
//! `w = 0` this is exactly point-to-point ICP.
//!
//! - [`Reference`]: the point set matched against (a scan, a keyframe window,
//!   the mapping layer's map), with normals and a k-d tree.
//! - [`Matcher`]: one match, with gate, trimming, point-to-point or
//!   point-to-line solve and a [`Quality`] report.
//! - [`KeyframeMap`] and [`Tracker`]: scan-to-map tracking over a sequence.
//! - [`synth`]: synthetic scans of wall segments, for tests and benchmarks.
//!
//! The evaluation against a log's relations (Kümmerle et al. 2009) is
//! tooling with file input: `sweepline::sim::eval`.

mod correlative;
mod error;
mod local_map;
mod matcher;
mod params;
mod reference;
pub mod synth;
mod tracker;

pub use correlative::{CorrelativeSearch, SearchHit, SearchParams};
pub use error::IcpError;
pub use local_map::{KeyframeMap, KeyframeState};
pub use matcher::{Match, Matcher, Quality, Rejection};
pub use params::{IcpParams, Metric, Prior, MAX_KEYFRAMES};
pub use reference::Reference;
pub use tracker::{Outcome, SearchCounts, Step, Tracker, TrackerState};
