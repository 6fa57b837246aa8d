//! Plain geometry shared by every algorithm: poses, points with intensity,
//! line segments. Units are metres and radians; world frame x right, y up,
//! angles counter-clockwise.

use nalgebra::{Isometry2, Point2, Vector2};

/// A planar pose (SE(2)): translation plus rotation, in metres and radians.
pub type Pose = Isometry2<f64>;

/// Builds a pose from `x`, `y` (m) and heading `theta` (rad).
pub fn pose(x: f64, y: f64, theta: f64) -> Pose {
    Isometry2::new(Vector2::new(x, y), theta)
}

/// Heading of a pose in radians, in (-π, π].
pub fn heading(p: &Pose) -> f64 {
    p.rotation.angle()
}

/// The pose `f` of the way from `a` to `b` (0 = `a`, 1 = `b`): the position
/// along the straight line, the heading along the shorter turn.
pub fn interpolate(a: &Pose, b: &Pose, f: f64) -> Pose {
    let th = heading(a) + f * wrap_angle(heading(b) - heading(a));
    pose(
        a.translation.x + f * (b.translation.x - a.translation.x),
        a.translation.y + f * (b.translation.y - a.translation.y),
        wrap_angle(th),
    )
}

/// Pose `p` moved by the motion that took `from` to `to` (both in another
/// frame, e.g. two odometry readings): `p · from⁻¹ · to`, its rotation
/// re-normalised (nalgebra does not after products, and chained
/// predictions would drift).
pub fn carried(p: &Pose, from: &Pose, to: &Pose) -> Pose {
    let q = p * (from.inverse() * to);
    pose(q.translation.x, q.translation.y, heading(&q))
}

/// How far pose `a` is from pose `b`: the distance between their positions
/// (m) and the heading of `a` minus that of `b`, wrapped (rad).
pub fn pose_error(a: &Pose, b: &Pose) -> (f64, f64) {
    (
        (a.translation.vector - b.translation.vector).norm(),
        wrap_angle(heading(a) - heading(b)),
    )
}

/// The point `r` from `origin` in the direction `angle` (world frame): a
/// point on a robot's shell, at the end of a ray.
pub fn polar(origin: Point2<f64>, angle: f64, r: f64) -> Point2<f64> {
    origin + Vector2::new(angle.cos(), angle.sin()) * r
}

/// Points from `a` to `b` every `step` (m) or less, both ends included (one
/// step when the segment is shorter than `step`): samples of a segment for
/// a test along it, or a map of it.
pub fn points_along(
    a: Point2<f64>,
    b: Point2<f64>,
    step: f64,
) -> impl Iterator<Item = Point2<f64>> {
    let d = b - a;
    let n = (d.norm() / step).ceil().max(1.0) as usize;
    (0..=n).map(move |k| a + d * (k as f64 / n as f64))
}

/// Wraps an angle into (-π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let mut r = a % std::f64::consts::TAU;
    if r <= -std::f64::consts::PI {
        r += std::f64::consts::TAU;
    } else if r > std::f64::consts::PI {
        r -= std::f64::consts::TAU;
    }
    r
}

/// A 2-D point with the laser reflection intensity it was seen with
/// (0 when the sensor gives none; normalised units, typically 0..1).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IPoint {
    /// x in metres.
    pub x: f64,
    /// y in metres.
    pub y: f64,
    /// Reflection intensity (dimensionless).
    pub intensity: f64,
}

impl IPoint {
    /// A point at (`x`, `y`) with intensity `intensity`.
    pub const fn new(x: f64, y: f64, intensity: f64) -> Self {
        Self { x, y, intensity }
    }

    /// The position as an nalgebra point.
    pub fn xy(&self) -> Point2<f64> {
        Point2::new(self.x, self.y)
    }

    /// This point moved by `pose` (intensity unchanged).
    pub fn transformed(&self, pose: &Pose) -> Self {
        let p = pose * self.xy();
        Self::new(p.x, p.y, self.intensity)
    }
}

/// A line segment between two end points, in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// First end point.
    pub a: Point2<f64>,
    /// Second end point.
    pub b: Point2<f64>,
}

impl Segment {
    /// The segment from `a` to `b`.
    pub fn new(a: Point2<f64>, b: Point2<f64>) -> Self {
        Self { a, b }
    }

    /// Length in metres.
    pub fn length(&self) -> f64 {
        (self.b - self.a).norm()
    }

    /// Direction angle of `a -> b` in radians.
    pub fn angle(&self) -> f64 {
        let d = self.b - self.a;
        d.y.atan2(d.x)
    }

    /// The point of the segment closest to `p`.
    pub(crate) fn closest_point(&self, p: &Point2<f64>) -> Point2<f64> {
        let d = self.b - self.a;
        let l2 = d.norm_squared();
        if l2 == 0.0 {
            return self.a;
        }
        let t = ((p - self.a).dot(&d) / l2).clamp(0.0, 1.0);
        self.a + d * t
    }

    /// Distance from `p` to the closest point of the segment.
    pub fn distance_to(&self, p: &Point2<f64>) -> f64 {
        (p - self.closest_point(p)).norm()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_turns_the_short_way_and_errors_are_wrapped() {
        let (a, b) = (pose(0.0, 0.0, 3.0), pose(2.0, -4.0, -3.0));
        let m = interpolate(&a, &b, 0.5);
        assert!((m.translation.x - 1.0).abs() < 1e-12 && (m.translation.y + 2.0).abs() < 1e-12);
        // 3 rad to -3 rad is 0.28 rad through π, not 6 rad back through 0.
        assert!((heading(&m).abs() - std::f64::consts::PI).abs() < 1e-9);
        let (d, h) = pose_error(&b, &a);
        assert!((d - 20f64.sqrt()).abs() < 1e-12);
        assert!((h - (std::f64::consts::TAU - 6.0)).abs() < 1e-12);
    }

    #[test]
    fn wrap_angle_stays_in_range() {
        for k in -20..20 {
            let a = k as f64 * 0.7;
            let w = wrap_angle(a);
            assert!(w > -std::f64::consts::PI - 1e-12 && w <= std::f64::consts::PI + 1e-12);
            assert!(
                ((a - w) / std::f64::consts::TAU).fract().abs() < 1e-9
                    || (1.0 - ((a - w) / std::f64::consts::TAU).fract().abs()) < 1e-9
            );
        }
    }

    #[test]
    fn segment_distance() {
        let s = Segment::new(Point2::new(0.0, 0.0), Point2::new(2.0, 0.0));
        assert!((s.distance_to(&Point2::new(1.0, 1.0)) - 1.0).abs() < 1e-12);
        assert!((s.distance_to(&Point2::new(3.0, 0.0)) - 1.0).abs() < 1e-12);
        assert!((s.length() - 2.0).abs() < 1e-12);
    }
}
