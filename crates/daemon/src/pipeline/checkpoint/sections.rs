//! The sections the pipeline itself owns: the robot pose, the explored-area
//! grid and the run's progress counters. The map, cells and planner state are
//! added by their modules through the same [`Section`] trait.

use nalgebra::Point2;

use super::{CheckpointError, Decoder, Encoder, GridHeader, Section};
use crate::geom::{heading, pose, Pose};
use crate::grid::Grid;

/// Largest grid a checkpoint may restore (cells): 8192 × 8192 at 5 cm is a
/// 400 m square, far more than any room.
const MAX_GRID_CELLS: u64 = 8192 * 8192;

impl Section for Pose {
    const NAME: &'static str = "pose";
    const VERSION: u16 = 1;

    fn encode(&self, e: &mut Encoder) {
        e.f64(self.translation.x);
        e.f64(self.translation.y);
        e.f64(heading(self));
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let x = d.finite("x")?;
        let y = d.finite("y")?;
        let theta = d.finite("heading")?;
        Ok(pose(x, y, theta))
    }
}

impl Section for Grid {
    const NAME: &'static str = "grid";
    const VERSION: u16 = 1;

    fn encode(&self, e: &mut Encoder) {
        e.grid_header(&GridHeader {
            origin_x: self.origin().x,
            origin_y: self.origin().y,
            resolution: self.resolution(),
            width: self.width() as u32,
            height: self.height() as u32,
        });
        e.bytes(self.raw_evidence());
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let g = d.grid_header(MAX_GRID_CELLS)?;
        let cells = d.bytes()?;
        if cells.len() != g.cells() {
            return Err(d.error(format!(
                "{} cell values for a {} x {} grid",
                cells.len(),
                g.width,
                g.height
            )));
        }
        Grid::from_raw_evidence(
            Point2::new(g.origin_x, g.origin_y),
            g.resolution,
            g.width as usize,
            g.height as usize,
            cells.to_vec(),
        )
        .ok_or_else(|| d.error("grid geometry rejected"))
    }
}

/// When a checkpoint (or heartbeat) was written, as UNIX time on the wall
/// clock: the run's own clock may be simulated or restart at zero, the wall
/// clock says when it happened for the person reading the report.
#[derive(Clone, Copy, Debug, PartialEq)]
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

    fn encode(&self, e: &mut Encoder) {
        e.f64(self.unix);
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let unix = d.finite("unix time")?;
        if unix < 0.0 {
            return Err(d.error(format!("unix time {unix} is negative")));
        }
        Ok(Self { unix })
    }
}

/// The run finished its coverage (written into its last checkpoints): the
/// next start is a new run, not a resume of one with nothing left to do.
/// Payload, version 1: the run time at the finish (f64, s, finite, >= 0).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunFinished {
    /// Run time (s) when coverage finished, on the run's own clock.
    pub elapsed: f64,
}

impl Section for RunFinished {
    const NAME: &'static str = "run.finished";
    const VERSION: u16 = 1;

    fn encode(&self, e: &mut Encoder) {
        e.f64(self.elapsed);
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let elapsed = d.finite("elapsed")?;
        if elapsed < 0.0 {
            return Err(d.error(format!("run time {elapsed} is negative")));
        }
        Ok(Self { elapsed })
    }
}

/// How far a run had got: lets a restarted daemon resume and the report say
/// how much progress a crash lost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
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

    fn encode(&self, e: &mut Encoder) {
        e.u64(self.sequence);
        e.f64(self.elapsed);
        e.f64(self.coverage);
        e.u64(self.scans);
        e.f64(self.path_length);
        e.u32(self.resumes);
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let sequence = d.u64()?;
        let elapsed = d.finite("elapsed")?;
        let coverage = d.finite("coverage")?;
        let scans = d.u64()?;
        let path_length = d.finite("path_length")?;
        let resumes = d.u32()?;
        if elapsed < 0.0 || path_length < 0.0 {
            return Err(d.error("elapsed time and path length cannot be negative"));
        }
        if !(0.0..=1.0).contains(&coverage) {
            return Err(d.error(format!("coverage {coverage} is outside 0..=1")));
        }
        Ok(Self {
            sequence,
            elapsed,
            coverage,
            scans,
            path_length,
            resumes,
        })
    }
}
