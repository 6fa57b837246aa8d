//! Scan-to-map tracking over a sequence of scans: predict from odometry or a
//! constant-velocity prior, match against the keyframe local map, accept or
//! fall back to the prediction, add keyframes as the robot moves.
//!
//! With `scan_fusion` > 0 each scan is also matched against the previous scan
//! and the reported pose is a complementary filter of the two: it moves with
//! the scan-to-scan increments (locally the most consistent) and is pulled
//! towards the scan-to-map pose (which does not drift). The keyframe map, the
//! prior and the velocity keep following the scan-to-map pose, so the
//! reported pose stays within a bounded offset of it.

use super::{
    CorrelativeSearch, IcpError, IcpParams, KeyframeMap, KeyframeState, Matcher, Prior, Quality,
    Reference, Rejection,
};

/// `p` with its rotation re-normalised: nalgebra does not renormalise unit
/// complex numbers after products, and the rounding drift of thousands of
/// chained poses would otherwise grow without bound under repeated prediction.
fn unit(p: Pose) -> Pose {
    crate::geom::pose(p.translation.x, p.translation.y, p.rotation.angle())
}

/// Of two failed attempts, the one to report: a rejected match (it ran) over a
/// failure, else the first.
fn better_failure(a: Outcome, b: Outcome) -> Outcome {
    match (&a, &b) {
        (Outcome::Failed(_), Outcome::Rejected(..)) => b,
        _ => a,
    }
}
use crate::geom::{IPoint, Pose};
use crate::param_check::ParamError;
use nalgebra::Vector2;

/// What happened to one scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outcome {
    /// The first scan: it became the map; the pose is the start pose.
    First,
    /// The match was accepted.
    Matched(Quality),
    /// The match failed; the pose is the prior's prediction.
    Failed(IcpError),
    /// The match ran but was judged unreliable; the pose is the prediction.
    Rejected(Rejection, Quality),
}

/// The result of one tracking step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// Estimated pose of the scanner in the world frame after this scan.
    pub pose: Pose,
    /// How it was obtained.
    pub outcome: Outcome,
    /// True when the scan was added to the local map as a keyframe (after
    /// [`Tracker::step_deferred`]: when it is to be added by
    /// [`Tracker::finish_keyframe`]).
    pub keyframe: bool,
    /// True when the matches from the prior failed and a correlative search
    /// ran ([`Outcome::Matched`]: it found the pose).
    pub searched: bool,
}

/// How often the correlative search ran and what it cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SearchCounts {
    /// Searches run (each after the matches from the prior failed).
    pub calls: u64,
    /// Searches that found a candidate above `icp.search.min_score`.
    pub found: u64,
    /// ... whose ICP match from there was accepted.
    pub recovered: u64,
    /// Candidates scored over all searches.
    pub scored: u64,
}

/// What a tracker needs to carry on where another left off (e.g. after a
/// restart): its local map's keyframes, oldest first.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrackerState {
    /// The keyframes of the local map, oldest first.
    pub keyframes: Vec<KeyframeState>,
}

/// Tracks the scanner pose over a sequence of scans (scan-to-map odometry).
#[derive(Debug)]
pub struct Tracker {
    matcher: Matcher,
    map: KeyframeMap,
    map_pose: Pose,
    velocity: Pose,
    /// The last distinct odometry reading, and our pose estimate at the scan
    /// where it first appeared (odometry in logs may stall, then jump).
    odom_anchor: Option<(Pose, Pose)>,
    /// Scans processed since the anchor's odometry reading first appeared.
    scans_since_anchor: u32,
    /// Smoothed odometry translation per scan, in the robot frame (m).
    odom_step: Option<Vector2<f64>>,
    /// The next scan comes after a gap (see [`Tracker::note_gap`]).
    after_gap: bool,
    /// The next step's odometry is live (see [`Tracker::note_live_odometry`]).
    live_odometry: bool,
    started: bool,
    /// The reported (fused) pose; equals `pose` when `scan_fusion` is 0.
    reported: Pose,
    /// The previous scan at its reported pose (scan-to-scan reference).
    previous: Reference,
    /// A keyframe decided on by [`Tracker::step_deferred`] and not yet
    /// added: the scan-to-map pose it is added at (its points are the
    /// matcher's prepared points until the next step).
    pending_keyframe: Option<Pose>,
    /// The scans since the last accepted match and its scan-to-map pose,
    /// while every scan since came with live odometry (`None`: at the
    /// start, after a gap, a new pose or a logged reading): how far
    /// `live_correction` lets the next match move the pose from the
    /// odometry's prediction, and whether a scan may be bridged.
    since_accept: Option<(u32, Pose)>,
    search: CorrelativeSearch,
    search_counts: SearchCounts,
    /// Keyframes taken at the prediction since the last accepted match
    /// (see [`Tracker::forget_unconfirmed`]).
    unconfirmed: usize,
    /// Work buffer of [`Tracker::relocalise`]: every keyframe's points.
    everything: Vec<IPoint>,
}

impl Tracker {
    /// A tracker starting at `start` with `params` (checked).
    pub fn new(params: IcpParams, start: Pose) -> Result<Self, ParamError> {
        let map = KeyframeMap::new(&params);
        Ok(Self {
            matcher: Matcher::new(params)?,
            map,
            map_pose: start,
            velocity: Pose::identity(),
            odom_anchor: None,
            scans_since_anchor: 0,
            odom_step: None,
            after_gap: false,
            live_odometry: false,
            started: false,
            reported: start,
            previous: Reference::new(),
            search: CorrelativeSearch::new(),
            search_counts: SearchCounts::default(),
            unconfirmed: 0,
            everything: Vec::new(),
            pending_keyframe: None,
            since_accept: None,
        })
    }

    /// The state to continue from later ([`Tracker::restore`]); allocates.
    /// A keyframe still pending (see [`Tracker::step_deferred`]) is not in it.
    pub fn state(&self) -> TrackerState {
        TrackerState {
            keyframes: self.map.export(),
        }
    }

    /// A tracker at `start` whose local map is `state`'s keyframes, so the
    /// first scan is matched against them instead of starting a new map
    /// (whose frame would carry the error of `start`). With no usable
    /// keyframes this is [`Tracker::new`] and the error says why.
    pub fn restore(
        params: IcpParams,
        start: Pose,
        state: &TrackerState,
    ) -> Result<(Self, Option<IcpError>), ParamError> {
        let mut t = Self::new(params, start)?;
        if state.keyframes.is_empty() {
            return Ok((t, None));
        }
        let params = t.matcher.params().clone();
        match t.map.restore(&state.keyframes, &params) {
            Ok(()) => {
                t.started = true;
                Ok((t, None))
            }
            Err(e) => Ok((t, Some(e))),
        }
    }

    /// Moves the estimate to `pose` (e.g. a relocalisation), keeping the
    /// local map; the motion prior starts over.
    pub fn set_pose(&mut self, pose: Pose) {
        self.finish_keyframe();
        self.map_pose = unit(pose);
        self.reported = self.map_pose;
        self.previous.clear();
        self.velocity = Pose::identity();
        self.odom_anchor = None;
        self.scans_since_anchor = 0;
        self.odom_step = None;
        self.since_accept = None;
    }

    /// Says that the next scan follows the previous one after a gap (scans
    /// lost, the scanner's link down): its odometry increment spans more
    /// than one scan period, so it is taken as measured instead of smoothed
    /// per scan, the constant-velocity guess is not tried, and the scan is
    /// not fused with the previous one, nor does its increment become the
    /// constant velocity of the next scan. Without this, the guess after a
    /// 3.6 s outage fell 0.4 m short and the next few overshot; in 3 of 6
    /// simulated runs one such match then locked on up to 1.4 m off.
    pub fn note_gap(&mut self) {
        self.after_gap = true;
        self.since_accept = None;
        self.odom_step = None;
        self.velocity = Pose::identity();
        self.previous.clear();
    }

    /// Says that the next step's odometry was read at its scan's own time
    /// from a base whose readings are still coming: a reading equal to the
    /// previous one then means the robot stood still, and the scan is
    /// matched from the previous pose; a changed one is taken as measured,
    /// not smoothed (`odometry_smoothing` is for the logs' timing jitter; a
    /// smoothed step lags when the robot starts and overshoots when it
    /// stops). Without this, a repeated reading is
    /// taken for a stalled log (which says nothing of the motion) and the
    /// constant-velocity prior is used: a robot standing in a corridor,
    /// where the scans do not pin the pose along it, then slid along it
    /// with each match's small correction carried on as a velocity (131 mm
    /// in 30 s in `tests/icp_standstill.rs`).
    pub fn note_live_odometry(&mut self) {
        self.live_odometry = true;
    }

    /// The current pose estimate (the reported pose of the last step).
    pub fn pose(&self) -> Pose {
        self.reported
    }

    /// The current scan-to-map pose: the reported pose before fusion with
    /// scan-to-scan matching (the same when `scan_fusion` is 0).
    pub fn map_pose(&self) -> Pose {
        self.map_pose
    }

    /// The local map (keyframes and the reference built from them).
    pub fn map(&self) -> &KeyframeMap {
        &self.map
    }

    /// The matcher's parameters.
    pub fn params(&self) -> &IcpParams {
        self.matcher.params()
    }

    /// Processes one scan given as sensor-frame points in beam order, with the
    /// wheel odometry pose at the same time when there is one. Matches against
    /// the tracker's own keyframe map and adds keyframes as the robot moves.
    pub fn step(&mut self, points: &[IPoint], odom: Option<&Pose>) -> Step {
        let mut step = self.step_inner(points, odom, None);
        if self.pending_keyframe.is_some() {
            step.keyframe = self.finish_keyframe();
        }
        step
    }

    /// Like [`Tracker::step`], but a keyframe that is due is only decided
    /// on (`Step::keyframe` says so): adding it, which rebuilds the local
    /// map's k-d tree (the costliest part of a keyframe step), waits for
    /// [`Tracker::finish_keyframe`]. A daemon hands the pose on first and
    /// finishes after, off the pose's latency. The estimates are the same as
    /// with [`Tracker::step`]: the next step (or [`Tracker::set_pose`])
    /// finishes a keyframe left pending before doing anything else.
    pub fn step_deferred(&mut self, points: &[IPoint], odom: Option<&Pose>) -> Step {
        self.step_inner(points, odom, None)
    }

    /// Adds the keyframe [`Tracker::step_deferred`] decided on, if any;
    /// true when one was added. With a keyframe store, otherwise chooses
    /// the keyframes nearest the robot again (both rebuild the reference).
    pub fn finish_keyframe(&mut self) -> bool {
        let params = self.matcher.params().clone();
        let Some(pose) = self.pending_keyframe.take() else {
            // A failed rebuild leaves the previous reference in place.
            let _ = self.map.follow(&self.map_pose, &params);
            return false;
        };
        self.map
            .insert(&pose, self.matcher.prepared_points(), &params)
            .is_ok()
    }

    /// Like [`Tracker::step`], but matches against `reference` (e.g. a snapshot
    /// of the mapping layer's point map, in the same world frame) instead of
    /// the keyframe map, which is left untouched.
    pub fn step_with_reference(
        &mut self,
        points: &[IPoint],
        odom: Option<&Pose>,
        reference: &Reference,
    ) -> Step {
        self.step_inner(points, odom, Some(reference))
    }

    fn step_inner(
        &mut self,
        points: &[IPoint],
        odom: Option<&Pose>,
        external: Option<&Reference>,
    ) -> Step {
        self.finish_keyframe();
        // A fresh odometry reading predicts from the pose where the previous
        // distinct reading first appeared; a stalled (repeated) reading of a
        // log says nothing, so the constant-velocity prior is used instead.
        // A live reading is taken as measured, a repeated one too (a
        // standstill), and the logs' timing jitter is not smoothed out of it.
        let live = std::mem::take(&mut self.live_odometry);
        self.scans_since_anchor = self.scans_since_anchor.saturating_add(1);
        let fresh_odom = match (odom, self.odom_anchor) {
            // Live readings are taken at the scan's own time: as measured.
            // The step is kept, so that a log-style reading (late odometry)
            // after them is smoothed from the motion then, not an old one.
            (Some(now), Some((before, at))) if live => {
                let inc = before.inverse() * now;
                let scans = f64::from(self.scans_since_anchor.max(1));
                self.odom_step = Some(inc.translation.vector / scans);
                Some((*now, unit(at * inc)))
            }
            (Some(now), Some((before, at))) if *now != before => Some((
                *now,
                unit(at * self.smoothed_increment(&(before.inverse() * now))),
            )),
            (Some(now), None) => Some((*now, self.map_pose)),
            _ => None,
        };
        let prepared = self.matcher.prepare_points(points);
        if !self.started && external.is_none() {
            let step = match prepared {
                Ok(_) => {
                    let params = self.matcher.params().clone();
                    let kf =
                        self.map
                            .insert(&self.map_pose, self.matcher.prepared_points(), &params);
                    match kf {
                        Ok(()) => {
                            self.started = true;
                            self.reported = self.map_pose;
                            self.remember_scan();
                            Step {
                                pose: self.map_pose,
                                outcome: Outcome::First,
                                keyframe: true,
                                searched: false,
                            }
                        }
                        Err(e) => self.fallback(Outcome::Failed(e)),
                    }
                }
                Err(e) => self.fallback(Outcome::Failed(e)),
            };
            if let Some((now, _)) = fresh_odom {
                self.odom_anchor = Some((now, self.map_pose));
                self.scans_since_anchor = 0;
            }
            return step;
        }
        let cv_guess = unit(self.map_pose * self.velocity);
        let guess = match (self.matcher.params().prior, fresh_odom) {
            (Prior::Odometry, Some((_, g))) => g,
            _ => cv_guess,
        };
        // Across a gap the velocity says nothing: no second guess.
        let gap = self.after_gap;
        let alt = if gap { guess } else { cv_guess };
        let weight = match (self.matcher.params().prior, fresh_odom) {
            (Prior::Odometry, Some(_)) => self.matcher.params().prior_weight,
            _ => 0.0,
        };
        let live_limit = match (live && !gap, self.since_accept) {
            (true, Some((n, _))) if self.matcher.params().live_correction > 0.0 => {
                Some(self.matcher.params().live_correction * f64::from(n.saturating_add(1)))
            }
            _ => None,
        };
        let armed = match self.since_accept {
            Some((_, at)) if live && !gap && external.is_none() => Some(at),
            _ => None,
        };
        let mut step = self.register(
            prepared.map(|_| ()),
            (guess, weight),
            alt,
            live_limit,
            external,
        );
        if armed.is_some_and(|at| self.bridges(&step.outcome, &at)) {
            self.pending_keyframe = Some(self.map_pose);
            step.keyframe = true;
            self.unconfirmed += 1;
        }
        let accepted = matches!(step.outcome, Outcome::Matched(_));
        if accepted {
            self.unconfirmed = 0;
        }
        self.since_accept = match (live, accepted) {
            (false, _) => None,
            (true, true) => Some((0, self.map_pose)),
            (true, false) => self.since_accept.map(|(n, at)| (n.saturating_add(1), at)),
        };
        if gap {
            // The motion across the gap is no per-scan velocity: the next
            // scan, if its odometry is stale (wheels held), stays put.
            self.after_gap = false;
            self.velocity = Pose::identity();
        }
        if let Some((now, _)) = fresh_odom {
            self.odom_anchor = Some((now, self.map_pose));
            self.scans_since_anchor = 0;
        }
        step
    }

    /// The odometry increment `inc` (spanning the scans since the anchor) with
    /// its translation replaced by the smoothed per-scan step times that span;
    /// updates the smoothed step. The rotation is kept as measured.
    fn smoothed_increment(&mut self, inc: &Pose) -> Pose {
        if self.after_gap {
            return *inc;
        }
        let a = self.matcher.params().odometry_smoothing;
        let k = f64::from(self.scans_since_anchor.max(1));
        let raw = inc.translation.vector / k;
        let step = match self.odom_step {
            Some(s) if a > 0.0 => s * a + raw * (1.0 - a),
            _ => raw,
        };
        self.odom_step = Some(step);
        if a == 0.0 {
            return *inc;
        }
        let t = step * k;
        crate::geom::pose(t.x, t.y, inc.rotation.angle())
    }

    /// Matches the prepared scan from `guess` (with the prior's weight);
    /// when that match is rejected or fails, retries once from `alt` (if
    /// different) and keeps the better. A match that moves the pose farther
    /// than `live_limit` (m) from `guess` is rejected (see
    /// [`IcpParams::live_correction`]).
    fn register(
        &mut self,
        prepared: Result<(), IcpError>,
        (guess, weight): (Pose, f64),
        alt: Pose,
        live_limit: Option<f64>,
        external: Option<&Reference>,
    ) -> Step {
        if let Err(e) = prepared {
            return self.predict(guess, Outcome::Failed(e));
        }
        // Both variants are plain stack values used once, as in `try_match`.
        #[allow(clippy::result_large_err)]
        let within = |m: super::Match| match live_limit {
            Some(limit) => {
                let moved = (m.pose.translation.vector - guess.translation.vector).norm();
                if moved > limit {
                    Err(Outcome::Rejected(
                        Rejection::TooLargeCorrection {
                            translation: moved,
                            rotation: m.quality.correction_rotation,
                        },
                        m.quality,
                    ))
                } else {
                    Ok(m)
                }
            }
            None => Ok(m),
        };
        let first = self.try_match(&guess, weight, external).and_then(within);
        let outcome = match first {
            Ok(m) => Ok(m),
            Err(bad) if alt != guess => {
                match self.try_match(&alt, 0.0, external).and_then(within) {
                    Ok(m) => Ok(m),
                    Err(bad2) => Err(better_failure(bad, bad2)),
                }
            }
            Err(bad) => Err(bad),
        };
        let mut searched = false;
        let outcome = match outcome {
            Err(bad) if self.matcher.params().search.enabled() => {
                searched = true;
                match self.search_from(&guess, external) {
                    Some(Ok(m)) => match within(m) {
                        Ok(m) => {
                            self.search_counts.recovered += 1;
                            Ok(m)
                        }
                        Err(bad2) => Err(better_failure(bad, bad2)),
                    },
                    Some(Err(bad2)) => Err(better_failure(bad, bad2)),
                    None => Err(bad),
                }
            }
            o => o,
        };
        match outcome {
            Ok(m) => {
                let before = self.map_pose;
                self.velocity = unit(self.map_pose.inverse() * m.pose);
                self.map_pose = unit(m.pose);
                let keyframe = external.is_none() && self.keyframe_due();
                if keyframe {
                    self.pending_keyframe = Some(self.map_pose);
                }
                let pose = self.fuse(&before, true);
                Step {
                    pose,
                    outcome: Outcome::Matched(m.quality),
                    keyframe,
                    searched,
                }
            }
            Err(o) => Step {
                searched,
                ..self.predict(guess, o)
            },
        }
    }

    /// The correlative search around `guess` against the reference, and
    /// the ICP match from the pose it found; `None` when it found nothing
    /// worth matching (see [`CorrelativeSearch`]).
    #[allow(clippy::result_large_err)]
    fn search_from(
        &mut self,
        guess: &Pose,
        external: Option<&Reference>,
    ) -> Option<Result<super::Match, Outcome>> {
        let reference = external.unwrap_or(self.map.reference());
        let params = &self.matcher.params().search;
        self.search_counts.calls += 1;
        let hit = self.search.search(
            reference.points(),
            self.matcher.prepared_points(),
            guess,
            params,
        );
        let hit = hit?;
        self.search_counts.found += 1;
        self.search_counts.scored += hit.scored as u64;
        Some(self.try_match(&hit.pose, 0.0, external))
    }

    /// Looks for the scan `points` over every keyframe of the local map
    /// within `search`'s window around the estimate (a robot carried
    /// elsewhere, or lost after a slip the local search could not span):
    /// a correlative search, then ICP from its best candidate against the
    /// keyframes nearest it. Found: the estimate moves there, the motion
    /// prior starts over, and the outcome is [`Outcome::Matched`]. Else the
    /// estimate stays where it was and the outcome says why. Costs a search
    /// over the whole window (tens of milliseconds for a room and a full
    /// turn): for a robot that stands still.
    pub fn relocalise(&mut self, points: &[IPoint], search: &super::SearchParams) -> Step {
        self.finish_keyframe();
        let stay = |pose, outcome| Step {
            pose,
            outcome,
            keyframe: false,
            searched: true,
        };
        if let Err(e) = self.matcher.prepare_points(points) {
            return stay(self.reported, Outcome::Failed(e));
        }
        self.everything.clear();
        self.everything.extend(self.map.points().copied());
        self.search_counts.calls += 1;
        let hit = self.search.search(
            &self.everything,
            self.matcher.prepared_points(),
            &self.map_pose,
            search,
        );
        let Some(hit) = hit else {
            return stay(self.reported, Outcome::Failed(IcpError::NotFound));
        };
        self.search_counts.found += 1;
        self.search_counts.scored += hit.scored as u64;
        let params = self.matcher.params().clone();
        // A failed rebuild keeps the previous reference: the match fails.
        let _ = self.map.reselect(&hit.pose, &params);
        match self.try_match(&hit.pose, 0.0, None) {
            Ok(m) => {
                self.search_counts.recovered += 1;
                self.set_pose(m.pose);
                self.unconfirmed = 0;
                stay(self.reported, Outcome::Matched(m.quality))
            }
            Err(o) => {
                let _ = self.map.reselect(&self.map_pose, &params);
                stay(self.reported, o)
            }
        }
    }

    /// Forgets the keyframes taken at the prediction since the last
    /// accepted match (a scan that saw too little of the local map is
    /// taken at the wheels' pose: see `bridges`), for when that pose proved
    /// wrong (the robot was carried away); returns how many.
    pub fn forget_unconfirmed(&mut self) -> usize {
        self.finish_keyframe();
        let n = std::mem::take(&mut self.unconfirmed);
        let params = self.matcher.params().clone();
        // A failed rebuild keeps the previous reference.
        let _ = self.map.drop_newest(n, &params);
        n
    }

    /// Drops the keyframe [`Tracker::step_deferred`] decided on and has
    /// not added yet (its match proved wrong after all: the caller found it
    /// contradicts the map); true when there was one.
    pub fn discard_pending_keyframe(&mut self) -> bool {
        self.pending_keyframe.take().is_some()
    }

    /// How often the correlative search ran since the tracker was made.
    pub fn search_counts(&self) -> SearchCounts {
        self.search_counts
    }

    // Both variants are plain stack values used once; boxing would allocate per scan.
    #[allow(clippy::result_large_err)]
    fn try_match(
        &mut self,
        guess: &Pose,
        weight: f64,
        external: Option<&Reference>,
    ) -> Result<super::Match, Outcome> {
        let reference = external.unwrap_or(self.map.reference());
        match self
            .matcher
            .match_prepared_weighted(reference, guess, weight)
        {
            Ok(m) => match m.quality.check(self.matcher.params()) {
                Ok(()) => Ok(m),
                Err(r) => Err(Outcome::Rejected(r, m.quality)),
            },
            Err(e) => Err(Outcome::Failed(e)),
        }
    }

    fn predict(&mut self, guess: Pose, outcome: Outcome) -> Step {
        let before = self.map_pose;
        self.velocity = unit(self.map_pose.inverse() * guess);
        self.map_pose = unit(guess);
        let pose = self.fuse(&before, false);
        Step {
            pose,
            outcome,
            keyframe: false,
            searched: false,
        }
    }

    fn fallback(&self, outcome: Outcome) -> Step {
        Step {
            pose: self.reported,
            outcome,
            keyframe: false,
            searched: false,
        }
    }

    /// The reported pose after the scan-to-map pose moved from `before` to
    /// `self.map_pose`: the previous reported pose moved by the scan-to-scan match
    /// (or, without one, by the scan-to-map increment), then pulled
    /// `1 − scan_fusion` of the way to the scan-to-map pose. `matched` says
    /// whether the prepared points are this scan's registered points.
    fn fuse(&mut self, before: &Pose, matched: bool) -> Pose {
        let share = self.matcher.params().scan_fusion;
        if share <= 0.0 {
            self.reported = self.map_pose;
            return self.map_pose;
        }
        let follow = crate::geom::carried(&self.reported, before, &self.map_pose);
        let local = if matched && !self.previous.is_empty() {
            match self
                .matcher
                .match_prepared_weighted(&self.previous, &follow, 0.0)
            {
                Ok(m) if m.quality.check(self.matcher.params()).is_ok() => m.pose,
                _ => follow,
            }
        } else {
            follow
        };
        let d = self.map_pose.inverse() * local;
        self.reported = unit(
            self.map_pose
                * crate::geom::pose(
                    share * d.translation.x,
                    share * d.translation.y,
                    share * d.rotation.angle(),
                ),
        );
        if matched {
            self.remember_scan();
        } else {
            self.previous.clear();
        }
        self.reported
    }

    /// Keeps the prepared points at the reported pose as the next scan-to-scan reference.
    fn remember_scan(&mut self) {
        if self.matcher.params().scan_fusion <= 0.0 {
            return;
        }
        let params = self.matcher.params().clone();
        if self
            .previous
            .rebuild_scan(self.matcher.prepared_points(), &self.reported, &params)
            .is_err()
        {
            self.previous.clear();
        }
    }

    /// Whether a scan that found too little of the local map to match
    /// becomes a keyframe at the odometry's pose: the robot turned or
    /// stepped towards walls the keyframe window lacks (a frontier faced in
    /// a large room, an occluder gone), and it moved too little since the
    /// last accepted match, at `at` (`keyframe_distance`, `keyframe_angle`),
    /// for the live odometry to be off. Without this the next scans, seeing
    /// the same, fail too, and nothing new ever enters the local map: a
    /// robot waiting to see that frontier waits for ever. A scan that fits
    /// badly (high residual, too large a correction) is never bridged.
    fn bridges(&self, outcome: &Outcome, at: &Pose) -> bool {
        let little = matches!(
            outcome,
            Outcome::Failed(IcpError::TooFewPairs { .. })
                | Outcome::Rejected(Rejection::LowInlierRatio { .. }, _)
        );
        let params = self.matcher.params();
        let d = at.inverse() * self.map_pose;
        little
            && d.translation.vector.norm() <= params.keyframe_distance
            && d.rotation.angle().abs() <= params.keyframe_angle
    }

    /// Whether the scan just matched at `map_pose` is far enough from the
    /// keyframes to become one ([`KeyframeMap::due`]).
    fn keyframe_due(&self) -> bool {
        self.map.due(&self.map_pose, self.matcher.params())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;
    use crate::icp::synth::{cast_seeded, room, Wall};

    /// Deferring the keyframe (the daemon's order: pose out first, keyframe
    /// after) gives the very same estimates as adding it within the step,
    /// also when a relocalisation (`set_pose`) comes between.
    #[test]
    fn a_deferred_keyframe_changes_no_estimate() {
        let mut walls = room(5.0, 4.0, 0.5);
        walls.push(Wall::new(3.0, 1.0, 3.0, 2.2, 0.9));
        let truth = |k: u32| pose(1.0 + 0.04 * f64::from(k), 1.5, 0.03 * f64::from(k));
        let params = IcpParams {
            keyframe_distance: 0.1,
            keyframe_window: 6,
            ..IcpParams::default()
        };
        let mut now = Tracker::new(params.clone(), truth(0)).unwrap();
        let mut later = Tracker::new(params, truth(0)).unwrap();
        let mut keyframes = 0;
        for k in 0..40 {
            let scan = cast_seeded(&walls, &truth(k), u64::from(k));
            let odom = truth(k) * pose(0.002, -0.001, 0.001);
            let a = now.step(&scan, Some(&odom));
            let b = later.step_deferred(&scan, Some(&odom));
            assert_eq!(a.pose, b.pose, "scan {k}");
            assert_eq!(a.keyframe, b.keyframe, "scan {k}");
            if k == 25 {
                // The pending keyframe goes in before the pose moves.
                now.set_pose(truth(k));
                later.set_pose(truth(k));
                assert!(!later.finish_keyframe());
            } else if k % 3 != 0 {
                // Every third scan's keyframe is left for the next step.
                assert_eq!(later.finish_keyframe(), b.keyframe, "scan {k}");
            } else if b.keyframe && k > 0 {
                // Left pending: not in the local map yet.
                assert_ne!(now.map().last_pose(), later.map().last_pose(), "scan {k}");
            }
            keyframes += usize::from(a.keyframe);
        }
        assert!(keyframes >= 10, "{keyframes} keyframes");
        later.finish_keyframe();
        assert_eq!(now.state(), later.state());
    }

    /// A robot carried 1.6 m and turned 100° while the wheels say it
    /// stood still: the local search's window does not reach, matches
    /// fail; the whole-map search finds it, and the keyframes bridged at
    /// the wrong pose in between are forgotten first.
    #[test]
    fn a_carried_robot_is_found_over_the_whole_map() {
        let walls = crate::icp::synth::l_room_with_pillar();
        let params = IcpParams {
            keyframe_store: 200,
            keyframe_window: 20,
            keyframe_distance: 0.3,
            ..IcpParams::default()
        };
        let truth = |k: u32| {
            pose(
                0.8 + 0.1 * f64::from(k),
                0.6 + 0.04 * f64::from(k),
                0.05 * f64::from(k),
            )
        };
        let mut t = Tracker::new(params, truth(0)).unwrap();
        for k in 0..40 {
            t.note_live_odometry();
            let s = t.step(
                &cast_seeded(&walls, &truth(k), u64::from(k)),
                Some(&truth(k)),
            );
            assert!(
                matches!(s.outcome, Outcome::First | Outcome::Matched(_)),
                "scan {k}: {s:?}"
            );
        }
        let before = t.map().len();
        let here = truth(39);
        let carried = pose(1.2, 3.0, here.rotation.angle() + 100f64.to_radians());
        let mut failed = 0;
        for k in 0..5 {
            t.note_live_odometry();
            let s = t.step(&cast_seeded(&walls, &carried, 100 + k), Some(&here));
            failed += usize::from(!matches!(s.outcome, Outcome::Matched(_)));
        }
        assert_eq!(failed, 5, "the local search cannot reach 1.6 m and 100°");
        let forgotten = t.forget_unconfirmed();
        assert!(t.map().len() + forgotten >= before);
        let whole = crate::icp::SearchParams {
            window: 4.0,
            window_angle: std::f64::consts::PI,
            levels: 6,
            min_score: 0.5,
            ..crate::icp::SearchParams::default()
        };
        let s = t.relocalise(&cast_seeded(&walls, &carried, 200), &whole);
        assert!(matches!(s.outcome, Outcome::Matched(_)), "{s:?}");
        let d = s.pose.translation.vector - carried.translation.vector;
        assert!(d.norm() < 0.02, "{:?}", s.pose);
        assert!((s.pose.rotation.angle() - carried.rotation.angle()).abs() < 0.01);
        // Tracking goes on from there.
        let on = carried * pose(0.05, 0.0, 0.02);
        let s = t.step(&cast_seeded(&walls, &on, 300), None);
        assert!(matches!(s.outcome, Outcome::Matched(_)), "{s:?}");
        assert!((s.pose.translation.vector - on.translation.vector).norm() < 0.02);
    }

    #[test]
    fn restored_keyframes_pull_an_offset_start_back_into_their_frame() {
        let mut walls = room(5.0, 4.0, 0.5);
        walls.push(Wall::new(3.0, 1.0, 3.0, 2.2, 0.9));
        let truth = |k: u32| pose(1.0 + 0.05 * f64::from(k), 1.5, 0.02 * f64::from(k));
        let params = IcpParams::default();
        let mut a = Tracker::new(params.clone(), truth(0)).unwrap();
        for k in 0..30 {
            a.step(&cast_seeded(&walls, &truth(k), u64::from(k)), None);
        }
        let state = a.state();
        assert!(!state.keyframes.is_empty());
        assert!(state
            .keyframes
            .iter()
            .all(|k| k.points.len() == k.normals.len() && k.points.len() == k.edges.len()));

        // A resume 8 cm and 2° off the truth of the next scan.
        let next = truth(30);
        let off = next * pose(0.06, -0.05, 0.035);
        let (mut b, refused) = Tracker::restore(params.clone(), off, &state).unwrap();
        assert_eq!(refused, None);
        assert_eq!(b.map().len(), state.keyframes.len());
        let step = b.step(&cast_seeded(&walls, &next, 99), None);
        assert!(matches!(step.outcome, Outcome::Matched(_)), "{step:?}");
        let err = (step.pose.translation.vector - next.translation.vector).norm();
        assert!(err < 0.01, "restored: {err:.3} m off");

        // Without the keyframes the first scan founds a new map at the offset.
        let mut c = Tracker::new(params.clone(), off).unwrap();
        let step = c.step(&cast_seeded(&walls, &next, 99), None);
        let err = (step.pose.translation.vector - next.translation.vector).norm();
        assert!(err > 0.07, "fresh: {err:.3} m off");

        // Nothing usable to restore: a fresh tracker, and the reason.
        let empty = TrackerState::default();
        let (d, refused) = Tracker::restore(params.clone(), off, &empty).unwrap();
        assert!(d.map().is_empty() && refused.is_none());
        let mut thin = state.clone();
        thin.keyframes.truncate(1);
        thin.keyframes[0].points.truncate(3);
        let (d, refused) = Tracker::restore(params, off, &thin).unwrap();
        assert!(d.map().is_empty());
        assert!(refused.is_some());
    }

    /// Drives along y = 1.7 in the faults room at 2.2 cm per scan with exact
    /// odometry, loses the scans of 3.6 s (the scanner unplugged), stands
    /// still for 3 scans (wheels held: the odometry repeats), goes on for 5
    /// scans, and returns the largest correction a match made to its guess
    /// after the gap (infinite if one failed) and the largest position
    /// error.
    fn after_an_outage(note_gap: bool) -> (f64, f64) {
        let mut walls = room(3.2, 2.6, 0.55);
        walls.extend([
            Wall::new(1.8, 1.0, 2.3, 1.0, 0.8),
            Wall::new(2.3, 1.0, 2.3, 1.5, 0.8),
            Wall::new(2.3, 1.5, 1.8, 1.5, 0.8),
            Wall::new(1.8, 1.5, 1.8, 1.0, 0.8),
        ]);
        let truth = |k: u32| pose(0.3 + 0.022 * f64::from(k), 1.7, 0.0);
        let mut t = Tracker::new(IcpParams::default(), truth(0)).unwrap();
        for k in 0..14 {
            t.step(
                &cast_seeded(&walls, &truth(k), u64::from(k)),
                Some(&truth(k)),
            );
        }
        if note_gap {
            t.note_gap();
        }
        let (mut correction, mut error) = (0.0f64, 0.0f64);
        for k in [50, 50, 50, 50, 51, 52, 53, 54, 55] {
            let step = t.step(
                &cast_seeded(&walls, &truth(k), u64::from(k)),
                Some(&truth(k)),
            );
            correction = correction.max(match step.outcome {
                Outcome::Matched(q) => q.correction_translation,
                _ => f64::INFINITY,
            });
            error = error.max((step.pose.translation.vector - truth(k).translation.vector).norm());
        }
        (correction, error)
    }

    /// The robot really moved 0.2 m that its live odometry missed (wheels
    /// slipping): the scans say so at once, but `live_correction` takes a
    /// jump that large only after a few scans, its limit growing by 5 cm a
    /// scan; without live odometry, or with the limit off, at once.
    fn scans_until_an_unseen_slide_is_taken(live: bool, live_correction: f64) -> usize {
        let mut walls = room(4.0, 3.0, 0.5);
        walls.push(Wall::new(2.5, 1.0, 2.5, 2.0, 0.9));
        let start = pose(1.0, 1.5, 0.1);
        let params = IcpParams {
            live_correction,
            ..IcpParams::default()
        };
        let mut t = Tracker::new(params, start).unwrap();
        let odom = pose(0.0, 0.0, 0.0);
        for k in 0..5 {
            if live {
                t.note_live_odometry();
            }
            let step = t.step(&cast_seeded(&walls, &start, k), Some(&odom));
            assert!(matches!(step.outcome, Outcome::First | Outcome::Matched(_)));
        }
        let slid = start * pose(0.2, 0.0, 0.0);
        for k in 0..8u64 {
            if live {
                t.note_live_odometry();
            }
            let step = t.step(&cast_seeded(&walls, &slid, 10 + k), Some(&odom));
            match step.outcome {
                Outcome::Matched(_) => {
                    let err = (step.pose.translation.vector - slid.translation.vector).norm();
                    assert!(err < 0.01, "taken {err:.3} m off");
                    return k as usize;
                }
                Outcome::Rejected(Rejection::TooLargeCorrection { translation, .. }, _) => {
                    assert!(translation > 0.15, "{translation}");
                    let held = (step.pose.translation.vector - start.translation.vector).norm();
                    assert!(held < 0.01, "held at the odometry: {held:.3} m");
                }
                other => panic!("scan {k}: {other:?}"),
            }
        }
        panic!("never taken");
    }

    /// A robot standing boxed in (a screen around it) while its local map
    /// forms; the screen is lifted and the room's walls, a metre and more
    /// beyond it, share nothing with that map. With live odometry the
    /// first such scan becomes a keyframe where the wheels say the robot
    /// stands, and the next one matches it; from logged odometry no scan
    /// ever matches again.
    fn scans_matched_after_the_view_opens(live: bool) -> usize {
        let room_walls = room(6.0, 4.0, 0.5);
        let mut boxed = room_walls.clone();
        boxed.extend([
            Wall::new(2.5, 1.5, 3.5, 1.5, 0.5),
            Wall::new(3.5, 1.5, 3.5, 2.5, 0.5),
            Wall::new(3.5, 2.5, 2.5, 2.5, 0.5),
            Wall::new(2.5, 2.5, 2.5, 1.5, 0.5),
        ]);
        let at = pose(3.0, 2.0, 0.3);
        let odom = pose(0.0, 0.0, 0.0);
        let mut t = Tracker::new(IcpParams::default(), at).unwrap();
        for k in 0..4 {
            if live {
                t.note_live_odometry();
            }
            t.step(&cast_seeded(&boxed, &at, k), Some(&odom));
        }
        let mut matched = 0;
        for k in 0..6 {
            if live {
                t.note_live_odometry();
            }
            let step = t.step(&cast_seeded(&room_walls, &at, 10 + k), Some(&odom));
            let err = (step.pose.translation.vector - at.translation.vector).norm();
            // From logged odometry (a repeated reading is a stalled log)
            // the pose moves on at the last velocity: held only when live.
            assert!(!live || err < 0.02, "scan {k}: {err:.3} m off");
            if k == 0 {
                assert!(
                    matches!(step.outcome, Outcome::Failed(IcpError::TooFewPairs { .. })),
                    "{:?}",
                    step.outcome
                );
                assert_eq!(step.keyframe, live, "bridged only with live odometry");
            }
            matched += usize::from(matches!(step.outcome, Outcome::Matched(_)));
        }
        matched
    }

    #[test]
    fn a_view_opening_onto_unmapped_walls_is_bridged_by_live_odometry() {
        assert_eq!(scans_matched_after_the_view_opens(true), 5);
        assert_eq!(scans_matched_after_the_view_opens(false), 0);
    }

    #[test]
    fn a_live_match_far_from_the_odometry_is_taken_only_as_its_limit_grows() {
        // 0.2 m: over 0.05, 0.10 and 0.15, within 0.20 at the fourth scan.
        assert_eq!(scans_until_an_unseen_slide_is_taken(true, 0.05), 3);
        assert_eq!(scans_until_an_unseen_slide_is_taken(true, 0.0), 0);
        assert_eq!(scans_until_an_unseen_slide_is_taken(false, 0.05), 0);
    }

    #[test]
    fn after_a_gap_the_odometry_increment_is_taken_whole() {
        let (correction, error) = after_an_outage(true);
        assert!(correction < 0.02, "gap noted: guess {correction:.3} m off");
        assert!(error < 0.01, "gap noted: {error:.3} m off");
        // Smoothed as if one scan period had passed, the guess falls half
        // the motion short, and the next scans' guesses overshoot.
        let (correction, _) = after_an_outage(false);
        assert!(
            correction > 0.3,
            "gap not noted: guess {correction:.3} m off"
        );
    }
}
