//! The map frame turned to the room at a fresh start. The daemon's map frame
//! is the robot's pose when it was switched on, so a robot put down at 20°
//! to the walls would see a room at 20° in its grid; the decomposition and
//! the lanes run along the grid axes, and would cross such a room in steps.
//! Before tracking starts, the line features of the first scan give the
//! dominant wall direction (modulo 90°), and the start heading is turned by
//! the least angle that puts those walls along the axes. The start position
//! stays where it is. A resumed run keeps its checkpointed frame.

use crate::decomp::direction::{from_segments, AxisEstimate};
use crate::geom::{wrap_angle, IPoint, Segment};
use crate::map::lines::{Curve, LineExtractor, ScanLine};
use crate::map::params::MapParams;

/// Least length (m) of the first scan's line features within
/// `INLIER_BAND` of the axes found.
pub const MIN_WALL_EVIDENCE: f64 = 3.0;

/// Least share of the line features' length within `INLIER_BAND` of the
/// axes found: below it the scan sees no rectilinear room (clutter, walls
/// at several angles).
pub const MIN_AGREEMENT: f64 = 0.7;

/// Lines within this angle (rad) of the axes, modulo 90°, count as walls
/// along them: the axes are re-estimated from these alone, so that clutter
/// at other angles does not pull them.
pub(crate) const INLIER_BAND: f64 = 8.0 * std::f64::consts::PI / 180.0;

/// Re-estimations of the axes from the lines within [`INLIER_BAND`].
const REFINE_ROUNDS: usize = 3;

/// Scans tried before the frame is left as it is.
pub const MAX_ALIGN_SCANS: u32 = 20;

/// What the first scans say about the walls' direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlignStep {
    /// Turn the start heading by `turn` (rad, in (-π/4, π/4]): `evidence`
    /// metres of wall lines, the share `agreement` of all, lie along the
    /// axes found.
    Turn {
        /// Rotation added to the start heading (rad).
        turn: f64,
        /// Length of the wall lines along the axes (m).
        evidence: f64,
        /// Their share of all line features' length, 0..=1.
        agreement: f64,
    },
    /// This scan says too little; wait for the next.
    NotYet,
    /// [`MAX_ALIGN_SCANS`] scans said too little: keep the frame.
    GiveUp,
}

/// Finds the wall direction in the first scans (reused buffers).
pub struct WallAlign {
    params: MapParams,
    extractor: LineExtractor,
    lines: Vec<ScanLine>,
    curves: Vec<Curve>,
    segments: Vec<Segment>,
    inliers: Vec<Segment>,
    scans: u32,
}

impl Default for WallAlign {
    fn default() -> Self {
        Self::new()
    }
}

impl WallAlign {
    /// An aligner with the map's default line-feature settings.
    pub fn new() -> Self {
        Self {
            params: MapParams::default(),
            extractor: LineExtractor::new(),
            lines: Vec::new(),
            curves: Vec::new(),
            segments: Vec::new(),
            inliers: Vec::new(),
            scans: 0,
        }
    }

    /// The dominant wall axis of one scan's `points` (scanner frame, beam
    /// order), re-estimated from the lines within [`INLIER_BAND`] of it,
    /// with the length (m) and the share of the lines that agree with it;
    /// `None` without line features.
    pub(crate) fn wall_axis(&mut self, points: &[IPoint]) -> Option<(AxisEstimate, f64)> {
        let origin = nalgebra::Point2::origin();
        self.extractor.extract(
            points,
            &origin,
            &self.params,
            &mut self.lines,
            &mut self.curves,
        );
        self.segments.clear();
        self.segments.extend(self.lines.iter().map(|l| l.seg));
        let all = from_segments(&self.segments)?;
        let mut axis = all;
        for _ in 0..REFINE_ROUNDS {
            let near = |s: &&Segment| turn_to_axes(s.angle() - axis.angle).abs() <= INLIER_BAND;
            self.inliers.clear();
            self.inliers.extend(self.segments.iter().filter(near));
            match from_segments(&self.inliers) {
                Some(a) => axis = a,
                None => break,
            }
        }
        // `evidence` is the inliers' length around the final angle.
        let near = |s: &&Segment| turn_to_axes(s.angle() - axis.angle).abs() <= INLIER_BAND;
        axis.evidence = self.segments.iter().filter(near).map(Segment::length).sum();
        Some((axis, axis.evidence / all.evidence))
    }

    /// Looks at one more scan taken with the scanner at `heading` (rad, in
    /// the map frame): how far to turn the frame, or wait, or give up.
    pub fn step(&mut self, points: &[IPoint], heading: f64) -> AlignStep {
        self.scans += 1;
        if let Some((axis, agreement)) = self.wall_axis(points) {
            if axis.evidence >= MIN_WALL_EVIDENCE && agreement >= MIN_AGREEMENT {
                return AlignStep::Turn {
                    turn: turn_to_axes(heading + axis.angle),
                    evidence: axis.evidence,
                    agreement,
                };
            }
        }
        if self.scans >= MAX_ALIGN_SCANS {
            AlignStep::GiveUp
        } else {
            AlignStep::NotYet
        }
    }
}

/// The least rotation (rad, in (-π/4, π/4]) that brings a direction at
/// `angle` onto one of the axes.
pub fn turn_to_axes(angle: f64) -> f64 {
    let q = std::f64::consts::FRAC_PI_2;
    let r = wrap_angle(angle).rem_euclid(q);
    if r > q / 2.0 {
        q - r
    } else {
        -r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;
    use crate::icp::synth::{cast, room, ScanSpec, Wall};
    use std::f64::consts::FRAC_PI_6;

    fn scan_in_room(walls: &[Wall], x: f64, y: f64, heading_deg: f64) -> Vec<IPoint> {
        cast(
            walls,
            &pose(x, y, heading_deg.to_radians()),
            &ScanSpec::default(),
        )
    }

    #[test]
    fn the_turn_puts_a_direction_on_the_nearest_axis() {
        for (a, t) in [
            (0.0, 0.0),
            (20.0, -20.0),
            (-20.0, 20.0),
            (70.0, 20.0),
            (110.0, -20.0),
            (-135.0 + 1.0, -46.0 + 90.0),
            (200.0, -20.0),
        ] {
            let got = turn_to_axes(f64::to_radians(a)).to_degrees();
            assert!((got - t).abs() < 1e-9, "{a}°: {got}° (want {t}°)");
        }
    }

    #[test]
    fn a_robot_put_down_at_an_angle_gets_a_frame_along_the_walls() {
        let walls = room(6.5, 4.1, 0.5);
        for (h, seed) in [(20.0, 1), (-33.0, 2), (52.0, 3), (0.0, 4), (90.0, 5)] {
            let pts = cast(
                &walls,
                &pose(2.0, 1.5, f64::to_radians(h)),
                &ScanSpec {
                    seed,
                    ..ScanSpec::default()
                },
            );
            let mut a = WallAlign::new();
            // The frame believes the robot starts at heading 0: the walls
            // are seen at -h; the turn must give them back their true
            // direction modulo 90°.
            match a.step(&pts, 0.0) {
                AlignStep::Turn {
                    turn,
                    evidence,
                    agreement,
                } => {
                    let residual = turn_to_axes(turn - f64::to_radians(h)).to_degrees();
                    assert!(residual.abs() < 0.3, "{h}°: turn {}°", turn.to_degrees());
                    assert!(evidence > 5.0 && agreement > 0.95, "{evidence} {agreement}");
                }
                s => panic!("{h}°: {s:?}"),
            }
        }
    }

    #[test]
    fn a_scan_without_a_rectilinear_room_waits_then_gives_up() {
        // Walls every 30°: no axis pair dominates.
        let walls: Vec<Wall> = (0..12)
            .map(|k| {
                let (a0, a1) = (f64::from(k) * FRAC_PI_6, f64::from(k + 1) * FRAC_PI_6);
                Wall::new(
                    3.0 * a0.cos(),
                    3.0 * a0.sin(),
                    3.0 * a1.cos(),
                    3.0 * a1.sin(),
                    0.5,
                )
            })
            .collect();
        let pts = scan_in_room(&walls, 0.0, 0.0, 7.0);
        let mut a = WallAlign::new();
        for _ in 1..MAX_ALIGN_SCANS {
            assert_eq!(a.step(&pts, 0.0), AlignStep::NotYet);
        }
        assert_eq!(a.step(&pts, 0.0), AlignStep::GiveUp);
        // Nothing seen at all: the same.
        let mut b = WallAlign::new();
        assert_eq!(b.step(&[], 0.0), AlignStep::NotYet);
    }
}
