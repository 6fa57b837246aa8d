//! The way out of a pocket of the configuration space.
//!
//! The planner keeps the robot centre `robot.radius + plan.safety_margin`
//! away from seen obstacles and unexplored cells, on a 5 cm grid. A passage
//! between furniture just wide enough for the body (a gap between two chair
//! groups, seen from one side) then splits the traversable space: the robot
//! ends a lane on one side and finds everything else out of reach, although
//! its body fits through. `way_out` finds the shortest move, over cells
//! where the bare body (radius, no margin) covers seen-free floor only, to
//! the nearest traversable cell of another part of the space that still has
//! work (as judged by the caller), preferring traversable cells on the way.
//!
//! Pure and deterministic; allocates its buffers per call (it runs only when
//! the robot's own part of the space has nothing left to do).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use nalgebra::Point2;

use super::cspace::CSpace;
use crate::grid::NEIGHBOURS_8;

/// Cost factor of a step onto a cell that is body-clear but not
/// traversable: the way out keeps to the inflated free space where it can.
const TIGHT_STEP_COST: f64 = 3.0;

#[derive(Clone, Copy, PartialEq)]
struct Entry {
    cost: f64,
    idx: usize,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        o.cost
            .total_cmp(&self.cost)
            .then_with(|| o.idx.cmp(&self.idx))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// The part of the space the robot may step onto during a way out.
fn passable(cs: &CSpace, i: usize) -> bool {
    cs.traversable[i] || cs.body_clear(i)
}

/// The 8-neighbours of `i` inside the grid that pass `ok`, never cutting a
/// corner past a cell that does not.
fn neighbours(cs: &CSpace, i: usize, ok: impl Fn(usize) -> bool) -> heapless::Vec<(usize, f64), 8> {
    let f = cs.frame;
    let (w, h) = (f.w as i64, f.h as i64);
    let (x, y) = ((i as i64) % w, (i as i64) / w);
    let mut out = heapless::Vec::new();
    for (dx, dy) in NEIGHBOURS_8 {
        let (nx, ny) = (x + dx, y + dy);
        if nx < 0 || ny < 0 || nx >= w || ny >= h {
            continue;
        }
        let j = (ny * w + nx) as usize;
        if !ok(j) {
            continue;
        }
        if dx != 0 && dy != 0 && (!ok((y * w + nx) as usize) || !ok((ny * w + x) as usize)) {
            continue;
        }
        let step = if dx != 0 && dy != 0 {
            std::f64::consts::SQRT_2
        } else {
            1.0
        };
        // At most 8 neighbours: the push cannot fail.
        let _ = out.push((j, step * f.res));
    }
    out
}

/// The traversable cells connected to `start` (8-connected, no corner
/// cutting), labelled `label` in `labels`.
fn component(cs: &CSpace, start: usize, label: u32, labels: &mut [u32]) -> Vec<usize> {
    let mut out = vec![start];
    labels[start] = label;
    let mut k = 0;
    while k < out.len() {
        let i = out[k];
        k += 1;
        for (j, _) in neighbours(cs, i, |j| cs.traversable[j]) {
            if labels[j] == u32::MAX {
                labels[j] = label;
                out.push(j);
            }
        }
    }
    out
}

/// Whether the straight segment `a`–`b` stays on traversable cells
/// (sampled every quarter cell).
fn segment_traversable(cs: &CSpace, a: &Point2<f64>, b: &Point2<f64>) -> bool {
    crate::geom::points_along(*a, *b, cs.frame.res * 0.25)
        .all(|p| cs.frame.index_of(&p).is_some_and(|i| cs.traversable[i]))
}

/// String-pulls a cell path where it runs over traversable cells; through
/// the tight stretch (body-clear cells only, a few millimetres to spare) it
/// keeps to the cell centres, step by step.
fn shorten(cs: &CSpace, cells: &[usize]) -> Vec<Point2<f64>> {
    let pts: Vec<Point2<f64>> = cells.iter().map(|&i| cs.frame.centre(i)).collect();
    let mut out = Vec::new();
    let mut anchor = 0;
    while anchor + 1 < pts.len() {
        let mut far = anchor + 1;
        for j in anchor + 2..pts.len() {
            if !cs.traversable[cells[j - 1]] {
                break;
            }
            if segment_traversable(cs, &pts[anchor], &pts[j]) {
                far = j;
            }
        }
        out.push(pts[far]);
        anchor = far;
    }
    out
}

/// The way out of the robot's part of the space (see the module docs):
/// waypoints (the robot's own cell excluded) to the nearest traversable
/// cell outside `reachable` whose part of the traversable space passes
/// `has_work` (called once per part, with its cells), with at most
/// `max_tight` metres of the way off the traversable space (steps there
/// count `TIGHT_STEP_COST` times in the choice of the way). `None` when
/// there is no such place.
pub(crate) fn way_out(
    cs: &CSpace,
    robot: usize,
    reachable: &[bool],
    max_tight: f64,
    mut has_work: impl FnMut(&[usize]) -> bool,
) -> Option<Vec<Point2<f64>>> {
    let n = cs.frame.len();
    if robot >= n || reachable.len() != n {
        return None;
    }
    let mut dist = vec![f64::INFINITY; n];
    // Length of the way to each cell off the traversable space.
    let mut tight = vec![0.0; n];
    let mut prev = vec![usize::MAX; n];
    let mut labels = vec![u32::MAX; n];
    // Per label: whether that part of the space has work.
    let mut work: Vec<bool> = Vec::new();
    let mut heap = BinaryHeap::new();
    dist[robot] = 0.0;
    heap.push(Entry {
        cost: 0.0,
        idx: robot,
    });
    while let Some(Entry { cost, idx: i }) = heap.pop() {
        if cost > dist[i] {
            continue;
        }
        if cs.traversable[i] && !reachable[i] {
            if labels[i] == u32::MAX {
                let label = work.len() as u32;
                let part = component(cs, i, label, &mut labels);
                work.push(has_work(&part));
            }
            if work[labels[i] as usize] {
                let mut cells = vec![i];
                let mut k = i;
                while prev[k] != usize::MAX {
                    k = prev[k];
                    cells.push(k);
                }
                cells.reverse();
                return Some(shorten(cs, &cells));
            }
        }
        for (j, step) in neighbours(cs, i, |j| passable(cs, j)) {
            let (c, t) = if cs.traversable[j] {
                (cost + step, tight[i])
            } else {
                (cost + step * TIGHT_STEP_COST, tight[i] + step)
            };
            if c < dist[j] && t <= max_tight {
                dist[j] = c;
                tight[j] = t;
                prev[j] = i;
                heap.push(Entry { cost: c, idx: j });
            }
        }
    }
    None
}

/// The traversable cells the robot at `robot` can get to when it may take
/// passages where only the bare body fits (of any length): what it could
/// reach with ways out, for the report of unreachable floor.
pub(crate) fn reachable_with_ways_out(cs: &CSpace, robot: usize) -> Vec<bool> {
    let mut seen = bare_body_reach(cs, robot);
    for (s, t) in seen.iter_mut().zip(&cs.traversable) {
        *s &= *t;
    }
    seen
}

/// Every place the bare body's centre can get to from `robot`, with no
/// safety margin: the reachable floor as the ground truth counts it.
pub(crate) fn bare_body_reach(cs: &CSpace, robot: usize) -> Vec<bool> {
    let n = cs.frame.len();
    let mut seen = vec![false; n];
    if robot >= n {
        return seen;
    }
    seen[robot] = true;
    let mut stack = vec![robot];
    while let Some(i) = stack.pop() {
        for (j, _) in neighbours(cs, i, |j| passable(cs, j)) {
            if !seen[j] {
                seen[j] = true;
                stack.push(j);
            }
        }
    }
    seen
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{CellState, Grid};

    /// A 4 m x 2 m room split by a wall at x = 2 with a door of `door` m
    /// (centred on y = 1).
    fn two_rooms(door: f64) -> Grid {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 80, 40);
        for y in 0..40 {
            for x in 0..80 {
                let c = g.centre_of((x, y));
                let edge = x == 0 || y == 0 || x == 79 || y == 39;
                let wall = (c.x - 2.0).abs() < 0.05 && (c.y - 1.0).abs() > door / 2.0;
                let s = if edge || wall {
                    CellState::Occupied
                } else {
                    CellState::Free
                };
                g.set_state((x, y), s);
            }
        }
        g
    }

    fn reachable_from(cs: &mut CSpace, robot: usize) -> Vec<bool> {
        cs.distances_from(robot);
        (0..cs.frame.len())
            .map(|i| cs.traversable[i] && cs.dist[i].is_finite())
            .collect()
    }

    #[test]
    fn a_door_as_wide_as_the_body_plus_a_little_leads_out() {
        // 0.40 m door: the body (0.34 m) fits, the inflated space (0.18 m
        // each side on the 5 cm grid) does not pass it.
        let mut cs = CSpace::new(0.18, 0.17);
        cs.rebuild(&two_rooms(0.40));
        let f = cs.frame;
        let robot = f.index_of(&Point2::new(1.0, 1.0)).unwrap();
        let reach = reachable_from(&mut cs, robot);
        let right = f.index_of(&Point2::new(3.0, 1.0)).unwrap();
        assert!(
            cs.traversable[right] && !reach[right],
            "the door splits the space"
        );
        let mut asked = 0;
        let path = way_out(&cs, robot, &reach, 3.0, |part| {
            asked += 1;
            part.contains(&right)
        })
        .expect("a way out through the door");
        assert_eq!(asked, 1);
        let end = *path.last().unwrap();
        assert!(end.x > 2.0, "{path:?}");
        // Every point of the way keeps the bare body on free floor, and the
        // tight stretch is driven cell by cell.
        let mut from = f.centre(robot);
        for p in &path {
            assert!(cs.segment_safe(&from, p), "{from} -> {p}");
            let tight = [from, *p]
                .iter()
                .any(|q| !cs.traversable[f.index_of(q).unwrap()]);
            if tight {
                assert!((p - from).norm() < 0.08, "{from} -> {p}");
            }
            from = *p;
        }
        // Both sides count as reachable with ways out.
        let all = reachable_with_ways_out(&cs, robot);
        assert!(all[right] && all[robot]);
        // The other side has nothing to do: no way out.
        assert!(way_out(&cs, robot, &reach, 3.0, |_| false).is_none());
        // A passage longer than allowed.
        assert!(way_out(&cs, robot, &reach, 0.1, |_| true).is_none());
    }

    #[test]
    fn a_door_narrower_than_the_body_is_no_way_out() {
        let mut cs = CSpace::new(0.18, 0.17);
        cs.rebuild(&two_rooms(0.30));
        let f = cs.frame;
        let robot = f.index_of(&Point2::new(1.0, 1.0)).unwrap();
        let reach = reachable_from(&mut cs, robot);
        assert!(way_out(&cs, robot, &reach, 10.0, |_| true).is_none());
        let all = reachable_with_ways_out(&cs, robot);
        assert_eq!(all, reach);
        // Out of range or inconsistent input: no way out, no panic.
        assert!(way_out(&cs, f.len(), &reach, 10.0, |_| true).is_none());
        assert!(way_out(&cs, robot, &[], 10.0, |_| true).is_none());
    }
}
