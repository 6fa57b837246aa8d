//! Segment correction: before a scan is merged, its line features are paired
//! with the map segments they re-observe, and the small rigid motion that best
//! lays them onto those segments is computed. The caller applies it to the
//! scan and feeds it back into the pose, so heading and offset errors do not
//! accumulate along walls.
//!
//! Estimation: the rotation (about the sensor) is the inverse-variance weighted
//! mean of the angle differences; then the translation t minimises
//! Σ w_i (n_iᵀ t − d_i)², with n_i the map segment's normal and d_i the offset
//! of the rotated scan line's centre from it. Directions no segment constrains
//! (e.g. along a corridor) get no translation (a tiny ridge term).

use nalgebra::{Isometry2, Matrix2, Point2, Rotation2, Vector2};

use super::fit::undirected_turn;
use super::lines::ScanLine;
use super::params::MapParams;
use super::segments::SegmentMap;

/// A correction computed from segment pairs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction {
    /// The world-frame motion to apply to the scan (and to its pose): a new pose
    /// is `motion * pose`.
    pub motion: Isometry2<f64>,
    /// Its rotation (rad).
    pub rotation: f64,
    /// Its translation at the sensor (m).
    pub translation: Vector2<f64>,
    /// Number of scan lines paired with map segments.
    pub pairs: usize,
    /// Total length of the paired scan lines (m).
    pub(crate) paired_length: f64,
}

/// What segment correction did for one scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CorrectionOutcome {
    /// Switched off in the settings.
    Disabled,
    /// Not enough paired segment length to estimate anything.
    TooFewPairs {
        /// Paired length found (m).
        paired_length: f64,
    },
    /// Computed but larger than the configured bounds: not applied (the pose is
    /// left as the matcher gave it).
    Refused(Correction),
    /// Computed and applied.
    Applied(Correction),
}

impl CorrectionOutcome {
    /// The applied correction, if any.
    pub fn applied(&self) -> Option<&Correction> {
        match self {
            CorrectionOutcome::Applied(c) => Some(c),
            _ => None,
        }
    }
}

/// Estimates the correction for scan `lines` (world frame, seen from `origin`)
/// against the map's segments. Pairs only with segments seen in ≥ 2 scans.
pub fn estimate(
    lines: &[ScanLine],
    map: &SegmentMap,
    origin: &Point2<f64>,
    p: &MapParams,
) -> CorrectionOutcome {
    if !p.correction {
        return CorrectionOutcome::Disabled;
    }
    let segs = map.segments();
    // Pass 1: rotation.
    let (mut wsum, mut rot, mut length, mut pairs) = (0.0, 0.0, 0.0, 0usize);
    let pair_of = |l: &ScanLine| -> Option<usize> {
        let i = map.find(
            l,
            p.correction_max_angle,
            p.correction_max_distance,
            p.segment_merge_gap,
        )?;
        (segs[i].observations >= 2).then_some(i)
    };
    for l in lines {
        let Some(i) = pair_of(l) else { continue };
        let s = &segs[i];
        let var = l.fit.var_angle + s.fit.var_angle;
        let w = 1.0 / var.max(1e-12);
        rot += w * undirected_turn(&l.fit.dir, &s.fit.dir);
        wsum += w;
        length += l.seg.length();
        pairs += 1;
    }
    if pairs == 0 || length < p.correction_min_length {
        return CorrectionOutcome::TooFewPairs {
            paired_length: length,
        };
    }
    let rotation = rot / wsum;
    let r = Rotation2::new(rotation);
    // Pass 2: translation after the rotation about the sensor.
    let mut a = Matrix2::zeros();
    let mut b = Vector2::zeros();
    for l in lines {
        let Some(i) = pair_of(l) else { continue };
        let s = &segs[i];
        let c = origin + r * (l.fit.centre - origin);
        let n = s.fit.normal();
        let d = -s.fit.offset(&c);
        let w = 1.0 / (l.fit.var_offset + s.fit.var_offset).max(1e-12);
        a += w * n * n.transpose();
        b += w * n * d;
    }
    let ridge = 1e-6 * a.trace().max(1e-12);
    a += Matrix2::identity() * ridge;
    let translation = a.try_inverse().map(|inv| inv * b).unwrap_or_default();
    // p' = R (p − o) + o + t  ⇒  isometry with rotation R and translation o + t − R o.
    let motion = Isometry2::new(origin.coords + translation - r * origin.coords, rotation);
    let c = Correction {
        motion,
        rotation,
        translation,
        pairs,
        paired_length: length,
    };
    if translation.norm() > p.correction_max_translation
        || rotation.abs() > p.correction_max_rotation
        || !translation.iter().all(|v| v.is_finite())
        || !rotation.is_finite()
    {
        CorrectionOutcome::Refused(c)
    } else {
        CorrectionOutcome::Applied(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::IPoint;
    use crate::map::lines::LineExtractor;

    /// Lines of an L-shaped corner (walls y = 0 for x in 0..2 and x = 2 for y in
    /// 0..1.5 of a 2 × 1.5 m room) scanned from (1, 0.8) at uniform beam
    /// steps, seen through `motion` (the scan's pose error).
    fn corner_lines(motion: &Isometry2<f64>) -> Vec<ScanLine> {
        let world = crate::icp::synth::room(2.0, 1.5, 0.5);
        let origin = Point2::new(1.0, 0.8);
        let pts: Vec<IPoint> = (0..470)
            .filter_map(|k| {
                let a = (-139.0 + k as f64 * 0.36f64).to_radians();
                let range = crate::icp::synth::ray(&world, &origin, a, 10.0)?;
                let p = crate::geom::polar(origin, a, range);
                Some(IPoint::new(p.x, p.y, 0.5))
            })
            .collect();
        let moved: Vec<IPoint> = pts.iter().map(|p| p.transformed(motion)).collect();
        let mut ex = LineExtractor::new();
        let (mut lines, mut curves) = (Vec::new(), Vec::new());
        let params = MapParams::default();
        ex.extract(&moved, &(motion * origin), &params, &mut lines, &mut curves);
        assert_eq!(lines.len(), 2, "{lines:?}");
        lines
    }

    #[test]
    fn recovers_a_small_pose_error() {
        let p = MapParams::default();
        let mut map = SegmentMap::default();
        for l in corner_lines(&Isometry2::identity()) {
            map.merge_line(&l, &p);
            map.merge_line(&l, &p);
        }
        let origin = Point2::new(1.0, 0.8);
        let err = Isometry2::new(Vector2::new(0.03, -0.02), 0.02);
        let lines = corner_lines(&err);
        let CorrectionOutcome::Applied(c) = estimate(&lines, &map, &origin, &p) else {
            panic!("not applied");
        };
        assert_eq!(c.pairs, 2);
        let fixed = c.motion * err;
        assert!(fixed.translation.vector.norm() < 1e-6, "{fixed:?}");
        assert!(fixed.rotation.angle().abs() < 1e-6);
    }

    #[test]
    fn refuses_large_and_lacks_pairs() {
        let p = MapParams::default();
        let mut map = SegmentMap::default();
        let origin = Point2::new(1.0, 0.8);
        let lines = corner_lines(&Isometry2::identity());
        assert!(matches!(
            estimate(&lines, &map, &origin, &p),
            CorrectionOutcome::TooFewPairs { .. }
        ));
        for l in &lines {
            map.merge_line(l, &p);
            map.merge_line(l, &p);
        }
        let far = corner_lines(&Isometry2::new(Vector2::new(0.0, 0.09), 0.0));
        let tight = MapParams {
            correction_max_translation: 0.05,
            ..Default::default()
        };
        assert!(matches!(
            estimate(&far, &map, &origin, &tight),
            CorrectionOutcome::Refused(_)
        ));
        let off = MapParams {
            correction: false,
            ..Default::default()
        };
        assert_eq!(
            estimate(&lines, &map, &origin, &off),
            CorrectionOutcome::Disabled
        );
    }
}
