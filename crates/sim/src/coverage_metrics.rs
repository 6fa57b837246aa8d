//! Coverage metrics against the world's ground truth (never the robot's own
//! map): which floor the robot could reach, what its tool actually swept,
//! how often, how far it drove, how often it turned, and whether its body
//! ever touched an obstacle.
//!
//! Definitions (see also `docs/coverage-planning.md`):
//! * **reachable**: ground-truth cells where a disk of the robot radius centred
//!   on the cell is free, 8-connected to the start cell: where the robot's
//!   centre can go. Coverage % is the share of these cells the tool swept.
//! * **footprint-reachable** (stricter, reported beside it): reachable cells
//!   dilated by the tool half-width: all floor the tool could touch.
//! * **reachable with clearance** (laxer, reported beside it): reachable cells
//!   where a disk of the robot radius plus a clearance (the planner's safety
//!   margin, see [`CoverageTracker::with_clearance`]) is free, connected to
//!   the start: floor behind a passage that leaves the body less than that
//!   clearance is out of it. It tells floor missed from floor behind such a
//!   passage (5 mm a side in some of the floor-plan rooms).
//! * **unreachable area**: free floor the robot body cannot even touch (free
//!   cells farther than one robot radius from every reachable cell), e.g. a
//!   pocket behind furniture; reported, never counted as missed.
//! * **overlap**: area swept in more than one pass / area swept. A pass over a
//!   cell starts when the tool disk (exact distance to the cell centre) enters
//!   it and ends when it has been out of it for more than a second.
//! * **turns**: heading changes of the direction of travel above 30°, the
//!   travel direction sampled every 5 cm of path (as the IPA evaluation does on
//!   its pixel path); rotation is the total absolute heading change.
//! * **collision**: a recorded pose whose robot disk is not entirely on free
//!   ground truth; counted once per entry.

use nalgebra::Point2;

use crate::geom::{heading, wrap_angle, Pose};
use crate::grid::neighbours8_of;
use crate::plan::cspace::disk;
use crate::plan::Motion;
use crate::world::{FreeRaster, World};

/// Distance of travel between two samples of the travel direction (m).
const TURN_SAMPLE: f64 = 0.05;
/// A cell swept again within this time (s) of last being under the tool
/// continues its pass: tracking jitter of a millimetre at the tool's edge is
/// not a second pass, while coming back along the next lane (after two turns
/// in place) always is.
const SAME_PASS: f64 = 1.0;
/// Heading change that counts as a turn (rad), 30° as in the IPA evaluation.
const TURN_ANGLE: f64 = 0.52;

/// Causes of repeat sweeping, in the order of [`CoverageMetrics::overlap_by`].
pub const OVERLAP_CAUSES: [&str; 7] = [
    "lane over an earlier lane of its own task",
    "lane over floor swept otherwise (earlier task, transit, connection)",
    "fix-up lane",
    "connection between lanes",
    "transit to a region",
    "exploration",
    "turns in place, look-around, escape",
];

/// Why metrics cannot be set up.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MetricsError {
    /// The start pose is in collision with the ground truth.
    #[error("start ({x:.2}, {y:.2}) m: a robot of radius {radius} m there overlaps an obstacle or lies outside the room")]
    StartInCollision {
        /// Start x (m).
        x: f64,
        /// Start y (m).
        y: f64,
        /// Robot radius (m).
        radius: f64,
    },
}

/// The figures of one run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoverageMetrics {
    /// Swept share of the reachable cells (0..1).
    pub coverage: f64,
    /// Swept share of the footprint-reachable cells (0..1), the stricter figure.
    pub footprint_coverage: f64,
    /// Reachable area (m²).
    pub reachable_area: f64,
    /// Footprint-reachable area (m²).
    pub(crate) footprint_reachable_area: f64,
    /// Swept share of the cells reachable with the clearance (0..1; equal
    /// to `coverage` without a clearance).
    pub clear_coverage: f64,
    /// Area reachable with the clearance (m²).
    pub clear_reachable_area: f64,
    /// All free floor (m²).
    pub free_area: f64,
    /// Free floor the robot body cannot touch (m²).
    pub unreachable_area: f64,
    /// Area swept at least once (m²).
    pub covered_area: f64,
    /// Area swept in more than one pass / area swept (0..).
    pub overlap: f64,
    /// `overlap` split by what the robot was doing when a cell's second pass
    /// began (see [`OVERLAP_CAUSES`]); sums to `overlap`.
    pub overlap_by: [f64; 7],
    /// Path length driven (m).
    pub path_length: f64,
    /// Number of heading changes above 30°.
    pub turns: usize,
    /// Total absolute rotation (rad).
    pub rotation: f64,
    /// Number of times the robot disk entered non-free ground truth.
    pub collisions: usize,
    /// Number of times the robot disk touched a person walking through the
    /// room (see [`crate::walker`]; 0 in a room nobody walks through).
    pub person_contacts: usize,
    /// Simulated time (s), up to the end of coverage (the drive back to
    /// the start not included).
    pub time: f64,
    /// Length of the drive back to the start (m; 0 without one): not in
    /// `path_length`, and sweeping nothing the other figures count.
    pub home_length: f64,
    /// Duration of the drive back to the start (s).
    pub home_time: f64,
}

/// Accumulates coverage over the executed poses of a run.
#[derive(Clone, Debug)]
pub struct CoverageTracker {
    raster: FreeRaster,
    reachable: Vec<bool>,
    footprint: Vec<bool>,
    clear: Vec<bool>,
    start_cell: (usize, usize),
    unreachable_cells: usize,
    passes: Vec<u16>,
    last_seen: Vec<f64>,
    /// Per cell: the task whose lane swept it first (`u32::MAX`: swept
    /// first by something else, or never).
    first_task: Vec<u32>,
    repeat_cause: Vec<u8>,
    repeats: [usize; 7],
    tool_radius: f64,
    tool: Vec<(i64, i64)>,
    robot_radius: f64,
    last: Option<Pose>,
    path_length: f64,
    rotation: f64,
    turns: usize,
    dir_anchor: Option<Point2<f64>>,
    last_dir: Option<f64>,
    colliding: bool,
    collisions: usize,
    touching_person: bool,
    person_contacts: usize,
    time: f64,
    /// When the drive back to the start began (s); `None` before.
    home_since: Option<f64>,
    home_length: f64,
    home_time: f64,
}

/// Cells whose centre lies at least `radius` from every non-free cell (the
/// obstacle taken as its full square) and inside the raster.
pub(crate) fn centre_free(raster: &FreeRaster, radius: f64) -> Vec<bool> {
    let (w, h, r) = (raster.width, raster.height, raster.resolution);
    let mut ok = raster.free.clone();
    let n = (radius / r).ceil() as i64 + 1;
    let is_free = |x: i64, y: i64| {
        x >= 0
            && y >= 0
            && (x as usize) < w
            && (y as usize) < h
            && raster.free[y as usize * w + x as usize]
    };
    for y in -1..=h as i64 {
        for x in -1..=w as i64 {
            if is_free(x, y) {
                continue;
            }
            let boundary =
                is_free(x + 1, y) || is_free(x - 1, y) || is_free(x, y + 1) || is_free(x, y - 1);
            if !boundary {
                continue;
            }
            for dy in -n..=n {
                for dx in -n..=n {
                    let (cx, cy) = (x + dx, y + dy);
                    if cx < 0 || cy < 0 || cx >= w as i64 || cy >= h as i64 {
                        continue;
                    }
                    // Distance from the free cell's centre to the obstacle square.
                    let gx = (dx.abs() as f64 - 0.5).max(0.0) * r;
                    let gy = (dy.abs() as f64 - 0.5).max(0.0) * r;
                    if (gx * gx + gy * gy).sqrt() < radius {
                        ok[cy as usize * w + cx as usize] = false;
                    }
                }
            }
        }
    }
    ok
}

/// Cells of `mask` 8-connected to `start` (empty when `start` is not in `mask`).
pub(crate) fn connected_from(
    mask: &[bool],
    w: usize,
    h: usize,
    start: (usize, usize),
) -> Vec<bool> {
    let mut out = vec![false; w * h];
    let s = start.1 * w + start.0;
    if start.0 >= w || start.1 >= h || !mask[s] {
        return out;
    }
    out[s] = true;
    let mut stack = vec![s];
    while let Some(i) = stack.pop() {
        for j in neighbours8_of(i, w, h) {
            if mask[j] && !out[j] {
                out[j] = true;
                stack.push(j);
            }
        }
    }
    out
}

/// `mask` dilated by the cell offsets `disk`, restricted to `within`.
fn dilate(mask: &[bool], w: usize, h: usize, disk: &[(i64, i64)], within: &[bool]) -> Vec<bool> {
    let mut out = vec![false; w * h];
    for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        for &(dx, dy) in disk {
            let (nx, ny) = (x + dx, y + dy);
            if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                let j = ny as usize * w + nx as usize;
                out[j] = within[j];
            }
        }
    }
    out
}

impl CoverageTracker {
    /// Sets up the ground truth for `world` and a robot of `robot_radius` with
    /// a round tool of diameter `tool_width`, starting at `start`.
    pub fn new(
        world: &World,
        robot_radius: f64,
        tool_width: f64,
        start: &Pose,
    ) -> Result<Self, MetricsError> {
        let raster = world.free.clone();
        let (w, h, res) = (raster.width, raster.height, raster.resolution);
        let p: Point2<f64> = start.translation.vector.into();
        let centre_ok = centre_free(&raster, robot_radius);
        let start_cell = raster
            .cell_of(&p)
            .filter(|&(x, y)| centre_ok[y * w + x] && world.disk_is_free(&p, robot_radius * 0.999));
        let Some(start_cell) = start_cell else {
            return Err(MetricsError::StartInCollision {
                x: p.x,
                y: p.y,
                radius: robot_radius,
            });
        };
        let reachable = connected_from(&centre_ok, w, h, start_cell);
        // One cell more than the tool: membership is decided on exact distance.
        let tool = disk(tool_width / 2.0 + res * 1.5, res);
        let body = disk(robot_radius, res);
        let footprint = dilate(&reachable, w, h, &disk(tool_width / 2.0, res), &raster.free);
        let touchable = dilate(&reachable, w, h, &body, &raster.free);
        let unreachable_cells = raster
            .free
            .iter()
            .zip(&touchable)
            .filter(|(&f, &t)| f && !t)
            .count();
        Ok(Self {
            passes: vec![0; w * h],
            last_seen: vec![f64::NEG_INFINITY; w * h],
            first_task: vec![u32::MAX; w * h],
            repeat_cause: vec![u8::MAX; w * h],
            repeats: [0; 7],
            clear: reachable.clone(),
            start_cell,
            raster,
            reachable,
            footprint,
            unreachable_cells,
            tool_radius: tool_width / 2.0,
            tool,
            robot_radius,
            last: None,
            path_length: 0.0,
            rotation: 0.0,
            turns: 0,
            dir_anchor: None,
            last_dir: None,
            colliding: false,
            collisions: 0,
            touching_person: false,
            person_contacts: 0,
            time: 0.0,
            home_since: None,
            home_length: 0.0,
            home_time: 0.0,
        })
    }

    /// Also reports coverage of the floor the robot centre reaches keeping
    /// `clearance` (m) more than its radius from every obstacle (the
    /// planner's `plan.safety_margin`), beside the strict figure.
    pub(crate) fn with_clearance(mut self, clearance: f64) -> Self {
        let (w, h) = (self.raster.width, self.raster.height);
        let ok = centre_free(&self.raster, self.robot_radius + clearance.max(0.0));
        self.clear = connected_from(&ok, w, h, self.start_cell);
        self
    }

    /// The ground truth raster the metrics are computed on.
    pub fn raster(&self) -> &FreeRaster {
        &self.raster
    }

    /// Per-cell pass counts (row-major, same geometry as [`Self::raster`]).
    pub fn passes(&self) -> &[u16] {
        &self.passes
    }

    /// Per-cell cause of the second pass (index into [`OVERLAP_CAUSES`];
    /// `u8::MAX`: swept at most once), row-major.
    pub fn repeat_causes(&self) -> &[u8] {
        &self.repeat_cause
    }

    /// Per-cell reachability (row-major).
    pub fn reachable(&self) -> &[bool] {
        &self.reachable
    }

    /// Records the robot at `pose` at simulated time `time` (s): sweeps the
    /// tool, adds path length and rotation, counts turns and collisions.
    pub fn record(&mut self, pose: &Pose, time: f64) {
        self.record_doing(pose, time, Motion::Other, 0);
    }

    /// [`Self::record`], knowing what the robot was doing (`motion`, as part
    /// of the planner's task number `task`), for the overlap breakdown.
    ///
    /// From the first [`Motion::Home`] on, the robot is on its way back to
    /// the start with coverage done: what it drives is counted apart
    /// (`home_length`, `home_time`), it sweeps nothing, and only its
    /// collisions still count.
    pub(crate) fn record_doing(&mut self, pose: &Pose, time: f64, motion: Motion, task: u32) {
        let p: Point2<f64> = pose.translation.vector.into();
        if motion == Motion::Home && self.home_since.is_none() {
            self.home_since = Some(self.time);
        }
        if let Some(t0) = self.home_since {
            if let Some(prev) = self.last {
                self.home_length += (p - Point2::from(prev.translation.vector)).norm();
            }
            self.last = Some(*pose);
            self.home_time = time - t0;
            self.check_collision(&p, time, motion);
            return;
        }
        let th = heading(pose);
        self.time = time;
        if let Some(prev) = self.last {
            let q: Point2<f64> = prev.translation.vector.into();
            self.path_length += (p - q).norm();
            self.rotation += wrap_angle(th - heading(&prev)).abs();
        }
        self.last = Some(*pose);
        match self.dir_anchor {
            None => self.dir_anchor = Some(p),
            Some(a) => {
                let d = p - a;
                if d.norm() >= TURN_SAMPLE {
                    let dir = d.y.atan2(d.x);
                    if let Some(prev) = self.last_dir {
                        if wrap_angle(dir - prev).abs() > TURN_ANGLE {
                            self.turns += 1;
                        }
                    }
                    self.last_dir = Some(dir);
                    self.dir_anchor = Some(p);
                }
            }
        }
        let (w, h, res) = (
            self.raster.width,
            self.raster.height,
            self.raster.resolution,
        );
        let fx = ((p.x - self.raster.origin.x) / res).floor();
        let fy = ((p.y - self.raster.origin.y) / res).floor();
        if !(fx.is_finite() && fy.is_finite()) {
            return;
        }
        let (cx, cy) = (fx as i64, fy as i64);
        let r2 = self.tool_radius * self.tool_radius;
        for &(dx, dy) in &self.tool {
            let (nx, ny) = (cx + dx, cy + dy);
            if nx < 0 || ny < 0 || nx as usize >= w || ny as usize >= h {
                continue;
            }
            let j = ny as usize * w + nx as usize;
            if !self.raster.free[j] {
                continue;
            }
            let c = self.raster.centre_of(nx as usize, ny as usize);
            if (c - p).norm_squared() > r2 {
                continue;
            }
            // (A never-seen cell has last_seen = -inf: always a new pass.)
            if time - self.last_seen[j] > SAME_PASS {
                self.passes[j] = self.passes[j].saturating_add(1);
                match self.passes[j] {
                    // The task of a first pass by a lane (`u32::MAX` otherwise).
                    1 => {
                        self.first_task[j] = match motion {
                            Motion::Lane | Motion::FixUp => task,
                            _ => u32::MAX,
                        }
                    }
                    2 => {
                        let cause = match motion {
                            Motion::Lane if self.first_task[j] == task => 0,
                            Motion::Lane => 1,
                            Motion::FixUp => 2,
                            Motion::Connection => 3,
                            Motion::Transit => 4,
                            Motion::Explore => 5,
                            Motion::Other | Motion::Home => 6,
                        };
                        self.repeats[cause] += 1;
                        self.repeat_cause[j] = cause as u8;
                    }
                    _ => {}
                }
            }
            self.last_seen[j] = time;
        }
        self.check_collision(&p, time, motion);
    }

    /// Counts a collision when the robot disk at `p` enters an obstacle.
    fn check_collision(&mut self, p: &Point2<f64>, time: f64, motion: Motion) {
        let hit = !self.disk_free(p);
        if begins(&mut self.colliding, hit, &mut self.collisions) {
            log::warn!(
                "collision: the robot disk entered an obstacle at ({:.3}, {:.3}) m, t = {time:.1} s, while on a {motion:?} motion",
                p.x,
                p.y
            );
        }
    }

    fn disk_free(&self, p: &Point2<f64>) -> bool {
        // Exact test against obstacle squares near p.
        let r = self.raster.resolution;
        let rad = self.robot_radius * 0.999;
        let n = (rad / r).ceil() as i64 + 1;
        let fx = ((p.x - self.raster.origin.x) / r).floor() as i64;
        let fy = ((p.y - self.raster.origin.y) / r).floor() as i64;
        for dy in -n..=n {
            for dx in -n..=n {
                let (x, y) = (fx + dx, fy + dy);
                let free = x >= 0
                    && y >= 0
                    && (x as usize) < self.raster.width
                    && (y as usize) < self.raster.height
                    && self.raster.free[y as usize * self.raster.width + x as usize];
                if free {
                    continue;
                }
                let x0 = self.raster.origin.x + x as f64 * r;
                let y0 = self.raster.origin.y + y as f64 * r;
                let qx = p.x.clamp(x0, x0 + r);
                let qy = p.y.clamp(y0, y0 + r);
                if (p.x - qx).powi(2) + (p.y - qy).powi(2) < rad * rad {
                    return false;
                }
            }
        }
        true
    }

    /// The figures so far.
    pub fn metrics(&self) -> CoverageMetrics {
        let a = self.raster.resolution * self.raster.resolution;
        let (mut reach, mut reach_cov, mut fp, mut fp_cov, mut cov, mut multi) = (0, 0, 0, 0, 0, 0);
        let (mut clear, mut clear_cov) = (0, 0);
        for i in 0..self.passes.len() {
            let c = self.passes[i] > 0;
            if self.reachable[i] {
                reach += 1;
                reach_cov += c as usize;
            }
            if self.footprint[i] {
                fp += 1;
                fp_cov += c as usize;
            }
            if self.clear[i] {
                clear += 1;
                clear_cov += c as usize;
            }
            cov += c as usize;
            multi += (self.passes[i] > 1) as usize;
        }
        let ratio = |n: usize, d: usize| if d == 0 { 0.0 } else { n as f64 / d as f64 };
        CoverageMetrics {
            coverage: ratio(reach_cov, reach),
            footprint_coverage: ratio(fp_cov, fp),
            reachable_area: reach as f64 * a,
            footprint_reachable_area: fp as f64 * a,
            clear_coverage: ratio(clear_cov, clear),
            clear_reachable_area: clear as f64 * a,
            free_area: self.raster.free_area(),
            unreachable_area: self.unreachable_cells as f64 * a,
            covered_area: cov as f64 * a,
            overlap: ratio(multi, cov),
            overlap_by: self.repeats.map(|n| ratio(n, cov)),
            path_length: self.path_length,
            turns: self.turns,
            rotation: self.rotation,
            collisions: self.collisions,
            person_contacts: self.person_contacts,
            time: self.time,
            home_length: self.home_length,
            home_time: self.home_time,
        }
    }

    /// Records whether the robot disk at `p` touches a person walking
    /// through the room at `time` (s); each new touch is a contact, logged.
    pub(crate) fn record_contact(&mut self, touching: bool, p: &Point2<f64>, time: f64) {
        if begins(
            &mut self.touching_person,
            touching,
            &mut self.person_contacts,
        ) {
            log::warn!(
                "contact: the robot disk touched a person walking by at ({:.3}, {:.3}) m, t = {time:.1} s",
                p.x,
                p.y
            );
        }
    }
}

/// Whether a touch begins now (`now`, and not `was` at the last record),
/// counted in `count`; `was` becomes `now`.
fn begins(was: &mut bool, now: bool, count: &mut usize) -> bool {
    let new = now && !*was;
    *was = now;
    *count += usize::from(new);
    new
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    const ROOM: &str = "room 0 0 4 0 4 3 0 3\nbox 1.5 1 2.5 2\nstart 0.5 0.5 0\n";

    #[test]
    fn one_straight_pass_covers_a_strip_once() {
        let w = World::parse(ROOM).unwrap();
        let mut t = CoverageTracker::new(&w, 0.17, 0.3, &w.start).unwrap();
        let mut x = 0.5;
        let mut time = 0.0;
        while x <= 3.5 {
            t.record(&pose(x, 0.5, 0.0), time);
            x += 0.01;
            time += 0.05;
        }
        let m = t.metrics();
        assert_eq!(m.collisions, 0);
        assert_eq!(m.turns, 0);
        assert!((m.path_length - 3.0).abs() < 0.02, "{}", m.path_length);
        // A 3 m stroke of a 0.3 m disk: 0.9 + π·0.15² ≈ 0.97 m².
        assert!((m.covered_area - 0.97).abs() < 0.05, "{}", m.covered_area);
        assert_eq!(m.overlap, 0.0);
        assert!(m.coverage > 0.05 && m.coverage < 0.2, "{}", m.coverage);
        // Only the slivers in the room's and the box's concave corners.
        assert!(m.unreachable_area < 0.06, "{}", m.unreachable_area);
    }

    #[test]
    fn the_drive_back_to_the_start_is_counted_apart_and_sweeps_nothing() {
        let w = World::parse(ROOM).unwrap();
        let mut t = CoverageTracker::new(&w, 0.17, 0.3, &w.start).unwrap();
        let mut k = 0.0;
        for i in 0..=100 {
            t.record_doing(&pose(0.5 + i as f64 * 0.01, 0.5, 0.0), k, Motion::Lane, 1);
            k += 0.1;
        }
        let before = t.metrics();
        // Back over the lane and on over unswept floor, then into the box.
        let back: Vec<Pose> = (0..=100)
            .map(|i| pose(1.5 - i as f64 * 0.01, 0.5, std::f64::consts::PI))
            .chain((1..=50).map(|i| pose(0.5, 0.5 + i as f64 * 0.01, 1.57)))
            .collect();
        for (i, p) in back.iter().enumerate() {
            // Turning at the end of the path is recorded as another motion:
            // still the drive back.
            let m = if i > 140 { Motion::Other } else { Motion::Home };
            t.record_doing(p, k, m, 2);
            k += 0.1;
        }
        let m = t.metrics();
        assert_eq!(m.covered_area, before.covered_area);
        assert_eq!(m.overlap, before.overlap);
        assert_eq!(m.path_length, before.path_length);
        assert_eq!(m.time, before.time);
        assert!((m.home_length - 1.5).abs() < 0.02, "{}", m.home_length);
        assert!((m.home_time - 15.1).abs() < 0.05, "{}", m.home_time);
        assert_eq!(m.collisions, 0);
        // Its collisions still count.
        t.record_doing(&pose(1.6, 1.5, 0.0), k, Motion::Home, 2);
        assert_eq!(t.metrics().collisions, 1);
    }

    #[test]
    fn driving_back_counts_overlap_and_a_turn() {
        let w = World::parse(ROOM).unwrap();
        let mut t = CoverageTracker::new(&w, 0.17, 0.3, &w.start).unwrap();
        let mut k = 0.0;
        for i in 0..=100 {
            t.record(&pose(0.5 + i as f64 * 0.01, 0.5, 0.0), k);
            k += 0.1;
        }
        for i in 0..=100 {
            t.record(&pose(1.5 - i as f64 * 0.01, 0.5, std::f64::consts::PI), k);
            k += 0.1;
        }
        let m = t.metrics();
        // All but the cells the tool never left while turning back at x = 1.5.
        assert!(m.overlap > 0.75 && m.overlap < 0.9, "{}", m.overlap);
        assert_eq!(m.turns, 1);
        assert!((m.rotation - std::f64::consts::PI).abs() < 1e-6);
        // Recorded without knowing what the robot did: all of it "other".
        assert_eq!(m.overlap_by[6], m.overlap);
    }

    #[test]
    fn the_overlap_breakdown_names_what_swept_again() {
        let w = World::parse(ROOM).unwrap();
        let mut t = CoverageTracker::new(&w, 0.17, 0.3, &w.start).unwrap();
        let mut k = 0.0;
        // A lane of task 1, then a transit of task 2 back over its first
        // half, then a lane of task 2 over its second half.
        for i in 0..=100 {
            t.record_doing(&pose(0.5 + i as f64 * 0.02, 0.5, 0.0), k, Motion::Lane, 1);
            k += 0.1;
        }
        k += 5.0;
        for i in 0..=50 {
            t.record_doing(
                &pose(0.5 + i as f64 * 0.02, 0.5, 0.0),
                k,
                Motion::Transit,
                2,
            );
            k += 0.1;
        }
        k += 5.0;
        for i in 50..=100 {
            t.record_doing(&pose(0.5 + i as f64 * 0.02, 0.5, 0.0), k, Motion::Lane, 2);
            k += 0.1;
        }
        let m = t.metrics();
        let sum: f64 = m.overlap_by.iter().sum();
        assert!((sum - m.overlap).abs() < 1e-12, "{sum} vs {}", m.overlap);
        // Both halves were swept again, the transit's half first.
        assert!(m.overlap > 0.9, "{}", m.overlap);
        assert!(
            m.overlap_by[4] > 0.4 && m.overlap_by[1] > 0.4,
            "{:?}",
            m.overlap_by
        );
        assert_eq!(m.overlap_by[0], 0.0);
        // A task's transit, then its own lane over it: not "its own lanes".
        k += 5.0;
        for i in 0..=50 {
            t.record_doing(
                &pose(0.5 + i as f64 * 0.02, 1.5, 0.0),
                k,
                Motion::Transit,
                3,
            );
            k += 0.1;
        }
        k += 5.0;
        for i in 0..=50 {
            t.record_doing(&pose(0.5 + i as f64 * 0.02, 1.5, 0.0), k, Motion::Lane, 3);
            k += 0.1;
        }
        let m2 = t.metrics();
        assert_eq!(m2.overlap_by[0], 0.0, "{:?}", m2.overlap_by);
        assert!(m2.overlap_by[1] > m.overlap_by[1]);
        let causes = t.repeat_causes();
        assert!(causes.contains(&4) && causes.contains(&1));
    }

    #[test]
    fn turning_in_place_sweeps_nothing_twice() {
        let w = World::parse(ROOM).unwrap();
        let mut t = CoverageTracker::new(&w, 0.17, 0.3, &w.start).unwrap();
        for k in 0..=200 {
            let th = k as f64 * std::f64::consts::TAU / 100.0;
            t.record(&pose(0.5, 0.5, th), k as f64 * 0.05);
        }
        let m = t.metrics();
        assert_eq!(m.overlap, 0.0);
        assert!((m.covered_area - 0.0707).abs() < 0.01, "{}", m.covered_area);
    }

    #[test]
    fn a_u_turn_between_lanes_one_spacing_apart_overlaps_only_a_seam() {
        // The planner's lane end: lane, turn in place, shift one spacing
        // (0.29 m for a 0.30 m tool), turn in place, lane back.
        let w = World::parse(ROOM).unwrap();
        let mut t = CoverageTracker::new(&w, 0.17, 0.3, &w.start).unwrap();
        let (y1, y2) = (0.5, 0.79);
        let mut k = 0.0;
        let mut rec = |t: &mut CoverageTracker, x: f64, y: f64, th: f64| {
            t.record(&pose(x, y, th), k);
            k += 0.05;
        };
        let half = std::f64::consts::FRAC_PI_2;
        for i in 0..=250 {
            rec(&mut t, 0.5 + i as f64 * 0.01, y1, 0.0);
        }
        for i in 0..=40 {
            rec(&mut t, 3.0, y1, half * i as f64 / 40.0);
        }
        for i in 0..=29 {
            rec(&mut t, 3.0, y1 + i as f64 * 0.01, half);
        }
        for i in 0..=40 {
            rec(&mut t, 3.0, y2, half + half * i as f64 / 40.0);
        }
        for i in 0..=250 {
            rec(&mut t, 3.0 - i as f64 * 0.01, y2, std::f64::consts::PI);
        }
        let m = t.metrics();
        // Two 2.5 m strips of 0.3 m plus the end caps: ~1.65 m²; swept twice
        // only the seam where the strips meet (about one 2 cm row) and the
        // rim of the turn.
        assert!((m.covered_area - 1.65).abs() < 0.1, "{}", m.covered_area);
        assert!(m.overlap > 0.0 && m.overlap < 0.03, "{}", m.overlap);
    }

    #[test]
    fn touching_the_box_is_a_collision() {
        let w = World::parse(ROOM).unwrap();
        let mut t = CoverageTracker::new(&w, 0.17, 0.3, &w.start).unwrap();
        t.record(&pose(1.2, 1.5, 0.0), 0.0);
        t.record(&pose(1.4, 1.5, 0.0), 0.1);
        t.record(&pose(1.45, 1.5, 0.0), 0.2);
        t.record(&pose(1.1, 1.5, 0.0), 0.3);
        t.record(&pose(1.4, 1.5, 0.0), 0.4);
        assert_eq!(t.metrics().collisions, 2);
    }

    #[test]
    fn start_in_an_obstacle_is_refused() {
        let w = World::parse(ROOM).unwrap();
        let e = CoverageTracker::new(&w, 0.17, 0.3, &pose(1.45, 1.5, 0.0)).unwrap_err();
        assert!(e.to_string().contains("overlaps"), "{e}");
        assert!(CoverageTracker::new(&w, 0.17, 0.3, &pose(0.1, 0.5, 0.0)).is_err());
    }

    #[test]
    fn a_closed_pocket_is_unreachable_not_missed() {
        // A walled-off 1 m x 1 m closet in the corner.
        let text = "room 0 0 4 0 4 3 0 3\nwall 3 0 3 1\nwall 3 1 4 1\nstart 0.5 0.5 0\n";
        let w = World::parse(text).unwrap();
        let t = CoverageTracker::new(&w, 0.17, 0.3, &w.start).unwrap();
        let m = t.metrics();
        assert!(
            (m.unreachable_area - 1.0).abs() < 0.1,
            "{}",
            m.unreachable_area
        );
        assert!(m.reachable_area < m.free_area - 1.0);
    }

    #[test]
    fn floor_behind_a_passage_tighter_than_the_clearance_is_told_apart() {
        // A wall splits the room at x = 2, leaving a 0.40 m passage at the
        // top: the body (0.34 m) fits, with 3 cm a side; 5 cm do not.
        let text = "room 0 0 4 0 4 3 0 3\nwall 2 0 2 2.6\nstart 0.5 0.5 0\n";
        let w = World::parse(text).unwrap();
        let mut t = CoverageTracker::new(&w, 0.17, 0.3, &w.start)
            .unwrap()
            .with_clearance(0.05);
        // Sweep the left half only.
        let mut time = 0.0;
        for row in 0..11 {
            let y = 0.2 + 0.26 * f64::from(row);
            for k in 0..=40 {
                let x = 0.2 + 1.6 * f64::from(k) / 40.0;
                time += 0.1;
                t.record(&pose(x, y, 0.0), time);
            }
        }
        let m = t.metrics();
        assert!(m.reachable_area > 8.0, "{}", m.reachable_area);
        assert!(
            m.clear_reachable_area < m.reachable_area * 0.6,
            "{} of {}",
            m.clear_reachable_area,
            m.reachable_area
        );
        assert!(m.coverage < 0.6, "{}", m.coverage);
        assert!(m.clear_coverage > 0.95, "{}", m.clear_coverage);
        // Without a clearance the two figures agree.
        let plain = CoverageTracker::new(&w, 0.17, 0.3, &w.start).unwrap();
        let p = plain.metrics();
        assert_eq!(p.clear_reachable_area, p.reachable_area);
    }
}
