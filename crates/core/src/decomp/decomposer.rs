//! The online decomposer: sweep direction, slicing, sweep, then cell
//! inheritance (ids by overlap with the previous update) and finality.

use std::collections::HashMap;
use std::f64::consts::FRAC_PI_2;

use nalgebra::Point2;

use crate::geom::{wrap_angle, Segment};
use crate::grid::{CellState, Grid};

use super::cell::{Adjacency, Cell, CellId, CellStatus, Decomposition, Frontier};
use super::direction;
use super::frame::SweepFrame;
use super::labels::LabelSpans;
use super::polygon::simplify_chain;
use super::slices::{FrozenSpan, SliceInput, Slices};
use super::sweep::{CellRef, RawCell, Sweep, SweepInput};
use super::{check, DecompError, DecompParams, Lap, PhaseTimes};

const NO_LABEL: u32 = u32::MAX;

/// What the decomposer remembers of a non-final cell between updates.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Track {
    id: CellId,
    width: f64,
    length: f64,
    stable: u32,
}

/// A final cell: frozen polygon and its slice spans.
#[derive(Clone, Debug, PartialEq)]
struct Frozen {
    cell: Cell,
    spans: Vec<(u32, f64, f64)>,
}

/// Geometry of the grid the frame was built for; a change resets the decomposer.
#[derive(Clone, Copy, Debug, PartialEq)]
struct GridShape {
    origin: Point2<f64>,
    resolution: f64,
    width: usize,
    height: usize,
}

impl GridShape {
    fn of(g: &Grid) -> Self {
        Self {
            origin: g.origin(),
            resolution: g.resolution(),
            width: g.width(),
            height: g.height(),
        }
    }
}

/// The online decomposer: keeps the previous decomposition so cells inherit
/// their ids and finality builds up over updates.
#[derive(Clone, Debug)]
pub struct Decomposer {
    params: DecompParams,
    inflation: f64,
    current: Decomposition,
    shape: Option<GridShape>,
    locked_angle: Option<f64>,
    frame: Option<SweepFrame>,
    slices: Slices,
    sweep: Sweep,
    labels: Vec<u32>,
    prev_labels: Vec<u32>,
    spans: LabelSpans,
    prev_frame: Option<SweepFrame>,
    tracks: Vec<Track>,
    frozen: Vec<Frozen>,
    frozen_spans: Vec<FrozenSpan>,
    frozen_adjacency: Vec<Adjacency>,
    next_id: u32,
    updates: u64,
    times: PhaseTimes,
}

impl Decomposer {
    /// A decomposer for a robot of radius `robot_radius` (m); walls are
    /// inflated by `robot_radius + params.inflation_margin`.
    pub fn new(params: &DecompParams, robot_radius: f64) -> Result<Self, DecompError> {
        params.validate()?;
        check(
            "robot_radius",
            robot_radius.is_finite() && (0.0..=2.0).contains(&robot_radius),
            format!("robot radius must be within 0..2 m, got {robot_radius}"),
        )?;
        let inflation = robot_radius + params.inflation_margin;
        Ok(Self {
            params: params.clone(),
            inflation,
            current: Decomposition {
                inflation,
                ..Decomposition::default()
            },
            shape: None,
            locked_angle: None,
            frame: None,
            slices: Slices::default(),
            sweep: Sweep::default(),
            labels: Vec::new(),
            prev_labels: Vec::new(),
            spans: LabelSpans::default(),
            prev_frame: None,
            tracks: Vec::new(),
            frozen: Vec::new(),
            frozen_spans: Vec::new(),
            frozen_adjacency: Vec::new(),
            next_id: 0,
            updates: 0,
            times: PhaseTimes::default(),
        })
    }

    /// The settings in use.
    pub fn params(&self) -> &DecompParams {
        &self.params
    }

    /// The latest decomposition (empty before the first update).
    pub fn decomposition(&self) -> &Decomposition {
        &self.current
    }

    /// The lane direction once fixed for the run (rad), `None` while too
    /// little wall has been seen.
    pub fn locked_angle(&self) -> Option<f64> {
        self.locked_angle
    }

    /// Where the last update's time went.
    pub fn phase_times(&self) -> PhaseTimes {
        self.times
    }

    /// Number of updates so far.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// Forgets every cell: nothing is final, the direction is free again. Ids
    /// are never reused: new cells get ids above every id handed out before,
    /// so a planner's bookkeeping by id cannot mix old and new cells.
    pub fn reset(&mut self) {
        self.shape = None;
        self.locked_angle = None;
        self.frame = None;
        self.prev_frame = None;
        self.labels.clear();
        self.prev_labels.clear();
        self.spans.clear();
        self.tracks.clear();
        self.frozen.clear();
        self.frozen_spans.clear();
        self.frozen_adjacency.clear();
        self.current = Decomposition {
            inflation: self.inflation,
            ..Decomposition::default()
        };
    }

    /// Recomposes the open cells from the current map: `grid` is the
    /// explored-area evidence grid, `segments` the walls seen as lines (may be
    /// empty). Final cells keep their polygons; the others inherit ids by
    /// overlap. Never fails: an unexplored grid gives an empty decomposition.
    /// A grid of another size, origin or resolution than the previous one
    /// starts afresh (see [`Decomposer::reset`]).
    pub fn update(&mut self, grid: &Grid, segments: &[Segment]) -> &Decomposition {
        self.updates += 1;
        let shape = GridShape::of(grid);
        if self.shape != Some(shape) {
            self.reset();
            self.shape = Some(shape);
        }
        let mut clock = Lap::start();
        let angle = self.sweep_angle(grid, segments);
        let direction = clock.lap();
        let Some(frame) = SweepFrame::over_grid(grid, angle, self.params.resolution) else {
            // A grid with non-finite or absurd geometry: nothing usable.
            self.reset();
            return &self.current;
        };
        if self.frame != Some(frame) {
            // Only before the direction is locked: nothing is frozen yet.
            self.frozen.clear();
            self.frozen_spans.clear();
            self.frozen_adjacency.clear();
        }
        self.prev_frame = self.frame;
        self.frame = Some(frame);
        let gap_pixels = (self.params.gap_fill / frame.h).floor() as usize;
        self.slices.compute(
            &frame,
            &SliceInput {
                grid,
                segments,
                radius: self.inflation,
                gap_pixels,
                frozen: &self.frozen_spans,
                min_beside_frozen: self.params.min_cell_width * 0.5,
            },
        );
        // The slicing times its own steps (`Slices::times`).
        clock.lap();
        self.sweep.run(
            &frame,
            &self.slices,
            &SweepInput {
                step_split: self.params.step_split,
                radius: self.inflation,
                frozen: &self.frozen_spans,
                min_width: self.params.min_cell_width,
                min_area: self.params.min_cell_area,
            },
        );
        let sweep = clock.lap();
        self.inherit_and_publish(&frame);
        self.times = PhaseTimes {
            direction,
            sweep,
            inherit: clock.lap(),
            ..self.slices.times
        };
        &self.current
    }

    fn sweep_angle(&mut self, grid: &Grid, segments: &[Segment]) -> f64 {
        if let Some(a) = self.locked_angle {
            return a;
        }
        if let Some(a) = self.params.sweep_angle {
            self.locked_angle = Some(wrap_angle(a));
            return wrap_angle(a);
        }
        // The explored part of the grid.
        let Some(((x0, y0), (x1, y1))) = grid.explored_cells() else {
            return 0.0;
        };
        let window = (x0.saturating_sub(1), y0.saturating_sub(1), x1 + 2, y1 + 2);
        let est = direction::from_segments(segments)
            .or_else(|| direction::from_grid_window(grid, window));
        let Some(mut est) = est else {
            return 0.0;
        };
        if est.angle.abs() <= self.params.axis_snap {
            est.angle = 0.0;
        }
        // Lanes along the axis on which the explored free space is longer.
        let (c, s) = (est.angle.cos(), est.angle.sin());
        let (mut lo_u, mut hi_u, mut lo_v, mut hi_v) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for y in y0..=y1 {
            for x in x0..=x1 {
                if grid.state((x, y)) == CellState::Free {
                    let p = grid.centre_of((x, y));
                    let (u, v) = (c * p.x + s * p.y, -s * p.x + c * p.y);
                    lo_u = lo_u.min(u);
                    hi_u = hi_u.max(u);
                    lo_v = lo_v.min(v);
                    hi_v = hi_v.max(v);
                }
            }
        }
        let angle = if hi_v - lo_v > hi_u - lo_u {
            wrap_angle(est.angle + FRAC_PI_2)
        } else {
            est.angle
        };
        if est.evidence >= self.params.min_wall_evidence {
            self.locked_angle = Some(angle);
        }
        angle
    }

    fn inherit_and_publish(&mut self, f: &SweepFrame) {
        let n = f.nu * f.nv;
        // Pixel labels serve only a next update in another frame, which
        // cannot follow once the direction is locked.
        let pixels = self.locked_angle.is_none();
        std::mem::swap(&mut self.labels, &mut self.prev_labels);
        self.labels.clear();
        if pixels {
            self.labels.resize(n, NO_LABEL);
        }
        self.spans.begin();
        for fz in &self.frozen {
            for &(k, l, r) in &fz.spans {
                let span = pixel_span(f, l, r);
                self.spans.paint(k as usize, span, fz.cell.id.0);
                if pixels {
                    paint(&mut self.labels, f, k as usize, span, fz.cell.id.0);
                }
            }
        }
        let cells = &self.sweep.cells;
        let nc = cells.len();
        // Overlap of every new cell with the previous update's cells, in
        // pixels: span against span in the same frame, else pixel by pixel
        // through the world.
        let same_frame = self.prev_frame == Some(*f);
        let mut overlaps: Vec<((u32, u32), u32)> = Vec::new();
        let mut of_cell: Vec<(u32, u32)> = Vec::new();
        for (ci, cell) in cells.iter().enumerate() {
            of_cell.clear();
            let mut add = |old: u32, count: u32| match of_cell.iter_mut().find(|o| o.0 == old) {
                Some(o) => o.1 += count,
                None => of_cell.push((old, count)),
            };
            for p in &cell.pieces {
                let k = p.row as usize;
                let (a, b) = pixel_span(f, p.l, p.r);
                if same_frame {
                    self.spans.overlaps(k, (a, b), &mut add);
                    continue;
                }
                let Some(pf) = self.prev_frame else {
                    continue;
                };
                for i in a..b {
                    let old =
                        old_label(&self.prev_labels, &pf, &f.to_world(f.col_u(i), f.row_v(k)));
                    if old != NO_LABEL {
                        add(old, 1);
                    }
                }
            }
            overlaps.extend(
                of_cell
                    .iter()
                    .map(|&(old, count)| ((old, ci as u32), count)),
            );
        }
        let frozen_ids: Vec<u32> = self.frozen.iter().map(|z| z.cell.id.0).collect();
        let mut pairs: Vec<((u32, u32), u32)> = overlaps
            .into_iter()
            .filter(|((old, _), _)| !frozen_ids.contains(old))
            .collect();
        pairs.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let mut assigned: Vec<Option<Track>> = vec![None; nc];
        let old_tracks: HashMap<u32, Track> = self.tracks.iter().map(|t| (t.id.0, *t)).collect();
        let mut used: Vec<u32> = Vec::new();
        for ((old, ci), _) in pairs {
            if assigned[ci as usize].is_some() || used.contains(&old) {
                continue;
            }
            if let Some(t) = old_tracks.get(&old) {
                assigned[ci as usize] = Some(*t);
                used.push(old);
            }
        }
        // Ids, stability, status.
        let tol = self.params.size_tolerance;
        let open_at = self.params.min_frontier;
        let mut new_tracks = Vec::with_capacity(nc);
        let mut out_cells: Vec<Cell> = Vec::with_capacity(nc + self.frozen.len());
        let mut index_to_id: Vec<CellId> = Vec::with_capacity(nc);
        let mut newly_frozen: Vec<usize> = Vec::new();
        let locked = self.locked_angle.is_some();
        for (ci, cell) in cells.iter().enumerate() {
            let (w, l) = (cell.width(), cell.length());
            let open = cell.frontier_len >= open_at;
            let track = match assigned[ci] {
                Some(t) => {
                    let unchanged = (t.width - w).abs() <= tol && (t.length - l).abs() <= tol;
                    Track {
                        id: t.id,
                        width: w,
                        length: l,
                        stable: if unchanged && !open { t.stable + 1 } else { 0 },
                    }
                }
                None => {
                    let id = CellId(self.next_id);
                    self.next_id += 1;
                    Track {
                        id,
                        width: w,
                        length: l,
                        stable: 0,
                    }
                }
            };
            let status = if open {
                CellStatus::Open
            } else if locked && track.stable >= self.params.stable_updates {
                CellStatus::Final
            } else {
                CellStatus::Settling
            };
            index_to_id.push(track.id);
            if status == CellStatus::Final {
                newly_frozen.push(ci);
            } else {
                new_tracks.push(track);
            }
            out_cells.push(Cell {
                id: track.id,
                polygon: cell_polygon(f, cell, self.params.simplify_tolerance),
                status,
                sweep_angle: f.angle,
                width: w,
                length: l,
            });
            for p in &cell.pieces {
                let span = pixel_span(f, p.l, p.r);
                self.spans.paint(p.row as usize, span, track.id.0);
                if pixels {
                    paint(&mut self.labels, f, p.row as usize, span, track.id.0);
                }
            }
        }
        self.tracks = new_tracks;
        // Adjacency with ids.
        let id_of = |r: CellRef, frozen: &[Frozen]| match r {
            CellRef::New(i) => index_to_id[i as usize],
            CellRef::Frozen(z) => frozen[z as usize].cell.id,
        };
        let mut adjacency: Vec<Adjacency> = self.frozen_adjacency.clone();
        for a in &self.sweep.adjacency {
            adjacency.push(Adjacency {
                a: id_of(a.a, &self.frozen),
                b: id_of(a.b, &self.frozen),
                boundary: Segment::new(f.to_world(a.seg.0, a.seg.1), f.to_world(a.seg.2, a.seg.3)),
            });
        }
        let mut frontiers = Vec::new();
        for (ci, cell) in cells.iter().enumerate() {
            if cell.frontier_len < open_at {
                continue;
            }
            for &(u1, v1, u2, v2) in &cell.frontier {
                frontiers.push(Frontier {
                    cell: index_to_id[ci],
                    boundary: Segment::new(f.to_world(u1, v1), f.to_world(u2, v2)),
                });
            }
        }
        // Freeze the cells that became final.
        for &ci in &newly_frozen {
            let cell = &cells[ci];
            self.frozen.push(Frozen {
                cell: out_cells[ci].clone(),
                spans: cell.pieces.iter().map(|p| (p.row, p.l, p.r)).collect(),
            });
        }
        let frozen_ids: Vec<CellId> = self.frozen.iter().map(|z| z.cell.id).collect();
        self.frozen_adjacency = adjacency
            .iter()
            .filter(|a| frozen_ids.contains(&a.a) && frozen_ids.contains(&a.b))
            .copied()
            .collect();
        self.frozen_adjacency.sort_by_key(|a| (a.a, a.b));
        self.frozen_adjacency.dedup_by_key(|a| (a.a, a.b));
        self.frozen_spans.clear();
        for (zi, z) in self.frozen.iter().enumerate() {
            for &(row, l, r) in &z.spans {
                self.frozen_spans.push(FrozenSpan {
                    row,
                    l,
                    r,
                    cell: zi as u32,
                });
            }
        }
        self.frozen_spans
            .sort_by(|a, b| a.row.cmp(&b.row).then(a.l.total_cmp(&b.l)));
        // Publish: frozen (final) cells plus the new ones, by id.
        let mut all: Vec<Cell> = self
            .frozen
            .iter()
            .filter(|z| !out_cells.iter().any(|c| c.id == z.cell.id))
            .map(|z| z.cell.clone())
            .collect();
        all.extend(out_cells);
        all.sort_by_key(|c| c.id);
        adjacency.sort_by_key(|a| (a.a.min(a.b), a.a.max(a.b)));
        adjacency.dedup_by_key(|a| (a.a.min(a.b), a.a.max(a.b)));
        let virtual_edges = adjacency.iter().map(|a| a.boundary).collect();
        self.current = Decomposition {
            cells: all,
            adjacency,
            sweep_angle: f.angle,
            frontiers,
            virtual_edges,
            inflation: self.inflation,
        };
    }
}

/// Columns whose centres lie in `[l, r]`, as a half-open range.
fn pixel_span(f: &SweepFrame, l: f64, r: f64) -> (usize, usize) {
    let a = ((l - f.u0) / f.h - 0.5).ceil().max(0.0) as usize;
    let b = (((r - f.u0) / f.h - 0.5).floor() + 1.0).max(0.0) as usize;
    (a.min(f.nu), b.min(f.nu).max(a.min(f.nu)))
}

/// Labels the pixels `a..b` (a [`pixel_span`]) of row `k` with `id`.
fn paint(labels: &mut [u32], f: &SweepFrame, k: usize, (a, b): (usize, usize), id: u32) {
    if k >= f.nv {
        return;
    }
    for x in &mut labels[k * f.nu + a..k * f.nu + b] {
        *x = id;
    }
}

fn old_label(labels: &[u32], pf: &SweepFrame, p: &Point2<f64>) -> u32 {
    let (u, v) = pf.to_uv(p);
    let (fi, fk) = ((u - pf.u0) / pf.h, (v - pf.v0) / pf.h);
    if !(fi >= 0.0 && fk >= 0.0) {
        return NO_LABEL;
    }
    let (i, k) = (fi as usize, fk as usize);
    if i >= pf.nu || k >= pf.nv {
        return NO_LABEL;
    }
    labels.get(k * pf.nu + i).copied().unwrap_or(NO_LABEL)
}

/// The polygon of a swept cell, counter-clockwise in the world frame. Sides
/// follow the slice ends at the slice centres (a slanted or curved wall stays
/// a slanted or curved polyline); where an end jumps by more than a pixel
/// between slices, the side steps at the slice boundary instead.
fn cell_polygon(f: &SweepFrame, cell: &RawCell, tol: f64) -> Vec<Point2<f64>> {
    let (Some(first), Some(last)) = (cell.pieces.first(), cell.pieces.last()) else {
        return Vec::new();
    };
    let side = |end: &dyn Fn(&super::slices::Piece) -> f64| -> Vec<(f64, f64)> {
        let mut out = vec![(end(first), cell.vb)];
        for (t, p) in cell.pieces.iter().enumerate() {
            let vc = f.row_v(p.row as usize).clamp(cell.vb, cell.vt);
            if t > 0 {
                let q = &cell.pieces[t - 1];
                if (end(p) - end(q)).abs() > f.h {
                    let edge = f.row_edge(p.row as usize).clamp(cell.vb, cell.vt);
                    out.push((end(q), edge));
                    out.push((end(p), edge));
                }
            }
            out.push((end(p), vc));
        }
        out.push((end(last), cell.vt));
        out
    };
    let mut right = vec![(first.l, cell.vb)];
    right.extend(side(&|p| p.r));
    let mut left = vec![(last.r, cell.vt)];
    left.extend(side(&|p| p.l).into_iter().rev());
    let a = simplify_chain(&right, tol);
    let b = simplify_chain(&left, tol);
    let mut ring: Vec<(f64, f64)> = a;
    ring.pop();
    ring.extend(b);
    ring.pop();
    ring.dedup_by(|x, y| (x.0 - y.0).abs() < 1e-9 && (x.1 - y.1).abs() < 1e-9);
    ring.into_iter().map(|(u, v)| f.to_world(u, v)).collect()
}
