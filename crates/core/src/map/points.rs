//! The sparse point map and the paper's modified merging rule (its Fig. 3b).
//!
//! Points are stored in one contiguous `Vec<IPoint>` (what the matcher takes as
//! its reference) and indexed by a spatial hash: square cells of side d_th,
//! each the head of an intrusive chain through the points it holds. A
//! neighbour query looks at 3 × 3 cells: O(1) per query, so merging n scan
//! points into m stored ones costs O(n), not O(n·m).
//!
//! The merging rule, our reading of the paper: a scan point q whose nearest
//! stored point p is farther than d_th is new. Otherwise q is a duplicate when
//! the stored surface around p is dense on q's side, i.e. p has a stored
//! neighbour within d_th on the side of p where q lies along the surface
//! (the paper's "both neighbours within d_th" is the case where both sides are
//! covered, and then every q near p is a duplicate). Where p is the end of what
//! has been seen (an edge, a gap, the frontier of a first-seen surface) and q
//! extends the surface beyond p by at least `min_spacing`, q is kept.
//!
//! Allocation: inserting grows the point store and the hash table (amortised,
//! both reserved up front for `reserve_points`); queries never allocate.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use nalgebra::{Point2, Vector2};

use crate::geom::IPoint;

const NIL: u32 = u32::MAX;

/// A fast multiplicative hasher for packed cell keys (no DoS concern: keys
/// come from our own geometry).
#[derive(Default, Clone, Copy)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(5) ^ u64::from(b)).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
        }
    }
    fn write_u64(&mut self, k: u64) {
        let h = (self.0 ^ k).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        self.0 = h ^ (h >> 29);
    }
}

/// Counts of one merge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MergeCounts {
    /// Points added to the map.
    pub kept: usize,
    /// Points dropped as duplicates of the stored surface.
    pub duplicates: usize,
    /// Points dropped because they were closer than `min_spacing` to the
    /// previous point of the same scan.
    pub thinned: usize,
}

/// The sparse point map with its spatial index.
#[derive(Clone, Debug)]
pub struct PointMap {
    points: Vec<IPoint>,
    next: Vec<u32>,
    heads: HashMap<u64, u32, BuildHasherDefault<CellHasher>>,
    cell: f64,
}

impl PointMap {
    /// An empty map whose index cells are `cell` metres (use d_th), reserving
    /// room for `reserve` points.
    pub fn new(cell: f64, reserve: usize) -> Self {
        Self {
            points: Vec::with_capacity(reserve),
            next: Vec::with_capacity(reserve),
            heads: HashMap::with_capacity_and_hasher(reserve, Default::default()),
            cell,
        }
    }

    /// The stored points (the matcher's reference set), in insertion order.
    pub fn points(&self) -> &[IPoint] {
        &self.points
    }

    /// Points the store holds room for before it must grow.
    pub fn capacity(&self) -> usize {
        self.points.capacity()
    }

    /// Number of stored points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    fn key(&self, x: f64, y: f64) -> (i64, i64) {
        (
            (x / self.cell).floor() as i64,
            (y / self.cell).floor() as i64,
        )
    }

    fn pack(k: (i64, i64)) -> u64 {
        ((k.0 as i32 as u32 as u64) << 32) | (k.1 as i32 as u32 as u64)
    }

    /// Stores `p` (finite coordinates only; returns false and stores nothing otherwise).
    pub fn insert(&mut self, p: IPoint) -> bool {
        if !(p.x.is_finite() && p.y.is_finite() && p.intensity.is_finite()) {
            return false;
        }
        if self.points.len() >= NIL as usize {
            return false;
        }
        let idx = self.points.len() as u32;
        let k = Self::pack(self.key(p.x, p.y));
        let head = self.heads.entry(k).or_insert(NIL);
        self.next.push(*head);
        *head = idx;
        self.points.push(p);
        true
    }

    /// Calls `f(index, point)` for every stored point within `r` of `c`.
    pub(crate) fn for_each_within(
        &self,
        c: &Point2<f64>,
        r: f64,
        mut f: impl FnMut(usize, &IPoint),
    ) {
        if !(c.x.is_finite() && c.y.is_finite() && r.is_finite()) {
            return;
        }
        // Only the cells the query disc overlaps: at most 2 × 2 when r ≤ cell.
        let (kx0, ky0) = self.key(c.x - r, c.y - r);
        let (kx1, ky1) = self.key(c.x + r, c.y + r);
        let r2 = r * r;
        for ky in ky0..=ky1 {
            for kx in kx0..=kx1 {
                let Some(&head) = self.heads.get(&Self::pack((kx, ky))) else {
                    continue;
                };
                let mut i = head;
                while i != NIL {
                    let p = &self.points[i as usize];
                    if (p.x - c.x).powi(2) + (p.y - c.y).powi(2) <= r2 {
                        f(i as usize, p);
                    }
                    i = self.next[i as usize];
                }
            }
        }
    }

    /// The stored point nearest to `c` within `r`, with its distance.
    pub(crate) fn nearest_within(&self, c: &Point2<f64>, r: f64) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        self.for_each_within(c, r, |i, p| {
            let d2 = (p.x - c.x).powi(2) + (p.y - c.y).powi(2);
            if best.is_none_or(|(_, b)| d2 < b) {
                best = Some((i, d2));
            }
        });
        best.map(|(i, d2)| (i, d2.sqrt()))
    }

    /// The merging rule for one scan point `q` whose surface runs along the unit
    /// vector `tangent`: true when `q` is new information (see the module docs).
    pub(crate) fn is_new(
        &self,
        q: &IPoint,
        tangent: &Vector2<f64>,
        d_th: f64,
        min_spacing: f64,
    ) -> bool {
        let c = q.xy();
        let Some((pi, _)) = self.nearest_within(&c, d_th) else {
            return true;
        };
        let p = self.points[pi].xy();
        let s = (c - p).dot(tangent);
        if s.abs() < min_spacing {
            return false;
        }
        let side = s.signum();
        let mut covered = false;
        self.for_each_within(&p, d_th, |j, n| {
            if j != pi && (n.xy() - p).dot(tangent) * side >= min_spacing * 0.5 {
                covered = true;
            }
        });
        !covered
    }

    /// Merges one scan's points (world frame, beam order) into the map.
    /// `tangents[i]` is the surface direction at `pts[i]`. Every point is judged
    /// against the map as it was before this scan; `keep` is a reused buffer.
    pub fn merge(
        &mut self,
        pts: &[IPoint],
        tangents: &[Vector2<f64>],
        d_th: f64,
        min_spacing: f64,
        keep: &mut Vec<bool>,
    ) -> MergeCounts {
        let mut counts = MergeCounts::default();
        keep.clear();
        let mut last: Option<Point2<f64>> = None;
        for (q, t) in pts.iter().zip(tangents) {
            if let Some(l) = last {
                if (q.xy() - l).norm() < min_spacing {
                    counts.thinned += 1;
                    keep.push(false);
                    continue;
                }
            }
            last = Some(q.xy());
            let new = self.is_new(q, t, d_th, min_spacing);
            if !new {
                counts.duplicates += 1;
            }
            keep.push(new);
        }
        for (q, &k) in pts.iter().zip(keep.iter()) {
            if k && self.insert(*q) {
                counts.kept += 1;
            }
        }
        counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn wall(x0: f64, x1: f64, step: f64, y: f64) -> Vec<IPoint> {
        let n = ((x1 - x0) / step).round() as usize;
        (0..=n)
            .map(|i| IPoint::new(x0 + i as f64 * step, y, 0.5))
            .collect()
    }

    fn along_x(n: usize) -> Vec<Vector2<f64>> {
        vec![Vector2::new(1.0, 0.0); n]
    }

    #[test]
    fn neighbour_query_matches_brute_force() {
        let mut m = PointMap::new(0.05, 0);
        let mut rng = ChaCha8Rng::seed_from_u64(12345);
        let mut rnd = || rng.random::<f64>();
        for _ in 0..2000 {
            let (x, y) = (rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0);
            m.insert(IPoint::new(x, y, 0.1));
        }
        for _ in 0..200 {
            let c = Point2::new(rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0);
            let fast = m.nearest_within(&c, 0.05);
            let brute = m
                .points()
                .iter()
                .enumerate()
                .map(|(i, p)| (i, (p.xy() - c).norm()))
                .filter(|(_, d)| *d <= 0.05)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            assert_eq!(fast.map(|f| f.0), brute.map(|b| b.0));
            let mut n = 0;
            m.for_each_within(&c, 0.12, |_, _| n += 1);
            let bn = m
                .points()
                .iter()
                .filter(|p| (p.xy() - c).norm() <= 0.12)
                .count();
            assert_eq!(n, bn);
        }
    }

    #[test]
    fn dense_surface_drops_duplicates() {
        let mut m = PointMap::new(0.05, 0);
        let mut keep = Vec::new();
        let first = wall(0.0, 1.0, 0.02, 0.0);
        let c = m.merge(&first, &along_x(first.len()), 0.05, 0.01, &mut keep);
        assert_eq!(c.kept, first.len());
        // The same wall seen again, shifted by half a spacing and 5 mm off: all duplicates.
        let again: Vec<_> = wall(0.01, 0.99, 0.02, 0.005);
        let c = m.merge(&again, &along_x(again.len()), 0.05, 0.01, &mut keep);
        assert_eq!(c.kept, 0, "{c:?}");
        assert_eq!(m.len(), first.len());
    }

    #[test]
    fn edge_and_gap_keep_new_points() {
        let mut m = PointMap::new(0.05, 0);
        let mut keep = Vec::new();
        let first = wall(0.0, 1.0, 0.02, 0.0);
        m.merge(&first, &along_x(first.len()), 0.05, 0.01, &mut keep);
        // Extending the wall past its end: points beyond x = 1 are kept, those
        // over the seen part are not.
        let more = wall(0.9, 1.3, 0.02, 0.0);
        let c = m.merge(&more, &along_x(more.len()), 0.05, 0.01, &mut keep);
        assert_eq!(c.kept, 15, "{c:?}");
        for (q, k) in more.iter().zip(keep.iter()) {
            assert_eq!(*k, q.x > 1.005, "{q:?}");
        }
        // A second wall with a 8 cm gap in the map: a point in the gap is new.
        let mut g = PointMap::new(0.05, 0);
        let left = wall(0.0, 0.5, 0.02, 0.0);
        let right = wall(0.58, 1.0, 0.02, 0.0);
        g.merge(&left, &along_x(left.len()), 0.05, 0.01, &mut keep);
        g.merge(&right, &along_x(right.len()), 0.05, 0.01, &mut keep);
        let q = [IPoint::new(0.54, 0.0, 0.5)];
        let c = g.merge(&q, &along_x(1), 0.05, 0.01, &mut keep);
        assert_eq!(c.kept, 1);
    }

    #[test]
    fn non_finite_points_never_enter() {
        let mut m = PointMap::new(0.05, 0);
        assert!(!m.insert(IPoint::new(f64::NAN, 0.0, 0.0)));
        assert!(!m.insert(IPoint::new(0.0, f64::INFINITY, 0.0)));
        assert!(!m.insert(IPoint::new(0.0, 0.0, f64::NAN)));
        assert!(m.is_empty());
        assert!(m
            .nearest_within(&Point2::new(f64::NAN, 0.0), 0.05)
            .is_none());
    }

    #[test]
    fn in_scan_thinning() {
        let mut m = PointMap::new(0.05, 0);
        let mut keep = Vec::new();
        let dense = wall(0.0, 0.1, 0.002, 0.0);
        let c = m.merge(&dense, &along_x(dense.len()), 0.05, 0.01, &mut keep);
        assert_eq!(c.kept + c.thinned, dense.len());
        assert!(c.kept <= 11, "{c:?}");
    }
}
