//! The order of the next regions (the look-ahead of one region at a time):
//! exhaustive over a few candidates, a bounded local search beyond.

use nalgebra::Point2;

use super::Candidate;

/// Up to this many candidates the tour is searched exhaustively; beyond,
/// a greedy tour over all of them is improved by or-opt and 2-opt moves.
const TOUR_CANDIDATES: usize = 9;

/// Tour evaluations the heuristic search may spend (a fixed budget, so the
/// result is deterministic and the update time bounded).
const TOUR_EVALUATIONS: usize = 4000;

/// The candidate and variant to start with, from a tour through all
/// candidates: exhaustive for a few, heuristic for many.
pub(super) fn tour_start(cands: &[Candidate], weight: f64) -> (usize, usize) {
    if cands.len() <= TOUR_CANDIDATES {
        best_tour_start(cands, weight)
    } else {
        heuristic_tour_start(cands, weight)
    }
}

/// The tour costs between candidates' variants, computed once per search:
/// node `base[i] + v` is variant `v` of candidate `i`; `step[a * m + b]` is
/// `weight` times the straight line from node `a`'s exit to node `b`'s
/// entry plus node `b`'s length.
struct TourTable {
    base: Vec<usize>,
    step: Vec<f64>,
    m: usize,
}

impl TourTable {
    fn new(cands: &[Candidate], weight: f64) -> Self {
        let mut base = Vec::with_capacity(cands.len());
        let mut nodes = Vec::new();
        for c in cands {
            base.push(nodes.len());
            nodes.extend(c.variants.iter());
        }
        let m = nodes.len();
        let mut step = Vec::with_capacity(m * m);
        for a in &nodes {
            for b in &nodes {
                step.push(weight * ((b.entry() - a.exit()).norm() + b.length));
            }
        }
        Self { base, step, m }
    }
}

/// Cost of visiting `order` (the first from the robot), each candidate at
/// its best variant given the order (dynamic programming over variants),
/// and the variant of the first.
fn order_cost(
    cands: &[Candidate],
    table: &TourTable,
    order: &[usize],
    dp: &mut Vec<(f64, usize)>,
) -> (f64, usize) {
    dp.clear();
    let Some(&c0) = order.first() else {
        return (f64::INFINITY, 0);
    };
    // dp holds, per variant of the current candidate: (cost, first variant).
    for (v, var) in cands[c0].variants.iter().enumerate() {
        dp.push((cands[c0].entry_cost[v] + var.length, v));
    }
    let mut next = Vec::with_capacity(dp.len());
    for w in order.windows(2) {
        let (a, b) = (w[0], w[1]);
        next.clear();
        for vb in 0..cands[b].variants.len() {
            let col = table.base[b] + vb;
            let mut best = (f64::INFINITY, 0);
            for (va, &(c, f0)) in dp.iter().enumerate() {
                let t = c + table.step[(table.base[a] + va) * table.m + col];
                if t < best.0 {
                    best = (t, f0);
                }
            }
            next.push(best);
        }
        std::mem::swap(dp, &mut next);
    }
    dp.iter()
        .copied()
        .fold((f64::INFINITY, 0), |b, x| if x.0 < b.0 { x } else { b })
}

/// Costs the tour `trial` (one [`order_cost`] evaluation); when it beats
/// `best`, makes it the current `order` and its cost the best.
fn adopt_if_cheaper(
    cands: &[Candidate],
    table: &TourTable,
    dp: &mut Vec<(f64, usize)>,
    trial: &mut Vec<usize>,
    order: &mut Vec<usize>,
    best: &mut (f64, usize),
) -> bool {
    let c = order_cost(cands, table, trial, dp);
    if c.0 + 1e-9 < best.0 {
        *best = c;
        std::mem::swap(order, trial);
        true
    } else {
        false
    }
}

/// A greedy tour over all candidates (nearest next entry from the last
/// exit), improved by moving runs of one to three candidates elsewhere
/// (or-opt) and reversing stretches (2-opt) while that lowers
/// [`order_cost`], within [`TOUR_EVALUATIONS`].
fn heuristic_tour_start(cands: &[Candidate], weight: f64) -> (usize, usize) {
    let n = cands.len();
    let mut used = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut at: Option<Point2<f64>> = None;
    for _ in 0..n {
        let mut pick: Option<(f64, usize, usize)> = None;
        for (i, c) in cands.iter().enumerate().filter(|(i, _)| !used[*i]) {
            for (v, var) in c.variants.iter().enumerate() {
                let d = match at {
                    None => c.entry_cost[v],
                    Some(p) => (var.entry() - p).norm(),
                };
                if pick.is_none_or(|(b, _, _)| d < b) {
                    pick = Some((d, i, v));
                }
            }
        }
        let Some((_, i, v)) = pick else { break };
        used[i] = true;
        order.push(i);
        at = Some(cands[i].variants[v].exit());
    }
    let table = TourTable::new(cands, weight);
    let mut dp = Vec::with_capacity(8);
    let mut best = order_cost(cands, &table, &order, &mut dp);
    let mut evals = 1;
    let mut trial = Vec::with_capacity(n);
    let mut improved = true;
    while improved && evals < TOUR_EVALUATIONS {
        improved = false;
        // Or-opt: move order[i..i + len] to before position j of the rest.
        'moves: for len in 1..=3usize.min(n - 1) {
            for i in 0..=n - len {
                for j in 0..=n - len {
                    if j == i {
                        continue;
                    }
                    trial.clear();
                    trial.extend(order[..i].iter().chain(&order[i + len..]));
                    trial.splice(j..j, order[i..i + len].iter().copied());
                    evals += 1;
                    improved |=
                        adopt_if_cheaper(cands, &table, &mut dp, &mut trial, &mut order, &mut best);
                    if evals >= TOUR_EVALUATIONS {
                        break 'moves;
                    }
                }
            }
        }
        // 2-opt: reverse order[i..=j].
        'rev: for i in 0..n {
            for j in i + 1..n {
                if evals >= TOUR_EVALUATIONS {
                    break 'rev;
                }
                trial.clear();
                trial.extend_from_slice(&order);
                trial[i..=j].reverse();
                evals += 1;
                improved |=
                    adopt_if_cheaper(cands, &table, &mut dp, &mut trial, &mut order, &mut best);
            }
        }
    }
    (order.first().copied().unwrap_or(0), best.1)
}

/// The candidate and variant to start with: exhaustive search (dynamic
/// programming over subsets) of the order of all candidates and the variant
/// of each, minimising the travel to the first entry plus `weight` times the
/// rest (straight-line transits between exits and entries, and the lanes).
fn best_tour_start(cands: &[Candidate], weight: f64) -> (usize, usize) {
    let n = cands.len();
    // Flattened (candidate, variant) nodes.
    let nodes: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (0..cands[i].variants.len()).map(move |v| (i, v)))
        .collect();
    let m = nodes.len();
    let full = (1usize << n) - 1;
    // cost[mask][node], first[mask][node]
    let mut cost = vec![f64::INFINITY; (full + 1) * m];
    let mut first = vec![usize::MAX; (full + 1) * m];
    for (k, &(i, v)) in nodes.iter().enumerate() {
        let c = cands[i].entry_cost[v] + cands[i].variants[v].length;
        cost[(1 << i) * m + k] = c;
        first[(1 << i) * m + k] = k;
    }
    for mask in 1..=full {
        for (k, &(i, v)) in nodes.iter().enumerate() {
            let c = cost[mask * m + k];
            if !c.is_finite() || mask & (1 << i) == 0 {
                continue;
            }
            let exit = cands[i].variants[v].exit();
            for (k2, &(j, w)) in nodes.iter().enumerate() {
                if mask & (1 << j) != 0 {
                    continue;
                }
                let var = &cands[j].variants[w];
                let nc = c + weight * ((var.entry() - exit).norm() + var.length);
                let slot = (mask | (1 << j)) * m + k2;
                if nc < cost[slot] {
                    cost[slot] = nc;
                    first[slot] = first[mask * m + k];
                }
            }
        }
    }
    let mut best = (f64::INFINITY, 0usize);
    for k in 0..m {
        if cost[full * m + k] < best.0 {
            best = (cost[full * m + k], first[full * m + k]);
        }
    }
    nodes.get(best.1).copied().unwrap_or((0, 0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::lanes::{variants, Lane};

    /// One region per x: a single lane from (x, 0) to (x, 1), drivable
    /// either way, entered from the robot at `robot`.
    fn regions(xs: &[f64], robot: Point2<f64>) -> Vec<Candidate> {
        xs.iter()
            .map(|&x| {
                let l = Lane {
                    a: Point2::new(x, 0.0),
                    b: Point2::new(x, 1.0),
                    fixup: false,
                };
                let variants = variants(&[l], 0.58);
                let entry_cost = variants
                    .iter()
                    .map(|v| (v.entry() - robot).norm())
                    .collect();
                Candidate {
                    cell: None,
                    variants,
                    entry_cost,
                    targets: Vec::new(),
                }
            })
            .collect()
    }

    #[test]
    fn the_tour_over_many_regions_starts_with_the_short_side() {
        // The robot stands just right of the middle of a row of regions:
        // three to its left (0.7 m to the nearest), thirteen to its right
        // (0.4 m). Nearest first would go right, to the far end, and all
        // the way back; the whole tour is shorter clearing the left first.
        let robot = Point2::new(0.1, 0.0);
        let mut xs: Vec<f64> = (1..=3).map(|k| -0.6 * f64::from(k)).collect();
        xs.extend((0..13).map(|k| 0.5 + 0.5 * f64::from(k)));
        // Candidates arrive in no particular order.
        xs.reverse();
        xs.swap(2, 9);
        let cands = regions(&xs, robot);
        assert!(cands.len() > TOUR_CANDIDATES, "heuristic search in use");
        let (k, _) = tour_start(&cands, 1.0);
        assert!((xs[k] + 0.6).abs() < 1e-9, "starts at x = {}", xs[k]);
    }

    #[test]
    fn heuristic_and_exhaustive_search_agree_on_a_few_regions() {
        let robot = Point2::new(0.1, 0.0);
        let xs = [-1.2, -0.6, 0.5, 1.0, 1.5, 2.0, 2.5];
        let cands = regions(&xs, robot);
        let exact = best_tour_start(&cands, 1.0);
        let heur = heuristic_tour_start(&cands, 1.0);
        assert_eq!(exact.0, heur.0);
        assert!((xs[exact.0] + 0.6).abs() < 1e-9, "{}", xs[exact.0]);
    }
}
