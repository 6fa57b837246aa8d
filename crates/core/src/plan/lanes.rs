//! Back-and-forth lanes inside one region (a decomposition cell, or a
//! leftover patch): parallel to the sweep direction, on one lane lattice
//! shared by all regions (one lane spacing apart, so lanes of neighbouring
//! regions line up and nothing beside a virtual edge is swept twice), plus
//! one lane hugging a wall where the lattice leaves floor along it (so along
//! walls nothing is dropped) and fix-up lanes for stretches the lattice
//! lanes could not drive; each lane trimmed to the stretch that still has
//! uncovered floor within the tool's reach, and chained in the order with
//! the fewest and shortest connections.

use nalgebra::Point2;

use super::cspace::Frame;
use crate::geom::Segment;

/// Lane direction on the grid (the world is rectilinear: lanes run along x or y).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// Lanes parallel to x, stacked in y.
    X,
    /// Lanes parallel to y, stacked in x.
    Y,
}

impl Axis {
    /// The axis closest to the direction `angle` (rad).
    pub(crate) fn from_angle(angle: f64) -> Self {
        let a = angle.rem_euclid(std::f64::consts::PI);
        if (std::f64::consts::FRAC_PI_4..3.0 * std::f64::consts::FRAC_PI_4).contains(&a) {
            Axis::Y
        } else {
            Axis::X
        }
    }
}

/// One straight lane, driven from `a` to `b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lane {
    /// Start (m).
    pub a: Point2<f64>,
    /// End (m).
    pub b: Point2<f64>,
    /// True for a fix-up lane (floor the evenly spaced lanes missed).
    pub(crate) fixup: bool,
}

impl Lane {
    /// The lane driven the other way.
    pub fn reversed(&self) -> Lane {
        Lane {
            a: self.b,
            b: self.a,
            fixup: self.fixup,
        }
    }

    /// Length (m).
    pub fn length(&self) -> f64 {
        (self.b - self.a).norm()
    }
}

/// What the lane generator needs: the region's admissible centres, the
/// uncovered floor to reach, the tool, and the lane lattice.
pub struct LaneInput<'a> {
    /// Grid geometry.
    pub frame: Frame,
    /// Cells where the robot centre may drive in this region.
    pub(crate) admissible: &'a [bool],
    /// Cells where the robot centre may drive at all (any region): a lane
    /// whose position lies in this region may pass beside it over these.
    pub(crate) drivable: &'a [bool],
    /// Uncovered floor cells this region must reach.
    pub targets: &'a [bool],
    /// Bounding box (x0, y0, x1, y1) inclusive of admissible and target cells.
    pub(crate) bbox: (usize, usize, usize, usize),
    /// Lane direction.
    pub axis: Axis,
    /// Largest distance between neighbouring lanes (m).
    pub spacing: f64,
    /// How far across a lane the tool surely reaches (m).
    pub reach: f64,
    /// Phase of the lane lattice (m across the lanes: y for [`Axis::X`], x
    /// for [`Axis::Y`]): lanes lie at `phase + k * spacing`, the same for
    /// every region, so lanes of neighbouring regions line up and floor
    /// beside a virtual edge is swept by one lattice lane only.
    pub phase: f64,
    /// May the lanes leave the lattice where the region is walled in across
    /// (see [`lanes`])? False for leftover patches, whose floor lies between
    /// lanes already driven on the lattice.
    pub(crate) fit_walls: bool,
    /// Fewest uncovered floor cells a fix-up lane must reach: a fix-up
    /// for less costs more in detour (two joins) than it covers.
    pub(crate) min_fixup_cells: usize,
    /// Fewest uncovered floor cells any other lane piece must newly reach
    /// (a stub of a lattice lane into a corner, for a few cells, costs two
    /// joins over swept floor); 0 or 1 keeps every piece.
    pub(crate) min_lane_cells: usize,
}

/// The lattice lane position (m across) nearest to `v_m`.
pub(crate) fn lattice_position(phase: f64, spacing: f64, v_m: f64) -> f64 {
    phase + ((v_m - phase) / spacing).round() * spacing
}

/// (u, v) of cell (x, y) for the axis: u along lanes, v across.
fn uv(axis: Axis, x: usize, y: usize) -> (usize, usize) {
    match axis {
        Axis::X => (x, y),
        Axis::Y => (y, x),
    }
}

fn xy(axis: Axis, u: usize, v: usize) -> (usize, usize) {
    match axis {
        Axis::X => (u, v),
        Axis::Y => (v, u),
    }
}

/// (along, across) coordinates (m) of world point `p` for the axis.
fn along_across(axis: Axis, p: &Point2<f64>) -> (f64, f64) {
    match axis {
        Axis::X => (p.x, p.y),
        Axis::Y => (p.y, p.x),
    }
}

/// World point of the along-lane coordinate `u_m` on the lane at `v_m` (m).
fn point(axis: Axis, u_m: f64, v_m: f64) -> Point2<f64> {
    match axis {
        Axis::X => Point2::new(u_m, v_m),
        Axis::Y => Point2::new(v_m, u_m),
    }
}

/// The region in lane coordinates, with the record of floor its lanes serve.
struct Sweep<'a> {
    input: &'a LaneInput<'a>,
    u_lo: usize,
    u_hi: usize,
    v_lo: usize,
    v_hi: usize,
    /// Origin along (u) and across (v) the lanes (m).
    ou: f64,
    ov: f64,
    reach: f64,
    served: Vec<bool>,
    out: Vec<Lane>,
}

impl Sweep<'_> {
    fn coord(&self, k: usize, o: f64) -> f64 {
        o + (k as f64 + 0.5) * self.input.frame.res
    }

    fn at(&self, mask: &[bool], u: usize, v: usize) -> bool {
        let (x, y) = xy(self.input.axis, u, v);
        mask[y * self.input.frame.w + x]
    }

    fn slot(&self, u: usize, v: usize) -> usize {
        (v - self.v_lo) * (self.u_hi - self.u_lo + 1) + (u - self.u_lo)
    }

    fn unserved(&self, u: usize, v: usize) -> bool {
        self.at(self.input.targets, u, v) && !self.served[self.slot(u, v)]
    }

    /// Grid rows (v) bracketing the lane position `pos`: the centre passes
    /// between them (one row when `pos` is a row centre), and the one of the
    /// two holding `pos` (the lane's home row).
    fn rows(&self, pos: f64) -> Option<(usize, usize, usize)> {
        let fv = (pos - self.ov) / self.input.frame.res - 0.5;
        if fv < -1e-6 {
            return None;
        }
        let near = fv.round();
        let (r1, r2) = if (fv - near).abs() < 1e-6 {
            (near.max(0.0) as usize, near.max(0.0) as usize)
        } else {
            (fv.floor() as usize, fv.floor() as usize + 1)
        };
        let home = if fv - fv.floor() >= 0.5 { r2 } else { r1 };
        (r2 <= self.v_hi).then_some((r1, r2, home))
    }

    /// Calls `f(u, v)` for every cell the tool reaches driving from `a` to
    /// `b` (m along) at `pos` (m across).
    fn reached(&self, a: f64, b: f64, pos: f64, mut f: impl FnMut(usize, usize)) {
        for v in self.v_lo..=self.v_hi {
            let dv = (self.coord(v, self.ov) - pos).abs();
            if dv > self.reach {
                continue;
            }
            let half = (self.reach * self.reach - dv * dv).max(0.0).sqrt();
            for uu in self.u_lo..=self.u_hi {
                let c = self.coord(uu, self.ou);
                if c >= a - half && c <= b + half {
                    f(uu, v);
                }
            }
        }
    }

    /// Unserved target cells the tool reaches driving from `a` to `b` (m
    /// along) at `pos` (m across).
    fn fresh(&self, a: f64, b: f64, pos: f64) -> usize {
        let mut n = 0;
        self.reached(a, b, pos, |u, v| n += usize::from(self.unserved(u, v)));
        n
    }

    /// Marks the floor the tool reaches driving from `a` to `b` (m along)
    /// at `pos` (m across) as served.
    fn mark(&mut self, a: f64, b: f64, pos: f64) {
        let mut slots = Vec::new();
        self.reached(a, b, pos, |u, v| slots.push(self.slot(u, v)));
        for k in slots {
            self.served[k] = true;
        }
    }

    /// Lanes at `pos` (m across): along every admissible stretch, trimmed
    /// to the columns with unserved floor in the tool's reach, split where
    /// such columns are more than `gap` apart. Returns how many were added.
    fn lanes_at(&mut self, pos: f64, gap: f64, fixup: bool) -> usize {
        let Some((r1, r2, home)) = self.rows(pos) else {
            return 0;
        };
        let reach = self.reach;
        let before = self.out.len();
        let ok = |s: &Self, u: usize| {
            s.at(s.input.admissible, u, home)
                && s.at(s.input.drivable, u, r1)
                && s.at(s.input.drivable, u, r2)
        };
        let mut u = self.u_lo;
        while u <= self.u_hi {
            if !ok(self, u) {
                u += 1;
                continue;
            }
            let start = u;
            while u <= self.u_hi && ok(self, u) {
                u += 1;
            }
            let (s_m, e_m) = (self.coord(start, self.ou), self.coord(u - 1, self.ou));
            let mut pieces: Vec<(f64, f64)> = Vec::new();
            for uu in self.u_lo..=self.u_hi {
                let c = self.coord(uu, self.ou);
                if c < s_m - reach || c > e_m + reach {
                    continue;
                }
                let du = c - c.clamp(s_m, e_m);
                let hit = (self.v_lo..=self.v_hi).any(|v| {
                    let dv = self.coord(v, self.ov) - pos;
                    dv * dv + du * du <= reach * reach && self.unserved(uu, v)
                });
                if !hit {
                    continue;
                }
                match pieces.last_mut() {
                    Some((_, hi)) if c - *hi <= gap => *hi = c,
                    _ => pieces.push((c, c)),
                }
            }
            for (lo_t, hi_t) in pieces {
                let a = lo_t.clamp(s_m, e_m);
                let b = hi_t.clamp(s_m, e_m);
                if !fixup && self.fresh(a, b, pos) < self.input.min_lane_cells {
                    continue;
                }
                self.mark(a, b, pos);
                self.out.push(Lane {
                    a: point(self.input.axis, a, pos),
                    b: point(self.input.axis, b, pos),
                    fixup,
                });
            }
        }
        self.out.len() - before
    }

    /// Connections between lanes neighbouring across (ends at most `join`
    /// apart) sweep the floor between their ends (one side or the other,
    /// whatever the order): counts both as served.
    fn mark_connections(&mut self, join: f64) {
        let axis = self.input.axis;
        let across = |l: &Lane| match axis {
            Axis::X => l.a.y,
            Axis::Y => l.a.x,
        };
        let mut order: Vec<Lane> = self.out.clone();
        order.sort_by(|l, m| across(l).total_cmp(&across(m)));
        for w in order.windows(2) {
            for (p, q) in [(w[0].a, w[1].a), (w[0].b, w[1].b)] {
                if (q - p).norm() > join {
                    continue;
                }
                let join_line = Segment::new(p, q);
                // Only cells within reach of the join's bounding box.
                let (pu, pv) = along_across(axis, &p);
                let (qu, qv) = along_across(axis, &q);
                let (u0, u1) =
                    self.cells_between(pu.min(qu), pu.max(qu), self.ou, self.u_lo, self.u_hi);
                let (v0, v1) =
                    self.cells_between(pv.min(qv), pv.max(qv), self.ov, self.v_lo, self.v_hi);
                for v in v0..=v1 {
                    for uu in u0..=u1 {
                        let c = point(axis, self.coord(uu, self.ou), self.coord(v, self.ov));
                        if join_line.distance_to(&c) <= self.reach {
                            let i = self.slot(uu, v);
                            self.served[i] = true;
                        }
                    }
                }
            }
        }
    }

    /// The range of cells (clamped to `lo..=hi`) whose centres may lie
    /// within reach of the stretch `a..=b` (m, origin `o`).
    fn cells_between(&self, a: f64, b: f64, o: f64, lo: usize, hi: usize) -> (usize, usize) {
        let res = self.input.frame.res;
        let first = ((a - self.reach - o) / res - 0.5).floor().max(0.0) as usize;
        let last = ((b + self.reach - o) / res - 0.5).ceil().max(0.0) as usize;
        (first.max(lo), last.min(hi))
    }

    /// The extreme rows (v) with unserved floor: (lowest, highest).
    fn unserved_span(&self) -> Option<(usize, usize)> {
        let mut span: Option<(usize, usize)> = None;
        for v in self.v_lo..=self.v_hi {
            if (self.u_lo..=self.u_hi).any(|u| self.unserved(u, v)) {
                span = Some(span.map_or((v, v), |(lo, _)| (lo, v)));
            }
        }
        span
    }
}

/// The lanes covering the region's targets (unordered, each from low u to
/// high u): the lattice lanes inside the region; then, where floor along a
/// wall is still out of reach, one lane hugging that wall on either side;
/// then fix-up lanes along single rows for what blocked stretches left.
///
/// A region walled in across the lanes on both sides (no drivable space of
/// another region directly beside it across) shares no lane with a
/// neighbour, so its lanes may leave the lattice: they are also spread
/// evenly from wall to wall, and that set is kept when it is cheaper (see
/// `lane_cost`) — in a strip between two walls the lattice plus the lanes
/// hugging both walls can take one lane more than the strip needs.
pub fn lanes(input: &LaneInput) -> Vec<Lane> {
    let f = &input.frame;
    let (x0, y0, x1, y1) = input.bbox;
    let (u_lo, v_lo) = uv(input.axis, x0, y0);
    let (u_hi, v_hi) = uv(input.axis, x1, y1);
    let (ou, ov) = match input.axis {
        Axis::X => (f.origin.x, f.origin.y),
        Axis::Y => (f.origin.y, f.origin.x),
    };
    let res = f.res;
    let mut sw = Sweep {
        input,
        u_lo,
        u_hi,
        v_lo,
        v_hi,
        ou,
        ov,
        // A hair of tolerance: rows exactly half a spacing away count as reached.
        reach: input.reach.max(res) + 1e-6,
        served: vec![false; (u_hi - u_lo + 1) * (v_hi - v_lo + 1)],
        out: Vec::new(),
    };
    // Range of admissible rows.
    let (mut a_min, mut a_max) = (usize::MAX, 0);
    for v in v_lo..=v_hi {
        if (u_lo..=u_hi).any(|u| sw.at(input.admissible, u, v)) {
            a_min = a_min.min(v);
            a_max = a_max.max(v);
        }
    }
    let Some((t_lo, t_hi)) = sw.unserved_span() else {
        return Vec::new();
    };
    if a_min == usize::MAX {
        return Vec::new();
    }
    let (a_lo, a_hi) = (sw.coord(a_min, ov), sw.coord(a_max, ov));
    // Lattice lanes whose home row is admissible (a lane may lie up to half
    // a grid cell beyond the outermost admissible row centres).
    let (p_lo, p_hi) = (a_lo - res / 2.0, a_hi + res / 2.0);
    let mut lattice = Vec::new();
    let mut pos = lattice_position(input.phase, input.spacing, p_lo);
    if pos < p_lo - 1e-9 {
        pos += input.spacing;
    }
    while pos < p_hi - 1e-9 {
        lattice.push(pos);
        pos += input.spacing;
    }
    let on_lattice = sw.finish(&lattice, (a_min, a_max));
    if !input.fit_walls {
        return on_lattice;
    }
    let contacts = sw.contacts_across(a_min, a_max);
    // Beside another region, lanes off the lattice may sweep that region's
    // floor again (about a tool width along each contact): the set must save
    // at least that much driving.
    let penalty = contacts as f64 * res;
    let longest = on_lattice.iter().map(Lane::length).fold(0.0, f64::max);
    if penalty >= longest + input.spacing {
        return on_lattice;
    }
    // Evenly spread from the lane reaching the lowest unserved row to the
    // one reaching the highest.
    let reach = sw.reach;
    let lo = (sw.coord(t_lo, ov) - res / 2.0 + reach).clamp(a_lo, a_hi);
    let hi = (sw.coord(t_hi, ov) + res / 2.0 - reach).clamp(a_lo, a_hi);
    let fitted: Vec<f64> = if hi - lo < 1e-9 {
        vec![(lo + hi) / 2.0]
    } else {
        let n = ((hi - lo) / input.spacing - 1e-9).ceil().max(1.0) as usize;
        (0..=n)
            .map(|k| lo + (hi - lo) * k as f64 / n as f64)
            .collect()
    };
    sw.served.fill(false);
    sw.out.clear();
    let spread = sw.finish(&fitted, (a_min, a_max));
    let (c_spread, c_lattice) = (
        lane_cost(&spread, input.spacing),
        lane_cost(&on_lattice, input.spacing),
    );
    if c_spread + penalty < c_lattice - 1e-9 {
        spread
    } else {
        on_lattice
    }
}

/// What a set of lanes costs to drive, for choosing between two sets: the
/// lanes' length plus one lane spacing for each lane (a U-turn's connection).
pub(crate) fn lane_cost(lanes: &[Lane], spacing: f64) -> f64 {
    lanes.iter().map(|l| l.length() + spacing).sum()
}

impl Sweep<'_> {
    /// How many admissible cells have drivable space of another region
    /// directly beside them across the lanes (rows `a_min..=a_max`); cells
    /// on the bounding box's edge count (what lies beyond is not known).
    fn contacts_across(&self, a_min: usize, a_max: usize) -> usize {
        let (adm, drv) = (self.input.admissible, self.input.drivable);
        let mut count = 0;
        for v in a_min..=a_max {
            for u in self.u_lo..=self.u_hi {
                if !self.at(adm, u, v) {
                    continue;
                }
                let beside = |n: usize| !self.at(adm, u, n) && self.at(drv, u, n);
                if v == self.v_lo || v == self.v_hi || beside(v - 1) || beside(v + 1) {
                    count += 1;
                }
            }
        }
        count
    }

    /// Distance across from `pos` to the nearest lane passing along
    /// `lo..=hi` (m along); infinite when none does.
    fn clearance(&self, pos: f64, lo: f64, hi: f64) -> f64 {
        let ua = |p: &Point2<f64>| along_across(self.input.axis, p);
        self.out
            .iter()
            .filter(|l| {
                let (a, b) = (ua(&l.a).0, ua(&l.b).0);
                a.min(b) <= hi && a.max(b) >= lo
            })
            .map(|l| (ua(&l.a).1 - pos).abs())
            .fold(f64::INFINITY, f64::min)
    }

    /// Lanes at `positions` (m across), then where floor along a wall is
    /// still out of reach one lane hugging it, then fix-up lanes; returns
    /// them and leaves the record of served floor filled.
    fn finish(&mut self, positions: &[f64], (a_min, a_max): (usize, usize)) -> Vec<Lane> {
        let input = self.input;
        let (ov, res) = (self.ov, input.frame.res);
        let (a_lo, a_hi) = (self.coord(a_min, ov), self.coord(a_max, ov));
        let join = turn_join(input.spacing);
        for &pos in positions {
            self.lanes_at(pos, join, false);
        }
        // Walls: floor beyond the outermost lanes gets a lane hugging it.
        let reach = self.reach;
        self.mark_connections(join);
        let lowest = positions.iter().copied().fold(f64::INFINITY, f64::min);
        let highest = positions.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if let Some((lo, _)) = self.unserved_span() {
            let p = (self.coord(lo, ov) - res / 2.0 + reach).clamp(a_lo, a_hi);
            if p < lowest - 1e-9 {
                self.lanes_at(p, join, false);
            }
        }
        if let Some((_, hi)) = self.unserved_span() {
            let p = (self.coord(hi, ov) + res / 2.0 - reach).clamp(a_lo, a_hi);
            if p > highest + 1e-9 {
                self.lanes_at(p, join, false);
            }
        }
        self.mark_connections(join);
        // Fix-up: floor the lanes could not reach (their path between two
        // rows was blocked there) gets short lanes along single admissible
        // rows, the row reaching most of it first; of rows reaching as much,
        // the one farthest across from the lanes beside that floor (the
        // least swept again).
        let (u_lo, u_hi, v_lo, v_hi) = (self.u_lo, self.u_hi, self.v_lo, self.v_hi);
        for _ in 0..16 {
            let mut best: Option<(usize, f64, usize)> = None;
            for row in a_min..=a_max {
                let mut count = 0;
                let (mut first, mut last) = (usize::MAX, 0);
                for v in v_lo..=v_hi {
                    let dv = (self.coord(v, ov) - self.coord(row, ov)).abs();
                    if dv > reach {
                        continue;
                    }
                    let half = ((reach * reach - dv * dv).max(0.0).sqrt() / res).floor() as i64;
                    for u in u_lo..=u_hi {
                        if !self.unserved(u, v) {
                            continue;
                        }
                        let lo = (u as i64 - half).max(u_lo as i64) as usize;
                        let hi = ((u as i64 + half) as usize).min(u_hi);
                        if (lo..=hi).any(|uu| self.at(input.admissible, uu, row)) {
                            count += 1;
                            first = first.min(u);
                            last = last.max(u);
                        }
                    }
                }
                if count < input.min_fixup_cells.max(1) || best.is_some_and(|(c, ..)| count < c) {
                    continue;
                }
                let clear = self.clearance(
                    self.coord(row, ov),
                    self.coord(first, self.ou) - reach,
                    self.coord(last, self.ou) + reach,
                );
                if best.is_none_or(|(c, d, _)| count > c || clear > d + 1e-9) {
                    best = Some((count, clear, row));
                }
            }
            let Some((.., row)) = best else { break };
            if self.lanes_at(self.coord(row, ov), input.spacing / 2.0, true) == 0 {
                break;
            }
        }
        self.out.clone()
    }
}

/// One way to drive a region's lanes: the lanes in order and the length
/// driven inside the region (lanes plus connections, straight-line).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Variant {
    /// Lanes in driving order.
    pub lanes: Vec<Lane>,
    /// Length of lanes and connections (m).
    pub length: f64,
}

impl Variant {
    /// Where the variant starts.
    pub fn entry(&self) -> Point2<f64> {
        self.lanes
            .first()
            .map(|l| l.a)
            .unwrap_or_else(Point2::origin)
    }

    /// Where the variant ends.
    pub fn exit(&self) -> Point2<f64> {
        self.lanes
            .last()
            .map(|l| l.b)
            .unwrap_or_else(Point2::origin)
    }
}

/// The ways to drive `lanes`: starting with the first or the last lane
/// (across), from either end, the rest chained greedily by the nearest lane
/// end (a zig-zag in a simple cell), then improved by moving single lanes
/// to where they lengthen the connections least and by driving stretches
/// backwards, keeping the joins at most `keep` long (pass
/// [`turn_join`] of the lane spacing). Up to four variants.
pub(crate) fn variants(lanes: &[Lane], keep: f64) -> Vec<Variant> {
    if lanes.is_empty() {
        return Vec::new();
    }
    let across = |l: &Lane| {
        let d = l.b - l.a;
        if d.x.abs() >= d.y.abs() {
            l.a.y
        } else {
            l.a.x
        }
    };
    let (mut first, mut last) = (0, 0);
    for (i, l) in lanes.iter().enumerate() {
        if across(l) < across(&lanes[first]) {
            first = i;
        }
        if across(l) > across(&lanes[last]) {
            last = i;
        }
    }
    let starts: &[usize] = if first == last {
        &[first][..]
    } else {
        &[first, last][..]
    };
    let mut out = Vec::new();
    for &s in starts {
        for rev in [false, true] {
            let l0 = if rev { lanes[s].reversed() } else { lanes[s] };
            let mut used = vec![false; lanes.len()];
            used[s] = true;
            let mut seq = vec![l0];
            let mut at = l0.b;
            let mut at_across = across(&l0);
            for _ in 1..lanes.len() {
                let mut pick: Option<(f64, usize, bool)> = None;
                for (i, l) in lanes.iter().enumerate() {
                    if used[i] {
                        continue;
                    }
                    let jump = (across(l) - at_across).abs() * 0.01;
                    for (r, end) in [(false, l.a), (true, l.b)] {
                        let d = (end - at).norm() + jump;
                        if pick.is_none_or(|(bd, _, _)| d < bd) {
                            pick = Some((d, i, r));
                        }
                    }
                }
                let Some((_, i, r)) = pick else { break };
                used[i] = true;
                let l = if r { lanes[i].reversed() } else { lanes[i] };
                at = l.b;
                at_across = across(&l);
                seq.push(l);
            }
            improve_order(&mut seq, keep);
            let length = chain_length(&seq);
            out.push(Variant { lanes: seq, length });
        }
    }
    out
}

/// Longest connection between neighbouring lanes (m) that [`lanes`] counts
/// on to sweep the floor between their ends (twice the lane spacing).
pub(crate) fn turn_join(spacing: f64) -> f64 {
    2.0 * spacing
}

/// Length of lanes driven in order, with straight connections between them.
fn chain_length(seq: &[Lane]) -> f64 {
    let lanes: f64 = seq.iter().map(Lane::length).sum();
    let joins: f64 = seq.windows(2).map(|w| (w[1].a - w[0].b).norm()).sum();
    lanes + joins
}

/// Largest chain [`improve_order`] works on (its passes cost O(n²)).
const MAX_IMPROVED: usize = 48;

/// Moves single lanes (either way round) to the place in the chain where
/// they lengthen the connections least, and else drives stretches of the
/// chain backwards (2-opt), while that shortens the chain; the first lane
/// (the entry) stays first. Joins of the chain as given that are at most
/// `keep` long stay (a stretch driven backwards keeps its inner joins):
/// among them the U-turns between neighbouring lanes whose floor [`lanes`]
/// counted as swept by the connection when it trimmed the lanes (measured:
/// keeping only the joins between lanes that are not fix-ups, or none,
/// leaves floor unswept that is then given up, down to 94.7 % coverage).
fn improve_order(seq: &mut Vec<Lane>, keep: f64) {
    let n = seq.len();
    if !(3..=MAX_IMPROVED).contains(&n) {
        return;
    }
    let gap = |p: Option<&Lane>, q: Option<&Lane>| match (p, q) {
        (Some(p), Some(q)) => (q.a - p.b).norm(),
        _ => 0.0,
    };
    // Lanes by their place in the chain as given; the kept joins as pairs.
    let mut ids: Vec<usize> = (0..n).collect();
    let kept: Vec<(usize, usize)> = (0..n - 1)
        .filter(|&k| gap(seq.get(k), seq.get(k + 1)) <= keep)
        .map(|k| (k, k + 1))
        .collect();
    let fixed = |ids: &[usize], k: usize| {
        k + 1 < ids.len() && {
            let (x, y) = (ids[k].min(ids[k + 1]), ids[k].max(ids[k + 1]));
            kept.contains(&(x, y))
        }
    };
    for _ in 0..4 * n {
        let mut best: Option<(f64, usize, usize, bool)> = None;
        for i in 1..n {
            if fixed(&ids, i - 1) || fixed(&ids, i) {
                continue;
            }
            let l = seq[i];
            // Saved by taking lane i out.
            let saved = gap(seq.get(i - 1), Some(&l)) + gap(Some(&l), seq.get(i + 1))
                - gap(seq.get(i - 1), seq.get(i + 1));
            for j in 1..n {
                // Insert between j-1 and j of the chain without lane i.
                let at = |k: usize| if k < i { k } else { k + 1 };
                if at(j) == at(j - 1) + 1 && fixed(&ids, at(j - 1)) {
                    continue;
                }
                let (p, q) = (seq.get(at(j - 1)), seq.get(at(j)));
                for rev in [false, true] {
                    let m = if rev { l.reversed() } else { l };
                    let added = gap(p, Some(&m)) + gap(Some(&m), q) - gap(p, q);
                    let gain = saved - added;
                    if gain > 1e-6 && best.is_none_or(|(g, ..)| gain > g) {
                        best = Some((gain, i, j, rev));
                    }
                }
            }
        }
        if let Some((_, i, j, rev)) = best {
            let l = seq.remove(i);
            seq.insert(j, if rev { l.reversed() } else { l });
            let id = ids.remove(i);
            ids.insert(j, id);
            continue;
        }
        // No single lane to move: drive a stretch of the chain backwards
        // where that shortens its two outer connections.
        let mut flip: Option<(f64, usize, usize)> = None;
        for i in 1..n {
            if fixed(&ids, i - 1) {
                continue;
            }
            for j in i + 1..n {
                if fixed(&ids, j) {
                    continue;
                }
                let before = gap(seq.get(i - 1), seq.get(i)) + gap(seq.get(j), seq.get(j + 1));
                let (fi, fj) = (seq[j].reversed(), seq[i].reversed());
                let after = gap(seq.get(i - 1), Some(&fi)) + gap(Some(&fj), seq.get(j + 1));
                let gain = before - after;
                if gain > 1e-6 && flip.is_none_or(|(g, ..)| gain > g) {
                    flip = Some((gain, i, j));
                }
            }
        }
        let Some((_, i, j)) = flip else { break };
        seq[i..=j].reverse();
        ids[i..=j].reverse();
        for l in &mut seq[i..=j] {
            *l = l.reversed();
        }
    }
}

/// The variant (see `variants`) with the least `start_cost(entry) +
/// length`, and that cost; empty when no entry has a finite cost.
pub fn order(
    lanes: &[Lane],
    keep: f64,
    start_cost: impl Fn(&Point2<f64>) -> f64,
) -> (Vec<Lane>, f64) {
    let mut best: Option<(Vec<Lane>, f64)> = None;
    for v in variants(lanes, keep) {
        let c = start_cost(&v.entry()) + v.length;
        if c.is_finite() && best.as_ref().is_none_or(|(_, b)| c < *b) {
            best = Some((v.lanes, c));
        }
    }
    best.unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> Frame {
        Frame {
            origin: Point2::new(0.0, 0.0),
            res: 0.05,
            w: 60,
            h: 40,
        }
    }

    /// A lane input over the test frame: lanes along x, 0.29 m apart, the
    /// lattice at 0.225 m, walls fitted, fix-ups from 4 cells (the size
    /// fixed before `plan.min_fixup_area`) and every lane piece kept.
    fn room_input<'a>(adm: &'a [bool], drv: &'a [bool], tgt: &'a [bool]) -> LaneInput<'a> {
        LaneInput {
            frame: frame(),
            admissible: adm,
            drivable: drv,
            targets: tgt,
            bbox: (0, 0, 59, 39),
            axis: Axis::X,
            spacing: 0.29,
            reach: 0.145,
            phase: 0.225,
            fit_walls: true,
            min_fixup_cells: 4,
            min_lane_cells: 0,
        }
    }

    /// Admissible: x in 0.2..2.8, y in 0.2..1.8 (a 3 m x 2 m room inflated by 0.2).
    fn rect_masks(f: &Frame) -> (Vec<bool>, Vec<bool>) {
        let mut adm = vec![false; f.len()];
        let mut tgt = vec![false; f.len()];
        for i in 0..f.len() {
            let c = f.centre(i);
            adm[i] = c.x > 0.2 && c.x < 2.8 && c.y > 0.2 && c.y < 1.8;
            tgt[i] = c.x > 0.07 && c.x < 2.93 && c.y > 0.07 && c.y < 1.93;
        }
        (adm, tgt)
    }

    /// Lanes over a room whose uncovered floor is one band along the
    /// lattice lane at y = 0.515 plus a blob of `blob` cells near the
    /// lane's far end, with the given least cells per lane piece.
    fn band_and_blob(blob: usize, min_lane_cells: usize) -> Vec<Lane> {
        let f = frame();
        let (adm, _) = rect_masks(&f);
        let mut tgt: Vec<bool> = (0..f.len())
            .map(|i| {
                let c = f.centre(i);
                c.y > 0.45 && c.y < 0.6 && c.x > 0.3 && c.x < 1.2
            })
            .collect();
        // The blob: cells on the same lane's row 1.3 m on, beyond the
        // 0.58 m a piece bridges, so it is a piece of its own.
        for k in 0..blob {
            let (x, y) = (50 + k % 3, 9 + k / 3);
            tgt[y * f.w + x] = true;
        }
        let input = LaneInput {
            fit_walls: false,
            min_lane_cells,
            ..room_input(&adm, &adm, &tgt)
        };
        lanes(&input)
    }

    #[test]
    fn a_lane_stub_for_a_few_cells_is_left_out_and_one_for_more_kept() {
        // Without a least size, the 3-cell blob gets a stub of its own.
        assert_eq!(band_and_blob(3, 0).len(), 2);
        // With 8 cells required the stub goes; the band's lane stays.
        let ls = band_and_blob(3, 8);
        assert_eq!(ls.len(), 1, "{ls:?}");
        assert!(ls[0].b.x < 1.3, "{ls:?}");
        // A blob of 9 cells is worth its stub.
        assert_eq!(band_and_blob(9, 8).len(), 2);
    }

    #[test]
    fn lanes_span_the_cell_and_hug_both_walls() {
        let f = frame();
        let (adm, tgt) = rect_masks(&f);
        let input = room_input(&adm, &adm, &tgt);
        let ls = lanes(&input);
        // Targets 0.075..1.925 → centres 0.205..1.795 → ceil(1.59/0.29)+1 = 7 lanes.
        assert_eq!(ls.len(), 7, "{ls:?}");
        let ys: Vec<f64> = ls.iter().map(|l| l.a.y).collect();
        assert!(
            (ys[0] - 0.225).abs() < 0.03 && (ys[6] - 1.775).abs() < 0.03,
            "{ys:?}"
        );
        for w in ys.windows(2) {
            assert!(w[1] - w[0] <= 0.29 + 1e-9);
        }
        for l in &ls {
            assert!(l.a.x < 0.26 && l.b.x > 2.74, "{l:?}");
        }
        let (ord, cost) = order(&ls, turn_join(0.29), |p| (p - Point2::new(0.3, 0.3)).norm());
        assert_eq!(ord.len(), 7);
        // Zig-zag: consecutive lanes alternate direction.
        for w in ord.windows(2) {
            assert!((w[0].b.x - w[1].a.x).abs() < 1e-9);
            assert!((w[1].b.x - w[1].a.x).signum() != (w[0].b.x - w[0].a.x).signum());
        }
        assert!(cost < 7.0 * 2.6 + 6.0 * 0.3 + 0.2);
    }

    #[test]
    fn lanes_of_stacked_regions_lie_on_one_lattice_and_hug_only_walls() {
        let f = frame();
        // The 3 m x 2 m room cut by a virtual edge at y = 1.0; each region
        // gets the floor its lattice lanes serve (lattice 0.225 + k 0.29).
        let mut ys = Vec::new();
        for (v0, v1, t0, t1) in [(0.2, 1.0, 0.07, 0.95), (1.0, 1.8, 0.95, 1.93)] {
            let mut adm = vec![false; f.len()];
            let mut tgt = vec![false; f.len()];
            let mut all = vec![false; f.len()];
            for i in 0..f.len() {
                let c = f.centre(i);
                let inside = c.x > 0.2 && c.x < 2.8;
                all[i] = inside && c.y > 0.2 && c.y < 1.8;
                adm[i] = inside && c.y > v0 && c.y < v1;
                tgt[i] = c.x > 0.07 && c.x < 2.93 && c.y > t0 && c.y < t1;
            }
            let input = room_input(&adm, &all, &tgt);
            let mut region: Vec<f64> = lanes(&input).iter().map(|l| l.a.y).collect();
            region.sort_by(f64::total_cmp);
            ys.push(region);
        }
        // Below the edge: the lattice only (no lane pulled back to hug it).
        assert_eq!(ys[0].len(), 3, "{:?}", ys[0]);
        for (y, want) in ys[0].iter().zip([0.225, 0.515, 0.805]) {
            assert!((y - want).abs() < 1e-9, "{:?}", ys[0]);
        }
        // Above it: the lattice, then one lane hugging the real wall.
        assert_eq!(ys[1].len(), 4, "{:?}", ys[1]);
        for (y, want) in ys[1].iter().zip([1.095, 1.385, 1.675]) {
            assert!((y - want).abs() < 1e-9, "{:?}", ys[1]);
        }
        assert!(ys[1][3] > 1.74 && ys[1][3] < 1.8, "{:?}", ys[1]);
        assert!((lattice_position(0.225, 0.29, 1.0) - 1.095).abs() < 1e-9);
    }

    #[test]
    fn covered_rows_get_no_lane_and_lanes_are_trimmed() {
        let f = frame();
        let (adm, mut tgt) = rect_masks(&f);
        // Only a 0.5 m x 0.3 m patch is still uncovered.
        for (i, t) in tgt.iter_mut().enumerate() {
            let c = f.centre(i);
            *t &= c.x > 1.0 && c.x < 1.5 && c.y > 1.0 && c.y < 1.3;
        }
        let input = LaneInput {
            axis: Axis::Y,
            ..room_input(&adm, &adm, &tgt)
        };
        let ls = lanes(&input);
        assert!(!ls.is_empty() && ls.len() <= 3, "{ls:?}");
        for l in &ls {
            assert!((l.a.x - l.b.x).abs() < 1e-9, "along y");
            assert!(l.a.y >= 0.95 && l.b.y <= 1.35, "{l:?}");
        }
    }

    #[test]
    fn nothing_to_do_gives_no_lanes() {
        let f = frame();
        let (adm, _) = rect_masks(&f);
        let none = vec![false; f.len()];
        let input = room_input(&adm, &adm, &none);
        assert!(lanes(&input).is_empty());
        assert!(order(&[], 0.58, |_| 0.0).0.is_empty());
        assert_eq!(Axis::from_angle(1.5), Axis::Y);
        assert_eq!(Axis::from_angle(-3.1), Axis::X);
    }

    /// A strip between two walls, 2.5 m long, centres at y 0.2..0.8, and
    /// (with `beside`) the drivable space of another region above it.
    fn strip(f: &Frame, beside: bool) -> (Vec<bool>, Vec<bool>, Vec<bool>) {
        let mut adm = vec![false; f.len()];
        let mut drv = vec![false; f.len()];
        let mut tgt = vec![false; f.len()];
        for i in 0..f.len() {
            let c = f.centre(i);
            let along = c.x > 0.2 && c.x < 2.7;
            adm[i] = along && c.y > 0.2 && c.y < 0.8;
            drv[i] = adm[i] || (beside && along && c.y > 0.8 && c.y < 1.8);
            // Beside the other region, floor nearer its lattice lane (0.88)
            // than this region's (0.59) is the other region's.
            let top = if beside { 0.735 } else { 0.92 };
            tgt[i] = c.x > 0.07 && c.x < 2.83 && c.y > 0.08 && c.y < top;
        }
        (adm, drv, tgt)
    }

    fn strip_lanes(adm: &[bool], drv: &[bool], tgt: &[bool], fit_walls: bool) -> Vec<f64> {
        let input = LaneInput {
            // Lattice lanes at 0.30 and 0.59: both walls need a lane of their own.
            phase: 0.30,
            fit_walls,
            ..room_input(adm, drv, tgt)
        };
        let mut ys: Vec<f64> = lanes(&input).iter().map(|l| l.a.y).collect();
        ys.sort_by(f64::total_cmp);
        ys
    }

    #[test]
    fn a_strip_walled_in_on_both_sides_spreads_its_lanes_and_saves_one() {
        let f = frame();
        let (adm, drv, tgt) = strip(&f, false);
        // On the lattice: 0.30 and 0.59 plus a lane hugging each wall.
        let lattice = strip_lanes(&adm, &drv, &tgt, false);
        assert_eq!(lattice.len(), 4, "{lattice:?}");
        // Spread from wall to wall: one lane fewer, evenly spaced, so that
        // neighbouring lanes overlap by at most 5 cm of the 0.30 m tool
        // (on the lattice, the lanes hugging the walls overlap theirs by
        // 24 cm).
        let ys = strip_lanes(&adm, &drv, &tgt, true);
        assert_eq!(ys.len(), 3, "{ys:?}");
        assert!(
            (ys[0] - 0.245).abs() < 1e-5 && (ys[2] - 0.755).abs() < 1e-5,
            "{ys:?}"
        );
        for w in ys.windows(2) {
            assert!(w[1] - w[0] <= 0.29 + 1e-9 && w[1] - w[0] >= 0.25, "{ys:?}");
        }
        // The spread lanes reach every target.
        for (i, _) in tgt.iter().enumerate().filter(|(_, t)| **t) {
            let c = f.centre(i);
            let near = ys.iter().any(|y| {
                let dx = c.x - c.x.clamp(0.225, 2.675);
                (c.y - y).powi(2) + dx * dx <= 0.145f64.powi(2) + 1e-6
            });
            // (Corners beyond the lane ends are the connections' floor.)
            let corner = c.x < 0.225 || c.x > 2.675;
            assert!(
                near || corner,
                "({:.3}, {:.3}) unreached by {ys:?}",
                c.x,
                c.y
            );
        }
    }

    #[test]
    fn a_strip_beside_another_region_keeps_the_lattice() {
        let f = frame();
        let (adm, drv, tgt) = strip(&f, true);
        // 2.5 m of contact with the region above: lanes off the lattice
        // would sweep its floor again and save no lane, so the lattice
        // lanes stay.
        let ys = strip_lanes(&adm, &drv, &tgt, true);
        assert!(
            ys.iter().any(|y| (y - 0.30).abs() < 1e-6)
                && ys.iter().any(|y| (y - 0.59).abs() < 1e-6),
            "{ys:?}"
        );
    }

    #[test]
    fn moving_a_lane_left_behind_shortens_the_chain() {
        let at = |x: f64| Lane {
            a: Point2::new(x, 0.0),
            b: Point2::new(x, 0.0),
            fixup: true,
        };
        // Nearest-first from 0: 1, 2.2, then back to -1.5 (joins 5.9 m).
        let mut seq = vec![at(0.0), at(1.0), at(2.2), at(-1.5)];
        assert!((chain_length(&seq) - 5.9).abs() < 1e-9);
        improve_order(&mut seq, 0.5);
        assert_eq!(seq[0], at(0.0), "the entry stays first");
        assert!((chain_length(&seq) - 5.2).abs() < 1e-9, "{seq:?}");
        assert_eq!(seq.len(), 4);
        // A join no longer than `keep` stays: with 0 -> 1 kept, only -1.5
        // can move (to the front: 0, -1.5 ... breaks 0 -> 1, so it stays last
        // unless it goes between 1 and 2.2, which is longer).
        let mut kept = vec![at(0.0), at(1.0), at(2.2), at(-1.5)];
        improve_order(&mut kept, 1.0);
        assert_eq!(kept[1], at(1.0), "{kept:?}");
        assert!(chain_length(&kept) <= 5.9 + 1e-9);
        // A zig-zag is left as it is.
        let lane = |y: f64, rev: bool| {
            let l = Lane {
                a: Point2::new(0.0, y),
                b: Point2::new(2.0, y),
                fixup: false,
            };
            if rev {
                l.reversed()
            } else {
                l
            }
        };
        let zig: Vec<Lane> = (0..5).map(|k| lane(0.29 * k as f64, k % 2 == 1)).collect();
        let mut same = zig.clone();
        improve_order(&mut same, 0.0);
        assert_eq!(same, zig);
    }
}
