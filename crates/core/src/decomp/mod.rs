//! Adaptive (online) boustrophedon cell decomposition with virtual edges and
//! cell inheritance (paper-notes §4).
//!
//! [`Decomposer::update`] takes the explored-area evidence grid (and, when the
//! map has them, wall segments) and returns a [`Decomposition`]:
//!
//! 1. **Direction.** The lanes follow the dominant wall direction (segments
//!    if given, else the Sobel gradients of the occupied cells, averaged mod
//!    90°), along whichever of the two axes the explored floor is longer. It
//!    is fixed for the run once `min_wall_evidence` metres of wall are seen;
//!    no cell becomes final before that.
//! 2. **Slices of the configuration space.** The grid is resampled into the
//!    lane frame (slices `resolution` apart). Every seen wall blocks the
//!    places the robot's *centre* cannot be: an occupied grid cell blocks its
//!    whole square grown by the robot radius plus `inflation_margin` (a
//!    rounded square, the same rule as the planner's C-space), a point of a
//!    segment blocks the disk around it. Blocked intervals are exact floats
//!    along each slice, so cell sides are not pixel staircases. **Cells are
//!    therefore in C-space: the planner must not inflate them again.**
//! 3. **Events.** Free intervals of consecutive slices that overlap one to
//!    one continue a cell. A change of connectivity (an interval appears,
//!    ends, splits or merges: a critical point, e.g. an obstacle's edge) or
//!    an isolated wall step of at least `step_split` (a reflex corner of a
//!    rectilinear room) starts new cells; the slice boundary where that
//!    happens is the critical edge extended along the lanes until it meets
//!    walls or unexplored space: a *virtual edge* (the adjacency boundaries).
//!    Every cell has exactly one interval per slice, so every lane inside a
//!    cell is one unbroken segment. Cells thinner than `min_cell_width` or
//!    smaller than `min_cell_area` are merged into the neighbour above or
//!    below (which keeps that property).
//! 4. **State and inheritance.** A cell with at least `min_frontier` of
//!    boundary on unexplored space is `Open` (its [`Frontier`]s say where).
//!    Each update the new cells inherit the ids of the old cells they overlap
//!    most (greedy by overlap, each old id used once; ids are never reused).
//!    A closed cell whose width and length change by at most
//!    `size_tolerance` over `stable_updates` consecutive updates becomes
//!    `Final`: its polygon is frozen, it is never recomposed, and the space
//!    around it is decomposed without it.
//!
//! Cost per update is linear in the explored window of the grid (resampling,
//! gap filling, wall points, and for a frame aligned with the grid the
//! inflation too: each column's distance to its nearest wall cell) plus the
//! pieces; wall points off the lattice (segments, a turned frame) add wall
//! points × slices within the inflation. No step looks at the history
//! beyond the previous update's cells. [`Decomposer::phase_times`] says
//! where an update's time went. Deterministic: the same inputs give the
//! same output.
pub mod cell;
mod decomposer;
pub mod direction;
pub mod frame;
mod labels;
mod polygon;
pub mod raster;
mod rows;
pub mod slices;
pub mod svg;
pub mod sweep;

/// Where the time of one [`Decomposer::update`] went (wall clock), step by
/// step: what a benchmark or a run report shows to say which step to make
/// faster. Measuring costs a clock read per step; the output never depends
/// on it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseTimes {
    /// Lane direction.
    pub direction: std::time::Duration,
    /// Grid resampled into the lane frame.
    pub(crate) resample: std::time::Duration,
    /// Short unknown gaps filled.
    pub gaps: std::time::Duration,
    /// Wall points collected.
    pub wall_points: std::time::Duration,
    /// Wall points inflated into blocked intervals.
    pub(crate) inflate: std::time::Duration,
    /// Free pieces cut from the slices.
    pub pieces: std::time::Duration,
    /// Sweep over the slices into cells.
    pub sweep: std::time::Duration,
    /// Ids inherited, polygons and adjacency published.
    pub(crate) inherit: std::time::Duration,
}

impl PhaseTimes {
    /// Every step with its name, in the order an update runs them.
    pub fn steps(&self) -> [(&'static str, std::time::Duration); 8] {
        [
            ("direction", self.direction),
            ("resample", self.resample),
            ("gaps", self.gaps),
            ("wall points", self.wall_points),
            ("inflate", self.inflate),
            ("pieces", self.pieces),
            ("sweep", self.sweep),
            ("inherit", self.inherit),
        ]
    }
}

/// A stopwatch read step by step.
struct Lap(std::time::Instant);

impl Lap {
    fn start() -> Self {
        Self(std::time::Instant::now())
    }

    /// Time since the start or the last lap.
    fn lap(&mut self) -> std::time::Duration {
        let now = std::time::Instant::now();
        now.duration_since(std::mem::replace(&mut self.0, now))
    }
}

pub use cell::{Adjacency, Cell, CellId, CellStatus, Decomposition, Frontier};
pub use decomposer::Decomposer;

/// Cell decomposition settings.
/// Loaded from the `[decomp]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DecompParams {
    /// Slice spacing and raster cell of the decomposition (m).
    pub resolution: f64,
    /// Safety margin added to the robot radius when inflating walls (m).
    pub inflation_margin: f64,
    /// Forced lane direction (rad, world frame); unset = dominant wall direction.
    pub sweep_angle: Option<f64>,
    /// Wall length (m) that must be seen before the sweep direction is fixed.
    pub min_wall_evidence: f64,
    /// An estimated wall direction this close to the grid's axes (rad) is
    /// snapped onto them. The default, π/4, snaps every direction: the
    /// planner's lanes run along the grid axes, and cells swept at another
    /// angle do not line up with them (a room 2.3° off the axes of a
    /// gmapping map: 31.1 % overlap instead of 26.1 %, decomposition twice
    /// as slow). Smaller values sweep the cells along the walls (the
    /// paper's method) for consumers whose lanes follow them.
    pub axis_snap: f64,
    /// A wall step at least this long between two slices starts a new cell (m).
    pub step_split: f64,
    /// Width/length change below which a cell counts as unchanged (m); from
    /// the sensor error plus the grid quantisation.
    pub size_tolerance: f64,
    /// Consecutive unchanged updates after which a closed cell becomes final.
    pub stable_updates: u32,
    /// Boundary length on unexplored space that makes a cell open (m).
    pub min_frontier: f64,
    /// Unknown gaps in a slice up to this long between explored free space
    /// are treated as free (ray gaps far from the scanner) (m).
    pub gap_fill: f64,
    /// Polygon simplification tolerance (m).
    pub simplify_tolerance: f64,
    /// Cells thinner than this across the lanes merge into the neighbour
    /// above or below (m); strips and slivers under half of it beside a
    /// final cell are left to that cell's outer lane.
    pub min_cell_width: f64,
    /// Cells smaller than this merge into the neighbour above or below;
    /// isolated ones under a 25th of it are dropped as noise (m²).
    pub min_cell_area: f64,
}

impl Default for DecompParams {
    fn default() -> Self {
        Self {
            resolution: 0.05,
            inflation_margin: 0.0,
            sweep_angle: None,
            min_wall_evidence: 1.0,
            axis_snap: std::f64::consts::FRAC_PI_4,
            step_split: 0.25,
            size_tolerance: 0.10,
            stable_updates: 3,
            min_frontier: 0.15,
            gap_fill: 0.15,
            simplify_tolerance: 0.02,
            min_cell_width: 0.30,
            min_cell_area: 0.25,
        }
    }
}

/// Why a decomposer could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecompError {
    /// A setting is out of its allowed range.
    #[error("decomp.{key}: {message}")]
    BadParam {
        /// The key in the `[decomp]` table.
        key: &'static str,
        /// What is wrong and what is allowed.
        message: String,
    },
}

fn check(key: &'static str, ok: bool, message: impl Into<String>) -> Result<(), DecompError> {
    if ok {
        Ok(())
    } else {
        Err(DecompError::BadParam {
            key,
            message: message.into(),
        })
    }
}

impl DecompParams {
    /// Checks every value range, naming the key that is wrong.
    pub fn validate(&self) -> Result<(), DecompError> {
        let fin = |v: f64| v.is_finite();
        check(
            "resolution",
            fin(self.resolution) && (0.005..=0.5).contains(&self.resolution),
            format!("must be within 0.005..0.5 m, got {}", self.resolution),
        )?;
        check(
            "inflation_margin",
            fin(self.inflation_margin) && (0.0..=1.0).contains(&self.inflation_margin),
            format!("must be within 0..1 m, got {}", self.inflation_margin),
        )?;
        if let Some(a) = self.sweep_angle {
            check("sweep_angle", fin(a), format!("must be finite, got {a}"))?;
        }
        for (key, v) in [
            ("min_wall_evidence", self.min_wall_evidence),
            ("axis_snap", self.axis_snap),
            ("step_split", self.step_split),
            ("size_tolerance", self.size_tolerance),
            ("min_frontier", self.min_frontier),
            ("gap_fill", self.gap_fill),
            ("simplify_tolerance", self.simplify_tolerance),
            ("min_cell_width", self.min_cell_width),
            ("min_cell_area", self.min_cell_area),
        ] {
            check(
                key,
                fin(v) && v >= 0.0,
                format!("must be a finite number >= 0, got {v}"),
            )?;
        }
        check(
            "stable_updates",
            self.stable_updates >= 1,
            "must be at least 1",
        )?;
        Ok(())
    }
}
