//! Fixtures shared by the unit tests of the planner and of its checkpoint
//! sections: a small walled room and a planner that skips the look-around.

use nalgebra::Point2;

use crate::config::RobotParams;
use crate::grid::{CellState, Grid};
use crate::plan::{CoveragePlanner, PlanParams};

/// A 3 m × 2 m room (0.05 m cells) with one-cell walls all round.
pub(crate) fn walled_room() -> Grid {
    room_with(60, 40, |_, _| false)
}

/// A room of `w` × `h` cells of 0.05 m, seen whole: one-cell walls all
/// round, and occupied wherever `inside(x, y)` holds.
pub(crate) fn room_with(w: usize, h: usize, inside: impl Fn(usize, usize) -> bool) -> Grid {
    let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, w, h);
    for y in 0..h {
        for x in 0..w {
            let wall = x == 0 || y == 0 || x + 1 == w || y + 1 == h;
            let s = if wall || inside(x, y) {
                CellState::Occupied
            } else {
                CellState::Free
            };
            g.set_state((x, y), s);
        }
    }
    g
}

/// A planner with the default robot that starts covering at once.
pub(crate) fn planner() -> CoveragePlanner {
    let params = PlanParams {
        look_around: false,
        ..PlanParams::default()
    };
    CoveragePlanner::new(&params, &RobotParams::default()).unwrap()
}
