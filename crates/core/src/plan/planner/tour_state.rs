//! The lane tour's state: whether the room has been toured, whether the
//! current task is a tour, which of its floor an interruption is charged
//! to, and the targets of the last decision it watches for new floor.
//!
//! Once no cell touches unexplored space, what is left is driven in one
//! tour lane by lane ([`crate::plan::tour`]); floor seen near the robot
//! during it takes the tour again from there. Those decisions need to
//! remember a little across updates, kept here.

/// What the planner remembers of lane tours.
#[derive(Default)]
pub(crate) struct TourState {
    /// A lane tour has been taken: the room was explored once.
    pub(crate) toured: bool,
    /// The current task is a lane tour (see `CoveragePlanner::take_lane_tour`).
    pub(crate) touring: bool,
    /// Of a lane tour's targets, how many (first) are the floor of the
    /// region it drives to first: all an interruption before any progress
    /// is charged to.
    pub(crate) first: usize,
    /// The next decision takes a lane tour again for new floor near the
    /// robot: its regions were counted by the tour before.
    pub(crate) retour: bool,
    /// Per cell: a target as last computed, i.e. at the last decision (see
    /// `CoveragePlanner::new_floor_near`).
    pub(crate) decided: Vec<bool>,
}

impl TourState {
    /// Fits the record of the last decision to a grid of `n` cells: nothing
    /// counts as new floor until the next decision.
    pub fn fit(&mut self, n: usize) {
        self.decided = vec![true; n];
    }

    /// A tour begins whose first region holds the first `first` targets.
    pub(crate) fn begin(&mut self, first: usize) {
        self.touring = true;
        self.first = first;
    }

    /// A new task begins (the tour, if one was driven, ends).
    pub(crate) fn end(&mut self) {
        self.touring = false;
        self.retour = false;
    }

    /// Of `targets` targets of the task that ends, how many (first) an
    /// interruption is charged to: on a tour only its first region's (it
    /// stopped on its way there: that region is at fault, not the whole
    /// room's floor).
    pub(crate) fn at_fault(&self, targets: usize) -> usize {
        if self.touring {
            self.first.min(targets)
        } else {
            targets
        }
    }
}
