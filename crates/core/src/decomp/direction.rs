//! The dominant wall direction, modulo 90°: from line segments when the map
//! has them, else from the gradients of the occupied cells of the grid.
//!
//! Directions are averaged as `Σ w·e^{4iθ}` so that walls at θ and θ + 90°
//! reinforce each other (a rectilinear room has one dominant axis pair).

use std::f64::consts::FRAC_PI_2;

use crate::geom::Segment;
use crate::grid::{CellState, Grid};

/// A direction estimate: the axis angle in (-π/4, π/4] and how much wall (m)
/// supports it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct AxisEstimate {
    /// Angle of one of the two dominant axes (rad).
    pub angle: f64,
    /// Supporting wall length (m).
    pub evidence: f64,
}

fn finish(sx: f64, sy: f64, evidence: f64) -> Option<AxisEstimate> {
    if evidence <= 0.0 || (sx == 0.0 && sy == 0.0) || !(sx.is_finite() && sy.is_finite()) {
        return None;
    }
    Some(AxisEstimate {
        angle: sy.atan2(sx) / 4.0,
        evidence,
    })
}

/// Dominant axis of `segments`, weighted by length; `None` without usable segments.
pub(crate) fn from_segments(segments: &[Segment]) -> Option<AxisEstimate> {
    let (mut sx, mut sy, mut total) = (0.0, 0.0, 0.0);
    for s in segments {
        let len = s.length();
        let a = s.angle();
        if !(len.is_finite() && a.is_finite()) || len <= 0.0 {
            continue;
        }
        sx += len * (4.0 * a).cos();
        sy += len * (4.0 * a).sin();
        total += len;
    }
    finish(sx, sy, total)
}

/// Dominant axis of the occupied structure of `grid` (Sobel gradients of the
/// occupied indicator); `None` when nothing is occupied.
#[cfg(test)]
pub(crate) fn from_grid(grid: &Grid) -> Option<AxisEstimate> {
    from_grid_window(grid, (0, 0, grid.width(), grid.height()))
}

/// [`from_grid`] over the cells `x0..x1`, `y0..y1` only (the explored part).
pub(crate) fn from_grid_window(
    grid: &Grid,
    (x0, y0, x1, y1): (usize, usize, usize, usize),
) -> Option<AxisEstimate> {
    let (w, h) = (grid.width(), grid.height());
    if w < 3 || h < 3 {
        return None;
    }
    let (x0, y0) = (x0.max(1), y0.max(1));
    let (x1, y1) = (x1.min(w - 1), y1.min(h - 1));
    let occ = |x: usize, y: usize| (grid.state((x, y)) == CellState::Occupied) as i32 as f64;
    let (mut sx, mut sy, mut n_occ) = (0.0, 0.0, 0usize);
    for y in y0..y1 {
        for x in x0..x1 {
            if occ(x, y) > 0.0 {
                n_occ += 1;
            }
            // Only cells next to an occupied one can have a gradient.
            let any = (y - 1..=y + 1).any(|yy| (x - 1..=x + 1).any(|xx| occ(xx, yy) > 0.0));
            if !any {
                continue;
            }
            let gx = (occ(x + 1, y - 1) + 2.0 * occ(x + 1, y) + occ(x + 1, y + 1))
                - (occ(x - 1, y - 1) + 2.0 * occ(x - 1, y) + occ(x - 1, y + 1));
            let gy = (occ(x - 1, y + 1) + 2.0 * occ(x, y + 1) + occ(x + 1, y + 1))
                - (occ(x - 1, y - 1) + 2.0 * occ(x, y - 1) + occ(x + 1, y - 1));
            let m = (gx * gx + gy * gy).sqrt();
            if m == 0.0 {
                continue;
            }
            // The wall runs perpendicular to the gradient; mod 90° that is the same axis.
            let a = gy.atan2(gx) + FRAC_PI_2;
            sx += m * (4.0 * a).cos();
            sy += m * (4.0 * a).sin();
        }
    }
    finish(sx, sy, n_occ as f64 * grid.resolution())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point2;

    fn seg(a: (f64, f64), b: (f64, f64)) -> Segment {
        Segment::new(Point2::new(a.0, a.1), Point2::new(b.0, b.1))
    }

    #[test]
    fn rectilinear_segments_give_their_axis() {
        let t = 0.3f64;
        let (c, s) = (t.cos(), t.sin());
        let segs = [
            seg((0.0, 0.0), (2.0 * c, 2.0 * s)),
            seg((0.0, 0.0), (-s, c)),
            seg((1.0, 1.0), (1.0 - 3.0 * s, 1.0 + 3.0 * c)),
        ];
        let e = from_segments(&segs).unwrap();
        assert!((e.angle - t).abs() < 1e-9, "{e:?}");
        assert!((e.evidence - 6.0).abs() < 1e-9);
        assert!(from_segments(&[]).is_none());
        assert!(from_segments(&[seg((f64::NAN, 0.0), (1.0, 1.0))]).is_none());
    }

    #[test]
    fn grid_walls_give_axis_zero() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 60, 40);
        for x in 5..55 {
            g.set_state((x, 5), CellState::Occupied);
            g.set_state((x, 35), CellState::Occupied);
        }
        for y in 5..36 {
            g.set_state((5, y), CellState::Occupied);
            g.set_state((54, y), CellState::Occupied);
        }
        let e = from_grid(&g).unwrap();
        assert!(e.angle.abs() < 1e-6, "{e:?}");
        assert!(from_grid(&Grid::new(Point2::new(0.0, 0.0), 0.05, 10, 10)).is_none());
    }
}
