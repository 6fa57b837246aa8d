//! Where the error of the short (≤ 1 s) relations comes from: its
//! distribution, its bias, how it grows with the turn, and how much of it two
//! trajectories share (an error both make comes from the data or from the
//! ground truth, not from what differs between the two).

use super::truth_noise::SHORT;
use super::{lookup, Relation, Stamped};
use crate::geom::{wrap_angle, Pose};

/// Signed error of one short relation (estimate − truth).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelationError {
    /// First stamp (s).
    pub t1: f64,
    /// Duration t2 − t1 (s).
    pub dt: f64,
    /// True yaw of the relation (deg).
    pub(crate) true_yaw_deg: f64,
    /// x error in the frame of t1 (m).
    pub dx: f64,
    /// y error in the frame of t1 (m).
    pub dy: f64,
    /// Yaw error (deg, wrapped).
    pub(crate) dyaw_deg: f64,
}

/// The signed errors of every short relation both of whose stamps are in `traj`.
pub fn short_errors(relations: &[Relation], traj: &[Stamped]) -> Vec<RelationError> {
    relations
        .iter()
        .filter(|r| r.t2 - r.t1 <= SHORT)
        .filter_map(|r| {
            let (p1, p2) = (lookup(traj, r.t1)?, lookup(traj, r.t2)?);
            let est: Pose = p1.inverse() * p2;
            Some(RelationError {
                t1: r.t1,
                dt: r.t2 - r.t1,
                true_yaw_deg: r.delta.rotation.angle().to_degrees(),
                dx: est.translation.x - r.delta.translation.x,
                dy: est.translation.y - r.delta.translation.y,
                dyaw_deg: wrap_angle(est.rotation.angle() - r.delta.rotation.angle()).to_degrees(),
            })
        })
        .collect()
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// Upper bounds (deg) of the |true yaw| bins of [`breakdown`].
pub(crate) const TURN_BINS: [f64; 5] = [0.5, 2.0, 5.0, 10.0, 30.0];

/// A text report of the short relations' rotational error: quantiles, the
/// mean without the worst relations, the bias, and the mean by size of the turn.
pub fn breakdown(errors: &[RelationError]) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let mut abs: Vec<f64> = errors.iter().map(|e| e.dyaw_deg.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let n = abs.len();
    let _ = writeln!(
        s,
        "short relations: {n}; |rot error| [deg]: mean {:.3}, median {:.3}, p90 {:.3}, p99 {:.3}, max {:.3}",
        mean(abs.iter().copied()),
        quantile(&abs, 0.5),
        quantile(&abs, 0.9),
        quantile(&abs, 0.99),
        abs.last().copied().unwrap_or(f64::NAN)
    );
    let _ = writeln!(
        s,
        "mean without the worst 1 % / 5 % / 10 %: {:.3} / {:.3} / {:.3} deg (over all {n}); signed mean (bias) {:+.3} deg",
        abs[..n - n / 100].iter().sum::<f64>() / n.max(1) as f64,
        abs[..n - n / 20].iter().sum::<f64>() / n.max(1) as f64,
        abs[..n - n / 10].iter().sum::<f64>() / n.max(1) as f64,
        mean(errors.iter().map(|e| e.dyaw_deg))
    );
    let mut lo = 0.0;
    for hi in TURN_BINS.iter().copied().chain([f64::INFINITY]) {
        let bin: Vec<&RelationError> = errors
            .iter()
            .filter(|e| (lo..hi).contains(&e.true_yaw_deg.abs()))
            .collect();
        let _ = writeln!(
            s,
            "  |true yaw| {lo:>4}..{hi:<4} deg: n {:>4}  rot {:.3} deg  signed {:+.3} deg  trans {:.4} m",
            bin.len(),
            mean(bin.iter().map(|e| e.dyaw_deg.abs())),
            mean(bin.iter().map(|e| e.dyaw_deg)),
            mean(bin.iter().map(|e| e.dx.hypot(e.dy)))
        );
        lo = hi;
    }
    s
}

/// How much two trajectories' signed errors on the same relations agree, per
/// component (x m, y m, yaw deg).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Shared {
    /// Relations compared.
    pub count: usize,
    /// Correlation of the signed errors.
    pub(crate) correlation: [f64; 3],
    /// Standard deviation of the common part (√ of the covariance, 0 if negative).
    pub(crate) common_sd: [f64; 3],
    /// Standard deviations of the two error series.
    pub sd: [[f64; 3]; 2],
}

/// Compares the errors of two trajectories on the short relations both cover.
pub fn shared(a: &[RelationError], b: &[RelationError]) -> Shared {
    let pairs: Vec<(&RelationError, &RelationError)> = a
        .iter()
        .filter_map(|x| {
            b.iter()
                .find(|y| y.t1 == x.t1 && y.dt == x.dt)
                .map(|y| (x, y))
        })
        .collect();
    let comp = |e: &RelationError, k: usize| [e.dx, e.dy, e.dyaw_deg][k];
    let mut out = Shared {
        count: pairs.len(),
        ..Shared::default()
    };
    for k in 0..3 {
        let ma = mean(pairs.iter().map(|p| comp(p.0, k)));
        let mb = mean(pairs.iter().map(|p| comp(p.1, k)));
        let cov = mean(
            pairs
                .iter()
                .map(|p| (comp(p.0, k) - ma) * (comp(p.1, k) - mb)),
        );
        let va = mean(pairs.iter().map(|p| (comp(p.0, k) - ma).powi(2)));
        let vb = mean(pairs.iter().map(|p| (comp(p.1, k) - mb).powi(2)));
        out.correlation[k] = cov / (va * vb).sqrt();
        out.common_sd[k] = cov.max(0.0).sqrt();
        out.sd[0][k] = va.sqrt();
        out.sd[1][k] = vb.sqrt();
    }
    out
}

impl std::fmt::Display for Shared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "signed errors of the two trajectories on {} short relations:",
            self.count
        )?;
        for (k, name) in ["x [m]", "y [m]", "yaw [deg]"].iter().enumerate() {
            writeln!(
                f,
                "  {name:<10} sd {:.4} / {:.4}  correlation {:.3}  common part sd {:.4}",
                self.sd[0][k], self.sd[1][k], self.correlation[k], self.common_sd[k]
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    fn traj(yaw_noise: &[f64]) -> Vec<Stamped> {
        yaw_noise
            .iter()
            .enumerate()
            .map(|(i, n)| Stamped {
                t: i as f64 * 0.2,
                pose: pose(i as f64 * 0.1, 0.0, 0.1 * i as f64 + n.to_radians()),
            })
            .collect()
    }

    #[test]
    fn errors_bias_and_shared_part_are_measured() {
        let truth = traj(&[0.0; 6]);
        let rels: Vec<Relation> = (0..5)
            .map(|i| Relation {
                t1: truth[i].t,
                t2: truth[i + 1].t,
                delta: truth[i].pose.inverse() * truth[i + 1].pose,
            })
            .collect();
        // Estimate a: yaw off by +1 deg at scan 2 only; b: the same plus 0.5 deg at scan 4.
        let a = short_errors(&rels, &traj(&[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]));
        let b = short_errors(&rels, &traj(&[0.0, 0.0, 1.0, 0.0, 0.5, 0.0]));
        assert_eq!(a.len(), 5);
        assert!((a[1].dyaw_deg - 1.0).abs() < 1e-9 && (a[2].dyaw_deg + 1.0).abs() < 1e-9);
        assert!(a[0].dyaw_deg.abs() < 1e-9);
        let text = breakdown(&a);
        assert!(text.contains("mean 0.400"), "{text}");
        assert!(text.contains("signed mean (bias) +0.000"), "{text}");
        let s = shared(&a, &b);
        assert_eq!(s.count, 5);
        assert!(s.correlation[2] > 0.5 && s.correlation[2] < 1.0, "{s}");
        assert!((shared(&a, &a).correlation[2] - 1.0).abs() < 1e-9);
    }
}
