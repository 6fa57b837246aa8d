//! Scratch buffers the planner reuses between decisions, so that a
//! decision allocates little. None holds state from one use to the next:
//! each is cleared (or left cleared) by the function that uses it.

/// Buffers reused between decisions.
#[derive(Default)]
pub(crate) struct Scratch {
    /// Per cell: the admissible centres of the region being laid out.
    pub(crate) admissible: Vec<bool>,
    /// Per cell: the targets of the region being laid out.
    pub(crate) targets: Vec<bool>,
    /// The frontier cells of the map.
    pub(crate) frontier: Vec<usize>,
    /// Of `CoveragePlanner::new_floor_near`: cells reached, cells counted
    /// (all false between uses), and its queue.
    pub(crate) near_reached: Vec<bool>,
    pub(crate) near_counted: Vec<bool>,
    pub(crate) near_queue: Vec<usize>,
    /// Travel costs between lane ends of the last lane tour.
    pub(crate) tour_costs: Vec<f64>,
}

impl Scratch {
    /// Fits the per-cell buffers to a grid of `n` cells.
    pub fn fit(&mut self, n: usize) {
        self.near_reached = vec![false; n];
        self.near_counted = vec![false; n];
        self.admissible = vec![false; n];
        self.targets = vec![false; n];
    }
}
