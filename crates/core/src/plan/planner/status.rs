//! What the planner reports: its errors, tasks, motions, status, the
//! final report, counters and the record of tasks planned.

use nalgebra::Point2;

use super::HomeOutcome;
use crate::decomp::CellId;

/// Why the planner cannot work.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A setting is out of its allowed range.
    #[error("plan.{key}: {message}")]
    BadParam {
        /// The key in the `[plan]` table (or `robot.*`).
        key: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The robot is outside the map grid.
    #[error("robot at ({x:.2}, {y:.2}) m is outside the map grid")]
    OutsideMap {
        /// x (m).
        x: f64,
        /// y (m).
        y: f64,
    },
    /// The robot stands on or inside a seen obstacle and no free place is near.
    #[error("robot at ({x:.2}, {y:.2}) m is inside an obstacle's inflation zone with no way out")]
    Trapped {
        /// x (m).
        x: f64,
        /// y (m).
        y: f64,
    },
}

/// What the planner is doing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Task {
    /// Nothing planned yet.
    Idle,
    /// Turning in place at the start to see all around.
    LookAround,
    /// Leaving an obstacle's inflation zone.
    Escape,
    /// Covering a final cell (`Some`) or a leftover patch (`None`).
    Cover(Option<CellId>),
    /// Driving toward unexplored space.
    Explore,
    /// Driving to a place near seen floor that obstacles wall off, to wait
    /// there for the way to clear (see [`crate::plan::PlanParams::clear_wait`]).
    Wait,
    /// Coverage is done: driving back to where the robot started
    /// (`plan.return_home`).
    Home,
    /// Nothing reachable is left.
    Done,
}

impl std::fmt::Display for Task {
    /// The task in plain words, as progress lines and logs show it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Task::Idle => f.write_str("waiting for a plan"),
            Task::LookAround => f.write_str("looking around"),
            Task::Escape => f.write_str("leaving an obstacle's margin"),
            Task::Cover(Some(c)) => write!(f, "covering cell {}", c.0),
            Task::Cover(None) => f.write_str("covering a leftover patch"),
            Task::Explore => f.write_str("exploring"),
            Task::Wait => f.write_str("waiting for a way to clear"),
            Task::Home => f.write_str("driving home"),
            Task::Done => f.write_str("done"),
        }
    }
}

/// What the robot does on its way to one waypoint of the path (for the
/// overlap breakdown of the metrics).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Motion {
    /// Turning in place, looking around, escaping, or nothing planned.
    #[default]
    Other,
    /// Driving a lane of the evenly spaced set.
    Lane,
    /// Driving a fix-up lane (floor the evenly spaced lanes missed).
    FixUp,
    /// Joining two lanes of the same region.
    Connection,
    /// Travelling to a region's first lane.
    Transit,
    /// Driving toward unexplored space.
    Explore,
    /// Driving back to the start once coverage is done (not part of the
    /// coverage figures: see `plan.return_home`).
    Home,
}

/// The planner's answer to one update.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlanStatus {
    /// Working on a task; `new_path` is true when the path changed.
    Working {
        /// The current task.
        task: Task,
        /// Whether [`super::CoveragePlanner::path`] changed in this update.
        new_path: bool,
    },
    /// Coverage finished.
    Done(DoneReport),
}

/// What the planner knows when it is done.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DoneReport {
    /// Seen free floor the robot cannot reach with its tool (m²).
    pub unreachable_area: f64,
    /// Floor it could reach but gave up on (lanes could not reach it) (m²).
    pub abandoned_area: f64,
    /// Leftover floor it chose to leave: fetching it would have swept more
    /// floor again than `plan.leftover_ratio` allows (m²; see
    /// `plan.coverage_goal`).
    pub declined_area: f64,
    /// Seen floor left unswept that the body could get to only through
    /// passages narrower than the clearance, which the planner takes only
    /// with `plan.way_out_passage` (m²; not in the other figures). Without
    /// it such floor was in no figure of the report.
    pub behind_tight_passages: f64,
    /// Floor its own record shows as swept (m²).
    pub covered_area: f64,
    /// Boundary left between seen floor and unexplored space (m, frontier
    /// cells times the grid cell): space no reachable place sees into
    /// (the far side of furniture in a corner), or given up after
    /// exploration moves that showed nothing new.
    pub unexplored_frontier: f64,
    /// How the drive back to the start ended.
    pub home: HomeOutcome,
    /// Distance (m) from the start where the robot ended (NaN when the
    /// start is unknown).
    pub home_distance: f64,
}

/// Counters of what the planner did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlanStats {
    /// Tasks planned.
    pub tasks: usize,
    /// Final cells covered: distinct cells some cover task was planned for
    /// (a region split over several tasks, or a lane tour taken again,
    /// counts once).
    pub cells: usize,
    /// Exploration moves.
    pub explores: usize,
    /// Clean-up patches covered.
    pub patches: usize,
    /// Lanes planned.
    pub lanes: usize,
    /// Escapes from an inflation zone the robot found itself in.
    pub escapes: usize,
    /// Moves out of a part of the space with nothing left to do, through a
    /// passage only the bare body fits (see [`crate::plan::unbox`]).
    pub ways_out: usize,
    /// Plans started over because something seen since blocked the path.
    pub blocked: usize,
    /// Lane tours taken again for floor that appeared near the robot.
    pub retours: usize,
}

/// One planned task, for reports and pictures.
#[derive(Clone, Debug, PartialEq)]
pub struct TaskRecord {
    /// The task.
    pub task: Task,
    /// Number of lanes (cover tasks).
    pub lanes: usize,
    /// The planned path.
    pub path: Vec<Point2<f64>>,
}
