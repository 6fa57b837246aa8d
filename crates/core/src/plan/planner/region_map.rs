//! The region map of the last decision: which places the robot can get
//! to, which floor is a target, which reachable centre and which region
//! owns each floor cell, which slivers are lent to a neighbour; and the
//! lane lattice's phase, fixed at its first use for the whole run.
//!
//! Computed afresh at each decision (`CoveragePlanner::compute_targets`,
//! `CoveragePlanner::mark_cells`) and read by the candidate regions, the
//! exploration goals and the end of the run; only the phase persists
//! (a checkpoint saves it as [`LatticePhase`]).

use crate::plan::cspace::Frame;
use crate::plan::lanes::Axis;
use crate::plan::swept::LatticePhase;

/// Per cell of the grid of the last decision: reachability, targets,
/// owners and regions; and the lane lattice.
#[derive(Default)]
pub(crate) struct RegionMap {
    /// Per cell: a centre the robot can get to with the full clearance.
    pub(crate) reachable: Vec<bool>,
    /// Per cell: floor not swept and not given up, within the tool's reach
    /// of a reachable centre.
    pub(crate) targets: Vec<bool>,
    /// Per floor cell, its nearest reachable centre (`u32::MAX`: none).
    pub(crate) owner: Vec<u32>,
    /// Per reachable centre, the region holding it: the index (in the
    /// current decomposition) of its cell, or of the cell that sliver is lent
    /// to (see `CoveragePlanner::mark_cells`); `u32::MAX` outside every cell.
    pub(crate) region_of: Vec<u32>,
    /// Per cell of the current decomposition (by index), the index of the
    /// neighbour it is lent to when it is a sliver.
    pub(crate) lent_to: Vec<Option<usize>>,
    /// Per axis and floor cell, the reachable centre whose region the floor
    /// belongs to (see `CoveragePlanner::floor_owner`), `u32::MAX` for none,
    /// or `OWNER_UNSET` until asked; cleared at every
    /// `CoveragePlanner::cell_candidates`, since it follows the regions.
    pub(crate) floor_owner: [Vec<u32>; 2],
    /// Lane lattice phase per axis (see [`Self::lattice_phase`]).
    pub(crate) phase: [Option<f64>; 2],
}

impl RegionMap {
    /// Fits the per-cell maps to a grid of `n` cells.
    pub fn fit(&mut self, n: usize) {
        self.reachable = vec![false; n];
        self.targets = vec![false; n];
        self.owner = vec![u32::MAX; n];
        self.region_of = vec![u32::MAX; n];
    }

    /// Reachable centres of the last decision.
    pub(crate) fn reachable_cells(&self) -> usize {
        self.reachable.iter().filter(|&&r| r).count()
    }

    /// The phase of the lane lattice along `axis`, fixed for the whole run
    /// at its first use: a lane hugs the lowest wall (across the lanes) of
    /// the space reachable then (on grid `f`).
    pub(crate) fn lattice_phase(&mut self, axis: Axis, f: Frame) -> f64 {
        let k = axis as usize;
        if let Some(p) = self.phase[k] {
            return p;
        }
        let lowest = (0..f.len())
            .filter(|&i| self.reachable[i])
            .map(|i| {
                let c = f.centre(i);
                match axis {
                    Axis::X => c.y,
                    Axis::Y => c.x,
                }
            })
            .fold(f64::INFINITY, f64::min);
        let p = if lowest.is_finite() { lowest } else { 0.0 };
        self.phase[k] = Some(p);
        p
    }

    /// The lattice phase, for a checkpoint.
    pub(crate) fn lattice(&self) -> LatticePhase {
        LatticePhase {
            x: self.phase[Axis::X as usize],
            y: self.phase[Axis::Y as usize],
        }
    }

    /// Restores a lattice phase; non-finite values are ignored.
    pub(crate) fn restore_lattice(&mut self, lattice: LatticePhase) {
        for (k, v) in [(Axis::X, lattice.x), (Axis::Y, lattice.y)] {
            if let Some(p) = v.filter(|p| p.is_finite()) {
                self.phase[k as usize] = Some(p);
            }
        }
    }
}
