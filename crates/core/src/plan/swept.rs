//! The planner's record of swept floor, as plain data a daemon checkpoints
//! (the section's encoding lives in `pipeline::checkpoint::swept`) so that,
//! restarted after a crash, it continues the coverage instead of starting
//! over; beside it, the record of floor the planner tried and gave up
//! ([`PlanTries`]), so that floor does not get all its tries again. The
//! configuration space, frontier and reachability are recomputed from the
//! restored map on the first update.

use serde::{Deserialize, Serialize};

use super::cspace::Frame;

/// What the tool has swept, on the planner's grid (the map's geometry).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweptFloor {
    /// The grid geometry the record belongs to.
    pub frame: Frame,
    /// One flag per cell, row-major: swept or not.
    #[serde(with = "crate::stored::bits")]
    pub covered: Vec<bool>,
}

/// Where the robot started, in the map frame, as plain data a daemon
/// checkpoints (section `plan.home`): after a restart the robot still drives
/// back to where it was put down, not to where it was resumed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct HomePlace {
    /// x (m).
    pub x: f64,
    /// y (m).
    pub y: f64,
    /// Heading at the start (rad).
    pub heading: f64,
}

/// The phase of the planner's lane lattice per lane axis (m across the
/// lanes; `None`: not fixed yet), as plain data a daemon checkpoints (the
/// section's encoding lives in `pipeline::checkpoint::lattice`): lanes
/// planned after a restart then line up with the lanes driven before it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LatticePhase {
    /// Phase of lanes along x (their y positions).
    pub x: Option<f64>,
    /// Phase of lanes along y (their x positions).
    pub y: Option<f64>,
}

/// One cell the planner has tried to reach or given up on.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TriedCell {
    /// Row-major cell index on the record's grid.
    pub index: u32,
    /// Tries charged to the cell so far (saturating).
    pub tries: u8,
    /// Floor given up as a cover target (the lanes could not reach it).
    pub abandoned: bool,
    /// Frontier given up as an exploration goal.
    pub given_up: bool,
}

/// The planner's tries and give-ups, as plain data a daemon checkpoints
/// (encoding in `pipeline::checkpoint::tries`): sparse, since only cells
/// the planner failed on are listed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanTries {
    /// The grid geometry the record belongs to.
    pub frame: Frame,
    /// Cells with a try or a give-up, by increasing index.
    pub cells: Vec<TriedCell>,
    /// Floor given up has had its second round already.
    pub retried: bool,
}

/// Where the robot could once get to with the full clearance, and how
/// often it waited for walled-off floor and gave given-up floor a further
/// round, as plain data a daemon checkpoints (encoding in
/// `pipeline::checkpoint::reach`): after a restart the planner still waits
/// for floor a person walls off, and does not get its waits and rounds
/// afresh.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanReach {
    /// The grid geometry the record belongs to.
    pub frame: Frame,
    /// One flag per cell, row-major: once within reach.
    #[serde(with = "crate::stored::bits")]
    pub ever_reachable: Vec<bool>,
    /// Waits for walled-off floor so far.
    pub clear_waits: u32,
    /// Further rounds of given-up floor so far.
    pub extra_retries: u32,
}

impl SweptFloor {
    /// Swept area (m²).
    pub fn area(&self) -> f64 {
        self.covered.iter().filter(|c| **c).count() as f64 * self.frame.res * self.frame.res
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point2;

    use super::*;
    use crate::decomp::Decomposition;
    use crate::geom::pose;
    use crate::plan::test_support::{planner, walled_room as room};

    #[test]
    fn record_of_another_geometry_is_ignored() {
        let grid = room();
        let empty = Decomposition::default();
        let start = pose(0.6, 0.6, 0.0);
        let mut b = planner();
        let n = 10 * 10;
        b.restore_swept(SweptFloor {
            frame: Frame {
                origin: Point2::new(0.0, 0.0),
                res: 0.05,
                w: 10,
                h: 10,
            },
            covered: vec![true; n],
        });
        b.update(&grid, &empty, &start, None).unwrap();
        let mut c = planner();
        c.update(&grid, &empty, &start, None).unwrap();
        assert_eq!(b.covered(), c.covered());
    }
}
