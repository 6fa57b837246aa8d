//! Shared helpers for the decomposition tests: an evidence grid built by
//! casting simulated URG-04LX scans in a world.
#![allow(dead_code)]

use nalgebra::Point2;
use sweepline::geom::{Pose, Segment};
use sweepline::grid::Grid;
use sweepline::sim::world::World;

/// URG-04LX-like scan: 240° field of view, 0.352° steps, 5.6 m range.
pub const FOV: f64 = 240.0 * std::f64::consts::PI / 180.0;
/// Beams per scan.
pub const BEAMS: usize = 683;
/// Maximum range (m).
pub const RANGE: f64 = 5.6;

/// A grid covering `world` with a margin, at `res`.
pub fn grid_for(world: &World, res: f64) -> Grid {
    let f = &world.free;
    let margin = 1.0;
    let w = ((f.width as f64 * f.resolution + 2.0 * margin) / res).ceil() as usize;
    let h = ((f.height as f64 * f.resolution + 2.0 * margin) / res).ceil() as usize;
    Grid::new(
        Point2::new(
            (f.origin.x - margin).div_euclid(res) * res,
            (f.origin.y - margin).div_euclid(res) * res,
        ),
        res,
        w,
        h,
    )
}

/// Integrates one scan taken at `pose` into `grid`; returns the wall pieces
/// seen (hit points joined along each wall), for tests that want segments.
pub fn scan(world: &World, grid: &mut Grid, pose: &Pose) {
    let o = Point2::new(pose.translation.x, pose.translation.y);
    let th = pose.rotation.angle();
    for b in 0..BEAMS {
        let a = th - FOV / 2.0 + FOV * b as f64 / (BEAMS - 1) as f64;
        let dir = nalgebra::Vector2::new(a.cos(), a.sin());
        match world.cast_ray(&o, a, RANGE) {
            Some(hit) => grid.integrate_ray(&o, &(o + dir * hit.range), true),
            None => grid.integrate_ray(&o, &(o + dir * RANGE), false),
        }
    }
}

/// The world's walls that have at least one sample point within `RANGE` in
/// line of sight of one of `poses` (a crude "seen walls" list), clipped to
/// the part that was seen.
pub fn seen_segments(world: &World, poses: &[Pose]) -> Vec<Segment> {
    let mut out = Vec::new();
    for w in &world.walls {
        let n = ((w.seg.length() / 0.05).ceil() as usize).max(1);
        let mut first: Option<Point2<f64>> = None;
        let mut last: Option<Point2<f64>> = None;
        for j in 0..=n {
            let p = w.seg.a + (w.seg.b - w.seg.a) * (j as f64 / n as f64);
            let seen = poses.iter().any(|pose| {
                let o = Point2::new(pose.translation.x, pose.translation.y);
                let d = p - o;
                let dist = d.norm();
                if !(1e-6..=RANGE).contains(&dist) {
                    return false;
                }
                let a = d.y.atan2(d.x);
                world
                    .cast_ray(&o, a, RANGE)
                    .is_some_and(|h| (h.range - dist).abs() < 0.03)
            });
            if seen {
                if first.is_none() {
                    first = Some(p);
                }
                last = Some(p);
            } else if let (Some(a), Some(b)) = (first.take(), last.take()) {
                if (b - a).norm() > 0.1 {
                    out.push(Segment::new(a, b));
                }
            }
        }
        if let (Some(a), Some(b)) = (first, last) {
            if (b - a).norm() > 0.1 {
                out.push(Segment::new(a, b));
            }
        }
    }
    out
}

/// The paper's workspace.
pub fn paper_world() -> World {
    let path = sweepline::testdata::repo_file("hw/worlds/paper.world");
    World::load(&path).expect("paper world loads")
}

/// Scan poses for exploring `world`: free points (0.3 m clearance) on a
/// lattice of `step` metres, visited row by row in boustrophedon order,
/// starting with the world's start pose.
pub fn tour(world: &World, step: f64) -> Vec<Pose> {
    let f = &world.free;
    let (x0, y0) = (f.origin.x, f.origin.y);
    let (x1, y1) = (
        x0 + f.width as f64 * f.resolution,
        y0 + f.height as f64 * f.resolution,
    );
    let mut out = vec![world.start];
    let mut row = 0;
    let mut y = y0 + step / 2.0;
    while y < y1 {
        let mut xs: Vec<f64> = Vec::new();
        let mut x = x0 + step / 2.0;
        while x < x1 {
            xs.push(x);
            x += step;
        }
        if row % 2 == 1 {
            xs.reverse();
        }
        for x in xs {
            let p = Point2::new(x, y);
            if world.disk_is_free(&p, 0.3) {
                let heading = if row % 2 == 0 {
                    0.0
                } else {
                    std::f64::consts::PI
                };
                out.push(sweepline::geom::pose(x, y, heading));
            }
        }
        y += step;
        row += 1;
    }
    out
}

/// Percentile `q` (0..1) of `v` (sorted copy).
pub fn percentile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    if s.is_empty() {
        return 0.0;
    }
    sweepline::pipeline::metrics::quantile_sorted(&s, q)
}

/// Like [`scan`], with Gaussian-ish range noise (`range_sd`, m) and the scan
/// registered at a pose off by (`dx`, `dy`, `dth`): what a real map with
/// localisation error looks like.
pub fn noisy_scan(
    world: &World,
    grid: &mut Grid,
    pose: &Pose,
    range_sd: f64,
    off: (f64, f64, f64),
    rng: &mut impl rand::Rng,
) {
    let o = Point2::new(pose.translation.x, pose.translation.y);
    let th = pose.rotation.angle();
    let reg = Point2::new(o.x + off.0, o.y + off.1);
    for b in 0..BEAMS {
        let a = th - FOV / 2.0 + FOV * b as f64 / (BEAMS - 1) as f64;
        // Sum of uniforms: close enough to a normal for a test.
        let n: f64 = (0..4).map(|_| rng.random::<f64>() - 0.5).sum::<f64>() * range_sd * 1.7;
        let ra = a + off.2;
        let dir = nalgebra::Vector2::new(ra.cos(), ra.sin());
        match world.cast_ray(&o, a, RANGE) {
            Some(hit) => grid.integrate_ray(&reg, &(reg + dir * (hit.range + n).max(0.0)), true),
            None => grid.integrate_ray(&reg, &(reg + dir * RANGE), false),
        }
    }
}
