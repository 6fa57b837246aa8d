//! Regions to cover: the floor targets, the lane lattice and which region
//! owns which floor, and each final cell (or leftover patch) as a candidate
//! with its lanes and their cost from the robot.

use nalgebra::Point2;

use super::{Candidate, CoveragePlanner};
use crate::decomp::{CellId, CellStatus, Decomposition};
use crate::plan::cspace::{Frame, FREE};
use crate::plan::lanes::{lanes, lattice_position, turn_join, variants, Axis, LaneInput};

/// Uncovered floor in clusters smaller than this (grid cells) is left to
/// lanes passing anyway: single cells at lane ends along a wall, where no
/// connection passes, are not worth a lane of their own.
const MIN_TARGET_CLUSTER: usize = 4;

/// [`CoveragePlanner::floor_owner`]: floor not asked about yet.
const OWNER_UNSET: u32 = u32::MAX - 1;

impl CoveragePlanner {
    /// Marks reachable centres, the uncovered floor they reach, and for every
    /// floor cell its nearest reachable centre (its owner: the region that
    /// covers it).
    pub(super) fn compute_targets(&mut self) {
        let f = self.cspace.frame;
        for i in 0..f.len() {
            self.regions.reachable[i] =
                self.cspace.traversable[i] && self.cspace.dist[i].is_finite();
            self.regions.targets[i] = false;
            self.regions.owner[i] = if self.regions.reachable[i] {
                i as u32
            } else {
                u32::MAX
            };
        }
        // The flood starts from the reachable centres beside seen-free
        // floor they do not cover themselves (the others have nothing to
        // pass on), in index order as before.
        let mut queue: std::collections::VecDeque<usize> = (0..f.len())
            .filter(|&i| {
                self.regions.reachable[i]
                    && f.neighbours8(i)
                        .any(|j| !self.regions.reachable[j] && self.cspace.state[j] == FREE)
            })
            .collect();
        let limit = self.reach + f.res;
        while let Some(i) = queue.pop_front() {
            let o = self.regions.owner[i] as usize;
            let oc = f.centre(o);
            for j in f.neighbours8(i) {
                if self.regions.owner[j] == u32::MAX
                    && self.cspace.state[j] == FREE
                    && (f.centre(j) - oc).norm() <= limit
                {
                    self.regions.owner[j] = o as u32;
                    queue.push_back(j);
                }
            }
        }
        // Floor within reach of a reachable centre (a centre inside the
        // reachable space adds only itself: see `four_neighbours_in`).
        for i in 0..f.len() {
            if !self.regions.reachable[i] {
                continue;
            }
            if four_neighbours_in(&self.regions.reachable, f, i) {
                if self.open_floor(i) {
                    self.regions.targets[i] = true;
                }
                continue;
            }
            for j in f.around(i, &self.reach_disk) {
                if self.open_floor(j) {
                    self.regions.targets[j] = true;
                }
            }
        }
        self.tour.decided.clone_from(&self.regions.targets);
    }

    /// Seen-free floor not swept yet and not given up: a target wherever
    /// the tool can reach it.
    pub(super) fn open_floor(&self, j: usize) -> bool {
        self.cspace.state[j] == FREE && !self.swept.covered[j] && !self.tried.abandoned[j]
    }

    /// The reachable centre on floor cell `j`'s nearest lattice lane (same
    /// position along the lanes), `None` when that lane lies in a wall.
    fn lattice_owner(&self, j: usize, axis: Axis, phase: f64) -> Option<usize> {
        let f = self.cspace.frame;
        let c = f.centre(j);
        let (across, o, n) = match axis {
            Axis::X => (c.y, f.origin.y, f.h),
            Axis::Y => (c.x, f.origin.x, f.w),
        };
        let p = lattice_position(phase, self.spacing, across);
        let row = ((p - o) / f.res).floor();
        if row < 0.0 || row >= n as f64 {
            return None;
        }
        let row = row as usize;
        let k = match axis {
            Axis::X => row * f.w + j % f.w,
            Axis::Y => (j / f.w) * f.w + row,
        };
        (self.regions.region_of[k] != u32::MAX).then_some(k)
    }

    /// The reachable centre whose region floor cell `j` belongs to: the one
    /// on its nearest lattice lane (across a virtual edge: the neighbour's);
    /// where that lane lies in a wall, its nearest reachable centre (that
    /// region hugs the wall). As an index, `u32::MAX` for none; remembered in
    /// `owners` (this axis's [`Self::floor_owner`] table).
    fn floor_owner(&self, owners: &mut [u32], j: usize, axis: Axis, phase: f64) -> usize {
        if owners[j] == OWNER_UNSET {
            owners[j] = match self.lattice_owner(j, axis, phase) {
                Some(k) => k as u32,
                None => self.regions.owner[j],
            };
        }
        owners[j] as usize
    }

    /// Marks the reachable centres that lie inside a cell (any status), and
    /// lends each sliver to a neighbour.
    ///
    /// A sliver is a cell with fewer reachable centres than the smallest
    /// patch worth a drive: it can never be a region of its own, yet floor
    /// beside it whose nearest lattice lane lies in it belongs to it (see
    /// [`Self::region_candidate`]), so that floor would be left to neither
    /// neighbour. A sliver is lent to the neighbour of the same status that
    /// is no sliver and shares the longest boundary with it; that neighbour
    /// covers it as part of itself.
    pub(super) fn mark_cells(&mut self, decomp: &Decomposition) {
        let f = self.cspace.frame;
        self.regions.region_of.fill(u32::MAX);
        let mut centres = vec![0usize; decomp.cells.len()];
        for (n, cell) in decomp.cells.iter().enumerate() {
            if cell.polygon.len() < 3 {
                continue;
            }
            let Some((x0, y0, x1, y1)) = cell_bbox(cell, &f) else {
                continue;
            };
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let i = y * f.w + x;
                    if self.regions.reachable[i]
                        && self.regions.region_of[i] == u32::MAX
                        && cell.contains(&f.centre(i))
                    {
                        self.regions.region_of[i] = n as u32;
                        centres[n] += 1;
                    }
                }
            }
        }
        let min = self.min_patch_cells();
        let index = |id: CellId| decomp.cells.iter().position(|c| c.id == id);
        self.regions.lent_to.clear();
        for (n, cell) in decomp.cells.iter().enumerate() {
            let sliver = cell.status != CellStatus::Open && (1..min).contains(&centres[n]);
            if !sliver {
                self.regions.lent_to.push(None);
                continue;
            }
            let mut best: Option<(f64, usize)> = None;
            for adj in &decomp.adjacency {
                let other = if adj.a == cell.id {
                    adj.b
                } else if adj.b == cell.id {
                    adj.a
                } else {
                    continue;
                };
                let Some(m) = index(other) else {
                    continue;
                };
                let shared = adj.boundary.length();
                if decomp.cells[m].status == cell.status
                    && centres[m] >= min
                    && best.is_none_or(|(l, _)| shared > l)
                {
                    best = Some((shared, m));
                }
            }
            self.regions.lent_to.push(best.map(|(_, m)| m));
        }
        for r in self
            .regions
            .region_of
            .iter_mut()
            .filter(|r| **r != u32::MAX)
        {
            if let Some(host) = self.regions.lent_to[*r as usize] {
                *r = host as u32;
            }
        }
    }

    /// The smallest patch worth a drive (grid cells, `plan.min_patch_area`).
    pub(super) fn min_patch_cells(&self) -> usize {
        self.area_cells(self.params.min_patch_area).max(1)
    }

    /// Grid cells in `area` (m²), rounded up (a float error just above a
    /// whole number of cells does not count as one more).
    fn area_cells(&self, area: f64) -> usize {
        let a = self.cspace.frame.res * self.cspace.frame.res;
        (area / a - 1e-9).ceil().max(0.0) as usize
    }

    /// The smallest leftover patch worth a drive at clean-up (grid cells):
    /// [`Self::min_patch_cells`], or `plan.min_patch_share` of the reachable
    /// floor where that is less, so that in a small room no single patch
    /// left costs more than that share (one 0.06 m² corner is 1 % of a
    /// 6 m² room).
    fn cleanup_patch_cells(&self) -> usize {
        let reachable = self.regions.reachable_cells() as f64;
        let share = (self.params.min_patch_share * reachable).ceil() as usize;
        let min = self.min_patch_cells();
        if share == 0 {
            min
        } else {
            min.min(share.max(MIN_TARGET_CLUSTER))
        }
    }

    /// Lanes and cost for a region given by its admissible mask (in
    /// `scratch_a`) over `bbox`; targets are those within reach, and the
    /// region needs a patch of at least `min` of them (grid cells).
    fn region_candidate(
        &mut self,
        cell: Option<CellId>,
        bbox: (usize, usize, usize, usize),
        axis: Axis,
        min: usize,
    ) -> Option<Candidate> {
        let f = self.cspace.frame;
        let phase = self.regions.lattice_phase(axis, f);
        let r = (self.reach / f.res).ceil() as usize + 1;
        let (x0, y0) = (bbox.0.saturating_sub(r), bbox.1.saturating_sub(r));
        let (x1, y1) = ((bbox.2 + r).min(f.w - 1), (bbox.3 + r).min(f.h - 1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                self.scratch.targets[y * f.w + x] = false;
            }
        }
        let mut targets = Vec::new();
        // A patch (no cell) takes all its floor and asks no owner.
        let mut owners = std::mem::take(&mut self.regions.floor_owner[axis as usize]);
        if cell.is_some() && owners.len() != f.len() {
            owners.clear();
            owners.resize(f.len(), OWNER_UNSET);
        }
        // A centre inside the region reaches nothing its neighbours do
        // not, but itself (see `four_neighbours_in`).
        let (inner, ring) = ([(0, 0)], &self.reach_disk);
        for y in bbox.1..=bbox.3 {
            for x in bbox.0..=bbox.2 {
                let i = y * f.w + x;
                if !self.scratch.admissible[i] {
                    continue;
                }
                let within = four_neighbours_in(&self.scratch.admissible, f, i);
                let disk: &[(i64, i64)] = if within { &inner } else { ring };
                for j in f.around(i, disk) {
                    if !self.regions.targets[j] || self.scratch.targets[j] {
                        continue;
                    }
                    // Floor belongs to one region: see `floor_owner`.
                    let own = cell.is_none() || {
                        let k = self.floor_owner(&mut owners, j, axis, phase);
                        k < f.len() && self.scratch.admissible[k]
                    };
                    if own {
                        self.scratch.targets[j] = true;
                        targets.push(j);
                    }
                }
            }
        }
        self.regions.floor_owner[axis as usize] = owners;
        // Scattered leftovers (single cells at lane ends along a wall, where
        // no connection passes) are not worth a drive: a region needs one
        // patch of at least the smallest patch worth covering.
        if drop_specks(
            &mut targets,
            &mut self.scratch.targets,
            f,
            MIN_TARGET_CLUSTER,
        ) < min
        {
            return None;
        }
        let input = LaneInput {
            frame: f,
            admissible: &self.scratch.admissible,
            drivable: &self.regions.reachable,
            targets: &self.scratch.targets,
            bbox: (x0, y0, x1, y1),
            axis,
            spacing: self.spacing,
            reach: self.reach,
            phase,
            fit_walls: cell.is_some(),
            min_fixup_cells: self.area_cells(self.params.min_fixup_area),
            min_lane_cells: self.area_cells(self.params.min_lane_area),
        };
        let ls = lanes(&input);
        let dist = &self.cspace.dist;
        let mut vars = Vec::new();
        let mut entry_cost = Vec::new();
        for var in variants(&ls, turn_join(self.spacing)) {
            let c = f
                .index_of(&var.entry())
                .map(|i| dist[i])
                .unwrap_or(f64::INFINITY);
            if c.is_finite() {
                vars.push(var);
                entry_cost.push(c);
            }
        }
        if vars.is_empty() {
            // Nothing the lanes can reach from here: give these up.
            self.tried.abandon(&targets);
            return None;
        }
        Some(Candidate {
            cell,
            variants: vars,
            entry_cost,
            targets,
        })
    }

    pub(super) fn cell_candidates(
        &mut self,
        decomp: &Decomposition,
        status: CellStatus,
    ) -> Vec<Candidate> {
        let f = self.cspace.frame;
        for owners in &mut self.regions.floor_owner {
            owners.clear();
        }
        let min = self.min_patch_cells();
        let mut out = Vec::new();
        for (n, cell) in decomp.cells.iter().enumerate() {
            if cell.status != status || cell.polygon.len() < 3 || self.regions.lent_to[n].is_some()
            {
                continue;
            }
            // The cell and the slivers lent to it.
            let Some(bbox) = std::iter::once(cell)
                .chain(
                    (0..decomp.cells.len())
                        .filter(|&m| self.regions.lent_to[m] == Some(n))
                        .map(|m| &decomp.cells[m]),
                )
                .filter_map(|c| cell_bbox(c, &f))
                .reduce(|a, b| (a.0.min(b.0), a.1.min(b.1), a.2.max(b.2), a.3.max(b.3)))
            else {
                continue;
            };
            let mut any = false;
            for y in bbox.1..=bbox.3 {
                for x in bbox.0..=bbox.2 {
                    let i = y * f.w + x;
                    let inside = self.regions.region_of[i] == n as u32;
                    self.scratch.admissible[i] = inside;
                    any |= inside;
                }
            }
            if any {
                let axis = Axis::from_angle(cell.sweep_angle);
                if let Some(c) = self.region_candidate(Some(cell.id), bbox, axis, min) {
                    if self.params.lane_tour {
                        self.clear_targets_along(&c.variants[0].lanes);
                    }
                    out.push(c);
                }
            }
            for y in bbox.1..=bbox.3 {
                for x in bbox.0..=bbox.2 {
                    self.scratch.admissible[y * f.w + x] = false;
                }
            }
        }
        out
    }

    /// Connected patches of uncovered reachable floor, each as a region.
    pub(super) fn patch_candidates(&mut self, decomp: &Decomposition) -> Vec<Candidate> {
        let f = self.cspace.frame;
        let mut seen = vec![false; f.len()];
        let mut out = Vec::new();
        let min = self.cleanup_patch_cells();
        let mut stack = Vec::new();
        for s in 0..f.len() {
            if !self.regions.targets[s] || seen[s] {
                continue;
            }
            let mut comp = Vec::new();
            seen[s] = true;
            stack.push(s);
            while let Some(i) = stack.pop() {
                comp.push(i);
                for j in f.neighbours8(i) {
                    if self.regions.targets[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
            if comp.len() < min {
                continue;
            }
            // Admissible: reachable centres within reach of the patch.
            let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
            for &i in &comp {
                for j in f.around(i, &self.reach_disk) {
                    if self.regions.reachable[j] {
                        let (nx, ny) = (j % f.w, j / f.w);
                        self.scratch.admissible[j] = true;
                        x0 = x0.min(nx);
                        y0 = y0.min(ny);
                        x1 = x1.max(nx);
                        y1 = y1.max(ny);
                    }
                }
            }
            if x0 == usize::MAX {
                continue;
            }
            let axis = if decomp.cells.is_empty() {
                if x1 - x0 >= y1 - y0 {
                    Axis::X
                } else {
                    Axis::Y
                }
            } else {
                Axis::from_angle(decomp.sweep_angle)
            };
            if let Some(c) = self.region_candidate(None, (x0, y0, x1, y1), axis, min) {
                out.push(c);
            }
            for y in y0..=y1 {
                for x in x0..=x1 {
                    self.scratch.admissible[y * f.w + x] = false;
                }
            }
        }
        out
    }
}

/// Whether the four neighbours of cell `i` lie inside the frame and in
/// `mask`. The reach disk of such a centre of `mask` adds only the centre
/// itself to the disks of the others: each other cell of it lies in the
/// disk of the neighbour one step toward it, which is nearer, and so on to
/// a centre on the edge of `mask`.
pub(super) fn four_neighbours_in(mask: &[bool], f: Frame, i: usize) -> bool {
    let (x, y, w) = (i % f.w, i / f.w, f.w);
    x > 0
        && y > 0
        && x + 1 < w
        && y + 1 < f.h
        && mask[i - 1]
        && mask[i + 1]
        && mask[i - w]
        && mask[i + w]
}

/// Keeps of `cells` (marked in `mark`) the 8-connected clusters of at
/// least `min_keep` cells, unmarking the rest; returns the largest
/// cluster's size (`min_keep = usize::MAX`: only measures, unmarking all).
pub(super) fn drop_specks(
    cells: &mut Vec<usize>,
    mark: &mut [bool],
    f: Frame,
    min_keep: usize,
) -> usize {
    let mut kept = Vec::with_capacity(cells.len());
    let mut best = 0;
    let mut stack = Vec::new();
    for &s in cells.iter() {
        if !mark[s] {
            continue;
        }
        mark[s] = false;
        stack.push(s);
        let start = kept.len();
        while let Some(i) = stack.pop() {
            kept.push(i);
            for j in f.neighbours8(i) {
                if mark[j] {
                    mark[j] = false;
                    stack.push(j);
                }
            }
        }
        let n = kept.len() - start;
        best = best.max(n);
        if n < min_keep {
            kept.truncate(start);
        }
    }
    for &i in &kept {
        mark[i] = true;
    }
    *cells = kept;
    best
}

/// Grid bounding box (x0, y0, x1, y1) of a cell's polygon, clamped to the frame.
fn cell_bbox(cell: &crate::decomp::Cell, f: &Frame) -> Option<(usize, usize, usize, usize)> {
    if f.is_empty() {
        return None;
    }
    let (mut lo, mut hi) = (
        Point2::new(f64::INFINITY, f64::INFINITY),
        Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for q in &cell.polygon {
        lo = lo.inf(q);
        hi = hi.sup(q);
    }
    let cx = |v: f64, o: f64, n: usize| {
        (((v - o) / f.res).floor().max(0.0) as usize).min(n.saturating_sub(1))
    };
    Some((
        cx(lo.x, f.origin.x, f.w),
        cx(lo.y, f.origin.y, f.h),
        cx(hi.x, f.origin.x, f.w),
        cx(hi.y, f.origin.y, f.h),
    ))
}
