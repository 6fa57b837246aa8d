//! Decomposition update time (the coverage target: ≤ 5 ms p99 per map update in
//! the largest room).
//!
//! Rooms cut from the IPA floor plans (shared data) are explored scan by scan
//! along a lattice tour; every scan is one map update. Before the criterion
//! groups run, the per-update latency over the whole tour is printed (wall
//! clock and thread CPU time, p50/p99/max): the CPU time is what the update
//! costs, the wall time also holds whatever the scheduler did to us.
//! Criterion then times a steady-state update (fully explored room) and an
//! update after one more scan.

#[path = "../../tests/decomp_support/mod.rs"]
mod decomp_support;

use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use decomp_support::*;
use sweepline::decomp::{DecompParams, Decomposer, PhaseTimes};
use sweepline::grid::Grid;
use sweepline::pipeline::clock::thread_cpu_time;
use sweepline::sim::floorplan::{load_room, MAPS_DIR};
use sweepline::sim::world::World;

/// Floor-plan rooms besides the paper's workspace: the largest planner-sized
/// room we use (lab_f_scan:19, 12.5 × 11.3 m) and a large hall
/// (lab_a_scan:0, 35 × 29 m).
const ROOMS: &[&str] = &["lab_f_scan:19", "lab_a_scan:0"];

fn worlds() -> Vec<(String, World)> {
    let mut out = vec![("paper".to_string(), paper_world())];
    match sweepline::testdata::shared_file(MAPS_DIR) {
        Some(dir) => {
            for spec in ROOMS {
                match load_room(&dir, spec) {
                    Ok(room) => out.push((spec.to_string(), room.world())),
                    Err(e) => eprintln!("skipping {spec}: {e}"),
                }
            }
        }
        None => eprintln!("shared maps missing: benching the paper workspace only"),
    }
    out
}

/// Explores `world` along the tour, one update per scan; returns the
/// decomposer and grid at the end and the per-update (wall, cpu) seconds.
fn tour_run(
    world: &World,
    daemon_grid: bool,
    phases: &mut [f64; 8],
) -> (Decomposer, Grid, Vec<(f64, f64)>) {
    let mut grid = if daemon_grid {
        // The daemon's map grid: 40 m square centred on the first pose.
        let s = world.start.translation;
        Grid::centred(nalgebra::Point2::new(s.x, s.y), 40.0, 0.05)
    } else {
        grid_for(world, 0.05)
    };
    let mut dec = Decomposer::new(&DecompParams::default(), 0.17).unwrap();
    let mut times = Vec::new();
    for p in tour(world, 1.0) {
        scan(world, &mut grid, &p);
        let (w0, c0) = (Instant::now(), thread_cpu_time().as_secs_f64());
        black_box(dec.update(&grid, &[]));
        for (sum, (_, d)) in phases.iter_mut().zip(dec.phase_times().steps()) {
            *sum += d.as_secs_f64();
        }
        times.push((
            w0.elapsed().as_secs_f64(),
            thread_cpu_time().as_secs_f64() - c0,
        ));
    }
    (dec, grid, times)
}

fn report(name: &str, times: &[(f64, f64)], cells: usize, phases: &[f64; 8]) {
    let wall: Vec<f64> = times.iter().map(|t| t.0).collect();
    let cpu: Vec<f64> = times.iter().map(|t| t.1).collect();
    let ms = |v: f64| v * 1e3;
    eprintln!(
        "decomp_update {name}: {} updates, {cells} cells at the end; cpu p50 {:.3} ms p99 {:.3} ms max {:.3} ms; wall p50 {:.3} ms p99 {:.3} ms max {:.3} ms",
        times.len(),
        ms(percentile(&cpu, 0.5)),
        ms(percentile(&cpu, 0.99)),
        ms(percentile(&cpu, 1.0)),
        ms(percentile(&wall, 0.5)),
        ms(percentile(&wall, 0.99)),
        ms(percentile(&wall, 1.0)),
    );
    let steps: Vec<String> = PhaseTimes::default()
        .steps()
        .iter()
        .map(|(n, _)| n)
        .zip(phases)
        .map(|(n, s)| format!("{n} {:.3}", ms(s / times.len().max(1) as f64)))
        .collect();
    eprintln!(
        "decomp_update {name}: mean wall ms by step: {}",
        steps.join(", ")
    );
}

fn bench(c: &mut Criterion) {
    let mut cases: Vec<(String, World, bool)> =
        worlds().into_iter().map(|(n, w)| (n, w, false)).collect();
    cases.insert(1, ("paper-in-40m-grid".to_string(), paper_world(), true));
    for (name, world, daemon_grid) in cases {
        // Three tours: the latency distribution over all their updates.
        let mut all = Vec::new();
        let mut last = None;
        let mut phases = [0.0; 8];
        for _ in 0..3 {
            let (dec, grid, times) = tour_run(&world, daemon_grid, &mut phases);
            all.extend(times);
            last = Some((dec, grid));
        }
        let (dec, grid) = last.unwrap();
        report(&name, &all, dec.decomposition().cells.len(), &phases);
        let mut g = c.benchmark_group(format!("decomp_update/{name}"));
        g.bench_function("steady", |b| {
            let mut d = dec.clone();
            b.iter(|| black_box(d.update(&grid, &[]).cells.len()))
        });
        // One more scan from the middle of the room, then the update.
        let mid = world.start;
        g.bench_function("after_scan", |b| {
            b.iter_batched(
                || {
                    let mut gr = grid.clone();
                    scan(&world, &mut gr, &mid);
                    (dec.clone(), gr)
                },
                |(mut d, gr)| black_box(d.update(&gr, &[]).cells.len()),
                BatchSize::LargeInput,
            )
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
