//! The reference point set a scan is matched against ("the map"): points with
//! intensities, their surface normals, and a k-d tree over (x, y, √w·l), or
//! over (x, y) alone when the intensity weight w is zero.
//!
//! Building the tree allocates (kiddo's `ImmutableKdTree` owns its storage), so
//! a reference is rebuilt only when the reference changes (a new keyframe, a
//! new map snapshot); matching against it never allocates. A single scan can
//! instead be indexed by beam bearing ([`Reference::rebuild_scan`], the
//! "projection" search of Censi's CSM, exact here): no tree, so rebuilding it
//! every scan allocates nothing once its buffers have grown.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Matrix2, Vector2};

use super::{IcpError, IcpParams};
use crate::geom::{IPoint, Pose};

/// The k-d tree over the reference points. With no intensity weight the
/// third axis would be zero everywhere: a plane tree then spends no levels
/// splitting on it, which makes both its build and its queries cheaper.
enum Tree {
    /// Over (x, y): the intensity weight is zero.
    Plane(ImmutableKdTree<f64, 2>),
    /// Over (x, y, √w·l).
    WithIntensity(ImmutableKdTree<f64, 3>),
}

/// A reference point set prepared for matching.
pub struct Reference {
    points: Vec<IPoint>,
    normals: Vec<Vector2<f64>>,
    edges: Vec<EdgeFeature>,
    coords: Vec<[f64; 3]>,
    coords2: Vec<[f64; 2]>,
    tree: Option<Tree>,
    intensity_scale: f64,
    /// Bearing index of a single scan: sensor pose and the sorted bearing of
    /// every point in the sensor frame. Used instead of the tree when set.
    fan: Option<Pose>,
    bearings: Vec<f64>,
}

impl Default for Reference {
    fn default() -> Self {
        Self::new()
    }
}

impl std::fmt::Debug for Reference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reference")
            .field("points", &self.points.len())
            .field("intensity_scale", &self.intensity_scale)
            .finish()
    }
}

impl Reference {
    /// An empty reference; fill it with one of the `rebuild*` methods.
    pub fn new() -> Self {
        Self {
            points: Vec::new(),
            normals: Vec::new(),
            edges: Vec::new(),
            coords: Vec::new(),
            coords2: Vec::new(),
            tree: None,
            intensity_scale: 0.0,
            fan: None,
            bearings: Vec::new(),
        }
    }

    /// Rebuilds from an unordered point set (e.g. a map snapshot). Normals come
    /// from the `normal_neighbours` nearest points within `normal_radius`.
    /// Non-finite points are dropped.
    pub fn rebuild(&mut self, points: &[IPoint], params: &IcpParams) -> Result<(), IcpError> {
        self.copy_finite(points);
        self.check_size(params)?;
        self.normals.clear();
        let xy: Vec<[f64; 2]> = self.points.iter().map(|p| [p.x, p.y]).collect();
        let tree2: ImmutableKdTree<f64, 2> =
            ImmutableKdTree::new_from_slice(&xy).map_err(|_| IcpError::TooFewReferencePoints {
                have: xy.len(),
                need: params.min_pairs,
            })?;
        let k = std::num::NonZeroUsize::new(params.normal_neighbours.max(2))
            .unwrap_or(std::num::NonZeroUsize::MIN);
        let r2 = params.normal_radius * params.normal_radius;
        let mut nb: Vec<Vector2<f64>> = Vec::with_capacity(k.get());
        // Unordered points have no surface order to find intensity steps along.
        self.edges.clear();
        for p in &self.points {
            nb.clear();
            for n in tree2
                .query(&[p.x, p.y])
                .nearest_n::<SquaredEuclidean<f64>>(k)
                .execute()
            {
                if n.distance <= r2 {
                    let q = &self.points[n.item as usize];
                    nb.push(Vector2::new(q.x, q.y));
                }
            }
            self.normals.push(normal_of(&nb));
        }
        self.build_tree(params)
    }

    /// Rebuilds from points ordered along the surfaces (a scan in beam order,
    /// or several scans one after the other): normals from sequence neighbours
    /// within `normal_radius`. Cheaper than [`Reference::rebuild`].
    pub fn rebuild_ordered(
        &mut self,
        points: &[IPoint],
        params: &IcpParams,
    ) -> Result<(), IcpError> {
        self.copy_finite(points);
        self.check_size(params)?;
        self.normals.clear();
        self.edges.clear();
        let n = self.points.len();
        for i in 0..n {
            self.normals.push(ordered_normal(&self.points, i, params));
            if let Some(e) = edge_after(&self.points, i, params) {
                self.edges.push(e);
            }
        }
        self.build_tree(params)
    }

    /// Rebuilds from points with their normals (zero vector = unknown) and
    /// intensity-edge flags already known (`edges[i]`: an intensity step lies
    /// between point `i` and point `i + 1` of the same surface, see
    /// [`edge_after`]). Entries with a non-finite point or normal are
    /// dropped; slices are read up to the shortest length.
    pub(crate) fn rebuild_with_normals(
        &mut self,
        points: &[IPoint],
        normals: &[Vector2<f64>],
        edges: &[bool],
        params: &IcpParams,
    ) -> Result<(), IcpError> {
        self.points.clear();
        self.normals.clear();
        self.edges.clear();
        for (i, ((p, n), e)) in points.iter().zip(normals).zip(edges).enumerate() {
            if finite_point(p) && n.x.is_finite() && n.y.is_finite() {
                self.points.push(*p);
                self.normals.push(*n);
            }
            if *e {
                // Checked again: the flag comes from a stored keyframe.
                let next = points.get(i + 1).zip(normals.get(i + 1));
                if let Some(f) = next.and_then(|(b, nb)| edge_between(p, b, n, nb, params)) {
                    self.edges.push(f);
                }
            }
        }
        self.check_size(params)?;
        self.build_tree(params)
    }

    /// Rebuilds from one scan: `points` in the sensor frame in beam order (as
    /// a scanner delivers them), seen from `pose`. Points are stored in the
    /// world frame with normals from their beam-order neighbours; nearest
    /// neighbours are found by bearing from the sensor, exactly and without a
    /// tree, so this allocates nothing once the buffers have grown. Points
    /// whose bearings do not increase (not a scan) fall back to a k-d tree.
    pub fn rebuild_scan(
        &mut self,
        points: &[IPoint],
        pose: &Pose,
        params: &IcpParams,
    ) -> Result<(), IcpError> {
        self.points.clear();
        self.normals.clear();
        self.edges.clear();
        self.bearings.clear();
        self.tree = None;
        self.fan = None;
        let rot = pose.rotation;
        let mut sorted = true;
        for (i, p) in points.iter().enumerate() {
            if !finite_point(p) {
                continue;
            }
            let n = ordered_normal(points, i, params);
            let b = p.y.atan2(p.x);
            sorted &= self.bearings.last().is_none_or(|&last| b >= last);
            self.bearings.push(b);
            self.points.push(p.transformed(pose));
            self.normals.push(rot * n);
            if let Some(e) = edge_after(points, i, params) {
                self.edges.push(e.transformed(pose));
            }
        }
        self.check_size(params)?;
        self.intensity_scale = params.intensity_weight.max(0.0).sqrt();
        if sorted {
            self.fan = Some(*pose);
            Ok(())
        } else {
            self.build_tree(params)
        }
    }

    /// Empties the reference (matching against it then fails with too few points).
    pub fn clear(&mut self) {
        self.points.clear();
        self.normals.clear();
        self.edges.clear();
        self.bearings.clear();
        self.tree = None;
        self.fan = None;
    }

    /// Number of usable points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the reference holds no points (never built or emptied).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty() || (self.tree.is_none() && self.fan.is_none())
    }

    /// The usable points.
    pub fn points(&self) -> &[IPoint] {
        &self.points
    }

    /// Unit surface normals, one per point (zero vector where unknown).
    pub fn normals(&self) -> &[Vector2<f64>] {
        &self.normals
    }

    /// The intensity edges along the reference's surfaces (a marker's
    /// borders; none when `w` = 0 or the points have no surface order).
    /// They constrain the pose along the surface, where geometry cannot.
    pub(crate) fn intensity_edges(&self) -> &[EdgeFeature] {
        &self.edges
    }

    /// Scale of the intensity axis in the tree (√w).
    pub(crate) fn intensity_scale(&self) -> f64 {
        self.intensity_scale
    }

    /// Nearest reference point to `q` (x, y, √w·l) and its squared distance,
    /// if that is at most `max_d2`.
    #[inline]
    pub(crate) fn nearest_within(&self, q: &[f64; 3], max_d2: f64) -> Option<(usize, f64)> {
        if let Some(origin) = &self.fan {
            return self.nearest_by_bearing(origin, q, max_d2);
        }
        self.nearest_in_tree(q).filter(|&(_, d2)| d2 <= max_d2)
    }

    fn nearest_in_tree(&self, q: &[f64; 3]) -> Option<(usize, f64)> {
        let r = match self.tree.as_ref()? {
            Tree::Plane(t) => t
                .query(&[q[0], q[1]])
                .nearest_one::<SquaredEuclidean<f64>>()
                .execute(),
            Tree::WithIntensity(t) => t.query(q).nearest_one::<SquaredEuclidean<f64>>().execute(),
        };
        Some((r.item as usize, r.distance))
    }

    /// Exact nearest neighbour in a bearing-sorted scan: walks outwards from
    /// the query's bearing on both sides (round the circle) and stops a side
    /// once the angle from the query's bearing alone puts the beam's ray
    /// farther than the best distance found (`r·sin Δ > d` with Δ < 90°; no
    /// bound when `d ≥ r`), or passes π (the other side is nearer from there).
    fn nearest_by_bearing(&self, origin: &Pose, q: &[f64; 3], max_d2: f64) -> Option<(usize, f64)> {
        use std::f64::consts::{PI, TAU};
        let (s, c) = (origin.rotation.im, origin.rotation.re);
        let (dx, dy) = (q[0] - origin.translation.x, q[1] - origin.translation.y);
        let (xs, ys) = (c * dx + s * dy, -s * dx + c * dy);
        let r = xs.hypot(ys);
        let phi = ys.atan2(xs);
        let scale = self.intensity_scale;
        let n = self.bearings.len();
        // Largest angle from the query's bearing that can still hold a point
        // within squared distance `d2` (π when any angle can).
        let reach = |d2: f64| {
            let d = d2.sqrt();
            if d < r {
                (d / r).asin()
            } else {
                PI
            }
        };
        // Only points within `max_d2` count: the search starts with that bound.
        let mut best = (usize::MAX, max_d2.next_up());
        let mut limit = reach(best.1);
        let start = self.bearings.partition_point(|&b| b < phi);
        for side in [true, false] {
            for step in 0..n {
                let j = if side {
                    (start + step) % n
                } else {
                    (start + 2 * n - 1 - step) % n
                };
                let mut delta = if side {
                    self.bearings[j] - phi
                } else {
                    phi - self.bearings[j]
                };
                if delta < 0.0 {
                    delta += TAU;
                }
                if delta > limit {
                    break;
                }
                let p = &self.points[j];
                let d = (p.x - q[0]).powi(2)
                    + (p.y - q[1]).powi(2)
                    + (scale * p.intensity - q[2]).powi(2);
                if d < best.1 {
                    best = (j, d);
                    limit = reach(d);
                }
            }
        }
        (best.0 != usize::MAX).then_some(best)
    }

    fn copy_finite(&mut self, points: &[IPoint]) {
        self.points.clear();
        self.points
            .extend(points.iter().filter(|p| finite_point(p)).copied());
    }

    fn check_size(&mut self, params: &IcpParams) -> Result<(), IcpError> {
        if self.points.len() < params.min_pairs {
            self.tree = None;
            self.fan = None;
            return Err(IcpError::TooFewReferencePoints {
                have: self.points.len(),
                need: params.min_pairs,
            });
        }
        Ok(())
    }

    fn build_tree(&mut self, params: &IcpParams) -> Result<(), IcpError> {
        self.fan = None;
        self.intensity_scale = params.intensity_weight.max(0.0).sqrt();
        let s = self.intensity_scale;
        let built = if s > 0.0 {
            self.coords.clear();
            self.coords
                .extend(self.points.iter().map(|p| [p.x, p.y, s * p.intensity]));
            ImmutableKdTree::new_from_slice(&self.coords).map(Tree::WithIntensity)
        } else {
            self.coords2.clear();
            self.coords2.extend(self.points.iter().map(|p| [p.x, p.y]));
            ImmutableKdTree::new_from_slice(&self.coords2).map(Tree::Plane)
        };
        match built {
            Ok(t) => {
                self.tree = Some(t);
                Ok(())
            }
            Err(_) => {
                self.tree = None;
                Err(IcpError::TooFewReferencePoints {
                    have: self.coords.len(),
                    need: params.min_pairs,
                })
            }
        }
    }
}

fn finite_point(p: &IPoint) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.intensity.is_finite()
}

/// Normal of point `i` of an ordered sequence, from its neighbours at most
/// `normal_neighbours` steps away on each side and within `normal_radius`.
pub(crate) fn ordered_normal(points: &[IPoint], i: usize, params: &IcpParams) -> Vector2<f64> {
    let half = params.normal_neighbours.max(1);
    let p = &points[i];
    let r2 = params.normal_radius * params.normal_radius;
    let lo = i.saturating_sub(half);
    let hi = (i + half).min(points.len() - 1);
    let mut acc = Accum::default();
    for q in &points[lo..=hi] {
        let (dx, dy) = (q.x - p.x, q.y - p.y);
        if dx * dx + dy * dy <= r2 {
            acc.add(q.x, q.y);
        }
    }
    acc.normal()
}

/// Farthest apart (m) two successive points may lie for an intensity step
/// between them to count as an edge: farther, they may sit on different
/// surfaces, and the edge's place between them is too uncertain to help.
/// (The URG-04LX's 0.7° intensity steps lie 12 cm apart on a wall seen at
/// 3 m and 17° off grazing.)
pub(crate) const EDGE_MAX_GAP: f64 = 0.15;

/// An intensity edge on a surface (a marker's border): where the intensity
/// steps between two successive points of a scan, and which way along the
/// surface it rises. Matched edge to edge, it fixes the pose along the
/// surface; its place is known to within the points' spacing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct EdgeFeature {
    /// Midway between the two points (m).
    pub(crate) at: Vector2<f64>,
    /// Unit vector along the surface, towards the brighter side.
    pub(crate) rise: Vector2<f64>,
    /// Distance between the two points (m): the edge lies somewhere between.
    pub(crate) spacing: f64,
}

impl EdgeFeature {
    /// The edge seen from `pose` (the points were in that frame's child).
    pub(crate) fn transformed(&self, pose: &Pose) -> Self {
        let at = pose * nalgebra::Point2::from(self.at);
        Self {
            at: at.coords,
            rise: pose.rotation * self.rise,
            spacing: self.spacing,
        }
    }
}

/// The intensity edge between successive points `a` and `b` of a surface
/// whose unit normals there are `na` and `nb` (zero = unknown): some when
/// intensity matching is on (`w` > 0), the points lie at most
/// [`EDGE_MAX_GAP`] apart on a known surface and their intensities step
/// (by the share `intensity_edge` or more, see [`steps`]). The direction along the surface comes from
/// the normals (fitted over several points), not from the two points,
/// whose range noise is as large as their spacing head-on.
pub(crate) fn edge_between(
    a: &IPoint,
    b: &IPoint,
    na: &Vector2<f64>,
    nb: &Vector2<f64>,
    params: &IcpParams,
) -> Option<EdgeFeature> {
    if params.intensity_weight <= 0.0 || !(finite_point(a) && finite_point(b)) {
        return None;
    }
    let d = Vector2::new(b.x - a.x, b.y - a.y);
    let spacing = d.norm();
    let step = b.intensity - a.intensity;
    if !(spacing > 0.0 && spacing <= EDGE_MAX_GAP && steps(a, b, params)) {
        return None;
    }
    // Both normals known and of one surface (within 30°), turned alike.
    if !(na.norm() > 0.5 && nb.norm() > 0.5) {
        return None;
    }
    let n = if na.dot(nb) < 0.0 { na - nb } else { na + nb };
    let len = n.norm();
    if len < 2.0 * SAME_SURFACE {
        return None;
    }
    let tangent = Vector2::new(-n.y, n.x) / len;
    let along = tangent.dot(&d);
    Some(EdgeFeature {
        at: Vector2::new(0.5 * (a.x + b.x), 0.5 * (a.y + b.y)),
        rise: tangent * (along.signum() * step.signum()),
        spacing,
    })
}

/// Whether the intensity steps between `a` and `b`: the brighter is
/// `intensity_edge` (a share) brighter than the darker, which is lit. A
/// share, not a difference: range and angle of incidence scale both
/// points' intensities alike, a surface's reflectivity does not. Tape
/// beside plaster (0.95 against 0.55) steps by 0.73 at any range; the same
/// wall seen head-on and at a grazing 87° (a corner of a rasterised floor
/// plan) by at most 0.47 (the emulator's cos^0.13, fitted to a real scan).
fn steps(a: &IPoint, b: &IPoint, params: &IcpParams) -> bool {
    let (lo, hi) = if a.intensity <= b.intensity {
        (a.intensity, b.intensity)
    } else {
        (b.intensity, a.intensity)
    };
    lo > 0.0 && hi >= lo * (1.0 + params.intensity_edge)
}

/// cos of the half angle between two normals of one surface (15°: their
/// mean then lies within 15° of each).
const SAME_SURFACE: f64 = 0.966;

/// The intensity edge between point `i` and point `i + 1` of an ordered
/// sequence, their normals fitted from their sequence neighbours.
pub(crate) fn edge_after(points: &[IPoint], i: usize, params: &IcpParams) -> Option<EdgeFeature> {
    let (a, b) = (points.get(i)?, points.get(i + 1)?);
    if params.intensity_weight <= 0.0 || !steps(a, b, params) {
        return None;
    }
    let (na, nb) = (
        ordered_normal(points, i, params),
        ordered_normal(points, i + 1, params),
    );
    edge_between(a, b, &na, &nb, params)
}

fn normal_of(nb: &[Vector2<f64>]) -> Vector2<f64> {
    let mut acc = Accum::default();
    for q in nb {
        acc.add(q.x, q.y);
    }
    acc.normal()
}

/// Running sums for a 2-D principal-axis fit.
#[derive(Default)]
struct Accum {
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

impl Accum {
    fn add(&mut self, x: f64, y: f64) {
        self.n += 1.0;
        self.sx += x;
        self.sy += y;
        self.sxx += x * x;
        self.sxy += x * y;
        self.syy += y * y;
    }

    /// Unit normal of the best-fit line, or zero when the neighbourhood is too
    /// small or not line-like (a corner, a cluster).
    fn normal(&self) -> Vector2<f64> {
        if self.n < 3.0 {
            return Vector2::zeros();
        }
        let mx = self.sx / self.n;
        let my = self.sy / self.n;
        let cxx = self.sxx / self.n - mx * mx;
        let cxy = self.sxy / self.n - mx * my;
        let cyy = self.syy / self.n - my * my;
        let c = Matrix2::new(cxx, cxy, cxy, cyy);
        let e = c.symmetric_eigen();
        let (small, large) = if e.eigenvalues[0] <= e.eigenvalues[1] {
            (0, 1)
        } else {
            (1, 0)
        };
        let (ls, ll) = (e.eigenvalues[small].max(0.0), e.eigenvalues[large]);
        if ll.is_nan() || ll <= 0.0 || ls > 0.1 * ll {
            return Vector2::zeros();
        }
        let v = e.eigenvectors.column(small).into_owned();
        let norm = v.norm();
        if norm > 0.0 && norm.is_finite() {
            v / norm
        } else {
            Vector2::zeros()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The bearing search finds exactly what an exhaustive search finds.
    #[test]
    fn bearing_index_is_exact() {
        let params = IcpParams {
            intensity_weight: 0.3,
            ..IcpParams::default()
        };
        // A jagged 240° scan: ranges jump between near and far surfaces.
        let scan: Vec<IPoint> = (0..400)
            .map(|i| {
                let a = -2.09 + 4.18 * i as f64 / 399.0;
                let r = 1.0 + 0.8 * (a * 7.0).sin().abs() + if i % 37 < 5 { 2.0 } else { 0.0 };
                IPoint::new(r * a.cos(), r * a.sin(), (i % 11) as f64 / 10.0)
            })
            .collect();
        let at = pose(1.0, -2.0, 0.7);
        let mut fan = Reference::new();
        fan.rebuild_scan(&scan, &at, &params).unwrap();
        assert!(fan.fan.is_some());
        let s = fan.intensity_scale();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut u = || rng.random::<f64>();
        for _ in 0..2000 {
            let q = [1.0 + 8.0 * (u() - 0.5), -2.0 + 8.0 * (u() - 0.5), s * u()];
            let (i, d) = fan.nearest_within(&q, f64::INFINITY).unwrap();
            let brute = fan
                .points()
                .iter()
                .map(|p| {
                    (p.x - q[0]).powi(2) + (p.y - q[1]).powi(2) + (s * p.intensity - q[2]).powi(2)
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                (d - brute).abs() < 1e-12,
                "query {q:?}: got {i} at {d}, best {brute}"
            );
        }
        // Points whose bearings do not increase are not a scan: a tree is built instead.
        let mut shuffled = scan.clone();
        shuffled.swap(10, 300);
        let mut tree = Reference::new();
        tree.rebuild_scan(&shuffled, &at, &params).unwrap();
        assert!(tree.fan.is_none() && tree.tree.is_some());
        // Too few points: an error, and an empty reference.
        assert!(fan.rebuild_scan(&scan[..3], &at, &params).is_err());
        assert!(fan.is_empty());
    }

    /// Both tree kinds, the plane one (no intensity weight) and the one with
    /// an intensity axis, find exactly what an exhaustive search finds, and
    /// honour the distance bound.
    #[test]
    fn tree_search_is_exact_with_and_without_intensity() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut u = || rng.random::<f64>();
        // Clustered points (walls and clutter), unordered: the tree is used.
        let points: Vec<IPoint> = (0..1500)
            .map(|i| {
                let t = u();
                let (x, y) = match i % 3 {
                    0 => (4.0 * t, 0.02 * u()),
                    1 => (0.02 * u(), 3.0 * t),
                    _ => (1.5 + 0.3 * u(), 1.0 + 0.3 * t),
                };
                IPoint::new(x, y, u())
            })
            .collect();
        for w in [0.0, 0.3] {
            let params = IcpParams {
                intensity_weight: w,
                ..IcpParams::default()
            };
            let mut r = Reference::new();
            r.rebuild(&points, &params).unwrap();
            assert_eq!(matches!(r.tree, Some(Tree::Plane(_))), w == 0.0);
            let s = r.intensity_scale();
            for _ in 0..2000 {
                let q = [5.0 * u() - 0.5, 4.0 * u() - 0.5, s * u()];
                let (i, d) = r.nearest_within(&q, f64::INFINITY).unwrap();
                let brute = r
                    .points()
                    .iter()
                    .map(|p| {
                        (p.x - q[0]).powi(2)
                            + (p.y - q[1]).powi(2)
                            + (s * p.intensity - q[2]).powi(2)
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    (d - brute).abs() < 1e-12,
                    "w {w}, query {q:?}: got {i} at {d}, best {brute}"
                );
                assert_eq!(r.nearest_within(&q, brute * 0.999).is_none(), brute > 0.0);
            }
        }
    }
}
