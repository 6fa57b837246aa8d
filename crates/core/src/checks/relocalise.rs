//! Relocalisation at resume: the checkpointed pose is up to one checkpoint
//! period old and the robot may have coasted after the crash, while the scan
//! tracker starts a fresh local map at whatever pose it is given. The first
//! scan of a resumed run is therefore laid onto the restored map by a
//! correlative search (coarse grid of poses around the checkpointed one, then
//! a finer one around the best): the pose whose scan points fall on the most
//! occupied cells wins, the nearer one on a tie.

use nalgebra::{Point2, Vector2};

use crate::geom::{heading, pose, IPoint, Pose};
use crate::grid::{CellState, Grid};

/// Half-width of the translation search (m).
pub const SEARCH_TRANSLATION: f64 = 0.6;
/// Half-width of the heading search (rad): the robot may have been turning
/// in place when it was killed.
pub const SEARCH_ROTATION: f64 = 1.2;
/// Most scan points used (evenly thinned).
const MAX_POINTS: usize = 240;
/// Share of the first scan's points that must fall on the restored map's
/// walls for the scan to fit there.
pub const MIN_FIT: f64 = 0.5;

/// What the first scan of a resumed run says about where the robot is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ResumeFit {
    /// It fits best at the checkpointed pose (share of points on walls).
    InPlace(f64),
    /// It fits better elsewhere within the search: the robot coasted or
    /// turned after the checkpoint.
    Moved(Relocalised),
    /// It fits nowhere within the search (the best place found, if the scan
    /// or the map had anything to match): the robot was moved while the
    /// daemon was down, or the map is not of this room.
    NoFit(Option<Relocalised>),
}

/// Judges the result of [`relocalise`] against [`MIN_FIT`].
pub fn judge(r: Option<Relocalised>) -> ResumeFit {
    match r {
        Some(r) if r.score >= MIN_FIT && r.score > r.guess_score => ResumeFit::Moved(r),
        Some(r) if r.score >= MIN_FIT => ResumeFit::InPlace(r.score),
        r => ResumeFit::NoFit(r),
    }
}

/// Where the search put the scanner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Relocalised {
    /// The scanner pose found (map frame).
    pub pose: Pose,
    /// Share of the scan points on occupied cells there, 0..=1.
    pub score: f64,
    /// The same share at the guess.
    pub guess_score: f64,
}

struct Scorer<'a> {
    near: Vec<bool>,
    grid: &'a Grid,
}

impl Scorer<'_> {
    fn hits(&self, pts: &[Point2<f64>], p: &Pose) -> usize {
        pts.iter()
            .filter(|q| {
                self.grid
                    .cell_of(&(p * *q))
                    .is_some_and(|(x, y)| self.near[y * self.grid.width() + x])
            })
            .count()
    }
}

/// Searches scanner poses within [`SEARCH_TRANSLATION`] and
/// [`SEARCH_ROTATION`] of `guess` for the one laying `points` (scanner
/// frame) best onto the occupied cells of `grid` (a cell next to one counts).
/// `None` when the scan or the map has nothing to match.
pub fn relocalise(grid: &Grid, points: &[IPoint], guess: &Pose) -> Option<Relocalised> {
    let (w, h) = (grid.width(), grid.height());
    let mut near = vec![false; w * h];
    let mut any = false;
    for y in 0..h {
        for x in 0..w {
            if grid.state((x, y)) == CellState::Occupied {
                any = true;
                for ny in y.saturating_sub(1)..(y + 2).min(h) {
                    for nx in x.saturating_sub(1)..(x + 2).min(w) {
                        near[ny * w + nx] = true;
                    }
                }
            }
        }
    }
    let stride = points.len().div_ceil(MAX_POINTS).max(1);
    let pts: Vec<Point2<f64>> = points
        .iter()
        .step_by(stride)
        .filter(|p| p.x.is_finite() && p.y.is_finite())
        .map(|p| Point2::new(p.x, p.y))
        .collect();
    if !any || pts.len() < 10 {
        return None;
    }
    let s = Scorer { near, grid };
    let (gx, gy, gt) = (guess.translation.x, guess.translation.y, heading(guess));
    let guess_hits = s.hits(&pts, guess);
    // (hits, -distance) lexicographic: more hits, then nearer.
    let best = (guess_hits, 0.0f64, *guess);
    let search = |best: (usize, f64, Pose), step: f64, half: f64, astep: f64, ahalf: f64| {
        let c = best.2;
        let centre = (c.translation.x, c.translation.y, heading(&c));
        let n = (half / step).round() as i64;
        let na = (ahalf / astep).round() as i64;
        let mut local = best;
        for k in -na..=na {
            let th = centre.2 + k as f64 * astep;
            for i in -n..=n {
                for j in -n..=n {
                    let d = Vector2::new(i as f64 * step, j as f64 * step);
                    let p = pose(centre.0 + d.x, centre.1 + d.y, th);
                    let off = (Vector2::new(p.translation.x - gx, p.translation.y - gy)).norm()
                        + 0.3 * (th - gt).abs();
                    let hits = s.hits(&pts, &p);
                    if hits > local.0 || (hits == local.0 && off < local.1) {
                        local = (hits, off, p);
                    }
                }
            }
        }
        local
    };
    let best = search(best, 0.05, SEARCH_TRANSLATION, 0.02, SEARCH_ROTATION);
    let best = search(best, 0.01, 0.05, 0.005, 0.02);
    let n = pts.len() as f64;
    Some(Relocalised {
        pose: best.2,
        score: best.0 as f64 / n,
        guess_score: guess_hits as f64 / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 m × 2 m room with a box, and the points a scanner at `at` sees
    /// (sampled along the walls in view, in the scanner frame).
    fn room() -> Grid {
        let mut g = Grid::new(Point2::new(-0.5, -0.5), 0.05, 80, 60);
        for y in 0..60 {
            for x in 0..80 {
                let c = g.centre_of((x, y));
                let wall = (c.x - 0.0).abs() < 0.03
                    || (c.x - 3.0).abs() < 0.03
                    || (c.y - 0.0).abs() < 0.03
                    || (c.y - 2.0).abs() < 0.03
                    || ((1.8..2.3).contains(&c.x) && (1.0..1.3).contains(&c.y));
                let inside = (0.0..3.0).contains(&c.x) && (0.0..2.0).contains(&c.y);
                let s = if wall {
                    CellState::Occupied
                } else if inside {
                    CellState::Free
                } else {
                    CellState::Unknown
                };
                g.set_state((x, y), s);
            }
        }
        g
    }

    fn scan_from(g: &Grid, at: &Pose) -> Vec<IPoint> {
        let inv = at.inverse();
        let mut out = Vec::new();
        for y in 0..g.height() {
            for x in 0..g.width() {
                if g.state((x, y)) == CellState::Occupied {
                    let q = inv * g.centre_of((x, y));
                    out.push(IPoint::new(q.x, q.y, 0.5));
                }
            }
        }
        out
    }

    #[test]
    fn a_stale_pose_is_pulled_back_onto_the_map() {
        let g = room();
        let truth = pose(1.0, 0.8, 0.3);
        let pts = scan_from(&g, &truth);
        let stale = pose(1.35, 0.6, -0.5);
        let r = relocalise(&g, &pts, &stale).unwrap();
        let e = (r.pose.translation.vector - truth.translation.vector).norm();
        assert!(e < 0.04, "{e} m off: {r:?}");
        assert!((heading(&r.pose) - 0.3).abs() < 0.02, "{r:?}");
        assert!(r.score > 0.9 && r.guess_score < 0.5, "{r:?}");
    }

    #[test]
    fn the_first_scan_is_judged_in_place_moved_or_not_fitting() {
        let g = room();
        let truth = pose(1.0, 0.8, 0.3);
        let pts = scan_from(&g, &truth);
        // At the checkpointed pose: in place (it used to be logged as not
        // fitting, since nothing beat the guess).
        match judge(relocalise(&g, &pts, &truth)) {
            ResumeFit::InPlace(score) => assert!(score > 0.9, "{score}"),
            j => panic!("{j:?}"),
        }
        // Coasted 0.3 m: moved back onto the map.
        let stale = pose(1.3, 0.8, 0.3);
        assert!(matches!(
            judge(relocalise(&g, &pts, &stale)),
            ResumeFit::Moved(_)
        ));
        // Carried 1.5 m away (outside the search): nothing fits.
        let other = scan_from(&g, &pose(2.6, 1.6, -1.0));
        match judge(relocalise(&g, &other, &truth)) {
            ResumeFit::NoFit(Some(r)) => assert!(r.score < MIN_FIT, "{r:?}"),
            j => panic!("{j:?}"),
        }
        assert_eq!(judge(None), ResumeFit::NoFit(None));
    }

    #[test]
    fn nothing_to_match_is_none() {
        let g = Grid::new(Point2::new(0.0, 0.0), 0.05, 10, 10);
        assert!(relocalise(&g, &[], &Pose::identity()).is_none());
        let full = room();
        assert!(relocalise(&full, &[], &Pose::identity()).is_none());
    }
}
