//! Pixel codes of the lane-frame raster and the passes over whole rows of
//! it: finding runs of one class eight pixels at a time and filling short
//! unknown gaps between free pixels. Pure functions over byte slices.

/// Pixel class: never observed.
pub const UNK: u8 = 0;
/// Pixel class: observed free.
pub const FREE: u8 = 1;
/// Pixel class: observed occupied.
pub const OCC: u8 = 2;
/// Flag: the pixel centre lies within the inflation radius of a wall point.
pub const BLOCKED: u8 = 4;
/// Mask of the class bits.
pub const CLASS: u8 = 3;

/// The class bits of every byte of a word.
const CLASS_WORD: u64 = u64::from_ne_bytes([CLASS; 8]);
/// The high bit of every byte of a word.
const HIGH_BITS: u64 = u64::from_ne_bytes([0x80; 8]);

/// Whether some byte of `x` is below `n` (`n` at most 128; the classic
/// word trick: the high bit survives only where a byte borrowed).
fn has_byte_below(x: u64, n: u8) -> bool {
    x.wrapping_sub(u64::from_ne_bytes([n; 8])) & !x & HIGH_BITS != 0
}

/// The eight pixels of `row` from `j` as one word.
fn word(row: &[u8], j: usize) -> u64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&row[j..j + 8]);
    u64::from_ne_bytes(b)
}

/// The first index at or after `j` whose pixel is not of class `class`
/// (`row.len()` if there is none): the end of a run.
pub(crate) fn skip_class(row: &[u8], mut j: usize, class: u8) -> usize {
    let pattern = u64::from_ne_bytes([class; 8]);
    while j + 8 <= row.len() && word(row, j) & CLASS_WORD == pattern {
        j += 8;
    }
    while j < row.len() && row[j] & CLASS == class {
        j += 1;
    }
    j
}

/// The first index at or after `j` whose pixel is of class `class`
/// (`row.len()` if there is none).
pub(crate) fn find_class(row: &[u8], mut j: usize, class: u8) -> usize {
    let pattern = u64::from_ne_bytes([class; 8]);
    while j + 8 <= row.len() {
        // A byte of `x` is zero exactly where the pixel is of `class`.
        let x = (word(row, j) & CLASS_WORD) ^ pattern;
        if has_byte_below(x, 1) {
            break;
        }
        j += 8;
    }
    while j < row.len() && row[j] & CLASS != class {
        j += 1;
    }
    j
}

/// Along one row of pure class codes: unknown runs of at most `max` pixels
/// with a free pixel at both ends become free (an occupied pixel between
/// breaks the pair).
pub(crate) fn fill_row(row: &mut [u8], max: usize) {
    let n = row.len();
    let mut j = find_class(row, 0, FREE);
    while j < n {
        let gap = skip_class(row, j, FREE);
        let end = skip_class(row, gap, UNK);
        if end >= n {
            return;
        }
        if row[end] & CLASS == FREE {
            if end - gap <= max {
                row[gap..end].fill(FREE);
            }
            j = end;
        } else {
            j = find_class(row, end, FREE);
        }
    }
}

/// Column counterpart of [`fill_row`] for the columns `cols` over the rows
/// `rows` of a raster `nu` pixels wide, walked row by row in memory order:
/// `run` holds, per column, the unknown pixels since its last free one
/// (saturating; `u16::MAX` after an occupied one or before any free one).
/// Rows with no gap to close cost one branch-free pass the compiler
/// vectorises.
pub(crate) fn fill_columns(
    px: &mut [u8],
    nu: usize,
    cols: std::ops::Range<usize>,
    rows: std::ops::Range<usize>,
    max: usize,
    run: &mut Vec<u16>,
) {
    // A gap as long as the saturated count could not be told from "no free
    // pixel before": such gaps are never filled (no map is that sparse).
    let max = max.min(usize::from(u16::MAX - 1)) as u16;
    // A free pixel closing a gap the fill takes.
    let closes = |p: u8, r: u16| p & CLASS == FREE && r >= 1 && r <= max;
    run.clear();
    run.resize(cols.len(), u16::MAX);
    for k in rows {
        let row = &px[k * nu + cols.start..k * nu + cols.end];
        if row
            .iter()
            .zip(run.iter())
            .fold(false, |any, (&p, &r)| any | closes(p, r))
        {
            for (c, i) in cols.clone().enumerate() {
                let r = run[c];
                if closes(px[k * nu + i], r) {
                    for t in k - usize::from(r)..k {
                        px[t * nu + i] = FREE;
                    }
                }
            }
        }
        let row = &px[k * nu + cols.start..k * nu + cols.end];
        for (&p, r) in row.iter().zip(run.iter_mut()) {
            *r = match p & CLASS {
                FREE => 0,
                OCC => u16::MAX,
                _ => r.saturating_add(1),
            };
        }
    }
}

/// The first index at or after `j` whose byte is at most `max` (`row.len()`
/// if there is none); `max` below 128.
pub(crate) fn find_at_most(row: &[u8], mut j: usize, max: u8) -> usize {
    debug_assert!(max < 128);
    while j + 8 <= row.len() {
        if has_byte_below(word(row, j), max + 1) {
            break;
        }
        j += 8;
    }
    while j < row.len() && row[j] > max {
        j += 1;
    }
    j
}

/// Down and then up every column `cols` over the rows `rows` of a raster
/// `nu` bytes wide: each byte becomes the distance in rows to the nearest 0
/// of its column (saturating at 255), given 0 at the seeds and 255 elsewhere.
/// Row against row, so the passes go in memory order and vectorise.
pub(crate) fn column_distances(
    near: &mut [u8],
    nu: usize,
    cols: std::ops::Range<usize>,
    rows: std::ops::Range<usize>,
) {
    for k in rows.start + 1..rows.end {
        let (before, after) = near.split_at_mut(k * nu);
        one_more_row(
            &mut after[cols.clone()],
            &before[(k - 1) * nu + cols.start..(k - 1) * nu + cols.end],
        );
    }
    for k in (rows.start..rows.end.saturating_sub(1)).rev() {
        let (upto, next) = near.split_at_mut((k + 1) * nu);
        one_more_row(
            &mut upto[k * nu + cols.start..k * nu + cols.end],
            &next[cols.clone()],
        );
    }
}

/// `cur = min(cur, from + 1)` byte by byte (saturating), in blocks of 32
/// bytes of fixed length so that the loop is vectorised.
fn one_more_row(cur: &mut [u8], from: &[u8]) {
    const LANES: usize = 32;
    let n = cur.len().min(from.len());
    let (cur, from) = (&mut cur[..n], &from[..n]);
    let mut cur_blocks = cur.chunks_exact_mut(LANES);
    let mut from_blocks = from.chunks_exact(LANES);
    for (c, f) in (&mut cur_blocks).zip(&mut from_blocks) {
        let c: &mut [u8; LANES] = c.try_into().expect("block of LANES");
        let f: &[u8; LANES] = f.try_into().expect("block of LANES");
        for j in 0..LANES {
            c[j] = c[j].min(f[j].saturating_add(1));
        }
    }
    for (c, &f) in cur_blocks
        .into_remainder()
        .iter_mut()
        .zip(from_blocks.remainder())
    {
        *c = (*c).min(f.saturating_add(1));
    }
}

/// Adds the closed interval `iv` to `runs`, sorted disjoint intervals, for
/// intervals given in increasing order of their centres (so none ends left
/// of a run before it): the runs it touches or overlaps are merged into it
/// from the back, and `runs` stays sorted and disjoint.
pub(crate) fn push_union(runs: &mut Vec<(f64, f64)>, iv: (f64, f64)) {
    let (mut l, mut r) = iv;
    while let Some(&(pl, pr)) = runs.last() {
        if pr < l {
            break;
        }
        l = l.min(pl);
        r = r.max(pr);
        runs.pop();
    }
    runs.push((l, r));
}

/// Pixel classes of raw grid evidence (0 unknown, `occupied_from` and up
/// occupied, free between; see `Grid::raw_evidence`), byte for byte.
pub fn classify(raw: &[u8], out: &mut [u8], occupied_from: u8) {
    for (c, &e) in out.iter_mut().zip(raw) {
        *c = u8::from(e != 0) + u8::from(e >= occupied_from);
    }
}

/// Transposes an 8 × 8 block of bytes held as eight words (byte `c` of word
/// `r` is element `(r, c)`, native byte order): three rounds of swapping
/// 2 × 2 blocks of bytes, pairs of bytes, then halves.
pub(crate) fn transpose8(mut a: [u64; 8]) -> [u64; 8] {
    let little = |w: u64| {
        if cfg!(target_endian = "little") {
            w
        } else {
            w.swap_bytes()
        }
    };
    for w in &mut a {
        *w = little(*w);
    }
    for (shift, mask, pairs) in [
        (
            8,
            0x00FF_00FF_00FF_00FFu64,
            [(0, 1), (2, 3), (4, 5), (6, 7)],
        ),
        (16, 0x0000_FFFF_0000_FFFF, [(0, 2), (1, 3), (4, 6), (5, 7)]),
        (32, 0x0000_0000_FFFF_FFFF, [(0, 4), (1, 5), (2, 6), (3, 7)]),
    ] {
        for (x, y) in pairs {
            let t = ((a[x] >> shift) ^ a[y]) & mask;
            a[y] ^= t;
            a[x] ^= t << shift;
        }
    }
    for w in &mut a {
        *w = little(*w);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pseudo-random raster of the three classes, mostly free.
    fn raster(n: usize, seed: u32) -> Vec<u8> {
        let mut seed = seed;
        (0..n)
            .map(|_| {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                match (seed >> 16) % 10 {
                    0..=4 => FREE,
                    5..=8 => UNK,
                    _ => OCC,
                }
            })
            .collect()
    }

    /// The rule of [`fill_row`] pixel by pixel: the reference.
    fn fill_slow(line: &mut [u8], max: usize) {
        let mut last_free: Option<usize> = None;
        for j in 0..line.len() {
            match line[j] & CLASS {
                FREE => {
                    if let Some(lf) = last_free {
                        if j - lf > 1 && j - lf - 1 <= max {
                            line[lf + 1..j].fill(FREE);
                        }
                    }
                    last_free = Some(j);
                }
                OCC => last_free = None,
                _ => {}
            }
        }
    }

    #[test]
    fn short_unknown_gaps_between_free_are_filled_only() {
        let (f, u, o) = (FREE, UNK, OCC);
        let mut px = vec![f, u, u, f, u, u, u, u, f, o, u, f, u, f];
        fill_row(&mut px, 3);
        assert_eq!(px, vec![f, f, f, f, u, u, u, u, f, o, u, f, f, f]);
    }

    #[test]
    fn row_fill_matches_the_pixel_rule_on_random_rows() {
        for (len, seed) in [(1, 1), (7, 2), (8, 3), (9, 4), (63, 5), (200, 6), (1001, 7)] {
            for max in [1, 2, 3, 5] {
                let px = raster(len, seed);
                let mut want = px.clone();
                fill_slow(&mut want, max);
                let mut got = px.clone();
                fill_row(&mut got, max);
                assert_eq!(got, want, "len {len}, max {max}");
            }
        }
        // Long runs that the word steps cross.
        let mut px = vec![FREE; 40];
        px[20..23].fill(UNK);
        px.extend([UNK; 30]);
        px.push(FREE);
        let mut want = px.clone();
        fill_slow(&mut want, 3);
        fill_row(&mut px, 3);
        assert_eq!(px, want);
        assert!(px[..40].iter().all(|&p| p == FREE));
    }

    #[test]
    fn runs_are_found_across_word_boundaries() {
        let mut row = vec![UNK | BLOCKED; 37];
        row[19] = FREE;
        row[20..31].fill(FREE | BLOCKED);
        assert_eq!(find_class(&row, 0, FREE), 19);
        assert_eq!(skip_class(&row, 19, FREE), 31);
        assert_eq!(find_class(&row, 31, FREE), 37);
        assert_eq!(skip_class(&row, 0, UNK), 19);
        assert_eq!(find_class(&row, 0, OCC), 37);
    }

    #[test]
    fn an_eight_by_eight_block_is_transposed() {
        let block: [[u8; 8]; 8] =
            std::array::from_fn(|r| std::array::from_fn(|c| (r * 8 + c) as u8));
        let out = transpose8(block.map(u64::from_ne_bytes)).map(u64::to_ne_bytes);
        for r in 0..8 {
            for c in 0..8 {
                assert_eq!(out[c][r], block[r][c], "({r}, {c})");
            }
        }
    }

    #[test]
    fn evidence_is_classified_as_the_grid_does() {
        use crate::grid::{CellState, Grid};
        let raw: Vec<u8> = (0..=255).collect();
        let mut got = vec![9; 256];
        classify(&raw, &mut got, Grid::OCCUPIED_EVIDENCE);
        for (e, c) in got.iter().enumerate() {
            let want = match Grid::state_of(e as u8) {
                CellState::Unknown => UNK,
                CellState::Free => FREE,
                CellState::Occupied => OCC,
            };
            assert_eq!(*c, want, "evidence {e}");
        }
    }

    #[test]
    fn columns_filled_row_by_row_as_column_by_column() {
        let (nu, nv) = (37, 23);
        let px = raster(nu * nv, 12345);
        for max in [1, 2, 3, 5] {
            let mut want = px.clone();
            for i in 2..35 {
                let mut col: Vec<u8> = (1..22).map(|k| want[k * nu + i]).collect();
                fill_slow(&mut col, max);
                for (k, p) in (1..22).zip(col) {
                    want[k * nu + i] = p;
                }
            }
            let mut got = px.clone();
            fill_columns(&mut got, nu, 2..35, 1..22, max, &mut Vec::new());
            assert_eq!(got, want, "max {max}");
            assert_ne!(got, px, "max {max}: something was filled");
        }
    }
}
