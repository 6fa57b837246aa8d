//! Items grouped by row with a stable counting sort: the per-row lists of
//! the slicing (wall points, blocked intervals) and of the label spans,
//! built from items made in any order.

/// Puts `items` into `out` grouped by row, in their order within a row:
/// item `x` goes to row `row(x)` as `map(x)`; `None`, or a row at or past
/// `rows`, drops it. On return `out[starts[k]..starts[k + 1]]` is row `k`
/// (`starts` has `rows + 1` entries).
pub(crate) fn group_by_row<T, U: Copy>(
    items: &[T],
    rows: usize,
    row: impl Fn(&T) -> Option<usize>,
    map: impl Fn(&T) -> U,
    out: &mut Vec<U>,
    starts: &mut Vec<u32>,
) {
    let row = |x: &T| row(x).filter(|&k| k < rows);
    starts.clear();
    starts.resize(rows + 1, 0);
    for k in items.iter().filter_map(row) {
        starts[k + 1] += 1;
    }
    for k in 0..rows {
        starts[k + 1] += starts[k];
    }
    out.clear();
    let Some(first) = items.iter().find(|x| row(x).is_some()) else {
        return;
    };
    out.resize(starts[rows] as usize, map(first));
    let mut next = starts.clone();
    for x in items {
        if let Some(k) = row(x) {
            out[next[k] as usize] = map(x);
            next[k] += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn items_land_in_their_rows_in_order_and_the_rest_are_dropped() {
        let items = [(2, 'a'), (0, 'b'), (9, 'x'), (2, 'c'), (-1, 'y'), (0, 'd')];
        let (mut out, mut starts) = (Vec::new(), Vec::new());
        group_by_row(
            &items,
            3,
            |&(k, _)| usize::try_from(k).ok(),
            |&(_, c)| c,
            &mut out,
            &mut starts,
        );
        assert_eq!(out, vec!['b', 'd', 'a', 'c']);
        assert_eq!(starts, vec![0, 2, 2, 4]);
        group_by_row(
            &items[2..3],
            3,
            |_| Some(7),
            |&(_, c)| c,
            &mut out,
            &mut starts,
        );
        assert!(out.is_empty());
        assert_eq!(starts, vec![0, 0, 0, 0]);
    }
}
