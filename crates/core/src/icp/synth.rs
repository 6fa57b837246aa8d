//! Synthetic scans for tests and benchmarks: a world of wall segments with a
//! reflectivity each, ray-cast from a pose. Deterministic (seeded noise).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::geom::{points_along, IPoint, Pose, Segment};

/// A wall: a segment and the intensity it returns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wall {
    /// The wall segment (world frame, m).
    pub segment: Segment,
    /// Returned intensity (normalised, 0..1).
    pub intensity: f64,
}

impl Wall {
    /// A wall from (x0, y0) to (x1, y1) with `intensity`.
    pub fn new(x0: f64, y0: f64, x1: f64, y1: f64, intensity: f64) -> Self {
        Self {
            segment: Segment::new(nalgebra::Point2::new(x0, y0), nalgebra::Point2::new(x1, y1)),
            intensity,
        }
    }
}

/// How to cast a synthetic scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanSpec {
    /// Number of beams.
    pub beams: usize,
    /// Angle of the first beam (rad, sensor frame).
    pub start_angle: f64,
    /// Angle of the last beam (rad).
    pub end_angle: f64,
    /// Longest range returned (m).
    pub max_range: f64,
    /// Standard deviation of the range noise (m); 0 for none.
    pub range_noise: f64,
    /// Noise seed.
    pub seed: u64,
}

impl Default for ScanSpec {
    /// A URG-04LX-like scan: 682 beams over 240°, 5.6 m, 1 cm noise.
    fn default() -> Self {
        Self {
            beams: 682,
            start_angle: -120f64.to_radians(),
            end_angle: 120f64.to_radians(),
            max_range: 5.6,
            range_noise: 0.01,
            seed: 1,
        }
    }
}

/// Casts a scan from `pose` into `walls`; returns the hits as sensor-frame
/// points in beam order (beams without a hit within range are left out).
pub fn cast(walls: &[Wall], pose: &Pose, spec: &ScanSpec) -> Vec<IPoint> {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let mut out = Vec::with_capacity(spec.beams);
    let o = pose.translation.vector;
    let th = pose.rotation.angle();
    for i in 0..spec.beams {
        let a = if spec.beams > 1 {
            spec.start_angle
                + (spec.end_angle - spec.start_angle) * i as f64 / (spec.beams - 1) as f64
        } else {
            spec.start_angle
        };
        let origin = nalgebra::Point2::new(o.x, o.y);
        if let Some((t, inten)) = nearest(walls, &origin, th + a, spec.max_range) {
            let noise = if spec.range_noise > 0.0 {
                // Sum of uniforms: a cheap, deterministic near-Gaussian.
                let u: f64 = (0..4).map(|_| rng.random::<f64>() - 0.5).sum();
                u * spec.range_noise * 3f64.sqrt()
            } else {
                0.0
            };
            let r = t + noise;
            let (sa, ca) = a.sin_cos();
            out.push(IPoint::new(r * ca, r * sa, inten));
        }
    }
    out
}

/// [`cast`] with the default (URG-04LX-like) [`ScanSpec`] and noise seed `seed`.
pub fn cast_seeded(walls: &[Wall], pose: &Pose, seed: u64) -> Vec<IPoint> {
    cast(
        walls,
        pose,
        &ScanSpec {
            seed,
            ..ScanSpec::default()
        },
    )
}

/// [`cast_seeded`] with the hits moved into the world frame: the points a
/// reference built from a scan taken at `pose` holds.
pub fn cast_world(walls: &[Wall], pose: &Pose, seed: u64) -> Vec<IPoint> {
    cast_seeded(walls, pose, seed)
        .iter()
        .map(|p| p.transformed(pose))
        .collect()
}

/// Distance along the ray (ox, oy) + t·(dx, dy) to `seg`, if it hits.
fn ray_hit(ox: f64, oy: f64, dx: f64, dy: f64, seg: &Segment) -> Option<f64> {
    let (ex, ey) = (seg.b.x - seg.a.x, seg.b.y - seg.a.y);
    let den = dx * ey - dy * ex;
    if den.abs() < 1e-12 {
        return None;
    }
    let (wx, wy) = (seg.a.x - ox, seg.a.y - oy);
    let t = (wx * ey - wy * ex) / den;
    let u = (wx * dy - wy * dx) / den;
    (t > 1e-9 && (0.0..=1.0).contains(&u)).then_some(t)
}

/// The distance (m) from `origin` along the ray at `angle` (rad, world
/// frame) to the nearest of `walls` within `max_range`.
pub fn ray(
    walls: &[Wall],
    origin: &nalgebra::Point2<f64>,
    angle: f64,
    max_range: f64,
) -> Option<f64> {
    nearest(walls, origin, angle, max_range).map(|(t, _)| t)
}

/// A full-circle scan of `walls` from `origin` (heading 0) in `beams` equal
/// steps from −π: one valid beam per ray that hits within 10 m.
pub fn laser_scan(
    walls: &[Wall],
    origin: &nalgebra::Point2<f64>,
    beams: usize,
) -> crate::scan::LaserScan {
    let mut s = crate::scan::LaserScan::default();
    for k in 0..beams {
        let a = k as f64 * std::f64::consts::TAU / beams as f64 - std::f64::consts::PI;
        if let Some(r) = ray(walls, origin, a, 10.0) {
            let _ = s.beams.push(crate::scan::Beam::hit(a, r));
        }
    }
    s
}

/// The nearest hit of the ray from `origin` at `angle` (rad, world frame)
/// within `max_range`: its distance (m) and the wall's intensity (the first
/// wall listed wins a tie).
fn nearest(
    walls: &[Wall],
    origin: &nalgebra::Point2<f64>,
    angle: f64,
    max_range: f64,
) -> Option<(f64, f64)> {
    let (s, c) = angle.sin_cos();
    walls
        .iter()
        .filter_map(|w| Some((ray_hit(origin.x, origin.y, c, s, &w.segment)?, w.intensity)))
        .filter(|&(t, _)| t <= max_range)
        .min_by(|x, y| x.0.total_cmp(&y.0))
}

/// The closed polygon through `corners` (m), every edge of `intensity`.
pub fn polygon(corners: &[(f64, f64)], intensity: f64) -> Vec<Wall> {
    (0..corners.len())
        .map(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % corners.len()]);
            Wall::new(a.0, a.1, b.0, b.1, intensity)
        })
        .collect()
}

/// A closed rectangular room `w` × `h` (m) with its lower-left corner at the
/// origin, every wall of `intensity`.
pub fn room(w: f64, h: f64, intensity: f64) -> Vec<Wall> {
    polygon(&[(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)], intensity)
}

/// An L-shaped room (6 × 4 m, the upper right 2.5 × 1.5 m cut away) with a
/// 0.4 m square pillar: no symmetry, every direction of a match constrained.
pub fn l_room_with_pillar() -> Vec<Wall> {
    let mut w = vec![
        Wall::new(0.0, 0.0, 6.0, 0.0, 0.5),
        Wall::new(6.0, 0.0, 6.0, 2.5, 0.5),
        Wall::new(6.0, 2.5, 3.5, 2.5, 0.5),
        Wall::new(3.5, 2.5, 3.5, 4.0, 0.5),
        Wall::new(3.5, 4.0, 0.0, 4.0, 0.5),
        Wall::new(0.0, 4.0, 0.0, 0.0, 0.5),
    ];
    w.extend(room(0.4, 0.4, 0.5).into_iter().map(|mut x| {
        for p in [&mut x.segment.a, &mut x.segment.b] {
            p.x += 1.5;
            p.y += 1.2;
        }
        x
    }));
    w
}

/// Points every `step` (m) or closer along every wall, with its
/// reflectivity: a dense, noise-free map of `walls` to match against.
pub fn wall_points(walls: &[Wall], step: f64) -> Vec<IPoint> {
    walls
        .iter()
        .flat_map(|w| {
            points_along(w.segment.a, w.segment.b, step).map(|p| IPoint::new(p.x, p.y, w.intensity))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    #[test]
    fn seeded_and_world_casts_follow_the_seed_and_the_pose() {
        let walls = room(5.0, 4.0, 0.5);
        let at = pose(2.0, 1.5, 0.3);
        let a = cast_seeded(&walls, &at, 3);
        assert!(a.len() > 600, "{} hits", a.len());
        assert_eq!(a, cast_seeded(&walls, &at, 3));
        assert_ne!(a, cast_seeded(&walls, &at, 4), "noise follows the seed");
        let w = cast_world(&walls, &at, 3);
        assert_eq!(w.len(), a.len());
        let back = at.inverse() * w[10].xy();
        assert!((back - a[10].xy()).norm() < 1e-9);
        // Every world-frame hit lies inside the 5 x 4 m room (1 cm noise).
        assert!(w.iter().all(|p| {
            let q = p.xy();
            (-0.1..5.1).contains(&q.x) && (-0.1..4.1).contains(&q.y)
        }));
    }
}
