//! The swept record: what the tool has swept, how often, and when last.
//!
//! The planner keeps its own record from the poses it is given (not the
//! map's), so that a cell partly swept by transits or by neighbouring
//! lanes only gets the lanes it still needs, and travel prefers floor not
//! swept yet. It is the part a checkpoint saves as [`SweptFloor`].

use nalgebra::Point2;

use super::{cells_within, SAME_PASS_RECORDS};
use crate::plan::cspace::{disk, CSpace, Frame, FREE};
use crate::plan::swept::SweptFloor;

/// What the tool has swept, on the grid of the last update.
pub(crate) struct SweptRecord {
    /// Per cell: swept at least once.
    pub(crate) covered: Vec<bool>,
    /// Passes of the tool over each cell (saturating; see [`Self::record`]).
    pub(crate) passes: Vec<u8>,
    /// The pose record at which each cell was last under the tool.
    pub(crate) last_under: Vec<u32>,
    /// Pose records so far (starts at 1: 0 marks "never under the tool").
    pub(crate) records: u32,
    /// Per cell: share of the floor around it not yet swept twice (see
    /// [`Self::fresh_share`]).
    pub(crate) fresh: Vec<f32>,
    /// Summed-area table scratch for [`Self::fresh_share`]: free cells,
    /// cells swept less than twice.
    pub(crate) sat: Vec<[u32; 2]>,
    /// Cell offsets the tool sweeps around a pose (a little beyond
    /// [`Self::stamp_radius`]: [`cells_within`] keeps the exact ones).
    pub(crate) stamp: Vec<(i64, i64)>,
    /// Radius (m) of the floor the tool sweeps around a pose.
    pub(crate) stamp_radius: f64,
    /// A record restored before the grid geometry was known: merged at
    /// the next update.
    pub(crate) restored: Option<SweptFloor>,
}

impl SweptRecord {
    /// An empty record of a tool sweeping `stamp_radius` (m) around a pose.
    pub(crate) fn new(stamp_radius: f64) -> Self {
        Self {
            covered: Vec::new(),
            passes: Vec::new(),
            last_under: Vec::new(),
            records: 1,
            fresh: Vec::new(),
            sat: Vec::new(),
            stamp: Vec::new(),
            stamp_radius,
            restored: None,
        }
    }

    /// Starts the record afresh on a grid of `n` cells of `res` (m): the
    /// geometry changed, the cells no longer mean the same floor.
    pub fn fit(&mut self, n: usize, res: f64) {
        self.covered = vec![false; n];
        self.passes = vec![0; n];
        self.last_under = vec![0; n];
        self.stamp = disk(self.stamp_radius + res, res);
    }

    /// Cells the tool sweeps from one place: the robot's footprint, the
    /// measure of "a little" floor or space.
    pub(crate) fn footprint(&self) -> usize {
        self.stamp.len()
    }

    /// Cells swept so far.
    pub(crate) fn swept_cells(&self) -> usize {
        self.covered.iter().filter(|c| **c).count()
    }

    /// Records the tool at `p` on grid `f`: the floor around it is swept,
    /// and a pass counted where it was not under the tool just before.
    pub(crate) fn record(&mut self, f: Frame, p: &Point2<f64>) {
        self.records = self.records.saturating_add(1);
        for j in cells_within(f, p, &self.stamp, self.stamp_radius) {
            self.covered[j] = true;
            if self.last_under[j] == 0 || self.records - self.last_under[j] > SAME_PASS_RECORDS {
                self.passes[j] = self.passes[j].saturating_add(1);
            }
            self.last_under[j] = self.records;
        }
    }

    /// Adds the floor swept in `covered` (a restored record of the same
    /// geometry) to the record.
    pub(crate) fn merge(&mut self, covered: &[bool]) {
        for (c, s) in self.covered.iter_mut().zip(covered) {
            *c |= *s;
        }
        self.passes_from_covered();
    }

    /// Sets the swept passes from the swept record (after a restore: one
    /// pass where swept, the number of passes before is not saved).
    fn passes_from_covered(&mut self) {
        for (p, c) in self.passes.iter_mut().zip(&self.covered) {
            if *c && *p == 0 {
                *p = 1;
            }
        }
    }

    /// The record with its grid geometry `frame`, for a checkpoint (`None`
    /// before the first update, when there is no grid yet).
    pub(crate) fn snapshot(&self, frame: Frame) -> Option<SweptFloor> {
        (!self.covered.is_empty()).then(|| SweptFloor {
            frame,
            covered: self.covered.clone(),
        })
    }

    /// Per cell: the share of the free floor in a tool-sized square around
    /// it (`reach` m each side of it) that is not yet swept twice (from a
    /// summed-area table): driving there adds that floor to the overlap,
    /// now (floor swept once) or when its lane sweeps it later (floor not
    /// swept yet), while floor swept twice is overlap already. Left as it
    /// was (resized) when `new_overlap_cost` does not price it.
    pub(crate) fn fresh_share(&mut self, cs: &CSpace, reach: f64, new_overlap_cost: f64) {
        let f = cs.frame;
        let (w, h) = (f.w, f.h);
        self.fresh.resize(f.len(), 0.0);
        if new_overlap_cost <= 0.0 {
            return;
        }
        let k = (reach / f.res).floor() as usize;
        let sw = w + 1;
        self.sat.clear();
        self.sat.resize(sw * (h + 1), [0; 2]);
        for y in 0..h {
            let mut row = [0u32; 2];
            for x in 0..w {
                let i = y * w + x;
                if cs.state[i] == FREE {
                    row[0] += 1;
                    row[1] += u32::from(self.passes[i] < 2);
                }
                let up = self.sat[y * sw + x + 1];
                self.sat[(y + 1) * sw + x + 1] = [up[0] + row[0], up[1] + row[1]];
            }
        }
        for y in 0..h {
            let (y0, y1) = (y.saturating_sub(k), (y + k + 1).min(h));
            for x in 0..w {
                let (x0, x1) = (x.saturating_sub(k), (x + k + 1).min(w));
                let box_sum = |c: usize| {
                    self.sat[y1 * sw + x1][c] + self.sat[y0 * sw + x0][c]
                        - self.sat[y0 * sw + x1][c]
                        - self.sat[y1 * sw + x0][c]
                };
                let (free, fresh) = (box_sum(0), box_sum(1));
                self.fresh[y * w + x] = if free == 0 {
                    0.0
                } else {
                    fresh as f32 / free as f32
                };
            }
        }
    }
}
