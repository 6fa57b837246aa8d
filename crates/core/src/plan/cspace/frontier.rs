//! Frontier cells, where explored free floor meets unexplored space, and
//! whether a place would see past one.

use super::{CSpace, FREE, UNKNOWN};

impl CSpace {
    /// Whether a scan from cell `from` would reach the unexplored space
    /// beside the frontier cell `fi`: on the straight line from `from`'s
    /// centre to one of `fi`'s unknown neighbours, the first cell that is
    /// not seen-free is unknown and touches `fi` (the line enters the
    /// unexplored space there, not through a gap between the corners of
    /// two occupied cells somewhere else). A frontier
    /// no reachable place sees this way (the far side of a table in a
    /// corner, seen only past its edge) is not worth a drive: it would stay
    /// unexplored.
    pub(crate) fn sees_unknown_beside(&self, from: usize, fi: usize) -> bool {
        let w = self.frame.w;
        let (fx, fy) = ((from % w) as f64, (from / w) as f64);
        [fi - 1, fi + 1, fi - w, fi + w]
            .into_iter()
            .filter(|&u| self.state[u] == UNKNOWN)
            .any(|u| {
                let (ux, uy) = ((u % w) as f64, (u / w) as f64);
                // Four samples per cell crossed: no cell the line passes
                // through by more than a corner is skipped. `samples`
                // spaces its points by length, not by cells crossed: it
                // meets other cells on grazing lines, and changed the
                // plans of lab_c_scan:0 and of the lab_ipa map.
                let steps = ((ux - fx).abs().max((uy - fy).abs()) * 4.0).ceil() as usize;
                (0..steps)
                    .map(|k| {
                        let t = k as f64 / steps as f64;
                        let (x, y) = (fx + (ux - fx) * t, fy + (uy - fy) * t);
                        (y.round() as usize) * w + x.round() as usize
                    })
                    .find(|&c| self.state[c] != FREE || self.surface[c])
                    .is_none_or(|c| {
                        let near = (c % w).abs_diff(fi % w) <= 1 && (c / w).abs_diff(fi / w) <= 1;
                        near && self.state[c] == UNKNOWN && !self.surface[c]
                    })
            })
    }

    /// Known-free cells with at least one unexplored 4-neighbour, except
    /// cells a beam has ended in (a surface lies there: what is unknown
    /// behind it is behind that surface, not a way into unexplored floor).
    pub fn frontier(&self, out: &mut Vec<usize>) {
        out.clear();
        let (w, h) = (self.frame.w, self.frame.h);
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                let i = y * w + x;
                if self.state[i] == FREE
                    && !self.surface[i]
                    && [i - 1, i + 1, i - w, i + w]
                        .iter()
                        .any(|&j| self.state[j] == UNKNOWN)
                {
                    out.push(i);
                }
            }
        }
    }
}
