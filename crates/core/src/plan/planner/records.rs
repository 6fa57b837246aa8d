//! The planner's records a restart needs (tries and give-ups, floor once
//! within reach, swept floor, the lane lattice's phase): taken out for the
//! checkpoint and put back after a restart.

use super::CoveragePlanner;
use crate::plan::swept::{LatticePhase, PlanReach, PlanTries, SweptFloor};

impl CoveragePlanner {
    /// Changes whenever the record of [`Self::tries`] changes: a daemon
    /// copies the record out only then (it scans the whole grid).
    pub fn tries_generation(&self) -> u64 {
        self.tried.tries_generation
    }

    /// The cells the planner has tried and failed on, and what it gave up,
    /// for a checkpoint (`None` before the first update).
    pub fn tries(&self) -> Option<PlanTries> {
        self.tried.tries_record(self.cspace.frame)
    }

    /// Restores a record saved by [`Self::tries`], as
    /// [`Self::restore_swept`] does: applied on the next update when the
    /// grid geometry is not known yet; a record of another geometry is
    /// ignored with a warning.
    pub fn restore_tries(&mut self, tries: PlanTries) {
        if self.tried.tries.is_empty() {
            self.tried.restored_tries = Some(tries);
        } else {
            self.tried.apply_tries(tries, self.cspace.frame);
        }
    }

    /// Changes whenever the record of [`Self::reach`] changes: a daemon
    /// copies the record out only then.
    pub fn reach_generation(&self) -> u64 {
        self.tried.reach_generation
    }

    /// Where the robot could once get to, and its waits and further rounds
    /// so far, for a checkpoint (`None` before the first update).
    pub fn reach(&self) -> Option<PlanReach> {
        self.tried.reach_record(self.cspace.frame)
    }

    /// Restores a record saved by [`Self::reach`], as
    /// [`Self::restore_tries`] does: applied on the next update when the
    /// grid geometry is not known yet; a record of another geometry is
    /// ignored with a warning.
    pub fn restore_reach(&mut self, reach: PlanReach) {
        if self.tried.ever_reachable.is_empty() {
            self.tried.restored_reach = Some(reach);
        } else {
            self.tried.apply_reach(reach, self.cspace.frame);
        }
    }

    /// The record of swept floor with its grid geometry, for a checkpoint
    /// (`None` before the first update, when there is no grid yet).
    pub fn swept(&self) -> Option<SweptFloor> {
        self.swept.snapshot(self.cspace.frame)
    }

    /// Restores a record of swept floor saved by [`CoveragePlanner::swept`]:
    /// it is merged into the planner's record on the next update, when the
    /// map (restored from the same checkpoint) gives the grid geometry. A
    /// record of another geometry is ignored with a warning.
    pub fn restore_swept(&mut self, swept: SweptFloor) {
        if self.cspace.frame == swept.frame && self.swept.covered.len() == swept.covered.len() {
            self.swept.merge(&swept.covered);
        } else {
            self.swept.restored = Some(swept);
        }
    }

    /// The phase of the lane lattice, for a checkpoint (see [`LatticePhase`]).
    pub fn lattice(&self) -> LatticePhase {
        self.regions.lattice()
    }

    /// Restores a lattice phase saved by [`CoveragePlanner::lattice`]: the
    /// lanes planned from now on lie on the lattice of the lanes driven
    /// before the restart. Non-finite values are ignored.
    pub fn restore_lattice(&mut self, lattice: LatticePhase) {
        self.regions.restore_lattice(lattice);
    }
}
