//! Travel over the configuration space: Dijkstra distances, linked travel
//! costs between many cells, A* paths, all shortened by line of sight.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use nalgebra::Point2;

use super::{CSpace, Frame, NEIGHBOURS};

/// A search frontier entry; the heap pops the least cost first, the least
/// index among equal costs (so searches are deterministic).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Entry {
    cost: f64,
    idx: u32,
}

impl Entry {
    /// The cost's bit pattern: for the non-negative costs of these searches
    /// (0, finite sums of positive steps, +∞) it orders as the cost does, and
    /// an integer comparison is cheaper than a float one in the heap.
    fn key(&self) -> (u64, u32) {
        debug_assert!(self.cost >= 0.0, "negative search cost {}", self.cost);
        (self.cost.to_bits(), self.idx)
    }
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        o.key().cmp(&self.key())
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// The cells one step from cell `i` that the robot may enter, each with the
/// cost of the step (m, weighted by the entered cell's extra cost); a
/// diagonal step never cuts past a blocked cell. Allocation-free; a free
/// function so that a search can borrow the grid beside its own tables.
fn grid_steps(
    frame: Frame,
    traversable: &[bool],
    extra: &[f32],
    i: usize,
) -> heapless::Vec<(usize, f64), 8> {
    let (w, h, r) = (frame.w as i64, frame.h as i64, frame.res);
    let (x, y) = ((i as i64) % w, (i as i64) / w);
    let mut out = heapless::Vec::new();
    for &(dx, dy, c) in &NEIGHBOURS {
        let (nx, ny) = (x + dx, y + dy);
        if nx < 0 || ny < 0 || nx >= w || ny >= h {
            continue;
        }
        let j = (ny * w + nx) as usize;
        if !traversable[j] {
            continue;
        }
        if dx != 0
            && dy != 0
            && (!traversable[(y * w + nx) as usize] || !traversable[(ny * w + x) as usize])
        {
            continue;
        }
        // At most 8 neighbours: the push cannot fail.
        let _ = out.push((j, c * r * (1.0 + extra[j] as f64)));
    }
    out
}

/// Dijkstra from the entries already in `heap` (their costs set in `dist`):
/// settles every cell reachable by `steps`, calling `improved(j, i, old)`
/// before cell `j`'s cost drops from `old` by a step from `i`.
fn settle<I: IntoIterator<Item = (usize, f64)>>(
    heap: &mut BinaryHeap<Entry>,
    dist: &mut [f64],
    steps: impl Fn(usize) -> I,
    mut improved: impl FnMut(usize, usize, f64),
) {
    while let Some(Entry { cost, idx }) = heap.pop() {
        let i = idx as usize;
        if cost > dist[i] {
            continue;
        }
        for (j, step) in steps(i) {
            let nc = cost + step;
            if nc < dist[j] {
                improved(j, i, dist[j]);
                dist[j] = nc;
                heap.push(Entry {
                    cost: nc,
                    idx: j as u32,
                });
            }
        }
    }
}

impl CSpace {
    /// Sets the extra travel cost factor of every cell (`f(i)` for cell
    /// `i`, at least 0): paths and travel costs then prefer cheap cells, e.g.
    /// floor the tool has not swept yet. Reset on a change of the grid's
    /// geometry.
    pub(crate) fn set_extra_cost(&mut self, f: impl Fn(usize) -> f64) {
        for (i, e) in self.extra.iter_mut().enumerate() {
            *e = f(i).max(0.0) as f32;
        }
    }

    /// Dijkstra travel distances (8-connected, m) over traversable cells from
    /// `source` (which may itself be non-traversable: the robot may start in
    /// an inflation zone). Fills [`CSpace::dist`].
    pub(crate) fn distances_from(&mut self, source: usize) {
        self.dist.iter_mut().for_each(|d| *d = f64::INFINITY);
        self.prev.iter_mut().for_each(|p| *p = u32::MAX);
        self.heap.clear();
        if source >= self.frame.len() {
            return;
        }
        self.dist[source] = 0.0;
        self.heap.push(Entry {
            cost: 0.0,
            idx: source as u32,
        });
        let (frame, trav, extra, prev) =
            (self.frame, &self.traversable, &self.extra, &mut self.prev);
        settle(
            &mut self.heap,
            &mut self.dist,
            |i| grid_steps(frame, trav, extra, i),
            |j, i, _| prev[j] = i as u32,
        );
    }

    /// Approximate travel costs between `cells`, row-major into `out`
    /// (`cells.len()²` values, ∞ where unreachable), from one search: a
    /// Dijkstra from all of them at once splits the space into the region
    /// each reaches first; two cells whose regions touch are linked by the
    /// cheapest way across their common border, and the cost between any
    /// two is the cheapest chain of such links. Exact between neighbours
    /// whose way stays in their two regions, an upper bound otherwise;
    /// about the cost of one whole-grid search. [`CSpace::dist`] is left as
    /// it was.
    pub(crate) fn travel_linked(&mut self, cells: &[usize], out: &mut Vec<f64>) {
        let n = self.frame.len();
        let k = cells.len();
        out.clear();
        out.resize(k * k, f64::INFINITY);
        if self.scratch.len() != n {
            self.scratch = vec![f64::INFINITY; n];
        }
        if self.label.len() != n {
            self.label = vec![u32::MAX; n];
        }
        // One node per distinct cell (a cell may be listed twice).
        let mut node_of = vec![usize::MAX; k];
        let mut nodes: Vec<usize> = Vec::new();
        for (a, &c) in cells.iter().enumerate() {
            if c >= n {
                continue;
            }
            node_of[a] = match nodes.iter().position(|&x| x == c) {
                Some(p) => p,
                None => {
                    nodes.push(c);
                    nodes.len() - 1
                }
            };
        }
        self.heap.clear();
        for (v, &c) in nodes.iter().enumerate() {
            self.scratch[c] = 0.0;
            self.label[c] = v as u32;
            self.touched.push(c as u32);
            self.heap.push(Entry {
                cost: 0.0,
                idx: c as u32,
            });
        }
        let (frame, trav, extra) = (self.frame, &self.traversable, &self.extra);
        let (label, touched) = (&mut self.label, &mut self.touched);
        settle(
            &mut self.heap,
            &mut self.scratch,
            |i| grid_steps(frame, trav, extra, i),
            |j, i, old| {
                if old.is_infinite() {
                    touched.push(j as u32);
                }
                label[j] = label[i];
            },
        );
        // Links across region borders.
        let v = nodes.len();
        let mut link = vec![f64::INFINITY; v * v];
        for &t in &self.touched {
            let i = t as usize;
            let li = self.label[i] as usize;
            for (j, step) in self.steps(i) {
                let lj = self.label[j];
                if lj == u32::MAX || lj as usize == li {
                    continue;
                }
                let c = self.scratch[i] + step + self.scratch[j];
                let e = &mut link[li * v + lj as usize];
                if c < *e {
                    *e = c;
                }
            }
        }
        for &t in &self.touched {
            self.scratch[t as usize] = f64::INFINITY;
            self.label[t as usize] = u32::MAX;
        }
        self.touched.clear();
        // Cheapest chains of links: a Dijkstra per node over the links.
        let mut adj: Vec<Vec<(usize, f64)>> = vec![Vec::new(); v];
        for a in 0..v {
            for b in a + 1..v {
                let c = link[a * v + b].min(link[b * v + a]);
                if c.is_finite() {
                    adj[a].push((b, c));
                    adj[b].push((a, c));
                }
            }
        }
        let mut chain = vec![f64::INFINITY; v * v];
        let mut heap = BinaryHeap::new();
        for s in 0..v {
            let row = &mut chain[s * v..(s + 1) * v];
            row[s] = 0.0;
            heap.push(Entry {
                cost: 0.0,
                idx: s as u32,
            });
            settle(&mut heap, row, |u| adj[u].iter().copied(), |_, _, _| {});
        }
        for a in 0..k {
            for b in 0..k {
                if node_of[a] != usize::MAX && node_of[b] != usize::MAX {
                    out[a * k + b] = chain[node_of[a] * v + node_of[b]];
                }
            }
        }
    }

    /// The cell path from the last Dijkstra source to `goal`, as cell centres,
    /// shortened by line of sight; `None` when `goal` is unreachable.
    pub(crate) fn path_to(&self, goal: usize) -> Option<Vec<Point2<f64>>> {
        if goal >= self.dist.len() || !self.dist[goal].is_finite() {
            return None;
        }
        let mut cells = vec![goal];
        let mut i = goal;
        while self.prev[i] != u32::MAX {
            i = self.prev[i] as usize;
            cells.push(i);
        }
        cells.reverse();
        Some(self.shorten(&cells))
    }

    /// A* path (cell centres, shortened) between two cells over traversable
    /// cells, `None` when there is none. Does not touch [`CSpace::dist`].
    pub(crate) fn astar(&self, from: usize, to: usize) -> Option<Vec<Point2<f64>>> {
        let n = self.frame.len();
        if from >= n || to >= n || !self.traversable[to] {
            return None;
        }
        let (w, r) = (self.frame.w as i64, self.frame.res);
        let goal = ((to as i64) % w, (to as i64) / w);
        let hfn = |i: usize| {
            let (x, y) = ((i as i64) % w, (i as i64) / w);
            let (dx, dy) = ((x - goal.0).abs() as f64, (y - goal.1).abs() as f64);
            (dx.max(dy) + (std::f64::consts::SQRT_2 - 1.0) * dx.min(dy)) * r
        };
        let mut g = std::collections::HashMap::<usize, (f64, usize)>::new();
        let mut heap = BinaryHeap::new();
        g.insert(from, (0.0, usize::MAX));
        heap.push(Entry {
            cost: hfn(from),
            idx: from as u32,
        });
        while let Some(Entry { idx, .. }) = heap.pop() {
            let i = idx as usize;
            if i == to {
                let mut cells = vec![to];
                let mut k = to;
                while let Some(&(_, p)) = g.get(&k) {
                    if p == usize::MAX {
                        break;
                    }
                    cells.push(p);
                    k = p;
                }
                cells.reverse();
                return Some(self.shorten(&cells));
            }
            let gi = g[&i].0;
            for (j, step) in self.steps(i) {
                let ng = gi + step;
                if g.get(&j).is_none_or(|&(old, _)| ng < old) {
                    g.insert(j, (ng, i));
                    heap.push(Entry {
                        cost: ng + hfn(j),
                        idx: j as u32,
                    });
                }
            }
        }
        None
    }

    /// Whether at least `n` traversable cells are connected to cell
    /// `start` (moving as the path search does): a flood fill that stops
    /// once it has found `n`, so a large part costs no more than a small one.
    pub(crate) fn traversable_part_holds(&self, start: usize, n: usize) -> bool {
        if start >= self.frame.len() || !self.traversable[start] {
            return false;
        }
        let mut found = vec![start];
        let mut next = 0;
        while next < found.len() && found.len() < n {
            let i = found[next];
            next += 1;
            for (j, _) in self.steps(i) {
                if !found.contains(&j) {
                    found.push(j);
                }
            }
        }
        found.len() >= n
    }

    /// [`grid_steps`] over this configuration space.
    fn steps(&self, i: usize) -> heapless::Vec<(usize, f64), 8> {
        grid_steps(self.frame, &self.traversable, &self.extra, i)
    }

    fn extra_at(&self, i: usize) -> f32 {
        self.extra.get(i).copied().unwrap_or(0.0)
    }

    /// The dearest extra cost factor along the segment `a`–`b`.
    fn segment_extra(&self, a: &Point2<f64>, b: &Point2<f64>) -> f32 {
        crate::geom::points_along(*a, *b, self.frame.res * 0.25)
            .filter_map(|p| self.frame.index_of(&p))
            .map(|i| self.extra_at(i))
            .fold(0.0, f32::max)
    }

    /// String-pulls a cell path: keeps only the points where line of sight breaks.
    fn shorten(&self, cells: &[usize]) -> Vec<Point2<f64>> {
        let pts: Vec<Point2<f64>> = cells.iter().map(|&i| self.frame.centre(i)).collect();
        if pts.len() <= 2 {
            return pts;
        }
        let mut out = vec![pts[0]];
        let mut anchor = 0;
        let mut k = 1;
        while k < pts.len() {
            // Farthest point visible from the anchor.
            let mut far = k;
            let mut j = k;
            // A shortcut may not cross dearer cells than the ones it replaces.
            let mut dearest = self.extra_at(cells[anchor]);
            while j < pts.len() {
                dearest = dearest.max(self.extra_at(cells[j]));
                if self.segment_clear(&pts[anchor], &pts[j])
                    && self.segment_extra(&pts[anchor], &pts[j]) <= dearest
                {
                    far = j;
                }
                j += 1;
                if j - far > 24 {
                    break;
                }
            }
            out.push(pts[far]);
            anchor = far;
            k = far + 1;
        }
        out
    }
}
