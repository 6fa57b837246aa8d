//! Slices of the explored configuration space: the evidence grid resampled
//! into the sweep frame, every seen wall point inflated into a disk, and, per
//! slice (row), the intervals where the robot's centre may be ("pieces").
//!
//! Buffers are kept between updates and reused; only the window around the
//! explored part of the grid is touched.

use crate::geom::Segment;
use crate::grid::{CellState, Grid};

use super::frame::SweepFrame;
use super::rows::group_by_row;
use super::{Lap, PhaseTimes};

use super::raster::{
    classify, column_distances, fill_columns, fill_row, find_at_most, find_class, push_union,
    skip_class, transpose8,
};
pub use super::raster::{BLOCKED, CLASS, FREE, OCC, UNK};

/// What ends a piece on one side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// An inflated wall (or the grid's occupied cells).
    Wall,
    /// Unexplored space (or the edge of the grid).
    Frontier,
    /// A frozen (final) cell, by its index in the frozen list.
    Frozen(u32),
}

/// One free interval of one slice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    /// Row (slice) index.
    pub row: u32,
    /// Lower `u` end (m).
    pub l: f64,
    /// Upper `u` end (m).
    pub r: f64,
    /// What bounds it at `l`.
    pub left: End,
    /// What bounds it at `r`.
    pub right: End,
}

/// A seen wall point with the disk (around a point of a segment) or rounded
/// square (around an occupied grid cell) it blocks for the robot's centre.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WallPoint {
    /// Lane coordinate along the lanes (m).
    pub u: f64,
    /// Lane coordinate across the lanes (m).
    pub v: f64,
    /// Half side of the square it stands for (0 for a point) (m).
    pub e: f64,
    /// Inflation radius around it (m).
    pub r: f64,
}

impl WallPoint {
    /// Half length of the blocked interval on the slice at `v`, if any.
    pub(crate) fn half_width_at(&self, v: f64) -> Option<f64> {
        let dv = ((v - self.v).abs() - self.e).max(0.0);
        let d2 = self.r * self.r - dv * dv;
        (d2 > 0.0).then(|| self.e + d2.sqrt())
    }

    /// How far across the lanes (from `v`) it blocks a slice interval
    /// `[l, r]`: the blocked region's extent toward the interval, if it
    /// reaches the interval's `u` range at all.
    pub(crate) fn reach_across(&self, l: f64, r: f64) -> Option<f64> {
        let du = ((l - self.u).max(self.u - r).max(0.0) - self.e).max(0.0);
        let d2 = self.r * self.r - du * du;
        (d2 > 0.0).then(|| self.e + d2.sqrt())
    }
}

/// An interval of a frozen cell in one row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FrozenSpan {
    /// Row.
    pub row: u32,
    /// Lower `u` (m).
    pub l: f64,
    /// Upper `u` (m).
    pub r: f64,
    /// Index of the frozen cell.
    pub cell: u32,
}

/// The per-update slice buffers.
#[derive(Clone, Debug, Default)]
pub struct Slices {
    /// Pixel classes and flags, `nu × nv`, row-major.
    pub px: Vec<u8>,
    /// Wall points sorted by row of `v`.
    pub points: Vec<WallPoint>,
    /// Largest `e + r` of any wall point: how far a point blocks (m).
    pub(crate) max_extent: f64,
    /// `points[point_rows[k]..point_rows[k+1]]` lie in row `k`.
    pub(crate) point_rows: Vec<u32>,
    /// Merged blocked intervals, sorted by row then `l`.
    pub blocked: Vec<(f64, f64)>,
    /// Row offsets into `blocked`.
    pub(crate) blocked_rows: Vec<u32>,
    /// Pieces, sorted by row then `l`.
    pub pieces: Vec<Piece>,
    /// Row offsets into `pieces`.
    pub(crate) piece_rows: Vec<u32>,
    /// Processed window: columns `i0..i1`, rows `k0..k1`.
    pub window: (usize, usize, usize, usize),
    /// Time of each step of the last pass (the slicing fields only).
    pub times: PhaseTimes,
    raw_points: Vec<WallPoint>,
    raw_intervals: Vec<(u32, f64, f64)>,
    sorted_intervals: Vec<(f64, f64)>,
    counts: Vec<u32>,
    col_runs: Vec<u16>,
    seg_mask: Vec<bool>,
    /// Indices set in `seg_mask` (cleared one by one, not by a pass over
    /// the whole grid).
    seg_marked: Vec<usize>,
    excl: Vec<(f64, f64, End)>,
    /// Half side and inflation radius of the occupied cells' wall points when
    /// they lie on pixel centres (a frame aligned with the grid), else `None`.
    lattice_square: Option<(f64, f64)>,
    /// Per pixel of the window: rows to the nearest such point in its column
    /// (saturating), see [`Slices::inflate`].
    near: Vec<u8>,
    /// One row's blocked intervals from the lattice points.
    lattice_runs: Vec<(f64, f64)>,
    /// Pixel classes of the grid's cells in grid order (turned frames).
    classes: Vec<u8>,
    /// Width of the raster `px` was laid out for.
    raster_nu: usize,
    grid_box: (usize, usize, usize, usize),
}

/// Inputs of one slicing pass.
pub(crate) struct SliceInput<'a> {
    /// The evidence grid.
    pub grid: &'a Grid,
    /// Wall segments seen (may be empty).
    pub segments: &'a [Segment],
    /// Inflation radius (m).
    pub radius: f64,
    /// Unknown gaps up to this many pixels between free pixels are filled.
    pub(crate) gap_pixels: usize,
    /// Frozen cells' spans, sorted by row then `l`.
    pub(crate) frozen: &'a [FrozenSpan],
    /// Pieces shorter than this beside a frozen cell are left to that cell's
    /// tool overlap and dropped (m).
    pub(crate) min_beside_frozen: f64,
}

impl Slices {
    /// Pixel at column `i`, row `k`.
    pub fn at(&self, f: &SweepFrame, i: usize, k: usize) -> u8 {
        self.px[k * f.nu + i]
    }

    /// Whether pixel `(i, k)` is unexplored and not within a wall's inflation
    /// (outside the raster counts as unexplored).
    pub(crate) fn is_frontier(&self, f: &SweepFrame, i: isize, k: isize) -> bool {
        if i < 0 || k < 0 || i as usize >= f.nu || k as usize >= f.nv {
            return true;
        }
        let p = self.at(f, i as usize, k as usize);
        p & CLASS == UNK && p & BLOCKED == 0
    }

    /// The pieces of row `k`.
    pub(crate) fn row_pieces(&self, k: usize) -> std::ops::Range<usize> {
        self.piece_rows[k] as usize..self.piece_rows[k + 1] as usize
    }

    /// The obstacle points of row `k`.
    pub(crate) fn row_points(&self, k: usize) -> &[WallPoint] {
        &self.points[self.point_rows[k] as usize..self.point_rows[k + 1] as usize]
    }

    /// Runs the whole slicing pass for `input` in frame `f`. Returns false when
    /// nothing of the grid is explored (no pieces).
    pub(crate) fn compute(&mut self, f: &SweepFrame, input: &SliceInput<'_>) -> bool {
        self.times = PhaseTimes::default();
        let mut clock = Lap::start();
        self.piece_rows.clear();
        self.piece_rows.resize(f.nv + 1, 0);
        self.pieces.clear();
        self.point_rows.clear();
        self.point_rows.resize(f.nv + 1, 0);
        self.blocked_rows.clear();
        self.blocked_rows.resize(f.nv + 1, 0);
        self.points.clear();
        self.blocked.clear();
        let window = self.explored_window(f, input);
        self.reset_raster(f, window.unwrap_or((0, 0, 0, 0)));
        if window.is_none() {
            return false;
        }
        self.resample(f, input.grid);
        self.times.resample = clock.lap();
        self.fill_gaps(f, input.gap_pixels);
        self.times.gaps = clock.lap();
        self.collect_points(f, input);
        self.times.wall_points = clock.lap();
        self.inflate(f);
        self.times.inflate = clock.lap();
        self.cut_pieces(f, input.frozen, input.min_beside_frozen);
        self.times.pieces = clock.lap();
        !self.pieces.is_empty()
    }

    /// Makes every pixel outside `window` unknown and sets the window: only
    /// the last window can hold anything else, and the resampling overwrites
    /// all of the new one, so only the part of the last window outside the
    /// new one is cleared (a new raster size clears everything).
    fn reset_raster(&mut self, f: &SweepFrame, window: (usize, usize, usize, usize)) {
        let n = f.nu * f.nv;
        let (o_i0, o_i1, o_k0, o_k1) = std::mem::replace(&mut self.window, window);
        if self.px.len() != n || self.raster_nu != f.nu {
            self.px.clear();
            self.px.resize(n, UNK);
            self.raster_nu = f.nu;
            return;
        }
        let (i0, i1, k0, k1) = window;
        for k in o_k0..o_k1 {
            let row = &mut self.px[k * f.nu..(k + 1) * f.nu];
            if (k0..k1).contains(&k) {
                row[o_i0..o_i1.min(i0).max(o_i0)].fill(UNK);
                row[o_i0.max(i1).min(o_i1)..o_i1].fill(UNK);
            } else {
                row[o_i0..o_i1].fill(UNK);
            }
        }
    }

    fn explored_window(
        &mut self,
        f: &SweepFrame,
        input: &SliceInput<'_>,
    ) -> Option<(usize, usize, usize, usize)> {
        let g = input.grid;
        let ((x0, y0), (x1, y1)) = g.explored_cells()?;
        self.grid_box = (x0, y0, x1 + 1, y1 + 1);
        let (o, r) = (g.origin(), g.resolution());
        let margin = input.radius + 2.0 * f.h;
        let (mut lo_u, mut lo_v, mut hi_u, mut hi_v) = (
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        );
        for (x, y) in [(x0, y0), (x1 + 1, y0), (x0, y1 + 1), (x1 + 1, y1 + 1)] {
            let p = nalgebra::Point2::new(o.x + x as f64 * r, o.y + y as f64 * r);
            let (u, v) = f.to_uv(&p);
            lo_u = lo_u.min(u);
            lo_v = lo_v.min(v);
            hi_u = hi_u.max(u);
            hi_v = hi_v.max(v);
        }
        for s in input.segments {
            for p in [s.a, s.b] {
                let (u, v) = f.to_uv(&p);
                if u.is_finite() && v.is_finite() {
                    lo_u = lo_u.min(u);
                    lo_v = lo_v.min(v);
                    hi_u = hi_u.max(u);
                    hi_v = hi_v.max(v);
                }
            }
        }
        let i0 = f.col_of(lo_u - margin);
        let i1 = f.col_of(hi_u + margin) + 1;
        let k0 = f.row_of(lo_v - margin);
        let k1 = f.row_of(hi_v + margin) + 1;
        Some((i0, i1, k0, k1))
    }

    fn resample(&mut self, f: &SweepFrame, g: &Grid) {
        let (i0, i1, k0, k1) = self.window;
        let class = |st: CellState| match st {
            CellState::Free => FREE,
            CellState::Occupied => OCC,
            CellState::Unknown => UNK,
        };
        // Fast path: the pixel lattice is the grid lattice, maybe rotated by
        // a multiple of 90° (axis-aligned rooms): integer index arithmetic.
        if let Some(m) = lattice_map(f, g) {
            let (gw, gh) = (g.width() as i64, g.height() as i64);
            // One table lookup per pixel into the raw evidence.
            let lut = Grid::state_table().map(class);
            let raw = g.raw_evidence();
            if m.xi == 0 {
                self.resample_turned(f, g, &m);
                return;
            }
            // Pixel rows are grid rows, maybe reversed: along a row the grid
            // index moves by ±1, over one interval of the row that lies on
            // the grid: no test per pixel.
            let stride = m.xi;
            for k in k0..k1 {
                let (xa, ya) = m.apply(0, k as i64);
                let (xl, xh) = on_grid(xa, m.xi, gw);
                let (yl, yh) = on_grid(ya, m.yi, gh);
                let lo = xl.max(yl).clamp(i0 as i64, i1 as i64) as usize;
                let hi = xh.min(yh).clamp(lo as i64, i1 as i64) as usize;
                let row = &mut self.px[k * f.nu..(k + 1) * f.nu];
                row[i0..lo].fill(UNK);
                row[hi..i1].fill(UNK);
                let mut at = ya * gw + xa + stride * lo as i64;
                for d in &mut row[lo..hi] {
                    *d = lut[raw[at as usize] as usize];
                    at += stride;
                }
            }
            return;
        }
        // A frame at any other angle: along a row the pixel centre moves by
        // a fixed step in grid-cell units, so a pixel costs two multiply-adds
        // and a table lookup (the cell rule of `Grid::cell_of`, without its
        // two divisions per pixel).
        let lut = Grid::state_table().map(class);
        let raw = g.raw_evidence();
        let (o, res, gw, gh) = (g.origin(), g.resolution(), g.width(), g.height());
        let step = f.to_world(f.h, 0.0) - f.to_world(0.0, 0.0);
        let (dx, dy) = (step.x / res, step.y / res);
        for k in k0..k1 {
            let p0 = f.to_world(f.col_u(0), f.row_v(k));
            let (sx, sy) = ((p0.x - o.x) / res, (p0.y - o.y) / res);
            for i in i0..i1 {
                let (fx, fy) = (sx + i as f64 * dx, sy + i as f64 * dy);
                let on = fx >= 0.0 && fy >= 0.0 && (fx as usize) < gw && (fy as usize) < gh;
                self.px[k * f.nu + i] = if on {
                    lut[raw[fy as usize * gw + fx as usize] as usize]
                } else {
                    UNK
                };
            }
        }
    }

    /// [`Slices::resample`] for a frame turned a quarter turn from the grid
    /// (pixel rows are grid columns): the grid's cells in the window are
    /// classified row by row, then transposed into the raster eight by eight
    /// pixels at a time, so that neither side is read or written across
    /// its rows pixel by pixel.
    fn resample_turned(&mut self, f: &SweepFrame, g: &Grid, m: &LatticeMap) {
        let (i0, i1, k0, k1) = self.window;
        let (nu, gw, gh) = (f.nu, g.width(), g.height());
        // Pixel (i, k) is cell (x0 + xk·k, y0 + yi·i): the pixels on the grid
        // are the columns `ia..ib` of the rows `ka..kb`.
        let (ka, kb) = on_grid(m.x0, m.xk, gw as i64);
        let (ia, ib) = on_grid(m.y0, m.yi, gh as i64);
        let clip = |a: i64, b: i64, lo: usize, hi: usize| {
            let a = a.clamp(lo as i64, hi as i64) as usize;
            (a, (b.clamp(lo as i64, hi as i64) as usize).max(a))
        };
        let (ka, kb) = clip(ka, kb, k0, k1);
        let (ia, ib) = clip(ia, ib, i0, i1);
        for k in k0..k1 {
            let row = &mut self.px[k * nu..(k + 1) * nu];
            if (ka..kb).contains(&k) {
                row[i0..ia].fill(UNK);
                row[ib..i1].fill(UNK);
            } else {
                row[i0..i1].fill(UNK);
            }
        }
        if ka == kb || ia == ib {
            return;
        }
        let cell = |i: usize, k: usize| {
            let (x, y) = m.apply(i as i64, k as i64);
            (x as usize, y as usize)
        };
        // The cells under the on-grid pixels, classified in grid order.
        let ((xa, ya), (xb, yb)) = (cell(ia, ka), cell(ib - 1, kb - 1));
        let (xs, ys) = (xa.min(xb)..xa.max(xb) + 1, ya.min(yb)..ya.max(yb) + 1);
        self.classes.resize(gw * gh, UNK);
        let raw = g.raw_evidence();
        for y in ys {
            let span = y * gw + xs.start..y * gw + xs.end;
            classify(
                &raw[span.clone()],
                &mut self.classes[span],
                Grid::OCCUPIED_EVIDENCE,
            );
        }
        let classes = &self.classes;
        let px = &mut self.px;
        let at = |i: usize, k: usize| {
            let (x, y) = cell(i, k);
            classes[y * gw + x]
        };
        let mut k = ka;
        while k < kb {
            if k + 8 > kb {
                for i in ia..ib {
                    px[k * nu + i] = at(i, k);
                }
                k += 1;
                continue;
            }
            // Eight pixel rows are eight neighbouring cells of a grid row.
            let x_first = cell(0, if m.xk > 0 { k } else { k + 7 }).0;
            let mut i = ia;
            while i + 8 <= ib {
                let mut words = [0u64; 8];
                for (r, w) in words.iter_mut().enumerate() {
                    let y = cell(i + r, k).1;
                    let at = y * gw + x_first;
                    let mut b = [0u8; 8];
                    b.copy_from_slice(&classes[at..at + 8]);
                    if m.xk < 0 {
                        b.reverse();
                    }
                    *w = u64::from_ne_bytes(b);
                }
                for (r, w) in transpose8(words).iter().enumerate() {
                    px[(k + r) * nu + i..(k + r) * nu + i + 8].copy_from_slice(&w.to_ne_bytes());
                }
                i += 8;
            }
            for kk in k..k + 8 {
                for ii in i..ib {
                    px[kk * nu + ii] = at(ii, kk);
                }
            }
            k += 8;
        }
    }

    /// Unknown runs of at most `max` pixels with free pixels on both ends
    /// become free, along rows and then along columns.
    fn fill_gaps(&mut self, f: &SweepFrame, max: usize) {
        if max == 0 {
            return;
        }
        let (i0, i1, k0, k1) = self.window;
        let nu = f.nu;
        for k in k0..k1 {
            fill_row(&mut self.px[k * nu + i0..k * nu + i1], max);
        }
        fill_columns(&mut self.px, nu, i0..i1, k0..k1, max, &mut self.col_runs);
    }

    fn collect_points(&mut self, f: &SweepFrame, input: &SliceInput<'_>) {
        let g = input.grid;
        let (gw, gh) = (g.width(), g.height());
        for &i in &self.seg_marked {
            if let Some(m) = self.seg_mask.get_mut(i) {
                *m = false;
            }
        }
        self.seg_marked.clear();
        if self.seg_mask.len() != gw * gh {
            self.seg_mask.clear();
            self.seg_mask.resize(gw * gh, false);
        }
        self.raw_points.clear();
        let step = (f.h * 0.5).min(g.resolution() * 0.5);
        for s in input.segments {
            let len = s.length();
            if !len.is_finite() {
                continue;
            }
            let n = ((len / step).ceil() as usize).clamp(1, 1_000_000);
            for j in 0..=n {
                let p = s.a + (s.b - s.a) * (j as f64 / n as f64);
                let (u, v) = f.to_uv(&p);
                self.raw_points.push(WallPoint {
                    u,
                    v,
                    e: 0.0,
                    r: input.radius,
                });
                if let Some((cx, cy)) = g.cell_of(&p) {
                    for yy in cy.saturating_sub(1)..(cy + 2).min(gh) {
                        for xx in cx.saturating_sub(1)..(cx + 2).min(gw) {
                            if !self.seg_mask[yy * gw + xx] {
                                self.seg_mask[yy * gw + xx] = true;
                                self.seg_marked.push(yy * gw + xx);
                            }
                        }
                    }
                }
            }
        }
        let occupied = Grid::state_table().map(|s| s == CellState::Occupied);
        let raw = g.raw_evidence();
        let occ = |i: usize| occupied[raw[i] as usize];
        let (bx0, by0, bx1, by1) = self.grid_box;
        // An occupied cell blocks its whole square: exactly (a rounded square)
        // when the frame is aligned with the grid, else by the disk around
        // the square.
        self.lattice_square = lattice_map(f, g).map(|_| (g.resolution() * 0.5, input.radius));
        let (e, r) = self.lattice_square.unwrap_or((
            0.0,
            input.radius + g.resolution() * std::f64::consts::FRAC_1_SQRT_2,
        ));
        // Occupied cells are few: blocks of cells with no evidence as high as
        // occupied are passed over whole (a branch-free maximum per block).
        const CHUNK: usize = 32;
        let occupied_from = Grid::OCCUPIED_EVIDENCE;
        for y in by0..by1 {
            let row = y * gw;
            let mut next = bx0;
            while next < bx1 {
                let x = next;
                if x + CHUNK <= bx1
                    && raw[row + x..row + x + CHUNK]
                        .iter()
                        .fold(0u8, |m, &e| m.max(e))
                        < occupied_from
                {
                    next += CHUNK;
                    continue;
                }
                next += 1;
                let i = row + x;
                if !occ(i) || self.seg_mask[i] {
                    continue;
                }
                let interior = x > 0
                    && y > 0
                    && x + 1 < gw
                    && y + 1 < gh
                    && occ(i - 1)
                    && occ(i + 1)
                    && occ(i - gw)
                    && occ(i + gw);
                if !interior {
                    let (u, v) = f.to_uv(&g.centre_of((x, y)));
                    self.raw_points.push(WallPoint { u, v, e, r });
                }
            }
        }
        group_by_row(
            &self.raw_points,
            f.nv,
            |p| (p.u.is_finite() && p.v.is_finite()).then(|| f.row_of(p.v)),
            |p| *p,
            &mut self.points,
            &mut self.point_rows,
        );
        // Along `u` within each row: neighbouring points' blocked intervals
        // then come one after the other (see `inflate`).
        for k in 0..f.nv {
            let row =
                &mut self.points[self.point_rows[k] as usize..self.point_rows[k + 1] as usize];
            row.sort_unstable_by(|a, b| a.u.total_cmp(&b.u));
        }
        self.max_extent = self.points.iter().map(|p| p.e + p.r).fold(0.0, f64::max);
    }

    /// The blocked intervals of every row: the union over the wall points
    /// within reach of the interval each blocks on the row. Wall points on
    /// pixel centres (occupied cells of a grid the frame is aligned with) all
    /// block the same interval at a given row distance, so for them only
    /// the nearest point in each column counts: one distance pass down and
    /// up the columns, then each row's intervals come in column order. Other
    /// points (segments, a turned frame) go row by row and are sorted.
    fn inflate(&mut self, f: &SweepFrame) {
        let (i0, i1, k0, k1) = self.window;
        let nu = f.nu;
        // Half widths by row distance for the lattice points, if usable.
        let mut widths = [0.0f64; 128];
        let mut lattice_reach = None;
        if let Some((e, r)) = self.lattice_square {
            let square = WallPoint {
                u: 0.0,
                v: 0.0,
                e,
                r,
            };
            let mut d = 0;
            while d < widths.len() {
                match square.half_width_at(d as f64 * f.h) {
                    Some(w) => widths[d] = w,
                    None => break,
                }
                d += 1;
            }
            // A reach of 128 rows or more (a fine frame, a big robot) takes
            // the general path.
            if (1..widths.len()).contains(&d) {
                lattice_reach = Some(d - 1);
            }
        }
        if lattice_reach.is_some() {
            self.near.resize(nu * f.nv, u8::MAX);
            for k in k0..k1 {
                self.near[k * nu + i0..k * nu + i1].fill(u8::MAX);
            }
            for p in self.points.iter().filter(|p| p.e > 0.0) {
                let (i, k) = (f.col_of(p.u), f.row_of(p.v));
                if !((i0..i1).contains(&i) && (k0..k1).contains(&k)) {
                    // Cannot be (the window holds the explored cells with a
                    // margin), but if it were, the general path is exact.
                    lattice_reach = None;
                    break;
                }
                self.near[k * nu + i] = 0;
            }
        }
        if lattice_reach.is_some() {
            column_distances(&mut self.near, nu, i0..i1, k0..k1);
        }
        let on_lattice = |p: &WallPoint| lattice_reach.is_some() && p.e > 0.0;
        self.raw_intervals.clear();
        for k in 0..f.nv {
            let row = &self.points[self.point_rows[k] as usize..self.point_rows[k + 1] as usize];
            let Some(reach) = row
                .iter()
                .filter(|p| !on_lattice(p))
                .map(|p| ((p.r + p.e) / f.h).ceil() as usize + 1)
                .max()
            else {
                continue;
            };
            for kk in k.saturating_sub(reach)..(k + reach + 1).min(f.nv) {
                if kk < k0 || kk >= k1 {
                    continue;
                }
                // The row's points in order of `u`: a run of overlapping
                // intervals goes in as its union (a wall along the row gives
                // one interval per row instead of one per point).
                let v = f.row_v(kk);
                let mut run: Option<(f64, f64)> = None;
                for p in row.iter().filter(|p| !on_lattice(p)) {
                    let Some(d) = p.half_width_at(v) else {
                        continue;
                    };
                    let (l, r) = (p.u - d, p.u + d);
                    run = match run {
                        Some((cl, cr)) if l <= cr && r >= cl => Some((cl.min(l), cr.max(r))),
                        Some((cl, cr)) => {
                            self.raw_intervals.push((kk as u32, cl, cr));
                            Some((l, r))
                        }
                        None => Some((l, r)),
                    };
                }
                if let Some((cl, cr)) = run {
                    self.raw_intervals.push((kk as u32, cl, cr));
                }
            }
        }
        // Grouped by row, then each row sorted by l and merged.
        group_by_row(
            &self.raw_intervals,
            f.nv,
            |&(k, _, _)| Some(k as usize),
            |&(_, l, r)| (l, r),
            &mut self.sorted_intervals,
            &mut self.counts,
        );
        self.blocked.clear();
        for k in 0..f.nv {
            self.blocked_rows[k] = self.blocked.len() as u32;
            let row =
                &mut self.sorted_intervals[self.counts[k] as usize..self.counts[k + 1] as usize];
            row.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            self.lattice_runs.clear();
            if let (Some(reach), true) = (lattice_reach, (k0..k1).contains(&k)) {
                let near = &self.near[k * nu..k * nu + i1];
                let mut i = find_at_most(near, i0, reach as u8);
                while i < i1 {
                    let w = widths[near[i] as usize];
                    push_union(&mut self.lattice_runs, (f.col_u(i) - w, f.col_u(i) + w));
                    i = find_at_most(near, i + 1, reach as u8);
                }
            }
            // Both lists sorted by `l`: merged, touching intervals joined.
            let start = self.blocked.len();
            let (mut a, mut b) = (0, 0);
            while a < row.len() || b < self.lattice_runs.len() {
                let next = if b >= self.lattice_runs.len()
                    || (a < row.len() && row[a].0 <= self.lattice_runs[b].0)
                {
                    a += 1;
                    row[a - 1]
                } else {
                    b += 1;
                    self.lattice_runs[b - 1]
                };
                let len = self.blocked.len();
                if len > start && next.0 <= self.blocked[len - 1].1 {
                    self.blocked[len - 1].1 = self.blocked[len - 1].1.max(next.1);
                } else {
                    self.blocked.push(next);
                }
            }
            // Flag blocked pixels.
            if k >= k0 && k < k1 {
                for &(l, r) in &self.blocked[start..] {
                    let a = ((l - f.u0) / f.h - 0.5).ceil().max(i0 as f64) as usize;
                    let b = ((r - f.u0) / f.h - 0.5).floor();
                    if b < a as f64 {
                        continue;
                    }
                    let b = (b as usize).min(i1 - 1);
                    self.px[k * nu + a..=k * nu + b]
                        .iter_mut()
                        .for_each(|p| *p |= BLOCKED);
                }
            }
        }
        self.blocked_rows[f.nv] = self.blocked.len() as u32;
    }

    fn cut_pieces(&mut self, f: &SweepFrame, frozen: &[FrozenSpan], min_beside: f64) {
        let (i0, i1, k0, k1) = self.window;
        let min_len = f.h * 0.5;
        // The shortest piece kept: beside a frozen cell, shorter ones are left
        // to that cell's tool overlap.
        let need = |beside_frozen: bool| {
            if beside_frozen {
                min_beside.max(min_len)
            } else {
                min_len
            }
        };
        let mut fz = 0usize;
        for k in 0..f.nv {
            self.piece_rows[k] = self.pieces.len() as u32;
            while fz < frozen.len() && (frozen[fz].row as usize) < k {
                fz += 1;
            }
            if k < k0 || k >= k1 {
                continue;
            }
            self.excl.clear();
            for &(l, r) in
                &self.blocked[self.blocked_rows[k] as usize..self.blocked_rows[k + 1] as usize]
            {
                self.excl.push((l, r, End::Wall));
            }
            let mut j = fz;
            while j < frozen.len() && frozen[j].row as usize == k {
                let s = frozen[j];
                self.excl.push((s.l, s.r, End::Frozen(s.cell)));
                j += 1;
            }
            self.excl.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            let line = &self.px[k * f.nu..k * f.nu + i1];
            let mut i = i0;
            loop {
                let a = find_class(line, i, FREE);
                if a >= i1 {
                    break;
                }
                i = skip_class(line, a, FREE);
                let b = i - 1;
                let left = if self.is_frontier(f, a as isize - 1, k as isize) {
                    End::Frontier
                } else {
                    End::Wall
                };
                let right = if self.is_frontier(f, b as isize + 1, k as isize) {
                    End::Frontier
                } else {
                    End::Wall
                };
                let (lu, ru) = (f.u0 + a as f64 * f.h, f.u0 + (b + 1) as f64 * f.h);
                let (mut cur, mut cur_end) = (lu, left);
                for &(el, er, ek) in &self.excl {
                    if er <= cur || el >= ru {
                        continue;
                    }
                    if el > cur {
                        let beside =
                            matches!(ek, End::Frozen(_)) || matches!(cur_end, End::Frozen(_));
                        if el - cur >= need(beside) {
                            self.pieces.push(Piece {
                                row: k as u32,
                                l: cur,
                                r: el,
                                left: cur_end,
                                right: ek,
                            });
                        }
                        cur = er;
                        cur_end = ek;
                    } else if er > cur {
                        cur = er;
                        cur_end = ek;
                    }
                    if cur >= ru {
                        break;
                    }
                }
                if ru - cur >= need(matches!(cur_end, End::Frozen(_))) {
                    self.pieces.push(Piece {
                        row: k as u32,
                        l: cur,
                        r: ru,
                        left: cur_end,
                        right,
                    });
                }
            }
        }
        self.piece_rows[f.nv] = self.pieces.len() as u32;
    }
}

/// Integer map from pixel `(i, k)` to grid cell `(x, y)`:
/// `x = x0 + xi·i + xk·k`, `y = y0 + yi·i + yk·k`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LatticeMap {
    x0: i64,
    xi: i64,
    xk: i64,
    y0: i64,
    yi: i64,
    yk: i64,
}

impl LatticeMap {
    fn apply(&self, i: i64, k: i64) -> (i64, i64) {
        (
            self.x0 + self.xi * i + self.xk * k,
            self.y0 + self.yi * i + self.yk * k,
        )
    }
}

/// The pixels `i` (half-open range) for which `a + c·i` lies in `0..n`, for
/// a step `c` of -1, 0 or 1 (one coordinate of a [`LatticeMap`] along a row).
fn on_grid(a: i64, c: i64, n: i64) -> (i64, i64) {
    match c {
        0 if (0..n).contains(&a) => (i64::MIN, i64::MAX),
        0 => (0, 0),
        1 => (-a, n - a),
        _ => (a - n + 1, a + 1),
    }
}

/// The integer map when pixel centres fall on grid cell centres (same cell
/// size, frame rotated by a multiple of 90°, lattices aligned), else `None`.
fn lattice_map(f: &SweepFrame, g: &Grid) -> Option<LatticeMap> {
    let r = g.resolution();
    if (f.h - r).abs() > 1e-9 * r {
        return None;
    }
    let o = g.origin();
    let at = |i: usize, k: usize| {
        let p = f.to_world(f.col_u(i), f.row_v(k));
        ((p.x - o.x) / r - 0.5, (p.y - o.y) / r - 0.5)
    };
    let (a, b, c) = (at(0, 0), at(1, 0), at(0, 1));
    let near_int = |v: f64| (v - v.round()).abs() < 1e-6;
    let all = [a.0, a.1, b.0 - a.0, b.1 - a.1, c.0 - a.0, c.1 - a.1];
    if !all.iter().all(|&v| v.is_finite() && near_int(v)) {
        return None;
    }
    Some(LatticeMap {
        x0: a.0.round() as i64,
        xi: (b.0 - a.0).round() as i64,
        xk: (c.0 - a.0).round() as i64,
        y0: a.1.round() as i64,
        yi: (b.1 - a.1).round() as i64,
        yk: (c.1 - a.1).round() as i64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 37 x 23 grid of the three states in a fixed pattern, origin off the
    /// cell lattice of the world.
    fn mixed_grid() -> Grid {
        let mut g = Grid::new(nalgebra::Point2::new(-1.25, 0.45), 0.05, 37, 23);
        for y in 0..23 {
            for x in 0..37 {
                let s = match (x * 7 + y * 3 + x * y) % 5 {
                    0 => CellState::Unknown,
                    1 | 2 => CellState::Free,
                    _ => CellState::Occupied,
                };
                g.set_state((x, y), s);
            }
        }
        g
    }

    #[test]
    fn wall_cells_on_the_lattice_block_what_each_cell_blocks_alone() {
        // Walls, a pillar and scattered occupied cells in a free room; the
        // blocked intervals from the column distances must be those of the
        // general path (every wall point inflated on its own, sorted,
        // merged), for the frame along each quarter turn.
        let mut g = Grid::new(nalgebra::Point2::new(-0.8, 0.35), 0.05, 61, 47);
        let mut seed = 777u32;
        for y in 0..47 {
            for x in 0..61 {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                let wall = x == 2
                    || y == 3
                    || x == 58
                    || y == 44
                    || (20..24).contains(&x) && (15..19).contains(&y);
                let s = if wall || (seed >> 16).is_multiple_of(37) {
                    CellState::Occupied
                } else if x < 2 || y < 3 || x > 58 || y > 44 {
                    CellState::Unknown
                } else {
                    CellState::Free
                };
                g.set_state((x, y), s);
            }
        }
        for q in 0..4 {
            let f =
                SweepFrame::over_grid(&g, q as f64 * std::f64::consts::FRAC_PI_2, 0.05).unwrap();
            let input = SliceInput {
                grid: &g,
                segments: &[],
                radius: 0.17,
                gap_pixels: 3,
                frozen: &[],
                min_beside_frozen: 0.0,
            };
            let mut sl = Slices::default();
            assert!(sl.compute(&f, &input));
            assert!(sl.lattice_square.is_some(), "quarter turn {q}");
            let (fast, fast_rows) = (sl.blocked.clone(), sl.blocked_rows.clone());
            sl.lattice_square = None;
            sl.inflate(&f);
            assert_eq!(
                fast_rows, sl.blocked_rows,
                "quarter turn {q}: intervals per row"
            );
            assert!(
                fast.len() > 100,
                "quarter turn {q}: {} intervals",
                fast.len()
            );
            for (a, b) in fast.iter().zip(&sl.blocked) {
                assert!(
                    (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9,
                    "quarter turn {q}: {a:?} against {b:?}"
                );
            }
        }
    }

    #[test]
    fn a_frame_off_the_lattice_resamples_the_cell_under_each_pixel() {
        let g = mixed_grid();
        // Turned frames, and one along the grid with smaller pixels.
        for (angle, h) in [(0.3, 0.05), (1.0, 0.05), (-2.2, 0.05), (0.0, 0.03)] {
            let f = SweepFrame::over_grid(&g, angle, h).unwrap();
            assert!(lattice_map(&f, &g).is_none(), "angle {angle}, h {h}");
            let mut sl = Slices {
                px: vec![BLOCKED; f.nu * f.nv],
                window: (1, f.nu - 1, 2, f.nv - 1),
                ..Slices::default()
            };
            sl.resample(&f, &g);
            let mut on_grid = 0;
            for k in 2..f.nv - 1 {
                for i in 1..f.nu - 1 {
                    let p = f.to_world(f.col_u(i), f.row_v(k));
                    let want = match g.cell_of(&p).map(|c| g.state(c)) {
                        Some(CellState::Free) => FREE,
                        Some(CellState::Occupied) => OCC,
                        _ => UNK,
                    };
                    // Within rounding of a cell's edge either cell will do.
                    let (fx, fy) = ((p.x + 1.25) / 0.05, (p.y - 0.45) / 0.05);
                    let edge = (fx - fx.round()).abs() < 1e-9 || (fy - fy.round()).abs() < 1e-9;
                    if !edge {
                        assert_eq!(sl.at(&f, i, k), want, "angle {angle}, pixel ({i}, {k})");
                    }
                    on_grid += usize::from(g.cell_of(&p).is_some());
                }
            }
            assert!(on_grid > 500, "angle {angle}: {on_grid} pixels on the grid");
        }
    }

    #[test]
    fn a_grid_turned_by_quarter_turns_resamples_cell_for_cell() {
        // A 37 x 23 grid of mixed cells; frames at 0, 90, 180 and 270
        // degrees map pixels onto cells (the lattice path): every pixel of
        // a window must hold the class of the cell under its centre.
        let g = mixed_grid();
        for q in 0..4 {
            let mut f =
                SweepFrame::over_grid(&g, q as f64 * std::f64::consts::FRAC_PI_2, 0.05).unwrap();
            // Three pixels more on every side: rows and columns off the grid.
            f.u0 -= 3.0 * f.h;
            f.v0 -= 3.0 * f.h;
            f.nu += 6;
            f.nv += 6;
            assert!(lattice_map(&f, &g).is_some(), "quarter turn {q}");
            for window in [(0, f.nu, 0, f.nv), (4, f.nu - 2, 1, f.nv - 5)] {
                let mut sl = Slices {
                    px: vec![BLOCKED; f.nu * f.nv],
                    window,
                    ..Slices::default()
                };
                sl.resample(&f, &g);
                let (i0, i1, k0, k1) = window;
                for k in k0..k1 {
                    for i in i0..i1 {
                        let p = f.to_world(f.col_u(i), f.row_v(k));
                        let want = match g.cell_of(&p).map(|c| g.state(c)) {
                            Some(CellState::Free) => FREE,
                            Some(CellState::Occupied) => OCC,
                            _ => UNK,
                        };
                        assert_eq!(sl.at(&f, i, k), want, "quarter turn {q}, pixel ({i}, {k})");
                    }
                }
            }
        }
    }

    #[test]
    fn wall_points_block_disks_and_rounded_squares() {
        let disk = WallPoint {
            u: 1.0,
            v: 2.0,
            e: 0.0,
            r: 0.5,
        };
        assert!((disk.half_width_at(2.0).unwrap() - 0.5).abs() < 1e-12);
        assert!((disk.half_width_at(2.3).unwrap() - 0.4).abs() < 1e-12);
        assert!(disk.half_width_at(2.5).is_none());
        let square = WallPoint { e: 0.1, ..disk };
        assert!((square.half_width_at(2.05).unwrap() - 0.6).abs() < 1e-12);
        assert!((square.half_width_at(2.4).unwrap() - 0.5).abs() < 1e-12);
        // Reach across the lanes toward an interval beside it.
        assert!((disk.reach_across(0.0, 0.6).unwrap() - 0.3).abs() < 1e-12);
        assert!(disk.reach_across(-2.0, 0.4).is_none());
        let expect = 0.1 + (0.25f64 - 0.01).sqrt();
        assert!((square.reach_across(1.2, 3.0).unwrap() - expect).abs() < 1e-12);
    }
}
