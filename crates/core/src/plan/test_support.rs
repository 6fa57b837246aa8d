//! Fixtures shared by the unit tests of the planner and of its checkpoint
//! sections: a small walled room and a planner that skips the look-around.

use nalgebra::Point2;

use crate::grid::{CellState, Grid};
use crate::plan::{CoveragePlanner, PlanParams};
use crate::robot::RobotParams;

/// A 3 m × 2 m room (0.05 m cells) with one-cell walls all round.
pub fn walled_room() -> Grid {
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
pub fn planner() -> CoveragePlanner {
    let params = PlanParams {
        look_around: false,
        ..PlanParams::default()
    };
    CoveragePlanner::new(&params, &RobotParams::default()).unwrap()
}

/// Runs `p` in the seen `grid` from `start` to the end of the run with a
/// perfect follower: every path is driven to its end (the tool recorded
/// every 2 cm, the robot turned to the final heading), then the planner is
/// asked again. Returns the report and the tasks in the order planned; at
/// most `updates` updates.
pub fn follow_to_done(
    p: &mut CoveragePlanner,
    grid: &Grid,
    start: crate::geom::Pose,
    updates: usize,
) -> Option<(crate::plan::planner::DoneReport, Vec<crate::plan::Task>)> {
    use crate::plan::PlanStatus;
    let empty = crate::decomp::Decomposition::default();
    let mut at = start;
    let mut tasks = Vec::new();
    for _ in 0..updates {
        match p.update(grid, &empty, &at, None).ok()? {
            PlanStatus::Done(r) => return Some((r, tasks)),
            PlanStatus::Working { task, .. } => {
                if tasks.last() != Some(&task) {
                    tasks.push(task);
                }
            }
        }
        let (path, heading) = p.path();
        let (path, heading) = (path.to_vec(), heading);
        let mut here = Point2::from(at.translation.vector);
        for q in path {
            let d = q - here;
            let n = (d.norm() / 0.02).ceil().max(1.0) as usize;
            let th = d.y.atan2(d.x);
            for k in 1..=n {
                let c = here + d * (k as f64 / n as f64);
                p.record_pose(&crate::geom::pose(c.x, c.y, th));
            }
            here = q;
        }
        let th = heading.unwrap_or(crate::geom::heading(&at));
        at = crate::geom::pose(here.x, here.y, th);
    }
    None
}
