//! Deterministic lock-step coverage simulation with ideal localisation: no
//! threads, no ptys, no clocks in the loop (simulated time only). Each scan
//! period: cast a simulated URG-04LX scan at the true pose, integrate it into
//! the evidence grid, run the decomposer and the planner; each control
//! period: run the path follower and integrate the differential drive.
//! Stops when the planner reports that nothing reachable is left, or at the
//! time cap. Metrics come from the world's ground truth
//! ([`CoverageTracker`]), never from the robot's map.
//!
//! In the offline reference mode the grid is filled from the ground truth
//! before the start and no scans are cast: the same planner with the room
//! known in advance, to measure the price of not knowing it.

use nalgebra::{Point2, Vector2};

use crate::config::Config;
use crate::control::{integrate, ControlError, PathFollower, Twist};
use crate::decomp::{DecompError, Decomposer, Decomposition};
use crate::geom::{heading, Pose};
use crate::grid::{CellState, Grid};
use crate::plan::planner::{DoneReport, PlanStats};
use crate::plan::{CoveragePlanner, PlanError, PlanStatus};
use crate::sim::coverage_metrics::{CoverageMetrics, CoverageTracker, MetricsError};
use crate::sim::world::World;

/// Simulated URG-04LX: number of beams (steps 44..=725).
pub const URG_BEAMS: usize = 682;
/// Angular step (rad): 360° / 1024.
pub const URG_STEP: f64 = std::f64::consts::TAU / 1024.0;
/// First beam's angle relative to the front (step 44 − 384).
pub const URG_FIRST: f64 = -340.0 * URG_STEP;
/// Shortest valid range (m).
pub const URG_MIN_RANGE: f64 = 0.02;
/// Longest valid range (m).
pub const URG_MAX_RANGE: f64 = 5.6;

/// Whether the robot explores or knows the room in advance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Unknown room: the map is built from simulated scans.
    Online,
    /// Known room: the grid is filled from ground truth (reference run).
    Offline,
}

/// Settings of the simulation harness (not of the robot).
#[derive(Clone, Debug, PartialEq)]
pub struct LockstepOptions {
    /// Control period (s).
    pub dt: f64,
    /// Scan / map / decomposition / planning period (s).
    pub scan_period: f64,
    /// Simulated time after which the run stops unfinished (s).
    pub time_cap: f64,
    /// Evidence grid cell (m).
    pub grid_resolution: f64,
    /// Grid margin around the world's bounding box (m).
    pub grid_margin: f64,
    /// Simulated seconds between stored decomposition snapshots (0 = none).
    pub snapshot_every: f64,
    /// Feed the planner the decomposer's cells; when false it gets none and
    /// falls back to exploring, then covering leftover patches (a baseline).
    pub use_cells: bool,
}

impl Default for LockstepOptions {
    fn default() -> Self {
        Self {
            dt: 0.05,
            scan_period: 0.2,
            time_cap: 3600.0,
            grid_resolution: 0.05,
            grid_margin: 0.5,
            snapshot_every: 0.0,
            use_cells: true,
        }
    }
}

/// Why a run could not start or had to stop.
#[derive(Debug, thiserror::Error)]
pub enum LockstepError {
    /// The start pose is in collision with the world.
    #[error("cannot start: {0}")]
    Start(#[from] MetricsError),
    /// The planner refused.
    #[error("planner: {0}")]
    Plan(#[from] PlanError),
    /// The decomposer refused its settings.
    #[error("decomposition: {0}")]
    Decomp(#[from] DecompError),
    /// The follower refused its settings.
    #[error("control: {0}")]
    Control(#[from] ControlError),
    /// A harness setting is out of range.
    #[error("lockstep option {0}")]
    BadOption(String),
}

/// A decomposition at one moment of the run, for pictures.
#[derive(Clone, Debug)]
pub struct Snapshot {
    /// Simulated time (s).
    pub time: f64,
    /// Robot pose.
    pub pose: Pose,
    /// The cells.
    pub decomposition: Decomposition,
}

/// Everything a run produced.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Ground-truth metrics.
    pub metrics: CoverageMetrics,
    /// True when the planner finished before the time cap.
    pub finished: bool,
    /// The planner's own end report (None at the time cap).
    pub report: Option<DoneReport>,
    /// Planner counters.
    pub stats: PlanStats,
    /// Executed poses, one per control step.
    pub trajectory: Vec<Pose>,
    /// Per pose of `trajectory`: what the robot was doing on the way to it
    /// and the number of the task it belonged to (for the motions picture).
    pub doing: Vec<(crate::plan::Motion, u32)>,
    /// Decomposition snapshots (see [`LockstepOptions::snapshot_every`]) and the last one.
    pub snapshots: Vec<Snapshot>,
    /// The final evidence grid.
    pub grid: Grid,
    /// Wall-clock duration of each decomposition update (s), for the budget.
    pub decomp_seconds: Vec<f64>,
    /// Wall-clock duration of each planner update (s).
    pub plan_seconds: Vec<f64>,
    /// Per-cell pass counts on the ground-truth raster.
    pub passes: Vec<u16>,
    /// Per-cell cause of the second pass (see `coverage_metrics::OVERLAP_CAUSES`).
    pub repeat_causes: Vec<u8>,
    /// Every task the planner planned, in order.
    pub tasks: Vec<crate::plan::planner::TaskRecord>,
}

/// Casts one simulated URG-04LX scan at `pose` and integrates it into `grid`.
pub fn scan_into(world: &World, pose: &Pose, grid: &mut Grid) {
    let o: Point2<f64> = pose.translation.vector.into();
    let th = heading(pose);
    for k in 0..URG_BEAMS {
        let a = th + URG_FIRST + k as f64 * URG_STEP;
        let dir = Vector2::new(a.cos(), a.sin());
        match world.cast_ray(&o, a, URG_MAX_RANGE) {
            Some(hit) if hit.range >= URG_MIN_RANGE => {
                grid.integrate_ray(&o, &(o + dir * hit.range), true);
            }
            Some(_) => {}
            None => grid.integrate_ray(&o, &(o + dir * URG_MAX_RANGE), false),
        }
    }
}

/// A grid covering the world's walls plus `margin`.
pub fn grid_for(world: &World, resolution: f64, margin: f64) -> Grid {
    let f = &world.free;
    let lo = Point2::new(f.origin.x - margin, f.origin.y - margin);
    let w = ((f.width as f64 * f.resolution + 2.0 * margin) / resolution).ceil() as usize;
    let h = ((f.height as f64 * f.resolution + 2.0 * margin) / resolution).ceil() as usize;
    Grid::new(lo, resolution, w.max(1), h.max(1))
}

/// Fills `grid` from the ground truth: free where the world is free at the
/// cell centre, occupied elsewhere.
pub fn fill_from_truth(world: &World, grid: &mut Grid) {
    for y in 0..grid.height() {
        for x in 0..grid.width() {
            let c = grid.centre_of((x, y));
            let s = if world.free.is_free(&c) {
                CellState::Free
            } else {
                CellState::Occupied
            };
            grid.set_state((x, y), s);
        }
    }
}

/// Runs a coverage simulation of `world` with the robot, decomposition,
/// planner and control settings of `config`.
pub fn run(
    world: &World,
    config: &Config,
    opts: &LockstepOptions,
    mode: Mode,
) -> Result<RunResult, LockstepError> {
    for (name, v) in [
        ("dt", opts.dt),
        ("scan_period", opts.scan_period),
        ("time_cap", opts.time_cap),
        ("grid_resolution", opts.grid_resolution),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(LockstepError::BadOption(format!(
                "{name} must be a finite number > 0, got {v}"
            )));
        }
    }
    let robot = &config.robot;
    let mut tracker = CoverageTracker::new(world, robot.radius, robot.tool_width, &world.start)?
        .with_clearance(config.plan.safety_margin);
    let mut decomposer = Decomposer::new(&config.decomp, robot.radius)?;
    let mut planner = CoveragePlanner::new(&config.plan, robot)?;
    let mut follower = PathFollower::new(&config.control, robot)?;
    let mut grid = grid_for(world, opts.grid_resolution, opts.grid_margin);
    if mode == Mode::Offline {
        fill_from_truth(world, &mut grid);
    }
    let mut pose = world.start;
    let mut t = 0.0;
    let mut next_scan = 0.0;
    let mut next_snapshot = 0.0;
    let mut trajectory = vec![pose];
    let mut doing = vec![(crate::plan::Motion::Other, 0)];
    let mut snapshots = Vec::new();
    let (mut decomp_seconds, mut plan_seconds) = (Vec::new(), Vec::new());
    let mut finished = false;
    let mut report = None;
    let empty = Decomposition::default();
    tracker.record(&pose, t);
    planner.record_pose(&pose);
    while t < opts.time_cap {
        if t + 1e-9 >= next_scan {
            next_scan += opts.scan_period;
            if mode == Mode::Online {
                scan_into(world, &pose, &mut grid);
            }
            let t0 = std::time::Instant::now();
            let decomp = if opts.use_cells {
                decomposer.update(&grid, &[])
            } else {
                &empty
            };
            decomp_seconds.push(t0.elapsed().as_secs_f64());
            let progress = (!follower.is_done()).then(|| follower.next_index());
            let t1 = std::time::Instant::now();
            let status = planner.update(&grid, decomp, &pose, progress)?;
            plan_seconds.push(t1.elapsed().as_secs_f64());
            if opts.snapshot_every > 0.0 && t + 1e-9 >= next_snapshot {
                next_snapshot += opts.snapshot_every;
                snapshots.push(Snapshot {
                    time: t,
                    pose,
                    decomposition: decomp.clone(),
                });
            }
            match status {
                PlanStatus::Done(r) => {
                    finished = true;
                    report = Some(r);
                    break;
                }
                PlanStatus::Working { new_path: true, .. } => {
                    let (path, fh) = planner.path();
                    follower.set_path(path, fh);
                }
                PlanStatus::Working { .. } => {}
            }
        }
        let (_, wheels) = follower.step(&pose, opts.dt);
        let twist = Twist::from_wheels(&wheels, robot.wheel_base);
        pose = integrate(&pose, &twist, opts.dt);
        t += opts.dt;
        trajectory.push(pose);
        let motion = if follower.is_done() {
            crate::plan::Motion::Other
        } else {
            planner.motion(follower.next_index())
        };
        let task = planner.stats().tasks as u32;
        doing.push((motion, task));
        tracker.record_doing(&pose, t, motion, task);
        planner.record_pose(&pose);
    }
    snapshots.push(Snapshot {
        time: t,
        pose,
        decomposition: decomposer.decomposition().clone(),
    });
    Ok(RunResult {
        metrics: tracker.metrics(),
        finished,
        report,
        stats: planner.stats(),
        trajectory,
        doing,
        snapshots,
        grid,
        decomp_seconds,
        plan_seconds,
        passes: tracker.passes().to_vec(),
        repeat_causes: tracker.repeat_causes().to_vec(),
        tasks: planner.history().to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scan_marks_the_room_free_and_walls_occupied() {
        let w = World::parse("room 0 0 4 0 4 3 0 3\nstart 2 1.5 0\n").unwrap();
        let mut g = grid_for(&w, 0.05, 0.5);
        scan_into(&w, &w.start, &mut g);
        let (_, free, occ) = g.counts();
        // 240° of a 4 x 3 m room: most of its 12 m² is seen free.
        assert!(free as f64 * 0.0025 > 7.0, "{free}");
        assert!(occ > 100, "{occ}");
        assert_eq!(
            g.state(g.cell_of(&Point2::new(3.0, 1.5)).unwrap()),
            CellState::Free
        );
        // Behind the scanner (the 120° blind sector) stays unknown.
        assert_eq!(
            g.state(g.cell_of(&Point2::new(0.3, 1.5)).unwrap()),
            CellState::Unknown
        );
    }

    #[test]
    fn bad_options_are_refused() {
        let w = World::parse("room 0 0 4 0 4 3 0 3\nstart 2 1.5 0\n").unwrap();
        let opts = LockstepOptions {
            dt: 0.0,
            ..LockstepOptions::default()
        };
        let e = run(&w, &Config::default(), &opts, Mode::Online).unwrap_err();
        assert!(e.to_string().contains("dt"), "{e}");
    }
}
