//! Decomposition behaviour: inheritance and finality while exploring,
//! direction from segments and from the grid, adjacency geometry, and the
//! defined outcomes for bad input (nothing explored, open room, robot inside
//! an inflation zone, bad settings, a grid that changes shape).

mod decomp_support;

use std::collections::HashMap;

use decomp_support::*;
use nalgebra::Point2;
use sweepline::decomp::{CellId, CellStatus, DecompError, DecompParams, Decomposer, Decomposition};
use sweepline::geom::{pose, Segment};
use sweepline::grid::{CellState, Grid};
use sweepline::sim::world::World;

fn decomposer() -> Decomposer {
    Decomposer::new(&DecompParams::default(), 0.17).unwrap()
}

/// Distance from `p` to the nearest wall of `world`.
fn wall_clearance(world: &World, p: &Point2<f64>) -> f64 {
    world
        .walls
        .iter()
        .map(|w| w.seg.distance_to(p))
        .fold(f64::INFINITY, f64::min)
}

fn distance_to_polygon(poly: &[Point2<f64>], p: &Point2<f64>) -> f64 {
    (0..poly.len())
        .map(|i| Segment::new(poly[i], poly[(i + 1) % poly.len()]).distance_to(p))
        .fold(f64::INFINITY, f64::min)
}

fn assert_consistent(d: &Decomposition) {
    let mut ids: Vec<CellId> = d.cells.iter().map(|c| c.id).collect();
    ids.dedup();
    assert_eq!(ids.len(), d.cells.len(), "ids are unique and sorted");
    for c in &d.cells {
        assert!(c.polygon.len() >= 3, "cell {:?} has a polygon", c.id);
        assert!(c.area() > 0.0, "cell {:?} is counter-clockwise", c.id);
        assert!(c.width > 0.0 && c.length > 0.0);
    }
    for a in &d.adjacency {
        assert_ne!(a.a, a.b);
        let (ca, cb) = (d.cell(a.a).unwrap(), d.cell(a.b).unwrap());
        let mid = Point2::from((a.boundary.a.coords + a.boundary.b.coords) / 2.0);
        // The shared boundary lies on both outlines (within a slice).
        assert!(distance_to_polygon(&ca.polygon, &mid) < 0.06, "{a:?}");
        assert!(distance_to_polygon(&cb.polygon, &mid) < 0.06, "{a:?}");
    }
    for f in &d.frontiers {
        assert_eq!(
            d.cell(f.cell).map(|c| c.status),
            Some(CellStatus::Open),
            "frontiers belong to open cells"
        );
    }
}

#[test]
fn nothing_explored_gives_an_empty_decomposition() {
    let grid = Grid::new(Point2::new(0.0, 0.0), 0.05, 100, 80);
    let mut dec = decomposer();
    for _ in 0..3 {
        let d = dec.update(&grid, &[]);
        assert!(d.cells.is_empty() && d.adjacency.is_empty() && d.frontiers.is_empty());
    }
    assert!(dec.locked_angle().is_none());
    // Segments alone (no explored floor) give no cells either.
    let segs = [Segment::new(Point2::new(1.0, 1.0), Point2::new(3.0, 1.0))];
    assert!(dec.update(&grid, &segs).cells.is_empty());
    // A degenerate grid.
    let tiny = Grid::new(Point2::new(0.0, 0.0), 0.05, 1, 1);
    assert!(dec.update(&tiny, &[]).cells.is_empty());
}

#[test]
fn explored_free_space_without_walls_is_one_open_cell() {
    let mut grid = Grid::new(Point2::new(0.0, 0.0), 0.05, 120, 120);
    for y in 40..80 {
        for x in 30..90 {
            grid.set_state((x, y), CellState::Free);
        }
    }
    let mut dec = decomposer();
    let d = dec.update(&grid, &[]).clone();
    assert_eq!(d.cells.len(), 1, "{:?}", d.cells);
    assert_eq!(d.cells[0].status, CellStatus::Open);
    assert!(!d.frontiers.is_empty());
    assert_consistent(&d);
    // It never becomes final, however often it is recomposed.
    for _ in 0..10 {
        dec.update(&grid, &[]);
    }
    assert_eq!(dec.decomposition().cells[0].status, CellStatus::Open);
    assert_eq!(dec.decomposition().cells[0].id, d.cells[0].id);
}

#[test]
fn ids_persist_and_finality_arrives_while_exploring() {
    let world = paper_world();
    let mut grid = grid_for(&world, 0.05);
    let mut dec = decomposer();
    // Poses along the room, one scan each, one update per scan.
    let poses: Vec<_> = [
        (0.5, 0.5, 0.0),
        (0.8, 1.2, 0.3),
        (1.4, 1.2, 0.0),
        (2.0, 1.2, 0.0),
        (2.6, 1.0, 0.0),
        (3.2, 1.0, 0.0),
        (3.8, 1.0, 0.0),
        (4.6, 1.0, 0.3),
        (5.3, 1.6, 1.2),
        (5.3, 2.3, 1.6),
        (4.8, 3.1, 2.8),
        (4.0, 3.3, 3.1),
        (3.0, 3.4, 3.1),
        (2.2, 2.7, 3.5),
        (1.0, 2.5, 2.0),
        (0.6, 3.5, 1.6),
        (0.6, 2.0, -1.6),
    ]
    .iter()
    .map(|&(x, y, t)| pose(x, y, t))
    .collect();
    let probe = Point2::new(0.6, 0.6);
    let mut probe_id: Option<CellId> = None;
    let mut final_polygons: HashMap<CellId, Vec<Point2<f64>>> = HashMap::new();
    let mut max_final = 0;
    for p in &poses {
        // The map is updated a few times per pose (the robot turns, scans repeat).
        scan(&world, &mut grid, p);
        for _ in 0..2 {
            let d = dec.update(&grid, &[]);
            assert_consistent(d);
            // The cell holding the start keeps its id.
            let id = d.cell_at(&probe).expect("the start is in a cell");
            assert_eq!(*probe_id.get_or_insert(id), id, "start cell id changed");
            // A final cell stays, unchanged.
            for (id, poly) in &final_polygons {
                let c = d.cell(*id).expect("final cell kept");
                assert_eq!(c.status, CellStatus::Final);
                assert_eq!(&c.polygon, poly);
            }
            for c in d.cells.iter().filter(|c| c.status == CellStatus::Final) {
                final_polygons.entry(c.id).or_insert(c.polygon.clone());
            }
            max_final = max_final.max(final_polygons.len());
        }
    }
    for _ in 0..4 {
        dec.update(&grid, &[]);
    }
    let d = dec.decomposition();
    let finals = d
        .cells
        .iter()
        .filter(|c| c.status == CellStatus::Final)
        .count();
    assert!(finals >= 6, "{finals} final cells: {:?}", d.cells);
    // Nearly all of the room's clear floor lies in final cells.
    let (mut clear, mut in_final) = (0, 0);
    for cy in (0..world.free.height).step_by(3) {
        for cx in (0..world.free.width).step_by(3) {
            let p = world.free.centre_of(cx, cy);
            if world.disk_is_free(&p, 0.25) {
                clear += 1;
                if d.cell_at(&p)
                    .and_then(|id| d.cell(id))
                    .is_some_and(|c| c.status == CellStatus::Final)
                {
                    in_final += 1;
                }
            }
        }
    }
    let share = in_final as f64 / clear as f64;
    assert!(
        share > 0.9,
        "final cells hold {share:.3} of the clear floor"
    );
    // Ids are never reused: the counter only grows.
    assert!(d.cells.iter().all(|c| c.id.0 < 1000));
}

#[test]
fn cells_do_not_reach_into_the_inflation_zone() {
    let world = paper_world();
    let mut grid = grid_for(&world, 0.05);
    let segs = seen_segments(
        &world,
        &[world.start, pose(4.8, 1.0, 1.0), pose(2.0, 3.4, 3.1)],
    );
    for p in [world.start, pose(4.8, 1.0, 1.0), pose(2.0, 3.4, 3.1)] {
        scan(&world, &mut grid, &p);
    }
    let mut dec = decomposer();
    let d = dec.update(&grid, &segs).clone();
    assert_consistent(&d);
    // Every polygon vertex keeps the robot radius from the true walls, less
    // at most half a slice (vertices at slice boundaries).
    for c in &d.cells {
        for v in &c.polygon {
            let clearance = wall_clearance(&world, v);
            assert!(
                clearance > 0.17 - 0.03,
                "cell {:?} vertex {v} at {clearance:.3} m from a wall",
                c.id
            );
        }
    }
}

#[test]
fn direction_follows_segments_of_a_rotated_room() {
    let t = 0.35f64; // 20°
    let (c, s) = (t.cos(), t.sin());
    let rot = |x: f64, y: f64| (3.0 + c * x - s * y, 1.0 + s * x + c * y);
    let corners = [rot(0.0, 0.0), rot(5.0, 0.0), rot(5.0, 3.0), rot(0.0, 3.0)];
    let text = format!(
        "room {} {} {} {} {} {} {} {}\nstart {} {} {}\n",
        corners[0].0,
        corners[0].1,
        corners[1].0,
        corners[1].1,
        corners[2].0,
        corners[2].1,
        corners[3].0,
        corners[3].1,
        rot(2.5, 1.5).0,
        rot(2.5, 1.5).1,
        t
    );
    let world = World::parse(&text).unwrap();
    let mut grid = grid_for(&world, 0.05);
    let poses = [world.start, pose(rot(2.5, 1.5).0, rot(2.5, 1.5).1, t + 3.1)];
    for p in &poses {
        scan(&world, &mut grid, p);
    }
    // Sweeping along the walls (the paper's method; the default snaps every
    // direction onto the grid axes, where the planner's lanes run).
    let along_walls = || {
        let p = DecompParams {
            axis_snap: 0.035,
            ..DecompParams::default()
        };
        Decomposer::new(&p, 0.17).unwrap()
    };
    // With segments: exact.
    let segs = seen_segments(&world, &poses);
    let mut dec = along_walls();
    let d = dec.update(&grid, &segs).clone();
    let a = dec.locked_angle().expect("direction locked");
    let err = ((a - t) * 2.0).sin().abs();
    assert!(err < 1e-3, "angle {a} vs {t}");
    assert_consistent(&d);
    assert_eq!(d.cells.len(), 1, "a rectangle is one cell: {:?}", d.cells);
    // The cell is a rectangle along the room.
    let cell = &d.cells[0];
    assert!((cell.length - (5.0 - 0.34)).abs() < 0.06, "{}", cell.length);
    assert!((cell.width - (3.0 - 0.34)).abs() < 0.06, "{}", cell.width);
    // Without segments: from the grid, within a degree and a half.
    let mut dec = along_walls();
    dec.update(&grid, &[]);
    let a = dec.locked_angle().expect("direction locked");
    assert!(((a - t) * 2.0).sin().abs() < 0.05, "grid angle {a} vs {t}");
    // The default: the sweep lies on a grid axis, the lanes' direction.
    let mut dec = decomposer();
    dec.update(&grid, &segs);
    let a = dec.locked_angle().expect("direction locked");
    assert!(
        (a * 2.0).sin().abs() < 1e-9,
        "default angle {a} not on an axis"
    );
}

#[test]
fn open_room_gives_open_cells_with_frontiers() {
    // A U of thin walls in a huge hall: the scanner cannot see the hall's far
    // walls, so beyond the opening everything stays unexplored.
    let text = "room 0 0 40 0 40 40 0 40\n\
                wall 10 10 14 10\nwall 10 10 10 13\nwall 14 10 14 13\n\
                start 12 11 1.5708\n";
    let world = World::parse(text).unwrap();
    let mut grid = grid_for(&world, 0.05);
    scan(&world, &mut grid, &world.start);
    scan(
        &world,
        &mut grid,
        &pose(12.0, 11.0, -std::f64::consts::FRAC_PI_2),
    );
    let mut dec = decomposer();
    for _ in 0..5 {
        dec.update(&grid, &[]);
    }
    let d = dec.decomposition();
    let out = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("decomp");
    std::fs::create_dir_all(&out).unwrap();
    let doc =
        sweepline::decomp::svg::render(d, &grid, Some(Point2::new(12.0, 11.0)), &[], "open room");
    sweepline::decomp::svg::save_to(&out.join("open_room.svg"), &doc).unwrap();
    assert_consistent(d);
    assert!(!d.cells.is_empty());
    let robot = Point2::new(12.0, 11.0);
    // Inside the U: closed by the walls and the virtual edge across the
    // opening; beyond it, an open cell with the frontier.
    let id = d.cell_at(&robot).expect("robot in a cell");
    assert_ne!(d.cell(id).unwrap().status, CellStatus::Open);
    let beyond = d.neighbours(id).collect::<Vec<_>>();
    assert_eq!(beyond.len(), 1, "{:?}", d.adjacency);
    assert_eq!(d.cell(beyond[0]).unwrap().status, CellStatus::Open);
    assert!(d.frontiers.iter().any(|f| f.cell == beyond[0]));
    let edge = d.adjacency[0].boundary;
    assert!(
        (edge.a.y - 13.0).abs() < 0.2 && (edge.b.y - 13.0).abs() < 0.2,
        "{edge:?}"
    );
    // The U was seen all round: the frontier lies beyond its opening.
    assert!(
        d.frontiers
            .iter()
            .all(|f| f.boundary.a.y > 12.5 && f.boundary.b.y > 12.5),
        "{:?}",
        d.frontiers
    );
}

#[test]
fn robot_inside_an_inflation_zone_is_in_no_cell() {
    let world = paper_world();
    let mut grid = grid_for(&world, 0.05);
    // 8 cm from the left wall: inside the 0.17 m inflation.
    let p = pose(0.08, 2.0, 0.0);
    scan(&world, &mut grid, &p);
    let mut dec = decomposer();
    let d = dec.update(&grid, &[]);
    assert_consistent(d);
    assert!(
        !d.cells.is_empty(),
        "the free space in view is still decomposed"
    );
    assert!(d.cell_at(&Point2::new(0.08, 2.0)).is_none());
    // A place 0.3 m further in is in a cell: the planner can escape there.
    assert!(d.cell_at(&Point2::new(0.45, 2.0)).is_some());
}

#[test]
fn bad_settings_are_refused_with_the_key() {
    let cases: Vec<(DecompParams, &str)> = vec![
        (
            DecompParams {
                resolution: 0.0,
                ..DecompParams::default()
            },
            "resolution",
        ),
        (
            DecompParams {
                resolution: f64::NAN,
                ..DecompParams::default()
            },
            "resolution",
        ),
        (
            DecompParams {
                step_split: -1.0,
                ..DecompParams::default()
            },
            "step_split",
        ),
        (
            DecompParams {
                stable_updates: 0,
                ..DecompParams::default()
            },
            "stable_updates",
        ),
        (
            DecompParams {
                sweep_angle: Some(f64::INFINITY),
                ..DecompParams::default()
            },
            "sweep_angle",
        ),
        (
            DecompParams {
                inflation_margin: 5.0,
                ..DecompParams::default()
            },
            "inflation_margin",
        ),
    ];
    for (p, key) in cases {
        let e = Decomposer::new(&p, 0.17).unwrap_err();
        assert!(matches!(e, DecompError::BadParam { .. }));
        assert!(e.to_string().contains(key), "{e}");
    }
    let e = Decomposer::new(&DecompParams::default(), -0.1).unwrap_err();
    assert!(e.to_string().contains("robot_radius"), "{e}");
    // The shipped table parses into the defaults.
    let cfg = sweepline::config::Config::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/hw/robot.toml"
    )))
    .unwrap();
    assert_eq!(cfg.decomp, DecompParams::default());
}

#[test]
fn forced_sweep_angle_is_used() {
    let world = paper_world();
    let mut grid = grid_for(&world, 0.05);
    scan(&world, &mut grid, &world.start);
    let mut dec = Decomposer::new(
        &DecompParams {
            sweep_angle: Some(std::f64::consts::FRAC_PI_2),
            ..DecompParams::default()
        },
        0.17,
    )
    .unwrap();
    let d = dec.update(&grid, &[]);
    assert!((d.sweep_angle - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    assert!(d
        .cells
        .iter()
        .all(|c| (c.sweep_angle - std::f64::consts::FRAC_PI_2).abs() < 1e-12));
    assert_consistent(d);
}

#[test]
fn a_grid_of_another_shape_starts_afresh() {
    let world = paper_world();
    let mut grid = grid_for(&world, 0.05);
    scan(&world, &mut grid, &world.start);
    let mut dec = decomposer();
    for _ in 0..5 {
        dec.update(&grid, &[]);
    }
    let before = dec.decomposition().cells.len();
    assert!(before > 0);
    let max_id = dec
        .decomposition()
        .cells
        .iter()
        .map(|c| c.id.0)
        .max()
        .unwrap();
    let mut other = grid_for(&world, 0.1);
    scan(&world, &mut other, &world.start);
    let d = dec.update(&other, &[]);
    assert!(!d.cells.is_empty());
    assert!(d.cells.iter().all(|c| c.status != CellStatus::Final));
    // Ids are never reused.
    assert!(d.cells.iter().all(|c| c.id.0 > max_id));
}

#[test]
fn the_same_input_gives_the_same_output() {
    let world = paper_world();
    let mut grid = grid_for(&world, 0.05);
    for p in [world.start, pose(4.0, 1.0, 0.5)] {
        scan(&world, &mut grid, &p);
    }
    let run = || {
        let mut dec = decomposer();
        (0..4)
            .map(|_| dec.update(&grid, &[]).clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(run(), run());
}

/// A fully known grid: `room` (x0, y0, x1, y1 in m) with one-cell walls
/// around, free inside except the filled `boxes`.
fn known_grid(room: (f64, f64, f64, f64), boxes: &[(f64, f64, f64, f64)]) -> Grid {
    let res = 0.05;
    let mut g = Grid::new(Point2::new(-1.0, -1.0), res, 200, 160);
    for y in 0..g.height() {
        for x in 0..g.width() {
            let p = g.centre_of((x, y));
            let inside =
                |b: &(f64, f64, f64, f64)| p.x > b.0 && p.x < b.2 && p.y > b.1 && p.y < b.3;
            let grown = (room.0 - res, room.1 - res, room.2 + res, room.3 + res);
            let s = if inside(&room) && !boxes.iter().any(inside) {
                CellState::Free
            } else if inside(&grown) || boxes.iter().any(inside) {
                CellState::Occupied
            } else {
                CellState::Unknown
            };
            g.set_state((x, y), s);
        }
    }
    g
}

#[test]
fn one_obstacle_gives_the_four_boustrophedon_cells() {
    let grid = known_grid((0.0, 0.0, 6.0, 4.0), &[(2.0, 1.5, 3.0, 2.5)]);
    let mut dec = decomposer();
    let d = dec.update(&grid, &[]).clone();
    assert_consistent(&d);
    assert!(d.sweep_angle.abs() < 1e-12, "lanes along the long side");
    assert_eq!(d.cells.len(), 4, "{:#?}", d.cells);
    let r = 0.17;
    let at = |x: f64, y: f64| d.cell_at(&Point2::new(x, y)).unwrap();
    let (below, left, right, above) = (at(3.0, 0.5), at(1.0, 2.0), at(5.0, 2.0), at(3.0, 3.5));
    let mut ids = vec![below, left, right, above];
    ids.sort();
    ids.dedup();
    assert_eq!(ids.len(), 4);
    // Adjacency: below–left, below–right, left–above, right–above.
    let adj = |a: CellId, b: CellId| {
        d.adjacency
            .iter()
            .any(|x| (x.a == a && x.b == b) || (x.a == b && x.b == a))
    };
    assert!(adj(below, left) && adj(below, right) && adj(left, above) && adj(right, above));
    assert!(!adj(left, right) && !adj(below, above));
    assert_eq!(d.adjacency.len(), 4);
    // Sizes: the bottom cell spans the room and reaches the inflated box.
    let b = d.cell(below).unwrap();
    assert!((b.length - (6.0 - 2.0 * r)).abs() < 0.06, "{}", b.length);
    assert!((b.width - (1.5 - r - r)).abs() < 0.06, "{}", b.width);
    // The left cell: between the wall and the inflated box, a little longer
    // where its first and last slices pass under the box's rounded corners.
    let l = d.cell(left).unwrap();
    assert!(
        l.length > 2.0 - 2.0 * r - 0.03 && l.length < 2.0,
        "{}",
        l.length
    );
    // Everything is closed: after the configured number of unchanged
    // updates every cell is final.
    for _ in 0..DecompParams::default().stable_updates {
        assert!(dec
            .decomposition()
            .cells
            .iter()
            .all(|c| c.status != CellStatus::Open));
        dec.update(&grid, &[]);
    }
    assert!(dec
        .decomposition()
        .cells
        .iter()
        .all(|c| c.status == CellStatus::Final));
}

#[test]
fn a_reflex_corner_splits_an_l_shaped_room_into_rectangles() {
    // L: 6 × 4 m minus the top-right 3 × 2 m.
    let grid = known_grid((0.0, 0.0, 6.0, 4.0), &[(3.0, 2.0, 6.5, 4.5)]);
    let mut dec = decomposer();
    let d = dec.update(&grid, &[]).clone();
    assert_consistent(&d);
    assert_eq!(d.cells.len(), 2, "{:#?}", d.cells);
    for c in &d.cells {
        // Rectangles (but for the inflated corner's rounding).
        assert!(c.polygon.len() <= 8, "{:?}", c.polygon);
        assert!(c.area() > 0.97 * c.width * c.length, "{c:?}");
    }
    // The C-space keeps exactly the robot radius from the walls.
    let lower = d.cell_at(&Point2::new(1.0, 1.0)).unwrap();
    let lower = d.cell(lower).unwrap();
    assert!(
        (lower.length - (6.0 - 0.34)).abs() < 0.01,
        "{}",
        lower.length
    );
    assert_eq!(d.adjacency.len(), 1);
    // The virtual edge extends the corner's wall along the lanes to the far wall.
    let e = d.adjacency[0].boundary;
    assert!((e.a.x - e.b.x).abs() > 2.5, "{e:?}");
}

#[test]
fn a_noisy_map_still_gives_a_sane_decomposition() {
    use rand::{Rng, SeedableRng};
    let world = paper_world();
    let mut grid = grid_for(&world, 0.05);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut dec = decomposer();
    let probe = Point2::new(0.6, 0.6);
    let mut probe_id = None;
    for p in tour(&world, 0.8) {
        for _ in 0..3 {
            let off = (
                (rng.random::<f64>() - 0.5) * 0.04,
                (rng.random::<f64>() - 0.5) * 0.04,
                (rng.random::<f64>() - 0.5) * 0.01,
            );
            noisy_scan(&world, &mut grid, &p, 0.01, off, &mut rng);
            let d = dec.update(&grid, &[]);
            assert_consistent(d);
            if let Some(id) = d.cell_at(&probe) {
                assert_eq!(*probe_id.get_or_insert(id), id, "start cell id changed");
            }
        }
    }
    let d = dec.decomposition();
    let out = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("decomp");
    std::fs::create_dir_all(&out).unwrap();
    let doc = sweepline::decomp::svg::render(d, &grid, None, &[], "noisy map");
    sweepline::decomp::svg::save_to(&out.join("paper_noisy.svg"), &doc).unwrap();
    assert!(d.cells.len() <= 25, "{} cells", d.cells.len());
    let (mut clear, mut inside) = (0, 0);
    for cy in (0..world.free.height).step_by(3) {
        for cx in (0..world.free.width).step_by(3) {
            let p = world.free.centre_of(cx, cy);
            if world.disk_is_free(&p, 0.3) {
                clear += 1;
                inside += d.cell_at(&p).is_some() as usize;
            }
        }
    }
    let share = inside as f64 / clear as f64;
    assert!(share > 0.95, "cells hold {share:.3} of the clear floor");
}

#[test]
fn slanted_and_round_walls_give_trapezoids_and_polylines() {
    // A room whose right wall is slanted, with a round pillar (16-gon).
    let mut text = String::from("room 0 0 6 0 5 4 0 4\n");
    let pillar: Vec<String> = (0..16)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 16.0;
            format!("{:.4} {:.4}", 2.5 + 0.4 * a.cos(), 2.0 + 0.4 * a.sin())
        })
        .collect();
    text.push_str(&format!("polygon {}\nstart 1 1 0\n", pillar.join(" ")));
    let world = World::parse(&text).unwrap();
    let mut grid = grid_for(&world, 0.05);
    let poses = [
        pose(1.0, 1.0, 0.0),
        pose(4.0, 3.0, 3.1),
        pose(1.0, 3.0, -1.0),
        pose(4.0, 0.8, 2.0),
    ];
    for p in &poses {
        scan(&world, &mut grid, p);
    }
    let segs = seen_segments(&world, &poses);
    let mut dec = Decomposer::new(
        &DecompParams {
            sweep_angle: Some(0.0),
            ..DecompParams::default()
        },
        0.17,
    )
    .unwrap();
    let d = dec.update(&grid, &segs).clone();
    assert_consistent(&d);
    let out = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("decomp");
    std::fs::create_dir_all(&out).unwrap();
    let doc = sweepline::decomp::svg::render(&d, &grid, None, &segs, "slanted wall, round pillar");
    sweepline::decomp::svg::save_to(&out.join("slanted_round.svg"), &doc).unwrap();
    // Left and right of the pillar: one side of each follows the pillar's
    // curve (a polyline of several vertices).
    let left = d.cell(d.cell_at(&Point2::new(1.0, 2.0)).unwrap()).unwrap();
    let right = d.cell(d.cell_at(&Point2::new(4.0, 2.0)).unwrap()).unwrap();
    assert_ne!(left.id, right.id);
    assert!(left.polygon.len() >= 6, "{:?}", left.polygon);
    // The right cell has the slanted wall as a side: an edge neither along
    // nor across the lanes.
    let slanted = (0..right.polygon.len()).any(|i| {
        let (a, b) = (
            right.polygon[i],
            right.polygon[(i + 1) % right.polygon.len()],
        );
        let dx = (b.x - a.x).abs();
        let dy = (b.y - a.y).abs();
        dx > 0.1 && dy > 0.4
    });
    assert!(slanted, "{:?}", right.polygon);
    // Clearance from every wall, curved ones included: every vertex lies
    // within half a slice of a slice point with full clearance.
    for c in &d.cells {
        for v in &c.polygon {
            let clearance = wall_clearance(&world, v);
            assert!(clearance > 0.17 - 0.025 - 1e-3, "{v} at {clearance:.3} m");
        }
    }
}

#[test]
fn degenerate_grids_and_segments_do_not_panic() {
    let mut dec = decomposer();
    // Zero and non-finite geometry, with something marked explored.
    for (origin, res) in [
        (Point2::new(0.0, 0.0), 0.0),
        (Point2::new(f64::NAN, 0.0), 0.05),
        (Point2::new(0.0, 0.0), f64::INFINITY),
        (Point2::new(1e9, -1e9), 0.05),
    ] {
        let mut g = Grid::new(origin, res, 20, 10);
        for x in 2..18 {
            g.set_state((x, 5), CellState::Free);
        }
        g.set_state((1, 5), CellState::Occupied);
        let d = dec.update(&g, &[]);
        assert_consistent(d);
    }
    // Non-finite segments are ignored (a zero-length one is a point wall,
    // here outside the explored square).
    let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 60, 60);
    for y in 10..50 {
        for x in 10..50 {
            g.set_state((x, y), CellState::Free);
        }
    }
    let segs = [
        Segment::new(Point2::new(f64::NAN, 1.0), Point2::new(2.0, 1.0)),
        Segment::new(Point2::new(2.9, 2.9), Point2::new(2.9, 2.9)),
        Segment::new(Point2::new(0.0, f64::INFINITY), Point2::new(2.0, 1.0)),
    ];
    let d = dec.update(&g, &segs);
    assert_consistent(d);
    assert_eq!(d.cells.len(), 1);
}
