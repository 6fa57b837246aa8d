//! The end of coverage: leftovers the end game leaves, and the report of
//! what is left once nothing reachable is.

use super::*;

impl CoveragePlanner {
    /// The end game: once the room has been toured and less than
    /// [`LEFTOVER_AREA`] of floor is left, a leftover whose fetching sweeps
    /// more floor again than `plan.leftover_ratio` times its own (travel
    /// to it, priced as transits are, × tool width) is left, worst first,
    /// while `plan.coverage_goal` of the places the bare body can reach
    /// (no safety margin: floor behind passages narrower than the margin
    /// counts as missed, as the ground truth counts it) stays swept or to
    /// be swept. Left floor is reported as declined (a resumed run fetches
    /// it again).
    pub(super) fn decline_leftovers(&mut self, cands: &mut Vec<Candidate>, robot: usize) {
        let goal = self.params.coverage_goal;
        let f = self.cspace.frame;
        let area = f.res * f.res;
        let total: usize = cands.iter().map(|c| c.targets.len()).sum();
        if goal >= 1.0 || !self.tour.toured || total as f64 * area > LEFTOVER_AREA {
            return;
        }
        let bare = crate::plan::unbox::bare_body_reach(&self.cspace, robot);
        let known = bare.iter().filter(|&&b| b).count();
        let in_bare = |c: &Candidate| c.targets.iter().filter(|&&i| bare[i]).count();
        let swept = (0..f.len())
            .filter(|&i| bare[i] && self.swept.covered[i])
            .count();
        let mut kept: usize = swept + cands.iter().map(in_bare).sum::<usize>();
        let tool = 2.0 * self.reach;
        let ratio = |c: &Candidate| c.cost() * tool / (c.targets.len().max(1) as f64 * area);
        let mut order: Vec<usize> = (0..cands.len()).collect();
        order.sort_by(|&x, &y| ratio(&cands[y]).total_cmp(&ratio(&cands[x])));
        let mut keep = vec![true; cands.len()];
        for j in order {
            let c = &cands[j];
            let (r, lost) = (ratio(c), in_bare(c));
            if r <= self.params.leftover_ratio || ((kept - lost) as f64) < goal * known as f64 {
                continue;
            }
            kept -= lost;
            keep[j] = false;
            log::info!(
                "leaving {:.3} m² of leftover floor: fetching it would sweep {r:.0}x as much again (plan.leftover_ratio {})",
                c.targets.len() as f64 * area,
                self.params.leftover_ratio
            );
            self.tried.decline(&c.targets);
        }
        let mut k = keep.iter();
        cands.retain(|_| k.next().copied().unwrap_or(true));
    }

    /// What is left at the end; the reachable centres
    /// (`reachable_mask`) must be this decision's.
    pub(super) fn done_report(&self, robot: usize) -> DoneReport {
        let f = self.cspace.frame;
        let a = f.res * f.res;
        let touch = body_touch(&self.cspace, robot);
        let own = touch_from(&self.cspace, &self.regions.reachable);
        let mut r = DoneReport::default();
        for (i, &t) in touch.iter().enumerate() {
            if self.cspace.state[i] == FREE && !t {
                r.unreachable_area += a;
            }
            if self.cspace.state[i] == FREE && t && !own[i] && !self.swept.covered[i] {
                r.behind_tight_passages += a;
            } else if self.tried.declined[i] && !self.swept.covered[i] {
                r.declined_area += a;
            } else if self.tried.abandoned[i] && !self.swept.covered[i] {
                r.abandoned_area += a;
            }
            if self.swept.covered[i] {
                r.covered_area += a;
            }
        }
        let mut frontier = Vec::new();
        self.cspace.frontier(&mut frontier);
        r.unexplored_frontier = frontier.len() as f64 * f.res;
        r
    }
}

/// The cells the body touches from some place the robot at `robot` can get
/// to (passages only the bare body fits included): seen free floor outside
/// it is floor no reachable centre can sweep.
fn body_touch(cs: &CSpace, robot: usize) -> Vec<bool> {
    touch_from(cs, &crate::plan::unbox::reachable_with_ways_out(cs, robot))
}

/// The cells the body touches (generously: the clearance and two cells)
/// from the places marked in `places`.
pub(super) fn touch_from(cs: &CSpace, places: &[bool]) -> Vec<bool> {
    let f = cs.frame;
    let body = disk(cs.inflation() + 2.0 * f.res, f.res);
    let mut touch = vec![false; f.len()];
    for i in (0..f.len()).filter(|&i| places[i]) {
        for j in f.around(i, &body) {
            touch[j] = true;
        }
    }
    touch
}
