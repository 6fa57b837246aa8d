//! The map's settings (`[map]` table of the config file) and their range checks.

use serde::{Deserialize, Serialize};

use crate::param_check::{invalid, ParamError};

/// Mapping settings. Loaded from the `[map]` table of the config file; every
/// field is documented in `hw/robot.toml`. Lengths in metres, angles in radians.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MapParams {
    /// What the planner's map is built from: the evidence grid alone, or the
    /// paper's point map with segment correction and its wall segments.
    pub kind: MapKind,
    /// Merge threshold d_th of the paper's rule: a scan point closer than this
    /// to a stored point where the stored surface is dense is a duplicate.
    pub merge_distance: f64,
    /// Smallest spacing kept between points: consecutive scan points closer than
    /// this are thinned, and a point extending a surface must add at least this much.
    pub min_spacing: f64,
    /// Beams shorter than this are dropped (sensor's blind zone).
    pub min_range: f64,
    /// Beams longer than this are dropped from points and lines; beyond it a beam
    /// only clears free space (as a no-return beam does).
    pub max_range: f64,
    /// How far a no-return (or too-long) beam clears free space in the grid.
    pub free_clear_range: f64,
    /// Explored-area grid cell size.
    pub grid_resolution: f64,
    /// Side of the square explored-area grid, centred on the first pose.
    pub grid_extent: f64,
    /// Expected range noise (1 σ) of the scanner; sizes the breakpoint detector.
    pub range_sigma: f64,
    /// Breakpoint detector angle λ (Borges & Aldon): consecutive points whose
    /// gap exceeds what a surface seen at this grazing angle would give start a
    /// new cluster.
    pub breakpoint_angle: f64,
    /// Split-and-merge: a piece whose farthest point lies more than this from the
    /// chord is split there.
    pub split_distance: f64,
    /// Split-and-merge: adjacent pieces whose fitted directions differ by less
    /// than this (and lie on each other's line) are merged again.
    pub collinear_angle: f64,
    /// Fewest points a line feature needs.
    pub min_line_points: usize,
    /// Shortest line feature kept.
    pub min_line_length: f64,
    /// A scan segment joins a map segment when their directions differ by less than this.
    pub segment_merge_angle: f64,
    /// ... and both its end points lie within this of the map segment's line.
    pub segment_merge_distance: f64,
    /// ... and the gap between them along the line is at most this.
    pub segment_merge_gap: f64,
    /// Snapshots show only segments seen in at least this many scans (filters
    /// one-off lines from noise and grazing views).
    pub min_segment_observations: u32,
    /// Snapshots show only segments whose direction is known to this (1 σ, rad)
    /// or better: short walls seen from afar wait for more observations.
    pub max_segment_angle_sigma: f64,
    /// Apply segment correction (align new segments to map segments before merging).
    pub correction: bool,
    /// Segment correction pairs a scan segment with a map segment only when their
    /// directions differ by less than this.
    pub correction_max_angle: f64,
    /// ... and the scan segment's end points lie within this of the map line.
    pub correction_max_distance: f64,
    /// Least total length of paired segments for a correction to be computed.
    pub correction_min_length: f64,
    /// A computed correction larger than this translation is refused (m).
    pub correction_max_translation: f64,
    /// A computed correction larger than this rotation is refused (rad).
    pub correction_max_rotation: f64,
    /// A run of at least 3 line pieces turning by between this and
    /// `curve_max_turn` at each joint is kept as a curve (polyline).
    pub curve_min_turn: f64,
    /// Largest turn between consecutive pieces of a curve.
    pub curve_max_turn: f64,
    /// Build and publish a new snapshot every this many merged scans.
    pub publish_every: u32,
    /// Points the store reserves up front (it grows past this, allocating).
    pub reserve_points: usize,
}

/// Which map the daemon and the lock-step simulation plan on (`[map] kind`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MapKind {
    /// Registered scans go straight into the evidence grid.
    #[default]
    Grid,
    /// Registered scans go into the paper's map (point map with the merge
    /// rule, line features, segment correction); the planner gets its
    /// explored-area grid with the wall segments drawn in
    /// ([`super::PaperGrid`]).
    Paper,
}

impl Default for MapParams {
    fn default() -> Self {
        Self {
            kind: MapKind::Grid,
            merge_distance: 0.05,
            min_spacing: 0.01,
            min_range: 0.02,
            max_range: 5.6,
            free_clear_range: 4.0,
            grid_resolution: 0.05,
            grid_extent: 40.0,
            range_sigma: 0.01,
            breakpoint_angle: 10f64.to_radians(),
            split_distance: 0.04,
            collinear_angle: 3f64.to_radians(),
            min_line_points: 8,
            min_line_length: 0.15,
            segment_merge_angle: 3f64.to_radians(),
            segment_merge_distance: 0.05,
            segment_merge_gap: 0.10,
            min_segment_observations: 2,
            max_segment_angle_sigma: 0.5f64.to_radians(),
            correction: true,
            correction_max_angle: 3f64.to_radians(),
            correction_max_distance: 0.10,
            correction_min_length: 0.5,
            correction_max_translation: 0.10,
            correction_max_rotation: 3f64.to_radians(),
            curve_min_turn: 4f64.to_radians(),
            curve_max_turn: 40f64.to_radians(),
            publish_every: 5,
            reserve_points: 50_000,
        }
    }
}

/// Longest range any setting may name (m): bounds the work of one beam.
const MAX_SANE_RANGE: f64 = 200.0;

impl MapParams {
    /// Checks value ranges; errors name the key (`map.<field>`).
    pub fn validate(&self) -> Result<(), ParamError> {
        crate::check_keys!(
            self,
            "map",
            positive: [
                merge_distance,
                min_spacing,
                max_range,
                free_clear_range,
                grid_resolution,
                grid_extent,
                range_sigma,
                breakpoint_angle,
                split_distance,
                collinear_angle,
                min_line_length,
                segment_merge_angle,
                segment_merge_distance,
                segment_merge_gap,
                max_segment_angle_sigma,
                correction_max_angle,
                correction_max_distance,
                correction_min_length,
                correction_max_translation,
                correction_max_rotation,
                curve_min_turn,
                curve_max_turn,
            ],
        );
        if !(self.min_range.is_finite() && self.min_range >= 0.0 && self.min_range < self.max_range)
        {
            return Err(invalid(
                "map.min_range",
                "must be a finite number >= 0 and below map.max_range",
            ));
        }
        for (k, v) in [
            ("map.max_range", self.max_range),
            ("map.free_clear_range", self.free_clear_range),
        ] {
            if v > MAX_SANE_RANGE {
                return Err(invalid(
                    k,
                    &format!(
                        "must be at most {MAX_SANE_RANGE} m (no laser scanner reaches further)"
                    ),
                ));
            }
        }
        if self.min_spacing >= self.merge_distance {
            return Err(invalid(
                "map.min_spacing",
                "must be smaller than map.merge_distance",
            ));
        }
        if self.breakpoint_angle >= std::f64::consts::FRAC_PI_2 {
            return Err(invalid("map.breakpoint_angle", "must be below π/2"));
        }
        if self.min_line_points < 3 {
            return Err(invalid("map.min_line_points", "must be at least 3"));
        }
        if self.curve_min_turn >= self.curve_max_turn {
            return Err(invalid(
                "map.curve_min_turn",
                "must be smaller than map.curve_max_turn",
            ));
        }
        if self.publish_every == 0 {
            return Err(invalid("map.publish_every", "must be at least 1"));
        }
        let cells = (self.grid_extent / self.grid_resolution).ceil();
        if cells * cells > 100_000_000.0 {
            return Err(invalid(
                "map.grid_extent",
                "grid_extent / grid_resolution gives more than 10^8 cells",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        MapParams::default().validate().unwrap();
    }

    #[test]
    fn bad_values_name_their_key() {
        let cases: Vec<(MapParams, &str)> = vec![
            (
                MapParams {
                    merge_distance: -1.0,
                    ..Default::default()
                },
                "map.merge_distance",
            ),
            (
                MapParams {
                    min_spacing: 0.2,
                    ..Default::default()
                },
                "map.min_spacing",
            ),
            (
                MapParams {
                    min_range: 9.0,
                    ..Default::default()
                },
                "map.min_range",
            ),
            (
                MapParams {
                    grid_resolution: f64::NAN,
                    ..Default::default()
                },
                "map.grid_resolution",
            ),
            (
                MapParams {
                    publish_every: 0,
                    ..Default::default()
                },
                "map.publish_every",
            ),
            (
                MapParams {
                    grid_resolution: 0.0001,
                    ..Default::default()
                },
                "map.grid_extent",
            ),
            (
                MapParams {
                    max_range: 1e9,
                    ..Default::default()
                },
                "map.max_range",
            ),
            (
                MapParams {
                    min_line_points: 1,
                    ..Default::default()
                },
                "map.min_line_points",
            ),
        ];
        for (p, key) in cases {
            let e = p.validate().unwrap_err().to_string();
            assert!(e.contains(key), "{key}: {e}");
        }
    }
}
