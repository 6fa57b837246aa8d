//! Bumper contacts: where an obstacle the scanner did not see must be, from
//! what the bumper proves and nothing more.
//!
//! A closed bumper proves that something touches the front half of the body
//! shell. The switches say which side (a Create 2 has two; a RoboClaw base
//! wires its bumper to one E-stop input, so both sides read closed), and the
//! motion at the time narrows it further: a robot turning in place can only
//! close its bumper with the shell's leading end (so a side switch that
//! closes on the side leading the turn is at that end); and nothing can stand
//! where the body itself has been ([`BodyTrack`]), so bearings whose contact
//! point the body has already passed over are ruled out (a lane that grazes
//! an obstacle's corner has the previous lane's track on its other side).
//! The contact is marked as a
//! short arc (a few centimetres) of the shell at that bearing, just outside
//! the body: small enough not to wall off floor beside the obstacle, and
//! repeated contacts with the same obstacle add further arcs until the
//! planner's path no longer touches it.

use nalgebra::Point2;

use serde::{Deserialize, Serialize};

use crate::base::{Sides, WheelSpeeds};
use crate::geom::{heading, polar, Pose};
use crate::grid::{CellIndex, CellState, Grid};
use crate::param_check::{invalid, ParamError};

/// Where contact marks go and how the daemon reacts to them: the
/// `[daemon.contact]` table.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactParams {
    /// Bearing of a contact on one side only (rad from straight ahead): the
    /// middle of that side's half of the front shell.
    pub side_bearing: f64,
    /// Bearing of a contact closed by turning in place on the side switch
    /// leading the turn (rad): the leading end of the front shell.
    pub(crate) turn_bearing: f64,
    /// Half width of the bumper's arc (rad from straight ahead).
    pub bumper_half_arc: f64,
    /// Distance of the contact outside the body (m): half the bumper's travel.
    pub gap: f64,
    /// Half length of the marked arc (m).
    pub arc_half_length: f64,
    /// A contact closer than this to an earlier one is the same contact (m).
    pub same_contact: f64,
    /// Longest a plan update waits for a bump's contact to reach the map
    /// (clock s).
    pub settle: f64,
    /// When coverage is otherwise done, take out (once per place) the mark
    /// that walls off the most unswept floor, if that is at least what the
    /// planner sends a lane for (`plan.min_lane_area`), so the robot tries
    /// that floor: a one-bit bumper's mark may stand up to 0.23 m from the
    /// contact, in open floor.
    pub retry_walled_floor: bool,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            side_bearing: 0.7,
            turn_bearing: 1.3,
            bumper_half_arc: 1.4,
            gap: 0.01,
            arc_half_length: 0.02,
            same_contact: 0.03,
            settle: 1.0,
            retry_walled_floor: true,
        }
    }
}

impl ContactParams {
    /// Farthest from the centre of a robot of `radius` that an earlier
    /// mark may lie to count as the obstacle a one-bit bumper met again
    /// (m): a body's width beyond the shell's reach (see
    /// [`ContactMark::estimate`]).
    pub fn prior_reach(&self, radius: f64) -> f64 {
        2.0 * (radius + self.gap)
    }

    /// Farthest from the centre of a robot of `radius` that something
    /// touching its shell can be (m): the contact's gap outside the body
    /// and the same-contact tolerance.
    pub fn reach(&self, radius: f64) -> f64 {
        radius + self.gap + self.same_contact
    }

    /// Checks every value's range; the error names the dotted key.
    pub fn validate(&self) -> Result<(), ParamError> {
        let within = |key: &str, v: f64, lo: f64, hi: f64, open_lo: bool| {
            let ok = v.is_finite() && v <= hi && if open_lo { v > lo } else { v >= lo };
            if ok {
                Ok(())
            } else {
                let lo_s = if open_lo { ">" } else { ">=" };
                Err(invalid(
                    &format!("daemon.contact.{key}"),
                    &format!("must be a finite number {lo_s} {lo} and <= {hi}, got {v:?}"),
                ))
            }
        };
        let half_pi = std::f64::consts::FRAC_PI_2;
        within("bumper_half_arc", self.bumper_half_arc, 0.0, half_pi, true)?;
        within(
            "side_bearing",
            self.side_bearing,
            0.0,
            self.bumper_half_arc,
            false,
        )?;
        within(
            "turn_bearing",
            self.turn_bearing,
            0.0,
            self.bumper_half_arc,
            true,
        )?;
        within("gap", self.gap, 0.0, 0.2, false)?;
        within("arc_half_length", self.arc_half_length, 0.0, 0.5, true)?;
        within("same_contact", self.same_contact, 0.0, 1.0, false)?;
        within("settle", self.settle, 0.0, 10.0, false)?;
        Ok(())
    }
}

/// How far beyond the closed arc a marked contact still explains a closure
/// (rad): the mark's bearing is an estimate, and backing off a contact at
/// the arc's end turns it a few degrees further out.
const EXPLAIN_SLACK: f64 = 0.2;
/// Step of the bearings tried along the bumper's arc (rad).
const BEARING_STEP: f64 = 0.05;
/// Longest half arc a mark is drawn with (m), whatever it holds.
pub(crate) const MAX_ARC_HALF_LENGTH: f64 = 0.5;
/// Most points along one marked arc.
const MAX_ARC_STEPS: usize = 1000;
/// Cell size of the [`BodyTrack`] (m).
pub(crate) const TRACK_RESOLUTION: f64 = 0.02;

/// Where the robot's body has been: cells wholly under the body at some
/// executed pose. Allocated once for the map's extent.
#[derive(Clone, Debug)]
pub struct BodyTrack {
    origin: Point2<f64>,
    w: usize,
    h: usize,
    cells: Vec<bool>,
}

impl BodyTrack {
    /// A track over the rectangle at `origin` of `width` × `height` metres.
    pub fn new(origin: Point2<f64>, width: f64, height: f64) -> Self {
        let n = |v: f64| {
            if v.is_finite() && v > 0.0 {
                (v / TRACK_RESOLUTION).ceil() as usize
            } else {
                0
            }
        };
        let (w, h) = (n(width), n(height));
        Self {
            origin,
            w,
            h,
            cells: vec![false; w * h],
        }
    }

    fn index(&self, p: &Point2<f64>) -> Option<usize> {
        let x = ((p.x - self.origin.x) / TRACK_RESOLUTION).floor();
        let y = ((p.y - self.origin.y) / TRACK_RESOLUTION).floor();
        (x >= 0.0 && y >= 0.0 && (x as usize) < self.w && (y as usize) < self.h)
            .then(|| y as usize * self.w + x as usize)
    }

    /// Records the body, a disc of `radius` at `centre`: every cell lying
    /// wholly inside it.
    pub fn stamp(&mut self, centre: &Point2<f64>, radius: f64) {
        let inner = radius - TRACK_RESOLUTION * std::f64::consts::FRAC_1_SQRT_2;
        if !(inner > 0.0 && centre.x.is_finite() && centre.y.is_finite()) {
            return;
        }
        let n = (inner / TRACK_RESOLUTION).ceil() as i64;
        let cx = ((centre.x - self.origin.x) / TRACK_RESOLUTION).floor() as i64;
        let cy = ((centre.y - self.origin.y) / TRACK_RESOLUTION).floor() as i64;
        for y in (cy - n).max(0)..=(cy + n).min(self.h as i64 - 1) {
            for x in (cx - n).max(0)..=(cx + n).min(self.w as i64 - 1) {
                let c = Point2::new(
                    self.origin.x + (x as f64 + 0.5) * TRACK_RESOLUTION,
                    self.origin.y + (y as f64 + 0.5) * TRACK_RESOLUTION,
                );
                if (c - centre).norm() <= inner {
                    self.cells[y as usize * self.w + x as usize] = true;
                }
            }
        }
    }

    /// Whether the body has been over `p`.
    pub fn covered(&self, p: &Point2<f64>) -> bool {
        self.index(p).is_some_and(|i| self.cells[i])
    }
}

/// What is known of a contact besides the closure itself (see
/// [`ContactMark::estimate`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Known<'a> {
    /// Where the body has been: bearings whose contact point it passed over
    /// are ruled out.
    pub track: Option<&'a BodyTrack>,
    /// The nearest earlier mark within [`ContactParams::prior_reach`] of
    /// the robot centre.
    pub near: Option<Point2<f64>>,
}

/// One bumper contact: the robot centre at the time and the contact point
/// on the shell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactMark {
    /// Robot centre when the bumper closed (map frame, m).
    pub centre: Point2<f64>,
    /// The contact point (map frame, m).
    pub at: Point2<f64>,
    /// Half length of the marked arc around `at` (m).
    pub half_length: f64,
}

impl ContactMark {
    /// The contact of a bumper closing on `sides` (`None`: a one-bit bumper
    /// that cannot tell them) with the robot of radius `radius` at `pose`,
    /// commanded to `wheels` (wheel base `wheel_base`), with the bearings the
    /// body's track rules out removed (`known.track`). `known.near` is the
    /// nearest earlier mark within [`ContactParams::prior_reach`] of the
    /// centre, if any: a bumper that cannot tell where on its front arc it
    /// closed has most likely met the obstacle it met there before, so the
    /// contact is taken at the shell's point facing that mark (when the arc
    /// and the track allow). Without it the middle of the open arc is up to 0.23 m off:
    /// such guesses stood 0.10-0.17 m from an unseen stool, in open floor,
    /// and shut the passage beside it.
    ///
    /// A disk turning in place sweeps no new space: a turn closes the bumper
    /// only where the end of its arc meets something beside the body, so
    /// the leading end is the contact when the side that closed is the one
    /// leading the turn. Both sides of a bumper that tells them apart
    /// closed together are a contact near the middle, whatever the motion.
    /// A one-bit bumper is marked across its front in a turn too: an
    /// obstacle resting at the bumper's reach closes it anywhere on the arc
    /// when wheel slip moves the body by a millimetre (in the stool room's
    /// runs three closures in a turn were on the trailing side, and their
    /// marks at the leading end lay 0.32-0.36 m from the stool; the
    /// straight-ahead guess is at most 0.23 m off).
    pub fn estimate(
        params: &ContactParams,
        pose: &Pose,
        sides: Option<Sides>,
        wheels: WheelSpeeds,
        radius: f64,
        wheel_base: f64,
        known: Known<'_>,
    ) -> Self {
        let Known { track, near } = known;
        let (turning, w) = turn_in_place(params, wheels, radius, wheel_base);
        let lead = |b: f64| (b, (b, b));
        let (bearing, arc) = match sides.map(|s| (s.left, s.right)) {
            Some((true, false)) if turning && w > 0.0 => lead(params.turn_bearing),
            Some((false, true)) if turning && w < 0.0 => lead(-params.turn_bearing),
            Some((true, false)) => (params.side_bearing, (0.0, params.bumper_half_arc)),
            Some((false, true)) => (-params.side_bearing, (-params.bumper_half_arc, 0.0)),
            _ => (0.0, (-params.bumper_half_arc, params.bumper_half_arc)),
        };
        let centre: Point2<f64> = pose.translation.vector.into();
        let th = heading(pose);
        let r = radius + params.gap;
        let point = |b: f64| polar(centre, th + b, r);
        let ruled_out = |b: f64| track.is_some_and(|t| t.covered(&point(b)));
        let facing = near
            .filter(|_| sides.is_none())
            .map(|q| crate::geom::wrap_angle((q.y - centre.y).atan2(q.x - centre.x) - th))
            .filter(|b| (arc.0..=arc.1).contains(b))
            .and_then(|b| nearest_open(arc, b, ruled_out));
        let bearing = facing.unwrap_or_else(|| {
            track
                .and_then(|_| open_bearing(arc, bearing, ruled_out))
                .unwrap_or(bearing)
        });
        Self {
            centre,
            at: point(bearing),
            half_length: params.arc_half_length,
        }
    }

    /// Whether this marked contact explains a bumper closing on `sides`
    /// (`None`: either) with the robot of `radius` at `pose`: its point
    /// touches the shell (within `params.same_contact` of the bumper's
    /// reach) on the part of the bumper's arc that closed. A bumper that
    /// closes again at an obstacle it has just marked (after backing off a
    /// few millimetres and turning, say) has learnt nothing new; a fresh
    /// mark would be a guess at another bearing, and a wrong guess walls
    /// off floor.
    pub fn explains(
        &self,
        params: &ContactParams,
        pose: &Pose,
        sides: Option<Sides>,
        radius: f64,
    ) -> bool {
        let centre: Point2<f64> = pose.translation.vector.into();
        let d = self.at - centre;
        let reach = params.reach(radius);
        if d.norm() > reach || !d.norm().is_finite() {
            return false;
        }
        let b = crate::geom::wrap_angle(d.y.atan2(d.x) - heading(pose));
        let (lo, hi) = closed_arc(params, sides);
        (lo - EXPLAIN_SLACK..=hi + EXPLAIN_SLACK).contains(&b)
    }

    /// Whether `other` is the same contact as this one: its contact point
    /// lies within `tolerance` (m).
    pub fn same_as(&self, other: &ContactMark, tolerance: f64) -> bool {
        (self.at - other.at).norm() <= tolerance
    }

    /// The cells of `grid` the marked arc lies in (a cell may repeat). The
    /// iterator holds the grid's geometry, not the grid: the caller may set
    /// the cells' states as it goes.
    pub fn cells<'a>(&'a self, grid: &Grid) -> impl Iterator<Item = CellIndex> + 'a {
        let (origin, res) = (grid.origin(), grid.resolution());
        let size = (grid.width(), grid.height());
        self.arc(res / 2.0)
            .filter_map(move |p| crate::grid::cell_containing(origin, res, size, &p))
    }

    /// Points along the marked arc, at most `step` apart (ends included).
    pub fn arc(&self, step: f64) -> impl Iterator<Item = Point2<f64>> + '_ {
        let d = self.at - self.centre;
        let r = d.norm().max(1e-6);
        let a0 = d.y.atan2(d.x);
        let len = if self.half_length.is_finite() {
            self.half_length.clamp(0.0, MAX_ARC_HALF_LENGTH)
        } else {
            0.0
        };
        let half = len / r;
        let n = ((2.0 * len / step.max(1e-3)).ceil() as usize).clamp(1, MAX_ARC_STEPS);
        (0..=n).map(move |k| {
            let a = a0 - half + 2.0 * half * k as f64 / n as f64;
            polar(self.centre, a, r)
        })
    }
}

/// Slowest wheel travel taken as motion (m/s, both wheels together).
const MOVING: f64 = 0.005;
/// Longest a measured motion stands for the motion a contact interrupted
/// (clock s): a few encoder polls.
const MOTION_MEMORY: f64 = 0.2;

/// The wheels' last measured motion (encoder travel over a poll). A
/// contact interrupts what the wheels did, not what was last commanded:
/// at a lane's end the command is already the turn while the base still
/// rolls forward into the wall, and a turn's contact is marked at the
/// shell's side, a forward one ahead.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionMemory {
    speeds: WheelSpeeds,
    at: f64,
}

impl Default for MotionMemory {
    fn default() -> Self {
        Self {
            speeds: WheelSpeeds::STOP,
            at: f64::NEG_INFINITY,
        }
    }
}

impl MotionMemory {
    /// Takes the wheel speeds of one odometry reading, if the wheels moved.
    pub fn note(&mut self, o: &crate::base::Odometry) {
        let dt = o.t1 - o.t0;
        if dt > 0.0 && (o.left.abs() + o.right.abs()) > MOVING * dt {
            self.speeds = WheelSpeeds {
                left: o.left / dt,
                right: o.right / dt,
            };
            self.at = o.t1;
        }
    }

    /// The motion a contact closing at clock time `now` interrupted: the
    /// measured one when recent, else the `commanded` one.
    pub fn interrupted(&self, now: f64, commanded: WheelSpeeds) -> WheelSpeeds {
        if now - self.at <= MOTION_MEMORY {
            self.speeds
        } else {
            commanded
        }
    }
}

/// A contact waiting for the pose to be known. Until the first matched scan
/// of a (re)started daemon, its pose is the start or checkpointed guess (a
/// resumed robot was measured 0.11 m from its checkpointed pose): a contact
/// marked then lands where nothing is, and rays never clear a mark. So a
/// contact closed before that is held, with the odometry driven since (the
/// control stage backs off), and marked where the robot was once the pose
/// is known.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HeldContact {
    held: Option<(Option<Sides>, WheelSpeeds, Pose)>,
}

impl HeldContact {
    /// A contact closed on `sides` with `wheels` commanded: returned at once
    /// when the pose is `localised`, else held (a newer one replaces it).
    pub fn closed(
        &mut self,
        localised: bool,
        sides: Option<Sides>,
        wheels: WheelSpeeds,
    ) -> Option<(Option<Sides>, WheelSpeeds)> {
        if localised {
            return Some((sides, wheels));
        }
        self.held = Some((sides, wheels, Pose::identity()));
        None
    }

    /// Odometry `delta` (in the earlier base frame) driven since.
    pub fn moved(&mut self, delta: &Pose) {
        if let Some((_, _, since)) = &mut self.held {
            *since *= delta;
        }
    }

    /// The held contact once the pose is `localised`: its sides, wheels and
    /// the robot's pose when it closed, from the pose `now`.
    pub fn release(
        &mut self,
        localised: bool,
        now: &Pose,
    ) -> Option<(Option<Sides>, WheelSpeeds, Pose)> {
        if !localised {
            return None;
        }
        self.held
            .take()
            .map(|(sides, wheels, since)| (sides, wheels, now * since.inverse()))
    }
}

/// Whether a bumper that closed under `wheels` (a robot of `radius`, wheel
/// base `wheel_base`) closed by the turn, at the leading end of its arc,
/// rather than by the advance, across its front; and the turn rate (rad/s).
///
/// A disc's shell moves outward only by translation: advancing at `v`, the
/// arc sweeps new ring (the band between the body and the bumper's reach,
/// `radius + 2 gap`) at `v · 2 reach · sin(half arc)` per second; turning at
/// `w`, only the arc's leading end sweeps new ring, at `|w| (reach² −
/// radius²) / 2`. The closure is put on the larger: at 0.5 rad/s a creep of
/// 2.5 mm/s forward already sweeps more.
pub fn turn_in_place(
    params: &ContactParams,
    wheels: WheelSpeeds,
    radius: f64,
    wheel_base: f64,
) -> (bool, f64) {
    let v = 0.5 * (wheels.left + wheels.right);
    let w = if wheel_base > 0.0 {
        (wheels.right - wheels.left) / wheel_base
    } else {
        0.0
    };
    let reach = radius + 2.0 * params.gap;
    let by_turn = w.abs() * (reach * reach - radius * radius) / 2.0;
    let by_advance = v.max(0.0) * 2.0 * reach * params.bumper_half_arc.sin();
    let turning = w.is_finite() && v.is_finite() && by_turn > by_advance;
    (turning, w)
}

/// The bearings (rad from straight ahead, low to high) of the bumper's arc
/// that can have closed on `sides` (`None`: either).
fn closed_arc(params: &ContactParams, sides: Option<Sides>) -> (f64, f64) {
    match sides.map(|s| (s.left, s.right)) {
        Some((true, false)) => (0.0, params.bumper_half_arc),
        Some((false, true)) => (-params.bumper_half_arc, 0.0),
        _ => (-params.bumper_half_arc, params.bumper_half_arc),
    }
}

/// A mapped obstacle (an occupied cell of `grid`, the scanner's or an
/// earlier contact's) touching the part of the shell of a robot of `radius`
/// at `pose` that closed on `sides`: the centre of the nearest such cell.
/// A disc turning in place comes no nearer to anything, so a bumper that
/// closes while turning beside a mapped wall has found that wall; a guess
/// at the turn's leading end would put a mark in open floor.
pub fn mapped_touch(
    grid: &Grid,
    params: &ContactParams,
    pose: &Pose,
    sides: Option<Sides>,
    radius: f64,
) -> Option<Point2<f64>> {
    let (lo, hi) = closed_arc(params, sides);
    let centre: Point2<f64> = pose.translation.vector.into();
    let th = heading(pose);
    let step = grid.resolution() / 2.0;
    let reach = params.reach(radius);
    let n = ((hi - lo) / BEARING_STEP).round().max(0.0) as usize;
    let mut r = radius;
    while r <= reach {
        for k in 0..=n {
            let a = th + lo + k as f64 * BEARING_STEP;
            let p = polar(centre, a, r);
            if let Some(c) = grid.cell_of(&p) {
                if grid.state(c) == CellState::Occupied {
                    return Some(grid.centre_of(c));
                }
            }
        }
        r += step;
    }
    None
}

/// The bearing in `arc` nearest `wanted` that is not `ruled_out` (in steps
/// of [`BEARING_STEP`]); `None` when every step is.
fn nearest_open(arc: (f64, f64), wanted: f64, ruled_out: impl Fn(f64) -> bool) -> Option<f64> {
    let n = ((arc.1 - arc.0) / BEARING_STEP).ceil().max(0.0) as usize;
    (0..=n).find_map(|k| {
        let d = k as f64 * BEARING_STEP;
        [wanted - d, wanted + d]
            .into_iter()
            .find(|b| (arc.0..=arc.1).contains(b) && !ruled_out(*b))
    })
}

/// The middle of the run of bearings in `arc` not `ruled_out` that holds
/// `preferred` (or else the longest run); `None` when the whole arc is
/// open (nothing learnt) or ruled out (nothing to go by).
fn open_bearing(arc: (f64, f64), preferred: f64, ruled_out: impl Fn(f64) -> bool) -> Option<f64> {
    let n = ((arc.1 - arc.0) / BEARING_STEP).round().max(0.0) as usize;
    let at = |k: usize| arc.0 + k as f64 * BEARING_STEP;
    let mut runs: heapless::Vec<(usize, usize), 32> = heapless::Vec::new();
    let mut start = None;
    for k in 0..=n {
        match (ruled_out(at(k)), start) {
            (false, None) => start = Some(k),
            (true, Some(s)) => {
                let _ = runs.push((s, k - 1));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        let _ = runs.push((s, n));
    }
    match runs.as_slice() {
        [] => None,
        [(0, e)] if *e == n => None,
        rs => {
            let holds = |&&(s, e): &&(usize, usize)| {
                at(s) - BEARING_STEP / 2.0 <= preferred && preferred <= at(e) + BEARING_STEP / 2.0
            };
            let run = rs
                .iter()
                .find(holds)
                .or_else(|| rs.iter().max_by_key(|(s, e)| e - s))?;
            Some(0.5 * (at(run.0) + at(run.1)))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    const R: f64 = 0.17;
    const B: f64 = 0.235;

    fn est(
        pose: &Pose,
        sides: impl Into<Option<Sides>>,
        wheels: WheelSpeeds,
        track: Option<&BodyTrack>,
    ) -> ContactMark {
        ContactMark::estimate(
            &ContactParams::default(),
            pose,
            sides.into(),
            wheels,
            R,
            B,
            Known { track, near: None },
        )
    }

    fn both() -> Sides {
        Sides {
            left: true,
            right: true,
        }
    }

    #[test]
    fn a_one_bit_bumper_meeting_a_marked_obstacle_again_marks_the_point_facing_it() {
        // A CI run's closure: the robot at (1.27, 2.19) m heading 167°, its
        // bumper on the stool's corner (1.10, 2.10) 38° to its left, the
        // stool marked before at (1.11, 1.98) on its right side.
        let p = pose(1.27, 2.19, 167f64.to_radians());
        let fwd = WheelSpeeds::from_body(0.2, 0.0, B);
        let earlier = Point2::new(1.11, 1.98);
        let corner = Point2::new(1.10, 2.10);
        let params = ContactParams::default();
        let mark = |sides: Option<Sides>, near: Option<Point2<f64>>| {
            ContactMark::estimate(&params, &p, sides, fwd, R, B, Known { track: None, near })
        };
        let facing = mark(None, Some(earlier));
        let ahead = mark(None, None);
        assert!((facing.at - corner).norm() < 0.09, "{:?}", facing.at);
        assert!(
            (ahead.at - corner).norm() > (facing.at - corner).norm() + 0.04,
            "{:?}",
            ahead.at
        );
        // Switches that tell the sides keep their bearing (both closed: the
        // middle), whatever was marked before.
        let left = Some(Sides {
            left: true,
            right: false,
        });
        assert_eq!(mark(left, Some(earlier)), mark(left, None));
        assert_eq!(mark(Some(both()), Some(earlier)), mark(Some(both()), None));
        // Where the body has been nothing stands: the facing bearing gives
        // way to the nearest open one.
        let mut track = BodyTrack::new(Point2::new(0.0, 0.0), 3.0, 3.0);
        track.stamp(&Point2::new(1.22, 1.95), R);
        let known = Known {
            track: Some(&track),
            near: Some(earlier),
        };
        let open = ContactMark::estimate(&params, &p, None, fwd, R, B, known);
        assert!(!track.covered(&open.at), "{:?}", open.at);
        assert!((open.at - corner).norm() < 0.09, "{:?}", open.at);
        assert!((open.at - facing.at).norm() > 0.01, "{:?}", open.at);
        // A mark behind the bumper's arc says nothing of this contact.
        let behind = Point2::new(1.45, 2.15);
        assert_eq!(mark(None, Some(behind)), ahead);
    }

    #[test]
    fn a_head_on_contact_is_straight_ahead_just_outside_the_body() {
        let m = est(
            &pose(1.0, 2.0, std::f64::consts::FRAC_PI_2),
            both(),
            WheelSpeeds::from_body(0.2, 0.0, B),
            None,
        );
        assert!((m.at.x - 1.0).abs() < 1e-9, "{:?}", m.at);
        assert!(
            (m.at.y - (2.0 + R + ContactParams::default().gap)).abs() < 1e-9,
            "{:?}",
            m.at
        );
    }

    #[test]
    fn one_side_or_a_turn_moves_the_contact_to_that_side() {
        let p = pose(0.0, 0.0, 0.0);
        let fwd = WheelSpeeds::from_body(0.2, 0.0, B);
        let left = est(
            &p,
            Sides {
                left: true,
                right: false,
            },
            fwd,
            None,
        );
        assert!(left.at.y > 0.05 && left.at.x > 0.05, "{:?}", left.at);
        let right = est(
            &p,
            Sides {
                left: false,
                right: true,
            },
            fwd,
            None,
        );
        assert!(right.at.y < -0.05, "{:?}", right.at);
        // A RoboClaw E-stop (one bit) while turning right in place: across
        // the front, where the guess is off by at most half the arc.
        let spin_right = WheelSpeeds::from_body(0.0, -1.0, B);
        let turn = est(&p, None, spin_right, None);
        assert!(turn.at.x > 0.17 && turn.at.y.abs() < 1e-9, "{:?}", turn.at);
        // The right switch of a Create 2 while turning right: the arc's
        // leading end; the left switch cannot close by that turn.
        let right_end = est(
            &p,
            Sides {
                left: false,
                right: true,
            },
            spin_right,
            None,
        );
        assert!(right_end.at.y < -0.15, "{:?}", right_end.at);
        let trailing = est(
            &p,
            Sides {
                left: true,
                right: false,
            },
            spin_right,
            None,
        );
        assert!((trailing.at - left.at).norm() < 1e-9, "{:?}", trailing.at);
    }

    #[test]
    fn a_one_bit_bumper_closing_in_a_turn_is_marked_across_its_front() {
        // Logged in the stool room (`tests/sim_faults.rs`, debug build,
        // ×8): the robot at its lane's start (0.79, 1.75), the stool's
        // corner (0.9, 1.9) at its bumper's reach 50-67° to the right, the
        // RoboClaw's one-bit bumper closing while the robot turned left
        // (once easing in at 2 cm/s). Marked at the turn's leading end, the
        // contacts were 0.32-0.36 m from the corner in open floor.
        let corner = Point2::new(0.9, 1.9);
        for (deg, left, right) in [
            (103.0, -0.04, 0.08),
            (111.0, -0.09, 0.09),
            (121.0, -0.09, 0.09),
        ] {
            let at = pose(0.79, 1.75, f64::to_radians(deg));
            let m = est(&at, None, WheelSpeeds { left, right }, None);
            assert!((m.at - corner).norm() < 0.21, "{deg}°: {:?}", m.at);
        }
        // A side switch that closes on the side leading the turn is at
        // that end (a Create 2 turning left, its left switch).
        let spin = WheelSpeeds::from_body(0.001, 0.8, B);
        let left = Sides {
            left: true,
            right: false,
        };
        let lead = est(&pose(0.0, 0.0, 0.0), left, spin, None);
        assert!(lead.at.y > 0.15, "{:?}", lead.at);
    }

    #[test]
    fn both_switches_of_a_two_sided_bumper_are_a_contact_ahead_even_in_a_turn() {
        // A Create 2 facing a stool 2 cm ahead turns right in place: both
        // switches close on the stool straight ahead (the failure of a
        // closed-loop run: marking the turn's leading end instead put the
        // contact 0.19 m off, across a passage beside the stool).
        let p = pose(1.29, 2.04, std::f64::consts::PI);
        let m = est(&p, both(), WheelSpeeds::from_body(0.0, -0.8, B), None);
        let ahead = Point2::new(1.29 - R - ContactParams::default().gap, 2.04);
        assert!((m.at - ahead).norm() < 1e-9, "{:?}", m.at);
    }

    #[test]
    fn the_body_track_rules_out_the_side_the_robot_has_swept() {
        // The previous lane ran 0.28 m to the right (south) of this one,
        // and the robot came along this lane from the west.
        let mut t = BodyTrack::new(Point2::new(-3.0, -2.0), 6.0, 4.0);
        for k in 0..=300 {
            let x = -2.0 + k as f64 * 0.01;
            t.stamp(&Point2::new(x, -0.28), R);
            if x <= 0.0 {
                t.stamp(&Point2::new(x, 0.0), R);
            }
        }
        assert!(t.covered(&Point2::new(0.5, -0.28 + R - 0.02)));
        assert!(!t.covered(&Point2::new(0.5, -0.28 + R + 0.01)));
        let m = est(
            &pose(0.0, 0.0, 0.0),
            both(),
            WheelSpeeds::from_body(0.2, 0.0, B),
            Some(&t),
        );
        // Not straight ahead: on the left, where the body has not been.
        assert!(m.at.y > 0.03, "{:?}", m.at);
        assert!(((m.at - m.centre).norm() - (R + ContactParams::default().gap)).abs() < 1e-9);
        // Nothing swept around: the same as without a track.
        let empty = BodyTrack::new(Point2::new(-3.0, -2.0), 6.0, 4.0);
        let a = est(
            &pose(0.0, 0.0, 0.0),
            both(),
            WheelSpeeds::from_body(0.2, 0.0, B),
            Some(&empty),
        );
        assert!(a.at.y.abs() < 1e-9, "{:?}", a.at);
        // Outside the track's extent nothing is known.
        assert!(!empty.covered(&Point2::new(50.0, 0.0)));
    }

    #[test]
    fn a_contact_before_the_pose_is_known_is_marked_where_it_closed() {
        let mut h = HeldContact::default();
        let fwd = WheelSpeeds::from_body(0.2, 0.0, B);
        // Localised: at once, nothing held.
        assert_eq!(h.closed(true, Some(both()), fwd), Some((Some(both()), fwd)));
        assert_eq!(h.release(true, &pose(0.0, 0.0, 0.0)), None);
        // Not yet: held while the robot backs off 0.1 m and turns 0.2 rad.
        assert_eq!(h.closed(false, None, fwd), None);
        h.moved(&pose(-0.06, 0.0, 0.1));
        h.moved(&pose(-0.04, 0.0, 0.1));
        assert_eq!(h.release(false, &pose(0.0, 0.0, 0.0)), None);
        // Localised at (1.9, 1.0) facing 0.2 rad: the contact closed about
        // 0.1 m ahead of it, facing 0.
        let now = pose(1.9, 1.0, 0.2);
        let (sides, wheels, at) = h.release(true, &now).unwrap();
        assert_eq!((sides, wheels), (None, fwd));
        assert!(heading(&at).abs() < 1e-9, "{at:?}");
        let back = (at.translation.vector - now.translation.vector).norm();
        assert!((back - 0.1).abs() < 0.01, "{back}");
        assert_eq!(h.release(true, &now), None, "released once");
    }

    #[test]
    fn the_open_run_holding_the_preferred_bearing_is_chosen() {
        // Open between -0.5 and 0.5 and beyond 1.0: the run holding 0.
        let b = open_bearing((-1.4, 1.4), 0.0, |b| !(-0.5..=0.5).contains(&b) && b < 1.0);
        assert!(b.unwrap().abs() < 0.03, "{b:?}");
        // Preferred bearing ruled out: the longest open run.
        let b = open_bearing((-1.4, 1.4), 0.0, |b| b > -1.0);
        assert!((b.unwrap() + 1.2).abs() < 0.03, "{b:?}");
        assert_eq!(open_bearing((-1.4, 1.4), 0.0, |_| false), None);
        assert_eq!(open_bearing((-1.4, 1.4), 0.0, |_| true), None);
    }

    #[test]
    fn the_arc_is_a_few_centimetres_of_the_shell() {
        let m = est(&pose(0.0, 0.0, 0.3), both(), WheelSpeeds::STOP, None);
        let pts: Vec<_> = m.arc(0.01).collect();
        assert!(pts.len() >= 4);
        for q in &pts {
            assert!(((q - m.centre).norm() - (R + ContactParams::default().gap)).abs() < 1e-9);
            assert!((q - m.at).norm() <= ContactParams::default().arc_half_length + 1e-9);
        }
        let ends = (pts[0] - pts[pts.len() - 1]).norm();
        assert!(
            ends > 1.5 * ContactParams::default().arc_half_length,
            "{ends}"
        );
        assert!(m.same_as(&m, 0.0));
    }

    #[test]
    fn the_marks_follow_their_keys() {
        let p = ContactParams {
            side_bearing: 0.3,
            gap: 0.05,
            arc_half_length: 0.06,
            ..ContactParams::default()
        };
        let left = Sides {
            left: true,
            right: false,
        };
        let m = ContactMark::estimate(
            &p,
            &pose(0.0, 0.0, 0.0),
            Some(left),
            WheelSpeeds::from_body(0.2, 0.0, B),
            R,
            B,
            Known::default(),
        );
        let d = m.at - m.centre;
        assert!((d.norm() - (R + 0.05)).abs() < 1e-9, "{d:?}");
        assert!((d.y.atan2(d.x) - 0.3).abs() < 1e-9, "{d:?}");
        let pts: Vec<_> = m.arc(0.01).collect();
        let ends = (pts[0] - pts[pts.len() - 1]).norm();
        assert!(ends > 0.11 && ends <= 0.12 + 1e-9, "{ends}");
        // An absurd arc held by a corrupt mark is drawn bounded.
        let huge = ContactMark {
            half_length: 1e12,
            ..m
        };
        assert!(huge.arc(1e-9).count() <= MAX_ARC_STEPS + 1);
    }

    #[test]
    fn bad_values_name_their_key() {
        assert!(ContactParams::default().validate().is_ok());
        let cases = [
            (
                ContactParams {
                    side_bearing: 2.0,
                    ..ContactParams::default()
                },
                "side_bearing",
            ),
            (
                ContactParams {
                    turn_bearing: 0.0,
                    ..ContactParams::default()
                },
                "turn_bearing",
            ),
            (
                ContactParams {
                    bumper_half_arc: f64::NAN,
                    ..ContactParams::default()
                },
                "bumper_half_arc",
            ),
            (
                ContactParams {
                    gap: -0.01,
                    ..ContactParams::default()
                },
                "gap",
            ),
            (
                ContactParams {
                    arc_half_length: 0.0,
                    ..ContactParams::default()
                },
                "arc_half_length",
            ),
            (
                ContactParams {
                    same_contact: f64::INFINITY,
                    ..ContactParams::default()
                },
                "same_contact",
            ),
            (
                ContactParams {
                    settle: -1.0,
                    ..ContactParams::default()
                },
                "settle",
            ),
        ];
        for (p, key) in cases {
            let e = p.validate().unwrap_err().to_string();
            assert!(e.contains(&format!("daemon.contact.{key}")), "{e}");
        }
    }

    #[test]
    fn a_closure_at_a_marked_contact_is_explained_by_it_on_the_closed_side() {
        let params = ContactParams::default();
        // Driving west along the top of a stool, touching its corner with
        // the shell's left (south) side; then backed off 14 mm and turning.
        let first = est(
            &pose(1.163, 2.266, std::f64::consts::PI),
            Sides {
                left: true,
                right: false,
            },
            WheelSpeeds::from_body(0.23, 0.0, B),
            None,
        );
        let now = pose(1.177, 2.266, 176f64.to_radians());
        assert!(first.explains(&params, &now, None, R));
        let left = Sides {
            left: true,
            right: false,
        };
        let right = Sides {
            left: false,
            right: true,
        };
        assert!(first.explains(&params, &now, Some(left), R));
        assert!(!first.explains(&params, &now, Some(right), R));
        // Facing away from it, or a body length off, it explains nothing.
        assert!(!first.explains(&params, &pose(1.177, 2.266, 0.0), None, R));
        assert!(!first.explains(&params, &pose(1.5, 2.266, 176f64.to_radians()), None, R));
    }

    #[test]
    fn a_mapped_wall_touching_the_closed_arc_is_found() {
        let params = ContactParams::default();
        let mut grid = Grid::new(Point2::new(0.0, 0.0), 0.05, 80, 60);
        // A box corner 0.187 m from the centre, 26° to the right of the
        // heading (the turn-in-place closure at the box of a bench run).
        let at = pose(2.383, 1.666, -89f64.to_radians());
        let corner = Point2::new(2.29, 1.50);
        grid.set_state(grid.cell_of(&corner).unwrap(), CellState::Occupied);
        let hit = mapped_touch(&grid, &params, &at, None, R).expect("the corner touches");
        assert!((hit - corner).norm() < 0.05, "{hit:?}");
        let left = Sides {
            left: true,
            right: false,
        };
        assert_eq!(mapped_touch(&grid, &params, &at, Some(left), R), None);
        // Half a metre away nothing is touched.
        assert_eq!(
            mapped_touch(&grid, &params, &pose(2.9, 1.666, -1.55), None, R),
            None
        );
    }

    #[test]
    fn the_interrupted_motion_is_the_measured_one_while_recent() {
        let mut m = MotionMemory::default();
        let turn = WheelSpeeds::from_body(0.0, 0.8, B);
        // Nothing measured yet: the command.
        assert_eq!(m.interrupted(1.0, turn), turn);
        // Rolling forward at 0.2 m/s while the turn is already commanded.
        m.note(&crate::base::Odometry {
            t0: 1.00,
            t1: 1.02,
            delta: pose(0.004, 0.0, 0.0),
            left: 0.004,
            right: 0.004,
        });
        let fwd = m.interrupted(1.05, turn);
        assert!((fwd.left - 0.2).abs() < 1e-9 && (fwd.right - 0.2).abs() < 1e-9);
        let params = ContactParams::default();
        assert!(!turn_in_place(&params, fwd, R, B).0 && turn_in_place(&params, turn, R, B).0);
        // Standing still is not a motion; an old reading gives way.
        m.note(&crate::base::Odometry {
            t0: 1.02,
            t1: 1.04,
            delta: pose(0.0, 0.0, 0.0),
            left: 0.0,
            right: 0.0,
        });
        assert_eq!(m.interrupted(1.1, turn), fwd);
        assert_eq!(m.interrupted(2.0, turn), turn);
    }
}
