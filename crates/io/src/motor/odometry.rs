//! Encoder odometry: wrapping counter readings in, pose increments out. Pure
//! (no clock, no I/O): the caller passes each reading's timestamp.

use nalgebra::{Isometry2, Vector2};

use crate::geom::Pose;
use crate::motor::Odometry;

/// Width of the controller's encoder counters, which wrap around.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CounterWidth {
    /// 16-bit counters (Create 2 packets 43/44).
    Bits16,
    /// 32-bit counters (RoboClaw).
    Bits32,
}

impl CounterWidth {
    /// Signed difference `new - old` of two raw readings, across a wrap.
    pub fn diff(self, old: u32, new: u32) -> i64 {
        match self {
            CounterWidth::Bits16 => (new as u16).wrapping_sub(old as u16) as i16 as i64,
            CounterWidth::Bits32 => new.wrapping_sub(old) as i32 as i64,
        }
    }
}

/// Encoder counts per metre of wheel travel for `counts_per_rev` counts per
/// wheel revolution on wheels of `wheel_radius` metres.
pub fn counts_per_metre(counts_per_rev: f64, wheel_radius: f64) -> f64 {
    counts_per_rev / (2.0 * std::f64::consts::PI * wheel_radius)
}

/// Pose increment of a differential drive whose left and right wheels travelled
/// `dl` and `dr` metres on an axle of `wheel_base` metres, assuming a
/// constant-curvature arc; expressed in the starting base frame.
pub fn arc_increment(dl: f64, dr: f64, wheel_base: f64) -> Pose {
    let ds = 0.5 * (dl + dr);
    let dth = (dr - dl) / wheel_base;
    let (dx, dy) = if dth.abs() < 1e-9 {
        (ds, 0.0)
    } else {
        let r = ds / dth;
        (r * dth.sin(), r * (1.0 - dth.cos()))
    };
    Isometry2::new(Vector2::new(dx, dy), dth)
}

/// A reading rejected as physically impossible (a counter reset by a
/// controller reboot, or a corrupted value that passed the checksum).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("encoder jump of {left:.3} m (left) / {right:.3} m (right) {dt:.3} s after the last accepted reading is not plausible (at most {limit:.3} m in the {elapsed:.3} s the counters may have been apart); reading ignored, the next one decides between a corrupt value and a counter reset")]
pub struct OdometryGlitch {
    /// Left travel implied by the reading (m).
    pub left: f64,
    /// Right travel implied (m).
    pub right: f64,
    /// Time between the readings' stamps (s).
    pub dt: f64,
    /// Longest the two readings' counters may have been latched apart (s):
    /// from the request of the last accepted reading to the answer of this
    /// one.
    pub elapsed: f64,
    /// Largest travel of one wheel plausible in `elapsed` (m).
    pub limit: f64,
}

/// Slack on the plausible wheel speed (reading jitter, acceleration).
const SPEED_MARGIN: f64 = 1.5;
/// Default latency allowance (s): a few control periods of reading jitter.
pub(crate) const DEFAULT_LATENCY: f64 = 0.05;

/// One reading of both counters and when they were latched.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Reading {
    left: u32,
    right: u32,
    /// The reading's timestamp (s).
    stamp: f64,
    /// Earliest time the counters can have been latched (s): when the
    /// request went out.
    earliest: f64,
}

/// What `Odometer::update_within` made of a reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Accepted {
    /// The first reading: the baseline, no increment.
    Baseline,
    /// Plausible against the last accepted reading: the travel since it,
    /// whatever readings were rejected in between.
    Increment(Odometry),
    /// Implausible against the last accepted reading but continuing from
    /// the rejected one before it: the counters really jumped (a controller
    /// reboot reset them); odometry re-based on the rejected reading and
    /// this is the travel since it (the jump itself is not counted).
    Rebased(Odometry),
}

impl Accepted {
    /// The increment, if any.
    pub fn odometry(self) -> Option<Odometry> {
        match self {
            Accepted::Baseline => None,
            Accepted::Increment(o) | Accepted::Rebased(o) => Some(o),
        }
    }
}

/// Turns successive encoder readings into [`Odometry`] increments.
///
/// A reading is plausible when no wheel travelled farther than the top
/// wheel speed (with a margin) allows in the longest time the two readings'
/// counters may have been latched apart: from the *request* of the last
/// accepted reading to the *answer* of this one, plus a latency allowance.
/// A delayed or bunched reply thus widens the bound instead of making real
/// travel look like a jump. An implausible reading is set aside and the
/// last accepted one stays the baseline, so a corrupt value loses no
/// motion: the next good reading carries all the travel since. When the
/// next reading continues from the set-aside one instead, the counters did
/// jump (a reset) and odometry re-bases there.
#[derive(Clone, Debug)]
pub struct Odometer {
    width: CounterWidth,
    counts_per_metre: f64,
    wheel_base: f64,
    max_wheel_speed: f64,
    latency: f64,
    last: Option<Reading>,
    suspect: Option<Reading>,
}

impl Odometer {
    /// An odometer for counters of `width`, `counts_per_metre` of wheel travel,
    /// wheels `wheel_base` metres apart; readings implying a wheel faster than
    /// `max_wheel_speed` (m/s) are glitches.
    pub fn new(
        width: CounterWidth,
        counts_per_metre: f64,
        wheel_base: f64,
        max_wheel_speed: f64,
    ) -> Self {
        Self {
            width,
            counts_per_metre,
            wheel_base,
            max_wheel_speed,
            latency: DEFAULT_LATENCY,
            last: None,
            suspect: None,
        }
    }

    /// The same odometer with a latency allowance of `seconds` (the link's
    /// reply timeout and reading jitter; non-finite or negative: the default)
    /// added to the time the counters may have been apart.
    pub(crate) fn with_latency(mut self, seconds: f64) -> Self {
        self.latency = if seconds.is_finite() && seconds >= 0.0 {
            seconds
        } else {
            DEFAULT_LATENCY
        };
        self
    }

    /// Forgets the previous reading: the next one becomes the new baseline
    /// (after a reconnect, when counters may have been reset).
    pub(crate) fn rebase(&mut self) {
        self.last = None;
        self.suspect = None;
    }

    /// Feeds one reading of both counters taken at `t` seconds; returns the
    /// increment since the last accepted reading (`None` for the first one).
    pub fn update(
        &mut self,
        left: u32,
        right: u32,
        t: f64,
    ) -> Result<Option<Odometry>, OdometryGlitch> {
        self.update_within(left, right, t, (t, t))
            .map(Accepted::odometry)
    }

    /// Feeds one reading stamped `stamp`, whose counters were latched some
    /// time within `latched` (request sent, answer received; s).
    pub(crate) fn update_within(
        &mut self,
        left: u32,
        right: u32,
        stamp: f64,
        latched: (f64, f64),
    ) -> Result<Accepted, OdometryGlitch> {
        let earliest = if latched.0.is_finite() {
            latched.0.min(stamp)
        } else {
            stamp
        };
        let latest = if latched.1.is_finite() {
            latched.1.max(stamp)
        } else {
            stamp
        };
        let now = Reading {
            left,
            right,
            stamp,
            earliest,
        };
        let Some(base) = self.last else {
            self.last = Some(now);
            self.suspect = None;
            return Ok(Accepted::Baseline);
        };
        let glitch = match self.travel(&base, &now, latest) {
            Ok(o) => {
                self.last = Some(now);
                self.suspect = None;
                return Ok(Accepted::Increment(o));
            }
            Err(g) => g,
        };
        if let Some(Ok(o)) = self.suspect.map(|s| self.travel(&s, &now, latest)) {
            self.last = Some(now);
            self.suspect = None;
            return Ok(Accepted::Rebased(o));
        }
        self.suspect = Some(now);
        Err(glitch)
    }

    /// The travel from `from` to `to` (answered at `latest`), or why it is
    /// not plausible.
    fn travel(
        &self,
        from: &Reading,
        to: &Reading,
        latest: f64,
    ) -> Result<Odometry, OdometryGlitch> {
        let dl = self.width.diff(from.left, to.left) as f64 / self.counts_per_metre;
        let dr = self.width.diff(from.right, to.right) as f64 / self.counts_per_metre;
        let dt = (to.stamp - from.stamp).max(0.0);
        let elapsed = (latest - from.earliest).max(dt);
        let limit = self.max_wheel_speed * (elapsed + self.latency) * SPEED_MARGIN;
        if !(dl.abs() <= limit && dr.abs() <= limit) {
            return Err(OdometryGlitch {
                left: dl,
                right: dr,
                dt,
                elapsed,
                limit,
            });
        }
        Ok(Odometry {
            t0: from.stamp,
            t1: to.stamp,
            delta: arc_increment(dl, dr, self.wheel_base),
            left: dl,
            right: dr,
        })
    }
}

/// Capacity of an [`OdometryTrack`] (poses kept); at 20 Hz about 12 s.
pub(crate) const TRACK_LEN: usize = 256;

/// The integrated odometry pose over the last few seconds, to look up where
/// the base was (by odometry) at a scan's timestamp: the localiser's prior.
/// Fixed capacity, allocation-free.
#[derive(Clone, Debug)]
pub struct OdometryTrack {
    poses: heapless::Deque<(f64, Pose), TRACK_LEN>,
}

impl Default for OdometryTrack {
    fn default() -> Self {
        Self::new()
    }
}

impl OdometryTrack {
    /// An empty track; the first increment starts it at the identity pose.
    pub fn new() -> Self {
        Self {
            poses: heapless::Deque::new(),
        }
    }

    /// Appends an increment (the oldest pose drops out when full). An
    /// increment that does not start where the track ends (a gap after a
    /// lost link) continues from the last pose anyway: odometry is relative.
    pub fn push(&mut self, o: &Odometry) {
        let last = match self.poses.back() {
            Some(&(_, p)) => p,
            None => {
                let _ = self.poses.push_back((o.t0, Pose::identity()));
                Pose::identity()
            }
        };
        if self.poses.is_full() {
            let _ = self.poses.pop_front();
        }
        let _ = self.poses.push_back((o.t1, last * o.delta));
    }

    /// The latest odometry pose and its time.
    pub fn latest(&self) -> Option<(f64, Pose)> {
        self.poses.back().copied()
    }

    /// The odometry pose at time `t`, interpolated between the readings
    /// around it; `None` outside the kept span (no extrapolation).
    pub fn pose_at(&self, t: f64) -> Option<Pose> {
        let (first, last) = (self.poses.front()?, self.poses.back()?);
        if !(t >= first.0 && t <= last.0) {
            return None;
        }
        let mut prev = *first;
        for &(ti, pi) in self.poses.iter() {
            if ti >= t {
                let span = ti - prev.0;
                if span <= 0.0 || ti == t {
                    return Some(pi);
                }
                let a = (t - prev.0) / span;
                let step = prev.1.inverse() * pi;
                let part = Isometry2::new(step.translation.vector * a, step.rotation.angle() * a);
                return Some(prev.1 * part);
            }
            prev = (ti, pi);
        }
        Some(last.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::heading;
    use std::f64::consts::PI;

    #[test]
    fn sixteen_bit_wrap_both_ways() {
        let w = CounterWidth::Bits16;
        assert_eq!(w.diff(65_530, 5), 11);
        assert_eq!(w.diff(5, 65_530), -11);
        assert_eq!(w.diff(100, 100), 0);
    }

    #[test]
    fn thirty_two_bit_wrap_both_ways() {
        let w = CounterWidth::Bits32;
        assert_eq!(w.diff(u32::MAX - 2, 3), 6);
        assert_eq!(w.diff(3, u32::MAX - 2), -6);
    }

    #[test]
    fn straight_line_and_spin_in_place() {
        let p = arc_increment(0.1, 0.1, 0.235);
        assert!((p.translation.x - 0.1).abs() < 1e-12 && p.translation.y.abs() < 1e-12);
        // Quarter turn in place: each wheel travels b/2 * pi/2.
        let s = 0.235 / 2.0 * PI / 2.0;
        let p = arc_increment(-s, s, 0.235);
        assert!((heading(&p) - PI / 2.0).abs() < 1e-12);
        assert!(p.translation.vector.norm() < 1e-12);
    }

    #[test]
    fn arc_lands_on_the_circle() {
        // Half circle of radius 1 m, counter-clockwise.
        let b = 0.2;
        let (dl, dr) = ((1.0 - b / 2.0) * PI, (1.0 + b / 2.0) * PI);
        let p = arc_increment(dl, dr, b);
        assert!((p.translation.x).abs() < 1e-9, "{p}");
        assert!((p.translation.y - 2.0).abs() < 1e-9, "{p}");
        assert!((heading(&p).abs() - PI).abs() < 1e-9);
    }

    #[test]
    fn increments_across_a_wrap_compose_to_the_travel() {
        let cpm = 2250.0;
        let mut o = Odometer::new(CounterWidth::Bits16, cpm, 0.235, 0.5);
        let mut l: u16 = 65_000;
        let mut total = Pose::identity();
        assert_eq!(o.update(l as u32, l as u32, 0.0), Ok(None));
        for i in 1..=100 {
            l = l.wrapping_add(45); // 0.02 m per 0.1 s
            let d = o
                .update(l as u32, l as u32, i as f64 * 0.1)
                .unwrap()
                .unwrap();
            total *= d.delta;
        }
        assert!((total.translation.x - 2.0).abs() < 1e-9, "{total}");
    }

    fn odo(t0: f64, t1: f64, dx: f64, dth: f64) -> Odometry {
        Odometry {
            t0,
            t1,
            delta: Isometry2::new(Vector2::new(dx, 0.0), dth),
            left: dx,
            right: dx,
        }
    }

    #[test]
    fn track_interpolates_and_refuses_to_extrapolate() {
        let mut tr = OdometryTrack::new();
        assert_eq!(tr.pose_at(0.0), None);
        tr.push(&odo(1.0, 1.1, 0.02, 0.0));
        tr.push(&odo(1.1, 1.2, 0.02, 0.1));
        let p = tr.pose_at(1.05).unwrap();
        assert!((p.translation.x - 0.01).abs() < 1e-12);
        let p = tr.pose_at(1.15).unwrap();
        assert!((p.translation.x - 0.03).abs() < 1e-12);
        assert!((heading(&p) - 0.05).abs() < 1e-12);
        assert_eq!(tr.pose_at(1.2), Some(tr.latest().unwrap().1));
        assert_eq!(tr.pose_at(0.99), None);
        assert_eq!(tr.pose_at(1.21), None);
        assert_eq!(tr.pose_at(f64::NAN), None);
    }

    #[test]
    fn track_keeps_the_newest_poses() {
        let mut tr = OdometryTrack::new();
        for i in 0..(TRACK_LEN + 50) {
            let t = i as f64 * 0.05;
            tr.push(&odo(t, t + 0.05, 0.01, 0.0));
        }
        let (t, p) = tr.latest().unwrap();
        assert!((p.translation.x - 0.01 * (TRACK_LEN + 50) as f64).abs() < 1e-9);
        assert!(tr.pose_at(t - 0.05 * (TRACK_LEN as f64 - 2.0)).is_some());
        assert!(tr.pose_at(0.0).is_none());
    }

    #[test]
    fn implausible_jump_is_rejected_and_rebased() {
        let mut o = Odometer::new(CounterWidth::Bits32, 10_000.0, 0.235, 0.5);
        o.update(0, 0, 0.0).unwrap();
        // 5 m in 0.1 s.
        let e = o.update(50_000, 50_000, 0.1).unwrap_err();
        assert!(e.to_string().contains("not plausible"), "{e}");
        // The glitching reading is the new baseline.
        let d = o.update(50_100, 50_100, 0.2).unwrap().unwrap();
        assert!((d.left - 0.01).abs() < 1e-12);
    }

    fn roboclaw() -> Odometer {
        // 10 000 counts per metre, 0.5 m/s top wheel speed.
        Odometer::new(CounterWidth::Bits32, 10_000.0, 0.235, 0.5).with_latency(0.02)
    }

    #[test]
    fn a_delayed_reading_carrying_real_travel_is_accepted() {
        let mut o = roboclaw();
        assert_eq!(
            o.update_within(0, 0, 0.0, (0.0, 0.0)),
            Ok(Accepted::Baseline)
        );
        // The next reply took 0.3 s (a stalled host): stamped near its end,
        // but the counters may have been latched right after the request.
        let a = o.update_within(100, 100, 0.29, (0.0, 0.3)).unwrap();
        assert!(matches!(a, Accepted::Increment(_)), "{a:?}");
        // 13 ms later by the stamps the counters show 0.14 m more: travel
        // over the 0.3 s the counters may really have been apart (0.47 m/s).
        let b = o.update_within(1_500, 1_500, 0.303, (0.3, 0.306)).unwrap();
        let Accepted::Increment(d) = b else {
            panic!("{b:?}")
        };
        assert!((d.left - 0.14).abs() < 1e-12 && (d.right - 0.14).abs() < 1e-12);
        // The same jump where the counters cannot have been more than 16 ms
        // apart (prompt replies both times) is a glitch.
        let mut o = roboclaw();
        o.update_within(0, 0, 0.0, (-0.002, 0.002)).unwrap();
        let e = o
            .update_within(1_400, 1_400, 0.013, (0.011, 0.015))
            .unwrap_err();
        assert!(e.limit < 0.14 && e.elapsed < 0.02, "{e:?}");
        assert!(e.to_string().contains("reading ignored"), "{e}");
    }

    #[test]
    fn a_corrupt_reading_is_rejected_and_no_travel_is_lost() {
        let mut o = roboclaw();
        o.update(0, 0, 0.0).unwrap();
        o.update(50, 50, 0.05).unwrap();
        // One corrupt value (a flipped high bit that passed the CRC).
        let e = o.update(50 | 1 << 24, 100, 0.1).unwrap_err();
        assert!(e.left > 1000.0, "{e:?}");
        // The next good reading carries all the travel since 0.05 s.
        let d = o.update(150, 150, 0.15).unwrap().unwrap();
        assert!(
            (d.left - 0.01).abs() < 1e-12 && (d.right - 0.01).abs() < 1e-12,
            "{d:?}"
        );
        assert_eq!(d.t0, 0.05);
        // Two corrupt values in a row: still measured from the last good one.
        assert!(o.update(7_000_000, 150, 0.2).is_err());
        assert!(o.update(150, 3_000_000, 0.25).is_err());
        let d = o.update(250, 250, 0.3).unwrap().unwrap();
        assert!((d.left - 0.01).abs() < 1e-12, "{d:?}");
    }

    #[test]
    fn a_counter_reset_rebases_on_the_reading_after_it() {
        let mut o = roboclaw();
        o.update(5_000_000, 5_000_000, 0.0).unwrap();
        // The controller rebooted: counters restart near 0.
        assert!(o.update(20, 20, 0.05).is_err());
        let a = o.update_within(120, 120, 0.1, (0.1, 0.1)).unwrap();
        let Accepted::Rebased(d) = a else {
            panic!("{a:?}")
        };
        assert!((d.left - 0.01).abs() < 1e-12, "{d:?}");
        // From then on readings follow the new counters.
        let d = o.update(220, 220, 0.15).unwrap().unwrap();
        assert!((d.left - 0.01).abs() < 1e-12, "{d:?}");
    }
}
