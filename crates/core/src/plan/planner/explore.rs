//! Exploration and its bookkeeping: where to look from next, ways out of a
//! pocket, and frontiers or floor given up after fruitless tries.

use nalgebra::Point2;

use super::regions::drop_specks;
use super::{
    CoveragePlanner, Task, FRUITFUL_EXPLORE_CELLS, MAX_EXTRA_RETRIES, MAX_FRUITLESS_EXPLORES,
    MAX_WAYS_OUT,
};
use crate::plan::cspace::{Frame, FREE};

/// Distance (m) from seen floor walled off by obstacles at which the robot
/// waits for it to clear (see [`CoveragePlanner::look_place`]): near enough
/// that its beams pass densely through what walls the floor off (a person's
/// trail is let go in a few scans), far enough that a person walking there
/// passes the robot without waiting for it.
const LOOK_DISTANCE: f64 = 1.0;

impl CoveragePlanner {
    /// Seen free floor, not swept, that the robot could get to once but no
    /// place it can get to now with the full clearance lets it sweep (floor
    /// beyond a person standing or walking in the way, or behind a passage
    /// seen too tight since), in pieces of at least `plan.min_patch_area`.
    /// Floor never within reach (a pocket behind furniture) is not in it.
    pub(super) fn walled_off(&self) -> Vec<bool> {
        let f = self.cspace.frame;
        let own = super::end::touch_from(&self.cspace, &self.regions.reachable);
        let once = super::end::touch_from(&self.cspace, &self.tried.ever_reachable);
        let mut walled: Vec<bool> = (0..f.len())
            .map(|i| self.cspace.state[i] == FREE && !self.swept.covered[i] && !own[i] && once[i])
            .collect();
        let mut cells: Vec<usize> = (0..f.len()).filter(|&i| walled[i]).collect();
        let min_cells = (self.params.min_patch_area / (f.res * f.res)).ceil() as usize;
        drop_specks(&mut cells, &mut walled, f, min_cells.max(1));
        walled
    }

    /// The place to wait at for walled-off floor (`walled`) to clear, and
    /// the point of that floor nearest to it (to face: the scanner sees 240°):
    /// of the places the robot can get to (the travel costs from the robot
    /// must be up to date), the one nearest to [`LOOK_DISTANCE`] from that
    /// floor, the nearer by travel of two as near (the robot's own place
    /// when it is as near as any). `None` when there is no such floor.
    pub(super) fn look_place(&self, robot: usize, walled: &[bool]) -> Option<(usize, Point2<f64>)> {
        let f = self.cspace.frame;
        let away = chamfer_distance(f, walled);
        let want = LOOK_DISTANCE / f.res;
        let key = |j: usize| ((away[j] - want).abs().round(), self.cspace.dist[j]);
        let best = (0..f.len())
            .filter(|&j| self.regions.reachable[j] && self.cspace.dist[j].is_finite())
            .filter(|&j| away[j].is_finite())
            .min_by(|&a, &b| {
                let (ka, kb) = (key(a), key(b));
                ka.0.total_cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
            })?;
        let place = if away[robot].is_finite() && key(robot).0 <= key(best).0 {
            robot
        } else {
            best
        };
        let at = f.centre(place);
        let face = (0..f.len())
            .filter(|&i| walled[i])
            .map(|i| f.centre(i))
            .min_by(|a, b| (a - at).norm().total_cmp(&(b - at).norm()))?;
        Some((place, face))
    }

    /// The nearest reachable place with unexplored space in view (within
    /// `explore_view_distance`, along a line a scan would pass: see
    /// [`crate::plan::cspace::CSpace::sees_unknown_beside`]), and the frontier point to face
    /// there. A frontier no reachable place sees now is kept: it may come
    /// into reach later (through a way out, or once a passage is seen from
    /// closer); at the end it is reported (`unexplored_frontier`).
    pub(super) fn explore_goal_from(&mut self, _robot: usize) -> Option<(usize, Point2<f64>)> {
        let f = self.cspace.frame;
        let mut list = std::mem::take(&mut self.scratch.frontier);
        self.cspace.frontier(&mut list);
        list.retain(|&i| !self.tried.given_up[i]);
        // Drop speckle: frontier clusters smaller than the minimum.
        let keep = cluster_filter(&list, f, self.params.min_frontier_cells);
        let view = self.params.explore_view_distance;
        let vr = (view / f.res).ceil() as i64;
        let mut best: Option<(f64, usize, Point2<f64>)> = None;
        for &fi in &keep {
            let (x, y) = ((fi % f.w) as i64, (fi / f.w) as i64);
            let fp = f.centre(fi);
            for dy in (-vr..=vr).step_by(2) {
                for dx in (-vr..=vr).step_by(2) {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx as usize >= f.w || ny as usize >= f.h {
                        continue;
                    }
                    let j = ny as usize * f.w + nx as usize;
                    let d = self.cspace.dist[j];
                    if !self.regions.reachable[j] || !d.is_finite() {
                        continue;
                    }
                    if ((dx * dx + dy * dy) as f64).sqrt() * f.res > view {
                        continue;
                    }
                    // Only a place a scan would see the unexplored space
                    // from (checked for the nearest so far only).
                    if best.is_none_or(|(b, _, _)| d < b) && self.cspace.sees_unknown_beside(j, fi)
                    {
                        best = Some((d, j, fp));
                    }
                }
            }
        }
        self.scratch.frontier = list;
        best.map(|(_, j, fp)| (j, fp))
    }

    /// The way out of the robot's part of the space to another part with
    /// work left (uncovered floor the lanes could reach, or unexplored space
    /// in view), through a passage only the bare body fits; `None` when
    /// there is none, or after [`MAX_WAYS_OUT`] in a row.
    pub(super) fn way_out(&mut self, robot: usize, max_tight: f64) -> Option<Vec<Point2<f64>>> {
        if self.stalls.ways_out_in_a_row >= MAX_WAYS_OUT || max_tight <= 0.0 {
            return None;
        }
        let f = self.cspace.frame;
        let mut list = std::mem::take(&mut self.scratch.frontier);
        self.cspace.frontier(&mut list);
        list.retain(|&i| !self.tried.given_up[i]);
        let frontier = cluster_filter(&list, f, self.params.min_frontier_cells);
        self.scratch.frontier = list;
        let min_floor = self.min_patch_cells();
        let view = self.params.explore_view_distance;
        let vr = (view / f.res).ceil() as i64;
        let (covered, abandoned, reach_disk) =
            (&self.swept.covered, &self.tried.abandoned, &self.reach_disk);
        // Floor the robot's own part reaches is left to it (it found nothing
        // it could plan there): only what the other part alone reaches counts.
        let own = &self.regions.targets;
        let cs = &self.cspace;
        let state = &cs.state;
        let mut counted = vec![false; f.len()];
        let mut in_part = vec![false; f.len()];
        let has_work = |part: &[usize]| {
            // Uncovered floor its centres reach, and the robot's part does
            // not, in a patch the planner would cover (see `min_patch_area`).
            let mut floor = Vec::new();
            for &c in part {
                for j in f.around(c, reach_disk) {
                    if state[j] == FREE && !covered[j] && !abandoned[j] && !own[j] && !counted[j] {
                        counted[j] = true;
                        floor.push(j);
                    }
                }
            }
            let big = drop_specks(&mut floor, &mut counted, f, usize::MAX) >= min_floor;
            if big {
                return true;
            }
            // Unexplored space in view of one of its centres, along a
            // clear line (sampled as the exploration goal is).
            for &c in part {
                in_part[c] = true;
            }
            let seen = frontier.iter().any(|&fi| {
                let (x, y) = ((fi % f.w) as i64, (fi / f.w) as i64);
                (-vr..=vr).step_by(2).any(|dy| {
                    (-vr..=vr).step_by(2).any(|dx| {
                        let (nx, ny) = (x + dx, y + dy);
                        nx >= 0
                            && ny >= 0
                            && (nx as usize) < f.w
                            && (ny as usize) < f.h
                            && ((dx * dx + dy * dy) as f64).sqrt() * f.res <= view
                            && in_part[ny as usize * f.w + nx as usize]
                            && cs.sees_unknown_beside(ny as usize * f.w + nx as usize, fi)
                    })
                })
            });
            for &c in part {
                in_part[c] = false;
            }
            seen
        };
        crate::plan::unbox::way_out(
            &self.cspace,
            robot,
            &self.regions.reachable,
            max_tight,
            has_work,
        )
    }

    /// Starts driving a way out (see [`Self::way_out`]): the task it leaves
    /// is not charged a try, and ways out in a row are counted.
    pub(super) fn take_way_out(&mut self, path: Vec<Point2<f64>>) {
        self.current.forgive();
        self.stats.ways_out += 1;
        self.stalls.ways_out_in_a_row += 1;
        self.set_task(Task::Escape, path, None);
    }

    /// Whether the space reachable from the robot is smaller than its own
    /// footprint (see [`super::BOXED_IN_UPDATES`]).
    pub(super) fn boxed_in_now(&self) -> bool {
        self.regions.reachable_cells() < self.swept.footprint()
    }

    pub(super) fn frontier_in_view(&mut self, g: &Point2<f64>) -> bool {
        let mut list = std::mem::take(&mut self.scratch.frontier);
        self.cspace.frontier(&mut list);
        let f = self.cspace.frame;
        let view = self.params.explore_view_distance;
        let any = list
            .iter()
            .any(|&i| !self.tried.given_up[i] && (f.centre(i) - g).norm() <= view);
        self.scratch.frontier = list;
        any
    }

    /// Takes back every give-up of floor not swept yet (see [`Self::choose`]);
    /// false when there is none.
    pub(super) fn retry_given_up(&mut self) -> bool {
        let now = self.now();
        let any = self.tried.retry_given_up(&self.swept.covered, now);
        if any {
            self.compute_targets();
        }
        any
    }

    /// Whether floor given up may be tried again now: the first round
    /// always; up to [`MAX_EXTRA_RETRIES`] more while the last round swept
    /// at least `plan.min_patch_area` of the floor it tried again, or while
    /// [`super::GIVEN_UP_AGAIN`] or more is given up and `plan.clear_wait` has
    /// passed since the last round: people crossing the robot's paths had
    /// it given up, not the room (a room nobody walks through gives up a
    /// few tenths of a square metre at most).
    pub(super) fn may_retry_again(&self) -> bool {
        if !self.tried.retried {
            return true;
        }
        let a = self.cspace.frame.res * self.cspace.frame.res;
        let swept = self
            .tried
            .retry_set
            .iter()
            .filter(|&&i| self.swept.covered[i])
            .count() as f64
            * a;
        let waited = self.now() - self.tried.retry_at >= self.params.clear_wait;
        self.tried.extra_retries < MAX_EXTRA_RETRIES
            && (swept >= self.params.min_patch_area || (self.much_given_up() && waited))
    }

    /// Whether [`super::GIVEN_UP_AGAIN`] or more floor is given up, after its first
    /// round, with rounds left (see [`Self::may_retry_again`]).
    pub(super) fn much_given_up(&self) -> bool {
        let a = self.cspace.frame.res * self.cspace.frame.res;
        self.tried.much_given_up(&self.swept.covered, a)
    }

    /// Seen-free cells of the map.
    pub(super) fn known_free(&self) -> usize {
        self.cspace.state.iter().filter(|&&s| s == FREE).count()
    }

    /// Counts an exploration move (just ended) that showed less new floor
    /// than [`FRUITFUL_EXPLORE_CELLS`]; after [`MAX_FRUITLESS_EXPLORES`] in a
    /// row, gives up every frontier cell there is now (a wall seen at a
    /// grazing angle keeps showing new frontier cells as its cells flip
    /// between free and occupied: an endless walk along it otherwise).
    pub(super) fn count_fruitless_explore(&mut self) {
        let known_free = self.known_free();
        if !self
            .stalls
            .explore_ended(known_free, FRUITFUL_EXPLORE_CELLS, MAX_FRUITLESS_EXPLORES)
        {
            return;
        }
        let mut list = std::mem::take(&mut self.scratch.frontier);
        self.cspace.frontier(&mut list);
        for &i in &list {
            self.tried.give_up_around(self.cspace.frame, i);
        }
        self.scratch.frontier = list;
    }

    /// Frontier cells in view of `g` get one more try; at `limit` tries (0:
    /// at once) they are given up.
    pub(super) fn give_up_frontier_near(&mut self, g: &Point2<f64>, limit: u8) {
        let mut list = std::mem::take(&mut self.scratch.frontier);
        self.cspace.frontier(&mut list);
        let f = self.cspace.frame;
        let view = self.params.explore_view_distance;
        for &i in &list {
            if (f.centre(i) - g).norm() <= view + f.res {
                self.tried.charge_frontier(f, i, limit);
            }
        }
        self.scratch.frontier = list;
    }
}

/// Frontier cells in 8-connected clusters of at least `min` cells.
fn cluster_filter(list: &[usize], f: Frame, min: usize) -> Vec<usize> {
    let mut in_list = std::collections::HashSet::with_capacity(list.len());
    in_list.extend(list.iter().copied());
    let mut seen = std::collections::HashSet::with_capacity(list.len());
    let mut out = Vec::new();
    for &s in list {
        if seen.contains(&s) {
            continue;
        }
        let mut comp = vec![s];
        seen.insert(s);
        let mut k = 0;
        while k < comp.len() {
            let i = comp[k];
            k += 1;
            for j in f.neighbours8(i) {
                if in_list.contains(&j) && seen.insert(j) {
                    comp.push(j);
                }
            }
        }
        if comp.len() >= min {
            out.extend(comp);
        }
    }
    out
}

/// Per cell, the distance (cells) to the nearest cell marked in `marked`
/// (infinite when none is): a two-pass chamfer transform (steps of 1 and
/// √2), within 8 % of the straight-line distance.
fn chamfer_distance(f: Frame, marked: &[bool]) -> Vec<f64> {
    let (w, h) = (f.w, f.h);
    let mut d: Vec<f64> = marked
        .iter()
        .map(|&m| if m { 0.0 } else { f64::INFINITY })
        .collect();
    let diag = std::f64::consts::SQRT_2;
    let forward = [
        (-1i64, 0i64, 1.0),
        (-1, -1, diag),
        (0, -1, 1.0),
        (1, -1, diag),
    ];
    let relax = |d: &mut Vec<f64>, x: usize, y: usize, steps: &[(i64, i64, f64)]| {
        let i = y * w + x;
        for &(dx, dy, c) in steps {
            let (nx, ny) = (x as i64 + dx, y as i64 + dy);
            if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                let v = d[ny as usize * w + nx as usize] + c;
                if v < d[i] {
                    d[i] = v;
                }
            }
        }
    };
    for y in 0..h {
        for x in 0..w {
            relax(&mut d, x, y, &forward);
        }
    }
    let backward = forward.map(|(dx, dy, c)| (-dx, -dy, c));
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            relax(&mut d, x, y, &backward);
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chamfer_distances_are_within_8_percent_of_straight_lines() {
        let f = Frame {
            origin: Point2::new(0.0, 0.0),
            res: 0.05,
            w: 40,
            h: 30,
        };
        let mut marked = vec![false; f.len()];
        marked[10 * f.w + 5] = true;
        let d = chamfer_distance(f, &marked);
        for y in 0..f.h {
            for x in 0..f.w {
                let exact = (((x as f64) - 5.0).powi(2) + ((y as f64) - 10.0).powi(2)).sqrt();
                let got = d[y * f.w + x];
                assert!(
                    got >= exact - 1e-9 && got <= exact * 1.09 + 1e-9,
                    "({x}, {y}): {got} vs {exact}"
                );
            }
        }
        assert!(chamfer_distance(f, &vec![false; f.len()])
            .iter()
            .all(|v| v.is_infinite()));
    }
}
