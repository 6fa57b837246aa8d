//! Ways out of the inflation zone: why the robot is in it, and the path
//! to the nearest place with full clearance.

use nalgebra::Point2;

use super::*;
use crate::geom::Segment;
use crate::plan::cspace::FREE;

impl CoveragePlanner {
    /// Says why the robot at `p` is out of the traversable space: what lies
    /// within its clearance, and whether the path it was on is still
    /// traversable where it passes nearest (the robot left it: tracking)
    /// or not (the map changed under it: something seen since).
    pub(super) fn log_escape_cause(&self, p: &Point2<f64>) {
        let what = match self.cspace.blocker(p) {
            Some(b) => format!(
                "{:.3} m from {} at ({:.2}, {:.2})",
                b.distance,
                b.kind.describe(),
                b.at.x,
                b.at.y
            ),
            None => "in a cell the clearance rules out".into(),
        };
        let nearest = self
            .current
            .path
            .windows(2)
            .map(|s| Segment::new(s[0], s[1]).closest_point(p))
            .min_by(|a, b| (a - p).norm().total_cmp(&(b - p).norm()));
        let path = match nearest {
            Some(q) => {
                let f = self.cspace.frame;
                let still = f.index_of(&q).is_some_and(|i| self.cspace.traversable[i]);
                format!(
                    "{:.1} cm off its path, which is {} there",
                    (q - p).norm() * 100.0,
                    if still {
                        "still traversable (the robot left it)"
                    } else {
                        "no longer traversable (seen since)"
                    }
                )
            }
            None => "on no path".into(),
        };
        log::info!(
            "escape: robot at ({:.2}, {:.2}) m is {what}, inside the {:.2} m clearance; {path}",
            p.x,
            p.y,
            self.cspace.inflation()
        );
    }

    /// Plans the escape of the robot at `p` (cell `robot`) out of an
    /// inflation zone it finds itself in, or fails with
    /// [`PlanError::Trapped`]. With `forgive`, the task it was on is not at
    /// fault (a cell seen occupied next to it, tracking error): its floor
    /// is not charged a try, up to a bound.
    pub(super) fn escape(
        &mut self,
        p: &Point2<f64>,
        robot: usize,
        forgive: bool,
    ) -> Result<PlanStatus, PlanError> {
        self.log_escape_cause(p);
        let Some(path) = self.escape_path(robot) else {
            return Err(PlanError::Trapped { x: p.x, y: p.y });
        };
        if forgive && self.may_forgive() {
            self.current.forgive();
        }
        self.stats.escapes += 1;
        self.set_task(Task::Escape, path, None);
        Ok(PlanStatus::Working {
            task: Task::Escape,
            new_path: true,
        })
    }

    /// Where the robot at cell `robot`, out of the traversable space,
    /// escapes to: the nearest traversable cell reachable over seen-free
    /// cells, found breadth first. When that cell's traversable part is
    /// smaller than the robot's footprint (an island a surface seen since
    /// left in a tight passage: the robot would be boxed in there at once,
    /// and escape again as the map changes, back and forth), the way to the
    /// nearest part at least that large over the cells the bare body fits
    /// on ([`crate::plan::unbox::way_out`]) instead; with none, the island.
    pub(super) fn escape_path(&self, robot: usize) -> Option<Vec<Point2<f64>>> {
        let f = self.cspace.frame;
        let goal = self.escape_target(robot)?;
        let need = self.swept.stamp.len();
        if self.cspace.traversable_part_holds(goal, need) {
            return Some(vec![f.centre(goal)]);
        }
        let nowhere = vec![false; f.len()];
        let Some(path) =
            crate::plan::unbox::way_out(&self.cspace, robot, &nowhere, f64::INFINITY, |part| {
                part.len() >= need
            })
        else {
            return Some(vec![f.centre(goal)]);
        };
        let end = path.last().copied().unwrap_or_else(|| f.centre(goal));
        log::info!(
            "escape: the nearest traversable floor, at ({:.2}, {:.2}) m, is an island smaller than the robot's footprint; escaping to ({:.2}, {:.2}) m instead",
            f.centre(goal).x,
            f.centre(goal).y,
            end.x,
            end.y
        );
        Some(path)
    }

    /// The nearest traversable cell to `robot` reachable over seen-free cells.
    pub(super) fn escape_target(&self, robot: usize) -> Option<usize> {
        let f = self.cspace.frame;
        let mut seen = vec![false; f.len()];
        let mut queue = std::collections::VecDeque::new();
        seen[robot] = true;
        queue.push_back(robot);
        while let Some(i) = queue.pop_front() {
            if self.cspace.traversable[i] {
                return Some(i);
            }
            let (x, y) = ((i % f.w) as i64, (i / f.w) as i64);
            for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx as usize >= f.w || ny as usize >= f.h {
                    continue;
                }
                let j = ny as usize * f.w + nx as usize;
                if !seen[j] && self.cspace.state[j] == FREE {
                    seen[j] = true;
                    queue.push_back(j);
                }
            }
        }
        None
    }
}
