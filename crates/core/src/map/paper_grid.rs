//! The paper's map as the planner sees it (`[map] kind = "paper"`).
//!
//! Every registered scan goes into the paper's [`Map`]: line features,
//! segment correction against the map's walls, the point map with the
//! modified merging rule, the wall segments, and the explored-area grid,
//! all in the corrected frame. The planner and the decomposer work on
//! grids, so the map is handed on as its explored-area grid with the wall
//! segments of the newest snapshot drawn in: a segment closes a wall
//! where the beams left gaps (seen at a grazing angle, or not seen yet
//! beyond its end), and its end points are where the walls, and so the
//! sweep line's events, end. A cell rays have seen free and no beam ever
//! ended in stays free: a segment is a fit, and one fitted a hair off a
//! wall must not narrow the floor beside it.
//!
//! The correction moves the map, not the robot: the pose estimate stays
//! the matcher's (the localise stage has handed it on by then). Each
//! scan's correction is its own (the map takes the matcher's pose anew
//! every scan), so map and robot differ by at most
//! `correction_max_translation`; [`CorrectionTally`] says by how much.

use nalgebra::Point2;

use super::{CorrectionOutcome, Map, MapError, MapParams, ScanQuality, UpdateReport};
use crate::geom::{Pose, Segment};
use crate::grid::{CellState, Grid};
use crate::scan::LaserScan;

/// What the segment correction did over a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CorrectionTally {
    /// Scans merged.
    pub scans: u64,
    /// Scans whose lines were aligned to the map's walls.
    pub applied: u64,
    /// Scans whose correction came out larger than the bounds (not applied).
    pub refused: u64,
    /// Sum of the applied corrections' translations (m).
    pub translation_sum: f64,
    /// Largest applied translation (m).
    pub translation_max: f64,
    /// Largest applied rotation (rad, absolute).
    pub rotation_max: f64,
}

impl CorrectionTally {
    fn note(&mut self, outcome: Option<CorrectionOutcome>) {
        self.scans += 1;
        match outcome {
            Some(CorrectionOutcome::Applied(c)) => {
                let t = c.translation.norm();
                self.applied += 1;
                self.translation_sum += t;
                self.translation_max = self.translation_max.max(t);
                self.rotation_max = self.rotation_max.max(c.rotation.abs());
            }
            Some(CorrectionOutcome::Refused(_)) => self.refused += 1,
            _ => {}
        }
    }

    /// Mean translation of the applied corrections (m; 0 with none).
    pub fn translation_mean(&self) -> f64 {
        if self.applied == 0 {
            0.0
        } else {
            self.translation_sum / self.applied as f64
        }
    }
}

/// The paper's map and the grid the planner gets from it.
#[derive(Debug)]
pub struct PaperGrid {
    map: Map,
    tally: CorrectionTally,
}

impl PaperGrid {
    /// An empty paper map starting at `start` over `grid` (its geometry,
    /// and the evidence to start from: empty for a fresh run, a resumed
    /// run's grid otherwise; the points and segments start empty).
    pub fn new(params: MapParams, start: Pose, grid: Grid) -> Result<Self, MapError> {
        Ok(Self {
            map: Map::with_grid(params, start, grid)?,
            tally: CorrectionTally::default(),
        })
    }

    /// Merges one registered scan (sensor frame) taken at `pose` (the
    /// sensor's pose in the world).
    pub fn merge(&mut self, scan: &LaserScan, pose: &Pose) -> Result<UpdateReport, MapError> {
        let r = self.map.update(scan, pose, ScanQuality::Good)?;
        self.tally.note(r.correction);
        Ok(r)
    }

    /// Makes `out` the grid the planner plans on: the map's explored-area
    /// grid with the newest snapshot's wall segments drawn in (see the
    /// module docs). Allocates nothing when `out` has the map grid's size.
    pub fn render_into(&self, out: &mut Grid) {
        out.copy_from(self.map.grid());
        let snap = self.map.snapshot();
        for w in &snap.walls {
            draw_wall(out, w);
        }
    }

    /// The paper's map.
    pub fn map(&self) -> &Map {
        &self.map
    }

    /// What the segment correction did so far.
    pub fn tally(&self) -> CorrectionTally {
        self.tally
    }

    /// Bytes the map holds: its points, its segments and its explored-area
    /// grid (the planner's grid rendered from it is the caller's).
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of_val(self.map.points())
            + std::mem::size_of_val(self.map.segment_map().segments())
            + self.map.grid().memory_bytes()
    }
}

/// Marks occupied every cell along `w` (sampled at a quarter cell) that is
/// unknown or where a beam has ended; cells seen free and never hit stay so.
fn draw_wall(out: &mut Grid, w: &Segment) {
    let step = out.resolution() / 4.0;
    let len = (w.b - w.a).norm();
    if !len.is_finite() {
        return;
    }
    let n = (len / step).ceil().max(1.0) as usize;
    for i in 0..=n {
        let p: Point2<f64> = w.a + (w.b - w.a) * (i as f64 / n as f64);
        let Some(c) = out.cell_of(&p) else {
            continue;
        };
        let solid = match out.state(c) {
            CellState::Unknown => true,
            CellState::Occupied => false,
            CellState::Free => out.was_hit(c),
        };
        if solid {
            out.set_state(c, CellState::Occupied);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    /// A scan from `at` (heading 0) of a room `[0, 4] × [0, 3]`, 1° steps.
    fn room_scan(at: Point2<f64>) -> LaserScan {
        crate::icp::synth::laser_scan(&crate::icp::synth::room(4.0, 3.0, 1.0), &at, 360)
    }

    fn grid() -> Grid {
        Grid::new(Point2::new(-0.475, -0.475), 0.05, 100, 80)
    }

    #[test]
    fn walls_close_what_the_beams_left_open_and_free_floor_stays_free() {
        let mut pg = PaperGrid::new(MapParams::default(), pose(2.0, 1.5, 0.0), grid()).unwrap();
        for k in 0..6 {
            let at = Point2::new(1.8 + 0.08 * k as f64, 1.5);
            pg.merge(&room_scan(at), &pose(at.x, at.y, 0.0)).unwrap();
        }
        assert!(
            pg.map().snapshot().walls.len() >= 4,
            "the room's four walls"
        );
        let mut out = grid();
        pg.render_into(&mut out);
        let (_, free, occupied) = out.counts();
        let (_, free0, occupied0) = pg.map().grid().counts();
        assert!(occupied >= occupied0, "{occupied} < {occupied0}");
        assert!(free + occupied >= free0 + occupied0);
        // The floor beside the walls is still free; the wall cells are not.
        for (x, y) in [(0.1, 1.5), (3.9, 1.5), (2.0, 0.1), (2.0, 2.9)] {
            let c = out.cell_of(&Point2::new(x, y)).unwrap();
            assert_eq!(out.state(c), CellState::Free, "({x}, {y})");
        }
        for (x, y) in [(-0.01, 1.5), (4.01, 1.5), (2.0, -0.01), (2.0, 3.01)] {
            let c = out.cell_of(&Point2::new(x, y)).unwrap();
            assert_eq!(out.state(c), CellState::Occupied, "({x}, {y})");
        }
        let t = pg.tally();
        assert_eq!(t.scans, 6);
        assert!(t.translation_max <= 0.01, "{t:?}");
        assert!(pg.memory_bytes() > pg.map().grid().memory_bytes());
        assert_eq!(grid().memory_bytes(), 100 * 80 * 5);
    }

    #[test]
    fn a_wall_is_drawn_through_unknown_cells_but_not_over_free_ones() {
        let mut out = grid();
        let row = |x: f64| out.cell_of(&Point2::new(x, 1.0)).unwrap();
        let seen_free = row(1.0);
        out.set_state(seen_free, CellState::Free);
        draw_wall(
            &mut out,
            &Segment::new(Point2::new(0.5, 1.0), Point2::new(1.5, 1.0)),
        );
        assert_eq!(out.state(seen_free), CellState::Free);
        let c = out.cell_of(&Point2::new(0.6, 1.0)).unwrap();
        assert_eq!(out.state(c), CellState::Occupied);
        let not_a_number = Segment::new(Point2::new(f64::NAN, 1.0), Point2::new(1.5, 1.0));
        draw_wall(&mut out, &not_a_number);
    }

    #[test]
    fn a_non_finite_pose_is_an_error_not_a_panic() {
        let mut pg = PaperGrid::new(MapParams::default(), pose(2.0, 1.5, 0.0), grid()).unwrap();
        let e = pg.merge(&room_scan(Point2::new(2.0, 1.5)), &pose(f64::NAN, 0.0, 0.0));
        assert!(matches!(e, Err(MapError::NonFinitePose(_))));
        assert_eq!(pg.tally().scans, 0);
    }
}
