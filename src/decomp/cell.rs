//! The cells the decomposition hands to the planner: polygons in the world
//! frame with stable ids (cell inheritance), an open/final state, and the
//! adjacency graph between them.

use nalgebra::Point2;

use crate::geom::Segment;

/// Stable identity of a cell across map updates (inherited by the cell that
/// replaces it when the explored area grows).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CellId(pub u32);

/// Lifecycle of a cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellStatus {
    /// Touches unexplored space: it may still grow.
    Open,
    /// Fully bounded by seen walls or other cells but its size still changes
    /// between updates.
    Settling,
    /// Width and length stable over the configured number of updates: ready to cover.
    Final,
}

/// One cell of the decomposition.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// Stable id.
    pub id: CellId,
    /// Boundary, counter-clockwise, world frame (m). A curved side is a polyline.
    pub polygon: Vec<Point2<f64>>,
    /// Lifecycle state.
    pub status: CellStatus,
    /// Sweep direction of the lanes in this cell (rad, world frame).
    pub sweep_angle: f64,
    /// Extent across the sweep (m), used for finality checks and lane counts.
    pub width: f64,
    /// Extent along the sweep (m).
    pub length: f64,
}

/// Two cells that share a boundary the robot can cross.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adjacency {
    /// One cell.
    pub a: CellId,
    /// The other cell.
    pub b: CellId,
    /// The shared boundary (m).
    pub boundary: Segment,
}

/// A decomposition of the explored free space at one map update.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Decomposition {
    /// The cells.
    pub cells: Vec<Cell>,
    /// Which cells touch.
    pub adjacency: Vec<Adjacency>,
    /// Dominant wall direction the sweep follows (rad).
    pub sweep_angle: f64,
}

impl Decomposition {
    /// The cell with id `id`, if present.
    pub fn cell(&self, id: CellId) -> Option<&Cell> {
        self.cells.iter().find(|c| c.id == id)
    }
}
