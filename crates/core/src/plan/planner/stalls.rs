//! Stalls and waits: the counters by which the planner notices it is
//! getting nowhere (boxed in, ways out in a row, exploration moves that
//! show nothing) and the waits it begins for the map to clear.
//!
//! Each bounds a loop the map's noise could otherwise keep going for ever:
//! kept together since none of them is the record of the floor, only of
//! the planner's own course.

/// The planner's counters of getting nowhere, and its waits.
#[derive(Default)]
pub(crate) struct Stalls {
    /// Consecutive updates that found the robot boxed in (see
    /// `BOXED_IN_UPDATES`).
    pub(crate) boxed_in: usize,
    /// Ways out planned since the last cover or explore task (see
    /// `MAX_WAYS_OUT`).
    pub(crate) ways_out_in_a_row: usize,
    /// Seen-free cells when the current exploration move began.
    pub(crate) free_at_explore: usize,
    /// Exploration moves in a row that showed little new floor (see
    /// `MAX_FRUITLESS_EXPLORES`).
    pub(crate) fruitless_explores: usize,
    /// The surface hold (`PlanParams::surface_hold`) ended: nothing was
    /// left to do once.
    pub(crate) hold_ended: bool,
    /// When the robot began to wait for walled-off floor to clear (see
    /// `PlanParams::clear_wait`; planner clock, s); `None` when not
    /// waiting.
    pub(crate) wait_since: Option<f64>,
}

impl Stalls {
    /// Counts the exploration move just ended, which left `known_free`
    /// seen-free cells: fruitless when it showed fewer than `fruitful` new
    /// ones. True when it is the `max`-th fruitless move in a row (the
    /// count starts over).
    pub(crate) fn explore_ended(&mut self, known_free: usize, fruitful: usize, max: usize) -> bool {
        if known_free >= self.free_at_explore + fruitful {
            self.fruitless_explores = 0;
            return false;
        }
        self.fruitless_explores += 1;
        if self.fruitless_explores < max {
            return false;
        }
        self.fruitless_explores = 0;
        true
    }
}
