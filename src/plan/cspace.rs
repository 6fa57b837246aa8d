//! The planner's view of the explored map: which grid cells the robot's
//! centre may occupy (known free, farther than the inflation distance from
//! every seen obstacle and every unexplored cell), travel distances over them
//! (Dijkstra), point-to-point paths (A*) shortened by line of sight, and
//! frontier cells where explored free space meets unexplored space.
//!
//! Buffers are allocated once per grid size and reused on every update.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use nalgebra::Point2;

use crate::grid::{CellState, Grid};

/// Cell state as the planner stores it.
pub const UNKNOWN: u8 = 0;
/// Seen free.
pub const FREE: u8 = 1;
/// Seen occupied.
pub const OCCUPIED: u8 = 2;

/// Grid geometry shared by every planner raster.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// World position of the lower-left corner of cell (0, 0).
    pub origin: Point2<f64>,
    /// Cell size (m).
    pub res: f64,
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
}

impl Frame {
    /// Linear indices of the up to 8 cells around cell `i` that lie inside
    /// the frame (the grid's `NEIGHBOURS_8` order).
    pub fn neighbours8(&self, i: usize) -> impl Iterator<Item = usize> {
        crate::grid::neighbours8_of(i, self.w, self.h)
    }

    /// Linear indices of the cells at `offsets` (cells across, cells up)
    /// from cell `i` that lie inside the frame, in the order given.
    pub fn around<'a>(
        &self,
        i: usize,
        offsets: &'a [(i64, i64)],
    ) -> impl Iterator<Item = usize> + 'a {
        let (w, h) = (self.w, self.h);
        let (x, y) = ((i % w.max(1)) as i64, (i / w.max(1)) as i64);
        offsets.iter().filter_map(move |&(dx, dy)| {
            let (nx, ny) = (x + dx, y + dy);
            (nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h)
                .then(|| ny as usize * w + nx as usize)
        })
    }

    /// Linear index of the cell containing `p`, if inside.
    pub fn index_of(&self, p: &Point2<f64>) -> Option<usize> {
        let fx = (p.x - self.origin.x) / self.res;
        let fy = (p.y - self.origin.y) / self.res;
        if !(fx.is_finite() && fy.is_finite()) || fx < 0.0 || fy < 0.0 {
            return None;
        }
        let (x, y) = (fx as usize, fy as usize);
        (x < self.w && y < self.h).then_some(y * self.w + x)
    }

    /// Centre of cell `i`.
    pub fn centre(&self, i: usize) -> Point2<f64> {
        Point2::new(
            self.origin.x + ((i % self.w) as f64 + 0.5) * self.res,
            self.origin.y + ((i / self.w) as f64 + 0.5) * self.res,
        )
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.w * self.h
    }

    /// Whether the frame has no cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Cell offsets whose centre distance is at most `radius`.
pub fn disk(radius: f64, res: f64) -> Vec<(i64, i64)> {
    let n = (radius / res).ceil() as i64 + 1;
    let mut v = Vec::new();
    for dy in -n..=n {
        for dx in -n..=n {
            if ((dx * dx + dy * dy) as f64).sqrt() * res <= radius + 1e-9 {
                v.push((dx, dy));
            }
        }
    }
    v
}

/// Length of a straight run of occupied cells (odd, cells) beside a surface
/// cell that makes it a face cell, which the surface hold does not keep
/// (see [`CSpace::set_surface_hold`]): 5 cells, 25 cm on a 5 cm grid.
const WALL_FACE_CELLS: usize = 5;

/// Configuration space and travel distances over the explored grid.
#[derive(Clone, Debug)]
pub struct CSpace {
    /// Geometry.
    pub frame: Frame,
    /// Per-cell [`UNKNOWN`]/[`FREE`]/[`OCCUPIED`].
    pub state: Vec<u8>,
    /// Free cells a beam has ended in (see [`Grid::was_hit`]): not frontier.
    pub surface: Vec<bool>,
    /// Free cells that hold a surface (see [`Grid::holds_surface`]), or
    /// held one within the last [`CSpace::set_surface_hold`] rebuilds: the
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
    pub collision_free: Vec<bool>,
    /// Travel distance from the last [`CSpace::distances_from`] source (m; ∞ unreachable).
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
pub enum BlockerKind {
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
pub struct Blocker {
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

/// A search frontier entry; the heap pops the least cost first, the least
/// index among equal costs (so searches are deterministic).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    cost: f64,
    idx: u32,
}

impl Entry {
    /// The cost's bit pattern: for the non-negative costs of these searches
    /// (0, finite sums of positive steps, +∞) it orders as the cost does, and
    /// an integer comparison is cheaper than a float one in the heap.
    fn key(&self) -> (u64, u32) {
        debug_assert!(self.cost >= 0.0, "negative search cost {}", self.cost);
        (self.cost.to_bits(), self.idx)
    }
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        o.key().cmp(&self.key())
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
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

/// The cells one step from cell `i` that the robot may enter, each with the
/// cost of the step (m, weighted by the entered cell's extra cost); a
/// diagonal step never cuts past a blocked cell. Allocation-free; a free
/// function so that a search can borrow the grid beside its own tables.
fn grid_steps(
    frame: Frame,
    traversable: &[bool],
    extra: &[f32],
    i: usize,
) -> heapless::Vec<(usize, f64), 8> {
    let (w, h, r) = (frame.w as i64, frame.h as i64, frame.res);
    let (x, y) = ((i as i64) % w, (i as i64) / w);
    let mut out = heapless::Vec::new();
    for &(dx, dy, c) in &NEIGHBOURS {
        let (nx, ny) = (x + dx, y + dy);
        if nx < 0 || ny < 0 || nx >= w || ny >= h {
            continue;
        }
        let j = (ny * w + nx) as usize;
        if !traversable[j] {
            continue;
        }
        if dx != 0
            && dy != 0
            && (!traversable[(y * w + nx) as usize] || !traversable[(ny * w + x) as usize])
        {
            continue;
        }
        // At most 8 neighbours: the push cannot fail.
        let _ = out.push((j, c * r * (1.0 + extra[j] as f64)));
    }
    out
}

/// Dijkstra from the entries already in `heap` (their costs set in `dist`):
/// settles every cell reachable by `steps`, calling `improved(j, i, old)`
/// before cell `j`'s cost drops from `old` by a step from `i`.
fn settle<I: IntoIterator<Item = (usize, f64)>>(
    heap: &mut BinaryHeap<Entry>,
    dist: &mut [f64],
    steps: impl Fn(usize) -> I,
    mut improved: impl FnMut(usize, usize, f64),
) {
    while let Some(Entry { cost, idx }) = heap.pop() {
        let i = idx as usize;
        if cost > dist[i] {
            continue;
        }
        for (j, step) in steps(i) {
            let nc = cost + step;
            if nc < dist[j] {
                improved(j, i, dist[j]);
                dist[j] = nc;
                heap.push(Entry {
                    cost: nc,
                    idx: j as u32,
                });
            }
        }
    }
}

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

    /// Keeps a surface cell blocking for `rebuilds` more rebuilds after the
    /// grid stops holding it (0, the default: as the grid says). A cell at
    /// the edge of a chair or a table, hit by some scans and passed by
    /// others, is held and let go by turns; a path planned while it is let
    /// go is blocked when it is held again, and the plan starts over. The
    /// hold makes the configuration space change once, not at every turn.
    /// A cell just inside a straight face of `WALL_FACE_CELLS` (5) occupied
    /// cells is not held: on a wall, ranges ending in the first floor cell
    /// now and then are noise, and holding such cells cuts the lane that
    /// hugs the wall into pieces.
    pub fn set_surface_hold(&mut self, rebuilds: u32) {
        self.hold = rebuilds;
    }

    /// Lets go at once every surface the grid no longer holds and only the
    /// hold ([`CSpace::set_surface_hold`]) keeps blocking; returns their
    /// cells. The hold steadies the plan while the robot works; when
    /// nothing is left to do, floor beside such a cell is not to be lost to
    /// it.
    pub fn release_held(&mut self) -> Vec<usize> {
        let w = self.frame.w;
        let mut released: Option<Rect> = None;
        let mut cells = Vec::new();
        for (i, u) in self.held_until.iter_mut().enumerate() {
            if *u == 0 {
                continue;
            }
            *u = 0;
            self.held[i] = false;
            cells.push(i);
            let (x, y) = (i % w, i / w);
            let cell = Rect {
                x0: x,
                y0: y,
                x1: x,
                y1: y,
            };
            released = Some(released.map_or(cell, |r| r.union(&cell)));
        }
        if let Some(r) = released {
            self.reinflate(r);
        }
        cells
    }

    /// Brings states and the traversable mask up to date with `grid`.
    ///
    /// Incremental: only cells whose state or held surface changed since the
    /// last call are re-inflated, with the band around them their inflation
    /// reaches (a building-size grid was rebuilt whole on every update, half
    /// of a run's CPU). A change of the grid's geometry rebuilds everything.
    pub fn rebuild(&mut self, grid: &Grid) {
        let frame = Frame {
            origin: grid.origin(),
            res: grid.resolution(),
            w: grid.width(),
            h: grid.height(),
        };
        let resized = frame != self.frame;
        if resized {
            self.frame = frame;
            let n = frame.len();
            self.state = vec![UNKNOWN; n];
            self.surface = vec![false; n];
            self.held = vec![false; n];
            self.held_until = vec![0; n];
            self.traversable = vec![false; n];
            self.collision_free = vec![true; n];
            self.dist = vec![f64::INFINITY; n];
            self.prev = vec![u32::MAX; n];
            self.extra = vec![0.0; n];
            self.known = None;
            // Offsets whose obstacle square lies closer than the inflation.
            self.inflate = square_offsets(self.inflation, frame.res);
            self.hard = square_offsets(self.radius, frame.res);
            self.reach = self
                .inflate
                .iter()
                .chain(&self.hard)
                .map(|&(dx, dy)| dx.abs().max(dy.abs()))
                .max()
                .unwrap_or(0) as usize;
        }
        self.rebuilds = self.rebuilds.wrapping_add(1).max(1);
        let changed = self.copy_states(grid);
        let whole = (frame.w > 0 && frame.h > 0).then(|| Rect {
            x0: 0,
            y0: 0,
            x1: frame.w - 1,
            y1: frame.h - 1,
        });
        if let Some(r) = if resized { whole } else { changed } {
            self.reinflate(r);
        }
    }

    /// Copies the grid's cell states, hit and held flags; returns the
    /// bounding box of the cells whose state or held flag changed. Only the
    /// grid's explored box and the box known at the last call are read: every
    /// cell outside both is unknown in the grid and here.
    fn copy_states(&mut self, grid: &Grid) -> Option<Rect> {
        let w = self.frame.w;
        let explored = grid
            .explored_cells()
            .map(|((x0, y0), (x1, y1))| Rect { x0, y0, x1, y1 });
        let read = match (explored, self.known) {
            (Some(a), Some(b)) => a.union(&b),
            (a, b) => a.or(b)?,
        };
        self.known = explored;
        let (evidence, hit, credit) = (
            grid.raw_evidence(),
            grid.hit_flags(),
            grid.surface_credits(),
        );
        let lut = Grid::state_table().map(|s| match s {
            CellState::Unknown => UNKNOWN,
            CellState::Free => FREE,
            CellState::Occupied => OCCUPIED,
        });
        let (now, hold) = (self.rebuilds, self.hold);
        // A cell just inside a straight face of at least WALL_FACE_CELLS
        // occupied cells (a wall, a long piece of furniture) is not held:
        // ranges ending in it now and then are noise on the face, and
        // holding it would cut the lane that hugs the face.
        let fh = self.frame.h;
        let occupied = |x: i64, y: i64| {
            x >= 0
                && y >= 0
                && (x as usize) < w
                && (y as usize) < fh
                && lut[evidence[y as usize * w + x as usize] as usize] == OCCUPIED
        };
        let wall_face = |i: usize| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            let half = (WALL_FACE_CELLS / 2) as i64;
            [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)]
                .iter()
                .any(|&(dx, dy)| (-half..=half).all(|k| occupied(x + dx - dy * k, y + dy + dx * k)))
        };
        let mut changed: Option<Rect> = None;
        for y in read.y0..=read.y1 {
            let (a, b) = (y * w + read.x0, y * w + read.x1 + 1);
            self.surface[a..b].copy_from_slice(&hit[a..b]);
            let (ev, cr) = (&evidence[a..b], &credit[a..b]);
            let (st, hd) = (&mut self.state[a..b], &mut self.held[a..b]);
            let until = &mut self.held_until[a..b];
            // Most rows hold no change: one branch-free pass to tell (a
            // surface let go but still kept, or held again while its
            // release was pending, counts as a change to look at).
            let differs = ev
                .iter()
                .zip(cr)
                .zip(st.iter().zip(hd.iter()))
                .zip(until.iter())
                .fold(false, |d, (((&e, &c), (&s, &h)), &u)| {
                    d | (lut[e as usize] != s) | ((c > 0) != h) | ((c > 0) & (u != 0))
                });
            if !differs {
                continue;
            }
            let (mut lo, mut hi) = (usize::MAX, 0);
            for (j, (((&e, &c), (s, h)), u)) in ev
                .iter()
                .zip(cr)
                .zip(st.iter_mut().zip(hd.iter_mut()))
                .zip(until.iter_mut())
                .enumerate()
            {
                let state = lut[e as usize];
                let held = if c > 0 {
                    *u = 0;
                    true
                } else if *h && hold > 0 && (*u != 0 || !wall_face(a + j)) {
                    if *u == 0 {
                        *u = now.saturating_add(hold);
                    }
                    if now >= *u {
                        *u = 0;
                        false
                    } else {
                        true
                    }
                } else {
                    false
                };
                if state != *s || held != *h {
                    (*s, *h) = (state, held);
                    lo = lo.min(j);
                    hi = j;
                }
            }
            if lo == usize::MAX {
                // Only surfaces let go and still kept: nothing changed.
                continue;
            }
            let row = Rect {
                x0: read.x0 + lo,
                y0: y,
                x1: read.x0 + hi,
                y1: y,
            };
            changed = Some(changed.map_or(row, |c| c.union(&row)));
        }
        changed
    }

    /// Recomputes the traversable and collision-free masks of every cell an
    /// obstacle in or beside `changed` can reach, from the obstacle and
    /// unknown cells within that reach of them.
    fn reinflate(&mut self, changed: Rect) {
        let (w, h) = (self.frame.w, self.frame.h);
        // A source's status depends on its 8 neighbours; its inflation
        // reaches `reach` cells: targets lie within reach + 1 of a change,
        // their sources within reach of a target.
        let target = changed.grow(self.reach + 1, w, h);
        let sources = target.grow(self.reach, w, h);
        for y in target.y0..=target.y1 {
            for x in target.x0..=target.x1 {
                let i = y * w + x;
                self.traversable[i] = self.state[i] == FREE;
                self.collision_free[i] = true;
            }
        }
        let inside = |x: i64, y: i64| {
            x >= target.x0 as i64
                && y >= target.y0 as i64
                && x <= target.x1 as i64
                && y <= target.y1 as i64
        };
        for y in sources.y0 as i64..=sources.y1 as i64 {
            for x in sources.x0 as i64..=sources.x1 as i64 {
                let i = y as usize * w + x as usize;
                // A free cell holding a surface is an obstacle to the body.
                if self.state[i] == FREE && !self.held[i] {
                    continue;
                }
                let solid = self.state[i] == OCCUPIED || self.held[i];
                // Only obstacle/unknown cells that border free space matter.
                if !self.borders_free(x, y) {
                    continue;
                }
                for &(dx, dy) in &self.inflate {
                    let (nx, ny) = (x + dx, y + dy);
                    if inside(nx, ny) {
                        self.traversable[ny as usize * w + nx as usize] = false;
                    }
                }
                if solid {
                    for &(dx, dy) in &self.hard {
                        let (nx, ny) = (x + dx, y + dy);
                        if inside(nx, ny) {
                            self.collision_free[ny as usize * w + nx as usize] = false;
                        }
                    }
                }
            }
        }
        // The grid's border counts as unexplored.
        for y in target.y0..=target.y1 {
            for x in target.x0..=target.x1 {
                if self.edge_distance(x, y) < self.inflation {
                    self.traversable[y * w + x] = false;
                }
            }
        }
    }

    /// Whether cell (`x`, `y`) has a free 8-neighbour: only obstacle and
    /// unexplored cells bordering free floor bound the clearance.
    fn borders_free(&self, x: i64, y: i64) -> bool {
        let (w, h) = (self.frame.w as i64, self.frame.h as i64);
        NEIGHBOURS.iter().any(|&(dx, dy, _)| {
            let (nx, ny) = (x + dx, y + dy);
            nx >= 0 && ny >= 0 && nx < w && ny < h && self.state[(ny * w + nx) as usize] == FREE
        })
    }

    /// Distance (m, whole cells) of cell (`x`, `y`) from the grid's edge,
    /// which counts as unexplored.
    fn edge_distance(&self, x: usize, y: usize) -> f64 {
        let (w, h) = (self.frame.w, self.frame.h);
        x.min(w - 1 - x).min(y).min(h - 1 - y) as f64 * self.frame.res
    }

    /// What keeps the robot centre at `p` out of the traversable space: of
    /// the obstacle, unexplored or surface-holding cells bordering free
    /// floor within the clearance of `p`'s cell, the nearest to `p` (by the
    /// distance to the edge of its square); else the grid's border; `None`
    /// when `p` is off the grid or its cell is not blocked.
    pub fn blocker(&self, p: &Point2<f64>) -> Option<Blocker> {
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
    pub fn body_clear(&self, i: usize) -> bool {
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

    /// Sets the extra travel cost factor of every cell (`f(i)` for cell
    /// `i`, at least 0): paths and travel costs then prefer cheap cells, e.g.
    /// floor the tool has not swept yet. Reset on a change of the grid's
    /// geometry.
    pub fn set_extra_cost(&mut self, f: impl Fn(usize) -> f64) {
        for (i, e) in self.extra.iter_mut().enumerate() {
            *e = f(i).max(0.0) as f32;
        }
    }

    /// Dijkstra travel distances (8-connected, m) over traversable cells from
    /// `source` (which may itself be non-traversable: the robot may start in
    /// an inflation zone). Fills [`CSpace::dist`].
    pub fn distances_from(&mut self, source: usize) {
        self.dist.iter_mut().for_each(|d| *d = f64::INFINITY);
        self.prev.iter_mut().for_each(|p| *p = u32::MAX);
        self.heap.clear();
        if source >= self.frame.len() {
            return;
        }
        self.dist[source] = 0.0;
        self.heap.push(Entry {
            cost: 0.0,
            idx: source as u32,
        });
        let (frame, trav, extra, prev) =
            (self.frame, &self.traversable, &self.extra, &mut self.prev);
        settle(
            &mut self.heap,
            &mut self.dist,
            |i| grid_steps(frame, trav, extra, i),
            |j, i, _| prev[j] = i as u32,
        );
    }

    /// Approximate travel costs between `cells`, row-major into `out`
    /// (`cells.len()²` values, ∞ where unreachable), from one search: a
    /// Dijkstra from all of them at once splits the space into the region
    /// each reaches first; two cells whose regions touch are linked by the
    /// cheapest way across their common border, and the cost between any
    /// two is the cheapest chain of such links. Exact between neighbours
    /// whose way stays in their two regions, an upper bound otherwise;
    /// about the cost of one whole-grid search. [`CSpace::dist`] is left as
    /// it was.
    pub fn travel_linked(&mut self, cells: &[usize], out: &mut Vec<f64>) {
        let n = self.frame.len();
        let k = cells.len();
        out.clear();
        out.resize(k * k, f64::INFINITY);
        if self.scratch.len() != n {
            self.scratch = vec![f64::INFINITY; n];
        }
        if self.label.len() != n {
            self.label = vec![u32::MAX; n];
        }
        // One node per distinct cell (a cell may be listed twice).
        let mut node_of = vec![usize::MAX; k];
        let mut nodes: Vec<usize> = Vec::new();
        for (a, &c) in cells.iter().enumerate() {
            if c >= n {
                continue;
            }
            node_of[a] = match nodes.iter().position(|&x| x == c) {
                Some(p) => p,
                None => {
                    nodes.push(c);
                    nodes.len() - 1
                }
            };
        }
        self.heap.clear();
        for (v, &c) in nodes.iter().enumerate() {
            self.scratch[c] = 0.0;
            self.label[c] = v as u32;
            self.touched.push(c as u32);
            self.heap.push(Entry {
                cost: 0.0,
                idx: c as u32,
            });
        }
        let (frame, trav, extra) = (self.frame, &self.traversable, &self.extra);
        let (label, touched) = (&mut self.label, &mut self.touched);
        settle(
            &mut self.heap,
            &mut self.scratch,
            |i| grid_steps(frame, trav, extra, i),
            |j, i, old| {
                if old.is_infinite() {
                    touched.push(j as u32);
                }
                label[j] = label[i];
            },
        );
        // Links across region borders.
        let v = nodes.len();
        let mut link = vec![f64::INFINITY; v * v];
        for &t in &self.touched {
            let i = t as usize;
            let li = self.label[i] as usize;
            for (j, step) in self.steps(i) {
                let lj = self.label[j];
                if lj == u32::MAX || lj as usize == li {
                    continue;
                }
                let c = self.scratch[i] + step + self.scratch[j];
                let e = &mut link[li * v + lj as usize];
                if c < *e {
                    *e = c;
                }
            }
        }
        for &t in &self.touched {
            self.scratch[t as usize] = f64::INFINITY;
            self.label[t as usize] = u32::MAX;
        }
        self.touched.clear();
        // Cheapest chains of links: a Dijkstra per node over the links.
        let mut adj: Vec<Vec<(usize, f64)>> = vec![Vec::new(); v];
        for a in 0..v {
            for b in a + 1..v {
                let c = link[a * v + b].min(link[b * v + a]);
                if c.is_finite() {
                    adj[a].push((b, c));
                    adj[b].push((a, c));
                }
            }
        }
        let mut chain = vec![f64::INFINITY; v * v];
        let mut heap = BinaryHeap::new();
        for s in 0..v {
            let row = &mut chain[s * v..(s + 1) * v];
            row[s] = 0.0;
            heap.push(Entry {
                cost: 0.0,
                idx: s as u32,
            });
            settle(&mut heap, row, |u| adj[u].iter().copied(), |_, _, _| {});
        }
        for a in 0..k {
            for b in 0..k {
                if node_of[a] != usize::MAX && node_of[b] != usize::MAX {
                    out[a * k + b] = chain[node_of[a] * v + node_of[b]];
                }
            }
        }
    }

    /// The cell path from the last Dijkstra source to `goal`, as cell centres,
    /// shortened by line of sight; `None` when `goal` is unreachable.
    pub fn path_to(&self, goal: usize) -> Option<Vec<Point2<f64>>> {
        if goal >= self.dist.len() || !self.dist[goal].is_finite() {
            return None;
        }
        let mut cells = vec![goal];
        let mut i = goal;
        while self.prev[i] != u32::MAX {
            i = self.prev[i] as usize;
            cells.push(i);
        }
        cells.reverse();
        Some(self.shorten(&cells))
    }

    /// A* path (cell centres, shortened) between two cells over traversable
    /// cells, `None` when there is none. Does not touch [`CSpace::dist`].
    pub fn astar(&self, from: usize, to: usize) -> Option<Vec<Point2<f64>>> {
        let n = self.frame.len();
        if from >= n || to >= n || !self.traversable[to] {
            return None;
        }
        let (w, r) = (self.frame.w as i64, self.frame.res);
        let goal = ((to as i64) % w, (to as i64) / w);
        let hfn = |i: usize| {
            let (x, y) = ((i as i64) % w, (i as i64) / w);
            let (dx, dy) = ((x - goal.0).abs() as f64, (y - goal.1).abs() as f64);
            (dx.max(dy) + (std::f64::consts::SQRT_2 - 1.0) * dx.min(dy)) * r
        };
        let mut g = std::collections::HashMap::<usize, (f64, usize)>::new();
        let mut heap = BinaryHeap::new();
        g.insert(from, (0.0, usize::MAX));
        heap.push(Entry {
            cost: hfn(from),
            idx: from as u32,
        });
        while let Some(Entry { idx, .. }) = heap.pop() {
            let i = idx as usize;
            if i == to {
                let mut cells = vec![to];
                let mut k = to;
                while let Some(&(_, p)) = g.get(&k) {
                    if p == usize::MAX {
                        break;
                    }
                    cells.push(p);
                    k = p;
                }
                cells.reverse();
                return Some(self.shorten(&cells));
            }
            let gi = g[&i].0;
            for (j, step) in self.steps(i) {
                let ng = gi + step;
                if g.get(&j).is_none_or(|&(old, _)| ng < old) {
                    g.insert(j, (ng, i));
                    heap.push(Entry {
                        cost: ng + hfn(j),
                        idx: j as u32,
                    });
                }
            }
        }
        None
    }

    /// Whether at least `n` traversable cells are connected to cell
    /// `start` (moving as the path search does): a flood fill that stops
    /// once it has found `n`, so a large part costs no more than a small one.
    pub fn traversable_part_holds(&self, start: usize, n: usize) -> bool {
        if start >= self.frame.len() || !self.traversable[start] {
            return false;
        }
        let mut found = vec![start];
        let mut next = 0;
        while next < found.len() && found.len() < n {
            let i = found[next];
            next += 1;
            for (j, _) in self.steps(i) {
                if !found.contains(&j) {
                    found.push(j);
                }
            }
        }
        found.len() >= n
    }

    /// Whether the straight segment `a`–`b` keeps the robot body off every
    /// seen obstacle (sampled every quarter cell).
    pub fn segment_safe(&self, a: &Point2<f64>, b: &Point2<f64>) -> bool {
        self.first_unsafe(a, b).is_none()
    }

    /// The first sample of the straight segment `a`–`b` (every quarter
    /// cell, from `a`) where the bare body would touch a seen obstacle or
    /// leave the map; `None` when the whole segment is safe. A sample in a
    /// cell that is not [`CSpace::collision_free`] (judged at the cell's
    /// centre) is measured again where it is: up to half a cell from the
    /// centre, a path may pass a surface seen since it was planned by a
    /// few millimetres more than the robot radius, and is not blocked.
    pub fn first_unsafe(&self, a: &Point2<f64>, b: &Point2<f64>) -> Option<Point2<f64>> {
        self.samples(a, b).find(|p| match self.frame.index_of(p) {
            Some(i) => !self.collision_free[i] && self.body_touches(p, i),
            None => true,
        })
    }

    /// Whether a robot body centred at `p`, in cell `i`, comes nearer than
    /// the robot radius to the square of a cell seen occupied or holding a
    /// surface (one bordering free floor, as [`CSpace::collision_free`]
    /// counts them).
    fn body_touches(&self, p: &Point2<f64>, i: usize) -> bool {
        let f = self.frame;
        let (w, h) = (f.w as i64, f.h as i64);
        let (x, y) = ((i % f.w) as i64, (i / f.w) as i64);
        let k = (self.radius / f.res).ceil() as i64 + 1;
        for ny in (y - k).max(0)..=(y + k).min(h - 1) {
            for nx in (x - k).max(0)..=(x + k).min(w - 1) {
                let j = ny as usize * f.w + nx as usize;
                let solid = self.state[j] == OCCUPIED || self.held[j];
                if !solid || !self.borders_free(nx, ny) {
                    continue;
                }
                if square_gap(p, &f.centre(j), f.res) < self.radius {
                    return true;
                }
            }
        }
        false
    }

    /// Whether the straight segment `a`–`b` stays on traversable cells
    /// (sampled every quarter cell).
    pub fn segment_clear(&self, a: &Point2<f64>, b: &Point2<f64>) -> bool {
        self.samples(a, b)
            .all(|p| self.frame.index_of(&p).is_some_and(|i| self.traversable[i]))
    }

    /// Points along the straight segment `a`–`b`, from `a` to `b` both
    /// included, a quarter cell or less apart: no cell the segment crosses
    /// by more than a corner is missed.
    fn samples(&self, a: &Point2<f64>, b: &Point2<f64>) -> impl Iterator<Item = Point2<f64>> {
        let (a, d) = (*a, b - a);
        let n = ((d.norm() / (self.frame.res * 0.25)).ceil() as usize).max(1);
        (0..=n).map(move |k| a + d * (k as f64 / n as f64))
    }

    /// [`grid_steps`] over this configuration space.
    fn steps(&self, i: usize) -> heapless::Vec<(usize, f64), 8> {
        grid_steps(self.frame, &self.traversable, &self.extra, i)
    }

    fn extra_at(&self, i: usize) -> f32 {
        self.extra.get(i).copied().unwrap_or(0.0)
    }

    /// The dearest extra cost factor along the segment `a`–`b`.
    fn segment_extra(&self, a: &Point2<f64>, b: &Point2<f64>) -> f32 {
        let d = b - a;
        let n = ((d.norm() / (self.frame.res * 0.25)).ceil() as usize).max(1);
        (0..=n)
            .filter_map(|k| self.frame.index_of(&(a + d * (k as f64 / n as f64))))
            .map(|i| self.extra_at(i))
            .fold(0.0, f32::max)
    }

    /// String-pulls a cell path: keeps only the points where line of sight breaks.
    fn shorten(&self, cells: &[usize]) -> Vec<Point2<f64>> {
        let pts: Vec<Point2<f64>> = cells.iter().map(|&i| self.frame.centre(i)).collect();
        if pts.len() <= 2 {
            return pts;
        }
        let mut out = vec![pts[0]];
        let mut anchor = 0;
        let mut k = 1;
        while k < pts.len() {
            // Farthest point visible from the anchor.
            let mut far = k;
            let mut j = k;
            // A shortcut may not cross dearer cells than the ones it replaces.
            let mut dearest = self.extra_at(cells[anchor]);
            while j < pts.len() {
                dearest = dearest.max(self.extra_at(cells[j]));
                if self.segment_clear(&pts[anchor], &pts[j])
                    && self.segment_extra(&pts[anchor], &pts[j]) <= dearest
                {
                    far = j;
                }
                j += 1;
                if j - far > 24 {
                    break;
                }
            }
            out.push(pts[far]);
            anchor = far;
            k = far + 1;
        }
        out
    }

    /// Whether a scan from cell `from` would reach the unexplored space
    /// beside the frontier cell `fi`: on the straight line from `from`'s
    /// centre to one of `fi`'s unknown neighbours, the first cell that is
    /// not seen-free is unknown and touches `fi` (the line enters the
    /// unexplored space there, not through a gap between the corners of
    /// two occupied cells somewhere else). A frontier
    /// no reachable place sees this way (the far side of a table in a
    /// corner, seen only past its edge) is not worth a drive: it would stay
    /// unexplored.
    pub fn sees_unknown_beside(&self, from: usize, fi: usize) -> bool {
        let w = self.frame.w;
        let (fx, fy) = ((from % w) as f64, (from / w) as f64);
        [fi - 1, fi + 1, fi - w, fi + w]
            .into_iter()
            .filter(|&u| self.state[u] == UNKNOWN)
            .any(|u| {
                let (ux, uy) = ((u % w) as f64, (u / w) as f64);
                // Four samples per cell crossed: no cell the line passes
                // through by more than a corner is skipped. `samples`
                // spaces its points by length, not by cells crossed: it
                // meets other cells on grazing lines, and changed the
                // plans of lab_c_scan:0 and of the lab_ipa map.
                let steps = ((ux - fx).abs().max((uy - fy).abs()) * 4.0).ceil() as usize;
                (0..steps)
                    .map(|k| {
                        let t = k as f64 / steps as f64;
                        let (x, y) = (fx + (ux - fx) * t, fy + (uy - fy) * t);
                        (y.round() as usize) * w + x.round() as usize
                    })
                    .find(|&c| self.state[c] != FREE || self.surface[c])
                    .is_none_or(|c| {
                        let near = (c % w).abs_diff(fi % w) <= 1 && (c / w).abs_diff(fi / w) <= 1;
                        near && self.state[c] == UNKNOWN && !self.surface[c]
                    })
            })
    }

    /// Known-free cells with at least one unexplored 4-neighbour, except
    /// cells a beam has ended in (a surface lies there: what is unknown
    /// behind it is behind that surface, not a way into unexplored floor).
    pub fn frontier(&self, out: &mut Vec<usize>) {
        out.clear();
        let (w, h) = (self.frame.w, self.frame.h);
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                let i = y * w + x;
                if self.state[i] == FREE
                    && !self.surface[i]
                    && [i - 1, i + 1, i - w, i + w]
                        .iter()
                        .any(|&j| self.state[j] == UNKNOWN)
                {
                    out.push(i);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_around_a_cell_stay_inside_the_frame() {
        let f = Frame {
            origin: Point2::origin(),
            res: 0.05,
            w: 4,
            h: 3,
        };
        let offsets = [(0, 0), (-1, 0), (1, 1), (0, -1), (3, 0), (0, 2)];
        // Cell (0, 0): left and below are outside; (3, 0) is the last column.
        let got: Vec<usize> = f.around(0, &offsets).collect();
        assert_eq!(got, vec![0, 5, 3, 8]);
        // Cell (3, 2), the last: only itself, left and below.
        let got: Vec<usize> = f.around(11, &offsets).collect();
        assert_eq!(got, vec![11, 10, 7]);
    }

    fn room_grid() -> Grid {
        // 4 m x 3 m room with a wall from (2, 0) to (2, 2): free except walls.
        let mut g = Grid::new(Point2::new(-0.5, -0.5), 0.05, 100, 80);
        for y in 0..80 {
            for x in 0..100 {
                let p = g.centre_of((x, y));
                let wall = p.x < 0.0 || p.y < 0.0 || p.x > 4.0 || p.y > 3.0;
                let inner = (p.x - 2.0).abs() < 0.05 && p.y < 2.0;
                let s = if wall || inner {
                    CellState::Occupied
                } else {
                    CellState::Free
                };
                let outside = p.x < -0.1 || p.y < -0.1 || p.x > 4.1 || p.y > 3.1;
                g.set_state((x, y), if outside { CellState::Unknown } else { s });
            }
        }
        g
    }

    /// A 40 x 20 grid of 5 cm cells, the first `free_cols` columns seen
    /// free, the rest unknown; a beam along row 10 ended at `x`, then ten
    /// beams across that row passed through the cell there. Returns the
    /// grid and the row's centre y.
    fn hit_then_passed(free_cols: usize, x: f64) -> (Grid, f64) {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 40, 20);
        for y in 0..20 {
            for c in 0..free_cols {
                g.set_state((c, y), CellState::Free);
            }
        }
        let y = 10.5 * 0.05;
        g.integrate_ray(&Point2::new(0.1, y), &Point2::new(x, y), true);
        for _ in 0..10 {
            g.integrate_ray(&Point2::new(x, 0.1), &Point2::new(x, 0.9), false);
        }
        (g, y)
    }

    #[test]
    fn a_cell_a_beam_ended_in_is_no_frontier() {
        // Seen free up to x = 1.0 (cells 0..20), unknown beyond; a beam
        // once ended in cell (19, 10) and later beams made it free again:
        // a surface lies there, so it is no way into unknown space.
        let (g, _) = hit_then_passed(20, 0.97);
        assert_eq!(g.state((19, 10)), CellState::Free);
        let mut c = CSpace::new(0.2, 0.17);
        c.rebuild(&g);
        let mut list = Vec::new();
        c.frontier(&mut list);
        let f = c.frame;
        assert!(!list.contains(&(10 * f.w + 19)), "the hit cell");
        assert!(list.contains(&(9 * f.w + 19)) && list.contains(&(11 * f.w + 19)));
        assert_eq!(list.len(), 17, "{list:?}");
    }

    #[test]
    fn unexplored_space_is_seen_only_along_a_clear_line() {
        // Room of `room_grid`; unknown cells (30..33, 50..53) behind a wall
        // piece (x = 29, y 45..58), with free floor all round the rest.
        let mut g = room_grid();
        for y in 45..58 {
            g.set_state((29, y), CellState::Occupied);
        }
        for y in 50..53 {
            for x in 30..33 {
                g.set_state((x, y), CellState::Unknown);
            }
        }
        let mut c = CSpace::new(0.2, 0.17);
        c.rebuild(&g);
        let w = c.frame.w;
        let at = |x: usize, y: usize| y * w + x;
        // Frontier cell (33, 51), right of the pocket: seen from the right
        // and from above, not from the left through the wall piece.
        assert!(c.sees_unknown_beside(at(45, 51), at(33, 51)));
        assert!(c.sees_unknown_beside(at(40, 60), at(33, 51)));
        assert!(!c.sees_unknown_beside(at(20, 51), at(33, 51)));
        // Frontier cell (31, 53), above it: seen from above, and past the
        // wall piece's top end from the upper left.
        assert!(c.sees_unknown_beside(at(31, 60), at(31, 53)));
        assert!(c.sees_unknown_beside(at(28, 68), at(31, 53)));
        // A cell with no unknown neighbour has nothing to see.
        assert!(!c.sees_unknown_beside(at(45, 51), at(40, 51)));
    }

    #[test]
    fn a_free_cell_holding_a_surface_keeps_the_body_off_it() {
        // A chair leg filling part of cell (20, 10): beams passing beside
        // it made the cell free on balance, yet one ended in it.
        let (mut g, y) = hit_then_passed(40, 1.02);
        let leg = (20, 10);
        assert_eq!(g.state(leg), CellState::Free);
        assert!(g.holds_surface(leg));
        let mut c = CSpace::new(0.2, 0.17);
        c.rebuild(&g);
        let f = c.frame;
        let near = f.index_of(&Point2::new(1.02 - 0.12, y)).unwrap();
        let far = f.index_of(&Point2::new(1.02 - 0.3, y)).unwrap();
        assert!(!c.traversable[near] && !c.collision_free[near]);
        assert!(!c.body_clear(near));
        assert!(c.traversable[far] && c.collision_free[far]);
        // Once enough beams pass with none ending there, it is gone.
        for _ in 0..crate::grid::HIT_CREDIT {
            g.integrate_ray(&Point2::new(1.02, 0.1), &Point2::new(1.02, 0.9), false);
        }
        c.rebuild(&g);
        assert!(c.traversable[near] && c.collision_free[near]);
    }

    #[test]
    fn a_path_is_blocked_where_the_body_itself_touches_a_surface_not_where_its_cell_would() {
        // The chair-leg cell (20, 10), the square [1.00, 1.05] x [0.50, 0.55].
        let (g, _) = hit_then_passed(40, 1.02);
        let mut c = CSpace::new(0.2, 0.17);
        c.rebuild(&g);
        // In cell (17, 8), whose centre is 0.146 m from the square, at its
        // far corner: 0.178 m from the square, clear of a 0.17 m body.
        let clear = Point2::new(0.852, 0.402);
        assert!(!c.collision_free[c.frame.index_of(&clear).unwrap()]);
        assert_eq!(c.first_unsafe(&clear, &clear), None);
        assert!(c.segment_safe(&Point2::new(0.5, 0.402), &clear));
        // In the same cell nearer the leg: 0.153 m, the body touches it.
        let touching = Point2::new(0.87, 0.42);
        assert_eq!(c.first_unsafe(&touching, &touching), Some(touching));
        assert!(!c.segment_safe(&clear, &touching));
        // Off the map is never safe.
        let off = Point2::new(-0.1, 0.4);
        assert_eq!(c.first_unsafe(&off, &off), Some(off));
    }

    #[test]
    fn a_surface_let_go_keeps_blocking_for_the_hold_and_held_again_starts_it_over() {
        // The chair-leg cell of the test above, held and let go by turns.
        let (mut g, y) = hit_then_passed(40, 1.02);
        let let_go = |g: &mut Grid| {
            for _ in 0..crate::grid::HIT_CREDIT {
                g.integrate_ray(&Point2::new(1.02, 0.1), &Point2::new(1.02, 0.9), false);
            }
        };
        let mut c = CSpace::new(0.2, 0.17);
        c.set_surface_hold(3);
        c.rebuild(&g);
        let near = c.frame.index_of(&Point2::new(1.02 - 0.12, y)).unwrap();
        assert!(!c.collision_free[near]);
        let_go(&mut g);
        assert!(!g.holds_surface((20, 10)));
        // Still blocking for three rebuilds, then gone.
        for k in 0..3 {
            c.rebuild(&g);
            assert!(
                !c.traversable[near] && !c.collision_free[near],
                "rebuild {k}"
            );
        }
        c.rebuild(&g);
        assert!(c.traversable[near] && c.collision_free[near]);
        // Hit again, let go, hit again before the release: the hold counts
        // from the last letting go.
        g.integrate_ray(&Point2::new(0.1, y), &Point2::new(1.02, y), true);
        c.rebuild(&g);
        assert!(!c.collision_free[near]);
        let_go(&mut g);
        c.rebuild(&g);
        c.rebuild(&g);
        g.integrate_ray(&Point2::new(0.1, y), &Point2::new(1.02, y), true);
        c.rebuild(&g);
        let_go(&mut g);
        for k in 0..3 {
            c.rebuild(&g);
            assert!(
                !c.collision_free[near],
                "rebuild {k} after the second letting go"
            );
        }
        c.rebuild(&g);
        assert!(c.collision_free[near]);
        // Without a hold (the default) the cell clears at once.
        let mut plain = CSpace::new(0.2, 0.17);
        g.integrate_ray(&Point2::new(0.1, y), &Point2::new(1.02, y), true);
        plain.rebuild(&g);
        assert!(!plain.collision_free[near]);
        let_go(&mut g);
        plain.rebuild(&g);
        assert!(plain.collision_free[near]);
    }

    #[test]
    fn a_surface_just_inside_a_long_face_is_not_held_and_one_beside_a_short_one_is() {
        // Cell (20, 10) at x = 1.00..1.05 m, a beam once ended in it and
        // later beams passed: a wall face at x = 1.05 m (column 21
        // occupied) over 5 rows or more makes it noise on the face, let go
        // at once; beside 3 rows (a post) it is held like a chair leg.
        for (rows, held) in [
            (0..20, false),
            (6..15, false),
            (8..13, false),
            (9..12, true),
        ] {
            let (mut g, _) = hit_then_passed(21, 1.02);
            for y in rows.clone() {
                g.set_state((21, y), CellState::Occupied);
            }
            g.integrate_ray(
                &Point2::new(0.1, 10.5 * 0.05),
                &Point2::new(1.02, 10.5 * 0.05),
                true,
            );
            let mut c = CSpace::new(0.2, 0.17);
            c.set_surface_hold(100);
            c.rebuild(&g);
            let cell = 10 * c.frame.w + 20;
            assert!(c.held[cell], "rows {rows:?}: held while the grid holds it");
            for _ in 0..crate::grid::HIT_CREDIT {
                g.integrate_ray(&Point2::new(1.02, 0.1), &Point2::new(1.02, 0.9), false);
            }
            assert!(!g.holds_surface((20, 10)));
            c.rebuild(&g);
            assert_eq!(c.held[cell], held, "rows {rows:?}");
        }
    }

    #[test]
    fn a_surface_kept_only_by_the_hold_is_let_go_on_request_and_one_still_held_is_not() {
        let (mut g, y) = hit_then_passed(40, 1.02);
        let mut c = CSpace::new(0.2, 0.17);
        c.set_surface_hold(100);
        c.rebuild(&g);
        let near = c.frame.index_of(&Point2::new(1.02 - 0.12, y)).unwrap();
        // Held by the grid: nothing to let go.
        assert!(c.release_held().is_empty());
        assert!(!c.collision_free[near]);
        for _ in 0..crate::grid::HIT_CREDIT {
            g.integrate_ray(&Point2::new(1.02, 0.1), &Point2::new(1.02, 0.9), false);
        }
        c.rebuild(&g);
        assert!(!c.traversable[near] && !c.collision_free[near]);
        // Kept only by the hold: let go at once, and the clearance with it.
        let cell = c.frame.index_of(&Point2::new(1.02, y)).unwrap();
        assert_eq!(c.release_held(), vec![cell]);
        assert!(c.traversable[near] && c.collision_free[near]);
        // As a fresh configuration space of the same grid says.
        let mut fresh = CSpace::new(0.2, 0.17);
        fresh.rebuild(&g);
        assert_eq!(fresh.traversable, c.traversable);
        assert_eq!(fresh.collision_free, c.collision_free);
        // Nothing pending any more; the next rebuild keeps it let go.
        assert!(c.release_held().is_empty());
        c.rebuild(&g);
        assert!(c.collision_free[near]);
    }

    #[test]
    fn inflation_keeps_the_centre_off_walls() {
        let mut c = CSpace::new(0.2, 0.17);
        c.rebuild(&room_grid());
        let f = c.frame;
        assert!(c.traversable[f.index_of(&Point2::new(1.0, 1.0)).unwrap()]);
        assert!(!c.traversable[f.index_of(&Point2::new(0.12, 1.0)).unwrap()]);
        assert!(!c.traversable[f.index_of(&Point2::new(1.85, 1.0)).unwrap()]);
        assert!(c.traversable[f.index_of(&Point2::new(1.7, 1.0)).unwrap()]);
    }

    #[test]
    fn the_blocker_of_a_centre_in_the_clearance_is_the_nearest_wall_cell() {
        let mut c = CSpace::new(0.2, 0.17);
        let mut g = room_grid();
        c.rebuild(&g);
        assert_eq!(c.blocker(&Point2::new(1.0, 1.0)), None);
        // The inner wall's cells span x 1.95-2.05 (centres 1.975, 2.025):
        // from x = 1.85 the nearest edge is 0.1 m away.
        let b = c.blocker(&Point2::new(1.85, 1.0)).unwrap();
        assert_eq!(b.kind, BlockerKind::Obstacle);
        assert!((b.distance - 0.1).abs() < 1e-9, "{}", b.distance);
        assert!((b.at.x - 1.975).abs() < 1e-9 && (b.at.y - 1.0).abs() < 0.026);
        // Floor not seen yet blocks as well, and is named so.
        g.set_state(
            g.cell_of(&Point2::new(1.0, 1.15)).unwrap(),
            CellState::Unknown,
        );
        c.rebuild(&g);
        let b = c.blocker(&Point2::new(1.0, 1.0)).unwrap();
        assert_eq!(b.kind, BlockerKind::Unexplored);
        assert!(b.distance < 0.2);
        assert!(c.blocker(&Point2::new(-9.0, 1.0)).is_none());
    }

    #[test]
    fn linked_travel_is_an_upper_bound_close_to_whole_grid_searches() {
        let mut c = CSpace::new(0.2, 0.17);
        c.rebuild(&room_grid());
        let f = c.frame;
        let cells: Vec<usize> = [
            (1.0, 0.5),
            (3.0, 0.5),
            (0.6, 2.6),
            (3.5, 2.5),
            (1.0, 0.5),
            (2.0, 2.5),
            (1.5, 1.5),
            (2.6, 1.5),
        ]
        .iter()
        .map(|&(x, y)| f.index_of(&Point2::new(x, y)).unwrap())
        .collect();
        c.distances_from(cells[2]);
        let before = c.dist.clone();
        let mut m = Vec::new();
        c.travel_linked(&cells, &mut m);
        // The whole-grid distances are left alone.
        assert_eq!(c.dist, before);
        let k = cells.len();
        for (a, &ca) in cells.iter().enumerate() {
            c.distances_from(ca);
            for (b, &cb) in cells.iter().enumerate() {
                let (got, exact) = (m[a * k + b], c.dist[cb]);
                assert!(got >= exact - 1e-9, "{a} {b}: {got} below {exact}");
                assert!(got <= exact * 1.25 + 1e-9, "{a} {b}: {got} vs {exact}");
            }
        }
        // Around the wall, never through it; a cell listed twice is one.
        assert!(m[1] > 4.0 && m[1] < 5.5, "{}", m[1]);
        assert_eq!(m[4], 0.0);
        // A cell inside the wall is unreachable from everywhere.
        let wall = f.index_of(&Point2::new(2.0, 0.5)).unwrap();
        c.travel_linked(&[cells[0], wall], &mut m);
        assert!(m[1].is_infinite() && m[2].is_infinite());
        assert_eq!(m[0], 0.0);
    }

    #[test]
    fn paths_go_around_the_wall_never_through() {
        let mut c = CSpace::new(0.2, 0.17);
        c.rebuild(&room_grid());
        let f = c.frame;
        let a = f.index_of(&Point2::new(1.0, 0.5)).unwrap();
        let b = f.index_of(&Point2::new(3.0, 0.5)).unwrap();
        c.distances_from(a);
        let d = c.dist[b];
        // Up past the wall end at y = 2 (+0.2 clearance) and down again.
        assert!(d > 4.0 && d < 5.0, "{d}");
        let p = c.path_to(b).unwrap();
        for s in p.windows(2) {
            assert!(c.segment_clear(&s[0], &s[1]));
        }
        assert!(p.iter().any(|q| q.y > 2.1));
        let q = c.astar(a, b).unwrap();
        let len: f64 = q.windows(2).map(|s| (s[1] - s[0]).norm()).sum();
        // Line of sight shortens the 8-connected detour, never below the taut string.
        assert!(len <= d + 1e-9 && len > 4.0, "{len} vs {d}");
        assert!(q.len() < 8, "{q:?}");
    }

    #[test]
    fn dear_cells_are_avoided_unless_the_detour_costs_more() {
        let mut c = CSpace::new(0.2, 0.17);
        c.rebuild(&room_grid());
        let f = c.frame;
        let a = f.index_of(&Point2::new(0.5, 0.5)).unwrap();
        let b = f.index_of(&Point2::new(1.5, 0.5)).unwrap();
        let length =
            |p: &[Point2<f64>]| -> f64 { p.windows(2).map(|s| (s[1] - s[0]).norm()).sum() };
        // A band of swept floor across the straight way, open above y = 1.2.
        let band = |c: &CSpace, i: usize, w: f64| {
            let p = c.frame.centre(i);
            if (0.8..1.2).contains(&p.x) && p.y < 1.2 {
                w
            } else {
                0.0
            }
        };
        for (w, detour) in [(20.0, true), (0.5, false)] {
            let extra: Vec<f64> = (0..f.len()).map(|i| band(&c, i, w)).collect();
            c.set_extra_cost(|i| extra[i]);
            c.distances_from(a);
            let p = c.path_to(b).unwrap();
            let q = c.astar(a, b).unwrap();
            for path in [&p, &q] {
                assert_eq!(path.iter().any(|q| q.y > 1.2), detour, "w {w}: {path:?}");
                if !detour {
                    assert!((length(path) - 1.0).abs() < 0.01, "{path:?}");
                }
            }
        }
        // Negative factors count as none.
        c.set_extra_cost(|_| -3.0);
        c.distances_from(a);
        assert!((c.dist[b] - 1.0).abs() < 1e-9, "{}", c.dist[b]);
    }

    #[test]
    fn unexplored_grid_has_no_traversable_cell() {
        let mut c = CSpace::new(0.2, 0.17);
        c.rebuild(&Grid::new(Point2::new(0.0, 0.0), 0.05, 20, 20));
        assert!(c.traversable.iter().all(|t| !t));
        c.distances_from(0);
        assert!(c.path_to(5).is_none());
        assert!(c.astar(0, 5).is_none());
    }

    #[test]
    fn incremental_rebuild_matches_a_fresh_one() {
        // Random edits to a 60 x 50 grid of mostly free floor: small boxes
        // of occupied or unknown cells, larger free ones, beams that leave
        // or wear off held surfaces. After each, the configuration space
        // kept up to date incrementally must equal one built from scratch.
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = |n: usize| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % n as u64) as usize
        };
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 60, 50);
        for y in 0..50 {
            for x in 0..60 {
                g.set_state((x, y), CellState::Free);
            }
        }
        let mut kept = CSpace::new(0.2, 0.17);
        for step in 0..400 {
            let (x, y) = (next(60), next(50));
            let s = match next(10) {
                0..=3 => Some((CellState::Free, 1 + next(6))),
                4..=6 => Some((CellState::Occupied, 1 + next(5))),
                7 => Some((CellState::Unknown, 1 + next(5))),
                _ => None,
            };
            match s {
                Some((s, size)) => {
                    for cy in y..(y + size).min(50) {
                        for cx in x..(x + size).min(60) {
                            g.set_state((cx, cy), s);
                        }
                    }
                }
                None => {
                    let a = g.centre_of((x, y));
                    let b = g.centre_of((next(60), next(50)));
                    g.integrate_ray(&a, &b, next(2) == 0);
                }
            }
            kept.rebuild(&g);
            let mut fresh = CSpace::new(0.2, 0.17);
            fresh.rebuild(&g);
            assert_eq!(kept.state, fresh.state, "step {step}");
            assert_eq!(kept.held, fresh.held, "step {step}");
            assert_eq!(kept.surface, fresh.surface, "step {step}");
            assert_eq!(kept.traversable, fresh.traversable, "step {step}");
            assert_eq!(kept.collision_free, fresh.collision_free, "step {step}");
        }
        assert!(kept.traversable.iter().any(|t| *t) && kept.traversable.iter().any(|t| !t));
        // Forgetting the outer columns shrinks the grid's explored box: the
        // cells left outside it must be read once more.
        for y in 0..50 {
            for x in (0..4).chain(52..60) {
                g.set_state((x, y), CellState::Unknown);
            }
        }
        assert_eq!(g.explored_cells().map(|b| (b.0 .0, b.1 .0)), Some((4, 51)));
        kept.rebuild(&g);
        let mut fresh = CSpace::new(0.2, 0.17);
        fresh.rebuild(&g);
        assert_eq!(kept.state, fresh.state);
        assert_eq!(kept.traversable, fresh.traversable);
    }
}
