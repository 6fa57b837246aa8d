//! Map line segments: scan line features merged into segments that grow as
//! more of a wall is seen, plus the curves. A map segment keeps the running
//! moments of every point that supported it (so its total-least-squares line
//! improves with each observation) and its extent along that line.

use nalgebra::Point2;

use nalgebra::Vector2;

use super::fit::{undirected_sin, LineFit, Moments};
use super::lines::{Curve, ScanLine};
use super::params::MapParams;
use crate::geom::Segment;

/// Weight (in points) above which a segment's moments are scaled down before
/// new data is added, so the line can still follow small drift.
const MAX_SEGMENT_WEIGHT: f64 = 4000.0;
/// Most curves the map keeps (oldest replaced first beyond this).
pub(crate) const MAX_CURVES: usize = 256;

/// One wall segment of the map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapSegment {
    /// End points (world frame, m): the extent seen, on the fitted line.
    pub seg: Segment,
    /// RMS distance of the supporting points to the line (m).
    pub residual: f64,
    /// Number of scans that contributed.
    pub(crate) observations: u32,
    /// Running moments of the supporting points.
    pub moments: Moments,
    /// The current line fit.
    pub fit: LineFit,
}

impl MapSegment {
    fn from_line(l: &ScanLine) -> MapSegment {
        MapSegment {
            seg: l.seg,
            residual: l.fit.rms,
            observations: 1,
            moments: l.moments,
            fit: l.fit,
        }
    }

    /// Length in metres.
    pub fn length(&self) -> f64 {
        self.seg.length()
    }

    /// Whether `other` (a line with end points `a`, `b`, unit direction `dir`
    /// known to angle variance `var_angle`) lies on this segment's line and
    /// touches or overlaps it. The angle tolerance widens to 3 σ of the two
    /// direction estimates for short, noisy lines. Cheap tests first, no
    /// trigonometry: this runs for every (line, segment) pair.
    #[allow(clippy::too_many_arguments)]
    fn accepts(
        &self,
        a: &Point2<f64>,
        b: &Point2<f64>,
        dir: &Vector2<f64>,
        var_angle: f64,
        angle_tol: f64,
        dist_tol: f64,
        gap_tol: f64,
    ) -> bool {
        if self.fit.offset(a).abs() > dist_tol || self.fit.offset(b).abs() > dist_tol {
            return false;
        }
        let (s0, s1) = ordered(self.fit.along(&self.seg.a), self.fit.along(&self.seg.b));
        let (t0, t1) = ordered(self.fit.along(a), self.fit.along(b));
        if t0 > s1 + gap_tol || t1 < s0 - gap_tol {
            return false;
        }
        let tol = angle_tol.max(3.0 * (var_angle + self.fit.var_angle).sqrt());
        tol >= std::f64::consts::FRAC_PI_2 || undirected_sin(dir, &self.fit.dir) <= tol.sin()
    }

    /// Absorbs the moments and extent of another observation of the same wall.
    fn absorb(&mut self, moments: &Moments, a: &Point2<f64>, b: &Point2<f64>, sigma: f64) {
        let old = if self.moments.n > MAX_SEGMENT_WEIGHT {
            self.moments.scaled(MAX_SEGMENT_WEIGHT / self.moments.n)
        } else {
            self.moments
        };
        let m = old.merged(moments);
        let Some(fit) = m.fit(sigma) else {
            return;
        };
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for p in [&self.seg.a, &self.seg.b, a, b] {
            let s = fit.along(p);
            lo = lo.min(s);
            hi = hi.max(s);
        }
        // Keep the orientation of the older segment.
        let (pa, pb) = (fit.at(lo), fit.at(hi));
        let forward = (pb - pa).dot(&(self.seg.b - self.seg.a)) >= 0.0;
        self.seg = if forward {
            Segment::new(pa, pb)
        } else {
            Segment::new(pb, pa)
        };
        self.moments = m;
        self.fit = fit;
        self.residual = fit.rms;
        self.observations = self.observations.saturating_add(1);
    }
}

fn ordered(a: f64, b: f64) -> (f64, f64) {
    if a <= b {
        (a, b)
    } else {
        (b, a)
    }
}

/// The segments and curves of the map.
#[derive(Clone, Debug, Default)]
pub struct SegmentMap {
    segments: Vec<MapSegment>,
    curves: Vec<Curve>,
    next_curve: usize,
}

impl SegmentMap {
    /// An empty map with room for `segments` segments and `MAX_CURVES` curves.
    pub fn with_capacity(segments: usize) -> Self {
        Self {
            segments: Vec::with_capacity(segments),
            curves: Vec::with_capacity(MAX_CURVES),
            next_curve: 0,
        }
    }

    /// Capacity of the segment list (snapshots reserve as much).
    pub fn capacity(&self) -> usize {
        self.segments.capacity()
    }

    /// The segments (raw extents, before corner snapping).
    pub fn segments(&self) -> &[MapSegment] {
        &self.segments
    }

    /// The curves.
    pub(crate) fn curves(&self) -> &[Curve] {
        &self.curves
    }

    /// The index of the map segment a scan line belongs to, if any: closest in
    /// perpendicular distance among those that accept it.
    pub fn find(&self, l: &ScanLine, angle_tol: f64, dist_tol: f64, gap_tol: f64) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for (i, s) in self.segments.iter().enumerate() {
            if s.accepts(
                &l.seg.a,
                &l.seg.b,
                &l.fit.dir,
                l.fit.var_angle,
                angle_tol,
                dist_tol,
                gap_tol,
            ) {
                let d = s.fit.offset(&l.fit.centre).abs();
                if best.is_none_or(|(_, bd)| d < bd) {
                    best = Some((i, d));
                }
            }
        }
        best.map(|b| b.0)
    }

    /// Merges one scan line: it grows the matching segment, or starts a new one.
    /// A grown segment that now reaches another one absorbs it.
    pub(crate) fn merge_line(&mut self, l: &ScanLine, p: &MapParams) {
        let (at, dt, gt) = (
            p.segment_merge_angle,
            p.segment_merge_distance,
            p.segment_merge_gap,
        );
        let Some(i) = self.find(l, at, dt, gt) else {
            self.segments.push(MapSegment::from_line(l));
            return;
        };
        self.segments[i].absorb(&l.moments, &l.seg.a, &l.seg.b, p.range_sigma);
        let mut i = i;
        let mut j = 0;
        while j < self.segments.len() {
            if j != i {
                let (s, o) = (&self.segments[i], &self.segments[j]);
                if s.accepts(&o.seg.a, &o.seg.b, &o.fit.dir, o.fit.var_angle, at, dt, gt) {
                    let o = self.segments.remove(j);
                    if j < i {
                        i -= 1;
                    }
                    let seen = o.observations;
                    let s = &mut self.segments[i];
                    s.absorb(&o.moments, &o.seg.a, &o.seg.b, p.range_sigma);
                    s.observations = s.observations.max(seen);
                    j = 0;
                    continue;
                }
            }
            j += 1;
        }
    }

    /// Adds a curve, replacing a stored curve it overlaps for most of its length
    /// when the new one is longer; beyond [`MAX_CURVES`] the oldest is replaced.
    pub(crate) fn merge_curve(&mut self, c: &Curve, tol: f64) {
        if c.vertices.len() < 2 {
            return;
        }
        for old in &mut self.curves {
            let near = c
                .vertices
                .iter()
                .filter(|v| old.distance_to(v) <= tol)
                .count();
            if near * 2 >= c.vertices.len() {
                if c.length() > old.length() {
                    *old = c.clone();
                }
                return;
            }
        }
        if self.curves.len() < MAX_CURVES {
            self.curves.push(c.clone());
        } else {
            let k = self.next_curve % MAX_CURVES;
            self.curves[k] = c.clone();
            self.next_curve = k + 1;
        }
    }

    /// The segments with end points snapped to corners: where an end lies within
    /// `tol` of the intersection with a clearly non-parallel segment (≥ 30°)
    /// whose own extent also reaches that point, the end moves to the
    /// intersection. Only settled segments are written, into `out` (cleared
    /// first): seen in at least `min_observations` scans, direction known to
    /// `max_angle_sigma` (1 σ, rad) or better. Candidates come from `index`
    /// (rebuilt here, buffers reused), so the cost is about linear in the
    /// number of segments.
    pub(crate) fn snapped_into(
        &self,
        tol: f64,
        min_observations: u32,
        max_angle_sigma: f64,
        index: &mut SnapIndex,
        out: &mut Vec<MapSegment>,
    ) {
        out.clear();
        let min_sin = 0.5; // sin 30°
        let settled = |s: &MapSegment| {
            s.observations >= min_observations && s.fit.var_angle.sqrt() <= max_angle_sigma
        };
        index.build(self.segments.iter().map(|s| (s, settled(s))), tol);
        for (si, s) in self.segments.iter().enumerate() {
            if !settled(s) {
                continue;
            }
            out.push(*s);
            let i = out.len() - 1;
            for end in 0..2 {
                let e = if end == 0 { s.seg.a } else { s.seg.b };
                let mut best: Option<(Point2<f64>, f64)> = None;
                index.for_each_near(&e, |oi| {
                    let o = &self.segments[oi];
                    if oi == si || undirected_sin(&o.fit.dir, &s.fit.dir) < min_sin {
                        return;
                    }
                    let Some(x) = intersect(&s.fit, &o.fit) else {
                        return;
                    };
                    let d = (x - e).norm();
                    if d > tol || o.seg.distance_to(&x) > tol {
                        return;
                    }
                    if best.is_none_or(|(_, bd)| d < bd) {
                        best = Some((x, d));
                    }
                });
                if let Some((x, _)) = best {
                    if end == 0 {
                        out[i].seg.a = x;
                    } else {
                        out[i].seg.b = x;
                    }
                }
            }
        }
    }
}

/// A reusable grid index over segments for corner snapping: sorted (cell,
/// segment) pairs, cells of side at least 4 × the snapping reach, each segment
/// entered at samples every half cell along it.
#[derive(Clone, Debug, Default)]
pub(crate) struct SnapIndex {
    entries: Vec<(u64, u32)>,
    cell: f64,
}

impl SnapIndex {
    fn key(&self, p: &Point2<f64>) -> (i64, i64) {
        (
            (p.x / self.cell).floor() as i64,
            (p.y / self.cell).floor() as i64,
        )
    }

    fn pack(k: (i64, i64)) -> u64 {
        ((k.0 as i32 as u32 as u64) << 32) | (k.1 as i32 as u32 as u64)
    }

    fn build<'a>(&mut self, segs: impl Iterator<Item = (&'a MapSegment, bool)>, tol: f64) {
        self.cell = (4.0 * tol).max(0.5);
        self.entries.clear();
        for (i, (s, keep)) in segs.enumerate() {
            if !keep || !(s.seg.a.coords.iter().chain(s.seg.b.coords.iter())).all(|v| v.is_finite())
            {
                continue;
            }
            let n = ((s.length() / (self.cell * 0.5)).ceil() as usize).max(1);
            for k in 0..=n {
                let p = s.seg.a + (s.seg.b - s.seg.a) * (k as f64 / n as f64);
                self.entries.push((Self::pack(self.key(&p)), i as u32));
            }
        }
        self.entries.sort_unstable();
        self.entries.dedup();
    }

    /// Calls `f(segment index)` for segments passing within about one cell of
    /// `p` (a segment may be reported more than once).
    fn for_each_near(&self, p: &Point2<f64>, mut f: impl FnMut(usize)) {
        if !(p.x.is_finite() && p.y.is_finite()) || self.cell <= 0.0 {
            return;
        }
        let (kx, ky) = self.key(p);
        for dy in -1..=1 {
            for dx in -1..=1 {
                let key = Self::pack((kx + dx, ky + dy));
                let from = self.entries.partition_point(|e| e.0 < key);
                for e in self.entries[from..].iter().take_while(|e| e.0 == key) {
                    f(e.1 as usize);
                }
            }
        }
    }
}

/// Intersection of two fitted lines, if not parallel.
fn intersect(a: &LineFit, b: &LineFit) -> Option<Point2<f64>> {
    let denom = a.dir.perp(&b.dir);
    if denom.abs() < 1e-9 {
        return None;
    }
    let t = (b.centre - a.centre).perp(&b.dir) / denom;
    Some(a.at(t))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::IPoint;
    use crate::map::lines::LineExtractor;

    fn line_from(pts: &[(f64, f64)]) -> ScanLine {
        let ip: Vec<IPoint> = pts.iter().map(|&(x, y)| IPoint::new(x, y, 0.5)).collect();
        let mut ex = LineExtractor::new();
        let (mut lines, mut curves) = (Vec::new(), Vec::new());
        ex.extract(
            &ip,
            &Point2::new(0.0, -1.0),
            &MapParams {
                breakpoint_angle: 1.5,
                ..Default::default()
            },
            &mut lines,
            &mut curves,
        );
        assert_eq!(lines.len(), 1, "{lines:?}");
        lines[0]
    }

    fn wall(x0: f64, x1: f64, y: f64) -> Vec<(f64, f64)> {
        let n = ((x1 - x0) / 0.02).round() as usize;
        (0..=n).map(|i| (x0 + i as f64 * 0.02, y)).collect()
    }

    #[test]
    fn segments_grow_and_join() {
        let p = MapParams::default();
        let mut m = SegmentMap::default();
        m.merge_line(&line_from(&wall(0.0, 1.0, 0.0)), &p);
        m.merge_line(&line_from(&wall(1.6, 2.4, 0.01)), &p);
        assert_eq!(m.segments().len(), 2);
        m.merge_line(&line_from(&wall(0.8, 1.66, 0.0)), &p);
        assert_eq!(m.segments().len(), 1, "{:?}", m.segments());
        let s = &m.segments()[0];
        assert!((s.length() - 2.4).abs() < 0.01, "{}", s.length());
        assert_eq!(s.observations, 3);
        // A parallel wall 20 cm away stays separate.
        m.merge_line(&line_from(&wall(0.0, 1.0, 0.2)), &p);
        assert_eq!(m.segments().len(), 2);
    }

    #[test]
    fn corners_snap_to_the_intersection() {
        let p = MapParams::default();
        let mut m = SegmentMap::default();
        m.merge_line(&line_from(&wall(0.0, 0.98, 0.0)), &p);
        let up: Vec<(f64, f64)> = (0..50).map(|i| (1.0, 0.03 + i as f64 * 0.02)).collect();
        m.merge_line(&line_from(&up), &p);
        let mut out = Vec::new();
        m.snapped_into(0.08, 1, 1.0, &mut SnapIndex::default(), &mut out);
        let corner = Point2::new(1.0, 0.0);
        let hits = out
            .iter()
            .flat_map(|s| [s.seg.a, s.seg.b])
            .filter(|e| (e - corner).norm() < 1e-6)
            .count();
        assert_eq!(hits, 2, "{out:?}");
    }
}
