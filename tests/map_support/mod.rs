//! Shared helpers of the map tests and bench: a simulated URG-04LX over a
//! `sim::world::World` with seeded range noise, paths through worlds, ground
//! truth of which parts of which walls were seen, and picture output.
#![allow(dead_code)]

use nalgebra::{Point2, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sweepline::geom::{pose, IPoint, Pose, Segment};
use sweepline::scan::{Beam, LaserScan};
use sweepline::sim::world::World;

/// URG-04LX geometry: 1024 steps per turn, front at step 384, steps 44..=725.
pub const URG_FIRST: i32 = 44;
/// Last step measured.
pub const URG_LAST: i32 = 725;
/// Maximum range (m).
pub const URG_MAX: f64 = 5.6;

/// Beam angle of URG step `k` (rad, sensor frame).
pub fn urg_angle(k: i32) -> f64 {
    (k - 384) as f64 * std::f64::consts::TAU / 1024.0
}

/// A seeded RNG.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// One N(0, 1) sample (Box-Muller).
pub fn gauss(r: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = r.random::<f64>().max(1e-300);
    let u2: f64 = r.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// A 682-beam URG-04LX scan from `at` (sensor pose) with range noise `sigma`.
/// Intensity = reflectivity · cos(incidence), so it depends on the surface.
pub fn urg_scan(world: &World, at: &Pose, sigma: f64, r: &mut ChaCha8Rng) -> LaserScan {
    let mut s = LaserScan::default();
    let o = Point2::from(at.translation.vector);
    let th = at.rotation.angle();
    for k in URG_FIRST..=URG_LAST {
        let a = urg_angle(k);
        let beam = match world.cast_ray(&o, th + a, URG_MAX) {
            Some(h) => Beam {
                angle: a,
                range: h.range + sigma * gauss(r),
                intensity: h.reflectivity * h.incidence.cos(),
                valid: true,
            },
            None => Beam {
                angle: a,
                range: f64::INFINITY,
                intensity: 0.0,
                valid: false,
            },
        };
        let _ = s.beams.push(beam);
    }
    s
}

/// Poses along a polyline of waypoints, every `step` metres, heading along the
/// path (turning in place at the waypoints in steps of at most 0.2 rad).
pub fn path(waypoints: &[(f64, f64)], step: f64) -> Vec<Pose> {
    let mut out: Vec<Pose> = Vec::new();
    for w in waypoints.windows(2) {
        let (a, b) = (Point2::new(w[0].0, w[0].1), Point2::new(w[1].0, w[1].1));
        let d = b - a;
        let th = d.y.atan2(d.x);
        if let Some(last) = out.last().copied() {
            let mut h = last.rotation.angle();
            let mut turn = sweepline::geom::wrap_angle(th - h);
            while turn.abs() > 0.2 {
                h += 0.2 * turn.signum();
                turn = sweepline::geom::wrap_angle(th - h);
                out.push(pose(a.x, a.y, h));
            }
        }
        let n = (d.norm() / step).ceil().max(1.0) as usize;
        for i in 0..n {
            let p = a + d * (i as f64 / n as f64);
            out.push(pose(p.x, p.y, th));
        }
    }
    if let Some(&(x, y)) = waypoints.last() {
        let h = out.last().map(|p| p.rotation.angle()).unwrap_or(0.0);
        out.push(pose(x, y, h));
    }
    out
}

/// Pose `p` perturbed by Gaussian noise (σ `st` metres, `sr` radians).
pub fn jitter(p: &Pose, st: f64, sr: f64, r: &mut ChaCha8Rng) -> Pose {
    pose(
        p.translation.x + st * gauss(r),
        p.translation.y + st * gauss(r),
        p.rotation.angle() + sr * gauss(r),
    )
}

/// The parts of each wall seen from `poses` by noise-free beams hitting at an
/// incidence below `max_incidence`: per wall index, intervals along the wall
/// (metres from its first end point), split where hits are more than `gap` apart.
pub fn seen_intervals(
    world: &World,
    poses: &[Pose],
    max_incidence: f64,
    gap: f64,
) -> Vec<Vec<(f64, f64)>> {
    let mut hits: Vec<Vec<f64>> = vec![Vec::new(); world.walls.len()];
    for at in poses {
        let o = Point2::from(at.translation.vector);
        let th = at.rotation.angle();
        for k in URG_FIRST..=URG_LAST {
            let a = th + urg_angle(k);
            let Some(h) = world.cast_ray(&o, a, URG_MAX) else {
                continue;
            };
            if h.incidence > max_incidence {
                continue;
            }
            let p = o + Vector2::new(a.cos(), a.sin()) * h.range;
            let mut best: Option<(usize, f64)> = None;
            for (i, w) in world.walls.iter().enumerate() {
                let d = w.seg.distance_to(&p);
                if d < 1e-6 && best.is_none_or(|(_, bd)| d < bd) {
                    best = Some((i, d));
                }
            }
            if let Some((i, _)) = best {
                let w = &world.walls[i].seg;
                let u = (w.b - w.a).normalize();
                hits[i].push((p - w.a).dot(&u));
            }
        }
    }
    hits.into_iter()
        .map(|mut h| {
            h.sort_by(f64::total_cmp);
            let mut out: Vec<(f64, f64)> = Vec::new();
            for s in h {
                match out.last_mut() {
                    Some(last) if s - last.1 <= gap => last.1 = s,
                    _ => out.push((s, s)),
                }
            }
            out
        })
        .collect()
}

/// The seen part `[s0, s1]` of wall `w` as a segment.
pub fn part(w: &Segment, s0: f64, s1: f64) -> Segment {
    let u = (w.b - w.a).normalize();
    Segment::new(w.a + u * s0, w.a + u * s1)
}

/// Points of a scan in the world frame (valid beams only).
pub fn world_points(s: &LaserScan, at: &Pose) -> Vec<IPoint> {
    let mut v = Vec::new();
    s.points_into(&mut v);
    v.iter().map(|p| p.transformed(at)).collect()
}

/// Writes an SVG document under `target/map-pictures/` and returns its path.
pub fn save_svg(name: &str, doc: &svg::Document) -> std::path::PathBuf {
    let dir = sweepline::testdata::repo_file("target/map-pictures");
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join(name);
    let _ = svg::save(&path, doc);
    path
}

/// A few hand-written rectilinear test worlds (name, text).
pub fn worlds() -> Vec<(&'static str, String)> {
    let paper = std::fs::read_to_string(sweepline::testdata::repo_file("hw/worlds/paper.world"))
        .expect("hw/worlds/paper.world is in the repository");
    vec![
        ("paper", paper),
        (
            "l-room",
            "name l-room\nroom 0 0 5 0 5 2 2.5 2 2.5 4 0 4 refl 0.5\nbox 3.5 0.6 4.1 1.2 refl 0.9\nstart 1 1 0\n"
                .to_string(),
        ),
        (
            "corridor",
            "name corridor\nroom 0 0 8 0 8 1.6 5.5 1.6 5.5 3.2 3.5 3.2 3.5 1.6 0 1.6 refl 0.6\nbox 1.5 1.2 2.1 1.6 refl 0.3\nstart 0.5 0.8 0\n"
                .to_string(),
        ),
        (
            "two-rooms",
            "name two-rooms\nroom 0 0 6 0 6 4 0 4 refl 0.5\nwall 3 0 3 1.5 refl 0.8\nwall 3 2.5 3 4 refl 0.8\nbox 4.5 3 5.2 3.6 refl 0.2\nstart 1 2 0\n"
                .to_string(),
        ),
    ]
}

/// A path through each of [`worlds`] (same order).
pub fn world_paths() -> Vec<Vec<(f64, f64)>> {
    vec![
        vec![
            (0.5, 0.8),
            (5.5, 0.8),
            (5.5, 3.0),
            (2.8, 3.0),
            (2.8, 3.7),
            (0.6, 3.7),
            (0.6, 1.2),
        ],
        vec![
            (0.7, 0.4),
            (4.5, 0.4),
            (4.5, 1.6),
            (1.2, 1.6),
            (1.2, 3.5),
            (2.0, 3.5),
        ],
        vec![
            (0.5, 0.6),
            (7.5, 0.6),
            (7.5, 1.1),
            (4.5, 1.1),
            (4.5, 2.8),
            (4.0, 2.8),
        ],
        vec![
            (0.8, 0.8),
            (2.5, 2.0),
            (4.0, 2.0),
            (5.4, 1.0),
            (5.4, 2.5),
            (3.8, 3.0),
        ],
    ]
}

/// A line chart of `series` (name, colour, values; one value per x) over `xs`,
/// each series scaled to its own maximum (labelled), as an SVG document.
pub fn plot(
    title: &str,
    x_label: &str,
    xs: &[f64],
    series: &[(&str, &str, Vec<f64>)],
) -> svg::Document {
    use svg::node::element::{Line, Polyline, Text};
    let (w, h, m) = (800.0, 420.0, 50.0);
    let xmax = xs.iter().cloned().fold(1e-9, f64::max);
    let mut doc = svg::Document::new()
        .set("viewBox", (0, 0, w, h))
        .set("width", w)
        .set("height", h)
        .add(
            svg::node::element::Rectangle::new()
                .set("width", w)
                .set("height", h)
                .set("fill", "white"),
        )
        .add(
            Text::new(title)
                .set("x", m)
                .set("y", 24)
                .set("font-family", "sans-serif")
                .set("font-size", 15),
        )
        .add(
            Text::new(x_label)
                .set("x", w / 2.0)
                .set("y", h - 10.0)
                .set("font-family", "sans-serif")
                .set("font-size", 12),
        )
        .add(
            Line::new()
                .set("x1", m)
                .set("y1", h - m)
                .set("x2", w - m)
                .set("y2", h - m)
                .set("stroke", "black"),
        )
        .add(
            Line::new()
                .set("x1", m)
                .set("y1", m)
                .set("x2", m)
                .set("y2", h - m)
                .set("stroke", "black"),
        )
        .add(
            Text::new(format!("{xmax:.0}"))
                .set("x", w - m - 20.0)
                .set("y", h - m + 16.0)
                .set("font-family", "sans-serif")
                .set("font-size", 11),
        );
    for (k, (name, colour, ys)) in series.iter().enumerate() {
        let ymax = ys.iter().cloned().fold(1e-9, f64::max);
        let pts: String = xs
            .iter()
            .zip(ys)
            .map(|(x, y)| {
                format!(
                    "{:.1},{:.1} ",
                    m + x / xmax * (w - 2.0 * m),
                    h - m - y / ymax * (h - 2.0 * m)
                )
            })
            .collect();
        doc = doc
            .add(
                Polyline::new()
                    .set("points", pts)
                    .set("fill", "none")
                    .set("stroke", *colour)
                    .set("stroke-width", 1.5),
            )
            .add(
                Text::new(format!("{name} (top = {ymax:.0})"))
                    .set("x", m + 10.0)
                    .set("y", m + 16.0 * k as f64)
                    .set("fill", *colour)
                    .set("font-family", "sans-serif")
                    .set("font-size", 12),
            );
    }
    doc
}
