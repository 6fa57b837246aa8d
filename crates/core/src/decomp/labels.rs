//! The cells of an update as runs of pixels per slice, kept for the next
//! update's cell inheritance: how many pixels of a new piece each old cell
//! held, counted span against span instead of pixel by pixel.

use super::rows::group_by_row;

/// Pixels `a..b` of row `row` painted with cell `id`, the `order`-th paint of
/// its update (a later paint wins where two overlap).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Span {
    row: u32,
    a: u32,
    b: u32,
    id: u32,
    order: u32,
}

/// The spans painted in this update and those of the last one, by row.
#[derive(Clone, Debug, Default)]
pub(crate) struct LabelSpans {
    /// This update's spans, in paint order.
    painted: Vec<Span>,
    /// The last update's spans, sorted by row, then `a`.
    by_row: Vec<Span>,
    /// `by_row[row_start[k]..row_start[k + 1]]` lie in row `k`.
    row_start: Vec<u32>,
    /// Rows of the last update where two spans overlap.
    mixed: Vec<bool>,
    /// Scratch for a mixed row: its spans in paint order, then its labels.
    scratch: Vec<Span>,
    row_labels: Vec<u32>,
}

/// No cell at this pixel.
const NONE: u32 = u32::MAX;

impl LabelSpans {
    /// Forgets every span.
    pub fn clear(&mut self) {
        self.painted.clear();
        self.by_row.clear();
        self.row_start.clear();
        self.mixed.clear();
    }

    /// Starts an update: the spans painted so far become the last update's,
    /// indexed by row.
    pub fn begin(&mut self) {
        let rows = self
            .painted
            .iter()
            .map(|s| s.row as usize + 1)
            .max()
            .unwrap_or(0);
        group_by_row(
            &self.painted,
            rows,
            |s| Some(s.row as usize),
            |s| *s,
            &mut self.by_row,
            &mut self.row_start,
        );
        self.mixed.clear();
        self.mixed.resize(rows, false);
        for k in 0..rows {
            let row = &mut self.by_row[self.row_start[k] as usize..self.row_start[k + 1] as usize];
            row.sort_unstable_by_key(|s| (s.a, s.order));
            self.mixed[k] = row.windows(2).any(|w| w[1].a < w[0].b);
        }
        self.painted.clear();
    }

    /// Paints the pixels `a..b` of row `row` with cell `id`.
    pub(crate) fn paint(&mut self, row: usize, (a, b): (usize, usize), id: u32) {
        if a < b {
            let order = self.painted.len() as u32;
            self.painted.push(Span {
                row: row as u32,
                a: a as u32,
                b: b as u32,
                id,
                order,
            });
        }
    }

    /// For each last-update cell with pixels among `a..b` of row `row`:
    /// `add(id, pixels)`, in order of `u` (a cell twice if it comes back).
    pub fn overlaps(&mut self, row: usize, (a, b): (usize, usize), mut add: impl FnMut(u32, u32)) {
        if row + 1 >= self.row_start.len() || a >= b {
            return;
        }
        let spans = &self.by_row[self.row_start[row] as usize..self.row_start[row + 1] as usize];
        if !self.mixed[row] {
            for s in spans {
                let (lo, hi) = (s.a.max(a as u32), s.b.min(b as u32));
                if lo < hi {
                    add(s.id, hi - lo);
                }
            }
            return;
        }
        // Overlapping spans: painted in their order, then read as runs.
        self.scratch.clear();
        self.scratch.extend_from_slice(spans);
        self.scratch.sort_unstable_by_key(|s| s.order);
        self.row_labels.clear();
        self.row_labels.resize(b - a, NONE);
        for s in &self.scratch {
            let (lo, hi) = (s.a.max(a as u32) as usize, s.b.min(b as u32) as usize);
            if lo < hi {
                self.row_labels[lo - a..hi - a].fill(s.id);
            }
        }
        let mut run = (NONE, 0);
        for &id in &self.row_labels {
            if id == run.0 {
                run.1 += 1;
                continue;
            }
            if run.0 != NONE {
                add(run.0, run.1);
            }
            run = (id, 1);
        }
        if run.0 != NONE {
            add(run.0, run.1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pixel rule the spans stand for: paint a row, count runs.
    fn by_pixels(paints: &[(usize, usize, u32)], a: usize, b: usize) -> Vec<(u32, u32)> {
        let mut row = vec![NONE; 64];
        for &(l, r, id) in paints {
            row[l..r].fill(id);
        }
        let mut out: Vec<(u32, u32)> = Vec::new();
        for &id in &row[a..b] {
            match out.last_mut() {
                Some(last) if last.0 == id => last.1 += 1,
                _ => out.push((id, 1)),
            }
        }
        out.retain(|o| o.0 != NONE);
        out
    }

    #[test]
    fn overlaps_count_the_pixels_a_paint_left_to_each_cell() {
        let cases: &[&[(usize, usize, u32)]] = &[
            &[(2, 10, 7), (12, 20, 8), (20, 30, 9)],
            // A later paint over an earlier one wins where they overlap.
            &[(2, 10, 7), (9, 15, 8), (0, 3, 9)],
            &[(5, 40, 7), (10, 12, 8)],
        ];
        for paints in cases {
            let mut spans = LabelSpans::default();
            for &(l, r, id) in paints.iter() {
                spans.paint(3, (l, r), id);
            }
            spans.paint(1, (0, 50), 99);
            spans.begin();
            for (a, b) in [(0, 50), (4, 11), (9, 10), (25, 26), (45, 50)] {
                let mut got = Vec::new();
                spans.overlaps(3, (a, b), |id, n| got.push((id, n)));
                assert_eq!(got, by_pixels(paints, a, b), "{paints:?} over {a}..{b}");
            }
            let mut other = Vec::new();
            spans.overlaps(2, (0, 50), |id, n| other.push((id, n)));
            spans.overlaps(9, (0, 50), |id, n| other.push((id, n)));
            assert!(other.is_empty(), "rows without paint hold nothing");
        }
    }
}
