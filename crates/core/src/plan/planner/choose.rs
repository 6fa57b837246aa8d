//! The choice of the next task: the planner's policy, as a sequence of
//! named decisions (see the module docs of the planner for the order of
//! preference). [`CoveragePlanner::choose`] reads as the policy; each
//! decision below plans its task and answers `Some` (or the status), or
//! passes with `None` to the next one.

use nalgebra::Point2;

use super::*;

/// The status of a decision that planned `task` with a new path.
fn new_path(task: Task) -> Result<PlanStatus, PlanError> {
    Ok(PlanStatus::Working {
        task,
        new_path: true,
    })
}

impl CoveragePlanner {
    /// Plans the next task for the robot at `pose` (cell `robot`) with the
    /// decomposition `decomp`; `keep_exploring`: an exploration move is
    /// under way and is kept while no region has work.
    pub(super) fn choose(
        &mut self,
        decomp: &Decomposition,
        pose: &Pose,
        robot: usize,
        keep_exploring: bool,
    ) -> Result<PlanStatus, PlanError> {
        let p: Point2<f64> = pose.translation.vector.into();
        if let Some(task) = self.start_look_around(pose) {
            return new_path(task);
        }
        if !self.cspace.traversable[robot] {
            return self.escape(&p, robot, true);
        }
        self.survey(decomp, robot);
        let mut cands = self.final_cells(decomp, keep_exploring);
        if cands.is_empty() {
            if keep_exploring {
                return Ok(self.keep_exploring());
            }
            if let Some(task) = self.explore_frontier(robot) {
                return new_path(task);
            }
            cands = self.patch_candidates(decomp);
        }
        self.decline_leftovers(&mut cands, robot);
        if cands.is_empty() {
            if let Some(task) = self.way_out_to_work(robot) {
                return new_path(task);
            }
        }
        if cands.is_empty() && self.boxed_in_now() {
            let boxed_in = self.wait_while_boxed_in(&p);
            if let Some(task) = boxed_in.or_else(|| self.step_out_of_pocket(&p, robot)) {
                return new_path(task);
            }
        } else {
            self.stalls.boxed_in = 0;
        }
        if cands.is_empty() {
            if let Some(task) = self.end_surface_hold() {
                return new_path(task);
            }
            cands = self.retry_given_up_floor(decomp);
        }
        if cands.is_empty() {
            if let Some(task) = self.wait_for_walled_off_floor(robot, &p) {
                return new_path(task);
            }
            return self.finish_coverage(pose, robot);
        }
        Ok(self.cover_next(cands, decomp, robot))
    }

    /// Once, at the start: look around (turn in place by half a turn, so
    /// the 240° scanner sees all around).
    fn start_look_around(&mut self, pose: &Pose) -> Option<Task> {
        if self.started {
            return None;
        }
        self.started = true;
        self.set_task(
            Task::LookAround,
            Vec::new(),
            Some(wrap_angle(heading(pose) + std::f64::consts::PI)),
        );
        Some(Task::LookAround)
    }

    /// What every decision below looks at: the travel costs from `robot`,
    /// the places it can get to and the floor they reach (added to the
    /// places once within reach), and which region holds which place.
    fn survey(&mut self, decomp: &Decomposition, robot: usize) {
        // Travel over swept floor sweeps it again (the tool is always on):
        // transits and the choice of the next cell prefer unswept floor
        // (`swept_travel_cost`), and floor already swept twice, where more
        // passes add no overlap (`new_overlap_cost`).
        self.swept
            .fresh_share(&self.cspace, self.reach, self.params.new_overlap_cost);
        let (covered, w) = (&self.swept.covered, self.params.swept_travel_cost);
        let (fresh, wo) = (&self.swept.fresh, self.params.new_overlap_cost);
        self.cspace
            .set_extra_cost(|i| (if covered[i] { w } else { 0.0 }) + wo * f64::from(fresh[i]));
        self.cspace.distances_from(robot);
        self.compute_targets();
        self.tried.note_reachable(&self.regions.reachable);
        self.mark_cells(decomp);
    }

    /// The final cells with work left; with none, the settling ones when
    /// `plan.cover_settling_cells` says so (not while exploring).
    fn final_cells(&mut self, decomp: &Decomposition, keep_exploring: bool) -> Vec<Candidate> {
        let cands = self.cell_candidates(decomp, CellStatus::Final);
        if cands.is_empty() && self.params.cover_settling_cells && !keep_exploring {
            return self.cell_candidates(decomp, CellStatus::Settling);
        }
        cands
    }

    /// No region has work while an exploration move is under way: drive on.
    fn keep_exploring(&mut self) -> PlanStatus {
        self.current.task = Task::Explore;
        PlanStatus::Working {
            task: Task::Explore,
            new_path: false,
        }
    }

    /// No region has work: go to the nearest reachable place with
    /// unexplored space in view, and face it.
    fn explore_frontier(&mut self, robot: usize) -> Option<Task> {
        let (goal, face) = self.explore_goal_from(robot)?;
        let mut path = self.cspace.path_to(goal).unwrap_or_default();
        if !path.is_empty() {
            path.remove(0);
        }
        let g = self.cspace.frame.centre(goal);
        let final_heading = {
            let d = face - g;
            (d.norm() > 1e-6).then(|| d.y.atan2(d.x))
        };
        self.stats.explores += 1;
        self.set_task(Task::Explore, path, final_heading);
        self.current.explore_goal = Some(g);
        Some(Task::Explore)
    }

    /// Nothing left where the robot can go with the full clearance, but its
    /// body fits through to another part of the space with work: go there.
    fn way_out_to_work(&mut self, robot: usize) -> Option<Task> {
        let path = self.way_out(robot, self.params.way_out_passage)?;
        self.take_way_out(path);
        Some(Task::Escape)
    }

    /// Boxed in (the robot at `p` can reach less than its own footprint,
    /// yet seen floor is left): wait, planning nothing, for up to
    /// [`BOXED_IN_UPDATES`] updates rather than report all of it
    /// unreachable at once.
    fn wait_while_boxed_in(&mut self, p: &Point2<f64>) -> Option<Task> {
        if self.stalls.boxed_in >= BOXED_IN_UPDATES {
            return None;
        }
        self.stalls.boxed_in += 1;
        if self.stalls.boxed_in == 1 {
            log::warn!(
                "robot at ({:.2}, {:.2}) m is boxed in by the map; waiting for it to clear",
                p.x,
                p.y
            );
        }
        self.current.stand_still();
        Some(Task::Idle)
    }

    /// Still boxed in after the wait: the pocket is a part of the
    /// traversable space smaller than the body (the robot stopped a few
    /// centimetres off its path, in the margin of something seen since),
    /// not floor cut off by walls. Step out where the bare body fits,
    /// rather than finish with the rest of the floor left.
    fn step_out_of_pocket(&mut self, p: &Point2<f64>, robot: usize) -> Option<Task> {
        let path = self.way_out(robot, BOXED_IN_WAY_OUT)?;
        log::warn!(
            "robot at ({:.2}, {:.2}) m still boxed in after {BOXED_IN_UPDATES} updates: stepping out to ({:.2}, {:.2}) m where only the bare body fits",
            p.x,
            p.y,
            path.last().map_or(p.x, |q| q.x),
            path.last().map_or(p.y, |q| q.y),
        );
        self.stalls.boxed_in = 0;
        self.take_way_out(path);
        Some(Task::Escape)
    }

    /// Nothing left to do, the first time: the surface hold, which steadies
    /// the plan while there is work, ends for the run. Surfaces kept
    /// blocking only by it are let go: floor beside them given up gets its
    /// tries back, and is looked at again from the next update.
    fn end_surface_hold(&mut self) -> Option<Task> {
        if self.stalls.hold_ended {
            return None;
        }
        self.stalls.hold_ended = true;
        self.cspace.set_surface_hold(0);
        let cells = self.cspace.release_held();
        if cells.is_empty() {
            return None;
        }
        let f = self.cspace.frame;
        let around: Vec<Point2<f64>> = cells.iter().map(|&i| f.centre(i)).collect();
        log::debug!(
            "nothing left to do: {} surfaces kept only by the hold let go, the floor beside them looked at again: {}",
            around.len(),
            around
                .iter()
                .map(|c| format!("({:.2}, {:.2})", c.x, c.y))
                .collect::<Vec<_>>()
                .join(", ")
        );
        self.set_task(Task::Idle, Vec::new(), None);
        self.reopen(&around, self.cspace.inflation() + self.reach + f.res);
        Some(Task::Idle)
    }

    /// Floor given up while the map was still changing (tasks interrupted
    /// again and again at furniture seen from closer, or by people crossing
    /// the robot's paths) gets one more round when nothing else is left,
    /// and more as `may_retry_again` allows: its patches, or none.
    fn retry_given_up_floor(&mut self, decomp: &Decomposition) -> Vec<Candidate> {
        if self.may_retry_again() && self.retry_given_up() {
            return self.patch_candidates(decomp);
        }
        Vec::new()
    }

    /// Floor the robot could once get to, walled off now: a person standing
    /// or walking in the way leaves surfaces in the map until beams pass
    /// through where they stood. Wait (plan nothing) before calling that
    /// floor unreachable; so too with much floor given up after its rounds
    /// (people kept crossing the robot's paths), then try it again.
    fn wait_for_walled_off_floor(&mut self, robot: usize, p: &Point2<f64>) -> Option<Task> {
        let walled = self.walled_off();
        let cell_area = self.cspace.frame.res * self.cspace.frame.res;
        let walled_off = walled.iter().filter(|&&w| w).count() as f64 * cell_area;
        let waiting = self.stalls.wait_since.is_some() || self.current.task == Task::Wait;
        let waited = self.stalls.wait_since.map_or(0.0, |t0| self.now() - t0);
        if (walled_off >= self.params.min_patch_area || self.much_given_up())
            && waited < self.params.clear_wait
            && (waiting || self.tried.clear_waits < MAX_CLEAR_WAITS)
        {
            if !waiting {
                if let Some(task) = self.begin_wait(robot, p, &walled, walled_off) {
                    return Some(task);
                }
            }
            self.stalls.wait_since.get_or_insert(self.now());
            self.current.stand_still();
            return Some(Task::Idle);
        }
        if let Some(t0) = self.stalls.wait_since.take() {
            log::warn!(
                "waited {:.0} s for {walled_off:.2} m² of floor beyond obstacles to clear; it stays walled off",
                self.now() - t0
            );
        }
        None
    }

    /// A wait for `walled_off` m² of floor (`walled`) begins: counted, and
    /// first looked at from near (a trail seen from afar is let go slowly,
    /// since few beams pass through it): the drive to the place to wait at,
    /// or `None` to wait where the robot (at `p`) is.
    fn begin_wait(
        &mut self,
        robot: usize,
        p: &Point2<f64>,
        walled: &[bool],
        walled_off: f64,
    ) -> Option<Task> {
        self.tried.clear_waits += 1;
        self.tried.reach_generation += 1;
        let look = (walled_off > 0.0)
            .then(|| self.look_place(robot, walled))
            .flatten();
        let Some((j, face)) = look else {
            log::info!(
                "nothing reachable left but {walled_off:.2} m² of seen floor unswept beyond obstacles and much floor given up on paths blocked again and again: waiting up to {:.0} s before trying it again",
                self.params.clear_wait
            );
            return None;
        };
        let mut path = self.cspace.path_to(j).unwrap_or_default();
        if !path.is_empty() {
            path.remove(0);
        }
        if path.is_empty() {
            path.push(*p);
        }
        let q = path[path.len() - 1];
        let d = face - q;
        log::info!(
            "nothing reachable left but {walled_off:.2} m² of seen floor unswept beyond obstacles: waiting at ({:.2}, {:.2}) m, facing ({:.2}, {:.2}), up to {:.0} s for the way to clear",
            q.x,
            q.y,
            face.x,
            face.y,
            self.params.clear_wait
        );
        self.set_task(Task::Wait, path, Some(d.y.atan2(d.x)));
        Some(Task::Wait)
    }

    /// Nothing reachable is left: report what is left, and drive home or
    /// finish.
    fn finish_coverage(&mut self, pose: &Pose, robot: usize) -> Result<PlanStatus, PlanError> {
        let report = self.done_report(robot);
        if report.behind_tight_passages > 0.0 {
            log::warn!(
                "done with {:.2} m² of seen floor unswept behind passages that leave the body less than its {:.3} m safety margin a side; plan.way_out_passage (now {} m) lets it take such passages",
                report.behind_tight_passages,
                self.params.safety_margin,
                self.params.way_out_passage
            );
        }
        self.coverage_done(report, pose, robot)
    }

    /// Cover the regions `cands` (not empty): once the room is explored, in
    /// one lane tour (`plan.lane_tour`), else the first region of the best
    /// look-ahead order.
    fn cover_next(
        &mut self,
        mut cands: Vec<Candidate>,
        decomp: &Decomposition,
        robot: usize,
    ) -> PlanStatus {
        // Look-ahead: the order of the nearest candidates (and the corner
        // each is entered at) that minimises the whole tour, exhaustively.
        cands.sort_by(|a, b| a.cost().total_cmp(&b.cost()));
        if self.params.lane_tour && self.room_explored(decomp, robot) {
            return self.take_lane_tour(&cands);
        }
        self.cover_first_region(cands)
    }

    /// Once no cell touches unexplored space, what is left is known: one
    /// tour lane by lane through it (while cells are open, regions one at a
    /// time: a tour through what is known so far would be driven past floor
    /// that is seen later; measured worse, 36 % against 32 %). An open cell
    /// whose unexplored space no reachable place sees (a corner behind
    /// furniture) will not change: it does not hold the tour back (the
    /// paper world kept such cells open to the end and fetched two regions
    /// passed by in 6 m of transit).
    fn room_explored(&mut self, decomp: &Decomposition, robot: usize) -> bool {
        !decomp.cells.iter().any(|c| c.status == CellStatus::Open)
            || self.explore_goal_from(robot).is_none()
    }

    /// Covers the first region of the best look-ahead order through
    /// `cands` (sorted nearest first, not empty), up to its first long join.
    fn cover_first_region(&mut self, mut cands: Vec<Candidate>) -> PlanStatus {
        let (k, v) = tour_start(&cands, self.params.lookahead_weight);
        let chosen = cands.swap_remove(k);
        let mut lanes = chosen.variants[v].lanes.clone();
        self.current.split = self.split_at_long_join(&mut lanes);
        if log::log_enabled!(log::Level::Debug) {
            log::debug!(
                "task {}: lanes {}",
                self.stats.tasks + 1,
                describe_lanes(&lanes)
            );
        }
        let (path, motions) = self.cover_path(&lanes, &[]);
        self.current.motions = motions;
        match chosen.cell {
            Some(id) => self.count_cell(id),
            None => self.stats.patches += 1,
        }
        self.stats.lanes += lanes.len();
        self.current.planned_lanes = lanes.len();
        let task = Task::Cover(chosen.cell);
        self.set_task(task, path, None);
        // The floor this task answers for: what its lanes pass within reach
        // of (a split task leaves the rest of its region untouched).
        let f = self.cspace.frame;
        let near = self.reach + f.res;
        self.current.targets = chosen.targets;
        if self.current.split {
            self.current.targets.retain(|&i| {
                let c = f.centre(i);
                lanes
                    .iter()
                    .any(|l| Segment::new(l.a, l.b).distance_to(&c) <= near)
            });
        }
        PlanStatus::Working {
            task,
            new_path: true,
        }
    }

    /// A long join between two lanes would drive over swept floor: the
    /// rest of the region waits for a later task (its floor is not charged
    /// a try for what this task leaves). Cuts `lanes` before the first
    /// join longer than `plan.max_lane_join`; true when it did.
    fn split_at_long_join(&self, lanes: &mut Vec<Lane>) -> bool {
        let m = self.params.max_lane_join;
        if m > 0.0 {
            if let Some(k) = lanes.windows(2).position(|w| (w[1].a - w[0].b).norm() > m) {
                lanes.truncate(k + 1);
                return true;
            }
        }
        false
    }
}
