//! Straight moves: whether a segment keeps the body off seen obstacles or
//! stays on traversable cells.

use nalgebra::Point2;

use super::{square_gap, CSpace, OCCUPIED};

impl CSpace {
    /// Whether the straight segment `a`–`b` keeps the robot body off every
    /// seen obstacle (sampled every quarter cell).
    #[cfg(test)]
    pub(crate) fn segment_safe(&self, a: &Point2<f64>, b: &Point2<f64>) -> bool {
        self.first_unsafe(a, b).is_none()
    }

    /// The first sample of the straight segment `a`–`b` (every quarter
    /// cell, from `a`) where the bare body would touch a seen obstacle or
    /// leave the map; `None` when the whole segment is safe. A sample in a
    /// cell that is not [`CSpace::collision_free`] (judged at the cell's
    /// centre) is measured again where it is: up to half a cell from the
    /// centre, a path may pass a surface seen since it was planned by a
    /// few millimetres more than the robot radius, and is not blocked.
    pub(crate) fn first_unsafe(&self, a: &Point2<f64>, b: &Point2<f64>) -> Option<Point2<f64>> {
        self.samples(a, b).find(|p| match self.frame.index_of(p) {
            Some(i) => !self.collision_free[i] && self.body_touches(p, i),
            None => true,
        })
    }

    /// Whether a robot body centred at `p`, in cell `i`, comes nearer than
    /// the robot radius to the square of a cell seen occupied or holding a
    /// surface (one bordering free floor, as [`CSpace::collision_free`]
    /// counts them).
    fn body_touches(&self, p: &Point2<f64>, i: usize) -> bool {
        let f = self.frame;
        let (w, h) = (f.w as i64, f.h as i64);
        let (x, y) = ((i % f.w) as i64, (i / f.w) as i64);
        let k = (self.radius / f.res).ceil() as i64 + 1;
        for ny in (y - k).max(0)..=(y + k).min(h - 1) {
            for nx in (x - k).max(0)..=(x + k).min(w - 1) {
                let j = ny as usize * f.w + nx as usize;
                let solid = self.state[j] == OCCUPIED || self.held[j];
                if !solid || !self.borders_free(nx, ny) {
                    continue;
                }
                if square_gap(p, &f.centre(j), f.res) < self.radius {
                    return true;
                }
            }
        }
        false
    }

    /// Whether the straight segment `a`–`b` stays on traversable cells
    /// (sampled every quarter cell).
    pub(crate) fn segment_clear(&self, a: &Point2<f64>, b: &Point2<f64>) -> bool {
        self.samples(a, b)
            .all(|p| self.frame.index_of(&p).is_some_and(|i| self.traversable[i]))
    }

    /// Points along the straight segment `a`–`b`, from `a` to `b` both
    /// included, a quarter cell or less apart: no cell the segment crosses
    /// by more than a corner is missed.
    fn samples(&self, a: &Point2<f64>, b: &Point2<f64>) -> impl Iterator<Item = Point2<f64>> {
        crate::geom::points_along(*a, *b, self.frame.res * 0.25)
    }
}
