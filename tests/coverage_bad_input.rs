//! Bad input to the coverage stack, each with a defined outcome: no cells
//! from the decomposition (no segments), an open room (the far end out of
//! the scanner's range), a robot started inside an obstacle's inflation zone
//! (moves out) or in collision (refused), and a room with a pocket the robot
//! cannot enter (reported as unreachable, not counted as missed).

use sweepline::config::Config;
use sweepline::decomp::Decomposition;
use sweepline::geom::pose;
use sweepline::grid::Grid;
use sweepline::plan::planner::HOME_REACH;
use sweepline::plan::{CoveragePlanner, HomeOutcome, PlanParams, PlanStatus, Task};
use sweepline::sim::lockstep::{run, LockstepError, LockstepOptions, Mode};
use sweepline::sim::world::World;

fn opts() -> LockstepOptions {
    LockstepOptions {
        scan_period: 0.5,
        time_cap: 2400.0,
        ..LockstepOptions::default()
    }
}

#[test]
fn no_cells_at_all_still_covers_by_exploring_then_patches() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/hw/worlds/paper.world");
    let world = World::load(std::path::Path::new(path)).unwrap();
    let o = LockstepOptions {
        use_cells: false,
        ..opts()
    };
    let r = run(&world, &Config::default(), &o, Mode::Online).unwrap();
    let m = &r.metrics;
    eprintln!("{m:?} {:?}", r.stats);
    assert!(r.finished);
    assert_eq!(m.collisions, 0);
    assert_eq!(r.stats.cells, 0);
    assert!(r.stats.patches > 0);
    assert!(m.coverage >= 0.97, "{}", m.coverage);
}

#[test]
fn an_unexplored_map_and_no_segments_first_look_then_explore() {
    let robot = Config::default().robot;
    let mut p = CoveragePlanner::new(&PlanParams::default(), &robot).unwrap();
    let mut grid = Grid::new(nalgebra::Point2::new(-3.0, -3.0), 0.05, 120, 120);
    let empty = Decomposition::default();
    let at = pose(0.0, 0.0, 0.0);
    match p.update(&grid, &empty, &at, None).unwrap() {
        PlanStatus::Working { task, new_path } => {
            assert_eq!(task, Task::LookAround);
            assert!(new_path);
        }
        s => panic!("{s:?}"),
    }
    // Only a 1 m disk around the robot is known free: the rest is unexplored.
    for y in 0..120 {
        for x in 0..120 {
            let c = grid.centre_of((x, y));
            if c.coords.norm() < 1.0 {
                grid.set_state((x, y), sweepline::grid::CellState::Free);
            }
        }
    }
    let s = p.update(&grid, &empty, &at, None).unwrap();
    assert_eq!(
        s,
        PlanStatus::Working {
            task: Task::Explore,
            new_path: true
        }
    );
    // Robot outside the grid: a typed error.
    let e = p
        .update(&grid, &empty, &pose(50.0, 0.0, 0.0), None)
        .unwrap_err();
    assert!(e.to_string().contains("outside the map"), "{e}");
}

#[test]
fn open_room_beyond_the_scanner_range_is_explored_and_covered() {
    // 9 m corridor: from the start the far end (8 m away) is out of range.
    let world = World::parse("room 0 0 9 0 9 2 0 2\nstart 0.6 1.0 0\n").unwrap();
    let r = run(&world, &Config::default(), &opts(), Mode::Online).unwrap();
    let m = &r.metrics;
    eprintln!("{m:?} {:?}", r.stats);
    assert!(r.finished);
    assert_eq!(m.collisions, 0);
    assert!(m.coverage >= 0.99, "{}", m.coverage);
    assert!(r.trajectory.iter().any(|p| p.translation.x > 8.0));
}

#[test]
fn start_inside_the_inflation_zone_moves_out_first() {
    // 0.175 m from the wall: the body is clear (radius 0.17) but inside the
    // planner's clearance (radius + safety margin).
    let world = World::parse("room 0 0 4 0 4 3 0 3\nstart 0.175 1.5 0\n").unwrap();
    let r = run(&world, &Config::default(), &opts(), Mode::Online).unwrap();
    assert!(r.finished);
    assert_eq!(r.metrics.collisions, 0);
    assert!(
        r.tasks.iter().any(|t| t.task == Task::Escape),
        "{:?}",
        r.tasks.iter().map(|t| t.task).collect::<Vec<_>>()
    );
    assert!(r.metrics.coverage >= 0.99, "{}", r.metrics.coverage);
    // Coverage done, it drives back to as near its start as the clearance
    // allows (the start itself is inside it), without a collision.
    let done = r.report.expect("a report");
    assert_eq!(done.home, HomeOutcome::Back);
    let end = r.trajectory.last().unwrap().translation.vector;
    let from = (end - world.start.translation.vector).norm();
    assert!(
        from > 0.0 && from <= HOME_REACH && (from - done.home_distance).abs() < 0.02,
        "ended {from:.3} m from the start, report {done:?}"
    );
}

#[test]
fn start_in_collision_is_refused_with_a_clear_message() {
    let world = World::parse("room 0 0 4 0 4 3 0 3\nbox 1 1 2 2\nstart 1.1 1.5 0\n").unwrap();
    let e = run(&world, &Config::default(), &opts(), Mode::Online).unwrap_err();
    assert!(matches!(e, LockstepError::Start(_)), "{e:?}");
    assert!(e.to_string().contains("overlaps an obstacle"), "{e}");
}

#[test]
fn a_pocket_behind_a_narrow_gap_is_unreachable_not_missed() {
    // A partition at x = 3.5 with a 0.25 m gap: the robot (0.34 m wide) sees
    // through it but cannot pass; the 1.5 m x 3 m pocket is unreachable.
    let text = "room 0 0 5 0 5 3 0 3\nwall 3.5 0 3.5 1.4\nwall 3.5 1.65 3.5 3\nstart 1 1.5 0\n";
    let world = World::parse(text).unwrap();
    let r = run(&world, &Config::default(), &opts(), Mode::Online).unwrap();
    let m = &r.metrics;
    eprintln!("{m:?} {:?}", r.report);
    assert!(r.finished);
    assert_eq!(m.collisions, 0);
    assert!(m.unreachable_area > 4.0, "{}", m.unreachable_area);
    assert!(m.coverage >= 0.99, "{}", m.coverage);
    assert!(r.trajectory.iter().all(|p| p.translation.x < 3.5));
    let report = r.report.unwrap();
    assert!(report.unreachable_area > 0.1, "{report:?}");
}

#[test]
fn bad_settings_are_refused() {
    let mut cfg = Config::default();
    cfg.plan.lane_overlap = f64::NAN;
    let world = World::parse("room 0 0 4 0 4 3 0 3\nstart 2 1.5 0\n").unwrap();
    let e = run(&world, &cfg, &opts(), Mode::Online).unwrap_err();
    assert!(e.to_string().contains("lane_overlap"), "{e}");
    let mut cfg = Config::default();
    cfg.control.heading_gain = -1.0;
    let e = run(&world, &cfg, &opts(), Mode::Online).unwrap_err();
    assert!(e.to_string().contains("heading_gain"), "{e}");
    let mut cfg = Config::default();
    cfg.plan.way_out_passage = -0.5;
    let e = run(&world, &cfg, &opts(), Mode::Online).unwrap_err();
    assert!(e.to_string().contains("plan.way_out_passage"), "{e}");
}
