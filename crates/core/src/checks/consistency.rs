//! Whether a matched scan agrees with the map: a match can pass every check
//! of its own (residual, inliers, correction) at a wrong place that looks
//! locally alike, the typical end of a kidnap (a robot carried elsewhere,
//! the match drawn onto look-alike walls near where the wheels say it is).
//! The map says otherwise: at a wrong pose many of the scan's end points
//! fall on floor the map has seen free many times over, where no wall can
//! be. The localise stage treats such a match as no match (see
//! `daemon.lost_after`).

use nalgebra::Point2;

use crate::geom::{IPoint, Pose};
use crate::grid::Grid;

/// Highest raw evidence (see [`Grid::evidence`]) of a cell the map holds
/// as surely free: five beams' worth of misses below neutral, net of hits.
pub const SURELY_FREE: u8 = 88;

/// Share of a scan's end points on surely free floor above which the scan
/// contradicts the map. A right match puts its end points on walls or in
/// the cells beside them; a person in the room covers a tenth of a scan
/// or less.
pub const CONTRADICTION: f64 = 0.3;

/// End points on known floor needed before the share means anything.
pub const MIN_KNOWN: usize = 40;

/// The share of `points` (scanner frame; their end points) that fall, with
/// the scanner at `pose` in the grid's frame, in a cell which, with all
/// eight of its neighbours, the grid holds as surely free; among the end
/// points that fall on observed cells. `None` when fewer than
/// [`MIN_KNOWN`] do (a fresh map).
pub fn free_share(grid: &Grid, points: &[IPoint], pose: &Pose) -> Option<f64> {
    let (w, h) = (grid.width(), grid.height());
    let surely_free = |x: usize, y: usize| {
        let v = grid.evidence((x, y));
        v != 0 && v <= SURELY_FREE
    };
    let (mut known, mut free) = (0usize, 0usize);
    for p in points {
        let q = pose * Point2::new(p.x, p.y);
        let Some((x, y)) = grid.cell_of(&q) else {
            continue;
        };
        if grid.evidence((x, y)) == 0 {
            continue;
        }
        known += 1;
        let inner = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
        if inner && (y - 1..=y + 1).all(|yy| (x - 1..=x + 1).all(|xx| surely_free(xx, yy))) {
            free += 1;
        }
    }
    (known >= MIN_KNOWN).then(|| free as f64 / known as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;
    use crate::icp::synth::{cast_seeded, room};

    /// A 5 × 4 m room mapped from its middle, then a scan laid at the right
    /// pose and at one 1 m off and turned.
    #[test]
    fn a_scan_at_a_wrong_pose_lands_on_free_floor() {
        let walls = room(5.0, 4.0, 0.5);
        let mut grid = Grid::new(Point2::new(-0.5, -0.5), 0.05, 120, 100);
        let at = pose(2.5, 2.0, 0.0);
        for k in 0..12u32 {
            let from = at * pose(0.0, 0.0, f64::from(k) * 0.5);
            for p in cast_seeded(&walls, &from, u64::from(k)) {
                let o = Point2::from(from.translation.vector);
                grid.integrate_ray(&o, &(from * Point2::new(p.x, p.y)), true);
            }
        }
        let truth = pose(2.0, 1.5, 0.3);
        let scan = cast_seeded(&walls, &truth, 99);
        let right = free_share(&grid, &scan, &truth).expect("known");
        let wrong = free_share(&grid, &scan, &pose(2.6, 2.1, 0.8)).expect("known");
        assert!(right < 0.05, "right pose: {right}");
        assert!(wrong > CONTRADICTION, "wrong pose: {wrong}");
        // Nothing known yet: no verdict.
        let empty = Grid::new(Point2::new(-0.5, -0.5), 0.05, 120, 100);
        assert_eq!(free_share(&empty, &scan, &truth), None);
    }
}
