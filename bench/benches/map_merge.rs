//! Speed of one map update (merge with the modified rule + line features +
//! segment correction + grid + snapshot publication) for a 682-beam URG-04LX
//! scan against a map of at least 20,000 points.
//!
//! Run: `cargo bench -p sweepline-bench --bench map_merge -- --warm-up-time 1 --measurement-time 3`.
//! Before criterion runs, the bench prints its own p50 / p99 / max over 10,000
//! updates (with and without snapshot publication).

#[path = "../../tests/map_support/mod.rs"]
mod map_support;

use std::time::Instant;

use criterion::Criterion;
use map_support::*;
use sweepline::geom::Pose;
use sweepline::map::{Map, MapParams, ScanQuality};
use sweepline::pipeline::clock::thread_cpu_time;
use sweepline::pipeline::metrics::quantile_sorted;
use sweepline::scan::LaserScan;
use sweepline::sim::world::World;

/// A 40 × 24 m hall with 138 pillars of 0.8 × 0.8 m and a few partition walls.
fn hall() -> World {
    let mut w = String::from("name hall\nroom 0 0 40 0 40 24 0 24 refl 0.5\n");
    for i in 0..23 {
        for j in 0..6 {
            let (x, y) = (2.5 + i as f64 * 1.6, 2.5 + j as f64 * 3.6);
            let refl = 0.2 + 0.1 * ((i + j) % 8) as f64;
            w.push_str(&format!(
                "box {x} {y} {} {} refl {refl:.1}\n",
                x + 0.8,
                y + 0.8
            ));
        }
    }
    w.push_str("wall 6 0 6 1.5 refl 0.3\nwall 12 24 12 22 refl 0.9\nwall 18 0 18 1.2 refl 0.6\n");
    World::parse(&w).expect("hall world parses")
}

/// A map of ≥ 20,000 points of the hall, and scans (with their poses) from
/// inside the mapped part for timing.
fn setup(params: MapParams) -> (Map, Vec<(LaserScan, Pose)>) {
    let world = hall();
    let mut rows = Vec::new();
    for (k, y) in [1.4, 4.5, 8.0, 11.6, 15.2, 18.8, 22.6].iter().enumerate() {
        if k % 2 == 0 {
            rows.push((0.8, *y));
            rows.push((39.2, *y));
        } else {
            rows.push((39.2, *y));
            rows.push((0.8, *y));
        }
    }
    let poses = path(&rows, 0.1);
    let mut r = rng(77);
    let params = MapParams {
        grid_extent: 48.0,
        ..params
    };
    let mut map = Map::new(params, sweepline::geom::pose(20.0, 12.0, 0.0)).expect("valid params");
    let mut timing = Vec::new();
    for (k, p) in poses.iter().enumerate() {
        let s = urg_scan(&world, p, 0.01, &mut r);
        map.update(&s, p, ScanQuality::Good).expect("finite pose");
        if k % 17 == 0 && timing.len() < 200 {
            timing.push((s, *p));
        }
    }
    assert!(
        map.points().len() >= 20_000,
        "hall map has only {} points",
        map.points().len()
    );
    (map, timing)
}

fn percentiles(label: &str, params: MapParams) {
    let (mut map, scans) = setup(params);
    let n0 = map.points().len();
    let mut wall = Vec::with_capacity(10_000);
    let mut cpu = Vec::with_capacity(10_000);
    for i in 0..10_000 {
        let (s, p) = &scans[i % scans.len()];
        let c0 = thread_cpu_time().as_secs_f64();
        let start = Instant::now();
        let r = map.update(s, p, ScanQuality::Good);
        wall.push(start.elapsed().as_secs_f64() * 1e3);
        cpu.push((thread_cpu_time().as_secs_f64() - c0) * 1e3);
        assert!(r.is_ok());
    }
    for t in [&mut wall, &mut cpu] {
        t.sort_by(f64::total_cmp);
    }
    println!(
        "map update, {label}: map {n0} -> {} points, 682-beam scans, 10000 updates:\n  thread CPU p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms\n  wall clock p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        map.points().len(),
        quantile_sorted(&cpu, 0.5),
        quantile_sorted(&cpu, 0.99),
        cpu[cpu.len() - 1],
        quantile_sorted(&wall, 0.5),
        quantile_sorted(&wall, 0.99),
        wall[wall.len() - 1]
    );
}

fn bench(c: &mut Criterion) {
    let (mut map, scans) = setup(MapParams::default());
    let mut i = 0;
    c.bench_function("map_update_682_beams_20k_points", |b| {
        b.iter(|| {
            let (s, p) = &scans[i % scans.len()];
            i += 1;
            map.update(s, p, ScanQuality::Good)
        })
    });
}

fn main() {
    percentiles("publishing every 5th scan", MapParams::default());
    percentiles(
        "no publication",
        MapParams {
            publish_every: u32::MAX,
            ..Default::default()
        },
    );
    let mut c = Criterion::default().configure_from_args();
    bench(&mut c);
    c.final_summary();
}
