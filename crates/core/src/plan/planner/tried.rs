//! Reach and tries: what the planner tried and failed on, what it gave
//! up, and where the robot could once get to.
//!
//! Tasks are interrupted (a transit blocked by furniture seen closer, a
//! person crossing the robot's path); their floor or frontier is charged a
//! try, and given up after a few, so the robot cannot go back and forth for
//! ever. Floor given up gets further rounds at the end, and the floor the
//! robot could once get to tells walled-off floor (a person in the way)
//! from floor that never was in reach. All of it survives a restart
//! ([`PlanTries`], [`PlanReach`]): the generations tell a daemon when to
//! copy it out.

use super::{FRONTIER_SPREAD, GIVEN_UP_AGAIN, MAX_EXTRA_RETRIES, MAX_FORGIVEN};
use crate::plan::cspace::Frame;
use crate::plan::swept::{PlanReach, PlanTries, TriedCell};

/// Tries, give-ups and places once within reach, per cell of the grid of
/// the last update, with the counts of rounds and waits.
#[derive(Default)]
pub(crate) struct ReachAndTries {
    /// Per cell: interruptions charged to it (saturating).
    pub(crate) tries: Vec<u8>,
    /// Per cell: floor given up as a cover target.
    pub(crate) abandoned: Vec<bool>,
    /// Per cell: leftover floor left by the end game (also abandoned).
    pub(crate) declined: Vec<bool>,
    /// Per cell: frontier given up as an exploration goal.
    pub(crate) given_up: Vec<bool>,
    /// Places the robot could get to with the full clearance at some
    /// decision of the run (see `CoveragePlanner::walled_off`).
    pub(crate) ever_reachable: Vec<bool>,
    /// Floor given up has had its second round (see `retry_given_up`).
    pub(crate) retried: bool,
    /// The floor the last round of given-up floor tried again (see
    /// `CoveragePlanner::may_retry_again`).
    pub(crate) retry_set: Vec<usize>,
    /// Rounds of given-up floor after the first (see [`MAX_EXTRA_RETRIES`]).
    pub(crate) extra_retries: usize,
    /// When the last round of given-up floor began (planner clock, s).
    pub(crate) retry_at: f64,
    /// Waits for walled-off floor begun in this run (see
    /// `MAX_CLEAR_WAITS`).
    pub(crate) clear_waits: usize,
    /// Swept cells when the count of forgiven interruptions was last reset.
    pub(crate) forgiven_at: usize,
    /// Interruptions forgiven since (see [`MAX_FORGIVEN`]).
    pub(crate) forgiven: usize,
    /// Bumped whenever floor first comes within reach or a wait or a
    /// further round is counted (see `CoveragePlanner::reach_generation`).
    pub(crate) reach_generation: u64,
    /// Bumped whenever tries, give-ups or `retried` change (see
    /// `CoveragePlanner::tries_generation`).
    pub(crate) tries_generation: u64,
    /// Records restored before the grid geometry was known: applied at the
    /// next update.
    pub(crate) restored_tries: Option<PlanTries>,
    pub(crate) restored_reach: Option<PlanReach>,
}

impl ReachAndTries {
    /// Starts the per-cell records afresh on a grid of `n` cells (the counts
    /// of rounds and waits are the run's, and stay).
    pub fn fit(&mut self, n: usize) {
        self.abandoned = vec![false; n];
        self.declined = vec![false; n];
        self.given_up = vec![false; n];
        self.ever_reachable = vec![false; n];
        self.tries = vec![0; n];
        self.tries_generation += 1;
    }

    /// Charges cell `i` one try; at `limit` it is abandoned as a target.
    pub(crate) fn charge(&mut self, i: usize, limit: u8) {
        self.tries[i] = self.tries[i].saturating_add(1);
        if self.tries[i] >= limit {
            self.abandoned[i] = true;
        }
        self.tries_generation += 1;
    }

    /// Charges frontier cell `i` of grid `f` one try; at `limit` (0: at
    /// once) it is given up with the cells beside it: the frontier along a
    /// wall seen at a grazing angle shifts by a cell or two as rays go on
    /// clearing and marking it, and must not come back as new frontier.
    pub(crate) fn charge_frontier(&mut self, f: Frame, i: usize, limit: u8) {
        self.tries[i] = self.tries[i].saturating_add(1);
        self.tries_generation += 1;
        if self.tries[i] >= limit {
            self.give_up_around(f, i);
        }
    }

    /// Gives up the floor `cells` as cover targets: the lanes cannot reach it.
    pub(crate) fn abandon(&mut self, cells: &[usize]) {
        for &i in cells {
            self.abandoned[i] = true;
        }
        self.tries_generation += 1;
    }

    /// Leaves the leftover floor `cells` (the end game): abandoned, and
    /// reported as declined.
    pub(crate) fn decline(&mut self, cells: &[usize]) {
        for &i in cells {
            self.abandoned[i] = true;
            self.declined[i] = true;
        }
    }

    /// Gives floor cell `i` its tries back.
    pub(crate) fn take_back(&mut self, i: usize) {
        self.abandoned[i] = false;
        self.tries[i] = 0;
    }

    /// Whether an interruption may be forgiven (see [`MAX_FORGIVEN`]), with
    /// `swept` cells swept so far and a footprint of `footprint` cells;
    /// counts it when so.
    pub(crate) fn may_forgive(&mut self, swept: usize, footprint: usize) -> bool {
        if swept >= self.forgiven_at + footprint {
            self.forgiven_at = swept;
            self.forgiven = 0;
        }
        let ok = self.forgiven < MAX_FORGIVEN;
        if ok {
            self.forgiven += 1;
        }
        ok
    }

    /// Gives up frontier cell `i` of grid `f` and the cells within
    /// [`FRONTIER_SPREAD`].
    pub(crate) fn give_up_around(&mut self, f: Frame, i: usize) {
        let (x, y) = ((i % f.w) as i64, (i / f.w) as i64);
        for dy in -FRONTIER_SPREAD..=FRONTIER_SPREAD {
            for dx in -FRONTIER_SPREAD..=FRONTIER_SPREAD {
                let (nx, ny) = (x + dx, y + dy);
                if nx >= 0 && ny >= 0 && (nx as usize) < f.w && (ny as usize) < f.h {
                    self.given_up[ny as usize * f.w + nx as usize] = true;
                }
            }
        }
        self.tries_generation += 1;
    }

    /// Adds the places `reachable` now to those once within reach; a new
    /// one bumps the reach generation.
    pub(crate) fn note_reachable(&mut self, reachable: &[bool]) {
        let mut grew = false;
        for (e, &r) in self.ever_reachable.iter_mut().zip(reachable) {
            grew |= r && !*e;
            *e |= r;
        }
        if grew {
            self.reach_generation += 1;
        }
    }

    /// Begins a round of given-up floor at `now` (planner clock, s): takes
    /// back every give-up of floor not `covered` and not declined; false
    /// when there is none.
    pub(crate) fn retry_given_up(&mut self, covered: &[bool], now: f64) -> bool {
        if self.retried {
            self.extra_retries += 1;
            self.reach_generation += 1;
        }
        self.retried = true;
        self.retry_at = now;
        self.tries_generation += 1;
        let mut any = false;
        self.retry_set.clear();
        for (i, (a, &c)) in self.abandoned.iter_mut().zip(covered).enumerate() {
            if *a && !c && !self.declined[i] {
                *a = false;
                self.tries[i] = 0;
                self.retry_set.push(i);
                any = true;
            }
        }
        any
    }

    /// Whether [`GIVEN_UP_AGAIN`] or more floor (cells of `cell_area` m²,
    /// not `covered`) is given up, after its first round, with rounds left
    /// (see `CoveragePlanner::may_retry_again`).
    pub(crate) fn much_given_up(&self, covered: &[bool], cell_area: f64) -> bool {
        let given_up = (0..self.abandoned.len())
            .filter(|&i| self.abandoned[i] && !covered[i] && !self.declined[i])
            .count() as f64
            * cell_area;
        self.retried && self.extra_retries < MAX_EXTRA_RETRIES && given_up >= GIVEN_UP_AGAIN
    }

    /// Sets the tries and give-ups of a record of the grid `frame`; a record
    /// of another geometry is ignored with a warning.
    pub(crate) fn apply_tries(&mut self, t: PlanTries, frame: Frame) {
        let n = self.tries.len();
        if t.frame != frame || t.cells.iter().any(|c| c.index as usize >= n) {
            log::warn!("planner tries record of a different map geometry ignored");
            return;
        }
        for c in &t.cells {
            let i = c.index as usize;
            self.tries[i] = c.tries;
            self.abandoned[i] = c.abandoned;
            self.given_up[i] = c.given_up;
        }
        self.retried |= t.retried;
        self.tries_generation += 1;
    }

    /// The cells tried and failed on, and what was given up, on the grid
    /// `frame` (`None` before the first update).
    pub(crate) fn tries_record(&self, frame: Frame) -> Option<PlanTries> {
        if self.tries.is_empty() {
            return None;
        }
        let cells = (0..self.tries.len())
            .filter(|&i| self.tries[i] > 0 || self.abandoned[i] || self.given_up[i])
            .map(|i| TriedCell {
                index: i as u32,
                tries: self.tries[i],
                abandoned: self.abandoned[i],
                given_up: self.given_up[i],
            })
            .collect();
        Some(PlanTries {
            frame,
            cells,
            retried: self.retried,
        })
    }

    /// Adds a record of the grid `frame`: the places once within reach join
    /// these, the counts are the larger of the two. A record of another
    /// geometry is ignored with a warning.
    pub(crate) fn apply_reach(&mut self, r: PlanReach, frame: Frame) {
        if r.frame != frame || r.ever_reachable.len() != self.ever_reachable.len() {
            log::warn!(
                "planner record of places once within reach of a different map geometry ignored"
            );
            return;
        }
        for (e, &o) in self.ever_reachable.iter_mut().zip(&r.ever_reachable) {
            *e |= o;
        }
        self.clear_waits = self.clear_waits.max(r.clear_waits as usize);
        self.extra_retries = self.extra_retries.max(r.extra_retries as usize);
        self.reach_generation += 1;
    }

    /// Where the robot could once get to, and its waits and further rounds
    /// so far, on the grid `frame` (`None` before the first update).
    pub(crate) fn reach_record(&self, frame: Frame) -> Option<PlanReach> {
        (!self.ever_reachable.is_empty()).then(|| PlanReach {
            frame,
            ever_reachable: self.ever_reachable.clone(),
            clear_waits: self.clear_waits as u32,
            extra_retries: self.extra_retries as u32,
        })
    }
}
