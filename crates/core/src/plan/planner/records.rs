//! The planner's records a restart needs (swept floor, the lane lattice's
//! phase, the start, tries and give-ups, floor once within reach): taken
//! out together as a [`PlanSnapshot`] for the checkpoint and put back
//! together after a restart ([`CoveragePlanner::snapshot`],
//! [`CoveragePlanner::restore`]).

use std::sync::Arc;

use super::CoveragePlanner;
use crate::plan::swept::{HomePlace, LatticePhase, PlanReach, PlanTries, SweptFloor};

/// Everything a restarted planner needs to go on where it stopped, as plain
/// data (a daemon stores each record as a section of its own, so that one
/// unreadable record costs only itself). `None`: the planner has no such
/// record (yet), or the checkpoint held none; the planner then starts it
/// afresh. The records are shared (`Arc`): a snapshot is cheap to copy, and
/// the next one reuses what did not change.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlanSnapshot {
    /// What the tool has swept.
    pub swept: Option<Arc<SweptFloor>>,
    /// The phase of the lane lattice.
    pub lattice: Option<LatticePhase>,
    /// Where the robot started.
    pub home: Option<HomePlace>,
    /// The cells tried and failed on, and what was given up.
    pub tries: Option<Arc<PlanTries>>,
    /// Where the robot could once get to, the waits and further rounds.
    pub reach: Option<Arc<PlanReach>>,
    /// The generations of [`Self::tries`] and [`Self::reach`] (see
    /// [`CoveragePlanner::tries_generation`]): the next snapshot copies a
    /// record out again only when its generation moved on.
    generations: (u64, u64),
}

/// A record that changed at `generation`: `get`'s when `generation` is not
/// `seen` and `get` has one, with `generation` as the one now seen; else
/// `last` and `seen` (unchanged, or nothing to copy out yet).
fn refreshed<T>(
    generation: u64,
    seen: u64,
    last: &Option<Arc<T>>,
    get: impl FnOnce() -> Option<T>,
) -> (Option<Arc<T>>, u64) {
    if generation != seen {
        if let Some(record) = get() {
            return (Some(Arc::new(record)), generation);
        }
    }
    (last.clone(), seen)
}

impl CoveragePlanner {
    /// What a restart needs of the planner now, for a checkpoint. Each
    /// record the planner has none of yet (before its first update; the
    /// lattice before the first lanes) is `last`'s: the records restored
    /// from the checkpoint stand until the planner has its own. The tries
    /// and the reach are copied out only when they changed since `last`
    /// (each is a scan of the whole grid); pass the previous snapshot, or
    /// the one restored, or a default one.
    pub fn snapshot(&self, last: &PlanSnapshot) -> PlanSnapshot {
        let lattice = self.lattice();
        let (tries_seen, reach_seen) = last.generations;
        let (tries, tries_seen) =
            refreshed(self.tries_generation(), tries_seen, &last.tries, || {
                self.tries()
            });
        let (reach, reach_seen) =
            refreshed(self.reach_generation(), reach_seen, &last.reach, || {
                self.reach()
            });
        PlanSnapshot {
            swept: self.swept().map(Arc::new).or_else(|| last.swept.clone()),
            lattice: (lattice != LatticePhase::default())
                .then_some(lattice)
                .or(last.lattice),
            home: self.home().or(last.home),
            tries,
            reach,
            generations: (tries_seen, reach_seen),
        }
    }

    /// Puts back the records of `snapshot` (taken by [`Self::snapshot`]
    /// before a restart), each as its own `restore_*` does: the swept floor,
    /// the tries and the reach are applied on the next update when the grid
    /// geometry is not known yet, and a record of another geometry is
    /// ignored with a warning.
    pub fn restore(&mut self, snapshot: &PlanSnapshot) {
        if let Some(s) = &snapshot.swept {
            self.restore_swept(SweptFloor::clone(s));
        }
        if let Some(l) = snapshot.lattice {
            self.restore_lattice(l);
        }
        if let Some(h) = snapshot.home {
            self.restore_home(h);
        }
        if let Some(r) = &snapshot.reach {
            self.restore_reach(PlanReach::clone(r));
        }
        if let Some(t) = &snapshot.tries {
            self.restore_tries(PlanTries::clone(t));
        }
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decomp::Decomposition;
    use crate::geom::pose;
    use crate::plan::test_support::{planner, walled_room};

    #[test]
    fn a_snapshot_restored_gives_the_same_records_and_unchanged_ones_are_reused() {
        let grid = walled_room();
        let empty = Decomposition::default();
        let start = pose(0.6, 0.6, 0.3);
        let mut a = planner();
        let none = a.snapshot(&PlanSnapshot::default());
        assert_eq!(none, PlanSnapshot::default(), "no records before an update");
        a.update(&grid, &empty, &start, None).unwrap();
        for k in 0..100 {
            a.record_pose(&pose(0.6 + 0.02 * f64::from(k), 0.6, 0.0));
        }
        a.update(&grid, &empty, &start, None).unwrap();
        let saved = a.snapshot(&PlanSnapshot::default());
        assert!(saved.swept.is_some() && saved.home.is_some() && saved.reach.is_some());
        // Nothing changed since: the tries and the reach are the same copies.
        let again = a.snapshot(&saved);
        assert!(Arc::ptr_eq(
            again.reach.as_ref().unwrap(),
            saved.reach.as_ref().unwrap()
        ));
        assert_eq!(again, saved);

        // Restored before its first update, a planner's snapshot is the one
        // restored; after it, the same records as the planner it came from.
        let mut b = planner();
        b.restore(&saved);
        assert_eq!(b.snapshot(&saved), saved);
        b.update(&grid, &empty, &pose(1.0, 0.6, 0.0), None).unwrap();
        let back = b.snapshot(&PlanSnapshot::default());
        assert_eq!(back.swept, saved.swept);
        assert_eq!(back.home, saved.home, "the start, not the resume pose");
        assert_eq!(back.lattice, saved.lattice);
        assert_eq!(b.covered(), a.covered());
    }
}
