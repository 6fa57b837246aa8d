//! The matcher: registers one scan against a [`Reference`] by intensity-ICP.
//!
//! Each iteration pairs every scan point with its nearest reference point in
//! (x, y, √w·l) space, drops pairs beyond an adaptive gate, trims the worst
//! pairs, then solves for the rigid pose in closed form (point-to-point) or by
//! one linear 3×3 solve (point-to-line). With `w` > 0 the point-to-line solve
//! also pairs the scan's intensity edges (a marker's borders) with the
//! reference's, edge to edge: each pair pins the pose along its surface,
//! where the point-to-line rows of a featureless wall say nothing. All buffers are owned by the
//! [`Matcher`] and reused: a match does not allocate once they have grown to
//! the scan size.

use nalgebra::{Matrix3, Vector2, Vector3};

use super::reference::{edge_after, EdgeFeature};
use super::{IcpError, IcpParams, Metric, Reference};
use crate::capacity::MAX_BEAMS;
use crate::geom::{IPoint, Pose};
use crate::param_check::ParamError;
use crate::scan::LaserScan;

/// How good a match is, so the caller can accept it or fall back to its prior.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quality {
    /// Correspondences used in the last solve (after gating and trimming).
    pub pairs: usize,
    /// Share of the usable scan points that found a partner inside the gate.
    pub inlier_ratio: f64,
    /// Root mean square residual of the used pairs in the chosen metric (m).
    pub residual_rms: f64,
    /// Iterations run.
    pub iterations: u32,
    /// True when the update fell below ε before the iteration cap.
    pub converged: bool,
    /// Smallest eigenvalue of the normalised information matrix Σ JᵀJ / pairs
    /// (point-to-line Jacobian, rotation scaled by the scan radius): near 0 the
    /// scan does not constrain some direction.
    pub min_eigenvalue: f64,
    /// True when some direction is unconstrained (a single wall, a featureless
    /// corridor). Along [`Quality::weak_direction`] the pose is then kept at the
    /// initial guess rather than guessed from the data.
    pub degenerate: bool,
    /// Unit eigenvector (dx, dy, r·dθ) of the smallest eigenvalue.
    pub weak_direction: Vector3<f64>,
    /// Covariance of the pose's (x, y, θ) in the reference frame (m², rad²),
    /// from the residual variance and the information matrix; `None` when
    /// degenerate. `tests/icp_covariance.rs` checks it against the spread of
    /// many matches.
    pub covariance: Option<Matrix3<f64>>,
    /// Distance between the result and the initial guess (m).
    pub correction_translation: f64,
    /// Rotation between the result and the initial guess (rad).
    pub correction_rotation: f64,
    /// Intensity edges of the scan paired with edges of the reference in
    /// the last solve (0 when `w` = 0).
    pub edge_pairs: usize,
}

/// Why a successful match was nonetheless judged unreliable.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum Rejection {
    /// Too few scan points found a partner.
    #[error("only {ratio:.2} of the scan points matched (minimum {min:.2})")]
    LowInlierRatio {
        /// Share that matched.
        ratio: f64,
        /// The `icp.min_inlier_ratio` setting.
        min: f64,
    },
    /// The pairs do not fit well after convergence.
    #[error("residual {rms:.3} m after convergence (maximum {max:.3} m)")]
    HighResidual {
        /// RMS residual (m).
        rms: f64,
        /// The `icp.max_residual` setting.
        max: f64,
    },
    /// The match moved the guess implausibly far.
    #[error("the match corrected the guess by {translation:.3} m / {rotation:.3} rad, beyond the limits")]
    TooLargeCorrection {
        /// Translation correction (m).
        translation: f64,
        /// Rotation correction (rad).
        rotation: f64,
    },
}

impl Quality {
    /// Checks the quality against the acceptance limits of `params`.
    pub fn check(&self, params: &IcpParams) -> Result<(), Rejection> {
        if self.inlier_ratio < params.min_inlier_ratio {
            return Err(Rejection::LowInlierRatio {
                ratio: self.inlier_ratio,
                min: params.min_inlier_ratio,
            });
        }
        if self.residual_rms > params.max_residual {
            return Err(Rejection::HighResidual {
                rms: self.residual_rms,
                max: params.max_residual,
            });
        }
        if self.correction_translation > params.max_correction_translation
            || self.correction_rotation > params.max_correction_rotation
        {
            return Err(Rejection::TooLargeCorrection {
                translation: self.correction_translation,
                rotation: self.correction_rotation,
            });
        }
        Ok(())
    }
}

/// The result of a match: the pose of the scan's frame in the reference frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Match {
    /// Estimated pose of the scan in the reference frame.
    pub pose: Pose,
    /// Quality report.
    pub quality: Quality,
}

#[derive(Clone, Copy, Debug, Default)]
struct Pair {
    /// Scan point, sensor frame.
    q: IPoint,
    /// Reference index.
    p: u32,
    /// Squared distance in (x, y, √w·l) space at pairing time.
    d2: f64,
}

/// A scan edge paired with a reference edge.
#[derive(Clone, Copy, Debug)]
struct EdgePair {
    /// Where the scan's edge lies, sensor frame.
    q: Vector2<f64>,
    /// Reference edge index.
    p: u32,
    /// Weight of the pair's row against a point-to-line row ([`edge_weight`]).
    weight: f64,
}

/// Two edges pair only when their rising directions agree within this
/// cosine (30°): same surface direction, same sense (dark to bright).
const EDGE_ALIGN: f64 = 0.866;
/// Standard deviation (m) of a point-to-line row's residual that an edge
/// row is weighed against: the URG-04LX's range noise, about a centimetre.
const ROW_NOISE: f64 = 0.01;

/// Weight of an edge pair's row against a point-to-line row: each edge lies
/// anywhere between its two points (a uniform spread of `spacing`² / 12),
/// on top of the range noise. An edge seen at a grazing angle, its points
/// 12 cm apart, weighs 0.08; one seen head-on at 2 m (2.4 cm), 0.6.
fn edge_weight(scan_spacing: f64, reference_spacing: f64) -> f64 {
    let n2 = ROW_NOISE * ROW_NOISE;
    EDGE_GAIN * n2
        / (n2 + (scan_spacing * scan_spacing + reference_spacing * reference_spacing) / 12.0)
}

/// How many point-to-line rows of equal noise one edge row counts as. The
/// residuals of a wall's hundred points are not independent (one surface,
/// one normal's error), an edge's are; and the degeneracy floor is a share
/// of the row count. Corridor world, seed 1, `w` = 0.05: gain 3 gave
/// 108 mm position RMSE, gain 10 54 mm (1 without gain: degenerate along
/// the corridor in `tests/icp_intensity.rs`).
const EDGE_GAIN: f64 = 10.0;

/// A reusable scan matcher. Holds its parameters and work buffers.
#[derive(Debug)]
pub struct Matcher {
    params: IcpParams,
    /// [`trimmed_variance_share`] of `params.trim_fraction`.
    trimmed_share: f64,
    scan: Vec<IPoint>,
    pairs: Vec<Pair>,
    tmp: Vec<f64>,
    /// Intensity edges of the prepared scan, sensor frame.
    scan_edges: Vec<EdgeFeature>,
    edge_pairs: Vec<EdgePair>,
}

impl Matcher {
    /// A matcher with `params` (checked) and buffers for [`MAX_BEAMS`] points.
    pub fn new(params: IcpParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(Self {
            trimmed_share: trimmed_variance_share(params.trim_fraction),
            params,
            scan: Vec::with_capacity(MAX_BEAMS),
            pairs: Vec::with_capacity(MAX_BEAMS),
            tmp: Vec::with_capacity(MAX_BEAMS),
            scan_edges: Vec::with_capacity(MAX_BEAMS),
            edge_pairs: Vec::with_capacity(MAX_BEAMS),
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &IcpParams {
        &self.params
    }

    /// The scan points (sensor frame) used by the last match, after filtering and thinning.
    pub fn prepared_points(&self) -> &[IPoint] {
        &self.scan
    }

    /// Filters `points` (sensor frame) into the matcher's scan buffer: drops
    /// non-finite values and ranges outside [min_range, max_range), thins
    /// successive points closer than `min_point_spacing`. Returns the count kept.
    pub fn prepare_points(&mut self, points: &[IPoint]) -> Result<usize, IcpError> {
        if points.is_empty() {
            return Err(IcpError::EmptyScan);
        }
        self.scan.clear();
        for p in points {
            self.push_filtered(*p);
        }
        self.check_prepared(points.len())
    }

    /// Like [`Matcher::prepare_points`], from a scan's valid beams.
    pub(crate) fn prepare_scan(&mut self, scan: &LaserScan) -> Result<usize, IcpError> {
        if scan.beams.is_empty() {
            return Err(IcpError::EmptyScan);
        }
        self.scan.clear();
        for b in scan.beams.iter().filter(|b| b.valid) {
            if !(b.range.is_finite() && b.angle.is_finite()) {
                continue;
            }
            let (s, c) = b.angle.sin_cos();
            self.push_filtered(IPoint::new(b.range * c, b.range * s, b.intensity));
        }
        self.check_prepared(scan.beams.len())
    }

    fn push_filtered(&mut self, p: IPoint) {
        if !(p.x.is_finite() && p.y.is_finite() && p.intensity.is_finite()) {
            return;
        }
        let r = p.x.hypot(p.y);
        if r < self.params.min_range || r >= self.params.max_range {
            return;
        }
        if let Some(last) = self.scan.last() {
            let s = self.params.min_point_spacing;
            if (p.x - last.x).powi(2) + (p.y - last.y).powi(2) < s * s {
                return;
            }
        }
        if self.scan.len() < MAX_BEAMS {
            self.scan.push(p);
        }
    }

    fn check_prepared(&mut self, total: usize) -> Result<usize, IcpError> {
        self.scan_edges.clear();
        for i in 0..self.scan.len() {
            if let Some(e) = edge_after(&self.scan, i, &self.params) {
                self.scan_edges.push(e);
            }
        }
        let n = self.scan.len();
        if n == 0 {
            return Err(IcpError::NoValidPoints { total });
        }
        if n < self.params.min_pairs {
            return Err(IcpError::TooFewScanPoints {
                have: n,
                need: self.params.min_pairs,
            });
        }
        Ok(n)
    }

    /// Registers `points` (sensor frame) against `reference`, starting from `guess`.
    pub fn match_points(
        &mut self,
        reference: &Reference,
        points: &[IPoint],
        guess: &Pose,
    ) -> Result<Match, IcpError> {
        self.prepare_points(points)?;
        self.match_prepared(reference, guess)
    }

    /// Registers the valid beams of `scan` against `reference`, starting from `guess`.
    pub fn match_scan(
        &mut self,
        reference: &Reference,
        scan: &LaserScan,
        guess: &Pose,
    ) -> Result<Match, IcpError> {
        self.prepare_scan(scan)?;
        self.match_prepared(reference, guess)
    }

    /// Registers the points last given to a `prepare_*` method, with the
    /// guess held by the configured `prior_weight` (see [`Matcher::match_prepared_weighted`]).
    pub(crate) fn match_prepared(
        &mut self,
        reference: &Reference,
        guess: &Pose,
    ) -> Result<Match, IcpError> {
        let w = self.params.prior_weight;
        self.match_prepared_weighted(reference, guess, w)
    }

    /// Registers the prepared points; `prior_weight` >= 0 adds a penalty on the
    /// translation away from `guess` (point-to-line metric only), worth
    /// `prior_weight` pairs per unit of squared distance: directions the scan
    /// constrains weakly then follow the prior (e.g. wheel odometry) instead of noise.
    pub fn match_prepared_weighted(
        &mut self,
        reference: &Reference,
        guess: &Pose,
        prior_weight: f64,
    ) -> Result<Match, IcpError> {
        let prm = self.params.clone();
        if self.scan.len() < prm.min_pairs {
            return Err(if self.scan.is_empty() {
                IcpError::EmptyScan
            } else {
                IcpError::TooFewScanPoints {
                    have: self.scan.len(),
                    need: prm.min_pairs,
                }
            });
        }
        if reference.is_empty() || reference.len() < prm.min_pairs {
            return Err(IcpError::TooFewReferencePoints {
                have: reference.len(),
                need: prm.min_pairs,
            });
        }
        let g = guess.translation.vector;
        let ga = guess.rotation.angle();
        if !(g.x.is_finite() && g.y.is_finite() && ga.is_finite()) {
            return Err(IcpError::BadInitialGuess);
        }

        let mut pose = *guess;
        let mut before = *guess;
        let mut gate = prm.gate_initial;
        let mut iterations = 0;
        let mut converged = false;
        let mut gated = 0;
        for it in 0..prm.max_iterations {
            iterations = it + 1;
            gated = self.pair(reference, &pose, gate);
            let used = self.trim(gated);
            self.pair_edges(reference, &pose, prm.gate_initial);
            if used < prm.min_pairs {
                return Err(IcpError::TooFewPairs {
                    pairs: used,
                    need: prm.min_pairs,
                    iteration: it,
                });
            }
            let next = match prm.metric {
                Metric::PointToPoint => solve_point_to_point(&self.pairs, reference),
                Metric::PointToLine => solve_point_to_line(
                    &self.pairs,
                    &self.edge_pairs,
                    reference,
                    &pose,
                    guess,
                    prior_weight.max(0.0),
                    prm.degeneracy_threshold,
                ),
            };
            let next = next.ok_or(IcpError::Diverged { iteration: it })?;
            // The step seen from the scanner (free of the lever arm of world coordinates).
            let step = pose.inverse() * next;
            let (dt, dr) = (step.translation.vector.norm(), step.rotation.angle().abs());
            if !(dt.is_finite() && dr.is_finite()) {
                return Err(IcpError::Diverged { iteration: it });
            }
            // Nearest-neighbour pairing can flip between two pair sets; a
            // return to the pose of two iterations ago is a 2-cycle: stop.
            let back = before.inverse() * next;
            let cycle = it > 0
                && back.translation.vector.norm() < prm.epsilon_translation
                && back.rotation.angle().abs() < prm.epsilon_rotation;
            before = pose;
            pose = next;
            gate = self.adapt_gate(gate);
            if cycle || (dt < prm.epsilon_translation && dr < prm.epsilon_rotation) {
                converged = true;
                break;
            }
        }
        // Final report on the converged pose with the last pairs.
        self.pair_edges(reference, &pose, prm.gate_initial);
        let info = information(
            &self.pairs,
            &self.edge_pairs,
            reference,
            &pose,
            prm.degeneracy_threshold,
        );
        if info.degenerate {
            pose = keep_guess_along(&pose, guess, &info);
        }
        let residual_rms = residual_rms(&self.pairs, reference, &pose, prm.metric);
        let covariance = if info.degenerate {
            None
        } else {
            // The residuals left after trimming are the smallest ones: their
            // mean square understates the noise's variance.
            let n = self.pairs.len() as f64;
            let sigma2 = residual_rms * residual_rms * n / (n - 3.0).max(1.0) / self.trimmed_share;
            info.raw
                .try_inverse()
                .map(|inv| about_origin(&inv, &pose, &info.centre) * sigma2)
        };
        let dpos = (pose.translation.vector - guess.translation.vector).norm();
        let drot = crate::geom::wrap_angle(pose.rotation.angle() - guess.rotation.angle()).abs();
        Ok(Match {
            pose,
            quality: Quality {
                pairs: self.pairs.len(),
                inlier_ratio: gated as f64 / self.scan.len() as f64,
                residual_rms,
                iterations,
                converged,
                min_eigenvalue: info.min_eigenvalue,
                degenerate: info.degenerate,
                weak_direction: info.weak,
                covariance,
                correction_translation: dpos,
                correction_rotation: drot,
                edge_pairs: self.edge_pairs.len(),
            },
        })
    }

    /// Pairs each scan point (moved by `pose`) with its nearest reference point
    /// inside `gate`; returns how many pairs passed.
    fn pair(&mut self, reference: &Reference, pose: &Pose, gate: f64) -> usize {
        self.pairs.clear();
        let s = reference.intensity_scale();
        let g2 = gate * gate;
        let (sin, cos) = pose.rotation.angle().sin_cos();
        let t = pose.translation.vector;
        for q in &self.scan {
            let x = cos * q.x - sin * q.y + t.x;
            let y = sin * q.x + cos * q.y + t.y;
            if let Some((idx, d2)) = reference.nearest_within(&[x, y, s * q.intensity], g2) {
                self.pairs.push(Pair {
                    q: *q,
                    p: idx as u32,
                    d2,
                });
            }
        }
        self.pairs.len()
    }

    /// Keeps the best `trim_fraction` of the pairs; returns how many remain.
    fn trim(&mut self, gated: usize) -> usize {
        let keep = ((gated as f64 * self.params.trim_fraction).ceil() as usize).min(gated);
        if keep >= gated || keep == 0 {
            return self.pairs.len();
        }
        self.pairs
            .select_nth_unstable_by(keep - 1, |a, b| a.d2.total_cmp(&b.d2));
        self.pairs.truncate(keep);
        self.pairs.len()
    }

    /// Pairs each intensity edge of the scan (moved by `pose`) with the
    /// nearest reference edge of the same sense within `gate` (m: the
    /// initial gate, the most a match may correct; marker borders of one
    /// sense lie farther apart than that in any sensible marking). The
    /// reference holds tens of edges: a plain search is cheapest. (The
    /// point-to-point solve, the paper's closed form, does not use them; its
    /// degeneracy check does.)
    fn pair_edges(&mut self, reference: &Reference, pose: &Pose, gate: f64) {
        self.edge_pairs.clear();
        let refs = reference.intensity_edges();
        if refs.is_empty() {
            return;
        }
        for e in &self.scan_edges {
            let at = (pose * nalgebra::Point2::from(e.at)).coords;
            let rise = pose.rotation * e.rise;
            let mut best = (u32::MAX, gate * gate);
            for (j, r) in refs.iter().enumerate() {
                let d2 = (r.at - at).norm_squared();
                if d2 < best.1 && r.rise.dot(&rise) >= EDGE_ALIGN {
                    best = (j as u32, d2);
                }
            }
            if best.0 != u32::MAX {
                self.edge_pairs.push(EdgePair {
                    q: e.at,
                    p: best.0,
                    weight: edge_weight(e.spacing, refs[best.0 as usize].spacing),
                });
            }
        }
    }

    /// Shrinks the gate towards `gate_sigmas` × the robust spread of the pair distances.
    fn adapt_gate(&mut self, gate: f64) -> f64 {
        self.tmp.clear();
        self.tmp.extend(self.pairs.iter().map(|p| p.d2));
        if self.tmp.is_empty() {
            return gate;
        }
        let mid = self.tmp.len() / 2;
        let (_, m, _) = self.tmp.select_nth_unstable_by(mid, f64::total_cmp);
        let sigma = 1.4826 * m.sqrt();
        (self.params.gate_sigmas * sigma).clamp(self.params.gate_min, gate)
    }
}

/// Closed-form least-squares rigid transform mapping the pairs' scan points
/// onto their reference points (centroids and the 2-D Kabsch angle).
fn solve_point_to_point(pairs: &[Pair], reference: &Reference) -> Option<Pose> {
    let refp = reference.points();
    let n = pairs.len() as f64;
    let (mut qx, mut qy, mut px, mut py) = (0.0, 0.0, 0.0, 0.0);
    for pr in pairs {
        let p = &refp[pr.p as usize];
        qx += pr.q.x;
        qy += pr.q.y;
        px += p.x;
        py += p.y;
    }
    let (qx, qy, px, py) = (qx / n, qy / n, px / n, py / n);
    let (mut sdot, mut scross) = (0.0, 0.0);
    for pr in pairs {
        let p = &refp[pr.p as usize];
        let (ax, ay) = (pr.q.x - qx, pr.q.y - qy);
        let (bx, by) = (p.x - px, p.y - py);
        sdot += ax * bx + ay * by;
        scross += ax * by - ay * bx;
    }
    let theta = scross.atan2(sdot);
    let (s, c) = theta.sin_cos();
    let tx = px - (c * qx - s * qy);
    let ty = py - (s * qx + c * qy);
    let pose = crate::geom::pose(tx, ty, theta);
    (tx.is_finite() && ty.is_finite() && theta.is_finite()).then_some(pose)
}

/// Calls `f(J, r)` for the point-to-line row of one pair at `pose`
/// (Jacobian over (dx, dy, radius·dθ) about `c`). Returns false when the
/// pair gives no row (no surface normal).
#[inline]
fn rows(
    pr: &Pair,
    reference: &Reference,
    pose: &Pose,
    c: &Vector2<f64>,
    radius: f64,
    mut f: impl FnMut(Vector3<f64>, f64),
) -> bool {
    let i = pr.p as usize;
    let q = pose * pr.q.xy();
    let p = &reference.points()[i];
    let d = Vector2::new(q.x - c.x, q.y - c.y);
    let n = reference.normals()[i];
    if n.x == 0.0 && n.y == 0.0 {
        return false;
    }
    let j = Vector3::new(n.x, n.y, (n.y * d.x - n.x * d.y) / radius);
    f(j, n.x * (q.x - p.x) + n.y * (q.y - p.y));
    true
}

/// Calls `f(J, r)` for the row of one edge pair at `pose`: the distance
/// between the two edges along the reference edge's surface.
#[inline]
fn edge_row(
    ep: &EdgePair,
    reference: &Reference,
    pose: &Pose,
    c: &Vector2<f64>,
    radius: f64,
    mut f: impl FnMut(Vector3<f64>, f64),
) {
    let r = &reference.intensity_edges()[ep.p as usize];
    let q = pose * nalgebra::Point2::from(ep.q);
    let t = r.rise;
    let d = Vector2::new(q.x - c.x, q.y - c.y);
    let j = Vector3::new(t.x, t.y, (t.y * d.x - t.x * d.y) / radius);
    f(j, t.x * (q.x - r.at.x) + t.y * (q.y - r.at.y));
}

/// One Gauss-Newton step of the point-to-line error (and the edge rows)
/// about the centroid of the moved scan points. Directions whose normalised
/// information is below `threshold` are not updated (they keep the current
/// estimate).
fn solve_point_to_line(
    pairs: &[Pair],
    edges: &[EdgePair],
    reference: &Reference,
    pose: &Pose,
    prior: &Pose,
    prior_weight: f64,
    threshold: f64,
) -> Option<Pose> {
    let (c, radius) = centroid_radius(pairs, pose);
    let mut h = Matrix3::zeros();
    let mut g = Vector3::zeros();
    let mut used = 0usize;
    for pr in pairs {
        let counted = rows(pr, reference, pose, &c, radius, |j, r| {
            h += j * j.transpose();
            g += j * r;
        });
        used += usize::from(counted);
    }
    if used < 3 {
        return None;
    }
    for ep in edges {
        edge_row(ep, reference, pose, &c, radius, |j, r| {
            h += j * j.transpose() * ep.weight;
            g += j * r * ep.weight;
        });
    }
    if prior_weight > 0.0 {
        // Prior term: the scan centroid c = pose(q_c) pulled towards prior(q_c).
        let qc = pose.inverse() * nalgebra::Point2::from(c);
        let pc = prior * qc;
        let lam = prior_weight * used as f64;
        h[(0, 0)] += lam;
        h[(1, 1)] += lam;
        g.x += lam * (c.x - pc.x);
        g.y += lam * (c.y - pc.y);
    }
    let e = h.symmetric_eigen();
    let floor = threshold * used as f64;
    let mut x = Vector3::zeros();
    for k in 0..3 {
        let lam = e.eigenvalues[k];
        if lam > floor && lam > 0.0 {
            let v = e.eigenvectors.column(k);
            x -= v * (v.dot(&g) / lam);
        }
    }
    Some(apply_about(pose, &c, x.x, x.y, x.z / radius))
}

/// `pose` moved by a rotation `dth` about world point `c` and a translation (dx, dy).
fn apply_about(pose: &Pose, c: &Vector2<f64>, dx: f64, dy: f64, dth: f64) -> Pose {
    let (s, co) = dth.sin_cos();
    // delta(x) = R(dth)(x - c) + c + d
    let tx = c.x - (co * c.x - s * c.y) + dx;
    let ty = c.y - (s * c.x + co * c.y) + dy;
    let p = crate::geom::pose(tx, ty, dth) * pose;
    // Rebuilt from its angle: products of unit complex numbers drift off unit length.
    crate::geom::pose(p.translation.x, p.translation.y, p.rotation.angle())
}

/// The share of a normal distribution's variance left in the central
/// `kept` fraction of it: E[z² ; |z| < a] / `kept` with P(|z| < a) =
/// `kept`, for z standard normal (1 when nothing is trimmed). Trimming the
/// worst pairs leaves residuals whose mean square is this share of the
/// noise's variance (0.62 when a tenth is trimmed).
fn trimmed_variance_share(kept: f64) -> f64 {
    if !(kept > 0.0 && kept < 1.0) {
        return 1.0;
    }
    let pdf = |z: f64| (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt();
    // P(|z| < a) by Simpson's rule over [0, a]: smooth, so 64 steps give
    // it to about 1e-10.
    let central = |a: f64| {
        let n = 64;
        let h = a / n as f64;
        let mut s = pdf(0.0) + pdf(a);
        for k in 1..n {
            s += pdf(k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        2.0 * s * h / 3.0
    };
    let (mut lo, mut hi) = (0.0, 10.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if central(mid) < kept {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let a = 0.5 * (lo + hi);
    // E[z² ; |z| < a] = P(|z| < a) − 2 a φ(a) (by parts).
    (kept - 2.0 * a * pdf(a)) / kept
}

/// The covariance `cov` of a correction taken about world point `c` (a
/// rotation about `c`, then a translation), carried to the pose's own
/// (x, y, θ): a rotation δθ about `c` moves the pose's origin `o` by
/// δθ·(−(o − c).y, (o − c).x) on top of the translation.
fn about_origin(cov: &Matrix3<f64>, pose: &Pose, c: &Vector2<f64>) -> Matrix3<f64> {
    let v = pose.translation.vector - c;
    let a = Matrix3::new(1.0, 0.0, -v.y, 0.0, 1.0, v.x, 0.0, 0.0, 1.0);
    a * cov * a.transpose()
}

fn centroid_radius(pairs: &[Pair], pose: &Pose) -> (Vector2<f64>, f64) {
    let n = pairs.len().max(1) as f64;
    let mut c = Vector2::zeros();
    for pr in pairs {
        c += (pose * pr.q.xy()).coords;
    }
    c /= n;
    let mut r2 = 0.0;
    for pr in pairs {
        r2 += ((pose * pr.q.xy()).coords - c).norm_squared();
    }
    let radius = (r2 / n).sqrt();
    (c, if radius > 1e-6 { radius } else { 1.0 })
}

struct Info {
    /// Σ JᵀJ in (x, y, θ) units.
    raw: Matrix3<f64>,
    min_eigenvalue: f64,
    degenerate: bool,
    weak: Vector3<f64>,
    centre: Vector2<f64>,
    radius: f64,
    /// Eigen-decomposition of the normalised matrix (scaled θ).
    eig: nalgebra::SymmetricEigen<f64, nalgebra::U3>,
    threshold: f64,
}

/// Point-to-line information matrix of the pairs and edge pairs at `pose`
/// (whatever metric was solved): it says which directions the scan constrains.
fn information(
    pairs: &[Pair],
    edges: &[EdgePair],
    reference: &Reference,
    pose: &Pose,
    threshold: f64,
) -> Info {
    let (c, radius) = centroid_radius(pairs, pose);
    let mut h = Matrix3::zeros();
    let mut used = 0usize;
    for pr in pairs {
        let counted = rows(pr, reference, pose, &c, radius, |j, _| {
            h += j * j.transpose()
        });
        used += usize::from(counted);
    }
    for ep in edges {
        edge_row(ep, reference, pose, &c, radius, |j, _| {
            h += j * j.transpose() * ep.weight
        });
    }
    let norm = h / used.max(1) as f64;
    let eig = norm.symmetric_eigen();
    let mut kmin = 0;
    for k in 1..3 {
        if eig.eigenvalues[k] < eig.eigenvalues[kmin] {
            kmin = k;
        }
    }
    let min_eigenvalue = eig.eigenvalues[kmin].max(0.0);
    let mut raw = h;
    // Undo the θ scaling: J_θ(raw) = radius · J_θ(scaled).
    for i in 0..3 {
        raw[(i, 2)] *= radius;
        raw[(2, i)] *= radius;
    }
    Info {
        raw,
        min_eigenvalue,
        degenerate: used < 3 || min_eigenvalue.is_nan() || min_eigenvalue < threshold,
        weak: eig.eigenvectors.column(kmin).into_owned(),
        centre: c,
        radius,
        eig,
        threshold,
    }
}

/// Removes from the correction `guess → pose` its components along the weak
/// (unconstrained) eigen-directions, so they stay at the guess.
fn keep_guess_along(pose: &Pose, guess: &Pose, info: &Info) -> Pose {
    let delta = pose * guess.inverse();
    let c = info.centre;
    let dth = delta.rotation.angle();
    let moved = delta * nalgebra::Point2::from(c);
    let mut x = Vector3::new(moved.x - c.x, moved.y - c.y, dth * info.radius);
    for k in 0..3 {
        if info.eig.eigenvalues[k] < info.threshold {
            let v = info.eig.eigenvectors.column(k);
            x -= v * v.dot(&x);
        }
    }
    apply_about(guess, &c, x.x, x.y, x.z / info.radius)
}

fn residual_rms(pairs: &[Pair], reference: &Reference, pose: &Pose, metric: Metric) -> f64 {
    let (refp, normals) = (reference.points(), reference.normals());
    let mut s = 0.0;
    for pr in pairs {
        let q = pose * pr.q.xy();
        let p = &refp[pr.p as usize];
        let n = normals[pr.p as usize];
        let (dx, dy) = (q.x - p.x, q.y - p.y);
        s += match metric {
            Metric::PointToLine if n.x != 0.0 || n.y != 0.0 => (n.x * dx + n.y * dy).powi(2),
            _ => dx * dx + dy * dy,
        };
    }
    (s / pairs.len().max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trimmed_variance_share_is_the_truncated_normals() {
        assert_eq!(trimmed_variance_share(1.0), 1.0);
        // a = 1.6449 (the 95th percentile): (0.9 − 2 a φ(a)) / 0.9.
        assert!((trimmed_variance_share(0.9) - 0.62302).abs() < 1e-4);
        // a = 0.6745 (the quartile): (0.5 − 2 a φ(a)) / 0.5.
        assert!((trimmed_variance_share(0.5) - 0.14265).abs() < 1e-4);
        assert!(trimmed_variance_share(0.999) < 1.0);
    }
}
