//! How noisy is a hand-made ground truth? An estimate that does not trust it.
//!
//! The Kümmerle et al. 2009 relations were aligned by people. Where a file
//! holds a triangle of relations — `a→b` and `a→c` (from the same scan `a`) and
//! the short `b→c` — there are three independent measurements of the same
//! relative pose `b→c`: the annotated short relation, the one implied by the
//! two others (`(a→b)⁻¹·(a→c)`), and a trajectory's estimate. With pairwise
//! difference variances `V₁₂, V₁₃, V₂₃` of independent errors, each one's
//! variance follows (the "three-cornered hat" of clock metrology):
//! `σ₁² = (V₁₂ + V₁₃ − V₂₃) / 2` and so on. `σ₁` is the annotation noise of
//! the short relations; a matcher that found the exact truth would still be
//! scored, on average, `σ_θ·√(2/π)` in rotation and about `σ·√(π/2)` in
//! translation (Rayleigh mean with `σ² = (σx² + σy²) / 2`).
//!
//! A percentile bootstrap over the triangles (deterministic seed) gives the
//! uncertainty of those floors.

use super::{lookup, EvalError, Relation, Stamped, STAMP_TOLERANCE};
use crate::geom::{wrap_angle, Pose};

/// Largest `t2 − t1` (s) of a "short" relation, as in the benchmark's local group.
pub(crate) const SHORT: f64 = 1.0;

/// Three measurements of the same short relative pose `b→c`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Stamp of scan `b`.
    pub(crate) t_b: f64,
    /// Stamp of scan `c`.
    pub(crate) t_c: f64,
    /// The annotated short relation `b→c`.
    pub short: Pose,
    /// `b→c` implied by the annotated `a→b` and `a→c`.
    pub implied: Pose,
    /// `b→c` from the trajectory under test.
    pub estimate: Pose,
}

/// Finds every triangle of relations whose `b→c` leg is short and whose
/// scans `b`, `c` are in the trajectory.
pub fn triangles(relations: &[Relation], traj: &[Stamped]) -> Vec<Triangle> {
    let same = |a: f64, b: f64| (a - b).abs() <= STAMP_TOLERANCE;
    let mut out = Vec::new();
    for bc in relations.iter().filter(|r| r.t2 - r.t1 <= SHORT) {
        let (Some(pb), Some(pc)) = (lookup(traj, bc.t1), lookup(traj, bc.t2)) else {
            continue;
        };
        for ab in relations.iter().filter(|r| same(r.t2, bc.t1)) {
            for ac in relations
                .iter()
                .filter(|r| same(r.t1, ab.t1) && same(r.t2, bc.t2))
            {
                out.push(Triangle {
                    t_b: bc.t1,
                    t_c: bc.t2,
                    short: bc.delta,
                    implied: ab.delta.inverse() * ac.delta,
                    estimate: pb.inverse() * pc,
                });
            }
        }
    }
    out
}

/// Error variances of the three measurements along one axis (units², may
/// come out slightly negative when one is far smaller than the others).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HatVariances {
    /// The annotated short relation.
    pub short: f64,
    /// The relation implied by the two long ones.
    pub implied: f64,
    /// The trajectory's estimate.
    pub estimate: f64,
}

impl HatVariances {
    fn solve(v12: f64, v13: f64, v23: f64) -> Self {
        Self {
            short: (v12 + v13 - v23) / 2.0,
            implied: (v12 + v23 - v13) / 2.0,
            estimate: (v13 + v23 - v12) / 2.0,
        }
    }
}

/// A value and its 5 %–95 % bootstrap interval.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Interval {
    /// Estimate on all triangles.
    pub value: f64,
    /// 5th percentile of the bootstrap.
    pub low: f64,
    /// 95th percentile of the bootstrap.
    pub high: f64,
}

/// The noise of the annotated short relations and the score a perfect matcher would get.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TruthNoise {
    /// Triangles used.
    pub triangles: usize,
    /// Variances along x (m²).
    pub x: HatVariances,
    /// Variances along y (m²).
    pub y: HatVariances,
    /// Variances of yaw (deg²).
    pub yaw: HatVariances,
    /// Mean translational error (m) a perfect matcher would be scored on short relations.
    pub floor_trans: Interval,
    /// Mean rotational error (deg) a perfect matcher would be scored on short relations.
    pub floor_rot_deg: Interval,
    /// The trajectory's own mean (translational m, rotational deg) error on the
    /// short legs of the triangles (to compare this subset with the whole set).
    pub(crate) subset_error: (f64, f64),
}

/// Differences (x m, y m, yaw deg) between two measurements of a relative pose.
fn diff(a: &Pose, b: &Pose) -> [f64; 3] {
    [
        a.translation.x - b.translation.x,
        a.translation.y - b.translation.y,
        wrap_angle(a.rotation.angle() - b.rotation.angle()).to_degrees(),
    ]
}

fn variance(v: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = v.clone().count().max(1) as f64;
    let m = v.clone().sum::<f64>() / n;
    v.map(|x| (x - m).powi(2)).sum::<f64>() / n
}

/// Three-cornered-hat variances per axis over the triangles picked by `idx`.
fn hat(tri: &[Triangle], idx: &[usize]) -> [HatVariances; 3] {
    let mut out = [HatVariances::default(); 3];
    for (k, o) in out.iter_mut().enumerate() {
        let d = |f: fn(&Triangle) -> (Pose, Pose)| {
            idx.iter().map(move |&i| {
                let (a, b) = f(&tri[i]);
                diff(&a, &b)[k]
            })
        };
        let v12 = variance(d(|t| (t.short, t.implied)));
        let v13 = variance(d(|t| (t.short, t.estimate)));
        let v23 = variance(d(|t| (t.implied, t.estimate)));
        *o = HatVariances::solve(v12, v13, v23);
    }
    out
}

/// Floors (trans m, rot deg) of a perfect matcher from the short relations' variances.
fn floors(v: &[HatVariances; 3]) -> (f64, f64) {
    let s2 = (v[0].short.max(0.0) + v[1].short.max(0.0)) / 2.0;
    let trans = s2.sqrt() * (std::f64::consts::PI / 2.0).sqrt();
    let rot = v[2].short.max(0.0).sqrt() * (2.0 / std::f64::consts::PI).sqrt();
    (trans, rot)
}

/// splitmix64: a tiny deterministic generator for the bootstrap.
fn next(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Estimates the annotation noise of the short relations from the relation
/// triangles and `traj` (see the module documentation), with `resamples`
/// bootstrap draws (deterministic for a given `seed`).
pub fn truth_noise(
    relations: &[Relation],
    traj: &[Stamped],
    resamples: usize,
    seed: u64,
) -> Result<TruthNoise, EvalError> {
    let tri = triangles(relations, traj);
    if tri.len() < 3 {
        return Err(EvalError::TooFewTriangles { found: tri.len() });
    }
    let all: Vec<usize> = (0..tri.len()).collect();
    let v = hat(&tri, &all);
    let (ft, fr) = floors(&v);
    let mut state = seed;
    let mut bt = Vec::with_capacity(resamples);
    let mut br = Vec::with_capacity(resamples);
    let mut idx = vec![0; tri.len()];
    for _ in 0..resamples {
        for i in idx.iter_mut() {
            *i = (next(&mut state) % tri.len() as u64) as usize;
        }
        let (t, r) = floors(&hat(&tri, &idx));
        bt.push(t);
        br.push(r);
    }
    bt.sort_by(f64::total_cmp);
    br.sort_by(f64::total_cmp);
    let interval = |value: f64, s: &[f64]| Interval {
        value,
        low: percentile(s, 0.05),
        high: percentile(s, 0.95),
    };
    let n = tri.len() as f64;
    let subset_error = tri.iter().fold((0.0, 0.0), |acc, t| {
        let d = diff(&t.estimate, &t.short);
        (acc.0 + d[0].hypot(d[1]) / n, acc.1 + d[2].abs() / n)
    });
    Ok(TruthNoise {
        triangles: tri.len(),
        x: v[0],
        y: v[1],
        yaw: v[2],
        floor_trans: interval(ft, &bt),
        floor_rot_deg: interval(fr, &br),
        subset_error,
    })
}

/// Signed square root: the standard deviation of a variance estimate that may be negative.
fn sd(v: f64) -> f64 {
    v.signum() * v.abs().sqrt()
}

impl std::fmt::Display for TruthNoise {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "ground-truth noise from {} relation triangles (a→b, a→c, short b→c), three-cornered hat:",
            self.triangles
        )?;
        writeln!(
            f,
            "{:<26} {:>10} {:>10} {:>10}",
            "error sd of", "x [m]", "y [m]", "yaw [deg]"
        )?;
        for (name, g) in [
            (
                "annotated short b→c",
                (|h: &HatVariances| h.short) as fn(&HatVariances) -> f64,
            ),
            ("implied by a→b, a→c", |h| h.implied),
            ("this trajectory", |h| h.estimate),
        ] {
            writeln!(
                f,
                "{:<26} {:>10.4} {:>10.4} {:>10.3}",
                name,
                sd(g(&self.x)),
                sd(g(&self.y)),
                sd(g(&self.yaw))
            )?;
        }
        writeln!(
            f,
            "a perfect matcher would score on short relations: trans {:.4} m [90 %: {:.4}..{:.4}], rot {:.3} deg [90 %: {:.3}..{:.3}]",
            self.floor_trans.value,
            self.floor_trans.low,
            self.floor_trans.high,
            self.floor_rot_deg.value,
            self.floor_rot_deg.low,
            self.floor_rot_deg.high
        )?;
        writeln!(
            f,
            "this trajectory on the triangles' short legs: trans {:.4} m, rot {:.3} deg",
            self.subset_error.0, self.subset_error.1
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    fn gauss(state: &mut u64) -> f64 {
        // Box-Muller from two uniforms in (0, 1].
        let u = |s: &mut u64| ((next(s) >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
        let (a, b) = (u(state), u(state));
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }

    fn noisy(p: &Pose, s_xy: f64, s_th: f64, st: &mut u64) -> Pose {
        *p * pose(s_xy * gauss(st), s_xy * gauss(st), s_th * gauss(st))
    }

    /// Relations with known annotation noise, a trajectory with known noise:
    /// the hat recovers both.
    #[test]
    fn recovers_known_noise_levels() {
        let mut st = 7u64;
        let mut traj = Vec::new();
        let mut truth = Vec::new();
        let mut rels = Vec::new();
        let mut p = pose(0.0, 0.0, 0.0);
        let (s_gt, th_gt) = (0.02, 0.3f64.to_radians());
        let (s_est, th_est) = (0.005, 0.1f64.to_radians());
        for k in 0..3000 {
            let t = k as f64 * 0.2;
            p *= pose(0.2, 0.0, 0.05 * (k as f64 * 0.01).sin());
            truth.push(Stamped { t, pose: p });
            // Independent per-scan estimate noise of sd s/√2 gives relation noise s.
            let e = noisy(&p, s_est / 2f64.sqrt(), th_est / 2f64.sqrt(), &mut st);
            traj.push(Stamped { t, pose: e });
        }
        for k in (0..2990).step_by(3) {
            let (a, b, c) = (&truth[k], &truth[k + 5], &truth[k + 7]);
            for (x, y) in [(a, b), (a, c), (b, c)] {
                rels.push(Relation {
                    t1: x.t,
                    t2: y.t,
                    delta: noisy(&(x.pose.inverse() * y.pose), s_gt, th_gt, &mut st),
                });
            }
        }
        let r = truth_noise(&rels, &traj, 200, 1).unwrap();
        assert!(r.triangles >= 990, "{r}");
        let rel_err = |got: f64, want: f64| (got - want).abs() / want;
        assert!(rel_err(sd(r.yaw.short), 0.3) < 0.15, "{r}");
        assert!(rel_err(sd(r.x.short), s_gt) < 0.15, "{r}");
        // A small variance is a difference of large ones: only its order of magnitude is sure.
        assert!(sd(r.yaw.estimate) < 0.2 && sd(r.yaw.implied) > 0.35, "{r}");
        // The floor of a perfect matcher: Rayleigh / half-normal means of the annotation noise.
        let want_t = s_gt * (std::f64::consts::PI / 2.0).sqrt();
        let want_r = 0.3 * (2.0 / std::f64::consts::PI).sqrt();
        assert!(rel_err(r.floor_trans.value, want_t) < 0.15, "{r}");
        assert!(rel_err(r.floor_rot_deg.value, want_r) < 0.15, "{r}");
        assert!(r.floor_rot_deg.low <= r.floor_rot_deg.value);
        assert!(r.floor_rot_deg.value <= r.floor_rot_deg.high);
        // Deterministic.
        assert_eq!(r, truth_noise(&rels, &traj, 200, 1).unwrap());
    }

    #[test]
    fn no_triangles_is_an_error() {
        let traj = vec![
            Stamped {
                t: 0.0,
                pose: pose(0.0, 0.0, 0.0),
            },
            Stamped {
                t: 0.5,
                pose: pose(0.1, 0.0, 0.0),
            },
        ];
        let rels = vec![Relation {
            t1: 0.0,
            t2: 0.5,
            delta: pose(0.1, 0.0, 0.0),
        }];
        let e = truth_noise(&rels, &traj, 10, 1).unwrap_err();
        assert!(e.to_string().contains("triangle"), "{e}");
    }
}
