//! One open tour through the lanes of several regions: from the robot
//! through every lane, each driven either way round, by the least travel
//! between lane ends (an open travelling-salesman path over the lanes).
//!
//! Covering region after region drives each region's lanes as one block,
//! so a region cut by furniture into stretches on both sides of it is
//! driven out and back. Pooling the lanes of all regions ready to cover and
//! ordering them as one tour lets the order leave a region half done and
//! finish it on the way back (the split-cell idea of Mannadiar and
//! Rekleitis, ICRA 2010, which covers each cell half out and half back).
//!
//! Pure: lane ends are numbered `2k` (lane `k`'s start `a`) and `2k + 1`
//! (its end `b`); the caller gives the travel cost from the robot to every
//! end and between every two ends.

/// Cost taken for travel between two ends that has no finite cost.
const UNREACHABLE: f64 = 1e6;

/// Passes of the local search at most (each pass tries every move once).
const MAX_PASSES: usize = 64;

/// Travel costs between lane ends (see the module docs).
pub struct TourCosts<'a> {
    /// Travel cost from the robot to each end (`2n` values).
    pub start: &'a [f64],
    /// Travel cost between ends, `2n × 2n` row-major; taken symmetric (the
    /// mean of both directions) so that driving a stretch of the tour
    /// backwards keeps its inner costs.
    pub between: &'a [f64],
}

/// One lane of the tour: its index and whether it is driven from `b` to `a`.
pub type Leg = (usize, bool);

fn entry(t: Leg) -> usize {
    2 * t.0 + usize::from(t.1)
}

fn exit(t: Leg) -> usize {
    2 * t.0 + 1 - usize::from(t.1)
}

struct Costs {
    m: usize,
    start: Vec<f64>,
    d: Vec<f64>,
}

impl Costs {
    fn new(c: &TourCosts) -> Self {
        let m = c.start.len();
        let fin = |v: f64| if v.is_finite() { v } else { UNREACHABLE };
        let mut d = vec![0.0; m * m];
        for a in 0..m {
            for b in 0..m {
                d[a * m + b] = 0.5 * (fin(c.between[a * m + b]) + fin(c.between[b * m + a]));
            }
        }
        Self {
            m,
            start: c.start.iter().map(|&v| fin(v)).collect(),
            d,
        }
    }

    /// Cost of arriving at end `to` from the exit end `from` (the robot when `None`).
    fn link(&self, from: Option<usize>, to: usize) -> f64 {
        match from {
            None => self.start[to],
            Some(a) => self.d[a * self.m + to],
        }
    }

    /// Cost of leaving exit end `from` for `to` (nothing when the tour ends).
    fn tail(&self, from: usize, to: Option<usize>) -> f64 {
        to.map_or(0.0, |b| self.d[from * self.m + b])
    }
}

/// Travel cost of the open tour `t` (lanes' own lengths not included).
pub fn tour_cost(t: &[Leg], costs: &TourCosts) -> f64 {
    let c = Costs::new(costs);
    travel(t, &c)
}

fn travel(t: &[Leg], c: &Costs) -> f64 {
    let Some(&first) = t.first() else {
        return 0.0;
    };
    c.link(None, entry(first))
        + t.windows(2)
            .map(|w| c.link(Some(exit(w[0])), entry(w[1])))
            .sum::<f64>()
}

/// The tour through all `costs.start.len() / 2` lanes: nearest lane end
/// first, then improved by driving stretches backwards (2-opt) and moving
/// stretches of one to three lanes elsewhere, either way round (or-opt),
/// while that shortens it. Deterministic; at most 64 passes (`MAX_PASSES`).
pub fn lane_tour(costs: &TourCosts) -> Vec<Leg> {
    let c = Costs::new(costs);
    let n = c.m / 2;
    let mut used = vec![false; n];
    let mut t: Vec<Leg> = Vec::with_capacity(n);
    for _ in 0..n {
        let from = t.last().map(|&l| exit(l));
        let mut best: Option<(f64, Leg)> = None;
        for k in (0..n).filter(|&k| !used[k]) {
            for r in [false, true] {
                let v = c.link(from, entry((k, r)));
                if best.is_none_or(|(b, _)| v < b) {
                    best = Some((v, (k, r)));
                }
            }
        }
        if let Some((_, l)) = best {
            used[l.0] = true;
            t.push(l);
        }
    }
    for _ in 0..MAX_PASSES {
        let a = two_opt(&mut t, &c);
        let b = or_opt(&mut t, &c);
        if !(a || b) {
            break;
        }
    }
    t
}

/// One pass of 2-opt: drives `t[i..=j]` backwards wherever that shortens the tour.
fn two_opt(t: &mut [Leg], c: &Costs) -> bool {
    let n = t.len();
    let mut any = false;
    for i in 0..n {
        for j in i + 1..n {
            let prev = (i > 0).then(|| exit(t[i - 1]));
            let next = (j + 1 < n).then(|| entry(t[j + 1]));
            let before = c.link(prev, entry(t[i])) + c.tail(exit(t[j]), next);
            let after = c.link(prev, exit(t[j])) + c.tail(entry(t[i]), next);
            if after < before - 1e-9 {
                t[i..=j].reverse();
                for l in &mut t[i..=j] {
                    l.1 = !l.1;
                }
                any = true;
            }
        }
    }
    any
}

/// One pass of or-opt: moves a stretch of one to three lanes to another
/// place, either way round, wherever that shortens the tour.
fn or_opt(t: &mut Vec<Leg>, c: &Costs) -> bool {
    let mut any = false;
    for len in 1..=3usize {
        let mut i = 0;
        while i + len <= t.len() {
            if let Some((p, rev)) = best_move(t, c, i, len) {
                let mut seg: Vec<Leg> = t.drain(i..i + len).collect();
                if rev {
                    seg.reverse();
                    for l in &mut seg {
                        l.1 = !l.1;
                    }
                }
                t.splice(p..p, seg);
                any = true;
            }
            i += 1;
        }
    }
    any
}

/// The best place (index into the tour without the stretch, and whether
/// reversed) to move `t[i..i + len]` to, if any shortens the tour.
fn best_move(t: &[Leg], c: &Costs, i: usize, len: usize) -> Option<(usize, bool)> {
    let n = t.len();
    let prev = (i > 0).then(|| exit(t[i - 1]));
    let next = (i + len < n).then(|| entry(t[i + len]));
    let (se, sx) = (entry(t[i]), exit(t[i + len - 1]));
    let removed = c.link(prev, se) + c.tail(sx, next) - next.map_or(0.0, |b| c.link(prev, b));
    // The tour without the stretch: position q of it is t[q] before i, t[q + len] after.
    let rest = |q: usize| if q < i { t[q] } else { t[q + len] };
    let mut best: Option<(f64, usize, bool)> = None;
    for p in 0..=n - len {
        let before = (p > 0).then(|| exit(rest(p - 1)));
        let after = (p < n - len).then(|| entry(rest(p)));
        let base = after.map_or(0.0, |b| c.link(before, b));
        for rev in [false, true] {
            if p == i && !rev {
                continue;
            }
            let (e, x) = if rev { (sx, se) } else { (se, sx) };
            let added = c.link(before, e) + c.tail(x, after) - base;
            let gain = removed - added;
            if gain > 1e-9 && best.is_none_or(|(g, ..)| gain > g) {
                best = Some((gain, p, rev));
            }
        }
    }
    best.map(|(_, p, rev)| (p, rev))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lane's two ends (x, y).
    type Ends = ((f64, f64), (f64, f64));

    /// Costs between lane ends as straight-line distances.
    fn costs(lanes: &[Ends], robot: (f64, f64)) -> (Vec<f64>, Vec<f64>) {
        let ends: Vec<(f64, f64)> = lanes.iter().flat_map(|&(a, b)| [a, b]).collect();
        let d = |p: (f64, f64), q: (f64, f64)| ((p.0 - q.0).powi(2) + (p.1 - q.1).powi(2)).sqrt();
        let start = ends.iter().map(|&e| d(robot, e)).collect();
        let between = ends
            .iter()
            .flat_map(|&p| ends.iter().map(move |&q| d(p, q)))
            .collect();
        (start, between)
    }

    fn permutations(n: usize) -> Vec<Vec<usize>> {
        if n == 0 {
            return vec![Vec::new()];
        }
        let mut out = Vec::new();
        for p in permutations(n - 1) {
            for k in 0..=p.len() {
                let mut q = p.clone();
                q.insert(k, n - 1);
                out.push(q);
            }
        }
        out
    }

    fn optimum(tc: &TourCosts, n: usize) -> f64 {
        let mut best = f64::INFINITY;
        for p in permutations(n) {
            for flips in 0..(1u32 << n) {
                let t: Vec<Leg> = p
                    .iter()
                    .enumerate()
                    .map(|(k, &l)| (l, flips & (1 << k) != 0))
                    .collect();
                best = best.min(tour_cost(&t, tc));
            }
        }
        best
    }

    #[test]
    fn parallel_lanes_are_driven_as_a_zig_zag() {
        let lanes: Vec<_> = [3.0, 0.0, 2.0, 1.0]
            .iter()
            .map(|&y| ((0.0, y), (4.0, y)))
            .collect();
        let (start, between) = costs(&lanes, (0.0, -0.5));
        let tc = TourCosts {
            start: &start,
            between: &between,
        };
        let t = lane_tour(&tc);
        let order: Vec<usize> = t.iter().map(|l| l.0).collect();
        assert_eq!(order, vec![1, 3, 2, 0]);
        assert!((tour_cost(&t, &tc) - 3.5).abs() < 1e-9);
    }

    #[test]
    fn the_tour_finishes_a_region_on_the_way_back() {
        // Two rows of short lanes either side of an obstacle at x 2..3 and
        // a long corridor lane below: the best tour covers the left lanes,
        // runs the corridor, and covers the right lanes, not left, right,
        // then back over the corridor.
        let lanes = vec![
            ((0.0, 1.0), (2.0, 1.0)),
            ((0.0, 1.3), (2.0, 1.3)),
            ((3.0, 1.0), (5.0, 1.0)),
            ((3.0, 1.3), (5.0, 1.3)),
            ((0.0, 0.7), (5.0, 0.7)),
        ];
        let (start, between) = costs(&lanes, (0.0, 1.5));
        let tc = TourCosts {
            start: &start,
            between: &between,
        };
        let t = lane_tour(&tc);
        let got = tour_cost(&t, &tc);
        assert!(
            (got - optimum(&tc, lanes.len())).abs() < 1e-9,
            "{t:?} {got}"
        );
        assert_eq!(t[2].0, 4, "{t:?}");
    }

    #[test]
    fn small_tours_match_the_exhaustive_optimum() {
        // Deterministic pseudo-random lanes (a linear congruential generator).
        let mut s: u64 = 7;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 33) as f64 / (1u64 << 31) as f64
        };
        let mut worst: f64 = 0.0;
        for _ in 0..30 {
            let lanes: Vec<_> = (0..5)
                .map(|_| {
                    let (x, y, l) = (rnd() * 5.0, rnd() * 5.0, 0.3 + rnd() * 2.0);
                    ((x, y), (x + l, y))
                })
                .collect();
            let (start, between) = costs(&lanes, (rnd() * 5.0, rnd() * 5.0));
            let tc = TourCosts {
                start: &start,
                between: &between,
            };
            let t = lane_tour(&tc);
            let mut seen: Vec<usize> = t.iter().map(|l| l.0).collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..5).collect::<Vec<_>>());
            worst = worst.max(tour_cost(&t, &tc) / optimum(&tc, 5));
        }
        // Local search, not exact: within 10 % of the optimum on these.
        assert!(worst < 1.10, "worst ratio {worst}");
    }

    #[test]
    fn an_unreachable_end_is_priced_not_dropped() {
        let lanes = vec![((0.0, 0.0), (1.0, 0.0)), ((0.0, 1.0), (1.0, 1.0))];
        let (mut start, between) = costs(&lanes, (0.0, -1.0));
        start[0] = f64::INFINITY;
        let tc = TourCosts {
            start: &start,
            between: &between,
        };
        let t = lane_tour(&tc);
        assert_eq!(t.len(), 2);
        assert_ne!(entry(t[0]), 0);
    }
}
