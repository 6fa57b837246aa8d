//! Line features against ground truth: in simulated rectilinear worlds with
//! known walls and σ = 10 mm range noise, every wall part longer than 0.3 m the
//! robot saw is found with end points within 3 cm and angle within 1°, and no
//! map segment longer than 0.1 m lies off the walls. Three noise seeds per world.

mod map_support;

use map_support::*;
use sweepline::geom::Segment;
use sweepline::map::fit::undirected_diff;
use sweepline::map::{Map, MapParams, ScanQuality};
use sweepline::sim::world::World;

fn end_error(m: &Segment, t: &Segment) -> f64 {
    let fwd = (m.a - t.a).norm().max((m.b - t.b).norm());
    let rev = (m.a - t.b).norm().max((m.b - t.a).norm());
    fwd.min(rev)
}

#[test]
fn walls_found_with_end_points_and_angles_in_tolerance() {
    let mut failures = Vec::new();
    let mut worst = (0.0f64, 0.0f64);
    let mut checked = 0;
    for seed in [11, 12, 13] {
        for ((name, text), waypoints) in worlds().iter().zip(world_paths()) {
            let world = World::parse(text).unwrap();
            let poses = path(&waypoints, 0.1);
            let mut r = rng(seed);
            let mut map = Map::new(MapParams::default(), poses[0]).unwrap();
            for p in &poses {
                let s = urg_scan(&world, p, 0.01, &mut r);
                map.update(&s, p, ScanQuality::Good).unwrap();
            }
            map.publish();
            let snap = map.snapshot();
            let seen = seen_intervals(&world, &poses, 80f64.to_radians(), 0.1);
            let mut truth_parts = Vec::new();
            for (wi, ivs) in seen.iter().enumerate() {
                for &(s0, s1) in ivs {
                    if s1 - s0 < 0.3 {
                        continue;
                    }
                    let t = part(&world.walls[wi].seg, s0, s1);
                    truth_parts.push(t);
                    checked += 1;
                    let best = snap
                        .segments
                        .iter()
                        .map(|m| {
                            (
                                undirected_diff(m.seg.angle(), t.angle()).abs().to_degrees(),
                                end_error(&m.seg, &t),
                            )
                        })
                        .min_by(|a, b| a.1.total_cmp(&b.1));
                    match best {
                    Some((ang, end)) if ang <= 1.0 && end <= 0.03 => {
                        worst.0 = worst.0.max(ang);
                        worst.1 = worst.1.max(end);
                    }
                    other => failures.push(format!(
                        "{name} seed {seed}: wall {wi} part {:.2}..{:.2} ({:.2} m): best match {other:?}",
                        s0,
                        s1,
                        s1 - s0
                    )),
                }
                }
            }
            for m in snap.segments.iter().filter(|m| m.length() > 0.1) {
                let on_wall = world.walls.iter().any(|w| {
                    undirected_diff(m.seg.angle(), w.seg.angle()).abs() <= 2f64.to_radians()
                        && w.seg.distance_to(&m.seg.a) <= 0.05
                        && w.seg.distance_to(&m.seg.b) <= 0.05
                });
                if !on_wall {
                    failures.push(format!("{name} seed {seed}: spurious segment {:?}", m.seg));
                }
            }
            let doc = sweepline::map::svg::render(&snap, &truth_parts);
            let file = save_svg(&format!("lines_{name}_{seed}.svg"), &doc);
            eprintln!(
                "{name}: {} scans, {} points, {} segments, {} wall parts checked; picture {}",
                poses.len(),
                snap.points.len(),
                snap.segments.len(),
                truth_parts.len(),
                file.display()
            );
        }
    }
    eprintln!(
        "{checked} wall parts: worst angle error {:.3} deg, worst end point error {:.4} m",
        worst.0, worst.1
    );
    assert!(checked >= 100, "too few wall parts checked: {checked}");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
