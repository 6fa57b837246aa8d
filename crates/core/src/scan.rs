//! The laser scan as algorithms see it: beams with their angle already computed
//! from the sensor's own parameters, ranges in metres, a validity flag, and a
//! timestamp on the daemon's monotonic clock. Fixed capacity, no heap.

use nalgebra::Point2;

use crate::capacity::MAX_BEAMS;
use crate::geom::{IPoint, Pose};

/// One beam of a scan.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Beam {
    /// Beam angle in the sensor frame (rad, counter-clockwise, 0 = front).
    pub angle: f64,
    /// Measured range in metres; meaningful only when `valid`.
    pub range: f64,
    /// Reflection intensity (0 when the sensor gives none).
    pub intensity: f64,
    /// False for error readings, no-return and out-of-range values.
    pub valid: bool,
}

impl Beam {
    /// A valid beam at `angle` (rad) measuring `range` (m), with no
    /// intensity.
    pub fn hit(angle: f64, range: f64) -> Self {
        Self {
            angle,
            range,
            intensity: 0.0,
            valid: true,
        }
    }
}

/// One scan, in the sensor frame.
#[derive(Clone, Debug, Default)]
pub struct LaserScan {
    /// Acquisition time of the first beam, seconds on the host monotonic clock
    /// (or the log's clock when replaying).
    pub stamp: f64,
    /// Sequence number assigned by the producer (driver, log reader, simulator).
    pub seq: u64,
    /// The beams, in scanning order (counter-clockwise).
    pub beams: heapless::Vec<Beam, MAX_BEAMS>,
    /// Time from `stamp` to the measurement of `beams[0]` (s).
    pub first_beam_time: f64,
    /// Time between the measurements of neighbouring beams, in the order of
    /// `beams` (s; negative once mirrored). A scanning laser measures its
    /// beams one after the other: the URG-04LX's 682 beams take 67 ms, in
    /// which a robot turning at 0.78 rad/s turns 3°. 0 when every beam
    /// counts as measured at `stamp` (logs that do not say, a scan already
    /// deskewed).
    pub beam_interval: f64,
}

impl LaserScan {
    /// The same scan seen from a sensor turned upside down: every angle
    /// negated, the beams reversed so they stay counter-clockwise. In place,
    /// no allocation.
    pub fn mirror(&mut self) {
        self.beams.reverse();
        for b in self.beams.iter_mut() {
            b.angle = -b.angle;
        }
        let last = self.beams.len().saturating_sub(1) as f64;
        self.first_beam_time += last * self.beam_interval;
        self.beam_interval = -self.beam_interval;
    }

    /// When beam `i` was measured, from `stamp` (s).
    pub fn beam_time(&self, i: usize) -> f64 {
        self.first_beam_time + i as f64 * self.beam_interval
    }

    /// Moves every beam into the sensor's frame at `stamp`: `motion(τ)` is
    /// the sensor's pose at `stamp + τ` in its frame at `stamp`. A valid
    /// beam's end point is carried by it (new angle and range), an invalid
    /// beam is turned with it. Afterwards every beam counts as measured at
    /// `stamp`. In place, no allocation; a scan with no beam timing is
    /// left as it is.
    pub fn deskew(&mut self, motion: impl Fn(f64) -> Pose) {
        if self.beam_interval == 0.0 && self.first_beam_time == 0.0 {
            return;
        }
        let (first, step) = (self.first_beam_time, self.beam_interval);
        for (i, b) in self.beams.iter_mut().enumerate() {
            let m = motion(first + i as f64 * step);
            if b.valid && b.range.is_finite() && b.angle.is_finite() {
                let (s, c) = b.angle.sin_cos();
                let p = m * Point2::new(b.range * c, b.range * s);
                b.range = p.coords.norm();
                b.angle = p.y.atan2(p.x);
            } else {
                b.angle = crate::geom::wrap_angle(b.angle + m.rotation.angle());
            }
        }
        self.first_beam_time = 0.0;
        self.beam_interval = 0.0;
    }

    /// [`deskew`](Self::deskew) for a robot that moved by `motion` over
    /// `window` seconds (its odometry over the window ending with the
    /// sweep) at a steady velocity, with the scanner at `mount` on it: the
    /// robot's pose at `τ` is `motion` interpolated at `τ / window`.
    pub fn deskew_steady(&mut self, motion: &Pose, window: f64, mount: &Pose) {
        let back = mount.inverse();
        let still = Pose::identity();
        self.deskew(|tau| back * crate::geom::interpolate(&still, motion, tau / window) * mount);
    }

    /// Number of valid beams.
    pub fn valid_count(&self) -> usize {
        self.beams.iter().filter(|b| b.valid).count()
    }

    /// Writes the valid beams as points in the sensor frame into `out`
    /// (cleared first); returns how many were written. Non-finite values are skipped.
    pub fn points_into(&self, out: &mut Vec<IPoint>) -> usize {
        out.clear();
        for b in self.beams.iter().filter(|b| b.valid) {
            if !(b.range.is_finite() && b.angle.is_finite()) {
                continue;
            }
            let (s, c) = b.angle.sin_cos();
            out.push(IPoint::new(b.range * c, b.range * s, b.intensity));
        }
        out.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mirrored_scan_keeps_its_beams_counter_clockwise() {
        let mut s = LaserScan::default();
        for (a, r) in [(-1.0, 2.0), (0.0, 3.0), (0.5, 4.0)] {
            s.beams.push(Beam::hit(a, r)).unwrap();
        }
        s.mirror();
        let got: Vec<(f64, f64)> = s.beams.iter().map(|b| (b.angle, b.range)).collect();
        assert_eq!(got, vec![(-0.5, 4.0), (0.0, 3.0), (1.0, 2.0)]);
        // A point seen at +0.5 rad by the upside-down sensor lies at -0.5
        // rad in the upright frame.
        let mut pts = Vec::new();
        s.points_into(&mut pts);
        assert!((pts[0].y - 4.0 * (-0.5f64).sin()).abs() < 1e-12);
    }

    #[test]
    fn a_mirrored_scan_keeps_when_each_beam_was_measured() {
        let mut s = LaserScan {
            first_beam_time: 0.001,
            beam_interval: 0.0001,
            ..LaserScan::default()
        };
        for a in [-1.0, 0.0, 0.5, 1.0] {
            s.beams
                .push(Beam {
                    angle: a,
                    range: 1.0,
                    ..Beam::default()
                })
                .unwrap();
        }
        let before: Vec<f64> = (0..4).map(|i| s.beam_time(i)).collect();
        s.mirror();
        for i in 0..4 {
            assert!((s.beam_time(i) - before[3 - i]).abs() < 1e-15);
        }
    }

    /// The sensor's pose `tau` s after the stamp while it drives at 0.3 m/s
    /// and turns at 0.78 rad/s, in its frame at the stamp.
    fn moving(tau: f64) -> Pose {
        let (v, w) = (0.3, 0.78);
        let th = w * tau;
        crate::geom::pose(v / w * th.sin(), v / w * (1.0 - th.cos()), th)
    }

    #[test]
    fn deskewing_puts_every_beam_where_the_sensor_at_the_stamp_would_see_it() {
        // Points on two walls of a room, seen in the sensor's frame at the
        // stamp; each beam measured 0.1 ms after the one before while moving.
        let truth: Vec<Point2<f64>> = (0..600)
            .map(|k| {
                let a = -2.0 + k as f64 * 0.0066;
                let r = if a < 0.3 {
                    3.0 / a.cos().abs().max(0.2)
                } else {
                    2.5 / a.sin()
                };
                Point2::new(r * a.cos(), r * a.sin())
            })
            .collect();
        let mut scan = LaserScan {
            first_beam_time: 0.0043,
            beam_interval: 0.0001,
            ..LaserScan::default()
        };
        for (i, p) in truth.iter().enumerate() {
            let q = moving(0.0043 + i as f64 * 0.0001).inverse() * p;
            scan.beams
                .push(Beam::hit(q.y.atan2(q.x), q.coords.norm()))
                .unwrap();
        }
        // Taken as measured all at once, the last beams are off by
        // centimetres; deskewed, by nothing.
        let mut raw = Vec::new();
        scan.points_into(&mut raw);
        let worst = |pts: &[IPoint]| {
            pts.iter()
                .zip(&truth)
                .map(|(p, t)| (p.xy() - t).norm())
                .fold(0.0, f64::max)
        };
        assert!(worst(&raw) > 0.05, "{}", worst(&raw));
        scan.deskew(moving);
        let mut fixed = Vec::new();
        scan.points_into(&mut fixed);
        assert!(worst(&fixed) < 1e-9, "{}", worst(&fixed));
        assert_eq!((scan.first_beam_time, scan.beam_interval), (0.0, 0.0));
    }

    #[test]
    fn a_scan_without_beam_timing_is_not_deskewed() {
        let mut s = LaserScan::default();
        s.beams.push(Beam::hit(0.3, 2.0)).unwrap();
        let before = s.beams[0];
        s.deskew(moving);
        assert_eq!(s.beams[0], before);
    }
}
