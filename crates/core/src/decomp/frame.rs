//! The sweep frame: world coordinates rotated so that `u` runs along the lanes
//! and `v` across them, and a raster of slices over the evidence grid in it.

use nalgebra::Point2;

use crate::grid::Grid;

/// A rotation into lane coordinates plus a raster laid over the evidence grid:
/// pixel `(i, k)` covers `u ∈ [u0 + i·h, u0 + (i+1)·h)`, `v ∈ [v0 + k·h, v0 + (k+1)·h)`;
/// row `k` is the slice at `v = v0 + (k + ½)·h`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepFrame {
    /// Lane direction (rad, world frame).
    pub angle: f64,
    cos: f64,
    sin: f64,
    /// `u` of the raster's first column edge (m).
    pub u0: f64,
    /// `v` of the raster's first row edge (m).
    pub v0: f64,
    /// Pixel size and slice spacing (m).
    pub h: f64,
    /// Columns.
    pub(crate) nu: usize,
    /// Rows (slices).
    pub nv: usize,
}

impl SweepFrame {
    /// Largest raster the decomposition works on (pixels).
    pub(crate) const MAX_PIXELS: usize = 64 << 20;

    /// A frame with lanes along `angle` whose raster of pixel size `h` covers the
    /// whole of `grid`; `None` when the grid's geometry is not finite or the
    /// raster would exceed [`SweepFrame::MAX_PIXELS`].
    pub(crate) fn over_grid(grid: &Grid, angle: f64, h: f64) -> Option<Self> {
        if !(angle.is_finite() && h.is_finite() && h > 0.0) {
            return None;
        }
        let mut f = Self {
            angle,
            cos: angle.cos(),
            sin: angle.sin(),
            u0: 0.0,
            v0: 0.0,
            h,
            nu: 0,
            nv: 0,
        };
        let o = grid.origin();
        let (w, ht) = (
            grid.width() as f64 * grid.resolution(),
            grid.height() as f64 * grid.resolution(),
        );
        let (mut lo_u, mut lo_v, mut hi_u, mut hi_v) = (
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        );
        for (dx, dy) in [(0.0, 0.0), (w, 0.0), (0.0, ht), (w, ht)] {
            let (u, v) = f.to_uv(&Point2::new(o.x + dx, o.y + dy));
            lo_u = lo_u.min(u);
            lo_v = lo_v.min(v);
            hi_u = hi_u.max(u);
            hi_v = hi_v.max(v);
        }
        if ![lo_u, lo_v, hi_u, hi_v].iter().all(|v| v.is_finite()) {
            return None;
        }
        // Snap to the pixel lattice so an axis-aligned grid maps cell to pixel.
        f.u0 = (lo_u / h).floor() * h;
        f.v0 = (lo_v / h).floor() * h;
        let (nu, nv) = (((hi_u - f.u0) / h).ceil(), ((hi_v - f.v0) / h).ceil());
        if !(nu.is_finite() && nv.is_finite())
            || nu.max(1.0) * nv.max(1.0) > Self::MAX_PIXELS as f64
        {
            return None;
        }
        f.nu = (nu.max(0.0) as usize).max(1);
        f.nv = (nv.max(0.0) as usize).max(1);
        Some(f)
    }

    /// World point to lane coordinates `(u, v)`.
    pub(crate) fn to_uv(self, p: &Point2<f64>) -> (f64, f64) {
        (
            self.cos * p.x + self.sin * p.y,
            -self.sin * p.x + self.cos * p.y,
        )
    }

    /// Lane coordinates to a world point.
    pub fn to_world(&self, u: f64, v: f64) -> Point2<f64> {
        Point2::new(self.cos * u - self.sin * v, self.sin * u + self.cos * v)
    }

    /// `v` of slice `k` (the centre of row `k`).
    pub(crate) fn row_v(&self, k: usize) -> f64 {
        self.v0 + (k as f64 + 0.5) * self.h
    }

    /// `v` of the lower edge of row `k`.
    pub(crate) fn row_edge(&self, k: usize) -> f64 {
        self.v0 + k as f64 * self.h
    }

    /// `u` of the centre of column `i`.
    pub(crate) fn col_u(&self, i: usize) -> f64 {
        self.u0 + (i as f64 + 0.5) * self.h
    }

    /// The column whose pixel contains `u`, clamped into the raster.
    pub(crate) fn col_of(&self, u: f64) -> usize {
        (((u - self.u0) / self.h).floor().max(0.0) as usize).min(self.nu - 1)
    }

    /// The row whose pixel contains `v`, clamped into the raster.
    pub(crate) fn row_of(&self, v: f64) -> usize {
        (((v - self.v0) / self.h).floor().max(0.0) as usize).min(self.nv - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_axis_aligned_lattice() {
        let g = Grid::new(Point2::new(-1.0, 2.0), 0.05, 40, 20);
        let f = SweepFrame::over_grid(&g, 0.0, 0.05).unwrap();
        assert_eq!((f.nu, f.nv), (40, 20));
        assert!((f.u0 + 1.0).abs() < 1e-9 && (f.v0 - 2.0).abs() < 1e-9);
        let f = SweepFrame::over_grid(&g, 0.7, 0.05).unwrap();
        let p = Point2::new(0.3, 2.4);
        let (u, v) = f.to_uv(&p);
        assert!((f.to_world(u, v) - p).norm() < 1e-12);
        // The rotated raster still covers all four grid corners.
        for c in [(-1.0, 2.0), (1.0, 2.0), (-1.0, 3.0), (1.0, 3.0)] {
            let (u, v) = f.to_uv(&Point2::new(c.0, c.1));
            assert!(u >= f.u0 - 1e-9 && u <= f.u0 + f.nu as f64 * f.h + 1e-9);
            assert!(v >= f.v0 - 1e-9 && v <= f.v0 + f.nv as f64 * f.h + 1e-9);
        }
        // Non-finite or absurd geometry gives no frame.
        assert!(SweepFrame::over_grid(
            &Grid::new(Point2::new(f64::NAN, 0.0), 0.05, 4, 4),
            0.0,
            0.05
        )
        .is_none());
        assert!(SweepFrame::over_grid(&g, 0.0, 0.0).is_none());
        assert!(
            SweepFrame::over_grid(&Grid::new(Point2::new(0.0, 0.0), 1e6, 4, 4), 0.0, 0.05)
                .is_none()
        );
    }
}
