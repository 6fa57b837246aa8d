//! The sweep: pieces of consecutive slices that overlap one-to-one continue
//! a cell; a change of connectivity (a split, a merge, a piece appearing or
//! ending: critical points) or an isolated wall step (a reflex corner) starts
//! a new cell. The slice boundary where a cell ends is the critical edge
//! extended along the lanes until walls or unexplored space: a virtual edge.

use std::collections::HashMap;

use super::frame::SweepFrame;
use super::polygon::simplify_chain;
use super::slices::{End, FrozenSpan, Piece, Slices};

/// A cell reference during one update: a cell built now, or a frozen one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CellRef {
    /// Index into the new cells.
    New(u32),
    /// Index into the frozen (final) cells.
    Frozen(u32),
}

/// A cell as the sweep found it, in lane coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RawCell {
    /// Its pieces, one per row, bottom to top.
    pub pieces: Vec<Piece>,
    /// Indices of those pieces in the slices.
    pub(crate) piece_idx: Vec<u32>,
    /// `v` of the bottom boundary (m).
    pub vb: f64,
    /// `v` of the top boundary (m).
    pub(crate) vt: f64,
    /// Frontier stretches `(u1, v1, u2, v2)`.
    pub frontier: Vec<(f64, f64, f64, f64)>,
    /// Total frontier length (m).
    pub(crate) frontier_len: f64,
}

impl RawCell {
    /// Extent across the lanes (m).
    pub fn width(&self) -> f64 {
        self.vt - self.vb
    }

    /// Extent along the lanes (m).
    pub fn length(&self) -> f64 {
        let lo = self
            .pieces
            .iter()
            .map(|p| p.l)
            .fold(f64::INFINITY, f64::min);
        let hi = self
            .pieces
            .iter()
            .map(|p| p.r)
            .fold(f64::NEG_INFINITY, f64::max);
        hi - lo
    }
}

/// Two cells sharing a boundary `(u1, v1, u2, v2)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawAdj {
    /// One cell.
    pub a: CellRef,
    /// The other.
    pub b: CellRef,
    /// Shared boundary in lane coordinates.
    pub seg: (f64, f64, f64, f64),
}

/// Settings of one sweep.
pub struct SweepInput<'a> {
    /// Wall steps at least this long start a new cell (m).
    pub step_split: f64,
    /// Inflation radius (m), for refining top and bottom boundaries.
    pub radius: f64,
    /// Frozen spans, sorted by row then `l`.
    pub(crate) frozen: &'a [FrozenSpan],
    /// Cells thinner than this across the lanes are merged into a neighbour (m).
    pub(crate) min_width: f64,
    /// Cells smaller than this are merged into a neighbour; isolated ones
    /// under a 25th of it are dropped as specks (m²).
    pub(crate) min_area: f64,
}

/// The sweep's output and buffers.
#[derive(Clone, Debug, Default)]
pub struct Sweep {
    /// Cells found.
    pub cells: Vec<RawCell>,
    /// Adjacencies between cells (new–new and new–frozen).
    pub adjacency: Vec<RawAdj>,
    /// Cell index of every piece.
    pub cell_of: Vec<u32>,
    pairs: Vec<(u32, u32)>,
    preds: Vec<u32>,
    succs: Vec<u32>,
    pred_of: Vec<u32>,
    chain_of: Vec<u32>,
    frozen_rows: Vec<u32>,
}

const NONE: u32 = u32::MAX;

fn overlap(a: &Piece, b: &Piece) -> f64 {
    a.r.min(b.r) - a.l.max(b.l)
}

impl Sweep {
    /// Runs the sweep over `s` (already sliced in frame `f`).
    pub fn run(&mut self, f: &SweepFrame, s: &Slices, input: &SweepInput<'_>) {
        let np = s.pieces.len();
        self.cells.clear();
        self.adjacency.clear();
        self.pairs.clear();
        for v in [&mut self.preds, &mut self.succs] {
            v.clear();
            v.resize(np, 0);
        }
        for v in [&mut self.pred_of, &mut self.chain_of, &mut self.cell_of] {
            v.clear();
            v.resize(np, NONE);
        }
        self.index_frozen(f, input.frozen);
        // Overlapping pieces of consecutive rows.
        for k in 0..f.nv.saturating_sub(1) {
            let (lo, hi) = (s.row_pieces(k), s.row_pieces(k + 1));
            let (mut i, mut j) = (lo.start, hi.start);
            while i < lo.end && j < hi.end {
                let (a, b) = (&s.pieces[i], &s.pieces[j]);
                if overlap(a, b) > 1e-9 {
                    self.pairs.push((i as u32, j as u32));
                    self.succs[i] += 1;
                    self.preds[j] += 1;
                    self.pred_of[j] = i as u32;
                }
                if a.r < b.r {
                    i += 1;
                } else {
                    j += 1;
                }
            }
        }
        // Chains of one-to-one continuation.
        let mut chains: Vec<Vec<u32>> = Vec::new();
        for j in 0..np {
            let p = self.pred_of[j];
            let chain = if self.preds[j] == 1 && self.succs[p as usize] == 1 {
                self.chain_of[p as usize]
            } else {
                chains.push(Vec::new());
                (chains.len() - 1) as u32
            };
            self.chain_of[j] = chain;
            chains[chain as usize].push(j as u32);
        }
        // Groups: chains cut at isolated wall steps (never where the inner
        // side is a frontier, which moves as exploration goes on).
        let mut groups: Vec<Vec<u32>> = Vec::new();
        for chain in &chains {
            let m = chain.len();
            let piece = |t: usize| &s.pieces[chain[t] as usize];
            let dl = |t: usize| piece(t + 1).l - piece(t).l;
            let dr = |t: usize| piece(t + 1).r - piece(t).r;
            let isolated = |d: &dyn Fn(usize) -> f64, t: usize| {
                let x = d(t).abs();
                x >= input.step_split
                    && (t == 0 || d(t - 1).abs() <= x * 0.5)
                    && (t + 2 >= m || d(t + 1).abs() <= x * 0.5)
            };
            // The inner of the two sides must be a wall: the outer one may
            // still be unexplored (a wall ending where unexplored space
            // begins, a critical point), since exploring only pushes it
            // farther out and the step stays.
            let walled = |t: usize, left: bool| {
                let (a, b) = (piece(t), piece(t + 1));
                if left {
                    let inner = if b.l >= a.l { b } else { a };
                    inner.left != End::Frontier
                } else {
                    let inner = if b.r <= a.r { b } else { a };
                    inner.right != End::Frontier
                }
            };
            let mut start = 0;
            for t in 0..m {
                let cut = t + 1 < m
                    && ((walled(t, true) && isolated(&dl, t))
                        || (walled(t, false) && isolated(&dr, t)));
                if t + 1 == m || cut {
                    groups.push(chain[start..=t].to_vec());
                    start = t + 1;
                }
            }
        }
        self.merge_thin(f, s, &mut groups, input);
        for g in groups.into_iter().filter(|g| !g.is_empty()) {
            let idx = self.cells.len() as u32;
            let mut cell = RawCell::default();
            for &pi in &g {
                self.cell_of[pi as usize] = idx;
                cell.pieces.push(s.pieces[pi as usize]);
                cell.piece_idx.push(pi);
            }
            self.cells.push(cell);
        }
        self.build_adjacency(f, s, input.frozen);
        self.bounds_and_frontiers(f, s, input);
    }

    /// Merges groups thinner than `min_width` or smaller than `min_area` into
    /// the neighbour above or below with the longest shared boundary (rows
    /// stay one piece each, so lanes stay unbroken); drops isolated specks and
    /// thin strips beside final cells.
    fn merge_thin(
        &mut self,
        f: &SweepFrame,
        s: &Slices,
        groups: &mut [Vec<u32>],
        input: &SweepInput<'_>,
    ) {
        let mut group_of = vec![NONE; s.pieces.len()];
        for (gi, g) in groups.iter().enumerate() {
            for &p in g {
                group_of[p as usize] = gi as u32;
            }
        }
        let width = |g: &Vec<u32>| g.len() as f64 * f.h;
        let area = |g: &Vec<u32>| -> f64 {
            g.iter()
                .map(|&p| (s.pieces[p as usize].r - s.pieces[p as usize].l) * f.h)
                .sum()
        };
        let small = |g: &Vec<u32>| width(g) < input.min_width || area(g) < input.min_area;
        let mut order: Vec<(f64, usize)> = (0..groups.len())
            .filter(|&g| small(&groups[g]))
            .map(|g| (area(&groups[g]), g))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for (_, t) in order {
            if groups[t].is_empty() || !small(&groups[t]) {
                continue;
            }
            let (first, last) = (groups[t][0], *groups[t].last().unwrap_or(&groups[t][0]));
            let mut best: Option<(f64, usize, bool)> = None;
            for &(i, j) in &self.pairs {
                let (gi, gj) = (group_of[i as usize] as usize, group_of[j as usize] as usize);
                if gi == gj || groups[gi].is_empty() || groups[gj].is_empty() {
                    continue;
                }
                // (i below, j above): i must be its group's last, j its group's first.
                let i_last = groups[gi].last() == Some(&i);
                let j_first = groups[gj].first() == Some(&j);
                if !(i_last && j_first) {
                    continue;
                }
                let ov = overlap(&s.pieces[i as usize], &s.pieces[j as usize]);
                let cand = if j == first {
                    Some((ov, gi, false))
                } else if i == last {
                    Some((ov, gj, true))
                } else {
                    None
                };
                if let Some(c) = cand {
                    if best.is_none_or(|b| c.0 > b.0) {
                        best = Some(c);
                    }
                }
            }
            match best {
                Some((_, n, above)) => {
                    let tp = std::mem::take(&mut groups[t]);
                    let np = std::mem::take(&mut groups[n]);
                    let merged: Vec<u32> = if above {
                        tp.into_iter().chain(np).collect()
                    } else {
                        np.into_iter().chain(tp).collect()
                    };
                    for &p in &merged {
                        group_of[p as usize] = n as u32;
                    }
                    groups[n] = merged;
                }
                None => {
                    let touches_frozen = groups[t].iter().any(|&p| {
                        let pc = &s.pieces[p as usize];
                        let k = pc.row as isize;
                        matches!(pc.left, End::Frozen(_))
                            || matches!(pc.right, End::Frozen(_))
                            || [k - 1, k + 1].iter().any(|&kk| {
                                self.frozen_in_row(input.frozen, kk)
                                    .iter()
                                    .any(|sp| sp.r.min(pc.r) - sp.l.max(pc.l) > 1e-9)
                            })
                    });
                    // A thin strip beside a final cell is covered by that
                    // cell's outer lane; an isolated speck is noise.
                    let thin = width(&groups[t]) < input.min_width * 0.5;
                    if (touches_frozen && thin) || area(&groups[t]) < input.min_area / 25.0 {
                        groups[t].clear();
                    }
                }
            }
        }
    }

    fn index_frozen(&mut self, f: &SweepFrame, frozen: &[FrozenSpan]) {
        self.frozen_rows.clear();
        self.frozen_rows.resize(f.nv + 1, 0);
        for sp in frozen {
            if (sp.row as usize) < f.nv {
                self.frozen_rows[sp.row as usize + 1] += 1;
            }
        }
        for k in 0..f.nv {
            self.frozen_rows[k + 1] += self.frozen_rows[k];
        }
    }

    fn frozen_in_row<'a>(&self, frozen: &'a [FrozenSpan], k: isize) -> &'a [FrozenSpan] {
        if k < 0 || k as usize + 1 >= self.frozen_rows.len() {
            return &[];
        }
        let k = k as usize;
        &frozen[self.frozen_rows[k] as usize..self.frozen_rows[k + 1] as usize]
    }

    fn build_adjacency(&mut self, f: &SweepFrame, s: &Slices, frozen: &[FrozenSpan]) {
        let mut acc: HashMap<(CellRef, CellRef), (f64, f64, f64, f64)> = HashMap::new();
        let mut add = |a: CellRef, b: CellRef, seg: (f64, f64, f64, f64)| {
            let key = if a < b { (a, b) } else { (b, a) };
            acc.entry(key)
                .and_modify(|e| *e = union(*e, seg))
                .or_insert(seg);
        };
        for &(i, j) in &self.pairs {
            let (ci, cj) = (self.cell_of[i as usize], self.cell_of[j as usize]);
            if ci != cj && ci != NONE && cj != NONE {
                let (a, b) = (&s.pieces[i as usize], &s.pieces[j as usize]);
                let v = f.row_edge(b.row as usize);
                add(
                    CellRef::New(ci),
                    CellRef::New(cj),
                    (a.l.max(b.l), v, a.r.min(b.r), v),
                );
            }
        }
        for (pi, p) in s.pieces.iter().enumerate() {
            if self.cell_of[pi] == NONE {
                continue;
            }
            let c = CellRef::New(self.cell_of[pi]);
            let k = p.row as usize;
            let (v0, v1) = (f.row_edge(k), f.row_edge(k + 1));
            if let End::Frozen(z) = p.left {
                add(c, CellRef::Frozen(z), (p.l, v0, p.l, v1));
            }
            if let End::Frozen(z) = p.right {
                add(c, CellRef::Frozen(z), (p.r, v0, p.r, v1));
            }
            for (dk, v) in [(-1isize, v0), (1, v1)] {
                for sp in self.frozen_in_row(frozen, k as isize + dk) {
                    let (lo, hi) = (p.l.max(sp.l), p.r.min(sp.r));
                    if hi - lo > 1e-9 {
                        add(c, CellRef::Frozen(sp.cell), (lo, v, hi, v));
                    }
                }
            }
        }
        let mut list: Vec<_> = acc.into_iter().collect();
        list.sort_by_key(|x| x.0);
        self.adjacency = list
            .into_iter()
            .map(|((a, b), seg)| RawAdj { a, b, seg })
            .collect();
    }

    fn bounds_and_frontiers(&mut self, f: &SweepFrame, s: &Slices, input: &SweepInput<'_>) {
        let h = f.h;
        let reach = (s.max_extent.max(input.radius) / h).ceil() as isize + 1;
        let mut cells = std::mem::take(&mut self.cells);
        for cell in &mut cells {
            let first = cell.pieces[0];
            let last = *cell.pieces.last().unwrap_or(&first);
            let (k0, k1) = (first.row as usize, last.row as usize);
            // Side frontiers: polylines over consecutive rows, simplified.
            for side in 0..2 {
                let mut run: Vec<(f64, f64)> = Vec::new();
                for (t, p) in cell.pieces.iter().enumerate() {
                    let (end, u) = if side == 0 {
                        (p.left, p.l)
                    } else {
                        (p.right, p.r)
                    };
                    if end == End::Frontier {
                        if run.is_empty() {
                            run.push((u, f.row_edge(p.row as usize)));
                        }
                        run.push((u, f.row_edge(p.row as usize + 1)));
                    }
                    let last_row = t + 1 == cell.pieces.len();
                    if (end != End::Frontier || last_row) && !run.is_empty() {
                        let kept = simplify_chain(&run, h);
                        for w in kept.windows(2) {
                            cell.frontier.push((w[0].0, w[0].1, w[1].0, w[1].1));
                        }
                        run.clear();
                    }
                }
            }
            // Frontier pixels just below and above every piece.
            let mut bottom_open = false;
            let mut top_open = false;
            for p in &cell.pieces {
                let k = p.row as isize;
                for (dk, v) in [
                    (-1isize, f.row_edge(p.row as usize)),
                    (1, f.row_edge(p.row as usize + 1)),
                ] {
                    let a = ((p.l - f.u0) / h - 0.5).ceil() as isize;
                    let b = ((p.r - f.u0) / h - 0.5).floor() as isize;
                    let mut run: Option<isize> = None;
                    for i in a..=b + 1 {
                        let fr = i <= b && s.is_frontier(f, i, k + dk);
                        match (fr, run) {
                            (true, None) => run = Some(i),
                            (false, Some(i0)) => {
                                let u1 = (f.u0 + i0 as f64 * h).max(p.l);
                                let u2 = (f.u0 + i as f64 * h).min(p.r);
                                cell.frontier.push((u1, v, u2, v));
                                if p.row as usize == k0 && dk < 0 {
                                    bottom_open = true;
                                }
                                if p.row as usize == k1 && dk > 0 {
                                    top_open = true;
                                }
                                run = None;
                            }
                            _ => {}
                        }
                    }
                }
            }
            cell.frontier_len = cell
                .frontier
                .iter()
                .map(|&(u1, v1, u2, v2)| ((u2 - u1).powi(2) + (v2 - v1).powi(2)).sqrt())
                .sum();
            // Bottom and top: a row edge, unless a wall bounds them: then the
            // exact distance to the nearest wall point.
            cell.vb = f.row_edge(k0);
            cell.vt = f.row_edge(k1 + 1);
            let below_taken = self.preds[cell.piece_idx[0] as usize] > 0;
            let frozen_below = self
                .frozen_in_row(input.frozen, k0 as isize - 1)
                .iter()
                .any(|sp| sp.r.min(first.r) - sp.l.max(first.l) > 1e-9);
            if !bottom_open && !below_taken && !frozen_below {
                let vc = f.row_v(k0);
                let mut best = f64::NEG_INFINITY;
                for kk in (k0 as isize - reach).max(0)..=k0 as isize {
                    for p in s.row_points(kk as usize) {
                        if p.v >= vc {
                            continue;
                        }
                        if let Some(d) = p.reach_across(first.l, first.r) {
                            best = best.max(p.v + d);
                        }
                    }
                }
                if best.is_finite() {
                    cell.vb = best.clamp(vc - h, vc);
                }
            }
            let above_taken = cell
                .piece_idx
                .last()
                .is_some_and(|&i| self.succs[i as usize] > 0);
            let frozen_above = self
                .frozen_in_row(input.frozen, k1 as isize + 1)
                .iter()
                .any(|sp| sp.r.min(last.r) - sp.l.max(last.l) > 1e-9);
            if !top_open && !above_taken && !frozen_above {
                let vc = f.row_v(k1);
                let mut best = f64::INFINITY;
                for kk in k1 as isize..=(k1 as isize + reach).min(f.nv as isize - 1) {
                    for p in s.row_points(kk as usize) {
                        if p.v <= vc {
                            continue;
                        }
                        if let Some(d) = p.reach_across(last.l, last.r) {
                            best = best.min(p.v - d);
                        }
                    }
                }
                if best.is_finite() {
                    cell.vt = best.clamp(vc, vc + h);
                }
            }
        }
        self.cells = cells;
    }
}

/// Union of two boundary stretches on the same line (else the longer one).
fn union(a: (f64, f64, f64, f64), b: (f64, f64, f64, f64)) -> (f64, f64, f64, f64) {
    let horizontal = |s: (f64, f64, f64, f64)| (s.1 - s.3).abs() < 1e-9;
    let vertical = |s: (f64, f64, f64, f64)| (s.0 - s.2).abs() < 1e-9;
    if horizontal(a) && horizontal(b) && (a.1 - b.1).abs() < 1e-9 {
        (a.0.min(b.0), a.1, a.2.max(b.2), a.3)
    } else if vertical(a) && vertical(b) && (a.0 - b.0).abs() < 1e-9 {
        (a.0, a.1.min(b.1), a.2, a.3.max(b.3))
    } else {
        let len = |s: (f64, f64, f64, f64)| (s.2 - s.0).hypot(s.3 - s.1);
        if len(b) > len(a) {
            b
        } else {
            a
        }
    }
}
