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

/// Most vertices a curve keeps (2 values each: the paper's 100 values).
pub const MAX_CURVE_VERTICES: usize = 50;

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

/// Splits ordered scan points into line features and curves, reusing its buffers.
#[derive(Debug)]
pub struct LineExtractor {
    clusters: Vec<(usize, usize)>,
    stack: Vec<(usize, usize)>,
    pieces: Vec<(usize, usize)>,
    merged: Vec<(usize, usize)>,
    curve_flags: Vec<bool>,
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
        }
    }

    /// Clusters (first, last inclusive) found by the last [`extract`](Self::extract).
    pub fn clusters(&self) -> &[(usize, usize)] {
        &self.clusters
    }

    /// Extracts line features and curves from `pts`, points of one scan in beam
    /// order seen from `origin` (same frame). Clears and fills `lines` and `curves`.
    pub fn extract(
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
            self.split(pts, a, b, params.split_distance);
        }
        self.merge_collinear(pts, params);
        self.mark_curves(pts, params, curves);
        for (k, &(a, b)) in self.merged.iter().enumerate() {
            if self.curve_flags[k] || b + 1 - a < params.min_line_points {
                continue;
            }
            let m = Moments::of(pts[a..=b].iter().map(xy));
            let Some(fit) = m.fit(params.range_sigma) else {
                continue;
            };
            let (s0, s1) = (fit.along(&xy(&pts[a])), fit.along(&xy(&pts[b])));
            if (s1 - s0).abs() < params.min_line_length || fit.rms > params.split_distance {
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

    /// Breakpoint detection: a new cluster starts where the gap between
    /// consecutive points exceeds r·sin Δφ / sin(λ − Δφ) + 3σ.
    fn cluster(&mut self, pts: &[IPoint], origin: &Point2<f64>, params: &MapParams) {
        self.clusters.clear();
        if pts.is_empty() {
            return;
        }
        let mut start = 0;
        for i in 1..pts.len() {
            let (p, q) = (xy(&pts[i - 1]), xy(&pts[i]));
            let (vp, vq) = (p - origin, q - origin);
            let r = vp.norm().min(vq.norm());
            let dphi = vp.perp(&vq).atan2(vp.dot(&vq)).abs();
            let lambda = params.breakpoint_angle;
            let limit = if dphi < lambda {
                r * dphi.sin() / (lambda - dphi).sin() + 3.0 * params.range_sigma
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

    /// Iterative split of cluster `[a, b]` at the point farthest from the chord;
    /// pieces come out in order and share their split points.
    fn split(&mut self, pts: &[IPoint], a: usize, b: usize, threshold: f64) {
        self.stack.clear();
        self.stack.push((a, b));
        while let Some((a, b)) = self.stack.pop() {
            if b < a + 2 {
                self.pieces.push((a, b));
                continue;
            }
            let (pa, pb) = (xy(&pts[a]), xy(&pts[b]));
            let mut best = (a, 0.0);
            for (k, p) in pts.iter().enumerate().take(b).skip(a + 1) {
                let d = line_distance(&pa, &pb, &xy(p));
                if d > best.1 {
                    best = (k, d);
                }
            }
            if best.1 > threshold {
                self.stack.push((best.0, b));
                self.stack.push((a, best.0));
            } else {
                self.pieces.push((a, b));
            }
        }
    }

    /// Joins consecutive pieces (sharing an end point) whose fits agree in
    /// direction and lie on each other's line.
    fn merge_collinear(&mut self, pts: &[IPoint], params: &MapParams) {
        self.merged.clear();
        let fit_of = |a: usize, b: usize| {
            if b < a + 2 {
                return None;
            }
            Moments::of(pts[a..=b].iter().map(xy)).fit(params.range_sigma)
        };
        for &(a, b) in &self.pieces {
            if let Some(last) = self.merged.last_mut() {
                if last.1 == a {
                    if let (Some(f0), Some(f1)) = (fit_of(last.0, last.1), fit_of(a, b)) {
                        let dang = super::fit::undirected_diff(f1.angle(), f0.angle()).abs();
                        if dang < params.collinear_angle
                            && f0.offset(&f1.centre).abs() < params.split_distance
                            && f1.offset(&f0.centre).abs() < params.split_distance
                        {
                            last.1 = b;
                            continue;
                        }
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
            if p.1 != q.0 {
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
            if e - j >= 3 {
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
