//! The online map: the paper's sparse point map with its modified merging
//! rule, line features with segment correction, and the explored-area grid.
//!
//! The pipeline calls [`Map::update`] (absolute pose from the matcher) or
//! [`Map::update_with_increment`] (the paper's equation 3) once per registered
//! scan. One update:
//!
//! 1. drops beams that are invalid, non-finite or outside
//!    `min_range..max_range`, and places the rest in the world frame;
//! 2. extracts line features and curves ([`lines`]);
//! 3. aligns those lines to the map's segments and applies the correction to
//!    the scan and the pose ([`correction`]);
//! 4. merges the points with the modified merging rule ([`points`]);
//! 5. merges the lines into map segments and the curves into the curve list
//!    ([`segments`]);
//! 6. integrates every beam into the explored-area grid ([`crate::grid`]);
//! 7. every `publish_every` merged scans, publishes a [`PointMapSnapshot`]
//!    ([`snapshot`]).
//!
//! A scan the matcher flags as badly registered ([`ScanQuality::Bad`]) moves
//! the pose but changes nothing in the map.
//!
//! Allocation in steady state: none in steps 1-6 except growth of the point
//! store and its hash index (amortised, reserved up front for
//! `reserve_points`), of the segment list when a new wall appears, of the
//! curve list (bounded by `segments::MAX_CURVES`) and of the trajectory
//! (one pose per 5 cm or 0.1 rad driven). Publication reuses the buffers of the snapshot
//! before last when no reader holds it any more, else builds a new one.

pub mod correction;
pub mod fit;
pub mod lines;
mod paper_grid;
pub mod params;
pub mod points;
pub mod pose;
pub mod segments;
pub mod snapshot;
pub mod svg;

use std::sync::Arc;

use nalgebra::{Point2, Vector2};

pub use correction::{Correction, CorrectionOutcome};
pub use lines::{Curve, LineExtractor, ScanLine};
pub use paper_grid::{CorrectionTally, PaperGrid};
pub use params::{MapKind, MapParams};
pub use points::{MergeCounts, PointMap};
pub use pose::compose_increment;
pub use segments::{MapSegment, SegmentMap};
pub use snapshot::{PointMapSnapshot, SnapshotCell};

use crate::capacity::MAX_BEAMS;
use crate::geom::{IPoint, Pose};
use crate::grid::Grid;
use crate::param_check::ParamError;
use crate::scan::LaserScan;

/// The trajectory keeps a pose once the robot has moved this far (m) ...
const TRAJECTORY_STEP: f64 = 0.05;
/// ... or turned this much (rad) since the last kept pose: it grows with the
/// path driven, not with time standing still.
const TRAJECTORY_TURN: f64 = 0.1;

/// Segments the map reserves room for up front.
const RESERVE_SEGMENTS: usize = 1024;

/// The matcher's verdict on a scan's registration, as the map needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScanQuality {
    /// The pose can be trusted: merge the scan.
    Good,
    /// The matcher flagged a bad match: keep the pose, merge nothing.
    Bad,
}

/// Why the map refused an update.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    /// The pose (or increment) holds NaN or infinity.
    #[error("map update refused: the pose is not finite ({0:?})")]
    NonFinitePose(Pose),
    /// The settings are out of range.
    #[error("map settings: {0}")]
    Params(#[from] ParamError),
}

/// What one update did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UpdateReport {
    /// The pose after the update (corrected when a correction was applied).
    pub pose: Pose,
    /// Whether the scan was merged (false for [`ScanQuality::Bad`]).
    pub merged: bool,
    /// Segment correction outcome (`None` when the scan was not merged).
    pub correction: Option<CorrectionOutcome>,
    /// Point merge counts.
    pub counts: MergeCounts,
    /// Beams dropped: invalid, non-finite, or outside `min_range..max_range`.
    pub rejected_beams: usize,
    /// Line features found in the scan.
    pub lines: usize,
    /// Curves found in the scan.
    pub(crate) curves: usize,
    /// Points stored after the update.
    pub points_total: usize,
    /// Map segments after the update.
    pub segments_total: usize,
    /// Whether a new snapshot was published.
    pub published: bool,
}

/// The online map (the writer side). Readers get snapshots through
/// [`Map::reader`].
#[derive(Debug)]
pub struct Map {
    params: MapParams,
    points: PointMap,
    segments: SegmentMap,
    grid: Grid,
    pose: Pose,
    trajectory: Vec<Pose>,
    scans_seen: u64,
    scans_merged: u64,
    world: Vec<IPoint>,
    tangents: Vec<Vector2<f64>>,
    keep: Vec<bool>,
    extractor: LineExtractor,
    lines: Vec<ScanLine>,
    curves: Vec<Curve>,
    cell: Arc<SnapshotCell>,
    spare: Option<Arc<PointMapSnapshot>>,
    snap_index: segments::SnapIndex,
    version: u64,
}

impl Map {
    /// An empty map whose robot starts at `start`; the explored-area grid is
    /// centred there.
    pub fn new(params: MapParams, start: Pose) -> Result<Map, MapError> {
        let centre = Point2::from(start.translation.vector);
        let grid = Grid::centred(centre, params.grid_extent, params.grid_resolution);
        Self::with_grid(params, start, grid)
    }

    /// An empty map whose robot starts at `start`, its explored-area grid
    /// `grid` (the caller's geometry, and evidence to start from: a resumed
    /// run's grid); `grid_extent` and `grid_resolution` are not used.
    pub fn with_grid(params: MapParams, start: Pose, grid: Grid) -> Result<Map, MapError> {
        params.validate()?;
        if !pose::pose_is_finite(&start) {
            return Err(MapError::NonFinitePose(start));
        }
        let first = Arc::new(PointMapSnapshot::empty(grid.clone(), start));
        Ok(Map {
            points: PointMap::new(params.merge_distance, params.reserve_points),
            segments: SegmentMap::with_capacity(RESERVE_SEGMENTS),
            grid,
            pose: start,
            trajectory: Vec::with_capacity(4096),
            scans_seen: 0,
            scans_merged: 0,
            world: Vec::with_capacity(MAX_BEAMS),
            tangents: Vec::with_capacity(MAX_BEAMS),
            keep: Vec::with_capacity(MAX_BEAMS),
            extractor: LineExtractor::new(),
            lines: Vec::with_capacity(MAX_BEAMS / 4),
            curves: Vec::with_capacity(MAX_BEAMS / 4),
            cell: Arc::new(SnapshotCell::new(first)),
            spare: None,
            snap_index: segments::SnapIndex::default(),
            version: 0,
            params,
        })
    }

    /// The settings.
    pub fn params(&self) -> &MapParams {
        &self.params
    }

    /// The current pose (after the last update).
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// The stored points (what the matcher uses as its reference set).
    pub fn points(&self) -> &[IPoint] {
        self.points.points()
    }

    /// The segments and curves.
    pub fn segment_map(&self) -> &SegmentMap {
        &self.segments
    }

    /// The explored-area grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Poses of the merged scans, one kept every 5 cm or 0.1 rad of motion.
    pub fn trajectory(&self) -> &[Pose] {
        &self.trajectory
    }

    /// Scans offered to the map, and scans merged.
    pub fn scan_counts(&self) -> (u64, u64) {
        (self.scans_seen, self.scans_merged)
    }

    /// The points of the last merged scan (world frame, corrected), in beam order.
    pub fn last_points(&self) -> &[IPoint] {
        &self.world
    }

    /// The shared cell readers load snapshots from (clone the `Arc` per thread).
    pub fn reader(&self) -> Arc<SnapshotCell> {
        Arc::clone(&self.cell)
    }

    /// The newest published snapshot.
    pub fn snapshot(&self) -> Arc<PointMapSnapshot> {
        self.cell.load()
    }

    /// The paper's equation 3: the pose becomes the current pose composed with
    /// `increment` (ΔX, ΔY, Δθ in the robot frame), then the scan is merged as
    /// in [`update`](Self::update).
    pub fn update_with_increment(
        &mut self,
        scan: &LaserScan,
        increment: &Pose,
        quality: ScanQuality,
    ) -> Result<UpdateReport, MapError> {
        if !pose::pose_is_finite(increment) {
            return Err(MapError::NonFinitePose(*increment));
        }
        let p = compose_increment(&self.pose, increment);
        self.update(scan, &p, quality)
    }

    /// Merges one scan (sensor frame) registered at `pose` (the sensor's pose
    /// in the world). See the module docs for the steps.
    pub fn update(
        &mut self,
        scan: &LaserScan,
        pose: &Pose,
        quality: ScanQuality,
    ) -> Result<UpdateReport, MapError> {
        if !pose::pose_is_finite(pose) {
            return Err(MapError::NonFinitePose(*pose));
        }
        self.scans_seen += 1;
        let mut report = UpdateReport {
            pose: *pose,
            merged: false,
            correction: None,
            counts: MergeCounts::default(),
            rejected_beams: 0,
            lines: 0,
            curves: 0,
            points_total: self.points.len(),
            segments_total: self.segments.segments().len(),
            published: false,
        };
        self.pose = *pose;
        if quality == ScanQuality::Bad {
            return Ok(report);
        }
        let p = &self.params;
        // 1. Points in the world frame.
        self.world.clear();
        for b in &scan.beams {
            let ok = b.valid
                && b.range.is_finite()
                && b.angle.is_finite()
                && b.intensity.is_finite()
                && b.range >= p.min_range
                && b.range <= p.max_range;
            if !ok {
                report.rejected_beams += 1;
                continue;
            }
            let (s, c) = b.angle.sin_cos();
            self.world
                .push(IPoint::new(b.range * c, b.range * s, b.intensity).transformed(pose));
        }
        // 2. Line features.
        let mut origin = Point2::from(pose.translation.vector);
        self.extractor
            .extract(&self.world, &origin, p, &mut self.lines, &mut self.curves);
        // 3. Segment correction.
        let outcome = correction::estimate(&self.lines, &self.segments, &origin, p);
        let mut corrected = *pose;
        if let CorrectionOutcome::Applied(c) = outcome {
            corrected = c.motion * pose;
            for q in &mut self.world {
                *q = q.transformed(&c.motion);
            }
            for l in &mut self.lines {
                *l = l.transformed(&c.motion);
            }
            for cv in &mut self.curves {
                *cv = cv.transformed(&c.motion);
            }
            origin = Point2::from(corrected.translation.vector);
        }
        // 4. Points, with the surface direction at each.
        estimate_tangents(
            &self.world,
            self.extractor.clusters(),
            &origin,
            p.merge_distance,
            &mut self.tangents,
        );
        for l in &self.lines {
            for t in &mut self.tangents[l.first..=l.last] {
                *t = l.fit.dir;
            }
        }
        report.counts = self.points.merge(
            &self.world,
            &self.tangents,
            p.merge_distance,
            p.min_spacing,
            &mut self.keep,
        );
        // 5. Segments and curves.
        for l in &self.lines {
            self.segments.merge_line(l, p);
        }
        for c in &self.curves {
            self.segments.merge_curve(c, p.segment_merge_distance);
        }
        // 6. Explored-area grid.
        integrate_grid(&mut self.grid, scan, &corrected, p);
        self.pose = corrected;
        let moved = self.trajectory.last().is_none_or(|last| {
            let (t, r) = pose::motion_size(&pose::increment_between(last, &corrected));
            t >= TRAJECTORY_STEP || r >= TRAJECTORY_TURN
        });
        if moved {
            self.trajectory.push(corrected);
        }
        self.scans_merged += 1;
        report.pose = corrected;
        report.merged = true;
        report.correction = Some(outcome);
        report.lines = self.lines.len();
        report.curves = self.curves.len();
        report.points_total = self.points.len();
        report.segments_total = self.segments.segments().len();
        // 7. Publication.
        if self.scans_merged == 1 || self.scans_merged.is_multiple_of(u64::from(p.publish_every)) {
            self.publish();
            report.published = true;
        }
        Ok(report)
    }

    /// Builds a snapshot of the current map and makes it the newest one.
    pub fn publish(&mut self) {
        self.version += 1;
        let reusable = self
            .spare
            .take()
            .filter(|a| Arc::strong_count(a) == 1 && Arc::weak_count(a) == 0);
        let mut arc = reusable.unwrap_or_else(|| {
            Arc::new(PointMapSnapshot::empty(
                Grid::new(self.grid.origin(), self.grid.resolution(), 0, 0),
                self.pose,
            ))
        });
        let snap = match Arc::get_mut(&mut arc) {
            Some(s) => s,
            None => {
                arc = Arc::new(PointMapSnapshot::empty(self.grid.clone(), self.pose));
                // A fresh Arc has no other owner.
                match Arc::get_mut(&mut arc) {
                    Some(s) => s,
                    None => return,
                }
            }
        };
        // Reserve what the map itself holds, so a reused snapshot grows only
        // when the map's own buffers did.
        snap.points.clear();
        snap.points.reserve(self.points.capacity());
        snap.segments.clear();
        snap.segments.reserve(self.segments.capacity());
        snap.walls.clear();
        snap.walls.reserve(self.segments.capacity());
        snap.curves.clear();
        snap.curves.reserve(segments::MAX_CURVES);
        snap.trajectory.clear();
        snap.trajectory.reserve(self.trajectory.capacity());
        snap.version = self.version;
        snap.scans_merged = self.scans_merged;
        snap.points.clear();
        snap.points.extend_from_slice(self.points.points());
        self.segments.snapped_into(
            self.params.segment_merge_gap,
            self.params.min_segment_observations,
            self.params.max_segment_angle_sigma,
            &mut self.snap_index,
            &mut snap.segments,
        );
        snap.walls.extend(snap.segments.iter().map(|s| s.seg));
        snap.curves.clear();
        snap.curves.extend_from_slice(self.segments.curves());
        snap.grid.copy_from(&self.grid);
        snap.pose = self.pose;
        snap.trajectory.clear();
        snap.trajectory.extend_from_slice(&self.trajectory);
        self.spare = Some(self.cell.store(arc));
    }
}

/// Surface direction at each point: the chord between the farthest points of
/// the same cluster within `reach` on either side; for an isolated point, the
/// direction across the beam.
fn estimate_tangents(
    pts: &[IPoint],
    clusters: &[(usize, usize)],
    origin: &Point2<f64>,
    reach: f64,
    out: &mut Vec<Vector2<f64>>,
) {
    out.clear();
    out.resize(pts.len(), Vector2::new(1.0, 0.0));
    let r2 = reach * reach;
    for &(a, b) in clusters {
        for i in a..=b {
            let c = pts[i].xy();
            let near = |j: usize| (pts[j].xy() - c).norm_squared() <= r2;
            let mut l = i;
            while l > a && near(l - 1) {
                l -= 1;
            }
            let mut r = i;
            while r < b && near(r + 1) {
                r += 1;
            }
            let chord = pts[r].xy() - pts[l].xy();
            out[i] = if r > l && chord.norm() > 1e-9 {
                chord.normalize()
            } else {
                let beam = c - origin;
                let n = beam.norm();
                if n > 1e-9 {
                    Vector2::new(-beam.y, beam.x) / n
                } else {
                    Vector2::new(1.0, 0.0)
                }
            };
        }
    }
}

/// Integrates every beam of `scan` (sensor frame) seen from `pose` into the
/// grid: free along the beam and occupied at the hit for accepted beams; free
/// up to `free_clear_range` (or the beam's length, when shorter) and nothing
/// occupied for no-return or too-long beams; nothing for other invalid beams.
fn integrate_grid(grid: &mut Grid, scan: &LaserScan, pose: &Pose, p: &MapParams) {
    let from = Point2::from(pose.translation.vector);
    for b in &scan.beams {
        if !b.angle.is_finite() || b.range.is_nan() {
            continue;
        }
        let long = b.range > p.max_range;
        let (len, hit) = if b.valid && !long && b.range >= p.min_range && b.range.is_finite() {
            (b.range, true)
        } else if long {
            (b.range.min(p.free_clear_range), false)
        } else {
            continue;
        };
        let (s, c) = b.angle.sin_cos();
        let to = pose * Point2::new(len * c, len * s);
        grid.integrate_ray(&from, &to, hit);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose as mk;
    use crate::scan::Beam;

    fn ring_scan(r: f64) -> LaserScan {
        let mut s = LaserScan::default();
        for i in 0..360 {
            let _ = s.beams.push(Beam {
                angle: (i as f64).to_radians() - std::f64::consts::PI,
                range: r,
                intensity: 0.5,
                valid: true,
            });
        }
        s
    }

    #[test]
    fn equation_3_drives_the_pose() {
        let mut m = Map::new(MapParams::default(), mk(1.0, 1.0, 0.5)).unwrap();
        let s = ring_scan(2.0);
        let r = m
            .update_with_increment(&s, &mk(0.2, 0.0, 0.1), ScanQuality::Bad)
            .unwrap();
        assert!(!r.merged);
        let want = mk(1.0, 1.0, 0.5) * mk(0.2, 0.0, 0.1);
        assert!((m.pose().translation.vector - want.translation.vector).norm() < 1e-12);
        assert!(m.points().is_empty());
        let e = m.update_with_increment(&s, &mk(f64::NAN, 0.0, 0.0), ScanQuality::Good);
        assert!(matches!(e, Err(MapError::NonFinitePose(_))));
    }

    #[test]
    fn standing_still_does_not_grow_the_trajectory() {
        let params = MapParams {
            correction: false,
            ..Default::default()
        };
        let mut m = Map::new(params, mk(1.0, 1.0, 0.0)).unwrap();
        let s = ring_scan(2.0);
        for _ in 0..5 {
            m.update(&s, &mk(1.0, 1.0, 0.0), ScanQuality::Good).unwrap();
        }
        assert_eq!(m.trajectory().len(), 1);
        m.update(&s, &mk(1.06, 1.0, 0.0), ScanQuality::Good)
            .unwrap();
        m.update(&s, &mk(1.06, 1.0, 0.15), ScanQuality::Good)
            .unwrap();
        assert_eq!(m.trajectory().len(), 3);
        assert_eq!(m.scan_counts(), (7, 7));
    }

    #[test]
    fn bad_params_are_refused() {
        let e = Map::new(
            MapParams {
                merge_distance: 0.0,
                ..Default::default()
            },
            Pose::identity(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("map.merge_distance"), "{e}");
    }

    #[test]
    fn long_beams_clear_but_do_not_occupy() {
        let p = MapParams::default();
        let mut m = Map::new(p.clone(), Pose::identity()).unwrap();
        let mut s = LaserScan::default();
        let _ = s.beams.push(Beam {
            angle: 0.0,
            range: f64::INFINITY,
            intensity: 0.0,
            valid: false,
        });
        let _ = s.beams.push(Beam {
            angle: 1.0,
            range: 0.0,
            intensity: 0.0,
            valid: false,
        });
        let r = m.update(&s, &Pose::identity(), ScanQuality::Good).unwrap();
        assert_eq!(r.rejected_beams, 2);
        assert_eq!(r.counts.kept, 0);
        let (_, free, occ) = m.grid().counts();
        assert_eq!(occ, 0);
        let expect = (p.free_clear_range / p.grid_resolution) as usize;
        assert!(free + 2 >= expect && free <= expect + 2, "{free}");
    }
}
