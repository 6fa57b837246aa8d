//! The laser scan as algorithms see it: beams with their angle already computed
//! from the sensor's own parameters, ranges in metres, a validity flag, and a
//! timestamp on the daemon's monotonic clock. Fixed capacity, no heap.

use crate::capacity::MAX_BEAMS;
use crate::geom::IPoint;

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
            s.beams
                .push(Beam {
                    angle: a,
                    range: r,
                    intensity: 0.0,
                    valid: true,
                })
                .unwrap();
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
}
