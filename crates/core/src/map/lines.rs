//! Line features of one scan: breakpoint clustering (Borges & Aldon), then
//! split-and-merge on the ordered points, then a total-least-squares fit per
//! piece. Runs of short pieces that keep turning the same way become curves
//! (the paper's "curve feature": a polyline of at most 50 vertices = 100 values).
//! All buffers are reused: no allocation once warmed up.

use nalgebra::{Isometry2, Point2};

use super::fit::{LineFit, Moments};
use super::params::MapParams;
use crate::capacity::MAX_BEAMS;
use crate::geom::{IPoint, Segment};

/// Pieces with fewer points than this are "tiny": noise-spike leftovers.
const TINY_PIECE: usize = 4;
/// Least length of each piece of a curve (m): shorter ones are noise, not shape.
const MIN_CURVE_PIECE: f64 = 0.05;

/// Most vertices a curve keeps (2 values each: the paper's 100 values).
pub(crate) const MAX_CURVE_VERTICES: usize = 50;

/// A line feature of one scan, in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanLine {
    /// End points: the first and last point of the piece projected on the fit.
    pub seg: Segment,
    /// Moments of the piece's points (for merging into map segments).
    pub moments: Moments,
    /// The total-least-squares fit.
    pub fit: LineFit,
    /// Index of the first point of the piece in the scan's point list.
    pub first: usize,
    /// Index of the last point (inclusive).
    pub last: usize,
}

impl ScanLine {
    /// The same line moved by `t`.
    pub fn transformed(&self, t: &Isometry2<f64>) -> ScanLine {
        let moments = self.moments.transformed(t);
        let fit = LineFit {
            centre: t * self.fit.centre,
            dir: t.rotation * self.fit.dir,
            ..self.fit
        };
        ScanLine {
            seg: Segment::new(t * self.seg.a, t * self.seg.b),
            moments,
            fit,
            ..*self
        }
    }
}

/// A curved surface kept as a polyline (world frame).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Curve {
    /// The vertices in scan order.
    pub vertices: heapless::Vec<Point2<f64>, MAX_CURVE_VERTICES>,
}

impl Curve {
    /// Length of the polyline (m).
    pub fn length(&self) -> f64 {
        self.vertices.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
    }

    /// Distance from `p` to the polyline.
    pub fn distance_to(&self, p: &Point2<f64>) -> f64 {
        match self.vertices.len() {
            0 => f64::INFINITY,
            1 => (p - self.vertices[0]).norm(),
            _ => self
                .vertices
                .windows(2)
                .map(|w| Segment::new(w[0], w[1]).distance_to(p))
                .fold(f64::INFINITY, f64::min),
        }
    }

    /// The same curve moved by `t`.
    pub fn transformed(&self, t: &Isometry2<f64>) -> Curve {
        let mut c = Curve::default();
        for v in &self.vertices {
            // Same capacity as the source: never overflows.
            let _ = c.vertices.push(t * v);
        }
        c
    }
}

/// Points trimmed at each end of a piece for its first fit.
const END_TRIM: usize = 2;

/// Fits piece `[a, b]` on its interior (ends trimmed), then gives back the end
/// points that lie on that line: from each end, points are dropped until one
/// and its inward neighbour are within max(3σ, 3·rms) of the line. This keeps
/// the points of the next wall around a corner (where split points are
/// uncertain) out of the fit. Returns the new range, its moments and fit.
fn refine_ends(
    pts: &[IPoint],
    a: usize,
    b: usize,
    params: &MapParams,
) -> Option<(usize, usize, Moments, LineFit)> {
    let t = if b + 1 - a >= params.min_line_points + 2 * END_TRIM {
        END_TRIM
    } else {
        0
    };
    let inner = Moments::of(pts[a + t..=b - t].iter().map(xy)).fit(params.range_sigma)?;
    let gate = (3.0 * params.range_sigma).max(3.0 * inner.rms);
    let on = |i: usize| inner.offset(&xy(&pts[i])).abs() <= gate;
    let (mut a2, mut b2) = (a, b);
    while a2 + 1 < b2 && !(on(a2) && on(a2 + 1)) {
        a2 += 1;
    }
    while b2 > a2 + 1 && !(on(b2) && on(b2 - 1)) {
        b2 -= 1;
    }
    let m = Moments::of(pts[a2..=b2].iter().map(xy));
    let fit = m.fit(params.range_sigma)?;
    Some((a2, b2, m, fit))
}

/// Largest radius a curve may have (m): flatter runs are walls seen noisily.
const MAX_CURVE_RADIUS: f64 = 3.0;
/// Least angle a curve must sweep around its centre (rad).
const MIN_CURVE_SWEEP: f64 = 0.5;

/// Whether `pts` lie on a circular arc: algebraic (Kåsa) circle fit with
/// radius at most [`MAX_CURVE_RADIUS`], RMS residual at most half the split
/// distance, sweeping at least [`MIN_CURVE_SWEEP`]. Rejects noisy straight
/// walls and rounded-looking corners that a chain of small turns may suggest.
fn is_arc(pts: &[IPoint], params: &MapParams) -> bool {
    if pts.len() < 5 {
        return false;
    }
    // Centre the data for conditioning.
    let n = pts.len() as f64;
    let c = pts
        .iter()
        .map(|p| xy(p).coords)
        .sum::<nalgebra::Vector2<f64>>()
        / n;
    let mut a = nalgebra::Matrix3::<f64>::zeros();
    let mut b = nalgebra::Vector3::<f64>::zeros();
    for p in pts {
        let (x, y) = (p.x - c.x, p.y - c.y);
        let row = nalgebra::Vector3::new(x, y, 1.0);
        a += row * row.transpose();
        b -= row * (x * x + y * y);
    }
    let Some(sol) = a.lu().solve(&b) else {
        return false;
    };
    let centre = nalgebra::Vector2::new(-sol.x / 2.0, -sol.y / 2.0);
    let r2 = centre.norm_squared() - sol.z;
    if !(r2.is_finite() && r2 > 0.0) {
        return false;
    }
    let r = r2.sqrt();
    if r > MAX_CURVE_RADIUS {
        return false;
    }
    let mut sq = 0.0;
    for p in pts {
        let d = (nalgebra::Vector2::new(p.x - c.x, p.y - c.y) - centre).norm() - r;
        sq += d * d;
    }
    let rms = (sq / n).sqrt();
    let (u, v) = (
        nalgebra::Vector2::new(pts[0].x - c.x, pts[0].y - c.y) - centre,
        nalgebra::Vector2::new(pts[pts.len() - 1].x - c.x, pts[pts.len() - 1].y - c.y) - centre,
    );
    let sweep = u.perp(&v).atan2(u.dot(&v)).abs();
    rms <= params.split_distance / 2.0 && sweep >= MIN_CURVE_SWEEP
}

/// Splits ordered scan points into line features and curves, reusing its buffers.
#[derive(Debug)]
pub struct LineExtractor {
    clusters: Vec<(usize, usize)>,
    stack: Vec<(usize, usize)>,
    pieces: Vec<(usize, usize)>,
    merged: Vec<(usize, usize)>,
    curve_flags: Vec<bool>,
    bounds: Vec<(usize, usize)>,
}

impl Default for LineExtractor {
    fn default() -> Self {
        Self::new()
    }
}

fn xy(p: &IPoint) -> Point2<f64> {
    Point2::new(p.x, p.y)
}

/// Perpendicular distance of `p` from the infinite line through `a` and `b`
/// (distance to `a` when they coincide).
fn line_distance(a: &Point2<f64>, b: &Point2<f64>, p: &Point2<f64>) -> f64 {
    let d = b - a;
    let l = d.norm();
    if l < 1e-12 {
        return (p - a).norm();
    }
    ((p - a).perp(&d) / l).abs()
}

impl LineExtractor {
    /// An extractor with buffers sized for the largest scan.
    pub fn new() -> Self {
        Self {
            clusters: Vec::with_capacity(MAX_BEAMS),
            stack: Vec::with_capacity(MAX_BEAMS),
            pieces: Vec::with_capacity(MAX_BEAMS),
            merged: Vec::with_capacity(MAX_BEAMS),
            curve_flags: Vec::with_capacity(MAX_BEAMS),
            bounds: Vec::with_capacity(MAX_BEAMS),
        }
    }

    /// Clusters (first, last inclusive) found by the last `extract`.
    pub fn clusters(&self) -> &[(usize, usize)] {
        &self.clusters
    }

    /// Extracts line features and curves from `pts`, points of one scan in beam
    /// order seen from `origin` (same frame). Clears and fills `lines` and `curves`.
    pub(crate) fn extract(
        &mut self,
        pts: &[IPoint],
        origin: &Point2<f64>,
        params: &MapParams,
        lines: &mut Vec<ScanLine>,
        curves: &mut Vec<Curve>,
    ) {
        lines.clear();
        curves.clear();
        self.cluster(pts, origin, params);
        self.pieces.clear();
        for ci in 0..self.clusters.len() {
            let (a, b) = self.clusters[ci];
            self.split(pts, a, b, params);
        }
        self.merge_collinear(pts, params);
        self.mark_curves(pts, params, curves);
        self.settle_corners(pts, params);
        for (k, &(a, b)) in self.bounds.iter().enumerate() {
            if self.curve_flags[k] || b + 1 - a < params.min_line_points {
                continue;
            }
            let Some((a, b, m, fit)) = refine_ends(pts, a, b, params) else {
                continue;
            };
            let (s0, s1) = (fit.along(&xy(&pts[a])), fit.along(&xy(&pts[b])));
            if b + 1 - a < params.min_line_points
                || (s1 - s0).abs() < params.min_line_length
                || fit.rms > params.split_distance
            {
                continue;
            }
            lines.push(ScanLine {
                seg: Segment::new(fit.at(s0), fit.at(s1)),
                moments: m,
                fit,
                first: a,
                last: b,
            });
        }
    }

    /// At each joint between two line pieces (a corner), hands the points near
    /// the joint to whichever piece's line is nearer, so neither fit is tilted
    /// by points of the other wall. Fills `bounds` from `merged`.
    fn settle_corners(&mut self, pts: &[IPoint], params: &MapParams) {
        const WINDOW: usize = 8;
        self.bounds.clear();
        self.bounds.extend_from_slice(&self.merged);
        let interior_fit = |(a, b): (usize, usize)| {
            if b + 1 < a + params.min_line_points {
                return None;
            }
            let t = if b + 1 - a >= params.min_line_points + 2 * END_TRIM {
                END_TRIM
            } else {
                0
            };
            Moments::of(pts[a + t..=b - t].iter().map(xy)).fit(params.range_sigma)
        };
        for j in 1..self.merged.len() {
            let (p, q) = (self.merged[j - 1], self.merged[j]);
            if p.1 != q.0 || self.curve_flags[j - 1] || self.curve_flags[j] {
                continue;
            }
            let (Some(fp), Some(fq)) = (interior_fit(p), interior_fit(q)) else {
                continue;
            };
            let joint = q.0;
            let lo = p.0.max(joint.saturating_sub(WINDOW)) + 1;
            let hi = q.1.min(joint + WINDOW) - 1;
            let nearer_p = |i: usize| {
                let c = xy(&pts[i]);
                fp.offset(&c).abs() <= fq.offset(&c).abs()
            };
            let end_p = (lo..=hi).rev().find(|&i| nearer_p(i)).unwrap_or(lo);
            let start_q = (lo..=hi).find(|&i| !nearer_p(i)).unwrap_or(hi);
            self.bounds[j - 1].1 = end_p.max(self.bounds[j - 1].0);
            self.bounds[j].0 = start_q.min(self.bounds[j].1);
        }
    }

    /// Breakpoint detection: a new cluster starts where the gap between
    /// consecutive points exceeds r·sin Δφ / sin(λ − Δφ) + 3σ (Borges &
    /// Aldon), or where beams are missing between them (Δφ more than 2.5 times
    /// the scan's smallest step): a dropout is a discontinuity, and the
    /// formula would allow huge gaps across it.
    fn cluster(&mut self, pts: &[IPoint], origin: &Point2<f64>, params: &MapParams) {
        self.clusters.clear();
        if pts.is_empty() {
            return;
        }
        // sin and cos of the angle between consecutive beams, from cross and
        // dot products (no trigonometry in this loop).
        let sc_of = |i: usize| {
            let (vp, vq) = (xy(&pts[i - 1]) - origin, xy(&pts[i]) - origin);
            let n = vp.norm() * vq.norm();
            if n <= 1e-12 {
                (0.0, 1.0)
            } else {
                ((vp.perp(&vq) / n).abs(), vp.dot(&vq) / n)
            }
        };
        let step = (1..pts.len())
            .map(sc_of)
            .filter(|(s, c)| *s > 1e-6 && *c > 0.0)
            .fold(f64::INFINITY, |m, (s, _)| m.min(s));
        let (sin_l, cos_l) = params.breakpoint_angle.sin_cos();
        let mut start = 0;
        for i in 1..pts.len() {
            let (p, q) = (xy(&pts[i - 1]), xy(&pts[i]));
            let r = (p - origin).norm().min((q - origin).norm());
            let (sd, cd) = sc_of(i);
            // sin(λ − Δφ) = sin λ cos Δφ − cos λ sin Δφ; positive iff Δφ < λ.
            let denom = sin_l * cd - cos_l * sd;
            let limit = if cd > 0.0 && denom > 0.0 && sd <= 2.5 * step {
                r * sd / denom + 3.0 * params.range_sigma
            } else {
                0.0
            };
            if (q - p).norm() > limit {
                self.clusters.push((start, i - 1));
                start = i;
            }
        }
        self.clusters.push((start, pts.len() - 1));
    }

    /// Iterative split of cluster `[a, b]`: a piece whose points stray more
    /// than `threshold` from their total-least-squares line is split at the
    /// point farthest from its chord (the chord's ends are averages of the
    /// first and last three points, so one noisy end point does not tilt it).
    /// Pieces come out in order and share their split points.
    fn split(&mut self, pts: &[IPoint], a: usize, b: usize, params: &MapParams) {
        let threshold = params.split_distance;
        self.stack.clear();
        self.stack.push((a, b));
        while let Some((a, b)) = self.stack.pop() {
            if b < a + 2 {
                self.pieces.push((a, b));
                continue;
            }
            let straight = Moments::of(pts[a..=b].iter().map(xy))
                .fit(params.range_sigma)
                .is_some_and(|f| {
                    pts[a..=b]
                        .iter()
                        .all(|p| f.offset(&xy(p)).abs() <= threshold)
                });
            if straight {
                self.pieces.push((a, b));
                continue;
            }
            let k = 3.min((b - a) / 2).max(1);
            let avg = |r: std::ops::Range<usize>| {
                let n = r.len() as f64;
                Point2::from(
                    pts[r]
                        .iter()
                        .map(|p| xy(p).coords)
                        .sum::<nalgebra::Vector2<f64>>()
                        / n,
                )
            };
            let (pa, pb) = (avg(a..a + k), avg(b + 1 - k..b + 1));
            let mut best = (a + 1, -1.0);
            for (i, p) in pts.iter().enumerate().take(b).skip(a + 1) {
                let d = line_distance(&pa, &pb, &xy(p));
                if d > best.1 {
                    best = (i, d);
                }
            }
            self.stack.push((best.0, b));
            self.stack.push((a, best.0));
        }
    }

    /// Joins consecutive pieces (sharing an end point) whose fits agree in
    /// direction and lie on each other's line. Tiny pieces (fewer than
    /// [`TINY_PIECE`] points, left by noise spikes next to a split point) join
    /// a neighbour when all their points lie within `split_distance` of its line.
    fn merge_collinear(&mut self, pts: &[IPoint], params: &MapParams) {
        self.merged.clear();
        let fit_of = |a: usize, b: usize| {
            if b < a + 2 {
                return None;
            }
            Moments::of(pts[a..=b].iter().map(xy)).fit(params.range_sigma)
        };
        let near_line = |f: &LineFit, a: usize, b: usize| {
            pts[a..=b]
                .iter()
                .all(|p| f.offset(&xy(p)).abs() <= params.split_distance)
        };
        for &(a, b) in &self.pieces {
            if let Some(last) = self.merged.last_mut() {
                if last.1 == a {
                    let last_tiny = last.1 + 1 - last.0 < TINY_PIECE;
                    let tiny = b + 1 - a < TINY_PIECE;
                    match (fit_of(last.0, last.1), fit_of(a, b)) {
                        (Some(f0), _) if tiny && !last_tiny && near_line(&f0, a, b) => {
                            last.1 = b;
                            continue;
                        }
                        (_, Some(f1)) if last_tiny && !tiny && near_line(&f1, last.0, last.1) => {
                            last.1 = b;
                            continue;
                        }
                        (Some(f0), Some(f1)) => {
                            let sin = super::fit::undirected_sin(&f0.dir, &f1.dir);
                            if sin < params.collinear_angle.sin()
                                && f0.offset(&f1.centre).abs() < params.split_distance
                                && f1.offset(&f0.centre).abs() < params.split_distance
                            {
                                last.1 = b;
                                continue;
                            }
                        }
                        _ => {}
                    }
                }
            }
            self.merged.push((a, b));
        }
    }

    /// Flags runs of ≥ 3 consecutive pieces turning the same way by between
    /// `curve_min_turn` and `curve_max_turn` at each joint, and emits each run as a curve.
    fn mark_curves(&mut self, pts: &[IPoint], params: &MapParams, curves: &mut Vec<Curve>) {
        let n = self.merged.len();
        self.curve_flags.clear();
        self.curve_flags.resize(n, false);
        let merged = &self.merged;
        // Turn at the joint before piece `k` (k ≥ 1), when the pieces touch and
        // the turn is within the curve band.
        let curvy = |k: usize| -> Option<f64> {
            let (p, q) = (merged[k - 1], merged[k]);
            if p.1 != q.0
                || p.1 + 1 - p.0 < TINY_PIECE
                || q.1 + 1 - q.0 < TINY_PIECE
                || (xy(&pts[p.1]) - xy(&pts[p.0])).norm() < MIN_CURVE_PIECE
                || (xy(&pts[q.1]) - xy(&pts[q.0])).norm() < MIN_CURVE_PIECE
            {
                return None;
            }
            let u = xy(&pts[p.1]) - xy(&pts[p.0]);
            let v = xy(&pts[q.1]) - xy(&pts[q.0]);
            let turn = u.perp(&v).atan2(u.dot(&v));
            (params.curve_min_turn..=params.curve_max_turn)
                .contains(&turn.abs())
                .then_some(turn.signum())
        };
        let mut j = 0;
        while j < n {
            let mut e = j + 1;
            let mut sign = 0.0;
            while e < n {
                match curvy(e) {
                    Some(s) if sign == 0.0 || s == sign => {
                        sign = s;
                        e += 1;
                    }
                    _ => break,
                }
            }
            if e - j >= 3 && is_arc(&pts[merged[j].0..=merged[e - 1].1], params) {
                for f in &mut self.curve_flags[j..e] {
                    *f = true;
                }
                curves.push(self.curve_of(pts, j, e));
                j = e;
            } else {
                j += 1;
            }
        }
    }

    /// The polyline through pieces `from..to` of `merged`, decimated to
    /// [`MAX_CURVE_VERTICES`].
    fn curve_of(&self, pts: &[IPoint], from: usize, to: usize) -> Curve {
        let (a, b) = (self.merged[from].0, self.merged[to - 1].1);
        let count = b + 1 - a;
        let step = count.div_ceil(MAX_CURVE_VERTICES - 1).max(1);
        let mut c = Curve::default();
        let mut i = a;
        while i < b && c.vertices.len() < MAX_CURVE_VERTICES - 1 {
            let _ = c.vertices.push(xy(&pts[i]));
            i += step;
        }
        let _ = c.vertices.push(xy(&pts[b]));
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::icp::synth::{self, Wall};
    use rand::{Rng, SeedableRng};

    /// A 682-beam URG-like scan of `world` from `origin` (heading 0), with
    /// Gaussian range noise `sigma`, as world-frame points.
    fn scan(world: &[Wall], origin: Point2<f64>, sigma: f64, seed: u64) -> Vec<IPoint> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (44..=725)
            .filter_map(|k| {
                let a = (k - 384) as f64 * std::f64::consts::TAU / 1024.0;
                let range = synth::ray(world, &origin, a, 5.6)?;
                let u1: f64 = rng.random::<f64>().max(1e-300);
                let u2: f64 = rng.random();
                let n = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                let r = range + sigma * n;
                Some(IPoint::new(
                    origin.x + r * a.cos(),
                    origin.y + r * a.sin(),
                    0.5,
                ))
            })
            .collect()
    }

    fn run(pts: &[IPoint], origin: Point2<f64>) -> (Vec<ScanLine>, Vec<Curve>) {
        let mut ex = LineExtractor::new();
        let (mut l, mut c) = (Vec::new(), Vec::new());
        ex.extract(pts, &origin, &MapParams::default(), &mut l, &mut c);
        (l, c)
    }

    #[test]
    fn noisy_room_gives_its_walls_and_no_curves() {
        let w = synth::room(4.0, 3.0, 0.5);
        let o = Point2::new(1.5, 1.2);
        for seed in 0..5 {
            let (lines, curves) = run(&scan(&w, o, 0.01, seed), o);
            assert!(curves.is_empty(), "seed {seed}: {curves:?}");
            // Front (x = 4), top, bottom and the visible parts of the back wall.
            assert!(
                lines.len() >= 3 && lines.len() <= 5,
                "seed {seed}: {lines:?}"
            );
            for l in &lines {
                let a = l.fit.angle().to_degrees();
                let err = a.abs().min((a.abs() - 90.0).abs());
                assert!(err < 1.0, "seed {seed}: angle {a}");
            }
        }
    }

    #[test]
    fn a_pillar_is_a_curve() {
        let pillar: Vec<(f64, f64)> = (0..48)
            .map(|k| {
                let t = k as f64 * std::f64::consts::TAU / 48.0;
                (2.5 + 0.5 * t.cos(), 1.5 + 0.5 * t.sin())
            })
            .collect();
        let mut w = synth::room(5.0, 3.0, 0.5);
        w.extend(synth::polygon(&pillar, 0.5));
        let o = Point2::new(0.8, 1.5);
        let (lines, curves) = run(&scan(&w, o, 0.005, 3), o);
        assert_eq!(curves.len(), 1, "{curves:?}");
        let c = &curves[0];
        assert!(c.vertices.len() >= 5 && c.vertices.len() <= MAX_CURVE_VERTICES);
        for v in &c.vertices {
            let r = (v - Point2::new(2.5, 1.5)).norm();
            assert!((r - 0.5).abs() < 0.03, "vertex {v} at radius {r}");
        }
        for l in &lines {
            assert!(
                l.fit.centre.x < 1.9
                    || l.fit.centre.x > 3.1
                    || l.fit.centre.y < 0.9
                    || l.fit.centre.y > 2.1,
                "a line on the pillar: {l:?}"
            );
        }
    }

    #[test]
    fn empty_and_tiny_inputs_give_nothing() {
        let o = Point2::new(0.0, 0.0);
        assert_eq!(run(&[], o), (vec![], vec![]));
        let one = [IPoint::new(1.0, 0.0, 0.1)];
        assert_eq!(run(&one, o), (vec![], vec![]));
        let two = [IPoint::new(1.0, 0.0, 0.1), IPoint::new(1.0, 0.01, 0.1)];
        assert_eq!(run(&two, o), (vec![], vec![]));
    }
}
