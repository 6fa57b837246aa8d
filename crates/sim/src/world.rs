//! Simulated worlds: walls with per-surface reflectivity for ray casting, and a
//! free-space raster for ground truth (coverage, collisions).
//!
//! A world is written by hand in a small text format (one directive a line,
//! `#` starts a comment), documented in `docs/simulator.md`:
//!
//! ```text
//! name paper-workspace
//! resolution 0.02                       # ground-truth raster cell (m), optional
//! room 0 0 6.5 0 6.5 4.1 0 4.1 refl 0.6 # outer boundary polygon (closed), x y pairs
//! box 1.0 1.0 1.6 1.4 refl 0.9          # rectangular obstacle: x0 y0 x1 y1
//! polygon 3 3 3.5 3 3.2 3.6 refl 0.3    # obstacle polygon (closed)
//! wall 2 0 2 1.5 refl 0.8               # a thin wall segment (no area)
//! tape 3 0 3.1 0 refl 0.95              # a strip of tape or paint on a wall
//! low box 0.9 1.9 1.1 2.1               # below the scanner's plane (a stool)
//! start 0.5 0.5 0.0                     # robot start pose: x y theta
//! walker 0.2 1.0 1 3 5.5 3 trips 2     # a person: radius speed, a path, how often
//! ```
//!
//! `tape X0 Y0 X1 Y1 refl R` changes the reflectivity of the wall it lies
//! on (within [`TAPE_REACH`]) along that stretch: reflective tape, a dark
//! skirting board, a painted stripe. It changes what the scanner's
//! intensities show, not the geometry.
//!
//! `low` before `box` or `polygon` makes an obstacle the scanner's plane
//! passes over: rays miss it, the body still runs into it (only the bumper
//! can find it).
//!
//! `walker RADIUS SPEED X0 Y0 X1 Y1 [X Y ...] [refl R] [after T] [trips N]
//! [near D]` is a person walking out and back along the way points from
//! time `T` (s; with `near`, once the robot comes within `D` m of the first
//! way point), `N` times one way or for the whole run (see [`crate::walker`]):
//! seen by the scanner, run into by the body, not part of the ground
//! truth's floor. Its path must stay on free floor.
//!
//! Worlds can also be built from an occupancy raster (the floor-plan PNGs of
//! `../shared/maps/`), see `World::from_raster`.

use std::fmt;

use nalgebra::{Point2, Vector2};

use crate::geom::{pose, Pose, Segment};
use crate::grid::CellWalk;
use crate::walker::Walker;

/// One wall segment with the reflectivity of its surface (0..1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wall {
    /// The segment.
    pub seg: Segment,
    /// Surface reflectivity, 0 (black, absorbs) .. 1 (retro-reflective tape).
    pub reflectivity: f64,
}

/// Result of casting one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Distance from the ray origin to the hit (m).
    pub range: f64,
    /// Reflectivity of the surface hit.
    pub reflectivity: f64,
    /// Angle between the ray and the surface normal (rad, 0 = head-on).
    pub incidence: f64,
}

/// A boolean raster: `true` where the floor is free.
#[derive(Clone, Debug)]
pub struct FreeRaster {
    /// World position of the lower-left corner of cell (0, 0).
    pub origin: Point2<f64>,
    /// Cell size (m).
    pub resolution: f64,
    /// Columns.
    pub width: usize,
    /// Rows (row 0 = lowest y).
    pub height: usize,
    /// Row-major cells, `true` = free.
    pub free: Vec<bool>,
}

impl FreeRaster {
    /// Whether the world point `p` lies on free floor (false outside the raster).
    pub fn is_free(&self, p: &Point2<f64>) -> bool {
        match self.cell_of(p) {
            Some((cx, cy)) => self.free[cy * self.width + cx],
            None => false,
        }
    }

    /// Whether cell (`x`, `y`) is free; false outside the raster (negative
    /// coordinates included), so neighbour scans need no bounds checks.
    pub(crate) fn free_at(&self, x: i64, y: i64) -> bool {
        x >= 0
            && y >= 0
            && (x as usize) < self.width
            && (y as usize) < self.height
            && self.free[y as usize * self.width + x as usize]
    }

    /// The cell containing `p`, if inside.
    pub fn cell_of(&self, p: &Point2<f64>) -> Option<(usize, usize)> {
        crate::grid::cell_containing(self.origin, self.resolution, (self.width, self.height), p)
    }

    /// Centre of cell (`cx`, `cy`).
    pub fn centre_of(&self, cx: usize, cy: usize) -> Point2<f64> {
        crate::grid::cell_centre(self.origin, self.resolution, (cx, cy))
    }

    /// Free area in m².
    pub fn free_area(&self) -> f64 {
        self.free.iter().filter(|&&f| f).count() as f64 * self.resolution * self.resolution
    }
}

/// Why a world could not be built.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldError {
    /// The file the world came from, when it came from one.
    pub file: Option<String>,
    /// Line number (1-based) in the world text, 0 when not about one line.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let file = self.file.as_deref().unwrap_or("world");
        if self.line > 0 {
            write!(f, "{file} line {}: {}", self.line, self.message)
        } else {
            write!(f, "{file}: {}", self.message)
        }
    }
}

impl std::error::Error for WorldError {}

fn err(line: usize, message: impl Into<String>) -> WorldError {
    WorldError {
        file: None,
        line,
        message: message.into(),
    }
}

/// Uniform bucket grid over wall segments, so a ray tests only nearby walls.
#[derive(Clone, Debug)]
struct WallIndex {
    origin: Point2<f64>,
    cell: f64,
    nx: usize,
    ny: usize,
    buckets: Vec<Vec<u32>>,
}

impl WallIndex {
    fn build(walls: &[Wall], lo: Point2<f64>, hi: Point2<f64>, cell: f64) -> Self {
        let nx = (((hi.x - lo.x) / cell).ceil() as usize).max(1);
        let ny = (((hi.y - lo.y) / cell).ceil() as usize).max(1);
        let mut buckets = vec![Vec::new(); nx * ny];
        for (i, w) in walls.iter().enumerate() {
            let pad = cell * 0.3;
            for p in crate::geom::points_along(w.seg.a, w.seg.b, cell * 0.25) {
                let bucket = |v: f64, o: f64, m: usize| {
                    (((v - o) / cell).floor().max(0.0) as usize).min(m - 1)
                };
                let (x0, x1) = (bucket(p.x - pad, lo.x, nx), bucket(p.x + pad, lo.x, nx));
                let (y0, y1) = (bucket(p.y - pad, lo.y, ny), bucket(p.y + pad, lo.y, ny));
                for cy in y0..=y1 {
                    for cx in x0..=x1 {
                        let list = &mut buckets[cy * nx + cx];
                        if !list.contains(&(i as u32)) {
                            list.push(i as u32);
                        }
                    }
                }
            }
        }
        Self {
            origin: lo,
            cell,
            nx,
            ny,
            buckets,
        }
    }
}

/// A simulated world: walls for the scanner, free floor for ground truth.
#[derive(Clone, Debug)]
pub struct World {
    /// Human-readable name.
    pub name: String,
    /// All wall segments the scanner sees (room boundary, obstacle
    /// outlines, thin walls).
    pub walls: Vec<Wall>,
    /// Outlines of the `low` obstacles: rays pass over them, the body does
    /// not (they are not free floor); kept for the pictures.
    pub low: Vec<Wall>,
    /// Ground-truth free floor.
    pub free: FreeRaster,
    /// Where the robot starts.
    pub start: Pose,
    /// People walking through the room (none unless the world says so).
    pub walkers: Vec<Walker>,
    /// Stretches of wall with a reflectivity of their own (`tape`).
    pub tapes: Vec<Wall>,
    index: WallIndex,
}

/// How far from a wall a `tape` may lie, and a hit from a tape to take its
/// reflectivity (m).
pub const TAPE_REACH: f64 = 0.01;

/// Default ground-truth raster cell for hand-written worlds (m).
const DEFAULT_RESOLUTION: f64 = 0.02;
/// Default reflectivity when a directive gives none.
const DEFAULT_REFLECTIVITY: f64 = 0.5;

impl World {
    /// Parses a world from its text form (see the module docs).
    pub fn parse(text: &str) -> Result<World, WorldError> {
        let mut name = String::from("unnamed");
        let mut resolution = DEFAULT_RESOLUTION;
        let mut room: Option<(Vec<Point2<f64>>, f64)> = None;
        let mut obstacles: Vec<(Vec<Point2<f64>>, f64)> = Vec::new();
        let mut low: Vec<Vec<Point2<f64>>> = Vec::new();
        let mut thin: Vec<Wall> = Vec::new();
        let mut tapes: Vec<(usize, Wall)> = Vec::new();
        let mut start: Option<Pose> = None;
        let mut walkers: Vec<(usize, Walker)> = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let ln = i + 1;
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let mut words = line.split_whitespace();
            let mut key = words.next().unwrap_or("");
            let below = key == "low";
            if below {
                key = words.next().unwrap_or("");
                if !matches!(key, "box" | "polygon") {
                    return Err(err(ln, "`low` takes `box` or `polygon` after it"));
                }
            }
            let rest: Vec<&str> = words.collect();
            let (nums, refl) = split_refl(&rest, ln)?;
            let before = obstacles.len();
            match key {
                "name" => name = rest.join(" "),
                "resolution" => {
                    let v = exactly(&nums, 1, ln, "resolution takes one number (m)")?[0];
                    if !(0.005..=0.5).contains(&v) {
                        return Err(err(ln, format!("resolution {v} outside 0.005..0.5 m")));
                    }
                    resolution = v;
                }
                "room" => {
                    if room.is_some() {
                        return Err(err(ln, "a world has one `room`"));
                    }
                    room = Some((polygon(&nums, ln)?, refl));
                }
                "box" => {
                    let v = exactly(&nums, 4, ln, "box takes x0 y0 x1 y1")?;
                    let (x0, x1) = (v[0].min(v[2]), v[0].max(v[2]));
                    let (y0, y1) = (v[1].min(v[3]), v[1].max(v[3]));
                    if x1 - x0 <= 0.0 || y1 - y0 <= 0.0 {
                        return Err(err(ln, "box has zero area"));
                    }
                    obstacles.push((
                        vec![
                            Point2::new(x0, y0),
                            Point2::new(x1, y0),
                            Point2::new(x1, y1),
                            Point2::new(x0, y1),
                        ],
                        refl,
                    ));
                }
                "polygon" => obstacles.push((polygon(&nums, ln)?, refl)),
                "wall" => {
                    let v = exactly(&nums, 4, ln, "wall takes x0 y0 x1 y1")?;
                    let seg = Segment::new(Point2::new(v[0], v[1]), Point2::new(v[2], v[3]));
                    if seg.length() <= 0.0 {
                        return Err(err(ln, "wall has zero length"));
                    }
                    thin.push(Wall {
                        seg,
                        reflectivity: refl,
                    });
                }
                "tape" => {
                    let v = exactly(&nums, 4, ln, "tape takes x0 y0 x1 y1")?;
                    let seg = Segment::new(Point2::new(v[0], v[1]), Point2::new(v[2], v[3]));
                    if seg.length() <= 0.0 {
                        return Err(err(ln, "tape has zero length"));
                    }
                    tapes.push((
                        ln,
                        Wall {
                            seg,
                            reflectivity: refl,
                        },
                    ));
                }
                "start" => {
                    let v = exactly(&nums, 3, ln, "start takes x y theta")?;
                    start = Some(pose(v[0], v[1], v[2]));
                }
                "walker" => walkers.push((ln, Walker::parse_words(&rest).map_err(|m| err(ln, m))?)),
                other => return Err(err(ln, format!("unknown directive `{other}`"))),
            }
            if below && obstacles.len() > before {
                low.extend(obstacles.pop().map(|(o, _)| o));
            }
        }
        let (outline, room_refl) = room.ok_or_else(|| err(0, "no `room` line"))?;
        let mut walls = Vec::new();
        push_ring(&mut walls, &outline, room_refl);
        for (poly, r) in &obstacles {
            push_ring(&mut walls, poly, *r);
        }
        walls.extend(thin.iter().copied());
        for (ln, t) in &tapes {
            let on_wall =
                |p: Point2<f64>| walls.iter().any(|w| w.seg.distance_to(&p) <= TAPE_REACH);
            let mid = Point2::from((t.seg.a.coords + t.seg.b.coords) / 2.0);
            if !(on_wall(t.seg.a) && on_wall(t.seg.b) && on_wall(mid)) {
                return Err(err(
                    *ln,
                    format!("tape does not lie on a wall (within {TAPE_REACH} m)"),
                ));
            }
        }
        let (lo, hi) = bounds(&outline);
        let margin = resolution * 2.0;
        let origin = Point2::new(lo.x - margin, lo.y - margin);
        let width = ((hi.x - lo.x + 2.0 * margin) / resolution).ceil() as usize;
        let height = ((hi.y - lo.y + 2.0 * margin) / resolution).ceil() as usize;
        if width.saturating_mul(height) > 50_000_000 {
            return Err(err(0, "world too large for its resolution"));
        }
        let mut free = vec![false; width * height];
        for cy in 0..height {
            for cx in 0..width {
                let p = Point2::new(
                    origin.x + (cx as f64 + 0.5) * resolution,
                    origin.y + (cy as f64 + 0.5) * resolution,
                );
                free[cy * width + cx] = inside(&outline, &p)
                    && !obstacles.iter().any(|(o, _)| inside(o, &p))
                    && !low.iter().any(|o| inside(o, &p));
            }
        }
        // Thin walls take no area but block the cells they cross.
        let raster = FreeRaster {
            origin,
            resolution,
            width,
            height,
            free,
        };
        let mut raster = raster;
        for w in &thin {
            block_segment(&mut raster, &w.seg);
        }
        let start = start.unwrap_or_else(|| {
            let c = Point2::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0);
            pose(c.x, c.y, 0.0)
        });
        let mut low_walls = Vec::new();
        for poly in &low {
            push_ring(&mut low_walls, poly, DEFAULT_REFLECTIVITY);
        }
        let mut world = World::assemble(name, walls, raster, start);
        world.low = low_walls;
        world.tapes = tapes.into_iter().map(|(_, t)| t).collect();
        for (ln, w) in walkers {
            world.add_walker(w).map_err(|m| err(ln, m))?;
        }
        Ok(world)
    }

    /// Reads and parses a world file.
    pub fn load(path: &std::path::Path) -> Result<World, WorldError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| err(0, format!("cannot read {}: {e}", path.display())))?;
        World::parse(&text).map_err(|mut e| {
            e.file = Some(path.display().to_string());
            e
        })
    }

    /// Builds a world from a free-space raster: every boundary between a free
    /// and a non-free cell becomes a wall (collinear cell edges merged), with
    /// the given reflectivity. Used for the floor-plan PNGs.
    pub(crate) fn from_raster(
        name: &str,
        raster: FreeRaster,
        reflectivity: f64,
        start: Pose,
    ) -> World {
        let (w, h, r) = (raster.width, raster.height, raster.resolution);
        let o = raster.origin;
        let at = |x: i64, y: i64| raster.free_at(x, y);
        let mut walls = Vec::new();
        // Horizontal edges: between row y-1 and row y, for y in 0..=h.
        for y in 0..=h as i64 {
            let mut run: Option<i64> = None;
            for x in 0..=w as i64 {
                let edge = x < w as i64 && at(x, y - 1) != at(x, y);
                match (edge, run) {
                    (true, None) => run = Some(x),
                    (false, Some(x0)) => {
                        let yy = o.y + y as f64 * r;
                        walls.push(Wall {
                            seg: Segment::new(
                                Point2::new(o.x + x0 as f64 * r, yy),
                                Point2::new(o.x + x as f64 * r, yy),
                            ),
                            reflectivity,
                        });
                        run = None;
                    }
                    _ => {}
                }
            }
        }
        for x in 0..=w as i64 {
            let mut run: Option<i64> = None;
            for y in 0..=h as i64 {
                let edge = y < h as i64 && at(x - 1, y) != at(x, y);
                match (edge, run) {
                    (true, None) => run = Some(y),
                    (false, Some(y0)) => {
                        let xx = o.x + x as f64 * r;
                        walls.push(Wall {
                            seg: Segment::new(
                                Point2::new(xx, o.y + y0 as f64 * r),
                                Point2::new(xx, o.y + y as f64 * r),
                            ),
                            reflectivity,
                        });
                        run = None;
                    }
                    _ => {}
                }
            }
        }
        World::assemble(name.to_string(), walls, raster, start)
    }

    fn assemble(name: String, walls: Vec<Wall>, free: FreeRaster, start: Pose) -> World {
        let lo = free.origin;
        let hi = Point2::new(
            lo.x + free.width as f64 * free.resolution,
            lo.y + free.height as f64 * free.resolution,
        );
        let index = WallIndex::build(&walls, lo, hi, 0.5);
        World {
            name,
            walls,
            low: Vec::new(),
            free,
            start,
            walkers: Vec::new(),
            tapes: Vec::new(),
            index,
        }
    }

    /// Adds a person walking through the room; refused (saying where) when
    /// the path leaves the free floor.
    pub fn add_walker(&mut self, w: Walker) -> Result<(), String> {
        let step = self.free.resolution.min(0.05);
        if let Some(p) = w.samples(step).find(|p| !self.free.is_free(p)) {
            return Err(format!(
                "the walker's path leaves the free floor at ({:.2}, {:.2}) m",
                p.x, p.y
            ));
        }
        self.walkers.push(w);
        Ok(())
    }

    /// Casts a ray from `origin` in direction `angle` (world frame) and returns
    /// the nearest wall hit within `max_range`, if any.
    pub fn cast_ray(&self, origin: &Point2<f64>, angle: f64, max_range: f64) -> Option<RayHit> {
        let dir = Vector2::new(angle.cos(), angle.sin());
        let idx = &self.index;
        // DDA over the bucket grid.
        let fx = (origin.x - idx.origin.x) / idx.cell;
        let fy = (origin.y - idx.origin.y) / idx.cell;
        if !(fx.is_finite() && fy.is_finite() && max_range.is_finite()) {
            return None;
        }
        let mut walk = CellWalk::new((fx, fy), (dir.x / idx.cell, dir.y / idx.cell));
        let (step_x, step_y) = walk.direction();
        let mut best: Option<(f64, usize)> = None;
        let mut t_cell_start = 0.0f64;
        loop {
            let (cx, cy) = walk.cell;
            if cx >= 0 && cy >= 0 && (cx as usize) < idx.nx && (cy as usize) < idx.ny {
                for &wi in &idx.buckets[cy as usize * idx.nx + cx as usize] {
                    let w = &self.walls[wi as usize];
                    if let Some(t) = ray_segment(origin, &dir, &w.seg) {
                        if t <= max_range && best.is_none_or(|(bt, _)| t < bt) {
                            best = Some((t, wi as usize));
                        }
                    }
                }
            } else if (cx < 0 && step_x < 0)
                || (cy < 0 && step_y < 0)
                || (cx >= idx.nx as i64 && step_x > 0)
                || (cy >= idx.ny as i64 && step_y > 0)
            {
                break;
            }
            let t_cell_end = walk.exit();
            if let Some((bt, _)) = best {
                if bt <= t_cell_end {
                    break;
                }
            }
            if t_cell_start > max_range {
                break;
            }
            t_cell_start = t_cell_end;
            walk.advance();
        }
        best.map(|(t, wi)| {
            let w = &self.walls[wi];
            let d = w.seg.b - w.seg.a;
            let n = Vector2::new(-d.y, d.x).normalize();
            let cos = dir.dot(&n).abs().min(1.0);
            let at = origin + dir * t;
            let reflectivity = self
                .tapes
                .iter()
                .find(|tape| tape.seg.distance_to(&at) <= TAPE_REACH)
                .map_or(w.reflectivity, |tape| tape.reflectivity);
            RayHit {
                range: t,
                reflectivity,
                incidence: cos.acos(),
            }
        })
    }

    /// Whether a disk of `radius` at `p` lies entirely on free floor (sampled on
    /// the ground-truth raster).
    pub fn disk_is_free(&self, p: &Point2<f64>, radius: f64) -> bool {
        let r = self.free.resolution;
        let n = (radius / r).ceil() as i64;
        for dy in -n..=n {
            for dx in -n..=n {
                let off = Vector2::new(dx as f64 * r, dy as f64 * r);
                if off.norm() <= radius && !self.free.is_free(&(p + off)) {
                    return false;
                }
            }
        }
        self.free.is_free(p)
    }
}

fn split_refl(words: &[&str], ln: usize) -> Result<(Vec<f64>, f64), WorldError> {
    let mut nums = Vec::new();
    let mut refl = DEFAULT_REFLECTIVITY;
    let mut i = 0;
    while i < words.len() {
        if words[i] == "refl" {
            let v = words
                .get(i + 1)
                .ok_or_else(|| err(ln, "`refl` needs a value"))?;
            refl = v
                .parse::<f64>()
                .map_err(|_| err(ln, format!("bad reflectivity `{v}`")))?;
            if !(0.0..=1.0).contains(&refl) {
                return Err(err(ln, format!("reflectivity {refl} outside 0..1")));
            }
            i += 2;
            continue;
        }
        if let Ok(v) = words[i].parse::<f64>() {
            if !v.is_finite() || v.abs() > 1.0e4 {
                return Err(err(
                    ln,
                    format!("value `{}` is not a sane finite number", words[i]),
                ));
            }
            nums.push(v);
        }
        i += 1;
    }
    Ok((nums, refl))
}

fn exactly<'a>(nums: &'a [f64], n: usize, ln: usize, what: &str) -> Result<&'a [f64], WorldError> {
    if nums.len() == n {
        Ok(nums)
    } else {
        Err(err(ln, format!("{what} (got {} numbers)", nums.len())))
    }
}

fn polygon(nums: &[f64], ln: usize) -> Result<Vec<Point2<f64>>, WorldError> {
    if nums.len() < 6 || !nums.len().is_multiple_of(2) {
        return Err(err(ln, "a polygon takes at least 3 x y pairs"));
    }
    let pts: Vec<Point2<f64>> = nums.chunks(2).map(|c| Point2::new(c[0], c[1])).collect();
    let area: f64 = (0..pts.len())
        .map(|i| {
            let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
        / 2.0;
    if area.abs() < 1e-9 {
        return Err(err(ln, "polygon has zero area"));
    }
    Ok(pts)
}

fn push_ring(walls: &mut Vec<Wall>, poly: &[Point2<f64>], reflectivity: f64) {
    for i in 0..poly.len() {
        let seg = Segment::new(poly[i], poly[(i + 1) % poly.len()]);
        if seg.length() > 0.0 {
            walls.push(Wall { seg, reflectivity });
        }
    }
}

fn bounds(poly: &[Point2<f64>]) -> (Point2<f64>, Point2<f64>) {
    let mut lo = Point2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in poly {
        lo.x = lo.x.min(p.x);
        lo.y = lo.y.min(p.y);
        hi.x = hi.x.max(p.x);
        hi.y = hi.y.max(p.y);
    }
    (lo, hi)
}

/// Even-odd point-in-polygon test.
pub fn inside(poly: &[Point2<f64>], p: &Point2<f64>) -> bool {
    let mut c = false;
    let n = poly.len();
    let mut j = n - 1;
    for i in 0..n {
        let (a, b) = (poly[i], poly[j]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            c = !c;
        }
        j = i;
    }
    c
}

fn block_segment(r: &mut FreeRaster, seg: &Segment) {
    let n = ((seg.length() / (r.resolution * 0.5)).ceil() as usize).max(1);
    for k in 0..=n {
        let p = seg.a + (seg.b - seg.a) * (k as f64 / n as f64);
        if let Some((cx, cy)) = r.cell_of(&p) {
            r.free[cy * r.width + cx] = false;
        }
    }
}

/// Distance along the ray `origin + t·dir` (t ≥ 0) to the segment, if it hits.
fn ray_segment(origin: &Point2<f64>, dir: &Vector2<f64>, seg: &Segment) -> Option<f64> {
    let e = seg.b - seg.a;
    let denom = dir.x * e.y - dir.y * e.x;
    if denom.abs() < 1e-12 {
        return None;
    }
    let w = seg.a - origin;
    let t = (w.x * e.y - w.y * e.x) / denom;
    let u = (w.x * dir.y - w.y * dir.x) / denom;
    (t >= 1e-9 && (-1e-9..=1.0 + 1e-9).contains(&u)).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROOM: &str =
        "name t\nroom 0 0 4 0 4 3 0 3 refl 0.4\nbox 1 1 2 2 refl 0.9\nstart 0.5 0.5 0\n";

    #[test]
    fn rays_hit_room_and_box() {
        let w = World::parse(ROOM).unwrap();
        let h = w.cast_ray(&Point2::new(0.5, 1.5), 0.0, 10.0).unwrap();
        assert!((h.range - 0.5).abs() < 1e-9, "{h:?}");
        assert!((h.reflectivity - 0.9).abs() < 1e-12);
        let h = w.cast_ray(&Point2::new(0.5, 0.5), 0.0, 10.0).unwrap();
        assert!((h.range - 3.5).abs() < 1e-9);
        assert!((h.reflectivity - 0.4).abs() < 1e-12);
        let h = w
            .cast_ray(&Point2::new(0.5, 0.5), std::f64::consts::FRAC_PI_2, 10.0)
            .unwrap();
        assert!((h.range - 2.5).abs() < 1e-9);
        assert!(w.cast_ray(&Point2::new(0.5, 0.5), 0.0, 1.0).is_none());
    }

    #[test]
    fn tape_changes_the_reflectivity_of_its_stretch_of_wall_only() {
        let w = World::parse(&format!("{ROOM}tape 4 2.2 4 2.6 refl 0.95\n")).unwrap();
        let o = Point2::new(3.0, 2.4);
        let on = w.cast_ray(&o, 0.0, 10.0).unwrap();
        assert!((on.range - 1.0).abs() < 1e-9);
        assert!((on.reflectivity - 0.95).abs() < 1e-12, "{on:?}");
        // Beside the tape: the wall's own.
        let off = w.cast_ray(&Point2::new(3.0, 2.0), 0.0, 10.0).unwrap();
        assert!((off.reflectivity - 0.4).abs() < 1e-12, "{off:?}");
        // The geometry is the room's: the free floor does not change.
        assert_eq!(w.free.free, World::parse(ROOM).unwrap().free.free);
        for bad in [
            "tape 3 2.2 3 2.6 refl 0.9",
            "tape 4 1 4 1 refl 0.9",
            "tape 4 1 4",
        ] {
            let e = World::parse(&format!("{ROOM}{bad}\n")).unwrap_err();
            assert_eq!(e.line, 5, "{bad}: {e}");
        }
    }

    #[test]
    fn diagonal_ray_matches_brute_force() {
        let w = World::parse(ROOM).unwrap();
        for k in 0..360 {
            let a = (k as f64).to_radians();
            let o = Point2::new(3.3, 2.7);
            let fast = w.cast_ray(&o, a, 20.0).map(|h| h.range);
            let dir = Vector2::new(a.cos(), a.sin());
            let brute = w
                .walls
                .iter()
                .filter_map(|wl| ray_segment(&o, &dir, &wl.seg))
                .fold(f64::INFINITY, f64::min);
            assert!((fast.unwrap() - brute).abs() < 1e-9, "angle {k}");
        }
    }

    #[test]
    fn free_area_and_disk() {
        let w = World::parse(ROOM).unwrap();
        assert!(
            (w.free.free_area() - 11.0).abs() < 0.1,
            "{}",
            w.free.free_area()
        );
        assert!(w.disk_is_free(&Point2::new(0.5, 0.5), 0.2));
        assert!(!w.disk_is_free(&Point2::new(0.9, 1.5), 0.2));
    }

    #[test]
    fn a_low_box_stops_the_body_but_not_the_rays() {
        let w = World::parse("room 0 0 4 0 4 3 0 3\nlow box 2 1 2.4 1.4\nstart 1 1.2 0\n").unwrap();
        // The ray along y = 1.2 passes over the stool to the far wall.
        let h = w.cast_ray(&Point2::new(1.0, 1.2), 0.0, 10.0).unwrap();
        assert!((h.range - 3.0).abs() < 1e-9, "{}", h.range);
        assert!(!w.free.is_free(&Point2::new(2.2, 1.2)));
        assert!(!w.disk_is_free(&Point2::new(1.9, 1.2), 0.17));
        assert_eq!((w.walls.len(), w.low.len()), (4, 4));
        let e = World::parse("room 0 0 4 0 4 3 0 3\nlow wall 1 1 2 2\n").unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
    }

    #[test]
    fn walker_lines_give_people_on_free_floor_and_bad_ones_name_the_line() {
        let w = World::parse("room 0 0 4 0 4 3 0 3\nwalker 0.2 1.0 0.5 1.5 3.5 1.5\nwalker 0.15 0.5 1 0.5 1 2.5 refl 0.9\n")
            .unwrap();
        assert_eq!(w.walkers.len(), 2);
        let default = crate::walker::DEFAULT_WALKER_REFLECTIVITY;
        assert!((w.walkers[0].reflectivity - default).abs() < 1e-12);
        assert!((w.walkers[1].reflectivity - 0.9).abs() < 1e-12);
        // People are not walls: the rays of the world alone miss them.
        assert_eq!(w.walls.len(), 4);
        for (text, needle) in [
            (
                "room 0 0 4 0 4 3 0 3\nbox 1 1 2 2\nwalker 0.2 1 0.5 1.5 3.5 1.5\n",
                "line 3: the walker's path leaves the free floor at (1.0",
            ),
            (
                "room 0 0 4 0 4 3 0 3\nwalker 0.2 1 0.5 1.5\n",
                "line 2: walker takes",
            ),
            (
                "room 0 0 4 0 4 3 0 3\nwalker 0.2 1 0.5 1.5 5 1.5\n",
                "leaves the free floor at (4.0",
            ),
        ] {
            let e = World::parse(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
    }

    #[test]
    fn bad_worlds_name_the_line() {
        for (text, needle) in [
            ("room 0 0 1 0\n", "line 1"),
            ("room 0 0 4 0 4 3 0 3\nbox 1 1 1 2\n", "line 2"),
            ("frobnicate 1\n", "unknown directive"),
            ("room 0 0 4 0 4 3 0 3 refl 7\n", "reflectivity"),
            ("box 0 0 1 1\n", "no `room`"),
            ("room 0 0 4 0 4 3 0 nan\n", "line 1"),
        ] {
            let e = World::parse(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text:?}: {e}");
        }
    }

    #[test]
    fn raster_world_walls_follow_free_cells() {
        let mut free = vec![false; 10 * 10];
        for y in 2..8 {
            for x in 2..8 {
                free[y * 10 + x] = true;
            }
        }
        let raster = FreeRaster {
            origin: Point2::new(0.0, 0.0),
            resolution: 0.1,
            width: 10,
            height: 10,
            free,
        };
        assert!(raster.free_at(2, 7) && raster.free_at(7, 2));
        assert!(!raster.free_at(1, 5) && !raster.free_at(8, 5));
        assert!(!raster.free_at(-1, 5) && !raster.free_at(5, 10) && !raster.free_at(10, 0));
        let w = World::from_raster("sq", raster, 0.5, pose(0.5, 0.5, 0.0));
        assert_eq!(w.walls.len(), 4);
        let h = w.cast_ray(&Point2::new(0.5, 0.5), 0.0, 5.0).unwrap();
        assert!((h.range - 0.3).abs() < 1e-9);
    }
}

#[cfg(test)]
mod shipped_worlds {
    use super::*;

    #[test]
    fn paper_world_parses_with_expected_area() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../hw/worlds/paper.world");
        let w = World::load(std::path::Path::new(path)).unwrap();
        // 6.5 × 4.1 = 26.65 m² less the obstacles 0.4 + 0.72 + 0.6 + 0.09 = 1.81 m².
        assert!(
            (w.free.free_area() - 24.84).abs() < 0.15,
            "{}",
            w.free.free_area()
        );
        assert!(w.disk_is_free(&w.start.translation.vector.into(), 0.17));
    }

    fn shipped(name: &str) -> World {
        let path = format!("{}/../../hw/worlds/{name}", env!("CARGO_MANIFEST_DIR"));
        World::load(std::path::Path::new(&path)).unwrap()
    }

    #[test]
    fn the_corridor_shows_its_tape_only_in_the_reflectivity() {
        let w = shipped("corridor.world");
        let o = Point2::new(7.0, 0.9);
        let down = -std::f64::consts::FRAC_PI_2;
        // Straight down from x = 7.0 is plaster; towards the strip at
        // x = 6.7-6.8 on the same wall, tape; the range is the wall's.
        let plaster = w.cast_ray(&o, down, 10.0).unwrap();
        let to_tape = (-0.9f64).atan2(-0.25);
        let tape = w.cast_ray(&o, to_tape, 10.0).unwrap();
        assert!((plaster.reflectivity - 0.55).abs() < 1e-12, "{plaster:?}");
        assert!((tape.reflectivity - 0.95).abs() < 1e-12, "{tape:?}");
        assert!((tape.range - 0.25f64.hypot(0.9)).abs() < 1e-9);
        // In the middle neither end wall is within the URG-04LX's 5.6 m.
        let mid = Point2::new(8.0, 0.9);
        assert!(w.cast_ray(&mid, 0.0, 5.6).is_none());
        assert!(w.cast_ray(&mid, std::f64::consts::PI, 5.6).is_none());
    }

    #[test]
    fn the_mirror_rooms_halves_differ_only_in_reflectivity() {
        let w = shipped("mirror.world");
        // Every ray from a point has its mirror image about x = 4 from the
        // mirrored point: the same range, a different reflectivity where it
        // hits the room's walls.
        let (p, q) = (Point2::new(0.9, 1.1), Point2::new(7.1, 1.1));
        let mut darker = 0;
        for k in 0..360 {
            let a = (k as f64 + 0.5).to_radians();
            let h = w.cast_ray(&p, a, 20.0).unwrap();
            let m = w.cast_ray(&q, std::f64::consts::PI - a, 20.0).unwrap();
            assert!((h.range - m.range).abs() < 1e-9, "ray {k}: {h:?} {m:?}");
            if h.reflectivity < m.reflectivity {
                darker += 1;
            }
        }
        assert!(darker > 180, "{darker} of 360 rays darker on the left");
        // The free floor is symmetric too.
        let r = &w.free;
        for cy in 0..r.height {
            for cx in 0..r.width {
                let p = Point2::new(
                    r.origin.x + (cx as f64 + 0.5) * r.resolution,
                    r.origin.y + (cy as f64 + 0.5) * r.resolution,
                );
                let m = Point2::new(8.0 - p.x, p.y);
                assert_eq!(r.is_free(&p), r.is_free(&m), "{p}");
            }
        }
    }
}
