//! Total-least-squares line fitting from running moments: mean and scatter of
//! a point set, combinable without revisiting points (Chan's update), so a map
//! segment can absorb new observations in O(1).

use nalgebra::{Isometry2, Point2, Vector2};

/// First and second moments of a planar point set about its mean.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Moments {
    /// Number of points (a weight: may be scaled down to forget old data).
    pub n: f64,
    /// Mean position.
    pub mean: Vector2<f64>,
    /// Σ (x − x̄)².
    pub sxx: f64,
    /// Σ (x − x̄)(y − ȳ).
    pub sxy: f64,
    /// Σ (y − ȳ)².
    pub(crate) syy: f64,
}

/// A fitted line: centre, unit direction, and how well the points fit it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineFit {
    /// Centroid of the points (lies on the line).
    pub centre: Point2<f64>,
    /// Unit direction of the line (the scatter's major axis).
    pub dir: Vector2<f64>,
    /// RMS perpendicular distance of the points to the line (m).
    pub rms: f64,
    /// Variance of the direction angle estimate (rad²).
    pub(crate) var_angle: f64,
    /// Variance of the line's perpendicular offset estimate (m²).
    pub(crate) var_offset: f64,
}

impl LineFit {
    /// Unit normal (direction turned +90°).
    pub fn normal(&self) -> Vector2<f64> {
        Vector2::new(-self.dir.y, self.dir.x)
    }

    /// Signed position of `p` along the line, from the centre.
    pub fn along(&self, p: &Point2<f64>) -> f64 {
        (p - self.centre).dot(&self.dir)
    }

    /// Signed perpendicular distance of `p` from the line.
    pub fn offset(&self, p: &Point2<f64>) -> f64 {
        (p - self.centre).dot(&self.normal())
    }

    /// The point of the line at signed position `s` from the centre.
    pub fn at(&self, s: f64) -> Point2<f64> {
        self.centre + self.dir * s
    }

    /// Direction angle in (−π/2, π/2] (lines have no orientation).
    pub fn angle(&self) -> f64 {
        undirected(self.dir.y.atan2(self.dir.x))
    }
}

/// |sin| of the angle between two undirected lines with unit directions `a`
/// and `b`: 0 when parallel, 1 when perpendicular. No trigonometry.
pub(crate) fn undirected_sin(a: &Vector2<f64>, b: &Vector2<f64>) -> f64 {
    a.perp(b).abs()
}

/// Signed angle (rad, in (−π/2, π/2]) that turns the undirected line with unit
/// direction `a` onto the one with unit direction `b`.
pub(crate) fn undirected_turn(a: &Vector2<f64>, b: &Vector2<f64>) -> f64 {
    let (c, s) = (a.dot(b), a.perp(b));
    if c >= 0.0 {
        s.atan2(c)
    } else {
        (-s).atan2(-c)
    }
}

/// Folds an angle into (−π/2, π/2]: the direction of an undirected line.
pub(crate) fn undirected(a: f64) -> f64 {
    let mut r = crate::geom::wrap_angle(a);
    if r > std::f64::consts::FRAC_PI_2 {
        r -= std::f64::consts::PI;
    } else if r <= -std::f64::consts::FRAC_PI_2 {
        r += std::f64::consts::PI;
    }
    r
}

/// Smallest angle between two undirected lines with angles `a` and `b`, signed
/// so that `a + undirected_diff(b, a)` points along `b`.
pub fn undirected_diff(b: f64, a: f64) -> f64 {
    undirected(b - a)
}

impl Moments {
    /// Moments of a point set (two passes, numerically stable).
    pub fn of(points: impl Iterator<Item = Point2<f64>> + Clone) -> Moments {
        let mut n = 0.0;
        let mut sum = Vector2::zeros();
        for p in points.clone() {
            n += 1.0;
            sum += p.coords;
        }
        if n == 0.0 {
            return Moments::default();
        }
        let mean = sum / n;
        let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
        for p in points {
            let d = p.coords - mean;
            sxx += d.x * d.x;
            sxy += d.x * d.y;
            syy += d.y * d.y;
        }
        Moments {
            n,
            mean,
            sxx,
            sxy,
            syy,
        }
    }

    /// Moments of the union of two point sets.
    pub fn merged(&self, o: &Moments) -> Moments {
        if self.n <= 0.0 {
            return *o;
        }
        if o.n <= 0.0 {
            return *self;
        }
        let n = self.n + o.n;
        let d = o.mean - self.mean;
        let f = self.n * o.n / n;
        Moments {
            n,
            mean: self.mean + d * (o.n / n),
            sxx: self.sxx + o.sxx + d.x * d.x * f,
            sxy: self.sxy + o.sxy + d.x * d.y * f,
            syy: self.syy + o.syy + d.y * d.y * f,
        }
    }

    /// The same moments with weight scaled by `k` (0 < k ≤ 1): forgets old data
    /// while keeping the line they describe.
    pub fn scaled(&self, k: f64) -> Moments {
        Moments {
            n: self.n * k,
            mean: self.mean,
            sxx: self.sxx * k,
            sxy: self.sxy * k,
            syy: self.syy * k,
        }
    }

    /// The moments of the point set moved by `t`.
    pub fn transformed(&self, t: &Isometry2<f64>) -> Moments {
        let mean = (t * Point2::from(self.mean)).coords;
        let (s, c) = t.rotation.angle().sin_cos();
        // S' = R S Rᵀ
        let (a, b, d) = (self.sxx, self.sxy, self.syy);
        let sxx = c * c * a - 2.0 * c * s * b + s * s * d;
        let syy = s * s * a + 2.0 * c * s * b + c * c * d;
        let sxy = c * s * (a - d) + (c * c - s * s) * b;
        Moments {
            n: self.n,
            mean,
            sxx,
            sxy,
            syy,
        }
    }

    /// Total-least-squares line through the points; `floor_sigma` bounds the
    /// per-point noise used for the variances from below (the sensor's σ).
    /// `None` for fewer than two points or no spread.
    pub fn fit(&self, floor_sigma: f64) -> Option<LineFit> {
        if self.n < 2.0 {
            return None;
        }
        let half_tr = 0.5 * (self.sxx + self.syy);
        let disc = (0.25 * (self.sxx - self.syy).powi(2) + self.sxy * self.sxy).sqrt();
        let l_max = half_tr + disc;
        let l_min = (half_tr - disc).max(0.0);
        if !(l_max.is_finite() && l_max > 1e-12) {
            return None;
        }
        let phi = 0.5 * (2.0 * self.sxy).atan2(self.sxx - self.syy);
        let dir = Vector2::new(phi.cos(), phi.sin());
        let rms = (l_min / self.n).sqrt();
        let dof = (self.n - 2.0).max(1.0);
        let sigma2 = (l_min / dof).max(floor_sigma * floor_sigma);
        Some(LineFit {
            centre: Point2::from(self.mean),
            dir,
            rms,
            var_angle: sigma2 / l_max,
            var_offset: sigma2 / self.n,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts(v: &[(f64, f64)]) -> Vec<Point2<f64>> {
        v.iter().map(|&(x, y)| Point2::new(x, y)).collect()
    }

    #[test]
    fn fits_a_line_exactly() {
        let p: Vec<_> = (0..20)
            .map(|i| {
                let s = i as f64 * 0.1;
                Point2::new(1.0 + s * 0.6, 2.0 + s * 0.8)
            })
            .collect();
        let f = Moments::of(p.iter().copied()).fit(0.0).unwrap();
        assert!(f.rms < 1e-9);
        assert!((f.angle() - 0.8f64.atan2(0.6)).abs() < 1e-9);
        assert!(f.offset(&Point2::new(1.0, 2.0)).abs() < 1e-9);
    }

    #[test]
    fn merge_equals_moments_of_union() {
        let a = pts(&[(0.0, 0.0), (1.0, 0.1), (2.0, -0.1), (3.0, 0.05)]);
        let b = pts(&[(5.0, 1.0), (6.0, 1.3), (7.0, 0.9)]);
        let all: Vec<_> = a.iter().chain(b.iter()).copied().collect();
        let m = Moments::of(a.iter().copied()).merged(&Moments::of(b.iter().copied()));
        let u = Moments::of(all.iter().copied());
        assert!((m.n - u.n).abs() < 1e-12);
        assert!((m.mean - u.mean).norm() < 1e-12);
        assert!((m.sxx - u.sxx).abs() < 1e-9);
        assert!((m.sxy - u.sxy).abs() < 1e-9);
        assert!((m.syy - u.syy).abs() < 1e-9);
    }

    #[test]
    fn transform_equals_moments_of_moved_points() {
        let a = pts(&[(0.0, 0.0), (1.0, 0.3), (2.0, -0.1), (3.0, 0.4)]);
        let t = Isometry2::new(Vector2::new(0.4, -1.0), 0.9);
        let moved: Vec<_> = a.iter().map(|p| t * p).collect();
        let m = Moments::of(a.iter().copied()).transformed(&t);
        let u = Moments::of(moved.iter().copied());
        assert!((m.mean - u.mean).norm() < 1e-12);
        assert!((m.sxx - u.sxx).abs() < 1e-9);
        assert!((m.sxy - u.sxy).abs() < 1e-9);
        assert!((m.syy - u.syy).abs() < 1e-9);
    }

    #[test]
    fn degenerate_sets_do_not_fit() {
        assert!(Moments::of(pts(&[(1.0, 1.0)]).into_iter())
            .fit(0.01)
            .is_none());
        assert!(Moments::of(pts(&[(1.0, 1.0), (1.0, 1.0)]).into_iter())
            .fit(0.01)
            .is_none());
        assert!(Moments::default().fit(0.01).is_none());
    }

    #[test]
    fn undirected_turn_matches_angles() {
        for (a, b) in [(0.1f64, 0.3f64), (1.5, -1.5), (3.0, 0.05), (-2.0, 1.0)] {
            let (u, v) = (
                Vector2::new(a.cos(), a.sin()),
                Vector2::new(b.cos(), b.sin()),
            );
            assert!(
                (undirected_turn(&u, &v) - undirected_diff(b, a)).abs() < 1e-12,
                "{a} {b}"
            );
            assert!((undirected_sin(&u, &v) - undirected_diff(b, a).sin().abs()).abs() < 1e-12);
        }
    }

    #[test]
    fn undirected_angles_fold() {
        assert!((undirected(std::f64::consts::PI) - 0.0).abs() < 1e-12);
        assert!((undirected(-3.0) - (std::f64::consts::PI - 3.0)).abs() < 1e-12);
        assert!((undirected_diff(3.1, -0.03) - (3.1 - std::f64::consts::PI + 0.03)).abs() < 1e-12);
    }
}
