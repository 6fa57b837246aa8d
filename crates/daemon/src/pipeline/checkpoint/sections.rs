//! The sections the pipeline itself owns: the robot pose, the explored-area
//! grid and the run's progress counters. The map, cells and planner state are
//! added by their modules through the same [`Section`] trait.

use serde::{Deserialize, Serialize};

use super::checks::{check_frame, checked_pose, finite};
use super::Section;
use crate::geom::Pose;
use crate::grid::Grid;
use crate::plan::cspace::Frame;

/// The robot pose (nalgebra's serde form: translation, unit complex
/// rotation).
impl Section for Pose {
    const NAME: &'static str = "pose";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        checked_pose("pose", &self)
    }
}

/// The explored-area grid: its geometry and evidence (see [`Grid::rebuilt`]).
impl Section for Grid {
    const NAME: &'static str = "grid";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        let frame = Frame {
            origin: self.origin(),
            res: self.resolution(),
            w: self.width(),
            h: self.height(),
        };
        check_frame(&frame, Some(("cell value", self.raw_evidence().len())))?;
        self.rebuilt()
            .ok_or_else(|| "grid geometry rejected".into())
    }
}

/// When a checkpoint (or heartbeat) was written, as UNIX time on the wall
/// clock: the run's own clock may be simulated or restart at zero, the wall
/// clock says when it happened for the person reading the report.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WrittenAt {
    /// Seconds since 1970-01-01 00:00 UTC.
    pub unix: f64,
}

impl WrittenAt {
    /// The wall clock now (0 if the system clock is before 1970).
    pub fn now() -> Self {
        let unix = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs_f64())
            .unwrap_or(0.0);
        Self { unix }
    }
}

impl Section for WrittenAt {
    const NAME: &'static str = "written";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        let unix = finite("unix time", self.unix)?;
        if unix < 0.0 {
            return Err(format!("unix time {unix} is negative"));
        }
        Ok(self)
    }
}

/// The run finished its coverage (written into its last checkpoints): the
/// next start is a new run, not a resume of one with nothing left to do.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunFinished {
    /// Run time (s) when coverage finished, on the run's own clock.
    pub elapsed: f64,
}

impl Section for RunFinished {
    const NAME: &'static str = "run.finished";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        let elapsed = finite("elapsed", self.elapsed)?;
        if elapsed < 0.0 {
            return Err(format!("run time {elapsed} is negative"));
        }
        Ok(self)
    }
}

/// How far a run had got: lets a restarted daemon resume and the report say
/// how much progress a crash lost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunProgress {
    /// Checkpoints written so far in this run, this one included.
    pub sequence: u64,
    /// Run time (s) when written, on the run's own (possibly simulated) clock.
    pub elapsed: f64,
    /// Fraction of the reachable floor covered, 0..=1.
    pub coverage: f64,
    /// Scans processed.
    pub scans: u64,
    /// Path driven so far (m).
    pub path_length: f64,
    /// Times the run was resumed from a checkpoint.
    pub resumes: u32,
}

impl Section for RunProgress {
    const NAME: &'static str = "progress";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        let elapsed = finite("elapsed", self.elapsed)?;
        let coverage = finite("coverage", self.coverage)?;
        let path_length = finite("path_length", self.path_length)?;
        if elapsed < 0.0 || path_length < 0.0 {
            return Err("elapsed time and path length cannot be negative".into());
        }
        if !(0.0..=1.0).contains(&coverage) {
            return Err(format!("coverage {coverage} is outside 0..=1"));
        }
        Ok(self)
    }
}
