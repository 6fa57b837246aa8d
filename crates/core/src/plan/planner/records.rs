//! The planner's records a restart needs (tries and give-ups, floor once
//! within reach, swept floor, the lane lattice's phase): taken out for the
//! checkpoint and put back after a restart.

use super::*;
use crate::plan::lanes::Axis;
use crate::plan::swept::{LatticePhase, PlanReach, PlanTries, SweptFloor, TriedCell};

impl CoveragePlanner {
    /// Sets the tries and give-ups of a record of this grid's geometry.
    pub(super) fn apply_tries(&mut self, t: PlanTries) {
        let n = self.tries.len();
        if t.frame != self.cspace.frame || t.cells.iter().any(|c| c.index as usize >= n) {
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

    /// Changes whenever the record of [`Self::tries`] changes: a daemon
    /// copies the record out only then (it scans the whole grid).
    pub fn tries_generation(&self) -> u64 {
        self.tries_generation
    }

    /// The cells the planner has tried and failed on, and what it gave up,
    /// for a checkpoint (`None` before the first update).
    pub fn tries(&self) -> Option<PlanTries> {
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
            frame: self.cspace.frame,
            cells,
            retried: self.retried,
        })
    }

    /// Restores a record saved by [`Self::tries`], as
    /// [`Self::restore_swept`] does: applied on the next update when the
    /// grid geometry is not known yet; a record of another geometry is
    /// ignored with a warning.
    pub fn restore_tries(&mut self, tries: PlanTries) {
        if self.tries.is_empty() {
            self.restored_tries = Some(tries);
        } else {
            self.apply_tries(tries);
        }
    }

    /// Changes whenever the record of [`Self::reach`] changes: a daemon
    /// copies the record out only then.
    pub fn reach_generation(&self) -> u64 {
        self.reach_generation
    }

    /// Where the robot could once get to, and its waits and further rounds
    /// so far, for a checkpoint (`None` before the first update).
    pub fn reach(&self) -> Option<PlanReach> {
        (!self.ever_reachable.is_empty()).then(|| PlanReach {
            frame: self.cspace.frame,
            ever_reachable: self.ever_reachable.clone(),
            clear_waits: self.clear_waits as u32,
            extra_retries: self.extra_retries as u32,
        })
    }

    /// Restores a record saved by [`Self::reach`], as
    /// [`Self::restore_tries`] does: applied on the next update when the
    /// grid geometry is not known yet; a record of another geometry is
    /// ignored with a warning.
    pub fn restore_reach(&mut self, reach: PlanReach) {
        if self.ever_reachable.is_empty() {
            self.restored_reach = Some(reach);
        } else {
            self.apply_reach(reach);
        }
    }

    /// Adds a record of this grid's geometry: the places once within reach
    /// join the planner's, the counts are the larger of the two.
    pub(super) fn apply_reach(&mut self, r: PlanReach) {
        if r.frame != self.cspace.frame || r.ever_reachable.len() != self.ever_reachable.len() {
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

    /// Charges cell `i` one try; at `limit` it is abandoned as a target.
    pub(super) fn charge_try(&mut self, i: usize, limit: u8) {
        self.tries[i] = self.tries[i].saturating_add(1);
        if self.tries[i] >= limit {
            self.abandoned[i] = true;
        }
        self.tries_generation += 1;
    }

    /// The record of swept floor with its grid geometry, for a checkpoint
    /// (`None` before the first update, when there is no grid yet).
    pub fn swept(&self) -> Option<SweptFloor> {
        (!self.covered.is_empty()).then(|| SweptFloor {
            frame: self.cspace.frame,
            covered: self.covered.clone(),
        })
    }

    /// Restores a record of swept floor saved by [`CoveragePlanner::swept`]:
    /// it is merged into the planner's record on the next update, when the
    /// map (restored from the same checkpoint) gives the grid geometry. A
    /// record of another geometry is ignored with a warning.
    pub fn restore_swept(&mut self, swept: SweptFloor) {
        if self.cspace.frame == swept.frame && self.covered.len() == swept.covered.len() {
            for (c, s) in self.covered.iter_mut().zip(&swept.covered) {
                *c |= *s;
            }
            self.passes_from_covered();
        } else {
            self.restored = Some(swept);
        }
    }

    /// The phase of the lane lattice, for a checkpoint (see [`LatticePhase`]).
    pub fn lattice(&self) -> LatticePhase {
        LatticePhase {
            x: self.phase[Axis::X as usize],
            y: self.phase[Axis::Y as usize],
        }
    }

    /// Restores a lattice phase saved by [`CoveragePlanner::lattice`]: the
    /// lanes planned from now on lie on the lattice of the lanes driven
    /// before the restart. Non-finite values are ignored.
    pub fn restore_lattice(&mut self, lattice: LatticePhase) {
        for (k, v) in [(Axis::X, lattice.x), (Axis::Y, lattice.y)] {
            if let Some(p) = v.filter(|p| p.is_finite()) {
                self.phase[k as usize] = Some(p);
            }
        }
    }
}
