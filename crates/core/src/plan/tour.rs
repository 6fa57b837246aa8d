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

/// Nearest ends of other lanes kept per lane end: the local search tries
/// only moves that link an end to one of these (neighbour lists, as in
/// Lin-Kernighan implementations), so a move costs no scan of the tour.
const NEAR: usize = 8;

/// Perturbations (double-bridge kicks) of the best tour so far, each
/// followed by a local search; the tour keeps a kick that shortened it.
/// Measured on the 24 rooms (`scripts/covrun.py @rooms24`, offline
/// overlap): 21.1 % with none, 19.8 % with 100, 18.7 % with 400 and with
/// 1000; a kick costs about 7 µs on the paper world's 38 lanes.
const KICKS: usize = 400;

/// Moves applied per lane per local search at most (a bound on the work;
/// every move shortens the tour, so the search ends without it too).
const MAX_MOVES_PER_LANE: usize = 64;

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
pub(crate) type Leg = (usize, bool);

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
    /// Per end, its `NEAR` nearest ends of other lanes (fewer when there are
    /// fewer lanes), nearest first.
    near: Vec<Vec<usize>>,
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
        let near = (0..m)
            .map(|a| {
                let mut others: Vec<usize> = (0..m).filter(|&b| b / 2 != a / 2).collect();
                let row = &d[a * m..(a + 1) * m];
                let k = NEAR.min(others.len());
                let by_cost = |x: &usize, y: &usize| row[*x].total_cmp(&row[*y]).then(x.cmp(y));
                if k < others.len() {
                    others.select_nth_unstable_by(k, by_cost);
                    others.truncate(k);
                }
                others.sort_by(by_cost);
                others
            })
            .collect();
        Self {
            m,
            start: c.start.iter().map(|&v| fin(v)).collect(),
            d,
            near,
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
#[cfg(test)]
pub(crate) fn tour_cost(t: &[Leg], costs: &TourCosts) -> f64 {
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
/// first; then a local search that drives stretches backwards (2-opt) and
/// moves stretches of one to three lanes elsewhere, either way round
/// (or-opt), trying the moves that link a lane end to one of its `NEAR`
/// nearest; then `KICKS` double-bridge perturbations, each searched again,
/// keeping the shortest (iterated local search). Deterministic: the kicks
/// come from a fixed-seed generator.
pub fn lane_tour(costs: &TourCosts) -> Vec<Leg> {
    search_tour(costs, KICKS)
}

/// [`lane_tour`] with `kicks` perturbations (none: the first local optimum).
fn search_tour(costs: &TourCosts, kicks: usize) -> Vec<Leg> {
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
    let mut s = Search::new(&c, t);
    for k in 0..n {
        s.activate(k);
    }
    s.settle();
    let mut best = s.t.clone();
    let mut best_cost = travel(&best, &c);
    let mut lcg = Lcg(0x9e37_79b9_7f4a_7c15);
    let mut rnd = |m: usize| (lcg.next() as usize) % m;
    // A double bridge needs three distinct cuts inside the tour.
    if n >= 4 {
        for _ in 0..kicks {
            let mut cuts = [1 + rnd(n - 1), 1 + rnd(n - 1), 1 + rnd(n - 1)];
            cuts.sort_unstable();
            let [p1, p2, p3] = cuts;
            if p1 == p2 || p2 == p3 {
                continue;
            }
            s.double_bridge(&best, p1, p2, p3);
            s.settle();
            let v = travel(&s.t, &c);
            if v < best_cost - 1e-9 {
                best_cost = v;
                best.clone_from(&s.t);
            }
        }
    }
    best
}

/// Sorts `v` (values below `n`) and drops repeats: through a bit set when
/// `n` fits one (no comparisons: this runs for every lane the local search
/// looks at), else by sorting.
fn sort_unique(v: &mut Vec<usize>, n: usize) {
    if n <= 128 {
        let mut bits = 0u128;
        for &p in v.iter() {
            bits |= 1 << p;
        }
        v.clear();
        while bits != 0 {
            v.push(bits.trailing_zeros() as usize);
            bits &= bits - 1;
        }
    } else {
        v.sort_unstable();
        v.dedup();
    }
}

/// A linear congruential generator: the kicks' fixed-seed source, so that
/// the same costs always give the same tour.
struct Lcg(u64);

impl Lcg {
    /// The next 31 random bits.
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        self.0 >> 33
    }

    /// The next number in `0..1`.
    #[cfg(test)]
    fn unit(&mut self) -> f64 {
        self.next() as f64 / (1u64 << 31) as f64
    }
}

/// A move: take the stretch `t[at..at + len]` out, and put it back
/// (backwards when `rev`) at index `to` of the tour without it. A stretch
/// put back where it was, backwards, is a 2-opt move.
#[derive(Clone, Copy)]
struct Move {
    at: usize,
    len: usize,
    to: usize,
    rev: bool,
}

/// Where a stretch goes back in: the exit end before, the entry end after,
/// and the cost of the link between them (see [`Search::gap`]).
type Gap = (Option<usize>, Option<usize>, f64);

/// The local search's state: the tour, each lane's place in it, and the
/// lanes whose links are still to be tried (don't-look bits).
struct Search<'a> {
    c: &'a Costs,
    t: Vec<Leg>,
    pos: Vec<usize>,
    queue: std::collections::VecDeque<usize>,
    queued: Vec<bool>,
    places: Vec<usize>,
    /// Scratch: the indices an or-opt stretch may go to.
    tos: Vec<usize>,
    /// Per index of the tour, the `stamp` of the last stretch that listed
    /// it in `tos` (a list without duplicates, in linear time).
    to_listed: Vec<u32>,
    /// Counts the stretches whose `tos` are listed.
    stamp: u32,
}

impl<'a> Search<'a> {
    fn new(c: &'a Costs, t: Vec<Leg>) -> Self {
        let n = t.len();
        let mut s = Self {
            c,
            t,
            pos: vec![0; n],
            queue: std::collections::VecDeque::with_capacity(n),
            queued: vec![false; n],
            places: Vec::with_capacity(4 + 2 * NEAR),
            tos: Vec::with_capacity(2 * (4 + 2 * NEAR)),
            to_listed: vec![0; n + 1],
            stamp: 0,
        };
        s.reindex();
        s
    }

    fn reindex(&mut self) {
        for (i, l) in self.t.iter().enumerate() {
            self.pos[l.0] = i;
        }
    }

    fn activate(&mut self, lane: usize) {
        if !self.queued[lane] {
            self.queued[lane] = true;
            self.queue.push_back(lane);
        }
    }

    /// Marks the lanes either side of the link before index `i` to be tried.
    fn activate_link(&mut self, i: usize) {
        for j in [i.wrapping_sub(1), i] {
            if let Some(&(lane, _)) = self.t.get(j) {
                self.activate(lane);
            }
        }
    }

    /// Sets the tour to `from` with the stretches `p1..p2` and `p2..p3`
    /// swapped (a double bridge: three links change, which no 2-opt or
    /// or-opt move undoes in one step), and marks the new links' lanes.
    fn double_bridge(&mut self, from: &[Leg], p1: usize, p2: usize, p3: usize) {
        self.t.clear();
        self.t.extend_from_slice(&from[..p1]);
        self.t.extend_from_slice(&from[p2..p3]);
        self.t.extend_from_slice(&from[p1..p2]);
        self.t.extend_from_slice(&from[p3..]);
        self.reindex();
        for i in [p1, p1 + p3 - p2, p3] {
            self.activate_link(i);
        }
    }

    /// Applies improving moves until no marked lane has one.
    fn settle(&mut self) {
        let mut budget = MAX_MOVES_PER_LANE * self.t.len();
        while let Some(lane) = self.queue.pop_front() {
            self.queued[lane] = false;
            if budget == 0 {
                continue;
            }
            let Some(mv) = self.best_at(self.pos[lane]) else {
                continue;
            };
            budget -= 1;
            for i in [mv.at, mv.at + mv.len] {
                self.activate_link(i);
            }
            self.apply(mv);
            for i in [mv.to, mv.to + mv.len] {
                self.activate_link(i);
            }
            self.activate(lane);
        }
    }

    /// Applies `mv` in place: the stretch is rotated to its new index (the
    /// lanes between shift over it), then turned round if `rev`.
    fn apply(&mut self, mv: Move) {
        let Move { at, len, to, rev } = mv;
        if to <= at {
            self.t[to..at + len].rotate_right(len);
        } else {
            self.t[at..to + len].rotate_left(len);
        }
        if rev {
            let seg = &mut self.t[to..to + len];
            seg.reverse();
            for l in seg {
                l.1 = !l.1;
            }
        }
        self.reindex();
    }

    /// What taking the stretch `t[at..at + len]` out saves: its two links
    /// less the one that closes the gap.
    fn removed(&self, at: usize, len: usize) -> f64 {
        let c = self.c;
        let (prev, next, se, sx) = self.stretch_ends(at, len);
        c.link(prev, se) + c.tail(sx, next) - next.map_or(0.0, |b| c.link(prev, b))
    }

    /// The ends around and of the stretch `t[at..at + len]`: the exit end
    /// before it and the entry end after it (`None` at the tour's start and
    /// end), its entry end and its exit end.
    fn stretch_ends(&self, at: usize, len: usize) -> (Option<usize>, Option<usize>, usize, usize) {
        let t = &self.t;
        let prev = (at > 0).then(|| exit(t[at - 1]));
        let next = t.get(at + len).map(|&l| entry(l));
        (prev, next, entry(t[at]), exit(t[at + len - 1]))
    }

    /// What driving the stretch `t[at..at + len]` backwards in place (a
    /// 2-opt move) saves: [`Self::removed`] less what putting it back
    /// turned round costs, in the same operations (the same value to the
    /// bit), without looking up the link it opens and closes twice.
    fn reversal_gain(&self, at: usize, len: usize) -> f64 {
        let c = self.c;
        let (prev, next, se, sx) = self.stretch_ends(at, len);
        let base = next.map_or(0.0, |b| c.link(prev, b));
        (c.link(prev, se) + c.tail(sx, next) - base) - (c.link(prev, sx) + c.tail(se, next) - base)
    }

    /// The link the stretch `t[at..at + len]` would open when put back at
    /// index `to` of the tour without it: the exit end before and the entry
    /// end after that index (`None` at the tour's start and end), and the
    /// cost of the link between them.
    fn gap(&self, at: usize, len: usize, to: usize) -> Gap {
        let (t, c) = (&self.t, self.c);
        // The tour without the stretch: its index q is t[q] before at, t[q + len] after.
        let rest = |q: usize| if q < at { t[q] } else { t[q + len] };
        let before = (to > 0).then(|| exit(rest(to - 1)));
        let after = (to < t.len() - len).then(|| entry(rest(to)));
        let base = after.map_or(0.0, |b| c.link(before, b));
        (before, after, base)
    }

    /// What putting the stretch of `mv` back costs, its gap already found:
    /// its two new links less the one it opens.
    fn added_at(&self, mv: Move, (before, after, base): Gap) -> f64 {
        let (t, c) = (&self.t, self.c);
        let (se, sx) = (entry(t[mv.at]), exit(t[mv.at + mv.len - 1]));
        let (e, x) = if mv.rev { (sx, se) } else { (se, sx) };
        c.link(before, e) + c.tail(x, after) - base
    }

    /// The best improving move that links the lane at index `i`, or a
    /// stretch it starts or ends, to a lane near one of its ends (or to
    /// the tour's ends); `None` when there is none.
    fn best_at(&mut self, i: usize) -> Option<Move> {
        let n = self.t.len();
        let mut places = std::mem::take(&mut self.places);
        let mut tos = std::mem::take(&mut self.tos);
        places.clear();
        places.extend([0, n - 1, i.saturating_sub(1), (i + 1).min(n - 1)]);
        // An improving move makes a link shorter than one it breaks: from
        // each end of the lane, only ends nearer than its present link.
        let (t, c) = (&self.t, self.c);
        let here = [
            (
                entry(t[i]),
                (i > 0).then(|| c.link(Some(exit(t[i - 1])), entry(t[i]))),
            ),
            (
                exit(t[i]),
                (i + 1 < n).then(|| c.link(Some(exit(t[i])), entry(t[i + 1]))),
            ),
        ];
        for (end, linked) in here {
            let bound = linked.unwrap_or(f64::INFINITY);
            let row = &c.d[end * c.m..(end + 1) * c.m];
            places.extend(
                c.near[end]
                    .iter()
                    .take_while(|&&e| row[e] < bound)
                    .map(|&e| self.pos[e / 2]),
            );
        }
        sort_unique(&mut places, n);
        let mut best: Option<(f64, Move)> = None;
        let mut consider = |mv: Move, g: f64| {
            if g > 1e-9 && best.is_none_or(|(b, _)| g > b) {
                best = Some((g, mv));
            }
        };
        for &p in &places {
            // 2-opt: a stretch from `i` to `p` (or next to it) backwards.
            for (lo, hi) in [(i, p), (i, p.wrapping_sub(1)), (p, i), (p + 1, i)] {
                if lo <= hi && hi < n {
                    let len = hi - lo + 1;
                    let mv = Move {
                        at: lo,
                        len,
                        to: lo,
                        rev: true,
                    };
                    consider(mv, self.reversal_gain(lo, len));
                }
            }
        }
        // Or-opt: a stretch of up to three lanes starting or ending at `i`,
        // put before or after the lane at a place, either way round. The
        // costs are shortest paths (a metric), so a stretch whose removal
        // saves nothing cannot gain anywhere.
        for len in 1..=3usize.min(n - 1) {
            for at in [Some(i), (i + 1).checked_sub(len).filter(|_| len > 1)]
                .into_iter()
                .flatten()
            {
                if at + len > n {
                    continue;
                }
                let removed = self.removed(at, len);
                if removed <= 1e-9 {
                    continue;
                }
                // Each index the stretch may go to, once (neighbouring
                // places share one), in the order the places give them.
                tos.clear();
                self.stamp = self.stamp.wrapping_add(1);
                if self.stamp == 0 {
                    self.to_listed.fill(0);
                    self.stamp = 1;
                }
                for &p in places.iter().filter(|&&p| !(at..at + len).contains(&p)) {
                    let r = if p < at { p } else { p - len };
                    for to in [r, r + 1] {
                        if self.to_listed[to] != self.stamp {
                            self.to_listed[to] = self.stamp;
                            tos.push(to);
                        }
                    }
                }
                for &to in &tos {
                    let gaps = self.gap(at, len, to);
                    for rev in [false, true] {
                        let mv = Move { at, len, to, rev };
                        consider(mv, removed - self.added_at(mv, gaps));
                    }
                }
            }
        }
        self.places = places;
        self.tos = tos;
        best.map(|(_, mv)| mv)
    }
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
    fn places_come_out_sorted_once_each_by_bit_set_and_by_sort() {
        for n in [5, 128, 129, 300] {
            let mut lcg = Lcg(n as u64);
            let mut v: Vec<usize> = (0..40).map(|_| lcg.next() as usize % n).collect();
            v.extend([0, n - 1, n - 1]);
            let mut want = v.clone();
            want.sort_unstable();
            want.dedup();
            sort_unique(&mut v, n);
            assert_eq!(v, want, "n = {n}");
        }
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
        let mut g = Lcg(7);
        let mut rnd = || g.unit();
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

    /// The exact optimum by dynamic programming over the sets of lanes
    /// driven (Held-Karp): the least cost of driving a set, ending at an
    /// exit end.
    fn exact(tc: &TourCosts) -> f64 {
        let c = Costs::new(tc);
        let (m, n) = (c.m, c.m / 2);
        let full = 1usize << n;
        let mut dp = vec![f64::INFINITY; full * m];
        for l in 0..n {
            for leg in [(l, false), (l, true)] {
                dp[(1 << l) * m + exit(leg)] = c.link(None, entry(leg));
            }
        }
        for mask in 1..full {
            for x in 0..m {
                let v = dp[mask * m + x];
                if !v.is_finite() {
                    continue;
                }
                for l in (0..n).filter(|&l| mask & (1 << l) == 0) {
                    for leg in [(l, false), (l, true)] {
                        let slot = &mut dp[(mask | 1 << l) * m + exit(leg)];
                        *slot = slot.min(v + c.link(Some(x), entry(leg)));
                    }
                }
            }
        }
        dp[(full - 1) * m..]
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn kicks_reach_the_exact_optimum_where_one_local_search_stops_short() {
        // Deterministic pseudo-random lanes in two clusters (a linear
        // congruential generator), 10 lanes each instance.
        let mut g = Lcg(11);
        let mut rnd = || g.unit();
        let (mut exact_hits, mut short_of_it, mut worst) = (0, 0, 0.0f64);
        let runs = 20;
        for _ in 0..runs {
            let lanes: Vec<_> = (0..10)
                .map(|k| {
                    let ox = if k % 2 == 0 { 0.0 } else { 6.0 };
                    let (x, y, l) = (ox + rnd() * 3.0, rnd() * 4.0, 0.3 + rnd() * 1.5);
                    if rnd() < 0.5 {
                        ((x, y), (x + l, y))
                    } else {
                        ((x, y), (x, y + l))
                    }
                })
                .collect();
            let (start, between) = costs(&lanes, (rnd() * 9.0, rnd() * 4.0));
            let tc = TourCosts {
                start: &start,
                between: &between,
            };
            let best = exact(&tc);
            let kicked = tour_cost(&lane_tour(&tc), &tc);
            let one = tour_cost(&search_tour(&tc, 0), &tc);
            assert!(
                kicked <= one + 1e-9,
                "kicks kept a longer tour: {kicked} > {one}"
            );
            assert!(
                kicked >= best - 1e-9,
                "shorter than the optimum: {kicked} < {best}"
            );
            exact_hits += usize::from(kicked <= best + 1e-9);
            short_of_it += usize::from(one > best + 1e-9);
            worst = worst.max(kicked / best);
        }
        assert!(
            exact_hits >= runs - 1,
            "{exact_hits} of {runs} optimal, worst ratio {worst}"
        );
        assert!(worst < 1.02, "worst ratio {worst}");
        assert!(
            short_of_it > 0,
            "one local search found every optimum: the test proves nothing"
        );
    }

    #[test]
    fn the_same_costs_give_the_same_tour() {
        let lanes: Vec<_> = (0..12)
            .map(|k| {
                let x = f64::from(k % 4) * 0.3 + f64::from(k / 4) * 2.0;
                ((x, 0.0), (x, 1.0 + 0.1 * f64::from(k % 3)))
            })
            .collect();
        let (start, between) = costs(&lanes, (3.0, -1.0));
        let tc = TourCosts {
            start: &start,
            between: &between,
        };
        assert_eq!(lane_tour(&tc), lane_tour(&tc));
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
