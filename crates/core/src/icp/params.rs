//! The matcher's settings (`[icp]` table of the config file) and their checks.

use super::SearchParams;
use crate::param_check::{invalid, ParamError};

/// Which error the solver minimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Metric {
    /// Squared point distance (the paper's metric; closed-form solution).
    PointToPoint,
    /// Squared distance to the line through the reference point along its
    /// surface (Censi's PL-ICP metric; one linear 3×3 solve per iteration).
    PointToLine,
}

/// Where the initial guess of a match comes from when tracking a sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Prior {
    /// Wheel odometry increment since the previous scan (constant velocity when
    /// no odometry is available).
    Odometry,
    /// Repeat the last estimated motion (constant velocity).
    ConstantVelocity,
}

/// Most keyframes a local map keeps (`icp.keyframe_window`,
/// `icp.keyframe_store`): 4096 scans of the URG-04LX are about 40 MB.
pub const MAX_KEYFRAMES: usize = 4096;

/// Scan matcher settings.
/// Loaded from the `[icp]` table of the config file; every field is documented
/// in `hw/robot.toml`. Defaults were tuned on the MIT CSAIL benchmark log.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct IcpParams {
    /// Intensity weight `w` of `E = Σ dx² + dy² + w·dl²` (m² per intensity unit²); 0 = plain ICP.
    pub intensity_weight: f64,
    /// Error metric: point-to-point or point-to-line.
    pub metric: Metric,
    /// Most iterations per match.
    pub max_iterations: u32,
    /// Stop when an iteration moves the pose by less than this (m).
    pub epsilon_translation: f64,
    /// Stop when an iteration turns the pose by less than this (rad).
    pub epsilon_rotation: f64,
    /// Correspondence gate at the first iteration (m, in (x, y, √w·l) space).
    pub gate_initial: f64,
    /// The gate never shrinks below this (m).
    pub gate_min: f64,
    /// Adaptive gate: after each iteration gate = clamp(gate_sigmas × robust σ of pair distances).
    pub gate_sigmas: f64,
    /// Fraction of the gated pairs kept (worst pairs trimmed), in (0, 1].
    pub trim_fraction: f64,
    /// Fewer pairs than this after gating and trimming: the match fails.
    pub min_pairs: usize,
    /// Smallest acceptable share of scan points that found a gated partner.
    pub min_inlier_ratio: f64,
    /// A match whose RMS residual (m) after convergence exceeds this is rejected.
    pub max_residual: f64,
    /// A direction whose normalised information (eigenvalue / pairs) is below this is degenerate.
    pub degeneracy_threshold: f64,
    /// Reference neighbours used to estimate a surface normal.
    pub normal_neighbours: usize,
    /// Neighbours farther than this (m) do not count for the normal.
    pub normal_radius: f64,
    /// Intensity step between successive scan points that marks an
    /// intensity edge, as a share of the darker one (0.6: 60 % brighter;
    /// used when `intensity_weight` > 0): scan and map edges are paired
    /// edge to edge and pin the pose along the surface.
    pub intensity_edge: f64,
    /// Readings at or beyond this range (m) are dropped before matching.
    pub max_range: f64,
    /// Readings closer than this (m) are dropped (robot body, dust).
    pub min_range: f64,
    /// Successive scan points closer than this (m) are thinned out before matching.
    pub min_point_spacing: f64,
    /// Weight of the prior (odometry) translation in point-to-line matching, per pair; 0 = none.
    pub prior_weight: f64,
    /// Initial guess for tracking: odometry or constant velocity.
    pub prior: Prior,
    /// Share of the previous smoothed odometry step kept when a new odometry
    /// increment arrives, in [0, 1): 0 = raw increments. Logged odometry is
    /// sampled with timing jitter (the step per scan alternates short/long);
    /// smoothing its translation gives a better prior along weakly constrained
    /// directions (corridors). Live odometry (the daemon's, read at each
    /// scan's own time: [`crate::icp::Tracker::note_live_odometry`]) is taken
    /// as measured.
    pub odometry_smoothing: f64,
    /// Share of the scan-to-scan estimate in the reported pose, in [0, 1): each
    /// scan is also matched against the previous one and the reported pose is
    /// this share of the way from the scan-to-map pose to the previous reported
    /// pose moved by that match (a complementary filter); 0 = off.
    pub scan_fusion: f64,
    /// Add a keyframe to the local map after this much travel (m).
    pub keyframe_distance: f64,
    /// ... or after this much rotation (rad).
    pub keyframe_angle: f64,
    /// Keyframes in the local map (the reference of scan-to-map matching).
    pub keyframe_window: usize,
    /// 0: the local map is a sliding window of the last `keyframe_window`
    /// keyframes. Else up to this many keyframes are kept where they were
    /// taken (a new one only on new ground or for a new view) and the local
    /// map is the `keyframe_window` nearest the robot: coming back, it is
    /// matched against what it mapped first (see [`crate::icp::KeyframeMap`]).
    pub keyframe_store: usize,
    /// A match that corrects the initial guess by more than this (m) is rejected.
    pub max_correction_translation: f64,
    /// A match that corrects the initial guess by more than this (rad) is rejected.
    pub max_correction_rotation: f64,
    /// With live odometry (the daemon's, [`crate::icp::Tracker::note_live_odometry`]),
    /// a match may move the pose at most this far (m) from the odometry's
    /// prediction per scan since the last accepted match: the wheels cannot
    /// be off by more than a few centimetres over one scan period, so a
    /// larger jump is a match drawn onto the wrong walls (a large room whose
    /// far walls lie out of range). The limit grows with each rejected
    /// scan, so a real offset (wheels slipping) is taken in a few scans.
    /// 0 = only `max_correction_translation`.
    pub live_correction: f64,
    /// The `[icp.search]` table: a correlative search around the prior
    /// when a match fails or is rejected (see
    /// [`crate::icp::CorrelativeSearch`]).
    pub search: SearchParams,
}

impl Default for IcpParams {
    fn default() -> Self {
        Self {
            intensity_weight: 0.0,
            metric: Metric::PointToLine,
            max_iterations: 30,
            epsilon_translation: 1e-4,
            epsilon_rotation: 1e-4,
            gate_initial: 0.5,
            gate_min: 0.05,
            gate_sigmas: 3.0,
            trim_fraction: 0.9,
            min_pairs: 20,
            min_inlier_ratio: 0.3,
            max_residual: 0.05,
            degeneracy_threshold: 0.02,
            normal_neighbours: 5,
            normal_radius: 0.3,
            intensity_edge: 0.6,
            max_range: 30.0,
            min_range: 0.05,
            min_point_spacing: 0.03,
            prior_weight: 0.0,
            prior: Prior::Odometry,
            odometry_smoothing: 0.5,
            scan_fusion: 0.7,
            keyframe_distance: 0.3,
            keyframe_angle: 0.2,
            keyframe_window: 6,
            keyframe_store: 0,
            max_correction_translation: 1.0,
            max_correction_rotation: 0.7,
            live_correction: 0.05,
            search: SearchParams::default(),
        }
    }
}

impl IcpParams {
    /// Checks ranges the types cannot express; errors name the key (`icp.…`).
    pub fn validate(&self) -> Result<(), ParamError> {
        crate::check_keys!(
            self,
            "icp",
            positive: [
                epsilon_translation,
                epsilon_rotation,
                gate_initial,
                gate_min,
                gate_sigmas,
                max_residual,
                normal_radius,
                intensity_edge,
                max_range,
                keyframe_distance,
                keyframe_angle,
                max_correction_translation,
                max_correction_rotation,
            ],
            non_negative: [
                intensity_weight,
                degeneracy_threshold,
                min_point_spacing,
                prior_weight,
            ],
        );
        if self.max_iterations == 0 {
            return Err(invalid("icp.max_iterations", "must be at least 1"));
        }
        if self.gate_min > self.gate_initial {
            return Err(invalid("icp.gate_min", "must not exceed icp.gate_initial"));
        }
        if !(self.trim_fraction > 0.0 && self.trim_fraction <= 1.0) {
            return Err(invalid("icp.trim_fraction", "must be in (0, 1]"));
        }
        if self.min_pairs < 3 {
            return Err(invalid("icp.min_pairs", "must be at least 3"));
        }
        if !(0.0..=1.0).contains(&self.min_inlier_ratio) {
            return Err(invalid("icp.min_inlier_ratio", "must be in [0, 1]"));
        }
        if !(2..=32).contains(&self.normal_neighbours) {
            return Err(invalid("icp.normal_neighbours", "must be in 2..=32"));
        }
        if !(self.min_range.is_finite() && self.min_range >= 0.0 && self.min_range < self.max_range)
        {
            return Err(invalid(
                "icp.min_range",
                "must be >= 0 and below icp.max_range",
            ));
        }
        if !(0.0..1.0).contains(&self.odometry_smoothing) {
            return Err(invalid("icp.odometry_smoothing", "must be in [0, 1)"));
        }
        if !(0.0..1.0).contains(&self.scan_fusion) {
            return Err(invalid("icp.scan_fusion", "must be in [0, 1)"));
        }
        if self.keyframe_window == 0 || self.keyframe_window > MAX_KEYFRAMES {
            return Err(invalid(
                "icp.keyframe_window",
                &format!("must be in 1..={MAX_KEYFRAMES}"),
            ));
        }
        if self.keyframe_store > MAX_KEYFRAMES {
            return Err(invalid(
                "icp.keyframe_store",
                &format!("must be at most {MAX_KEYFRAMES} (0 = a sliding window)"),
            ));
        }
        if !(self.live_correction.is_finite() && self.live_correction >= 0.0) {
            return Err(invalid(
                "icp.live_correction",
                "must be a finite number of metres >= 0 (0 = off)",
            ));
        }
        self.search.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_values_name_their_key() {
        let cases: [(IcpParams, &str); 7] = [
            (
                IcpParams {
                    odometry_smoothing: 1.0,
                    ..IcpParams::default()
                },
                "icp.odometry_smoothing",
            ),
            (
                IcpParams {
                    scan_fusion: 1.0,
                    ..IcpParams::default()
                },
                "icp.scan_fusion",
            ),
            (
                IcpParams {
                    gate_min: 1.0,
                    gate_initial: 0.5,
                    ..IcpParams::default()
                },
                "icp.gate_min",
            ),
            (
                IcpParams {
                    min_pairs: 2,
                    ..IcpParams::default()
                },
                "icp.min_pairs",
            ),
            (
                IcpParams {
                    max_iterations: 0,
                    ..IcpParams::default()
                },
                "icp.max_iterations",
            ),
            (
                IcpParams {
                    keyframe_window: 0,
                    ..IcpParams::default()
                },
                "icp.keyframe_window",
            ),
            (
                IcpParams {
                    live_correction: -0.05,
                    ..IcpParams::default()
                },
                "icp.live_correction",
            ),
        ];
        for (p, key) in cases {
            let e = p.validate().unwrap_err();
            assert!(e.to_string().contains(key), "{e}");
        }
    }
}
