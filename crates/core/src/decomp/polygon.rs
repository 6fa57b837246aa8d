//! Polyline simplification for cell outlines (Douglas–Peucker).

/// Douglas–Peucker simplification of an open polyline: keeps both ends and
/// every vertex farther than `tol` (m) from the simplified line.
pub(crate) fn simplify_chain(pts: &[(f64, f64)], tol: f64) -> Vec<(f64, f64)> {
    if pts.len() <= 2 {
        return pts.to_vec();
    }
    let mut keep = vec![false; pts.len()];
    keep[0] = true;
    keep[pts.len() - 1] = true;
    let mut stack = vec![(0usize, pts.len() - 1)];
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (mut far, mut best) = (a, -1.0);
        for (i, p) in pts.iter().enumerate().take(b).skip(a + 1) {
            let d = distance_to_segment(*p, pts[a], pts[b]);
            if d > best {
                best = d;
                far = i;
            }
        }
        if best > tol {
            keep[far] = true;
            stack.push((a, far));
            stack.push((far, b));
        }
    }
    pts.iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(*p))
        .collect()
}

fn distance_to_segment(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((p.0 - a.0 - t * dx).powi(2) + (p.1 - a.1 - t * dy).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collinear_points_go_corners_stay() {
        let pts = [
            (0.0, 0.0),
            (1.0, 0.0),
            (2.0, 0.001),
            (3.0, 0.0),
            (3.0, 1.0),
            (3.0, 2.0),
        ];
        let s = simplify_chain(&pts, 0.01);
        assert_eq!(s, vec![(0.0, 0.0), (3.0, 0.0), (3.0, 2.0)]);
        assert_eq!(simplify_chain(&pts[..2], 0.01).len(), 2);
    }
}
