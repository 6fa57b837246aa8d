//! Coverage planning: lanes inside a cell, the order of cells, and transit
//! paths between them, online, over the map explored so far.
//!
//! * [`cspace`]: where the robot centre may be (walls inflated by the robot
//!   radius plus a margin), travel distances, A* transit paths;
//! * [`lanes`]: back-and-forth lanes inside one region and their order;
//! * [`tour`]: one tour, lane by lane, through the lanes of several regions;
//! * [`planner`]: the event-driven [`CoveragePlanner`]: which final cell next
//!   (travel cost with look-ahead), exploration toward the frontier when no
//!   final cell is left, a clean-up of leftover patches, and the report of
//!   unreachable area.
pub mod cspace;
pub mod lanes;
pub mod planner;
pub mod swept;
/// Fixtures for tests here and in the crates above (the checkpoint tests):
/// the `test-support` feature, for tests only.
#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
pub mod test_support;
pub mod tour;
pub mod unbox;

pub use planner::{
    lane_geometry, CoveragePlanner, HomeOutcome, Motion, PlanError, PlanSnapshot, PlanStatus, Task,
};
pub use swept::{HomePlace, LatticePhase, PlanReach, PlanTries, SweptFloor, TriedCell};

/// Coverage planner settings.
/// Loaded from the `[plan]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlanParams {
    /// Clearance kept from seen walls and unexplored space beyond the robot radius (m).
    pub safety_margin: f64,
    /// How much neighbouring lanes overlap at least (m); lane spacing is
    /// `robot.tool_width - lane_overlap`.
    pub lane_overlap: f64,
    /// Part of the tool half-width not counted on when deciding what a lane
    /// reaches (m), against tracking error.
    pub reach_margin: f64,
    /// Weight of the look-ahead term (straight-line length of a greedy tour
    /// through the other candidate cells after this one) in the choice of
    /// the next cell; 0 = nearest cell first.
    pub lookahead_weight: f64,
    /// Extra cost factor of travel over floor the tool has already swept
    /// (0 = plain distance): transit paths and the choice of the next cell
    /// then prefer unswept floor, as the tool is always on and every metre
    /// over swept floor is overlap. Off by default: 0.3-2 gave no net gain
    /// over the paper world and five rooms, and 1.0 once left 10 % of a
    /// room uncovered online.
    pub swept_travel_cost: f64,
    /// Extra cost factor of travel over floor not yet swept twice, scaled
    /// by its share of the tool's width (0 = plain distance): floor swept
    /// twice already is overlap whatever drives over it again, so transits
    /// that share a corridor add no more.
    pub new_overlap_cost: f64,
    /// Longest connection between two consecutive lanes of one cover task
    /// (m): a region whose next lane is farther is finished in a later task,
    /// chosen again with the whole tour in view, instead of by a long drive
    /// over swept floor (0 = never split a region's lanes).
    pub max_lane_join: f64,
    /// Uncovered patches smaller than this are left alone (m²).
    pub min_patch_area: f64,
    /// Least uncovered floor a fix-up lane must reach (m²): a fix-up lane
    /// costs a detour in and out, over floor swept already, so one for a
    /// few cells adds more overlap than it covers floor.
    pub min_fixup_area: f64,
    /// Least uncovered floor any other lane piece must newly reach (m²):
    /// a stub of a lane into a corner for a few cells costs two joins.
    pub min_lane_area: f64,
    /// At clean-up, patches down to this share of the reachable floor are
    /// still covered where that is less than `min_patch_area` (a small room
    /// would otherwise lose a whole percent to one corner); 0 = off.
    pub min_patch_share: f64,
    /// A frontier within this distance of a reachable place, in sight of
    /// it (a clear line to the unknown beyond), counts as explorable from
    /// there (m).
    pub explore_view_distance: f64,
    /// Frontier clusters with fewer cells than this are ignored (ray speckle).
    pub min_frontier_cells: usize,
    /// Longest passage (m) where only the bare body fits (no safety margin)
    /// that the robot may take out of a part of the space with nothing left
    /// to do, to another part with work (0 = never, the default: such a
    /// passage leaves millimetres of clearance, below the closed loop's
    /// tracking error).
    pub way_out_passage: f64,
    /// Turn in place once at the start to see all around.
    pub look_around: bool,
    /// When no cell is final, cover closed cells whose size still settles
    /// (what they gain later is covered then) before exploring.
    pub cover_settling_cells: bool,
    /// Once no cell touches unexplored space, drive the lanes of all regions
    /// left (nearest regions first, up to `tour_max_lanes` lanes) in one
    /// tour ordered lane by lane (see [`tour`]), instead of one region
    /// after another.
    pub lane_tour: bool,
    /// Most lanes pooled into one tour (bounds the planner's update time:
    /// one travel search per lane end).
    pub tour_max_lanes: usize,
    /// Share of the places the bare body can reach (no safety margin)
    /// that must stay swept or to be swept when the end game leaves
    /// leftovers (0..=1; 1 = fetch every leftover).
    pub coverage_goal: f64,
    /// In the end game, a leftover is fetched only if the travel to it
    /// (priced as transits are) times the tool width is at most this many
    /// times its floor: more would sweep that much floor again for it.
    pub leftover_ratio: f64,
    /// Planner updates a surface cell at the edge of furniture keeps
    /// blocking after the map lets it go (see
    /// `cspace::CSpace::set_surface_hold`); 0 = as the map says. In the
    /// closed loop on office_f:0 (×5, 4 and 6 runs) 100 took the tasks
    /// planned from 33-55 to 15-20 a run and the overlap from 39.9 to
    /// 34.2 % (coverage 98.96 against 99.04 %). The hold ends the first
    /// time nothing is left to do, and the surfaces it kept are let go (the
    /// floor beside them is looked at again). A cell just inside a straight
    /// face of 5 cells or more (a wall) is not held: ranges ending in it now
    /// and then are noise, and holding it cut the lane hugging the wall.
    pub surface_hold: u32,
    /// Seconds to wait, planning nothing, when nothing reachable is left
    /// but floor the robot could once get to is left unswept beyond
    /// obstacles (at least `min_patch_area` of it): a person standing in a
    /// doorway walls a room off until they go and beams pass through where
    /// they stood. The robot first drives to about a metre from that floor
    /// to look at it from near. A wait that ends with work may come again
    /// (at most 20 in a run); one that does not ends the run. 0 = finish at
    /// once. When 1 m² or more of floor is given up after its rounds
    /// (paths to it blocked again and again by people), the planner waits
    /// as long before another round.
    pub clear_wait: f64,
    /// Once coverage is done, drive back to where the robot started (its
    /// dock, or where the operator put it down), facing the start heading,
    /// before the run ends. The drive back is not part of the coverage
    /// figures (coverage, overlap, path, time); reports give it apart.
    pub return_home: bool,
}

impl Default for PlanParams {
    fn default() -> Self {
        Self {
            safety_margin: 0.01,
            lane_overlap: 0.01,
            reach_margin: 0.005,
            lookahead_weight: 1.0,
            swept_travel_cost: 0.0,
            new_overlap_cost: 2.0,
            max_lane_join: 0.7,
            min_patch_area: 0.08,
            min_fixup_area: 0.04,
            min_lane_area: 0.02,
            min_patch_share: 0.0075,
            explore_view_distance: 1.0,
            min_frontier_cells: 4,
            way_out_passage: 0.0,
            look_around: true,
            cover_settling_cells: true,
            lane_tour: true,
            tour_max_lanes: 96,
            coverage_goal: 0.995,
            leftover_ratio: 10.0,
            surface_hold: 100,
            clear_wait: 60.0,
            return_home: true,
        }
    }
}

impl PlanParams {
    /// Checks every value range, naming the key that is wrong.
    pub fn validate(&self) -> Result<(), PlanError> {
        for (key, v) in [
            ("safety_margin", self.safety_margin),
            ("lane_overlap", self.lane_overlap),
            ("reach_margin", self.reach_margin),
            ("lookahead_weight", self.lookahead_weight),
            ("min_patch_area", self.min_patch_area),
            ("min_fixup_area", self.min_fixup_area),
            ("min_lane_area", self.min_lane_area),
            ("min_patch_share", self.min_patch_share),
            ("swept_travel_cost", self.swept_travel_cost),
            ("new_overlap_cost", self.new_overlap_cost),
            ("max_lane_join", self.max_lane_join),
            ("way_out_passage", self.way_out_passage),
            ("leftover_ratio", self.leftover_ratio),
            ("clear_wait", self.clear_wait),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(PlanError::BadParam {
                    key,
                    message: format!("must be a finite number >= 0, got {v}"),
                });
            }
        }
        if !(self.explore_view_distance.is_finite() && self.explore_view_distance > 0.0) {
            return Err(PlanError::BadParam {
                key: "explore_view_distance",
                message: format!(
                    "must be a finite number > 0, got {}",
                    self.explore_view_distance
                ),
            });
        }
        if !(self.coverage_goal > 0.0 && self.coverage_goal <= 1.0) {
            return Err(PlanError::BadParam {
                key: "coverage_goal",
                message: format!("must be a share in (0, 1], got {}", self.coverage_goal),
            });
        }
        if self.lane_tour && self.tour_max_lanes == 0 {
            return Err(PlanError::BadParam {
                key: "tour_max_lanes",
                message: "must be at least 1 when lane_tour is on".into(),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Asserts that `p` is refused with an error naming `key`.
    fn refused(p: PlanParams, key: &str) {
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains(key), "{key}: {e}");
    }

    #[test]
    fn bad_values_name_the_key() {
        let d = PlanParams::default;
        refused(
            PlanParams {
                lane_overlap: -1.0,
                ..d()
            },
            "lane_overlap",
        );
        refused(
            PlanParams {
                swept_travel_cost: -0.5,
                ..d()
            },
            "swept_travel_cost",
        );
        refused(
            PlanParams {
                min_lane_area: -0.01,
                ..d()
            },
            "min_lane_area",
        );
        for goal in [0.0, 1.5, f64::NAN] {
            refused(
                PlanParams {
                    coverage_goal: goal,
                    ..d()
                },
                "coverage_goal",
            );
        }
        refused(
            PlanParams {
                leftover_ratio: -1.0,
                ..d()
            },
            "leftover_ratio",
        );
        refused(
            PlanParams {
                min_fixup_area: f64::NAN,
                ..d()
            },
            "min_fixup_area",
        );
        refused(
            PlanParams {
                explore_view_distance: 0.0,
                ..d()
            },
            "explore_view_distance",
        );
        refused(
            PlanParams {
                tour_max_lanes: 0,
                ..d()
            },
            "tour_max_lanes",
        );
        // Without the lane tour the cap is not used, so 0 is accepted.
        let p = PlanParams {
            lane_tour: false,
            tour_max_lanes: 0,
            ..PlanParams::default()
        };
        assert!(p.validate().is_ok());
        let robot = crate::robot::RobotParams {
            tool_width: 0.01,
            ..Default::default()
        };
        let e = CoveragePlanner::new(&PlanParams::default(), &robot)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("tool width"), "{e}");
    }
}
