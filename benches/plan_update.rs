//! Coverage planner update time on the paper workspace, room known (the
//! decomposition's cells all final): `plan_decision` is an update that plans
//! a new task (configuration space, Dijkstra, lanes of every candidate cell,
//! the tour search), `plan_steady` an update that keeps the current task
//! (configuration space rebuild and the blocked-path check);
//! `plan_decision_plain_distance` is `plan_decision` with travel priced by
//! distance alone (`plan.new_overlap_cost = 0`), the price of the overlap
//! term as a ratio within one run.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use sweepline::config::Config;
use sweepline::decomp::{Decomposer, Decomposition};
use sweepline::grid::Grid;
use sweepline::plan::{CoveragePlanner, PlanParams};
use sweepline::sim::lockstep::{fill_from_truth, grid_for};
use sweepline::sim::world::World;

fn setup() -> (World, Grid, Decomposition) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/hw/worlds/paper.world");
    let world = World::load(std::path::Path::new(path)).expect("paper.world");
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
    c.bench_function("plan_decision", |b| {
        b.iter_batched(
            || CoveragePlanner::new(&params, &cfg.robot).expect("planner"),
            |mut p| black_box(p.update(&grid, &decomp, &world.start, None).expect("plan")),
            BatchSize::SmallInput,
        )
    });
    let plain = PlanParams {
        new_overlap_cost: 0.0,
        ..params.clone()
    };
    c.bench_function("plan_decision_plain_distance", |b| {
        b.iter_batched(
            || CoveragePlanner::new(&plain, &cfg.robot).expect("planner"),
            |mut p| black_box(p.update(&grid, &decomp, &world.start, None).expect("plan")),
            BatchSize::SmallInput,
        )
    });
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

criterion_group!(benches, bench);
criterion_main!(benches);
