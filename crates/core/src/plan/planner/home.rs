//! The drive back to where the robot started once coverage is done
//! (`plan.return_home`): an operator finds the robot where they put it down,
//! and a robot started from its dock ends beside it.
//!
//! The way back is a travel path over the known free space, planned again
//! when something seen since blocks it (the same check as every path) and
//! after an escape from an inflation zone. Floor seen on the way is not
//! covered: coverage was declared done. The drive ends within
//! [`HOME_NEAR`] of the start, facing the start heading.

use nalgebra::Point2;

use super::{cells_within, CoveragePlanner, DoneReport, Motion, PlanError, PlanStatus, Task};
use crate::geom::{heading, Pose};
use crate::plan::cspace::disk;
use crate::plan::HomePlace;

/// A robot this near its start (m) when coverage is done is home already:
/// a path that short would be a shuffle of a few centimetres.
pub const HOME_NEAR: f64 = 0.15;

/// Farthest (m) from the start the way back may end when the start itself
/// is out of the traversable space (something stands there now, or the
/// robot was put down inside an obstacle's inflation zone).
pub const HOME_REACH: f64 = 0.6;

/// Ways back planned at most (blocked again and again, escapes between):
/// after that the robot stays where it is.
pub const MAX_HOME_PLANS: usize = 20;

/// How the drive back to the start ended.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HomeOutcome {
    /// Not asked for (`plan.return_home` off), or the start is unknown (a
    /// checkpoint written before the start was recorded).
    #[default]
    NotAsked,
    /// At the start (or as near as the free space allows).
    Back,
    /// No way over the known free space leads there.
    NoWay,
    /// The way was blocked [`MAX_HOME_PLANS`] times.
    GaveUp,
}

impl HomeOutcome {
    /// A few words for reports.
    pub fn describe(self) -> &'static str {
        match self {
            HomeOutcome::NotAsked => "not asked",
            HomeOutcome::Back => "back at the start",
            HomeOutcome::NoWay => "no way back over the known floor",
            HomeOutcome::GaveUp => "gave up: the way back was blocked again and again",
        }
    }

    /// [`Self::describe`] of a run's outcome, or "coverage not finished"
    /// when the run ended before its coverage did (no drive back began):
    /// the words every report uses.
    pub fn describe_run(outcome: Option<Self>) -> &'static str {
        outcome.map_or("coverage not finished", Self::describe)
    }
}

/// The planner's state while it drives back.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Homing {
    /// The report of the coverage just finished, handed out on arrival.
    report: DoneReport,
    /// Ways back planned so far.
    plans: usize,
    /// The current path ends at the start (or as near as the floor
    /// allows), not at a passage on the way.
    to_start: bool,
}

/// Where the robot started, and the drive back to it once coverage is done.
#[derive(Default)]
pub(crate) struct HomeState {
    /// Where the robot started (recorded at its first update, or restored).
    pub(crate) start: Option<HomePlace>,
    /// Coverage is done and the robot drives back to the start.
    pub(crate) homing: Option<Homing>,
}

impl HomeState {
    /// Restores the start recorded before a restart; a non-finite place is
    /// ignored.
    pub(crate) fn restore(&mut self, home: HomePlace) {
        if home.x.is_finite() && home.y.is_finite() && home.heading.is_finite() {
            self.start = Some(home);
        }
    }

    /// Ways back planned since coverage was done (0 when not on the way back).
    pub(crate) fn plans(&self) -> usize {
        self.homing.map_or(0, |h| h.plans)
    }

    /// Records `pose` as the start when none is known yet.
    pub(crate) fn note_start(&mut self, pose: &Pose) {
        if self.start.is_none() {
            self.start = Some(HomePlace {
                x: pose.translation.x,
                y: pose.translation.y,
                heading: heading(pose),
            });
        }
    }

    /// Distance (m) of `p` from the start, NaN when it is unknown.
    pub(crate) fn distance_to_start(&self, p: &Point2<f64>) -> f64 {
        self.start
            .map_or(f64::NAN, |s| (p - Point2::new(s.x, s.y)).norm())
    }
}

impl CoveragePlanner {
    /// Where the robot started (recorded at its first update, or restored),
    /// for a checkpoint; `None` before.
    pub fn home(&self) -> Option<HomePlace> {
        self.home.start
    }

    /// Restores the start recorded before a restart: the robot drives back
    /// there, not to where it was resumed. A non-finite place is ignored.
    pub fn restore_home(&mut self, home: HomePlace) {
        self.home.restore(home);
    }

    /// Ways back planned since coverage was done (0 when not on the way
    /// back): 1 on the update that planned the first.
    pub fn home_plans(&self) -> usize {
        self.home.plans()
    }

    /// Coverage is done with `report`: drive back to the start when asked
    /// to, else finish.
    pub(super) fn coverage_done(
        &mut self,
        report: DoneReport,
        pose: &Pose,
        robot: usize,
    ) -> Result<PlanStatus, PlanError> {
        if !self.params.return_home || self.home.start.is_none() {
            let p: Point2<f64> = pose.translation.vector.into();
            return Ok(self.finish(report, HomeOutcome::NotAsked, &p));
        }
        self.home.homing = Some(Homing {
            report,
            plans: 0,
            to_start: false,
        });
        self.plan_home(pose, robot)
    }

    /// One update on the way back: arrived at the end of the path, planning
    /// again when `replan` (blocked, escaped, interrupted), else driving on.
    pub(super) fn home_update(
        &mut self,
        pose: &Pose,
        robot: usize,
        arrived: bool,
        replan: bool,
    ) -> Result<PlanStatus, PlanError> {
        let to_start = self.home.homing.is_some_and(|h| h.to_start);
        if arrived && self.current.task == Task::Home && to_start {
            return Ok(self.home_reached(pose));
        }
        if !replan && !arrived {
            return Ok(self.driving_on());
        }
        self.plan_home(pose, robot)
    }

    /// Plans the way back from `pose` (cell `robot`), or finishes when the
    /// robot is home, has no way there, or has planned too many.
    fn plan_home(&mut self, pose: &Pose, robot: usize) -> Result<PlanStatus, PlanError> {
        let (Some(home), Some(h)) = (self.home.start, self.home.homing.as_mut()) else {
            return Ok(self.driving_on());
        };
        let p: Point2<f64> = pose.translation.vector.into();
        let at = Point2::new(home.x, home.y);
        if (p - at).norm() <= HOME_NEAR {
            return Ok(self.home_reached(pose));
        }
        h.plans += 1;
        h.to_start = false;
        let plans = h.plans;
        if plans > MAX_HOME_PLANS {
            log::warn!(
                "the way back to the start at ({:.2}, {:.2}) m was blocked {MAX_HOME_PLANS} times: staying at ({:.2}, {:.2}) m, {:.2} m from it",
                at.x,
                at.y,
                p.x,
                p.y,
                (p - at).norm()
            );
            return Ok(self.home_ends(HomeOutcome::GaveUp, &p));
        }
        if !self.cspace.traversable[robot] {
            // Coverage is done: there is no task to forgive.
            return self.escape(&p, robot, false);
        }
        // Plain distance: the drive back sweeps nothing that counts.
        self.cspace.set_extra_cost(|_| 0.0);
        self.cspace.distances_from(robot);
        let goal = self.home_goal(&at);
        if goal.is_none() {
            if let Some(path) = self.home_way_out(robot, &at) {
                log::info!(
                    "the way back to the start at ({:.2}, {:.2}) m leads through a passage only the bare body fits (plan.way_out_passage)",
                    at.x,
                    at.y
                );
                self.set_task(Task::Home, path, None);
                return Ok(PlanStatus::Working {
                    task: Task::Home,
                    new_path: true,
                });
            }
        }
        let Some(goal) = goal else {
            log::warn!(
                "no way back to the start at ({:.2}, {:.2}) m over the known floor (nothing within {HOME_REACH} m of it is reachable): staying at ({:.2}, {:.2}) m",
                at.x,
                at.y,
                p.x,
                p.y
            );
            return Ok(self.home_ends(HomeOutcome::NoWay, &p));
        };
        let f = self.cspace.frame;
        let mut path = self.cspace.path_to(goal).unwrap_or_default();
        if !path.is_empty() {
            path.remove(0);
        }
        // The last waypoint on the start itself when the cell holding it is
        // the goal (the cell's centre is up to half a cell off).
        let end = if f.index_of(&at) == Some(goal) {
            at
        } else {
            f.centre(goal)
        };
        match path.last_mut() {
            Some(last) => *last = end,
            None => path.push(end),
        }
        if plans == 1 {
            log::info!(
                "coverage done: driving back to the start at ({:.2}, {:.2}) m, {:.1} m of travel",
                at.x,
                at.y,
                self.cspace.dist[goal]
            );
        }
        if let Some(h) = self.home.homing.as_mut() {
            h.to_start = true;
        }
        self.set_task(Task::Home, path, Some(home.heading));
        Ok(PlanStatus::Working {
            task: Task::Home,
            new_path: true,
        })
    }

    /// The traversable cell the way back ends in: the start's own cell when
    /// the robot can get there, else the reachable cell nearest the start
    /// within [`HOME_REACH`].
    fn home_goal(&self, at: &Point2<f64>) -> Option<usize> {
        let f = self.cspace.frame;
        let reachable = |i: usize| self.cspace.dist[i].is_finite();
        if let Some(i) = f.index_of(at).filter(|&i| reachable(i)) {
            return Some(i);
        }
        // Offsets one cell wider than the reach: the start is anywhere in
        // its cell; `cells_within` keeps the centres within the reach.
        let offsets = disk(HOME_REACH + f.res, f.res);
        let mut best: Option<(f64, usize)> = None;
        for i in cells_within(f, at, &offsets, HOME_REACH) {
            let d = (f.centre(i) - at).norm();
            if reachable(i) && best.is_none_or(|(b, _)| d < b) {
                best = Some((d, i));
            }
        }
        best.map(|(_, i)| i)
    }

    /// With `plan.way_out_passage`, the way through a passage only the bare
    /// body fits to the part of the space holding the start (the robot came
    /// the other way through it); `None` without one. The last
    /// [`Self::home_goal`] search must be from `robot`.
    fn home_way_out(&self, robot: usize, at: &Point2<f64>) -> Option<Vec<Point2<f64>>> {
        let max_tight = self.params.way_out_passage;
        if max_tight <= 0.0 {
            return None;
        }
        let f = self.cspace.frame;
        let reachable: Vec<bool> = self.cspace.dist.iter().map(|d| d.is_finite()).collect();
        crate::plan::unbox::way_out(&self.cspace, robot, &reachable, max_tight, |part| {
            part.iter()
                .any(|&i| (f.centre(i) - at).norm() <= HOME_REACH)
        })
    }

    fn home_reached(&mut self, pose: &Pose) -> PlanStatus {
        let p: Point2<f64> = pose.translation.vector.into();
        if let Some(home) = self.home.start {
            log::info!(
                "back at the start: ({:.2}, {:.2}) m, {:.2} m from where it started",
                p.x,
                p.y,
                (p - Point2::new(home.x, home.y)).norm()
            );
        }
        self.home_ends(HomeOutcome::Back, &p)
    }

    fn home_ends(&mut self, outcome: HomeOutcome, p: &Point2<f64>) -> PlanStatus {
        let Some(h) = self.home.homing.take() else {
            return self.driving_on();
        };
        self.finish(h.report, outcome, p)
    }

    /// The status of an update that keeps the current path.
    fn driving_on(&self) -> PlanStatus {
        PlanStatus::Working {
            task: self.current.task,
            new_path: false,
        }
    }

    /// Ends the run with `report`, the drive back ended by `outcome` with
    /// the robot at `p`.
    fn finish(
        &mut self,
        mut report: DoneReport,
        outcome: HomeOutcome,
        p: &Point2<f64>,
    ) -> PlanStatus {
        report.home = outcome;
        report.home_distance = self.home.distance_to_start(p);
        self.report = Some(report);
        self.set_task(Task::Done, Vec::new(), None);
        PlanStatus::Done(report)
    }
}

/// The motion recorded for a path of `task` made of travel alone.
pub(super) fn travel_motion(task: Task) -> Motion {
    match task {
        Task::Explore => Motion::Explore,
        Task::Home => Motion::Home,
        _ => Motion::Other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;
    use crate::grid::CellState;
    use crate::plan::test_support::{follow_to_done, planner, room_with, walled_room};
    use crate::plan::PlanParams;
    use crate::robot::RobotParams;

    /// The end of the last way back planned, and how many were planned.
    fn ways_back(p: &CoveragePlanner) -> (Option<Point2<f64>>, usize) {
        let homes: Vec<_> = p
            .history()
            .iter()
            .filter(|t| t.task == Task::Home)
            .collect();
        (
            homes.last().and_then(|t| t.path.last().copied()),
            homes.len(),
        )
    }

    #[test]
    fn coverage_done_the_robot_drives_back_to_its_start_and_faces_its_heading() {
        let grid = walled_room();
        let start = pose(0.5, 0.4, 1.0);
        let mut p = planner();
        let (r, tasks) = follow_to_done(&mut p, &grid, start, 400).expect("done");
        assert_eq!(tasks.last(), Some(&Task::Home), "{tasks:?}");
        assert_eq!(r.home, HomeOutcome::Back);
        assert!(r.home_distance < 1e-9, "{r:?}");
        let (end, n) = ways_back(&p);
        assert_eq!(n, 1);
        assert!((end.unwrap() - Point2::new(0.5, 0.4)).norm() < 1e-9);
        // The way back is all travel the metrics count apart.
        let last = p.history().last().unwrap();
        assert_eq!(last.task, Task::Done);
        assert!(p.motions().is_empty());

        // Off: the run ends where coverage ends, the report says so.
        let params = PlanParams {
            look_around: false,
            return_home: false,
            ..PlanParams::default()
        };
        let mut q = CoveragePlanner::new(&params, &RobotParams::default()).unwrap();
        let (r, tasks) = follow_to_done(&mut q, &grid, start, 400).expect("done");
        assert!(!tasks.contains(&Task::Home), "{tasks:?}");
        assert_eq!(r.home, HomeOutcome::NotAsked);
        assert!(r.home_distance > HOME_NEAR, "{r:?}");
    }

    #[test]
    fn a_robot_that_ends_near_its_start_does_not_shuffle_there() {
        let grid = walled_room();
        let mut p = planner();
        let start = pose(1.5, 1.0, 0.0);
        p.update(
            &grid,
            &crate::decomp::Decomposition::default(),
            &start,
            None,
        )
        .unwrap();
        p.home.homing = Some(Homing {
            report: DoneReport::default(),
            plans: 0,
            to_start: false,
        });
        let near = pose(1.5 + 0.8 * HOME_NEAR, 1.0, 2.0);
        let robot = p.cspace.frame.index_of(&Point2::new(1.62, 1.0)).unwrap();
        match p.plan_home(&near, robot).unwrap() {
            PlanStatus::Done(r) => {
                assert_eq!(r.home, HomeOutcome::Back);
                assert!((r.home_distance - 0.8 * HOME_NEAR).abs() < 1e-9);
            }
            st => panic!("{st:?}"),
        }
    }

    #[test]
    fn a_start_inside_an_inflation_zone_is_approached_as_near_as_the_floor_allows() {
        // Put down 0.1 m from two walls: inside the 0.18 m clearance.
        let grid = walled_room();
        let start = pose(0.15, 0.15, 0.0);
        let mut p = planner();
        let (r, tasks) = follow_to_done(&mut p, &grid, start, 400).expect("done");
        assert_eq!(tasks.last(), Some(&Task::Home), "{tasks:?}");
        assert_eq!(r.home, HomeOutcome::Back);
        let (end, _) = ways_back(&p);
        let d = (end.unwrap() - Point2::new(0.15, 0.15)).norm();
        assert!(d > 0.05 && d <= HOME_REACH, "ended {d} m from the start");
        assert!((r.home_distance - d).abs() < 1e-9, "{r:?} {d}");
    }

    #[test]
    fn a_start_walled_off_since_leaves_the_robot_where_it_is() {
        // Covered with the room open; then a wall across the middle (a
        // closed door) shuts the start off from the robot.
        let open = walled_room();
        let shut = room_with(60, 40, |x, _| x == 30);
        let mut p = planner();
        let start = pose(0.5, 1.0, 0.0);
        let empty = crate::decomp::Decomposition::default();
        p.update(&open, &empty, &start, None).unwrap();
        let far = pose(2.5, 1.0, 0.0);
        let robot = p.cspace.frame.index_of(&Point2::new(2.5, 1.0)).unwrap();
        p.cspace.rebuild(&shut);
        p.home.homing = Some(Homing {
            report: DoneReport::default(),
            plans: 0,
            to_start: false,
        });
        match p.plan_home(&far, robot).unwrap() {
            PlanStatus::Done(r) => {
                assert_eq!(r.home, HomeOutcome::NoWay);
                assert!((r.home_distance - 2.0).abs() < 1e-9, "{r:?}");
            }
            st => panic!("{st:?}"),
        }
    }

    #[test]
    fn a_way_back_blocked_again_and_again_is_given_up() {
        let grid = walled_room();
        let mut p = planner();
        let start = pose(0.5, 1.0, 0.0);
        let empty = crate::decomp::Decomposition::default();
        p.update(&grid, &empty, &start, None).unwrap();
        p.home.homing = Some(Homing {
            report: DoneReport::default(),
            plans: 0,
            to_start: false,
        });
        let far = pose(2.5, 1.0, std::f64::consts::PI);
        let robot = p.cspace.frame.index_of(&Point2::new(2.5, 1.0)).unwrap();
        let first = p.plan_home(&far, robot).unwrap();
        assert!(
            matches!(
                first,
                PlanStatus::Working {
                    task: Task::Home,
                    new_path: true
                }
            ),
            "{first:?}"
        );
        // Someone steps onto the way back at every update (and off the
        // last one): each time it is planned again, until the planner gives
        // up.
        let mut outcome = None;
        for k in 0..=MAX_HOME_PLANS {
            // 0.5 m down the way (out of the robot's own clearance).
            let (path, _) = p.path();
            let mut a = Point2::new(2.5, 1.0);
            let mut left = 0.5;
            let mut at = a;
            for &b in path {
                let d = (b - a).norm();
                if d >= left {
                    at = a + (b - a) * (left / d);
                    break;
                }
                left -= d;
                a = b;
                at = b;
            }
            let mut blocked = grid.clone();
            blocked.set_state(blocked.cell_of(&at).unwrap(), CellState::Occupied);
            match p.update(&blocked, &empty, &far, Some(0)).unwrap() {
                PlanStatus::Done(r) => {
                    outcome = Some((k, r.home));
                    break;
                }
                PlanStatus::Working { task, new_path } => {
                    assert!(new_path && task == Task::Home, "{task:?} {new_path}");
                }
            }
        }
        let (k, home) = outcome.expect("given up");
        assert_eq!(home, HomeOutcome::GaveUp);
        assert_eq!(k + 1, MAX_HOME_PLANS, "given up after {} plans", k + 2);
    }
}
