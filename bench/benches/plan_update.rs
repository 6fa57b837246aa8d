//! Coverage planner update time on the paper workspace, room known (the
//! decomposition's cells all final): `plan_decision` is an update that plans
//! a new task (configuration space, Dijkstra, lanes of every candidate cell,
//! the tour lane by lane through all of them, with its travel searches
//! between lane ends), `plan_decision_by_region` the same choosing one cell
//! (`plan.lane_tour = false`: the tour search over cells), `plan_steady` an update that keeps the current task
//! (configuration space rebuild and the blocked-path check);
//! `plan_decision_plain_distance` is `plan_decision` with travel priced by
//! distance alone (`plan.new_overlap_cost = 0`), the price of the overlap
//! term as a ratio within one run.
//!
//! The group `cspace`, on the 309 m² lab_ipa building map (shared
//! `map.pgm`, explored in full): `after_scan/building` brings the
//! configuration space up to date after one more scan,
//! `unchanged/building` after none, and `whole/building` when every cell
//! changed, which is what each update cost before the rebuild became
//! incremental.
//!
//! `lane_tour/96` orders the largest tour the planner pools
//! (`plan.tour_max_lanes` = 96 lanes: six blocks of 16 parallel 1.5 m
//! lanes in a 9 m × 4 m room, straight-line costs): the tour search alone,
//! its worst case per decision.

#[path = "../../tests/ros_map_support/mod.rs"]
mod ros_map_support;

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use sweepline::config::Config;
use sweepline::decomp::{Decomposer, Decomposition};
use sweepline::grid::Grid;
use sweepline::plan::cspace::CSpace;
use sweepline::plan::tour::{lane_tour, TourCosts};
use sweepline::plan::{CoveragePlanner, PlanParams};
use sweepline::sim::lockstep::{fill_from_truth, grid_for, scan_into};
use sweepline::sim::ros_map;
use sweepline::sim::world::World;

fn setup() -> (World, Grid, Decomposition) {
    let world =
        World::load(&sweepline::testdata::repo_file("hw/worlds/paper.world")).expect("paper.world");
    let mut grid = grid_for(&world, 0.05, 0.5, 0.0);
    fill_from_truth(&world, &mut grid);
    let cfg = Config::default();
    let mut d = Decomposer::new(&cfg.decomp, cfg.robot.radius).expect("decomposer");
    for _ in 0..6 {
        d.update(&grid, &[]);
    }
    (world, grid, d.decomposition().clone())
}

fn bench(c: &mut Criterion) {
    let (world, grid, decomp) = setup();
    let cfg = Config::default();
    let params = PlanParams {
        look_around: false,
        ..cfg.plan.clone()
    };
    let by_region = PlanParams {
        lane_tour: false,
        ..params.clone()
    };
    let plain = PlanParams {
        new_overlap_cost: 0.0,
        ..params.clone()
    };
    for (name, p) in [
        ("plan_decision", &params),
        ("plan_decision_by_region", &by_region),
        ("plan_decision_plain_distance", &plain),
    ] {
        c.bench_function(name, |b| {
            b.iter_batched(
                || CoveragePlanner::new(p, &cfg.robot).expect("planner"),
                |mut p| black_box(p.update(&grid, &decomp, &world.start, None).expect("plan")),
                BatchSize::SmallInput,
            )
        });
    }
    let mut p = CoveragePlanner::new(&params, &cfg.robot).expect("planner");
    p.update(&grid, &decomp, &world.start, None).expect("plan");
    c.bench_function("plan_steady", |b| {
        b.iter(|| {
            black_box(
                p.update(&grid, &decomp, &world.start, Some(0))
                    .expect("plan"),
            )
        })
    });
}

/// The lab_ipa building (shared `map.pgm`, through a map_server YAML written
/// to the bench's scratch folder) with its grid filled from ground truth;
/// `None` (said in one line) when the shared data is missing.
fn building() -> Option<(World, Grid)> {
    let Some(image) = sweepline::testdata::shared_file(ros_map_support::MAP) else {
        eprintln!("shared map.pgm missing: no building case");
        return None;
    };
    let yaml = ros_map_support::write_yaml(
        std::path::Path::new(env!("CARGO_TARGET_TMPDIR")),
        "bench_building.yaml",
        &image,
    );
    let world = ros_map::load_world(&yaml, None, None).expect("building map");
    let mut grid = grid_for(&world, 0.05, 0.5, 0.0);
    fill_from_truth(&world, &mut grid);
    Some((world, grid))
}

fn bench_building(c: &mut Criterion) {
    let Some((world, grid)) = building() else {
        return;
    };
    let cfg = Config::default();
    let inflation = cfg.robot.radius + cfg.plan.safety_margin;
    let mut synced = CSpace::new(inflation, cfg.robot.radius);
    synced.rebuild(&grid);
    let mut scanned = grid.clone();
    scan_into(&world, &world.start, &mut scanned);
    let blank = Grid::new(
        grid.origin(),
        grid.resolution(),
        grid.width(),
        grid.height(),
    );
    let mut g = c.benchmark_group("cspace");
    g.sample_size(20);
    g.bench_function("after_scan/building", |b| {
        b.iter_batched(
            || synced.clone(),
            |mut cs| {
                cs.rebuild(&scanned);
                black_box(cs.traversable.len())
            },
            BatchSize::LargeInput,
        )
    });
    g.bench_function("unchanged/building", |b| {
        let mut cs = synced.clone();
        b.iter(|| {
            cs.rebuild(&grid);
            black_box(cs.traversable.len())
        })
    });
    g.bench_function("whole/building", |b| {
        b.iter_batched(
            || {
                let mut cs = synced.clone();
                cs.rebuild(&blank);
                cs
            },
            |mut cs| {
                cs.rebuild(&scanned);
                black_box(cs.traversable.len())
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

/// Lane ends and straight-line costs of 96 lanes in six blocks of 16.
fn tour_costs() -> (Vec<f64>, Vec<f64>) {
    let mut ends = Vec::new();
    for block in 0..6 {
        let (x0, y0) = (f64::from(block % 3) * 3.0, f64::from(block / 3) * 2.0);
        for k in 0..16 {
            let x = x0 + 0.1 + f64::from(k) * 0.18;
            ends.push((x, y0 + 0.2));
            ends.push((x, y0 + 1.7));
        }
    }
    let d = |p: (f64, f64), q: (f64, f64)| ((p.0 - q.0).powi(2) + (p.1 - q.1).powi(2)).sqrt();
    let start = ends.iter().map(|&e| d((4.5, 2.0), e)).collect();
    let between = ends
        .iter()
        .flat_map(|&p| ends.iter().map(move |&q| d(p, q)))
        .collect();
    (start, between)
}

fn bench_tour(c: &mut Criterion) {
    let (start, between) = tour_costs();
    let costs = TourCosts {
        start: &start,
        between: &between,
    };
    c.bench_function("lane_tour/96", |b| {
        b.iter(|| black_box(lane_tour(black_box(&costs)).len()))
    });
}

criterion_group!(benches, bench, bench_building, bench_tour);
criterion_main!(benches);
