//! Bringing the configuration space up to date with the grid: cell states,
//! held surfaces and the inflated masks, incrementally.

use crate::grid::{CellState, Grid};

use super::{square_offsets, CSpace, Frame, Rect, FREE, OCCUPIED, UNKNOWN, WALL_FACE_CELLS};

impl CSpace {
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
    pub(crate) fn set_surface_hold(&mut self, rebuilds: u32) {
        self.hold = rebuilds;
    }

    /// Lets go at once every surface the grid no longer holds and only the
    /// hold ([`CSpace::set_surface_hold`]) keeps blocking; returns their
    /// cells. The hold steadies the plan while the robot works; when
    /// nothing is left to do, floor beside such a cell is not to be lost to
    /// it.
    pub(crate) fn release_held(&mut self) -> Vec<usize> {
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
}
