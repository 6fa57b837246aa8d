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

/// A stretch of a cell's boundary where explored free space meets unexplored
/// space: where the cell may still grow, and where exploring should look.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frontier {
    /// The open cell this frontier belongs to.
    pub cell: CellId,
    /// The frontier stretch (m), approximated by one segment.
    pub boundary: Segment,
}

/// A decomposition of the explored free space at one map update.
///
/// Cells live in the robot's configuration space: every point of a cell is a
/// place the robot's *centre* can be without touching a seen wall (walls and
/// obstacles are already inflated by the robot radius plus a margin). The
/// planner lays lanes inside the polygons without offsetting them again.
/// Cell sides are exact on every slice (slices `resolution` apart); between
/// slices, where a side is curved or steps, a vertex may come up to half a
/// slice closer to a wall than the inflation (raise `inflation_margin` by half
/// the resolution for a strict guarantee).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Decomposition {
    /// The cells.
    pub cells: Vec<Cell>,
    /// Which cells touch.
    pub adjacency: Vec<Adjacency>,
    /// Dominant wall direction the sweep follows (rad).
    pub sweep_angle: f64,
    /// Where open cells meet unexplored space.
    pub frontiers: Vec<Frontier>,
    /// Virtual edges: critical edges extended along the sweep direction, the
    /// cell boundaries that are not walls (m).
    pub(crate) virtual_edges: Vec<Segment>,
    /// Distance by which seen walls were inflated to get the cells (m).
    pub inflation: f64,
}

impl Decomposition {
    /// The cell with id `id`, if present.
    pub fn cell(&self, id: CellId) -> Option<&Cell> {
        self.cells.iter().find(|c| c.id == id)
    }

    /// The cell whose polygon contains `p`, if any.
    pub fn cell_at(&self, p: &Point2<f64>) -> Option<CellId> {
        self.cells
            .iter()
            .find(|c| polygon_contains(&c.polygon, p))
            .map(|c| c.id)
    }

    /// The ids of the cells adjacent to `id`.
    pub fn neighbours(&self, id: CellId) -> impl Iterator<Item = CellId> + '_ {
        self.adjacency.iter().filter_map(move |a| {
            if a.a == id {
                Some(a.b)
            } else if a.b == id {
                Some(a.a)
            } else {
                None
            }
        })
    }
}

impl Cell {
    /// Area of the polygon (m²).
    pub fn area(&self) -> f64 {
        polygon_area(&self.polygon)
    }

    /// Whether `p` lies inside the polygon.
    pub fn contains(&self, p: &Point2<f64>) -> bool {
        polygon_contains(&self.polygon, p)
    }
}

/// Signed area of a polygon (m², positive when counter-clockwise).
pub(crate) fn polygon_area(poly: &[Point2<f64>]) -> f64 {
    let n = poly.len();
    if n < 3 {
        return 0.0;
    }
    // Relative to the first vertex: exact enough far from the origin too.
    let o = poly[0];
    (1..n - 1)
        .map(|i| {
            let (a, b) = (poly[i] - o, poly[i + 1] - o);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
        / 2.0
}

/// Even-odd point-in-polygon test (false for degenerate polygons).
pub(crate) fn polygon_contains(poly: &[Point2<f64>], p: &Point2<f64>) -> bool {
    let n = poly.len();
    if n < 3 {
        return false;
    }
    let mut inside = false;
    let mut j = n - 1;
    for i in 0..n {
        let (a, b) = (poly[i], poly[j]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            inside = !inside;
        }
        j = i;
    }
    inside
}
