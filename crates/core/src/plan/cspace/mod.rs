//! The planner's view of the explored map: which grid cells the robot's
//! centre may occupy (known free, farther than the inflation distance from
//! every seen obstacle and every unexplored cell), travel distances over them
//! (Dijkstra), point-to-point paths (A*) shortened by line of sight, and
//! frontier cells where explored free space meets unexplored space.
//!
//! Buffers are allocated once per grid size and reused on every update.

mod build;
mod frame;
mod frontier;
mod search;
mod segments;
#[cfg(test)]
mod tests;

use std::collections::BinaryHeap;

use nalgebra::Point2;

pub use frame::{disk, Frame};
use search::Entry;

/// Cell state as the planner stores it.
pub(crate) const UNKNOWN: u8 = 0;
/// Seen free.
pub const FREE: u8 = 1;
/// Seen occupied.
pub(crate) const OCCUPIED: u8 = 2;

/// Length of a straight run of occupied cells (odd, cells) beside a surface
/// cell that makes it a face cell, which the surface hold does not keep
/// (see [`CSpace::set_surface_hold`]): 5 cells, 25 cm on a 5 cm grid.
const WALL_FACE_CELLS: usize = 5;

/// Configuration space and travel distances over the explored grid.
#[derive(Clone, Debug)]
pub struct CSpace {
    /// Geometry.
    pub frame: Frame,
    /// Per-cell `UNKNOWN`/[`FREE`]/`OCCUPIED`.
    pub state: Vec<u8>,
    /// Free cells a beam has ended in (see `Grid::was_hit`): not frontier.
    pub surface: Vec<bool>,
    /// Free cells that hold a surface (see `Grid::holds_surface`), or
    /// held one within the last `CSpace::set_surface_hold` rebuilds: the
    /// robot keeps its clearance from them as from obstacle cells.
    pub held: Vec<bool>,
    /// Rebuilds a surface keeps blocking after the grid lets it go.
    hold: u32,
    /// Rebuilds so far (the clock of `held_until`).
    rebuilds: u32,
    /// Per cell: the rebuild at which a surface the grid let go stops
    /// blocking (0: none pending).
    held_until: Vec<u32>,
    /// Where the robot centre may be.
    pub traversable: Vec<bool>,
    /// Where the robot body touches no seen obstacle (clearance of the bare
    /// robot radius, no margin): a path leaving it is blocked.
    pub(crate) collision_free: Vec<bool>,
    /// Travel distance from the last `CSpace::distances_from` source (m; ∞ unreachable).
    pub dist: Vec<f64>,
    prev: Vec<u32>,
    /// Extra cost factor per cell (0 = none): travel over a cell costs
    /// `(1 + extra)` times its length. See [`CSpace::set_extra_cost`].
    extra: Vec<f32>,
    inflate: Vec<(i64, i64)>,
    hard: Vec<(i64, i64)>,
    /// Chebyshev extent (cells) of the widest of `inflate` and `hard`.
    reach: usize,
    /// The grid's explored box at the last rebuild.
    known: Option<Rect>,
    radius: f64,
    inflation: f64,
    heap: BinaryHeap<Entry>,
    /// Scratch distances of [`CSpace::travel_linked`] (∞ where untouched).
    scratch: Vec<f64>,
    /// Cells `scratch` holds a value for (reset after each search).
    touched: Vec<u32>,
    /// Scratch: which source's region a cell is in (see [`CSpace::travel_linked`]).
    label: Vec<u32>,
}

/// What a cell within the clearance of the robot centre is (see
/// [`CSpace::blocker`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BlockerKind {
    /// A cell seen occupied.
    Obstacle,
    /// A free cell holding a surface (a wall seen in mid-cell).
    Surface,
    /// A cell not yet seen.
    Unexplored,
    /// The edge of the map's grid.
    Border,
}

impl BlockerKind {
    /// A few words for logs.
    pub fn describe(self) -> &'static str {
        match self {
            BlockerKind::Obstacle => "an obstacle cell",
            BlockerKind::Surface => "a free cell holding a surface",
            BlockerKind::Unexplored => "an unexplored cell",
            BlockerKind::Border => "the map's edge",
        }
    }
}

/// The nearest thing within the robot centre's clearance (see
/// [`CSpace::blocker`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Blocker {
    /// What it is.
    pub kind: BlockerKind,
    /// Its cell's centre (m).
    pub at: Point2<f64>,
    /// Distance from the robot centre to the edge of its cell (m).
    pub distance: f64,
}

/// An inclusive box of cells.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Rect {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

impl Rect {
    /// The smallest box holding both.
    fn union(&self, o: &Rect) -> Rect {
        Rect {
            x0: self.x0.min(o.x0),
            y0: self.y0.min(o.y0),
            x1: self.x1.max(o.x1),
            y1: self.y1.max(o.y1),
        }
    }

    /// Grown by `k` cells on every side, clipped to a `w` × `h` grid.
    fn grow(&self, k: usize, w: usize, h: usize) -> Rect {
        Rect {
            x0: self.x0.saturating_sub(k),
            y0: self.y0.saturating_sub(k),
            x1: (self.x1 + k).min(w - 1),
            y1: (self.y1 + k).min(h - 1),
        }
    }
}

const NEIGHBOURS: [(i64, i64, f64); 8] = [
    (1, 0, 1.0),
    (-1, 0, 1.0),
    (0, 1, 1.0),
    (0, -1, 1.0),
    (1, 1, std::f64::consts::SQRT_2),
    (1, -1, std::f64::consts::SQRT_2),
    (-1, 1, std::f64::consts::SQRT_2),
    (-1, -1, std::f64::consts::SQRT_2),
];

/// Cell offsets whose square lies closer than `radius` to a cell centre.
fn square_offsets(radius: f64, r: f64) -> Vec<(i64, i64)> {
    let k = (radius / r).ceil() as i64 + 1;
    let mut v = Vec::new();
    for dy in -k..=k {
        for dx in -k..=k {
            let gx = (dx.abs() as f64 - 0.5).max(0.0) * r;
            let gy = (dy.abs() as f64 - 0.5).max(0.0) * r;
            if (gx * gx + gy * gy).sqrt() < radius {
                v.push((dx, dy));
            }
        }
    }
    v
}

/// Distance from point `p` to the square of side `res` centred at `c` (0
/// inside it): how near a body centred at `p` comes to a whole grid cell.
#[inline]
fn square_gap(p: &Point2<f64>, c: &Point2<f64>, res: f64) -> f64 {
    let gx = ((p.x - c.x).abs() - 0.5 * res).max(0.0);
    let gy = ((p.y - c.y).abs() - 0.5 * res).max(0.0);
    gx.hypot(gy)
}

impl CSpace {
    /// An empty configuration space; `inflation` is the clearance (m) the
    /// robot centre keeps from obstacle and unexplored cells, `radius` the
    /// robot radius (a path closer than that to a seen obstacle is blocked).
    pub fn new(inflation: f64, radius: f64) -> Self {
        Self {
            frame: Frame {
                origin: Point2::origin(),
                res: 1.0,
                w: 0,
                h: 0,
            },
            state: Vec::new(),
            surface: Vec::new(),
            held: Vec::new(),
            hold: 0,
            rebuilds: 0,
            held_until: Vec::new(),
            traversable: Vec::new(),
            collision_free: Vec::new(),
            hard: Vec::new(),
            radius,
            dist: Vec::new(),
            prev: Vec::new(),
            extra: Vec::new(),
            inflate: Vec::new(),
            reach: 0,
            known: None,
            inflation,
            heap: BinaryHeap::new(),
            scratch: Vec::new(),
            touched: Vec::new(),
            label: Vec::new(),
        }
    }

    /// The clearance in use (m).
    pub fn inflation(&self) -> f64 {
        self.inflation
    }

    /// What keeps the robot centre at `p` out of the traversable space: of
    /// the obstacle, unexplored or surface-holding cells bordering free
    /// floor within the clearance of `p`'s cell, the nearest to `p` (by the
    /// distance to the edge of its square); else the grid's border; `None`
    /// when `p` is off the grid or its cell is not blocked.
    pub(crate) fn blocker(&self, p: &Point2<f64>) -> Option<Blocker> {
        let f = self.frame;
        let i = f.index_of(p)?;
        let (w, h) = (f.w as i64, f.h as i64);
        let (x, y) = ((i as i64) % w, (i as i64) / w);
        let mut best: Option<Blocker> = None;
        for &(dx, dy) in &self.inflate {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w || ny >= h {
                continue;
            }
            let j = (ny * w + nx) as usize;
            if self.state[j] == FREE && !self.held[j] {
                continue;
            }
            if !self.borders_free(nx, ny) {
                continue;
            }
            // Within the clearance of the robot's cell (what makes it not
            // traversable); measured from the robot itself.
            let c = f.centre(j);
            let distance = square_gap(p, &c, f.res);
            if square_gap(&f.centre(i), &c, f.res) >= self.inflation
                || best.is_some_and(|b| b.distance <= distance)
            {
                continue;
            }
            let kind = match self.state[j] {
                OCCUPIED => BlockerKind::Obstacle,
                FREE => BlockerKind::Surface,
                _ => BlockerKind::Unexplored,
            };
            best = Some(Blocker {
                kind,
                at: c,
                distance,
            });
        }
        if best.is_none() {
            let edge = self.edge_distance(x as usize, y as usize);
            if edge < self.inflation {
                best = Some(Blocker {
                    kind: BlockerKind::Border,
                    at: f.centre(i),
                    distance: edge,
                });
            }
        }
        best
    }

    /// Whether the bare robot body (radius, no margin) centred on cell `i`
    /// lies on seen-free floor only: no seen obstacle and no unexplored cell
    /// under it. Weaker than [`CSpace::traversable`] (no safety margin, no
    /// clearance from the grid border), for short moves through a passage
    /// just wide enough for the body.
    pub(crate) fn body_clear(&self, i: usize) -> bool {
        let (w, h) = (self.frame.w as i64, self.frame.h as i64);
        let open = |j: usize| self.state[j] == FREE && !self.held[j];
        if i >= self.frame.len() || !open(i) {
            return false;
        }
        let (x, y) = ((i as i64) % w, (i as i64) / w);
        self.hard.iter().all(|&(dx, dy)| {
            let (nx, ny) = (x + dx, y + dy);
            nx >= 0 && ny >= 0 && nx < w && ny < h && open((ny * w + nx) as usize)
        })
    }

    /// Whether cell (`x`, `y`) has a free 8-neighbour: only obstacle and
    /// unexplored cells bordering free floor bound the clearance.
    #[inline]
    fn borders_free(&self, x: i64, y: i64) -> bool {
        let (w, h) = (self.frame.w as i64, self.frame.h as i64);
        NEIGHBOURS.iter().any(|&(dx, dy, _)| {
            let (nx, ny) = (x + dx, y + dy);
            nx >= 0 && ny >= 0 && nx < w && ny < h && self.state[(ny * w + nx) as usize] == FREE
        })
    }

    /// Distance (m, whole cells) of cell (`x`, `y`) from the grid's edge,
    /// which counts as unexplored.
    #[inline]
    fn edge_distance(&self, x: usize, y: usize) -> f64 {
        let (w, h) = (self.frame.w, self.frame.h);
        x.min(w - 1 - x).min(y).min(h - 1 - y) as f64 * self.frame.res
    }
}
