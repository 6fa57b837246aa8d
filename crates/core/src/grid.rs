//! A fixed-size evidence grid of the explored area: which cells the scanner has
//! seen free, which it has seen occupied, and which are still unknown. The map
//! maintains it from registered scans; the decomposition reads it to know where
//! explored free space ends. Allocated once; updates never allocate.

use nalgebra::Point2;

/// State of one grid cell as the decomposition sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellState {
    /// Never observed.
    Unknown,
    /// Observed, more evidence of free than occupied.
    Free,
    /// Observed, more evidence of occupied.
    Occupied,
}

/// Evidence value of a cell never observed.
const UNKNOWN: u8 = 0;
/// Evidence a cell starts from when first observed.
const NEUTRAL: u8 = 128;
/// Evidence at or above which a cell counts as occupied.
const OCCUPIED_AT: u8 = 150;
/// How far (cells) a beam's end point is moved along the beam before the
/// cell holding it is found: far above rounding error, far below the
/// scanner's 1 mm range step.
const END_NUDGE: f64 = 1e-4;

/// Step added by a hit.
const HIT: u8 = 40;
/// Step removed by a pass-through.
const MISS: u8 = 8;
/// Beams that must pass a cell where its hits lie, with none ending in it,
/// before a surface hit there is taken for gone (see [`Grid::holds_surface`]): a
/// few scans of a cell near the robot, so a person who walked by does not
/// stay an obstacle, while a chair leg hit by some beam in every scan stays.
pub(crate) const HIT_CREDIT: u8 = 64;
/// How close (share of a cell) a cell's mean hit position may lie to a face
/// the beam heads for, with a solid cell across it, for the hit to count as
/// that cell's surface: 10 mm on a 5 cm grid, the default safety margin, so
/// moving such a surface to the face costs at most the margin.
const FACE_SNAP: f64 = 0.2;
/// How close (share of a cell) a beam must pass to a held cell's mean hit
/// position to count against the surface there: beams passing beside a
/// chair leg in its cell say nothing of it, and letting it go on them made
/// it flicker between held and let go (7.5 mm on a 5 cm grid).
const DRAIN_REACH: f64 = 0.15;
/// Units of a cell's mean hit position per cell (offsets from the cell's
/// centre, so ±0.5 cell fits an `i8`).
const MEAN_SCALE: f64 = 254.0;
/// A new hit moves a cell's mean hit position by 1/2^`MEAN_SHIFT` of its
/// offset from it: one stray reading cannot move it far.
const MEAN_SHIFT: u32 = 3;

/// The cell of a raster of `size` = (columns, rows) cells of `resolution`
/// metres, lower-left corner at `origin`, that contains world point `p`; `None`
/// outside the raster or for non-finite input. The one cell-indexing rule of
/// every raster in the crate ([`Grid`], the simulator's floor raster).
pub fn cell_containing(
    origin: Point2<f64>,
    resolution: f64,
    size: (usize, usize),
    p: &Point2<f64>,
) -> Option<CellIndex> {
    let fx = (p.x - origin.x) / resolution;
    let fy = (p.y - origin.y) / resolution;
    if !(fx.is_finite() && fy.is_finite()) || fx < 0.0 || fy < 0.0 {
        return None;
    }
    let (cx, cy) = (fx as usize, fy as usize);
    (cx < size.0 && cy < size.1).then_some((cx, cy))
}

/// World position of the centre of cell `c` of a raster of `resolution`-metre
/// cells whose lower-left corner is at `origin` (see [`cell_containing`]).
pub fn cell_centre(origin: Point2<f64>, resolution: f64, c: CellIndex) -> Point2<f64> {
    Point2::new(
        origin.x + (c.0 as f64 + 0.5) * resolution,
        origin.y + (c.1 as f64 + 0.5) * resolution,
    )
}

/// Exact walk over the cells a straight line passes through, in order
/// (Amanatides and Woo): the one traversal of the evidence grid's beams and
/// the simulator's ray casts. Positions are in cell units; `t` is the line's
/// parameter, `start + t * delta`.
#[derive(Clone, Copy, Debug)]
pub struct CellWalk {
    /// Current cell (column, row); may lie outside any raster.
    pub cell: (i64, i64),
    step: (i64, i64),
    next: (f64, f64),
    delta: (f64, f64),
}

impl CellWalk {
    /// A walk from `start` (cell units) along `delta` (cell units per unit
    /// of `t`), in the cell holding `start`.
    pub fn new(start: (f64, f64), delta: (f64, f64)) -> Self {
        let axis = |p: f64, d: f64| -> (i64, f64, f64) {
            let c = p.floor();
            if d > 0.0 {
                (1, (c + 1.0 - p) / d, 1.0 / d)
            } else if d < 0.0 {
                (-1, (p - c) / -d, -1.0 / d)
            } else {
                (0, f64::INFINITY, f64::INFINITY)
            }
        };
        let (sx, tx, dx) = axis(start.0, delta.0);
        let (sy, ty, dy) = axis(start.1, delta.1);
        Self {
            cell: (start.0.floor() as i64, start.1.floor() as i64),
            step: (sx, sy),
            next: (tx, ty),
            delta: (dx, dy),
        }
    }

    /// The step from one cell to the next (-1, 0 or 1 on each axis).
    pub fn direction(&self) -> (i64, i64) {
        self.step
    }

    /// `t` at which the line leaves the current cell.
    pub fn exit(&self) -> f64 {
        self.next.0.min(self.next.1)
    }

    /// Moves to the next cell along the line.
    pub fn advance(&mut self) {
        if self.next.0 < self.next.1 {
            self.cell.0 += self.step.0;
            self.next.0 += self.delta.0;
        } else {
            self.cell.1 += self.step.1;
            self.next.1 += self.delta.1;
        }
    }
}

/// An evidence grid over a fixed rectangle of the world.
///
/// Serialised (for a checkpoint) as its geometry and evidence only; the
/// surface memory (`hit`, `held`, `mean`) starts afresh and the explored
/// box is recomputed: see [`Grid::rebuilt`].
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Grid {
    origin: Point2<f64>,
    resolution: f64,
    width: usize,
    height: usize,
    cells: Vec<u8>,
    /// Per cell: a beam has ended in it (a surface passes through it), even
    /// if beams passing beside that surface made it free on balance.
    #[serde(skip)]
    hit: Vec<bool>,
    /// Per cell: pass-throughs left before a surface last hit in it is
    /// taken for gone ([`HIT_CREDIT`] at every hit, one less at every beam
    /// passing within [`DRAIN_REACH`] of the cell's mean hit position; 0: no
    /// surface held).
    #[serde(skip)]
    held: Vec<u8>,
    /// Per cell hit: the running mean of where in the cell beams ended
    /// ([`MEAN_SCALE`] units from its centre, x then y). Where a surface lies
    /// on a cell boundary, range noise puts about half its hits in the cell
    /// in front; their mean lies at the face, so those hits are the surface
    /// behind's (see [`Grid::integrate_ray`]).
    #[serde(skip)]
    mean: Vec<[i8; 2]>,
    /// Bounding box of every observed cell, kept as cells are observed (the
    /// decomposer asks for it on every update; a scan of a 40 m grid cost
    /// a tenth of the update).
    #[serde(skip)]
    explored: Option<(CellIndex, CellIndex)>,
}

/// Offsets to the 8 neighbours of a cell, the 4 edge neighbours first: the
/// order breadth-first searches over rasters (planner, floor-plan rooms) use.
pub const NEIGHBOURS_8: [(i64, i64); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
];

/// Linear indices of the up to 8 cells around cell `i` of a row-major
/// `w` × `h` raster that lie inside it, in [`NEIGHBOURS_8`] order.
pub fn neighbours8_of(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (w, h) = (w as i64, h as i64);
    let (x, y) = ((i as i64) % w, (i as i64) / w);
    NEIGHBOURS_8
        .into_iter()
        .map(move |(dx, dy)| (x + dx, y + dy))
        .filter(move |&(nx, ny)| nx >= 0 && ny >= 0 && nx < w && ny < h)
        .map(move |(nx, ny)| (ny * w + nx) as usize)
}

/// Integer cell coordinates (column, row); row 0 is the lowest y.
pub(crate) type CellIndex = (usize, usize);

impl Grid {
    /// A grid of `width` × `height` cells of `resolution` metres whose lower-left
    /// corner is at `origin`. All cells start unknown.
    pub fn new(origin: Point2<f64>, resolution: f64, width: usize, height: usize) -> Self {
        Self {
            origin,
            resolution,
            width,
            height,
            cells: vec![UNKNOWN; width * height],
            hit: vec![false; width * height],
            held: vec![0; width * height],
            mean: vec![[0; 2]; width * height],
            explored: None,
        }
    }

    /// A grid covering a square of `extent` metres on each side centred on `centre`.
    pub fn centred(centre: Point2<f64>, extent: f64, resolution: f64) -> Self {
        let n = (extent / resolution).ceil() as usize;
        let half = n as f64 * resolution / 2.0;
        Self::new(
            Point2::new(centre.x - half, centre.y - half),
            resolution,
            n,
            n,
        )
    }

    /// Cell size in metres.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Number of columns.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// World position of the lower-left corner of cell (0, 0).
    pub fn origin(&self) -> Point2<f64> {
        self.origin
    }

    /// The cell containing world point `p`, or `None` outside the grid or for
    /// non-finite input.
    pub fn cell_of(&self, p: &Point2<f64>) -> Option<CellIndex> {
        cell_containing(self.origin, self.resolution, (self.width, self.height), p)
    }

    /// World position of the centre of cell `c`.
    pub fn centre_of(&self, c: CellIndex) -> Point2<f64> {
        cell_centre(self.origin, self.resolution, c)
    }

    /// State of cell `c` (unknown outside the grid).
    pub fn state(&self, c: CellIndex) -> CellState {
        if c.0 >= self.width || c.1 >= self.height {
            return CellState::Unknown;
        }
        Self::state_of(self.cells[c.1 * self.width + c.0])
    }

    /// The lowest raw evidence value of an occupied cell: every value from
    /// it up is [`CellState::Occupied`] (for scans that pass over blocks of
    /// cells below it at once).
    pub(crate) const OCCUPIED_EVIDENCE: u8 = OCCUPIED_AT;

    /// The state a cell of raw evidence `v` is in (see [`Grid::raw_evidence`]).
    pub(crate) fn state_of(v: u8) -> CellState {
        match v {
            UNKNOWN => CellState::Unknown,
            v if v >= OCCUPIED_AT => CellState::Occupied,
            _ => CellState::Free,
        }
    }

    /// [`Grid::state_of`] of every raw evidence value, indexed by the value:
    /// for passes over [`Grid::raw_evidence`] that map each cell through a
    /// table (`.map` it to the reader's own codes).
    pub(crate) fn state_table() -> [CellState; 256] {
        std::array::from_fn(|v| Self::state_of(v as u8))
    }

    /// Raw evidence value of cell `c` (0 = unknown, else 1..=255, higher = more occupied).
    pub fn evidence(&self, c: CellIndex) -> u8 {
        self.cells[c.1 * self.width + c.0]
    }

    /// The maximal runs of cells of equal state along row `y` within the
    /// columns `cols` (clipped to the grid), as `(first column, one past the
    /// last, state)`, unknown runs included: what a picture draws as one
    /// rectangle each.
    pub(crate) fn state_runs(
        &self,
        y: usize,
        cols: std::ops::Range<usize>,
    ) -> impl Iterator<Item = (usize, usize, CellState)> + '_ {
        let end = cols.end.min(self.width);
        let mut x = cols.start;
        std::iter::from_fn(move || {
            if y >= self.height || x >= end {
                return None;
            }
            let (start, st) = (x, self.state((x, y)));
            while x < end && self.state((x, y)) == st {
                x += 1;
            }
            Some((start, x, st))
        })
    }

    /// The lowest and highest cell (column, row) of the bounding box of every
    /// observed cell (evidence not 0), or `None` when nothing was observed yet.
    pub(crate) fn explored_cells(&self) -> Option<(CellIndex, CellIndex)> {
        self.explored
    }

    /// The bounding box of every observed cell, by a scan of the whole grid.
    fn scan_explored(&self) -> Option<(CellIndex, CellIndex)> {
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for y in 0..self.height {
            for x in 0..self.width {
                if self.cells[y * self.width + x] != UNKNOWN {
                    x0 = x0.min(x);
                    y0 = y0.min(y);
                    x1 = x1.max(x);
                    y1 = y1.max(y);
                }
            }
        }
        (x0 != usize::MAX).then_some(((x0, y0), (x1, y1)))
    }

    /// Grows the explored bounding box to hold cell `(x, y)`.
    fn mark_explored(&mut self, x: usize, y: usize) {
        self.explored = Some(match self.explored {
            None => ((x, y), (x, y)),
            Some(((x0, y0), (x1, y1))) => ((x0.min(x), y0.min(y)), (x1.max(x), y1.max(y))),
        });
    }

    /// Overwrites the state of cell `c` (used by tests and checkpoint restore).
    pub fn set_state(&mut self, c: CellIndex, s: CellState) {
        if c.0 < self.width && c.1 < self.height {
            let i = c.1 * self.width + c.0;
            let was_known = self.cells[i] != UNKNOWN;
            self.cells[i] = match s {
                CellState::Unknown => UNKNOWN,
                CellState::Free => 1,
                CellState::Occupied => 255,
            };
            match s {
                CellState::Unknown if was_known => {
                    self.hit[i] = false;
                    self.held[i] = 0;
                    self.mean[i] = [0; 2];
                    self.explored = self.scan_explored();
                }
                CellState::Unknown => {}
                _ => self.mark_explored(c.0, c.1),
            }
        }
    }

    fn bump(&mut self, cx: usize, cy: usize, hit: bool) {
        let i = cy * self.width + cx;
        self.held[i] = if hit {
            HIT_CREDIT
        } else {
            self.held[i].saturating_sub(1)
        };
        let v = &mut self.cells[i];
        let first = *v == UNKNOWN;
        let base = if first { NEUTRAL } else { *v };
        *v = if hit {
            base.saturating_add(HIT)
        } else {
            base.saturating_sub(MISS).max(1)
        };
        if first {
            self.mark_explored(cx, cy);
        }
    }

    /// Integrates one beam from `from` to `to`: cells along it gain free evidence
    /// (and a cell holding a surface loses credit when the beam passes where its
    /// hits lie); when `hit`, the end cell gains occupied evidence, or the solid
    /// cell beyond it when the end cell's hits lie at that face on average.
    /// Parts outside the grid are ignored. Never allocates.
    pub fn integrate_ray(&mut self, from: &Point2<f64>, to: &Point2<f64>, hit: bool) {
        let r = self.resolution;
        let (x0, y0) = ((from.x - self.origin.x) / r, (from.y - self.origin.y) / r);
        let (x1, y1) = ((to.x - self.origin.x) / r, (to.y - self.origin.y) / r);
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            return;
        }
        let (dx, dy) = (x1 - x0, y1 - y0);
        // A surface on a cell boundary is in the cell the beam enters there:
        // the end point is nudged a hair along the beam, so rounding cannot
        // put the hit into the free cell in front of it.
        let len = dx.hypot(dy).max(1e-12);
        let end = (
            (x1 + dx / len * END_NUDGE).floor() as i64,
            (y1 + dy / len * END_NUDGE).floor() as i64,
        );
        // Every cell the beam passes through before the end cell, in order
        // (a beam along a cell boundary or through a corner skips no cell,
        // the one in front of the surface included): each step moves one
        // cell, so the end is that many steps (its grid distance) away.
        let mut walk = CellWalk::new((x0, y0), (dx, dy));
        let cells = (end.0 - walk.cell.0).abs() + (end.1 - walk.cell.1).abs();
        for _ in 0..cells {
            if let Some(((cx, cy), i)) = self.cell_at(walk.cell) {
                let held = self.held[i];
                self.bump(cx, cy, false);
                if held > 0 {
                    // Only a beam passing where the cell's hits lie is
                    // evidence the surface has gone.
                    let m = self.mean_offset(i);
                    let p = (cx as f64 + 0.5 + m.0 - x0, cy as f64 + 0.5 + m.1 - y0);
                    if (p.0 * dy - p.1 * dx).abs() > DRAIN_REACH * len {
                        self.held[i] = held;
                    }
                }
            }
            walk.advance();
        }
        if !hit {
            return;
        }
        let Some(((ex, ey), i)) = self.cell_at(end) else {
            return;
        };
        let at = (x1 - ex as f64 - 0.5, y1 - ey as f64 - 0.5);
        self.add_to_mean(i, at);
        self.hit[i] = true;
        if let Some(((nx, ny), j, face)) = self.solid_face_near_mean(end, (dx, dy)) {
            // The cell's hits lie, on the mean, at a face with a solid
            // cell beyond: a surface on the boundary, read short now
            // and then. The beam passed this cell and ended there.
            self.bump(ex, ey, false);
            self.add_to_mean(j, face);
            self.bump(nx, ny, true);
            self.hit[j] = true;
            return;
        }
        // A beam ending in a free cell just in front of an occupied one
        // is a short reading of that surface (range or pose error), not
        // a surface of its own: it adds evidence but does not make the
        // free cell hold a surface (see `holds_surface`). Measured with
        // independent per-scan errors of 5 mm / 0.17° / 10 mm: the
        // lowest of 24 rooms' coverage 84.8 -> 97.9 %; on ideal scans
        // nothing changes.
        walk.advance();
        let short = Self::state_of(self.cells[i]) == CellState::Free
            && self
                .cell_at(walk.cell)
                .is_some_and(|(_, j)| Self::state_of(self.cells[j]) == CellState::Occupied);
        let held = self.held[i];
        self.bump(ex, ey, true);
        if short {
            self.held[i] = held;
        }
    }

    /// Cell `c` (column, row, possibly off the grid) and its linear index,
    /// when it lies on the grid.
    fn cell_at(&self, c: (i64, i64)) -> Option<(CellIndex, usize)> {
        let inside =
            c.0 >= 0 && c.1 >= 0 && (c.0 as usize) < self.width && (c.1 as usize) < self.height;
        inside.then(|| {
            (
                (c.0 as usize, c.1 as usize),
                c.1 as usize * self.width + c.0 as usize,
            )
        })
    }

    /// The mean hit position of cell `i` (cell units from its centre; see
    /// [`Grid::add_to_mean`]).
    fn mean_offset(&self, i: usize) -> (f64, f64) {
        let m = self.mean[i];
        (f64::from(m[0]) / MEAN_SCALE, f64::from(m[1]) / MEAN_SCALE)
    }

    /// Moves the mean hit position of cell `i` towards `at` (cell units from
    /// its centre); the first hit (the cell not yet [`Grid::was_hit`]) sets
    /// it. Call before marking the cell hit.
    fn add_to_mean(&mut self, i: usize, at: (f64, f64)) {
        let q = |v: f64| (v.clamp(-0.5, 0.5) * MEAN_SCALE).round() as i32;
        let m = &mut self.mean[i];
        if !self.hit[i] {
            *m = [q(at.0) as i8, q(at.1) as i8];
            return;
        }
        for (k, v) in [at.0, at.1].into_iter().enumerate() {
            let old = i32::from(m[k]);
            m[k] = (old + ((q(v) - old) >> MEAN_SHIFT)) as i8;
        }
    }

    /// For a beam along `delta` ending in cell `c`: a solid cell (occupied
    /// or holding a surface) next to `c` where `c`'s mean hit position lies
    /// within [`FACE_SNAP`] of their shared boundary, on a side the beam
    /// heads for: across the nearer such face, else across the corner when
    /// the mean lies that close to both faces (a corner of furniture on a
    /// cell corner). With its linear index and the point of that boundary
    /// nearest the mean, in the other cell's units from its centre.
    fn solid_face_near_mean(
        &self,
        c: (i64, i64),
        delta: (f64, f64),
    ) -> Option<(CellIndex, usize, (f64, f64))> {
        let m = self.mean_offset(self.cell_at(c)?.1);
        // Per axis: the step towards the face the beam heads for and the
        // mean's distance from it (cells), when within FACE_SNAP.
        let near = |d: f64, along: f64| {
            let s = d.signum() as i64;
            let gap = 0.5 - d.signum() * along;
            (d != 0.0 && gap < FACE_SNAP).then_some((s, gap))
        };
        let (nx, ny) = (near(delta.0, m.0), near(delta.1, m.1));
        let solid = |x: i64, y: i64| -> Option<(CellIndex, usize)> {
            let (n, j) = self.cell_at((x, y))?;
            (Self::state_of(self.cells[j]) == CellState::Occupied || self.held[j] > 0)
                .then_some((n, j))
        };
        let across_x =
            nx.and_then(|(s, g)| Some((g, solid(c.0 + s, c.1)?, (-0.5 * s as f64, m.1))));
        let across_y =
            ny.and_then(|(s, g)| Some((g, solid(c.0, c.1 + s)?, (m.0, -0.5 * s as f64))));
        let face = match (across_x, across_y) {
            (Some(a), Some(b)) => Some(if a.0 <= b.0 { a } else { b }),
            (a, b) => a.or(b),
        };
        if let Some((_, (n, j), at)) = face {
            return Some((n, j, at));
        }
        let ((sx, _), (sy, _)) = (nx?, ny?);
        let (n, j) = solid(c.0 + sx, c.1 + sy)?;
        Some((n, j, (-0.5 * sx as f64, -0.5 * sy as f64)))
    }

    /// True when cell `c` is free and touches an unknown cell (4-neighbourhood,
    /// the grid's edge counts as unknown): the explored boundary, where free
    /// space seen by the scanner ends in unexplored space.
    #[cfg(test)]
    pub(crate) fn is_frontier(&self, c: CellIndex) -> bool {
        if self.state(c) != CellState::Free {
            return false;
        }
        let (x, y) = c;
        let unknown = |cx: Option<usize>, cy: Option<usize>| match (cx, cy) {
            (Some(cx), Some(cy)) => self.state((cx, cy)) == CellState::Unknown,
            _ => true,
        };
        unknown(x.checked_sub(1), Some(y))
            || unknown(Some(x + 1).filter(|&v| v < self.width), Some(y))
            || unknown(Some(x), y.checked_sub(1))
            || unknown(Some(x), Some(y + 1).filter(|&v| v < self.height))
    }

    /// Writes every explored-boundary cell ([`is_frontier`](Self::is_frontier))
    /// into `out` (cleared first), row by row.
    #[cfg(test)]
    pub(crate) fn frontier_into(&self, out: &mut Vec<CellIndex>) {
        out.clear();
        for y in 0..self.height {
            for x in 0..self.width {
                if self.is_frontier((x, y)) {
                    out.push((x, y));
                }
            }
        }
    }

    /// Makes `self` an exact copy of `other`, reusing `self`'s cell buffer when
    /// it is large enough (no allocation for grids of equal size).
    pub fn copy_from(&mut self, other: &Grid) {
        self.origin = other.origin;
        self.resolution = other.resolution;
        self.width = other.width;
        self.height = other.height;
        self.cells.clear();
        self.cells.extend_from_slice(&other.cells);
        self.hit.clear();
        self.hit.extend_from_slice(&other.hit);
        self.held.clear();
        self.held.extend_from_slice(&other.held);
        self.mean.clear();
        self.mean.extend_from_slice(&other.mean);
        self.explored = other.explored;
    }

    /// Whether a beam has ever ended in cell `c`: a surface passes through
    /// it, even when beams passing beside that surface left it free on
    /// balance (a wall seen at a grazing angle, a face on the cell's edge).
    /// Unknown space behind such a cell is not a way into unexplored floor.
    /// Not kept in checkpoints: a restored grid starts with no cell hit.
    pub(crate) fn was_hit(&self, c: CellIndex) -> bool {
        self.hit[c.1 * self.width + c.0]
    }

    /// Whether a surface is held in cell `c`: a beam ended in it, and fewer
    /// than [`HIT_CREDIT`] beams have passed through it since near where its
    /// hits lie. Such a cell
    /// may be free on balance (a chair leg or a wall filling part of the
    /// cell, passed by the beams beside it), yet the robot's body must keep
    /// off it. Not kept in checkpoints (like [`Grid::was_hit`]).
    #[cfg(test)]
    pub(crate) fn holds_surface(&self, c: CellIndex) -> bool {
        self.held[c.1 * self.width + c.0] > 0
    }

    /// [`Grid::was_hit`] of every cell, row-major from row 0: for readers
    /// that compare the whole grid with a copy of their own.
    pub(crate) fn hit_flags(&self) -> &[bool] {
        &self.hit
    }

    /// The pass-throughs left of every cell's held surface (0: none; see
    /// [`Grid::holds_surface`]), row-major from row 0.
    pub(crate) fn surface_credits(&self) -> &[u8] {
        &self.held
    }

    /// Raw evidence of every cell, row-major from row 0 (for checkpoints).
    pub fn raw_evidence(&self) -> &[u8] {
        &self.cells
    }

    /// Rebuilds a grid from raw evidence (checkpoint restore). `None` when
    /// `cells` does not hold `width` × `height` values or the geometry is not
    /// finite with a positive resolution.
    pub(crate) fn from_raw_evidence(
        origin: Point2<f64>,
        resolution: f64,
        width: usize,
        height: usize,
        cells: Vec<u8>,
    ) -> Option<Self> {
        let ok = origin.x.is_finite()
            && origin.y.is_finite()
            && resolution.is_finite()
            && resolution > 0.0
            && width.checked_mul(height) == Some(cells.len());
        ok.then(|| {
            let mut g = Self {
                origin,
                resolution,
                width,
                height,
                hit: vec![false; cells.len()],
                held: vec![0; cells.len()],
                mean: vec![[0; 2]; cells.len()],
                cells,
                explored: None,
            };
            g.explored = g.scan_explored();
            g
        })
    }

    /// A grid read back from its serialised form (geometry and evidence):
    /// checked as `Grid::from_raw_evidence` checks it, with the surface
    /// memory empty and the explored box recomputed. `None` when the
    /// geometry is invalid or disagrees with the evidence.
    pub fn rebuilt(self) -> Option<Self> {
        Self::from_raw_evidence(
            self.origin,
            self.resolution,
            self.width,
            self.height,
            self.cells,
        )
    }

    /// Bytes the grid's cells hold: evidence, the hit flag, the surface
    /// credit and the mean hit position.
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of_val(self.cells.as_slice())
            + std::mem::size_of_val(self.hit.as_slice())
            + std::mem::size_of_val(self.held.as_slice())
            + std::mem::size_of_val(self.mean.as_slice())
    }

    /// Number of cells in each state: (unknown, free, occupied).
    pub fn counts(&self) -> (usize, usize, usize) {
        let mut c = (0, 0, 0);
        for &v in &self.cells {
            match v {
                UNKNOWN => c.0 += 1,
                v if v >= OCCUPIED_AT => c.2 += 1,
                _ => c.1 += 1,
            }
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn explored_cells_bound_every_observed_cell() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 20, 20);
        assert_eq!(g.explored_cells(), None);
        g.set_state((3, 7), CellState::Free);
        g.set_state((12, 2), CellState::Occupied);
        assert_eq!(g.explored_cells(), Some(((3, 2), (12, 7))));
        // Kept as rays observe cells, shrunk when a corner cell is forgotten,
        // rebuilt on restore: always what a scan of the grid finds.
        g.integrate_ray(&Point2::new(0.55, 0.55), &Point2::new(1.85, 1.25), true);
        assert_eq!(g.explored_cells(), g.scan_explored());
        assert_eq!(g.explored_cells(), Some(((3, 2), (18, 12))));
        g.set_state((18, 12), CellState::Unknown);
        assert_eq!(g.explored_cells(), g.scan_explored());
        g.set_state((0, 0), CellState::Unknown);
        assert_eq!(g.explored_cells(), g.scan_explored());
        let r = Grid::from_raw_evidence(g.origin(), 0.1, 20, 20, g.raw_evidence().to_vec());
        assert_eq!(r.unwrap().explored_cells(), g.explored_cells());
        let mut c = Grid::new(Point2::new(0.0, 0.0), 0.1, 2, 2);
        c.copy_from(&g);
        assert_eq!(c.explored_cells(), g.explored_cells());
    }

    #[test]
    fn state_runs_split_a_row_at_every_change() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 8, 2);
        for x in 1..4 {
            g.set_state((x, 1), CellState::Free);
        }
        g.set_state((4, 1), CellState::Occupied);
        let runs: Vec<_> = g.state_runs(1, 0..100).collect();
        assert_eq!(
            runs,
            vec![
                (0, 1, CellState::Unknown),
                (1, 4, CellState::Free),
                (4, 5, CellState::Occupied),
                (5, 8, CellState::Unknown),
            ]
        );
        assert_eq!(
            g.state_runs(1, 2..4).collect::<Vec<_>>(),
            vec![(2, 4, CellState::Free)]
        );
        assert_eq!(g.state_runs(2, 0..8).count(), 0);
    }

    #[test]
    fn cell_containing_rejects_outside_and_non_finite_points() {
        let o = Point2::new(-1.0, 2.0);
        let at = |x: f64, y: f64| cell_containing(o, 0.5, (4, 3), &Point2::new(x, y));
        assert_eq!(at(-0.9, 2.1), Some((0, 0)));
        assert_eq!(at(0.99, 3.49), Some((3, 2)));
        assert_eq!(at(1.0, 2.1), None);
        assert_eq!(at(-1.1, 2.1), None);
        assert_eq!(at(f64::NAN, 2.1), None);
        assert_eq!(cell_centre(o, 0.5, (3, 2)), Point2::new(0.75, 3.25));
    }

    #[test]
    fn a_cell_walk_visits_every_cell_the_line_crosses_in_order() {
        // From (0.5, 0.2) to (3.5, 2.2): 3 columns and 2 rows to cross.
        let mut w = CellWalk::new((0.5, 0.2), (3.0, 2.0));
        let mut cells = vec![w.cell];
        let mut t = 0.0;
        while w.exit() <= 1.0 {
            assert!(w.exit() >= t, "t never goes back");
            t = w.exit();
            w.advance();
            cells.push(w.cell);
        }
        assert_eq!(cells, [(0, 0), (1, 0), (1, 1), (2, 1), (3, 1), (3, 2)]);
        // Along a cell boundary and through a corner: no cell skipped.
        let mut w = CellWalk::new((0.0, 0.0), (2.0, 2.0));
        let mut cells = vec![w.cell];
        for _ in 0..4 {
            w.advance();
            cells.push(w.cell);
        }
        assert_eq!(cells, [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2)]);
        assert_eq!(CellWalk::new((1.5, 1.5), (0.0, -1.0)).direction(), (0, -1));
    }

    #[test]
    fn a_hit_on_a_cell_boundary_is_in_the_cell_beyond_it() {
        // Cells 0.05 m from x = 0: a surface at x = 1.0 (a cell boundary,
        // 1.0 / 0.05 rounds either way) is hit from both sides.
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 60, 10);
        let y = 0.225;
        g.integrate_ray(&Point2::new(0.1, y), &Point2::new(1.0, y), true);
        g.integrate_ray(&Point2::new(2.93, y), &Point2::new(2.0, y), true);
        assert_eq!(g.state((19, 4)), CellState::Free, "in front of x = 1.0");
        assert_eq!(g.state((20, 4)), CellState::Occupied, "beyond x = 1.0");
        assert_eq!(g.state((40, 4)), CellState::Free, "in front of x = 2.0");
        assert_eq!(g.state((39, 4)), CellState::Occupied, "beyond x = 2.0");
        // Off a boundary the end point's own cell holds the hit.
        g.integrate_ray(&Point2::new(0.1, 0.375), &Point2::new(1.01, 0.375), true);
        assert_eq!(g.state((20, 7)), CellState::Occupied);
        assert_eq!(g.state((19, 7)), CellState::Free);
    }

    #[test]
    fn a_cell_a_beam_ended_in_stays_marked_hit_when_it_turns_free() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 50, 50);
        g.integrate_ray(&Point2::new(0.05, 0.05), &Point2::new(1.05, 0.05), true);
        assert!(g.was_hit((10, 0)));
        for _ in 0..20 {
            g.integrate_ray(&Point2::new(0.05, 0.05), &Point2::new(2.05, 0.05), false);
        }
        assert_eq!(g.state((10, 0)), CellState::Free);
        assert!(g.was_hit((10, 0)), "a surface passed through it");
        assert!(!g.was_hit((5, 0)) && !g.was_hit((20, 0)));
        let mut copy = Grid::new(Point2::new(0.0, 0.0), 0.1, 1, 1);
        copy.copy_from(&g);
        assert!(copy.was_hit((10, 0)));
        g.set_state((10, 0), CellState::Unknown);
        assert!(!g.was_hit((10, 0)), "a forgotten cell forgets its hits");
    }

    #[test]
    fn a_surface_is_held_until_enough_beams_pass_through_with_none_ending() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 50, 50);
        let (from, at, beyond) = (
            Point2::new(0.05, 0.05),
            Point2::new(1.05, 0.05),
            Point2::new(2.05, 0.05),
        );
        g.integrate_ray(&from, &at, true);
        assert!(g.holds_surface((10, 0)));
        assert!(!g.holds_surface((9, 0)), "passed, never hit");
        for _ in 0..HIT_CREDIT - 1 {
            g.integrate_ray(&from, &beyond, false);
        }
        assert_eq!(g.state((10, 0)), CellState::Free, "free on balance");
        assert!(g.holds_surface((10, 0)), "one pass-through left");
        // A hit renews the credit (a leg some beam hits in every scan).
        g.integrate_ray(&from, &at, true);
        for _ in 0..HIT_CREDIT - 1 {
            g.integrate_ray(&from, &beyond, false);
        }
        assert!(g.holds_surface((10, 0)));
        g.integrate_ray(&from, &beyond, false);
        assert!(!g.holds_surface((10, 0)), "gone: it walked away");
        assert!(g.was_hit((10, 0)), "but it was a surface once");
        g.integrate_ray(&from, &at, true);
        let mut copy = Grid::new(Point2::new(0.0, 0.0), 0.1, 1, 1);
        copy.copy_from(&g);
        assert!(copy.holds_surface((10, 0)));
        g.set_state((10, 0), CellState::Unknown);
        assert!(!g.holds_surface((10, 0)), "a forgotten cell holds nothing");
    }

    #[test]
    fn a_short_reading_of_a_surface_behind_holds_nothing() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 50, 50);
        let from = Point2::new(0.05, 0.05);
        // A wall in cell 10, seen by many beams; cell 9 in front of it free.
        for _ in 0..5 {
            g.integrate_ray(&from, &Point2::new(1.05, 0.05), true);
        }
        assert_eq!(g.state((10, 0)), CellState::Occupied);
        assert_eq!(g.state((9, 0)), CellState::Free);
        // One beam ends 6 cm short, in cell 9: range or pose error.
        g.integrate_ray(&from, &Point2::new(0.99, 0.05), true);
        assert!(g.was_hit((9, 0)));
        assert!(
            !g.holds_surface((9, 0)),
            "a short reading of the wall is no surface"
        );
        assert_eq!(g.state((9, 0)), CellState::Free, "free on balance");
        // The same hit with free floor behind it is a surface of its own
        // (a chair leg filling part of the cell).
        let mut open = Grid::new(Point2::new(0.0, 0.0), 0.1, 50, 50);
        for _ in 0..5 {
            open.integrate_ray(&from, &Point2::new(3.05, 0.05), false);
        }
        open.integrate_ray(&from, &Point2::new(0.99, 0.05), true);
        assert!(open.holds_surface((9, 0)));
    }

    #[test]
    fn a_surface_on_a_boundary_read_short_stays_in_the_cell_behind() {
        // A chair leg whose face lies on the boundary x = 1.0 between cells
        // 9 and 10 fills the lower part of cell 10; beams above it pass
        // through cell 10 and leave it free on balance.
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 50, 50);
        let from = Point2::new(0.05, 0.02);
        let (beside, beyond) = (Point2::new(0.05, 0.08), Point2::new(3.05, 0.08));
        for k in 0..40 {
            // Range noise: every other reading ends 4 mm short, in cell 9.
            let x = if k % 2 == 0 { 1.004 } else { 0.996 };
            g.integrate_ray(&from, &Point2::new(x, 0.02), true);
            for _ in 0..6 {
                g.integrate_ray(&beside, &beyond, false);
            }
        }
        assert_eq!(g.state((10, 0)), CellState::Free, "free on balance");
        assert!(g.holds_surface((10, 0)), "the leg");
        assert!(
            !g.holds_surface((9, 0)),
            "the short readings are the leg's, not a surface in front of it"
        );
        assert_eq!(g.state((9, 0)), CellState::Free);
        assert!(g.was_hit((9, 0)), "a beam did end there");
        // The same readings with nothing behind the boundary are a surface
        // of their own in cell 9 (a leg filling its right edge).
        let mut open = Grid::new(Point2::new(0.0, 0.0), 0.1, 50, 50);
        for _ in 0..40 {
            open.integrate_ray(&from, &Point2::new(0.996, 0.02), true);
        }
        assert!(open.holds_surface((9, 0)));
    }

    #[test]
    fn a_corner_on_a_cell_corner_read_short_stays_in_the_cell_behind() {
        // A box corner at (1.0, 1.0), the box above and right of it, seen
        // along the diagonal: readings end on either side of the corner.
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 50, 50);
        let from = Point2::new(0.05, 0.05);
        g.integrate_ray(&from, &Point2::new(1.004, 1.004), true);
        assert!(g.holds_surface((10, 10)));
        for _ in 0..10 {
            g.integrate_ray(&from, &Point2::new(0.996, 0.996), true);
        }
        assert!(
            !g.holds_surface((9, 9)),
            "the corner's, across the cell corner"
        );
        assert!(g.holds_surface((10, 10)));
        assert!(!g.holds_surface((10, 9)) && !g.holds_surface((9, 10)));
    }

    #[test]
    fn only_beams_passing_where_a_cell_was_hit_let_its_surface_go() {
        // A leg in the lower left of cell 10; beams pass 6 cm above it.
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 50, 50);
        let from = Point2::new(0.05, 0.02);
        g.integrate_ray(&from, &Point2::new(1.02, 0.02), true);
        for _ in 0..2 * u32::from(HIT_CREDIT) {
            g.integrate_ray(&Point2::new(0.05, 0.08), &Point2::new(3.05, 0.08), false);
        }
        assert!(
            g.holds_surface((10, 0)),
            "beams beside the leg say nothing of it"
        );
        // Beams through where it was: it has gone.
        for _ in 0..HIT_CREDIT {
            g.integrate_ray(&from, &Point2::new(3.05, 0.02), false);
        }
        assert!(!g.holds_surface((10, 0)));
    }

    #[test]
    fn ray_marks_free_then_occupied() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 50, 50);
        g.integrate_ray(&Point2::new(0.05, 0.05), &Point2::new(2.05, 0.05), true);
        assert_eq!(g.state((0, 0)), CellState::Free);
        assert_eq!(g.state((10, 0)), CellState::Free);
        assert_eq!(g.state((20, 0)), CellState::Occupied);
        assert_eq!(g.state((21, 0)), CellState::Unknown);
        assert_eq!(g.state((5, 1)), CellState::Unknown);
    }

    #[test]
    fn frontier_is_free_next_to_unknown() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 10, 10);
        g.integrate_ray(&Point2::new(0.05, 0.55), &Point2::new(0.55, 0.55), true);
        let mut f = Vec::new();
        g.frontier_into(&mut f);
        // Cells 0..=4 of row 5 are free, all next to unknown rows 4 and 6.
        assert_eq!(f, vec![(0, 5), (1, 5), (2, 5), (3, 5), (4, 5)]);
        assert!(!g.is_frontier((5, 5)), "occupied is not frontier");
        let mut h = Grid::new(Point2::new(1.0, 1.0), 0.2, 3, 3);
        h.copy_from(&g);
        assert_eq!(h.counts(), g.counts());
        assert_eq!(h.width(), 10);
        assert_eq!(h.state((5, 5)), CellState::Occupied);
    }

    #[test]
    fn outside_and_nan_are_ignored() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 10, 10);
        g.integrate_ray(&Point2::new(f64::NAN, 0.0), &Point2::new(1.0, 1.0), true);
        g.integrate_ray(&Point2::new(-5.0, -5.0), &Point2::new(50.0, 50.0), true);
        assert!(g.cell_of(&Point2::new(-0.1, 0.5)).is_none());
        assert!(g.cell_of(&Point2::new(f64::INFINITY, 0.5)).is_none());
        assert_eq!(g.counts().0 + g.counts().1 + g.counts().2, 100);
    }
}
