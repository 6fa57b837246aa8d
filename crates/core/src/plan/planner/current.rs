//! The current task: what the robot is doing, the path and motions it
//! follows, and what the task is after (the floor it answers for, the
//! frontier it goes to see).
//!
//! The follower reads the path; when the task ends or is interrupted, what
//! it was after is charged a try (or forgiven), so the two live together.

use nalgebra::Point2;

use super::home::travel_motion;
use super::{Motion, Task, TaskRecord};

/// The task being driven and what it is after.
pub(crate) struct CurrentTask {
    pub(crate) task: Task,
    /// The waypoints to follow.
    pub(crate) path: Vec<Point2<f64>>,
    /// The motion towards each waypoint (may be shorter than the path).
    pub(crate) motions: Vec<Motion>,
    /// The heading to turn to at the end of the path.
    pub(crate) final_heading: Option<f64>,
    /// The floor the task answers for: charged a try when it is left
    /// unswept.
    pub(crate) targets: Vec<usize>,
    /// The place an exploration move goes to see unexplored space from.
    pub(crate) explore_goal: Option<Point2<f64>>,
    /// Updates since the task began.
    pub(crate) updates: usize,
    /// The current cover task drives only part of its region's lanes.
    pub(crate) split: bool,
    /// Lanes of the task being planned, for its record.
    pub(crate) planned_lanes: usize,
}

impl Default for CurrentTask {
    fn default() -> Self {
        Self {
            task: Task::Idle,
            path: Vec::new(),
            motions: Vec::new(),
            final_heading: None,
            targets: Vec::new(),
            explore_goal: None,
            updates: 0,
            split: false,
            planned_lanes: 0,
        }
    }
}

impl CurrentTask {
    /// Drops what the task was after without charging it a try: the next
    /// task then has nothing to charge.
    pub(crate) fn forgive(&mut self) {
        self.targets.clear();
        self.explore_goal = None;
    }

    /// Plans nothing for now: no task, no path.
    pub(crate) fn stand_still(&mut self) {
        self.task = Task::Idle;
        self.path.clear();
        self.motions.clear();
        self.final_heading = None;
    }

    /// Begins `task` along `path`, turning to `final_heading` at its end
    /// (a cover task keeps the motions its lanes were planned with);
    /// returns its record.
    pub(crate) fn begin(
        &mut self,
        task: Task,
        path: Vec<Point2<f64>>,
        final_heading: Option<f64>,
    ) -> TaskRecord {
        self.task = task;
        let m = travel_motion(task);
        self.motions = match task {
            Task::Cover(_) => std::mem::take(&mut self.motions),
            _ => vec![m; path.len()],
        };
        self.motions.resize(path.len(), m);
        self.path = path;
        self.final_heading = final_heading;
        self.updates = 0;
        let lanes = std::mem::take(&mut self.planned_lanes);
        TaskRecord {
            task,
            lanes,
            path: self.path.clone(),
        }
    }
}
