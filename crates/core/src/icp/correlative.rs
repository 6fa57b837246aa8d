//! Correlative scan matching: finds the pose of a scan within a window
//! around a prior by scoring every candidate on a likelihood grid of the
//! reference, where iterative matching cannot (a prior more than a few
//! degrees or decimetres off leaves ICP in a wrong basin).
//!
//! The method is Olson's real-time correlative scan matcher (ICRA 2009) with
//! the branch and bound of Cartographer's fast matcher (Hess et al., ICRA
//! 2016): the reference is rasterised into a grid whose cells hold the
//! likelihood of a scan point falling there (a Gaussian of the distance to
//! the nearest reference point), and level `h` of a pyramid holds at each
//! cell the largest level-0 value of the `2^h × 2^h` block starting there.
//! A candidate offset at level `h` scored on that level bounds every finer
//! offset of its block from above, so the search descends depth first
//! through the best blocks and prunes every block that cannot beat the best
//! complete candidate: the result is the best pose of the full fine search
//! (within the heading and translation steps) at a small share of its cost.
//!
//! [`CorrelativeSearch`] keeps its buffers between calls: a search after the
//! first allocates nothing unless the grid or the scan is larger than ever
//! before.

use crate::geom::{pose, IPoint, Pose};
use crate::param_check::{invalid, ParamError};

/// Scan points a search uses at most (evenly thinned).
const MAX_POINTS: usize = 360;
/// Most cells of the likelihood grid (level 0); a larger reference is
/// clipped to the square around the prior that fits.
const MAX_CELLS: usize = 1 << 21;
/// Range (m) whose arc the heading step keeps within one cell; points
/// farther away move more per step, which the ICP that follows takes up.
const STEP_RANGE: f64 = 10.0;
/// Likelihood of a cell on a reference point.
const TOP: u8 = 255;

/// The `[icp.search]` table: when and how widely a failed match is searched
/// for (see [`CorrelativeSearch`]).
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SearchParams {
    /// Half-width of the translation window around the prior (m); 0 = never
    /// search (a failed match falls back to the prior, as without search).
    pub window: f64,
    /// Half-width of the heading window (rad).
    pub window_angle: f64,
    /// Cell of the likelihood grid and the finest translation step (m).
    pub resolution: f64,
    /// Coarser levels above the finest, each doubling the block (branch and
    /// bound); 0 = a plain exhaustive search.
    pub levels: u32,
    /// Standard deviation of the likelihood around a reference point (m).
    pub sigma: f64,
    /// Smallest mean likelihood (0..1) of a candidate worth handing to ICP.
    pub min_score: f64,
}

impl Default for SearchParams {
    fn default() -> Self {
        Self {
            window: 0.6,
            window_angle: 0.5,
            resolution: 0.05,
            levels: 4,
            sigma: 0.075,
            min_score: 0.3,
        }
    }
}

impl SearchParams {
    /// Checks the ranges; errors name the key (`icp.search.…`).
    pub fn validate(&self) -> Result<(), ParamError> {
        crate::check_keys!(
            self,
            "icp.search",
            positive: [resolution, sigma],
            non_negative: [window, window_angle],
        );
        if self.window_angle > std::f64::consts::PI {
            return Err(invalid("icp.search.window_angle", "must be at most π"));
        }
        if self.levels > 8 {
            return Err(invalid("icp.search.levels", "must be at most 8"));
        }
        if !(0.0..1.0).contains(&self.min_score) {
            return Err(invalid("icp.search.min_score", "must be in [0, 1)"));
        }
        let cells = (2.0 * self.window / self.resolution).ceil();
        if cells > 4096.0 {
            return Err(invalid(
                "icp.search.window",
                "spans more than 4096 cells of icp.search.resolution",
            ));
        }
        Ok(())
    }

    /// Whether failed matches are searched for at all.
    pub fn enabled(&self) -> bool {
        self.window > 0.0 || self.window_angle > 0.0
    }
}

/// The best pose a search found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SearchHit {
    /// The scanner pose (world frame).
    pub pose: Pose,
    /// Mean likelihood of the scan's points there, 0..=1.
    pub score: f64,
    /// Candidates scored (all levels): the search's cost.
    pub scored: usize,
}

/// One candidate offset: heading index, cell offset, pyramid level and its
/// score (sum of the points' likelihoods on that level).
#[derive(Clone, Copy, Debug)]
struct Candidate {
    score: u32,
    heading: u32,
    dx: i32,
    dy: i32,
    level: u32,
}

/// A correlative scan matcher with its reusable buffers.
#[derive(Debug, Default)]
pub struct CorrelativeSearch {
    /// Pyramid of likelihood grids, level 0 first, row-major.
    levels: Vec<Vec<u8>>,
    width: usize,
    height: usize,
    /// World coordinates of the lower-left corner of cell (0, 0).
    origin: [f64; 2],
    res: f64,
    /// The scan's thinned points (scanner frame).
    points: Vec<[f64; 2]>,
    /// Per heading, per point: the cell the point falls in at zero offset.
    cells: Vec<[i32; 2]>,
    kernel: Vec<(i32, i32, u8)>,
    candidates: Vec<Candidate>,
}

impl CorrelativeSearch {
    /// An empty searcher; buffers grow on first use.
    pub fn new() -> Self {
        Self::default()
    }

    /// Searches the window of `params` around `prior` for the scanner pose
    /// that lays `scan` (scanner frame) best onto `reference` (world frame).
    /// `None` when either is empty or no candidate reaches
    /// `params.min_score`.
    pub fn search(
        &mut self,
        reference: &[IPoint],
        scan: &[IPoint],
        prior: &Pose,
        params: &SearchParams,
    ) -> Option<SearchHit> {
        if reference.is_empty() || scan.is_empty() {
            return None;
        }
        let reach = self.take_points(scan);
        self.rasterise(reference, prior, params, reach + params.window);
        self.build_pyramid(params.levels);
        let step = heading_step(params.resolution, reach);
        let turns = (params.window_angle / step).ceil() as i32;
        self.rotate_points(prior, step, turns);
        let window = (params.window / params.resolution).ceil() as i32;
        let floor = (params.min_score * f64::from(TOP) * self.points.len() as f64) as u32;
        let (best, scored) = self.branch_and_bound(window, params.levels, floor);
        let best = best?;
        let theta = prior.rotation.angle() + f64::from(best.heading as i32 - turns) * step;
        let t = prior.translation.vector;
        Some(SearchHit {
            pose: pose(
                t.x + f64::from(best.dx) * self.res,
                t.y + f64::from(best.dy) * self.res,
                theta,
            ),
            score: f64::from(best.score) / (f64::from(TOP) * self.points.len() as f64),
            scored,
        })
    }

    /// Keeps up to [`MAX_POINTS`] of `scan`, evenly spread; returns the
    /// farthest range kept, clamped to 1..=[`STEP_RANGE`] m.
    fn take_points(&mut self, scan: &[IPoint]) -> f64 {
        let stride = scan.len().div_ceil(MAX_POINTS);
        self.points.clear();
        self.points
            .extend(scan.iter().step_by(stride).map(|p| [p.x, p.y]));
        let far = self
            .points
            .iter()
            .map(|p| p[0].hypot(p[1]))
            .fold(0.0, f64::max);
        far.clamp(1.0, STEP_RANGE)
    }

    /// Level 0: the likelihood of the reference points within `reach` (m) of
    /// the prior (plus the kernel), on a grid of `params.resolution`.
    fn rasterise(&mut self, reference: &[IPoint], prior: &Pose, params: &SearchParams, reach: f64) {
        let res = params.resolution;
        let radius = (3.0 * params.sigma / res).ceil() as i32;
        let margin = f64::from(radius + 1) * res;
        let c = prior.translation.vector;
        // Bounding box of the reference, within reach of the prior.
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for p in reference {
            lo = [lo[0].min(p.x), lo[1].min(p.y)];
            hi = [hi[0].max(p.x), hi[1].max(p.y)];
        }
        let side = (MAX_CELLS as f64).sqrt() * res / 2.0;
        let half = (reach + margin).min(side);
        // A coarse block starting left of (or below) the grid may still
        // reach into it; level h stores blocks by their lower corner, so
        // the low sides get 2^levels empty cells for the bound to hold.
        let pad = f64::from(1u32 << params.levels) * res;
        lo = [
            (lo[0] - margin).max(c.x - half) - pad,
            (lo[1] - margin).max(c.y - half) - pad,
        ];
        hi = [
            (hi[0] + margin).min(c.x + half),
            (hi[1] + margin).min(c.y + half),
        ];
        self.res = res;
        self.origin = lo;
        self.width = (((hi[0] - lo[0]) / res).ceil().max(1.0)) as usize;
        self.height = (((hi[1] - lo[1]) / res).ceil().max(1.0)) as usize;
        let n = self.width * self.height;
        self.kernel.clear();
        for dy in -radius..=radius {
            for dx in -radius..=radius {
                let d2 = f64::from(dx * dx + dy * dy) * res * res;
                let v =
                    (f64::from(TOP) * (-d2 / (2.0 * params.sigma * params.sigma)).exp()).round();
                if v >= 1.0 {
                    self.kernel.push((dx, dy, v as u8));
                }
            }
        }
        self.levels
            .resize_with(params.levels.max(1) as usize + 1, Vec::new);
        // Level 1 serves as scratch: which cells hold a reference point, so
        // that the kernel is stamped once per cell, not once per point.
        let [grid, scratch] = &mut self.levels[..2] else {
            unreachable!("at least two levels are kept")
        };
        reset(grid, n);
        reset(scratch, n);
        for p in reference {
            if let Some(i) = cell_index(self.origin, res, self.width, self.height, p.x, p.y) {
                scratch[i] = 1;
            }
        }
        let (w, h) = (self.width as i32, self.height as i32);
        for (i, _) in scratch.iter().enumerate().filter(|(_, &s)| s != 0) {
            let (x, y) = ((i % self.width) as i32, (i / self.width) as i32);
            for &(dx, dy, v) in &self.kernel {
                let (cx, cy) = (x + dx, y + dy);
                if cx >= 0 && cy >= 0 && cx < w && cy < h {
                    let cell = &mut grid[(cy * w + cx) as usize];
                    *cell = (*cell).max(v);
                }
            }
        }
    }

    /// Level `h` from level `h − 1`: the largest of the four blocks of half
    /// the size at the cell, right of it, above it and diagonally.
    fn build_pyramid(&mut self, levels: u32) {
        let (w, h) = (self.width, self.height);
        for level in 1..=levels as usize {
            let s = 1usize << (level - 1);
            let (below, above) = self.levels.split_at_mut(level);
            let (prev, next) = (&below[level - 1], &mut above[0]);
            reset(next, w * h);
            for y in 0..h {
                for x in 0..w {
                    let at = |xx: usize, yy: usize| {
                        if xx < w && yy < h {
                            prev[yy * w + xx]
                        } else {
                            0
                        }
                    };
                    next[y * w + x] = at(x, y)
                        .max(at(x + s, y))
                        .max(at(x, y + s))
                        .max(at(x + s, y + s));
                }
            }
        }
    }

    /// The cell of every point at every heading `prior + k·step`, k in
    /// `-turns..=turns`, before any translation offset.
    fn rotate_points(&mut self, prior: &Pose, step: f64, turns: i32) {
        self.cells.clear();
        let t = prior.translation.vector;
        for k in -turns..=turns {
            let (s, c) = (prior.rotation.angle() + f64::from(k) * step).sin_cos();
            for p in &self.points {
                let x = t.x + c * p[0] - s * p[1];
                let y = t.y + s * p[0] + c * p[1];
                self.cells.push([
                    ((x - self.origin[0]) / self.res).floor() as i32,
                    ((y - self.origin[1]) / self.res).floor() as i32,
                ]);
            }
        }
    }

    /// Sum of the points' values on `level` at heading `k`, offset (dx, dy).
    fn score(&self, level: u32, k: u32, dx: i32, dy: i32) -> u32 {
        let n = self.points.len();
        let grid = &self.levels[level as usize];
        let (w, h) = (self.width as i32, self.height as i32);
        self.cells[k as usize * n..(k as usize + 1) * n]
            .iter()
            .map(|c| {
                let (x, y) = (c[0] + dx, c[1] + dy);
                if x >= 0 && y >= 0 && x < w && y < h {
                    u32::from(grid[(y * w + x) as usize])
                } else {
                    0
                }
            })
            .sum()
    }

    /// Depth-first branch and bound over offsets in `-window..=window`
    /// cells and every heading: the best complete candidate above `floor`,
    /// and the number of candidates scored. Of equal scores the one met
    /// first wins, and the top level is ordered so that is the one nearest
    /// the prior.
    fn branch_and_bound(
        &mut self,
        window: i32,
        levels: u32,
        floor: u32,
    ) -> (Option<Candidate>, usize) {
        let headings = (self.cells.len() / self.points.len().max(1)) as u32;
        let turns = (headings / 2) as i32;
        let top = 1i32 << levels;
        self.candidates.clear();
        let mut scored = 0;
        for k in 0..headings {
            let mut dy = -window;
            while dy <= window {
                let mut dx = -window;
                while dx <= window {
                    let score = self.score(levels, k, dx, dy);
                    scored += 1;
                    if score > floor {
                        self.candidates.push(Candidate {
                            score,
                            heading: k,
                            dx,
                            dy,
                            level: levels,
                        });
                    }
                    dx += top;
                }
                dy += top;
            }
        }
        // Ascending, so that the best (then the nearest) is popped first.
        let near = |c: &Candidate| (c.heading as i32 - turns).abs() + c.dx.abs() + c.dy.abs();
        self.candidates
            .sort_unstable_by(|a, b| a.score.cmp(&b.score).then(near(b).cmp(&near(a))));
        let mut best: Option<Candidate> = None;
        let mut bar = floor;
        while let Some(c) = self.candidates.pop() {
            if c.score <= bar {
                continue;
            }
            if c.level == 0 {
                bar = c.score;
                best = Some(c);
                continue;
            }
            let half = 1i32 << (c.level - 1);
            let mut children = [None; 4];
            for (j, (ax, ay)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
                let (dx, dy) = (c.dx + ax * half, c.dy + ay * half);
                if dx > window || dy > window {
                    continue;
                }
                scored += 1;
                let score = self.score(c.level - 1, c.heading, dx, dy);
                if score > bar {
                    children[j] = Some(Candidate {
                        score,
                        heading: c.heading,
                        dx,
                        dy,
                        level: c.level - 1,
                    });
                }
            }
            let mut children: heapless::Vec<Candidate, 4> =
                children.into_iter().flatten().collect();
            children.sort_unstable_by(|a, b| a.score.cmp(&b.score).then(near(b).cmp(&near(a))));
            self.candidates.extend(children);
        }
        (best, scored)
    }
}

/// The heading step that moves a point at `range` (m) by at most one cell
/// of `res` (Olson's step; Cartographer's too).
fn heading_step(res: f64, range: f64) -> f64 {
    (1.0 - res * res / (2.0 * range * range)).acos()
}

/// `buf` resized to `n` cells, all 0 (keeps its capacity).
fn reset(buf: &mut Vec<u8>, n: usize) {
    buf.clear();
    buf.resize(n, 0);
}

fn cell_index(origin: [f64; 2], res: f64, w: usize, h: usize, x: f64, y: f64) -> Option<usize> {
    let cx = ((x - origin[0]) / res).floor();
    let cy = ((y - origin[1]) / res).floor();
    (cx >= 0.0 && cy >= 0.0 && (cx as usize) < w && (cy as usize) < h)
        .then(|| cy as usize * w + cx as usize)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::icp::synth::{cast_seeded, cast_world, l_room_with_pillar, polygon, Wall};

    fn scan_at(walls: &[Wall], at: &Pose) -> Vec<IPoint> {
        cast_seeded(walls, at, 7)
    }

    fn world(walls: &[Wall], at: &Pose) -> Vec<IPoint> {
        cast_world(walls, at, 3)
    }

    /// An L-shaped room with a pillar, so that no pose within the window
    /// looks like another.
    fn walls() -> Vec<Wall> {
        l_room_with_pillar()
    }

    #[test]
    fn a_prior_far_off_in_heading_and_place_is_found_to_a_cell() {
        let walls = walls();
        let truth = pose(3.0, 2.0, 0.4);
        let reference = world(&walls, &pose(2.7, 1.8, 0.2));
        let scan = scan_at(&walls, &truth);
        let prior = pose(2.6, 2.35, 0.4 + 0.3);
        let params = SearchParams::default();
        let mut s = CorrelativeSearch::new();
        let hit = s.search(&reference, &scan, &prior, &params).expect("found");
        let d = hit.pose.translation.vector - truth.translation.vector;
        let dth = (hit.pose.rotation.angle() - truth.rotation.angle()).abs();
        assert!(d.norm() < 0.05, "{hit:?}");
        assert!(dth < 0.01, "{hit:?}");
        assert!(hit.score > 0.6, "{hit:?}");
        // Branch and bound scores a small share of the exhaustive search.
        let exhaustive = SearchParams {
            levels: 0,
            ..params.clone()
        };
        let all = s
            .search(&reference, &scan, &prior, &exhaustive)
            .expect("found");
        assert_eq!(all.score, hit.score, "bounding loses nothing");
        assert!(
            hit.scored * 10 < all.scored,
            "{} vs {}",
            hit.scored,
            all.scored
        );
    }

    #[test]
    fn a_scan_of_another_place_finds_nothing_worth_matching() {
        let walls = walls();
        let reference = world(&walls, &pose(1.0, 1.0, 0.0));
        // Walls at 45° to the reference's: beyond the heading window.
        let other = polygon(&[(1.0, -0.5), (2.5, 1.0), (1.0, 2.5), (-0.5, 1.0)], 0.5);
        let scan = scan_at(&other, &pose(1.0, 1.0, 0.0));
        let params = SearchParams {
            min_score: 0.6,
            ..SearchParams::default()
        };
        let hit = CorrelativeSearch::new().search(&reference, &scan, &pose(1.0, 1.0, 0.0), &params);
        assert!(hit.is_none(), "{hit:?}");
        assert!(CorrelativeSearch::new()
            .search(&[], &scan, &pose(0.0, 0.0, 0.0), &params)
            .is_none());
    }

    /// The whole room and a full turn: scan points fall off the grid's
    /// sides at many candidates, where a coarse block starting outside
    /// must still bound the cells it reaches inside.
    #[test]
    fn a_search_over_the_whole_room_and_a_full_turn_finds_the_pose() {
        let walls = walls();
        let reference = crate::icp::synth::wall_points(&walls, 0.02);
        let truth = pose(1.2, 3.0, 3.695);
        let scan = scan_at(&walls, &truth);
        let whole = SearchParams {
            window: 4.0,
            window_angle: std::f64::consts::PI,
            levels: 6,
            ..SearchParams::default()
        };
        let mut s = CorrelativeSearch::new();
        let hit = s
            .search(&reference, &scan, &pose(4.7, 2.16, 1.95), &whole)
            .expect("found");
        let d = hit.pose.translation.vector - truth.translation.vector;
        assert!(d.norm() < 0.05, "{hit:?}");
        assert!(
            (hit.pose.rotation.angle() - truth.rotation.angle()).abs() < 0.01,
            "{hit:?}"
        );
        let at_truth = SearchParams {
            window: 0.0,
            window_angle: 0.0,
            ..whole.clone()
        };
        let there = s
            .search(&reference, &scan, &truth, &at_truth)
            .expect("fits");
        assert!(hit.score >= there.score - 0.01, "{hit:?} vs {there:?}");
        // Against the exhaustive search where the window hangs over the
        // grid's low corner.
        let edge = SearchParams {
            window: 0.6,
            window_angle: 0.1,
            levels: 3,
            ..SearchParams::default()
        };
        let exhaustive = SearchParams {
            levels: 0,
            ..edge.clone()
        };
        let prior = pose(0.4, 0.3, 3.9);
        let scan = scan_at(&walls, &pose(0.5, 0.5, 3.95));
        let a = s.search(&reference, &scan, &prior, &edge).expect("found");
        let b = s
            .search(&reference, &scan, &prior, &exhaustive)
            .expect("found");
        assert_eq!(a.score, b.score, "{a:?} vs {b:?}");
    }

    #[test]
    fn bad_values_name_their_key() {
        for (p, key) in [
            (
                SearchParams {
                    resolution: 0.0,
                    ..SearchParams::default()
                },
                "icp.search.resolution",
            ),
            (
                SearchParams {
                    levels: 9,
                    ..SearchParams::default()
                },
                "icp.search.levels",
            ),
            (
                SearchParams {
                    min_score: 1.0,
                    ..SearchParams::default()
                },
                "icp.search.min_score",
            ),
            (
                SearchParams {
                    window: 300.0,
                    ..SearchParams::default()
                },
                "icp.search.window",
            ),
        ] {
            let e = p.validate().unwrap_err();
            assert!(e.to_string().contains(key), "{e}");
        }
    }
}
