//! Covering lanes: the tour lane by lane through all the cells left, the
//! path through a task's lanes, and the transits spliced to their ends.

use nalgebra::Point2;

use super::*;
use crate::plan::cspace::CSpace;
use crate::plan::lanes::Lane;
use crate::plan::tour::{lane_tour, TourCosts};

impl CoveragePlanner {
    /// Drives the lanes of the nearest candidates (all of each, up to
    /// `plan.tour_max_lanes` in all) in one tour ordered lane by lane (see
    /// [`crate::plan::tour`]); `cands` sorted nearest first, not empty, and
    /// [`CSpace::dist`] holding the travel cost from the robot.
    pub(super) fn take_lane_tour(&mut self, cands: &[Candidate]) -> PlanStatus {
        self.tour.toured = true;
        let mut pooled: Vec<Lane> = Vec::new();
        let mut region: Vec<usize> = Vec::new();
        let mut taken = 0;
        for (k, c) in cands.iter().enumerate() {
            let ls = &c.variants[0].lanes;
            if k > 0 && pooled.len() + ls.len() > self.params.tour_max_lanes {
                break;
            }
            pooled.extend_from_slice(ls);
            region.extend(std::iter::repeat_n(k, ls.len()));
            taken = k + 1;
        }
        let f = self.cspace.frame;
        let ends: Vec<usize> = pooled
            .iter()
            .flat_map(|l| [l.a, l.b])
            .map(|p| f.index_of(&p).unwrap_or(usize::MAX))
            .collect();
        let start: Vec<f64> = ends
            .iter()
            .map(|&i| self.cspace.dist.get(i).copied().unwrap_or(f64::INFINITY))
            .collect();
        let mut between = std::mem::take(&mut self.scratch.tour_costs);
        self.cspace.travel_linked(&ends, &mut between);
        let tour = lane_tour(&TourCosts {
            start: &start,
            between: &between,
        });
        self.scratch.tour_costs = between;
        let lanes: Vec<Lane> = tour
            .iter()
            .map(|&(k, rev)| if rev { pooled[k].reversed() } else { pooled[k] })
            .collect();
        // A lane of another region than the lane before is reached by a transit.
        let new_region: Vec<bool> = tour
            .iter()
            .enumerate()
            .map(|(i, &(k, _))| i == 0 || region[k] != region[tour[i - 1].0])
            .collect();
        if log::log_enabled!(log::Level::Debug) {
            log::debug!(
                "task {}: one tour through {taken} regions, lanes {}",
                self.stats.tasks + 1,
                describe_lanes(&lanes)
            );
        }
        let (path, motions) = self.cover_path(&lanes, &new_region);
        self.current.motions = motions;
        let pooled_cands = &cands[..taken];
        for id in pooled_cands.iter().filter_map(|c| c.cell) {
            self.count_cell(id);
        }
        if !self.tour.retour {
            self.stats.patches += pooled_cands.iter().filter(|c| c.cell.is_none()).count();
            self.stats.lanes += lanes.len();
        }
        self.current.planned_lanes = lanes.len();
        // Every pooled region's lanes are driven whole: what they leave
        // uncovered is charged a try as a region's task would be.
        self.current.split = false;
        let first = tour.first().map_or(0, |&(k, _)| region[k]);
        let task = Task::Cover(cands[first].cell);
        self.set_task(task, path, None);
        let firsts = &pooled_cands[first].targets;
        self.tour.begin(firsts.len());
        self.current.targets = firsts
            .iter()
            .chain(
                pooled_cands
                    .iter()
                    .enumerate()
                    .filter(|&(k, _)| k != first)
                    .flat_map(|(_, c)| c.targets.iter()),
            )
            .copied()
            .collect();
        PlanStatus::Working {
            task,
            new_path: true,
        }
    }

    /// Clears the targets within reach of `ls` (the lanes of a region
    /// pooled into a lane tour): a region after it then lays no lane for
    /// floor the earlier one's lanes sweep (two regions sharing a border
    /// row would each drive a lane along it).
    pub(super) fn clear_targets_along(&mut self, ls: &[Lane]) {
        let f = self.cspace.frame;
        let radius = self.reach + f.res * 0.5;
        for l in ls {
            for p in crate::geom::points_along(l.a, l.b, f.res * 0.5) {
                for j in cells_within(f, &p, &self.reach_disk, radius) {
                    self.regions.targets[j] = false;
                }
            }
        }
    }

    /// Transit to the first lane, then the lanes joined by straight
    /// connections where clear, A* elsewhere; with the motion toward each
    /// waypoint. A lane marked in `new_region` (by index; none when empty)
    /// is reached by a transit rather than a connection.
    pub(super) fn cover_path(
        &self,
        ls: &[Lane],
        new_region: &[bool],
    ) -> (Vec<Point2<f64>>, Vec<Motion>) {
        let f = self.cspace.frame;
        let mut path = Vec::new();
        let mut motions = Vec::new();
        let Some(first) = ls.first() else {
            return (path, motions);
        };
        if let Some(entry) = f.index_of(&first.a) {
            if let Some(t) = self.cspace.path_to(entry) {
                let t = splice(&self.cspace, None, t, &first.a);
                motions.resize(t.len(), Motion::Transit);
                path.extend(t);
            }
        }
        let mut prev: Option<Point2<f64>> = None;
        for (k, l) in ls.iter().enumerate() {
            let join = if prev.is_some() && !new_region.get(k).copied().unwrap_or(false) {
                Motion::Connection
            } else {
                Motion::Transit
            };
            if let Some(q) = prev {
                if !self.cspace.segment_clear(&q, &l.a) {
                    if let (Some(a), Some(b)) = (f.index_of(&q), f.index_of(&l.a)) {
                        if let Some(t) = self.cspace.astar(a, b) {
                            let t = splice(&self.cspace, Some(&q), t, &l.a);
                            motions.resize(motions.len() + t.len(), join);
                            path.extend(t);
                        }
                    }
                }
            }
            path.push(l.a);
            motions.push(join);
            path.push(l.b);
            motions.push(if l.fixup { Motion::FixUp } else { Motion::Lane });
            prev = Some(l.b);
        }
        // Drop repeated waypoints (and their motions).
        let mut k = 0;
        for i in 0..path.len() {
            if k > 0 && (path[i] - path[k - 1]).norm() < 1e-9 {
                continue;
            }
            path[k] = path[i];
            motions[k] = motions[i];
            k += 1;
        }
        path.truncate(k);
        motions.truncate(k);
        (path, motions)
    }
}

/// Lanes as `(x, y)->(x, y)` (m) for the debug log, fix-ups marked.
pub(super) fn describe_lanes(lanes: &[Lane]) -> String {
    let list: Vec<String> = lanes
        .iter()
        .map(|l| {
            let f = if l.fixup { " fix-up" } else { "" };
            format!(
                "({:.2}, {:.2})->({:.2}, {:.2}){f}",
                l.a.x, l.a.y, l.b.x, l.b.y
            )
        })
        .collect();
    list.join(", ")
}

/// The waypoints between `from` (`None`: the robot, where the path starts)
/// and `to` of a searched path `t` (cell centres from `from`'s cell to
/// `to`'s): `t` without its first and last centre where the straight
/// segment from `from`, or to `to`, stays on traversable cells. Lane ends
/// lie off the cell centres: a segment cut short past a centre may come
/// closer to a wall than the search did.
pub(super) fn splice(
    cs: &CSpace,
    from: Option<&Point2<f64>>,
    mut t: Vec<Point2<f64>>,
    to: &Point2<f64>,
) -> Vec<Point2<f64>> {
    if t.len() < 2 {
        return Vec::new();
    }
    if from.is_none_or(|q| cs.segment_clear(q, &t[1])) {
        t.remove(0);
    }
    let before_last = if t.len() >= 2 {
        Some(t[t.len() - 2])
    } else {
        from.copied()
    };
    if before_last.is_none_or(|p| cs.segment_clear(&p, to)) {
        t.pop();
    }
    t
}

impl CoveragePlanner {
    /// Floor seen (or made reachable) near the robot (at `p`, cell `robot`,
    /// driving to waypoint `next`) during a lane tour joins the tour now,
    /// not in a drive back once the tour is done: whether the tour is
    /// taken again from here.
    pub(super) fn tour_again_for_new_floor(
        &mut self,
        decomp: &Decomposition,
        robot: usize,
        p: &Point2<f64>,
        next: usize,
    ) -> bool {
        let new_floor = self.new_floor_near(decomp, robot, p, next);
        if new_floor < NEW_FLOOR_MIN_CELLS {
            return false;
        }
        log::debug!(
            "new floor near ({:.2}, {:.2}) m, {new_floor} cells: the lane tour is taken again from here",
            p.x,
            p.y
        );
        self.stats.retours += 1;
        // The task is not at fault: its floor is in the new tour.
        self.current.forgive();
        self.tour.retour = true;
        true
    }

    /// Counts the floor cells, within the tool's reach of places in final
    /// cells the robot gets to within [`NEW_FLOOR_NEAR`] of where it is (at
    /// `p`, cell `robot`, driving to waypoint `next`), that would be targets
    /// now but were none at the last decision (seen free since, or next to
    /// places that became traversable), and that the rest of the path does
    /// not sweep. Floor of a cell still settling waits until the cell is
    /// final: a decision before would leave it out again. Only on a lane
    /// tour (the room explored; before that each decision is one region
    /// anyway, and regions change as cells grow), every
    /// [`NEW_FLOOR_SETTLE`] updates of the task (0 otherwise). Local: a few
    /// thousand cells, whatever the size of the map.
    pub(super) fn new_floor_near(
        &mut self,
        decomp: &Decomposition,
        robot: usize,
        p: &Point2<f64>,
        next: usize,
    ) -> usize {
        if !self.tour.touring
            || self.current.updates == 0
            || !self.current.updates.is_multiple_of(NEW_FLOOR_SETTLE)
            || !self.cspace.traversable[robot]
        {
            return 0;
        }
        let f = self.cspace.frame;
        let at = f.centre(robot);
        let mut queue = std::mem::take(&mut self.scratch.near_queue);
        queue.clear();
        queue.push(robot);
        self.scratch.near_reached[robot] = true;
        let mut k = 0;
        while k < queue.len() {
            let i = queue[k];
            k += 1;
            for j in f.neighbours8(i) {
                if !self.scratch.near_reached[j]
                    && self.cspace.traversable[j]
                    && (f.centre(j) - at).norm() <= NEW_FLOOR_NEAR
                {
                    self.scratch.near_reached[j] = true;
                    queue.push(j);
                }
            }
        }
        let reached = queue.len();
        // Floor the rest of the path sweeps anyway is no reason to re-plan.
        let rest = &self.current.path[next.min(self.current.path.len())..];
        let reach = self.reach + f.res * 0.5;
        let swept_later = |c: Point2<f64>| {
            let mut a = *p;
            rest.iter().any(|&b| {
                let near = Segment::new(a, b).distance_to(&c) <= reach;
                a = b;
                near
            })
        };
        let in_final = |c: Point2<f64>| {
            decomp.cells.iter().any(|cell| {
                cell.status == CellStatus::Final && cell.polygon.len() >= 3 && cell.contains(&c)
            })
        };
        let mut new = 0;
        for q in 0..reached {
            let i = queue[q];
            let mut from_final = None;
            for j in f.around(i, &self.reach_disk) {
                if self.scratch.near_counted[j] || self.tour.decided[j] || !self.open_floor(j) {
                    continue;
                }
                if !*from_final.get_or_insert_with(|| in_final(f.centre(i))) {
                    break;
                }
                self.scratch.near_counted[j] = true;
                queue.push(j);
                if !swept_later(f.centre(j)) {
                    new += 1;
                }
            }
        }
        for &i in &queue {
            self.scratch.near_reached[i] = false;
            self.scratch.near_counted[i] = false;
        }
        self.scratch.near_queue = queue;
        new
    }
}
