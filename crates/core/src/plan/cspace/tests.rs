//! Tests of the configuration space.

use super::*;
use crate::grid::{CellState, Grid};

#[test]
fn offsets_around_a_cell_stay_inside_the_frame() {
    let f = Frame {
        origin: Point2::origin(),
        res: 0.05,
        w: 4,
        h: 3,
    };
    let offsets = [(0, 0), (-1, 0), (1, 1), (0, -1), (3, 0), (0, 2)];
    // Cell (0, 0): left and below are outside; (3, 0) is the last column.
    let got: Vec<usize> = f.around(0, &offsets).collect();
    assert_eq!(got, vec![0, 5, 3, 8]);
    // Cell (3, 2), the last: only itself, left and below.
    let got: Vec<usize> = f.around(11, &offsets).collect();
    assert_eq!(got, vec![11, 10, 7]);
}

fn room_grid() -> Grid {
    // 4 m x 3 m room with a wall from (2, 0) to (2, 2): free except walls.
    let mut g = Grid::new(Point2::new(-0.5, -0.5), 0.05, 100, 80);
    for y in 0..80 {
        for x in 0..100 {
            let p = g.centre_of((x, y));
            let wall = p.x < 0.0 || p.y < 0.0 || p.x > 4.0 || p.y > 3.0;
            let inner = (p.x - 2.0).abs() < 0.05 && p.y < 2.0;
            let s = if wall || inner {
                CellState::Occupied
            } else {
                CellState::Free
            };
            let outside = p.x < -0.1 || p.y < -0.1 || p.x > 4.1 || p.y > 3.1;
            g.set_state((x, y), if outside { CellState::Unknown } else { s });
        }
    }
    g
}

/// A 40 x 20 grid of 5 cm cells, the first `free_cols` columns seen
/// free, the rest unknown; a beam along row 10 ended at `x`, then ten
/// beams across that row passed through the cell there. Returns the
/// grid and the row's centre y.
fn hit_then_passed(free_cols: usize, x: f64) -> (Grid, f64) {
    let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 40, 20);
    for y in 0..20 {
        for c in 0..free_cols {
            g.set_state((c, y), CellState::Free);
        }
    }
    let y = 10.5 * 0.05;
    g.integrate_ray(&Point2::new(0.1, y), &Point2::new(x, y), true);
    for _ in 0..10 {
        g.integrate_ray(&Point2::new(x, 0.1), &Point2::new(x, 0.9), false);
    }
    (g, y)
}

#[test]
fn a_cell_a_beam_ended_in_is_no_frontier() {
    // Seen free up to x = 1.0 (cells 0..20), unknown beyond; a beam
    // once ended in cell (19, 10) and later beams made it free again:
    // a surface lies there, so it is no way into unknown space.
    let (g, _) = hit_then_passed(20, 0.97);
    assert_eq!(g.state((19, 10)), CellState::Free);
    let mut c = CSpace::new(0.2, 0.17);
    c.rebuild(&g);
    let mut list = Vec::new();
    c.frontier(&mut list);
    let f = c.frame;
    assert!(!list.contains(&(10 * f.w + 19)), "the hit cell");
    assert!(list.contains(&(9 * f.w + 19)) && list.contains(&(11 * f.w + 19)));
    assert_eq!(list.len(), 17, "{list:?}");
}

#[test]
fn unexplored_space_is_seen_only_along_a_clear_line() {
    // Room of `room_grid`; unknown cells (30..33, 50..53) behind a wall
    // piece (x = 29, y 45..58), with free floor all round the rest.
    let mut g = room_grid();
    for y in 45..58 {
        g.set_state((29, y), CellState::Occupied);
    }
    for y in 50..53 {
        for x in 30..33 {
            g.set_state((x, y), CellState::Unknown);
        }
    }
    let mut c = CSpace::new(0.2, 0.17);
    c.rebuild(&g);
    let w = c.frame.w;
    let at = |x: usize, y: usize| y * w + x;
    // Frontier cell (33, 51), right of the pocket: seen from the right
    // and from above, not from the left through the wall piece.
    assert!(c.sees_unknown_beside(at(45, 51), at(33, 51)));
    assert!(c.sees_unknown_beside(at(40, 60), at(33, 51)));
    assert!(!c.sees_unknown_beside(at(20, 51), at(33, 51)));
    // Frontier cell (31, 53), above it: seen from above, and past the
    // wall piece's top end from the upper left.
    assert!(c.sees_unknown_beside(at(31, 60), at(31, 53)));
    assert!(c.sees_unknown_beside(at(28, 68), at(31, 53)));
    // A cell with no unknown neighbour has nothing to see.
    assert!(!c.sees_unknown_beside(at(45, 51), at(40, 51)));
}

#[test]
fn a_free_cell_holding_a_surface_keeps_the_body_off_it() {
    // A chair leg filling part of cell (20, 10): beams passing beside
    // it made the cell free on balance, yet one ended in it.
    let (mut g, y) = hit_then_passed(40, 1.02);
    let leg = (20, 10);
    assert_eq!(g.state(leg), CellState::Free);
    assert!(g.holds_surface(leg));
    let mut c = CSpace::new(0.2, 0.17);
    c.rebuild(&g);
    let f = c.frame;
    let near = f.index_of(&Point2::new(1.02 - 0.12, y)).unwrap();
    let far = f.index_of(&Point2::new(1.02 - 0.3, y)).unwrap();
    assert!(!c.traversable[near] && !c.collision_free[near]);
    assert!(!c.body_clear(near));
    assert!(c.traversable[far] && c.collision_free[far]);
    // Once enough beams pass with none ending there, it is gone.
    for _ in 0..crate::grid::HIT_CREDIT {
        g.integrate_ray(&Point2::new(1.02, 0.1), &Point2::new(1.02, 0.9), false);
    }
    c.rebuild(&g);
    assert!(c.traversable[near] && c.collision_free[near]);
}

#[test]
fn a_path_is_blocked_where_the_body_itself_touches_a_surface_not_where_its_cell_would() {
    // The chair-leg cell (20, 10), the square [1.00, 1.05] x [0.50, 0.55].
    let (g, _) = hit_then_passed(40, 1.02);
    let mut c = CSpace::new(0.2, 0.17);
    c.rebuild(&g);
    // In cell (17, 8), whose centre is 0.146 m from the square, at its
    // far corner: 0.178 m from the square, clear of a 0.17 m body.
    let clear = Point2::new(0.852, 0.402);
    assert!(!c.collision_free[c.frame.index_of(&clear).unwrap()]);
    assert_eq!(c.first_unsafe(&clear, &clear), None);
    assert!(c.segment_safe(&Point2::new(0.5, 0.402), &clear));
    // In the same cell nearer the leg: 0.153 m, the body touches it.
    let touching = Point2::new(0.87, 0.42);
    assert_eq!(c.first_unsafe(&touching, &touching), Some(touching));
    assert!(!c.segment_safe(&clear, &touching));
    // Off the map is never safe.
    let off = Point2::new(-0.1, 0.4);
    assert_eq!(c.first_unsafe(&off, &off), Some(off));
}

#[test]
fn a_surface_let_go_keeps_blocking_for_the_hold_and_held_again_starts_it_over() {
    // The chair-leg cell of the test above, held and let go by turns.
    let (mut g, y) = hit_then_passed(40, 1.02);
    let let_go = |g: &mut Grid| {
        for _ in 0..crate::grid::HIT_CREDIT {
            g.integrate_ray(&Point2::new(1.02, 0.1), &Point2::new(1.02, 0.9), false);
        }
    };
    let mut c = CSpace::new(0.2, 0.17);
    c.set_surface_hold(3);
    c.rebuild(&g);
    let near = c.frame.index_of(&Point2::new(1.02 - 0.12, y)).unwrap();
    assert!(!c.collision_free[near]);
    let_go(&mut g);
    assert!(!g.holds_surface((20, 10)));
    // Still blocking for three rebuilds, then gone.
    for k in 0..3 {
        c.rebuild(&g);
        assert!(
            !c.traversable[near] && !c.collision_free[near],
            "rebuild {k}"
        );
    }
    c.rebuild(&g);
    assert!(c.traversable[near] && c.collision_free[near]);
    // Hit again, let go, hit again before the release: the hold counts
    // from the last letting go.
    g.integrate_ray(&Point2::new(0.1, y), &Point2::new(1.02, y), true);
    c.rebuild(&g);
    assert!(!c.collision_free[near]);
    let_go(&mut g);
    c.rebuild(&g);
    c.rebuild(&g);
    g.integrate_ray(&Point2::new(0.1, y), &Point2::new(1.02, y), true);
    c.rebuild(&g);
    let_go(&mut g);
    for k in 0..3 {
        c.rebuild(&g);
        assert!(
            !c.collision_free[near],
            "rebuild {k} after the second letting go"
        );
    }
    c.rebuild(&g);
    assert!(c.collision_free[near]);
    // Without a hold (the default) the cell clears at once.
    let mut plain = CSpace::new(0.2, 0.17);
    g.integrate_ray(&Point2::new(0.1, y), &Point2::new(1.02, y), true);
    plain.rebuild(&g);
    assert!(!plain.collision_free[near]);
    let_go(&mut g);
    plain.rebuild(&g);
    assert!(plain.collision_free[near]);
}

#[test]
fn a_surface_just_inside_a_long_face_is_not_held_and_one_beside_a_short_one_is() {
    // Cell (20, 10) at x = 1.00..1.05 m, a beam once ended in it and
    // later beams passed: a wall face at x = 1.05 m (column 21
    // occupied) over 5 rows or more makes it noise on the face, let go
    // at once; beside 3 rows (a post) it is held like a chair leg.
    for (rows, held) in [
        (0..20, false),
        (6..15, false),
        (8..13, false),
        (9..12, true),
    ] {
        let (mut g, _) = hit_then_passed(21, 1.02);
        for y in rows.clone() {
            g.set_state((21, y), CellState::Occupied);
        }
        g.integrate_ray(
            &Point2::new(0.1, 10.5 * 0.05),
            &Point2::new(1.02, 10.5 * 0.05),
            true,
        );
        let mut c = CSpace::new(0.2, 0.17);
        c.set_surface_hold(100);
        c.rebuild(&g);
        let cell = 10 * c.frame.w + 20;
        assert!(c.held[cell], "rows {rows:?}: held while the grid holds it");
        for _ in 0..crate::grid::HIT_CREDIT {
            g.integrate_ray(&Point2::new(1.02, 0.1), &Point2::new(1.02, 0.9), false);
        }
        assert!(!g.holds_surface((20, 10)));
        c.rebuild(&g);
        assert_eq!(c.held[cell], held, "rows {rows:?}");
    }
}

#[test]
fn a_surface_kept_only_by_the_hold_is_let_go_on_request_and_one_still_held_is_not() {
    let (mut g, y) = hit_then_passed(40, 1.02);
    let mut c = CSpace::new(0.2, 0.17);
    c.set_surface_hold(100);
    c.rebuild(&g);
    let near = c.frame.index_of(&Point2::new(1.02 - 0.12, y)).unwrap();
    // Held by the grid: nothing to let go.
    assert!(c.release_held().is_empty());
    assert!(!c.collision_free[near]);
    for _ in 0..crate::grid::HIT_CREDIT {
        g.integrate_ray(&Point2::new(1.02, 0.1), &Point2::new(1.02, 0.9), false);
    }
    c.rebuild(&g);
    assert!(!c.traversable[near] && !c.collision_free[near]);
    // Kept only by the hold: let go at once, and the clearance with it.
    let cell = c.frame.index_of(&Point2::new(1.02, y)).unwrap();
    assert_eq!(c.release_held(), vec![cell]);
    assert!(c.traversable[near] && c.collision_free[near]);
    // As a fresh configuration space of the same grid says.
    let mut fresh = CSpace::new(0.2, 0.17);
    fresh.rebuild(&g);
    assert_eq!(fresh.traversable, c.traversable);
    assert_eq!(fresh.collision_free, c.collision_free);
    // Nothing pending any more; the next rebuild keeps it let go.
    assert!(c.release_held().is_empty());
    c.rebuild(&g);
    assert!(c.collision_free[near]);
}

#[test]
fn inflation_keeps_the_centre_off_walls() {
    let mut c = CSpace::new(0.2, 0.17);
    c.rebuild(&room_grid());
    let f = c.frame;
    assert!(c.traversable[f.index_of(&Point2::new(1.0, 1.0)).unwrap()]);
    assert!(!c.traversable[f.index_of(&Point2::new(0.12, 1.0)).unwrap()]);
    assert!(!c.traversable[f.index_of(&Point2::new(1.85, 1.0)).unwrap()]);
    assert!(c.traversable[f.index_of(&Point2::new(1.7, 1.0)).unwrap()]);
}

#[test]
fn the_blocker_of_a_centre_in_the_clearance_is_the_nearest_wall_cell() {
    let mut c = CSpace::new(0.2, 0.17);
    let mut g = room_grid();
    c.rebuild(&g);
    assert_eq!(c.blocker(&Point2::new(1.0, 1.0)), None);
    // The inner wall's cells span x 1.95-2.05 (centres 1.975, 2.025):
    // from x = 1.85 the nearest edge is 0.1 m away.
    let b = c.blocker(&Point2::new(1.85, 1.0)).unwrap();
    assert_eq!(b.kind, BlockerKind::Obstacle);
    assert!((b.distance - 0.1).abs() < 1e-9, "{}", b.distance);
    assert!((b.at.x - 1.975).abs() < 1e-9 && (b.at.y - 1.0).abs() < 0.026);
    // Floor not seen yet blocks as well, and is named so.
    g.set_state(
        g.cell_of(&Point2::new(1.0, 1.15)).unwrap(),
        CellState::Unknown,
    );
    c.rebuild(&g);
    let b = c.blocker(&Point2::new(1.0, 1.0)).unwrap();
    assert_eq!(b.kind, BlockerKind::Unexplored);
    assert!(b.distance < 0.2);
    assert!(c.blocker(&Point2::new(-9.0, 1.0)).is_none());
}

#[test]
fn linked_travel_is_an_upper_bound_close_to_whole_grid_searches() {
    let mut c = CSpace::new(0.2, 0.17);
    c.rebuild(&room_grid());
    let f = c.frame;
    let cells: Vec<usize> = [
        (1.0, 0.5),
        (3.0, 0.5),
        (0.6, 2.6),
        (3.5, 2.5),
        (1.0, 0.5),
        (2.0, 2.5),
        (1.5, 1.5),
        (2.6, 1.5),
    ]
    .iter()
    .map(|&(x, y)| f.index_of(&Point2::new(x, y)).unwrap())
    .collect();
    c.distances_from(cells[2]);
    let before = c.dist.clone();
    let mut m = Vec::new();
    c.travel_linked(&cells, &mut m);
    // The whole-grid distances are left alone.
    assert_eq!(c.dist, before);
    let k = cells.len();
    for (a, &ca) in cells.iter().enumerate() {
        c.distances_from(ca);
        for (b, &cb) in cells.iter().enumerate() {
            let (got, exact) = (m[a * k + b], c.dist[cb]);
            assert!(got >= exact - 1e-9, "{a} {b}: {got} below {exact}");
            assert!(got <= exact * 1.25 + 1e-9, "{a} {b}: {got} vs {exact}");
        }
    }
    // Around the wall, never through it; a cell listed twice is one.
    assert!(m[1] > 4.0 && m[1] < 5.5, "{}", m[1]);
    assert_eq!(m[4], 0.0);
    // A cell inside the wall is unreachable from everywhere.
    let wall = f.index_of(&Point2::new(2.0, 0.5)).unwrap();
    c.travel_linked(&[cells[0], wall], &mut m);
    assert!(m[1].is_infinite() && m[2].is_infinite());
    assert_eq!(m[0], 0.0);
}

#[test]
fn paths_go_around_the_wall_never_through() {
    let mut c = CSpace::new(0.2, 0.17);
    c.rebuild(&room_grid());
    let f = c.frame;
    let a = f.index_of(&Point2::new(1.0, 0.5)).unwrap();
    let b = f.index_of(&Point2::new(3.0, 0.5)).unwrap();
    c.distances_from(a);
    let d = c.dist[b];
    // Up past the wall end at y = 2 (+0.2 clearance) and down again.
    assert!(d > 4.0 && d < 5.0, "{d}");
    let p = c.path_to(b).unwrap();
    for s in p.windows(2) {
        assert!(c.segment_clear(&s[0], &s[1]));
    }
    assert!(p.iter().any(|q| q.y > 2.1));
    let q = c.astar(a, b).unwrap();
    let len: f64 = q.windows(2).map(|s| (s[1] - s[0]).norm()).sum();
    // Line of sight shortens the 8-connected detour, never below the taut string.
    assert!(len <= d + 1e-9 && len > 4.0, "{len} vs {d}");
    assert!(q.len() < 8, "{q:?}");
}

#[test]
fn dear_cells_are_avoided_unless_the_detour_costs_more() {
    let mut c = CSpace::new(0.2, 0.17);
    c.rebuild(&room_grid());
    let f = c.frame;
    let a = f.index_of(&Point2::new(0.5, 0.5)).unwrap();
    let b = f.index_of(&Point2::new(1.5, 0.5)).unwrap();
    let length = |p: &[Point2<f64>]| -> f64 { p.windows(2).map(|s| (s[1] - s[0]).norm()).sum() };
    // A band of swept floor across the straight way, open above y = 1.2.
    let band = |c: &CSpace, i: usize, w: f64| {
        let p = c.frame.centre(i);
        if (0.8..1.2).contains(&p.x) && p.y < 1.2 {
            w
        } else {
            0.0
        }
    };
    for (w, detour) in [(20.0, true), (0.5, false)] {
        let extra: Vec<f64> = (0..f.len()).map(|i| band(&c, i, w)).collect();
        c.set_extra_cost(|i| extra[i]);
        c.distances_from(a);
        let p = c.path_to(b).unwrap();
        let q = c.astar(a, b).unwrap();
        for path in [&p, &q] {
            assert_eq!(path.iter().any(|q| q.y > 1.2), detour, "w {w}: {path:?}");
            if !detour {
                assert!((length(path) - 1.0).abs() < 0.01, "{path:?}");
            }
        }
    }
    // Negative factors count as none.
    c.set_extra_cost(|_| -3.0);
    c.distances_from(a);
    assert!((c.dist[b] - 1.0).abs() < 1e-9, "{}", c.dist[b]);
}

#[test]
fn unexplored_grid_has_no_traversable_cell() {
    let mut c = CSpace::new(0.2, 0.17);
    c.rebuild(&Grid::new(Point2::new(0.0, 0.0), 0.05, 20, 20));
    assert!(c.traversable.iter().all(|t| !t));
    c.distances_from(0);
    assert!(c.path_to(5).is_none());
    assert!(c.astar(0, 5).is_none());
}

#[test]
fn incremental_rebuild_matches_a_fresh_one() {
    // Random edits to a 60 x 50 grid of mostly free floor: small boxes
    // of occupied or unknown cells, larger free ones, beams that leave
    // or wear off held surfaces. After each, the configuration space
    // kept up to date incrementally must equal one built from scratch.
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = |n: usize| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed % n as u64) as usize
    };
    let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 60, 50);
    for y in 0..50 {
        for x in 0..60 {
            g.set_state((x, y), CellState::Free);
        }
    }
    let mut kept = CSpace::new(0.2, 0.17);
    for step in 0..400 {
        let (x, y) = (next(60), next(50));
        let s = match next(10) {
            0..=3 => Some((CellState::Free, 1 + next(6))),
            4..=6 => Some((CellState::Occupied, 1 + next(5))),
            7 => Some((CellState::Unknown, 1 + next(5))),
            _ => None,
        };
        match s {
            Some((s, size)) => {
                for cy in y..(y + size).min(50) {
                    for cx in x..(x + size).min(60) {
                        g.set_state((cx, cy), s);
                    }
                }
            }
            None => {
                let a = g.centre_of((x, y));
                let b = g.centre_of((next(60), next(50)));
                g.integrate_ray(&a, &b, next(2) == 0);
            }
        }
        kept.rebuild(&g);
        let mut fresh = CSpace::new(0.2, 0.17);
        fresh.rebuild(&g);
        assert_eq!(kept.state, fresh.state, "step {step}");
        assert_eq!(kept.held, fresh.held, "step {step}");
        assert_eq!(kept.surface, fresh.surface, "step {step}");
        assert_eq!(kept.traversable, fresh.traversable, "step {step}");
        assert_eq!(kept.collision_free, fresh.collision_free, "step {step}");
    }
    assert!(kept.traversable.iter().any(|t| *t) && kept.traversable.iter().any(|t| !t));
    // Forgetting the outer columns shrinks the grid's explored box: the
    // cells left outside it must be read once more.
    for y in 0..50 {
        for x in (0..4).chain(52..60) {
            g.set_state((x, y), CellState::Unknown);
        }
    }
    assert_eq!(g.explored_cells().map(|b| (b.0 .0, b.1 .0)), Some((4, 51)));
    kept.rebuild(&g);
    let mut fresh = CSpace::new(0.2, 0.17);
    fresh.rebuild(&g);
    assert_eq!(kept.state, fresh.state);
    assert_eq!(kept.traversable, fresh.traversable);
}
