//! Grid geometry shared by every planner raster, and disk stencils on it.

use nalgebra::Point2;

/// Grid geometry shared by every planner raster.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Frame {
    /// World position of the lower-left corner of cell (0, 0).
    pub origin: Point2<f64>,
    /// Cell size (m).
    pub res: f64,
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
}

impl Frame {
    /// Linear indices of the up to 8 cells around cell `i` that lie inside
    /// the frame (the grid's `NEIGHBOURS_8` order).
    #[inline]
    pub(crate) fn neighbours8(&self, i: usize) -> impl Iterator<Item = usize> {
        crate::grid::neighbours8_of(i, self.w, self.h)
    }

    /// Linear indices of the cells at `offsets` (cells across, cells up)
    /// from cell `i` that lie inside the frame, in the order given.
    #[inline]
    pub fn around<'a>(
        &self,
        i: usize,
        offsets: &'a [(i64, i64)],
    ) -> impl Iterator<Item = usize> + 'a {
        let (w, h) = (self.w, self.h);
        let (x, y) = ((i % w.max(1)) as i64, (i / w.max(1)) as i64);
        offsets.iter().filter_map(move |&(dx, dy)| {
            let (nx, ny) = (x + dx, y + dy);
            (nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h)
                .then(|| ny as usize * w + nx as usize)
        })
    }

    /// Linear index of the cell containing `p`, if inside.
    #[inline]
    pub(crate) fn index_of(&self, p: &Point2<f64>) -> Option<usize> {
        let fx = (p.x - self.origin.x) / self.res;
        let fy = (p.y - self.origin.y) / self.res;
        if !(fx.is_finite() && fy.is_finite()) || fx < 0.0 || fy < 0.0 {
            return None;
        }
        let (x, y) = (fx as usize, fy as usize);
        (x < self.w && y < self.h).then_some(y * self.w + x)
    }

    /// Centre of cell `i`.
    #[inline]
    pub fn centre(&self, i: usize) -> Point2<f64> {
        Point2::new(
            self.origin.x + ((i % self.w) as f64 + 0.5) * self.res,
            self.origin.y + ((i / self.w) as f64 + 0.5) * self.res,
        )
    }

    /// Number of cells.
    #[inline]
    pub fn len(&self) -> usize {
        self.w * self.h
    }

    /// Whether the frame has no cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Cell offsets whose centre distance is at most `radius`.
pub fn disk(radius: f64, res: f64) -> Vec<(i64, i64)> {
    let n = (radius / res).ceil() as i64 + 1;
    let mut v = Vec::new();
    for dy in -n..=n {
        for dx in -n..=n {
            if ((dx * dx + dy * dy) as f64).sqrt() * res <= radius + 1e-9 {
                v.push((dx, dy));
            }
        }
    }
    v
}
