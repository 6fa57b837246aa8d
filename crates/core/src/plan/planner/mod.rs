//! The online coverage planner: event-driven, over the map explored so far.
//!
//! On every map update it rebuilds the configuration space; it plans a new
//! task only when the current one is finished, blocked by a newly seen
//! obstacle, or (while exploring) when a cell became final. Tasks, in order
//! of preference:
//!
//! 1. **look around** once at the start (turn in place by half a turn, so the
//!    240° scanner sees all around);
//! 2. **escape** when the robot stands inside the inflation zone of a seen
//!    obstacle: drive to the nearest place with full clearance;
//! 3. **cover a final cell**: among the decomposition's final cells with
//!    uncovered floor, the one with the least travel cost (Dijkstra over the
//!    configuration space to its best lane entry) plus a look-ahead term (the
//!    distance from its exit to the nearest other candidate), reached by the
//!    shortest transit path and covered by back-and-forth lanes; once no
//!    cell touches unexplored space (`plan.lane_tour`), the lanes of all
//!    cells left instead, in one tour ordered lane by lane ([`super::tour`]),
//!    so that a cell cut by furniture is finished on the way back;
//! 4. **explore**: when no final cell has work left, go to the nearest
//!    reachable place from which unexplored space is within view and face it;
//! 5. **clean up**: when nothing is left to explore, cover the remaining
//!    uncovered patches (floor between cells, cells that never became final,
//!    strips the lanes missed) the same way;
//! 6. **done**: nothing reachable is left; the floor seen but not reachable
//!    is reported.
//!
//! The planner keeps its own record of what the tool has swept (from the
//! poses it is given), so a cell that was partly swept by transits or by
//! neighbouring lanes only gets the lanes it still needs.
//!
//! This file holds the planner's state and its update; `choose` the choice
//! of the next task, the policy above as a sequence of named decisions.
//! The state is a few owned parts, each in its own module with its own
//! `impl`: `swept_record` what the tool has swept, `tried` the tries,
//! give-ups and floor once within reach, `tour_state` the lane tour,
//! `home` the start and the drive back to it, `current` the task being
//! driven, `region_map` the regions of the last decision and the lane
//! lattice, `stalls` the counters of getting nowhere and the waits, and
//! `scratch` buffers reused between decisions. Beside them: `status` what
//! the planner reports, `regions` the candidate regions (targets, the lane
//! lattice and who owns which floor), `order` the look-ahead order of one
//! region at a time, `cover` the lane tour (and when to take it again) and
//! the path through a task's lanes, `explore` the exploration goals, ways
//! out and what is given up, `escape` the way out of an inflation zone,
//! `end` the leftovers declined and the report at the end, and `records`
//! what a restart needs (one [`PlanSnapshot`] out, one restore in).

use nalgebra::Point2;

use super::cspace::{disk, CSpace, Frame, FREE};
use super::lanes::{Lane, Variant};
use super::PlanParams;
use crate::decomp::{CellId, CellStatus, Decomposition};
use crate::geom::{heading, wrap_angle, Pose, Segment};
use crate::grid::{CellIndex, CellState, Grid};
use crate::robot::RobotParams;

mod choose;
mod cover;
mod current;
mod end;
mod escape;
mod explore;
mod home;
mod order;
mod records;
mod region_map;
mod regions;
mod scratch;
mod stalls;
mod status;
mod swept_record;
#[cfg(test)]
mod tests;
mod tour_state;
mod tried;

use cover::describe_lanes;
use current::CurrentTask;
use home::HomeState;
pub use home::{HomeOutcome, HOME_NEAR, HOME_REACH, MAX_HOME_PLANS};
use order::tour_start;
pub use records::PlanSnapshot;
use region_map::RegionMap;
use scratch::Scratch;
use stalls::Stalls;
pub use status::{DoneReport, Motion, PlanError, PlanStats, PlanStatus, Task, TaskRecord};
use swept_record::SweptRecord;
use tour_state::TourState;
use tried::ReachAndTries;

struct Candidate {
    cell: Option<CellId>,
    variants: Vec<Variant>,
    /// Travel distance from the robot to each variant's entry (m).
    entry_cost: Vec<f64>,
    targets: Vec<usize>,
}

impl Candidate {
    fn cost(&self) -> f64 {
        self.entry_cost
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min)
    }
}

/// How far from the robot (m, straight line, over traversable cells) floor
/// seen or made reachable during a lane tour counts as "near": the tour is
/// taken again from here to fetch it now rather than after the tour, in a
/// drive back at the end.
const NEW_FLOOR_NEAR: f64 = 1.0;

/// Updates between looks for floor new near the robot on a lane tour (the
/// first after as many updates of the task): no re-decision at every
/// flicker of a cell, and a bounded cost.
const NEW_FLOOR_SETTLE: usize = 5;

/// Least new floor (grid cells, 0.04 m² at 5 cm) that takes the lane tour
/// again: four times the smallest cluster the planner lays a lane for,
/// since cells at the edges of furniture in a map built from noisy scans
/// come and go. Measured (2026-11-28, the debug log gives the count): the
/// closed loop in office_f:0 at ×5 took the tour again 8-19 times a run,
/// nearly always for 8-11 cells; with 8 cells, 9 runs gave overlap 37.3 %,
/// coverage 99.08 %, path 74.4 m (means), with 16 cells 8 runs 33.9 %,
/// 99.21 %, 69.1 m; the 24 lock-step rooms' means are the same both ways
/// (2026-11-27 chose 8 on them: 4 cells gave 1.5 points less overlap on
/// ideal maps but lost coverage on noisy ones).
const NEW_FLOOR_MIN_CELLS: usize = 16;

/// Pose records a cell may be out from under the tool and still count as
/// the same pass when it comes back (jitter at the tool's edge).
const SAME_PASS_RECORDS: u32 = 10;

/// Floor left (m²) below which the end game may leave leftovers (see
/// `CoveragePlanner::decline_leftovers`): while more is left, the travel
/// from the robot to a region is no measure of what it adds to a tour.
const LEFTOVER_AREA: f64 = 0.5;

/// Distance (m) ahead of the robot (measured along the stretch of path it
/// is on) from which that stretch is checked for surfaces seen since it
/// was planned: from its own place a surface it already stands near would
/// block every plan.
const ON_WAY_SKIP: f64 = 0.03;

/// Rounds of given-up floor after the first one, at most (see
/// `CoveragePlanner::may_retry_again`).
const MAX_EXTRA_RETRIES: usize = 10;

/// Floor given up (m²) that gets another round once `plan.clear_wait` has
/// passed since the last (see `CoveragePlanner::may_retry_again`): rooms
/// nobody walks through end with 0.24 m² given up at most (24 rooms, ideal
/// and noisy maps).
const GIVEN_UP_AGAIN: f64 = 1.0;

/// Interruptions after which a target or frontier is given up.
const MAX_TRIES: u8 = 2;

/// Where the path ahead is blocked (see `CoveragePlanner::path_blocked`).
struct Blocked {
    /// The stretch of path blocked, from `a` to `b`.
    a: Point2<f64>,
    b: Point2<f64>,
    /// The first place on it that is not safe now.
    at: Point2<f64>,
    /// Waypoints ahead of the robot the stretch is.
    ahead: usize,
}

/// The online coverage planner (see the module docs).
///
/// Its state is a handful of owned parts, each with its own `impl` beside
/// it: the swept record, the reach and tries, the tour, the drive home, the
/// current task, the regions of the last decision, the stalls and waits,
/// and scratch buffers. What is left here is what every part is planned
/// with (settings, tool geometry, configuration space) and what the planner
/// reports (counters, history, the final report, its clock).
pub struct CoveragePlanner {
    params: PlanParams,
    /// Distance between neighbouring lanes (m): the tool width less the overlap.
    spacing: f64,
    /// Reach of the tool from a lane (m): half the tool width less the margin.
    reach: f64,
    /// Cell offsets within [`Self::reach`] (for the grid of the last update).
    reach_disk: Vec<(i64, i64)>,
    cspace: CSpace,
    /// What the tool has swept.
    swept: SweptRecord,
    /// Tries, give-ups and floor once within reach.
    tried: ReachAndTries,
    /// The lane tour over the explored room.
    tour: TourState,
    /// The start and the drive back to it.
    home: HomeState,
    /// The task being driven.
    current: CurrentTask,
    /// Targets, owners and regions of the last decision, and the lane lattice.
    regions: RegionMap,
    /// Counters of waits and of moves that led nowhere.
    stalls: Stalls,
    /// Buffers reused between decisions (no state of their own).
    scratch: Scratch,
    /// The look around at the start is done (or was not asked for).
    started: bool,
    stats: PlanStats,
    /// The cells counted in `stats.cells`.
    counted: std::collections::BTreeSet<CellId>,
    report: Option<DoneReport>,
    history: Vec<TaskRecord>,
    /// The time last told by [`Self::set_time`] (s).
    clock: Option<f64>,
    /// Updates so far (the clock when none is told).
    update_count: u64,
}

/// Updates the planner waits, planning nothing, while the space reachable
/// from the robot is smaller than its own footprint (ghost obstacles from a
/// bad scan, or contact marks, around it) before it concludes that nothing
/// reachable is left: the map may clear meanwhile.
const BOXED_IN_UPDATES: usize = 25;

/// Seconds an update counts on a planner never told the time (see
/// [`CoveragePlanner::set_time`]): the lock-step simulation's planning period.
const UNTIMED_UPDATE: f64 = 0.2;

/// Waits for walled-off floor to clear (see [`PlanParams::clear_wait`])
/// begun in one run at most: after that many, nothing reachable left is
/// final (a cell flickering at the edge of a pocket could otherwise start a
/// wait, a try and a wait again for ever).
const MAX_CLEAR_WAITS: usize = 20;

/// Ways out (see [`super::unbox`]) in a row, with no cover or explore task
/// between them, after which the planner stops looking for one: the parts
/// they led to had no work the planner could plan.
const MAX_WAYS_OUT: usize = 2;

/// Longest way (m) off the traversable space a robot boxed in for
/// [`BOXED_IN_UPDATES`] updates may take out of its pocket, whatever
/// `plan.way_out_passage` says: the pocket is smaller than the body, so
/// the way out is at most about a body radius through the margin.
const BOXED_IN_WAY_OUT: f64 = 0.5;

/// Interruptions not charged to the interrupted task (escapes from an
/// inflation zone, transits blocked on the way) while the tool sweeps less
/// than a footprint of new floor; beyond, they are charged a try again, so
/// that a place the robot keeps being pushed out of, or a passage that keeps
/// closing, cannot hold it in an endless loop.
const MAX_FORGIVEN: usize = 3;

/// Cells on each side of a given-up frontier cell given up with it (see
/// `give_up_frontier_near`).
const FRONTIER_SPREAD: i64 = 2;

/// An exploration move that shows fewer new seen-free cells than this is
/// fruitless (0.1 m² on the 5 cm grid: less than the robot's footprint).
const FRUITFUL_EXPLORE_CELLS: usize = 40;

/// Fruitless exploration moves in a row after which all frontier there is
/// is given up (see `count_fruitless_explore`).
const MAX_FRUITLESS_EXPLORES: usize = 8;

/// Updates between re-evaluations while exploring (a cell may have become final).
const EXPLORE_RECHECK: usize = 5;

/// The lane spacing (tool width less the overlap) and the reach of the
/// tool from a lane (half the tool width less the margin), both m; an error
/// naming `plan.lane_overlap` when either is not positive. The planner and
/// the configuration check (`sweepline run --check-config`) both ask here.
pub fn lane_geometry(params: &PlanParams, robot: &RobotParams) -> Result<(f64, f64), PlanError> {
    let spacing = robot.tool_width - params.lane_overlap;
    let reach = robot.tool_width / 2.0 - params.reach_margin;
    if spacing > 0.0 && reach > 0.0 {
        return Ok((spacing, reach));
    }
    Err(PlanError::BadParam {
        key: "lane_overlap",
        message: format!(
            "lane_overlap ({}) and reach_margin ({}) must stay below the tool width {} (and its half)",
            params.lane_overlap, params.reach_margin, robot.tool_width
        ),
    })
}

impl CoveragePlanner {
    /// A planner for the robot `robot` (radius, tool width) with `params`.
    pub fn new(params: &PlanParams, robot: &RobotParams) -> Result<Self, PlanError> {
        params.validate()?;
        for (key, v) in [
            ("robot.radius", robot.radius),
            ("robot.tool_width", robot.tool_width),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(PlanError::BadParam {
                    key,
                    message: format!("must be a finite number > 0, got {v}"),
                });
            }
        }
        let (spacing, reach) = lane_geometry(params, robot)?;
        Ok(Self {
            params: params.clone(),
            spacing,
            reach,
            reach_disk: Vec::new(),
            cspace: {
                let mut c = CSpace::new(robot.radius + params.safety_margin, robot.radius);
                c.set_surface_hold(params.surface_hold);
                c
            },
            swept: SweptRecord::new(reach + 1e-6),
            tried: ReachAndTries::default(),
            tour: TourState::default(),
            home: HomeState::default(),
            current: CurrentTask::default(),
            regions: RegionMap::default(),
            stalls: Stalls::default(),
            scratch: Scratch::default(),
            started: !params.look_around,
            stats: PlanStats::default(),
            counted: std::collections::BTreeSet::new(),
            report: None,
            history: Vec::new(),
            clock: None,
            update_count: 0,
        })
    }

    /// The configuration space of the last update.
    pub fn cspace(&self) -> &CSpace {
        &self.cspace
    }

    /// The planner's record of swept floor (same geometry as the grid).
    pub fn covered(&self) -> &[bool] {
        &self.swept.covered
    }

    /// The path to follow now and the heading to turn to at its end.
    pub fn path(&self) -> (&[Point2<f64>], Option<f64>) {
        (&self.current.path, self.current.final_heading)
    }

    /// What the robot does on its way to waypoint `next` of [`Self::path`]
    /// ([`Motion::Other`] past its end).
    pub fn motion(&self, next: usize) -> Motion {
        self.current.motions.get(next).copied().unwrap_or_default()
    }

    /// The motion towards each waypoint of [`Self::path`] (may be shorter
    /// than the path: [`Motion::Other`] for the rest).
    pub fn motions(&self) -> &[Motion] {
        &self.current.motions
    }

    /// The current task.
    pub fn task(&self) -> Task {
        self.current.task
    }

    /// What the planner did so far.
    pub fn stats(&self) -> PlanStats {
        self.stats
    }

    /// Every task planned so far, in order.
    pub fn history(&self) -> &[TaskRecord] {
        &self.history
    }

    /// The report once coverage is finished.
    pub fn report(&self) -> Option<DoneReport> {
        self.report
    }

    /// Tells the planner the time (s, any origin, not going back): the
    /// clock its waits are timed by (see [`PlanParams::clear_wait`]).
    /// Without it, each update counts `UNTIMED_UPDATE` seconds.
    pub fn set_time(&mut self, now: f64) {
        if now.is_finite() {
            self.clock = Some(now);
        }
    }

    /// The planner's clock (s): the time last told, or the updates so far
    /// at [`UNTIMED_UPDATE`] seconds each.
    fn now(&self) -> f64 {
        self.clock
            .unwrap_or(self.update_count as f64 * UNTIMED_UPDATE)
    }

    /// Fits every part to the grid of this update when its geometry
    /// changed, then applies records restored before the geometry was known.
    fn ensure_frame(&mut self) {
        let n = self.cspace.frame.len();
        if self.swept.covered.len() != n {
            let res = self.cspace.frame.res;
            self.swept.fit(n, res);
            self.tried.fit(n);
            self.regions.fit(n);
            self.tour.fit(n);
            self.scratch.fit(n);
            self.reach_disk = disk(self.reach, res);
        }
        if let Some(r) = self.swept.restored.take() {
            if r.frame == self.cspace.frame && r.covered.len() == n {
                self.swept.merge(&r.covered);
            } else {
                log::warn!("swept-floor record of a different map geometry ignored");
            }
        }
        if let Some(t) = self.tried.restored_tries.take() {
            self.tried.apply_tries(t, self.cspace.frame);
        }
        if let Some(r) = self.tried.restored_reach.take() {
            self.tried.apply_reach(r, self.cspace.frame);
        }
    }

    /// Records that the robot was at `pose`: the tool swept the floor around it.
    pub fn record_pose(&mut self, pose: &Pose) {
        let f = self.cspace.frame;
        if self.swept.covered.len() != f.len() || f.is_empty() {
            return;
        }
        let p: Point2<f64> = pose.translation.vector.into();
        if f.index_of(&p).is_none() {
            return;
        }
        self.swept.record(f, &p);
    }

    /// The current path was cut short by an obstacle the map did not show
    /// (a bumper contact, now in the map): the next update plans again, and
    /// the floor or frontier the interrupted task was after is not charged a
    /// try (it is not at fault; the new plan goes around the obstacle).
    pub fn interrupt(&mut self) {
        if self.report.is_some() {
            return;
        }
        self.current.forgive();
        self.current.task = Task::Idle;
    }

    /// Seen free floor (m²), not swept yet, out of the tool's reach from
    /// every place the robot at `robot` can get to now, that would be in
    /// reach if the `cells` of `grid` (a bumper contact's mark) were free:
    /// the floor that mark walls off. Zero before the first update or with
    /// the robot off the map. Builds configuration spaces of its own: for
    /// the rare decision at the end of coverage, not for every update.
    pub fn floor_walled_off(&self, grid: &Grid, cells: &[CellIndex], robot: &Point2<f64>) -> f64 {
        let f = self.cspace.frame;
        let Some(at) = f.index_of(robot) else {
            return 0.0;
        };
        if self.swept.covered.len() != f.len() {
            return 0.0;
        }
        let mut open = grid.clone();
        for &c in cells {
            open.set_state(c, CellState::Free);
        }
        let mut then = self.cspace.clone();
        then.rebuild(&open);
        if then.frame != f {
            return 0.0;
        }
        let mut now = self.cspace.clone();
        let reach = |cs: &mut CSpace| {
            cs.distances_from(at);
            let mut r = vec![false; f.len()];
            for i in (0..f.len()).filter(|&i| cs.traversable[i] && cs.dist[i].is_finite()) {
                for j in f.around(i, &self.reach_disk) {
                    r[j] = true;
                }
            }
            r
        };
        let (now, then) = (reach(&mut now), reach(&mut then));
        let marked: Vec<usize> = cells.iter().map(|c| c.1 * f.w + c.0).collect();
        let n = (0..f.len())
            .filter(|&i| {
                self.cspace.state[i] == FREE
                    && !now[i]
                    && then[i]
                    && !self.swept.covered[i]
                    && !marked.contains(&i)
            })
            .count();
        n as f64 * f.res * f.res
    }

    /// Coverage goes on after [`PlanStatus::Done`]: the map was changed by
    /// something the planner could not foresee (a bumper contact's mark
    /// taken out to try the floor behind it). Floor within `radius` of each
    /// point of `around` that was given up gets its tries back.
    pub fn reopen(&mut self, around: &[Point2<f64>], radius: f64) {
        self.report = None;
        self.home.homing = None;
        self.current.task = Task::Idle;
        self.current.forgive();
        let f = self.cspace.frame;
        for i in 0..self.tried.abandoned.len().min(f.len()) {
            let c = f.centre(i);
            if around.iter().any(|p| (c - p).norm() <= radius) && !self.swept.covered[i] {
                self.tried.take_back(i);
            }
        }
        self.tried.tries_generation += 1;
    }

    /// Counts cell `id` in `stats.cells` unless it was counted before.
    fn count_cell(&mut self, id: CellId) {
        if self.counted.insert(id) {
            self.stats.cells += 1;
        }
    }

    /// Whether an interruption may be forgiven (see [`MAX_FORGIVEN`]);
    /// counts it when so.
    fn may_forgive(&mut self) -> bool {
        let swept = self.swept.swept_cells();
        self.tried.may_forgive(swept, self.swept.footprint())
    }

    /// One planning step after a map update. `grid` is the explored map,
    /// `decomp` the current decomposition, `pose` the robot's pose, and
    /// `progress` the index of the waypoint the follower drives to (`None`
    /// when it has finished the path).
    pub fn update(
        &mut self,
        grid: &Grid,
        decomp: &Decomposition,
        pose: &Pose,
        progress: Option<usize>,
    ) -> Result<PlanStatus, PlanError> {
        self.update_count += 1;
        self.cspace.rebuild(grid);
        self.ensure_frame();
        if let Some(r) = self.report {
            return Ok(PlanStatus::Done(r));
        }
        let p: Point2<f64> = pose.translation.vector.into();
        let f = self.cspace.frame;
        let robot = f
            .index_of(&p)
            .ok_or(PlanError::OutsideMap { x: p.x, y: p.y })?;
        self.current.updates += 1;
        self.home.note_start(pose);
        let mut replan = progress.is_none() || self.current.task == Task::Idle;
        if progress.is_none() {
            self.task_finished();
        }
        if let Some(next) = progress {
            replan |= self.path_blocked(next, &p);
            replan |= self.exploration_resolved();
        }
        if self.home.homing.is_some() {
            return self.home_update(pose, robot, progress.is_none(), replan);
        }
        if !replan {
            if let Some(next) = progress {
                replan = self.tour_again_for_new_floor(decomp, robot, &p, next);
            }
        }
        if !replan {
            return Ok(PlanStatus::Working {
                task: self.current.task,
                new_path: false,
            });
        }
        let keep_exploring = progress.is_some() && self.current.task == Task::Explore;
        self.choose(decomp, pose, robot, keep_exploring)
    }

    /// The follower reached the end of the path: an exploration move's
    /// frontier still in view from here cannot be seen, and a cover task's
    /// targets its lanes did not reach get one more try.
    fn task_finished(&mut self) {
        if self.current.task == Task::Explore {
            // Arrived: whatever frontier is still in view from here cannot be seen.
            if let Some(g) = self.current.explore_goal.take() {
                self.give_up_frontier_near(&g, 0);
            }
        }
        if matches!(self.current.task, Task::Cover(_)) {
            // Targets the finished lanes did not reach get one more try; after
            // MAX_TRIES they are given up (when the task was only part
            // of its region's lanes: only the floor near its lanes, and
            // only when it swept none of it).
            let spared =
                self.current.split && self.current.targets.iter().any(|&i| self.swept.covered[i]);
            let mut targets = std::mem::take(&mut self.current.targets);
            for &i in &targets {
                if !self.swept.covered[i] && !spared {
                    self.tried.charge(i, MAX_TRIES);
                }
            }
            targets.clear();
            self.current.targets = targets;
        }
    }

    /// Whether the path ahead of the robot at `p`, driving to waypoint
    /// `next`, is blocked by something seen since it was planned; counts
    /// it, and forgives the task when it was still in transit.
    fn path_blocked(&mut self, next: usize, p: &Point2<f64>) -> bool {
        let from = next.min(self.current.path.len());
        let Some(Blocked {
            a,
            b,
            at: q,
            ahead: k,
        }) = self.first_unsafe_ahead(from, p)
        else {
            return false;
        };
        if log::log_enabled!(log::Level::Debug) {
            let by = self
                .cspace
                .blocker(&q)
                .map_or("nothing found".to_string(), |bl| {
                    format!(
                        "{} at ({:.3}, {:.3}), {:.3} m from the path",
                        bl.kind.describe(),
                        bl.at.x,
                        bl.at.y,
                        bl.distance
                    )
                });
            log::debug!(
                "plan: path blocked between ({:.2}, {:.2}) and ({:.2}, {:.2}) m, {} waypoints ahead, by {by}; planning again",
                a.x,
                a.y,
                b.x,
                b.y,
                k
            );
        }
        self.stats.blocked += 1;
        // Still on the way to the task's first lane: the region is
        // not at fault (the transit ran into something seen on the
        // way, typically at a gap between furniture seen closer);
        // its floor is not charged a try, up to a bound.
        let in_transit = self.current.motions.get(from) == Some(&Motion::Transit);
        if in_transit && self.may_forgive() {
            self.current.forgive();
        }
        true
    }

    /// The first place on the path from waypoint `from` on that is not
    /// safe now (see [`Blocked`]). The stretch the robot (at `p`) is
    /// on, from a little ahead of where it is along it (a person who
    /// stepped beside the robot's way), then the rest. Along the planned
    /// stretch, not from the robot itself: a few millimetres of tracking
    /// error beside a wall would block every plan.
    fn first_unsafe_ahead(&self, from: usize, p: &Point2<f64>) -> Option<Blocked> {
        let p = *p;
        let on_way = self.current.path.get(from).and_then(|&b| {
            let a0 = from.checked_sub(1).map_or(p, |k| self.current.path[k]);
            let d = b - a0;
            let len = d.norm();
            if len <= ON_WAY_SKIP {
                return None;
            }
            let along = ((p - a0).dot(&d) / len).clamp(0.0, len) + ON_WAY_SKIP;
            if along >= len {
                return None;
            }
            let a = a0 + d * (along / len);
            self.cspace.first_unsafe(&a, &b).map(|q| (a, b, q))
        });
        let ahead = || {
            self.current.path[from..]
                .windows(2)
                .enumerate()
                .find_map(|(k, s)| {
                    self.cspace
                        .first_unsafe(&s[0], &s[1])
                        .map(|q| (s[0], s[1], q, k))
                })
        };
        on_way
            .map(|(a, b, q)| (a, b, q, 0))
            .or_else(ahead)
            .map(|(a, b, at, ahead)| Blocked { a, b, at, ahead })
    }

    /// Whether an exploration move under way is to be decided again: its
    /// frontier is out of view (seen, or given up), or it is time for
    /// the periodic look at whether a cell became final.
    fn exploration_resolved(&mut self) -> bool {
        if self.current.task != Task::Explore {
            return false;
        }
        let resolved = match self.current.explore_goal {
            Some(g) => !self.frontier_in_view(&g),
            None => true,
        };
        resolved || self.current.updates.is_multiple_of(EXPLORE_RECHECK)
    }

    /// Begins `task` along `path` (turning to `final_heading` at its end):
    /// the task it ends is charged what it left, and the counters that
    /// follow the kind of task are updated.
    fn set_task(&mut self, task: Task, path: Vec<Point2<f64>>, final_heading: Option<f64>) {
        if !matches!(task, Task::Idle | Task::Wait | Task::Done) {
            if let Some(t0) = self.stalls.wait_since.take() {
                log::info!(
                    "the way cleared after {:.0} s of waiting: {task:?} planned",
                    self.now() - t0
                );
            }
        }
        self.charge_task_left();
        if task == Task::Explore {
            self.stalls.free_at_explore = self.known_free();
        }
        if matches!(task, Task::Cover(_) | Task::Explore) {
            self.stalls.ways_out_in_a_row = 0;
        }
        self.tour.end();
        let record = self.current.begin(task, path, final_heading);
        self.stats.tasks += 1;
        self.history.push(record);
    }

    /// The current task ends, interrupted or not: what it was after and did
    /// not get counts one more try; after [`MAX_TRIES`] tries it is given up
    /// (no endless back and forth).
    fn charge_task_left(&mut self) {
        let old_targets = std::mem::take(&mut self.current.targets);
        // A task that swept some of its floor before being interrupted made
        // progress: its floor is not charged a try.
        let progressed = old_targets.iter().any(|&i| self.swept.covered[i]);
        for &i in &old_targets[..self.tour.at_fault(old_targets.len())] {
            if !progressed && !self.swept.covered[i] {
                self.tried.charge(i, MAX_TRIES);
            }
        }
        if self.current.task == Task::Explore {
            if let Some(g) = self.current.explore_goal.take() {
                self.give_up_frontier_near(&g, MAX_TRIES);
            }
            self.count_fruitless_explore();
        }
    }
}

/// The cells among `offsets` (cell offsets around the cell holding `p`)
/// whose centres lie within `radius` of `p` itself (exact distance from
/// the point, not from its cell's centre); none when `p` is off the grid.
fn cells_within<'a>(
    f: Frame,
    p: &Point2<f64>,
    offsets: &'a [(i64, i64)],
    radius: f64,
) -> impl Iterator<Item = usize> + 'a {
    let centre = f.index_of(p).map(|i| ((i % f.w) as i64, (i / f.w) as i64));
    let (p, r2) = (*p, radius * radius);
    offsets.iter().filter_map(move |&(dx, dy)| {
        let (x, y) = centre?;
        let (nx, ny) = (x + dx, y + dy);
        if nx < 0 || ny < 0 || nx as usize >= f.w || ny as usize >= f.h {
            return None;
        }
        let j = ny as usize * f.w + nx as usize;
        ((f.centre(j) - p).norm_squared() <= r2).then_some(j)
    })
}
