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
#[error("encoder jump of {left:.3} m (left) / {right:.3} m (right) in {dt:.3} s is not plausible; odometry re-based")]
pub struct OdometryGlitch {
    /// Left travel implied by the reading (m).
    pub left: f64,
    /// Right travel implied (m).
    pub right: f64,
    /// Time between the readings (s).
    pub dt: f64,
}

/// Turns successive encoder readings into [`Odometry`] increments.
#[derive(Clone, Debug)]
pub struct Odometer {
    width: CounterWidth,
    counts_per_metre: f64,
    wheel_base: f64,
    max_wheel_speed: f64,
    last: Option<(u32, u32, f64)>,
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
            last: None,
        }
    }

    /// Forgets the previous reading: the next one becomes the new baseline
    /// (after a reconnect, when counters may have been reset).
    pub fn rebase(&mut self) {
        self.last = None;
    }

    /// Feeds one reading of both counters taken at `t` seconds; returns the
    /// increment since the previous reading (`None` for the first one).
    pub fn update(
        &mut self,
        left: u32,
        right: u32,
        t: f64,
    ) -> Result<Option<Odometry>, OdometryGlitch> {
        let Some((l0, r0, t0)) = self.last.replace((left, right, t)) else {
            return Ok(None);
        };
        let dl = self.width.diff(l0, left) as f64 / self.counts_per_metre;
        let dr = self.width.diff(r0, right) as f64 / self.counts_per_metre;
        let dt = (t - t0).max(0.0);
        // Allow a few control periods of slack for reading jitter.
        let limit = self.max_wheel_speed * (dt + 0.05) * 1.5;
        if dl.abs() > limit || dr.abs() > limit {
            return Err(OdometryGlitch {
                left: dl,
                right: dr,
                dt,
            });
        }
        Ok(Some(Odometry {
            t0,
            t1: t,
            delta: arc_increment(dl, dr, self.wheel_base),
            left: dl,
            right: dr,
        }))
    }
}

/// Capacity of an [`OdometryTrack`] (poses kept); at 20 Hz about 12 s.
pub const TRACK_LEN: usize = 256;

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
}
