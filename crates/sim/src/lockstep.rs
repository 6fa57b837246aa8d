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
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::config::Config;
use crate::control::guard::{ObstaclePoints, StopCounter};
use crate::control::{integrate, ControlError, PathFollower, Twist};
use crate::coverage_metrics::{CoverageMetrics, CoverageTracker, MetricsError};
use crate::decomp::{DecompError, Decomposer, Decomposition};
use crate::geom::{heading, Pose};
use crate::grid::{CellState, Grid};
use crate::map::{CorrectionTally, MapError, MapKind, PaperGrid};
use crate::noise::gauss;
use crate::plan::planner::{DoneReport, PlanStats};
use crate::plan::{CoveragePlanner, PlanError, PlanStatus};
use crate::scan::{Beam, LaserScan};
use crate::walker::{cast_ray_among, touches, Body, Crowd};
use crate::world::World;

/// Simulated URG-04LX: number of beams (steps 44..=725).
pub(crate) const URG_BEAMS: usize = 682;
/// Angular step (rad): 360° / 1024.
pub(crate) const URG_STEP: f64 = std::f64::consts::TAU / 1024.0;
/// First beam's angle relative to the front (step 44 − 384).
pub const URG_FIRST: f64 = -340.0 * URG_STEP;
/// Shortest valid range (m).
pub(crate) const URG_MIN_RANGE: f64 = 0.02;
/// Longest valid range (m).
pub(crate) const URG_MAX_RANGE: f64 = 5.6;

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
    /// Shift of the evidence grid's cell boundaries against the world (m,
    /// both axes, `0..grid_resolution`). The floor plans' walls lie on
    /// multiples of 5 cm, so at 0 every wall is on a cell boundary and the
    /// grid holds the obstacles exactly; the daemon's grid is centred on the
    /// start pose, which puts a floor plan's walls in mid-cell (0.025).
    pub grid_offset: f64,
    /// Errors of the simulated scans (online runs only; zero: ideal).
    pub sensing: SensingNoise,
}

/// Errors of the simulated sensing, to measure how the planner copes with
/// an imperfect map (all zero: the ideal scans of the targets).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SensingNoise {
    /// Standard deviation of every beam's range (m).
    pub range: f64,
    /// Standard deviation of the scan pose's position, per axis, drawn
    /// once per scan (m): the localisation error the map is built with.
    pub position: f64,
    /// Standard deviation of the scan pose's heading, drawn once per scan (rad).
    pub heading: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl SensingNoise {
    /// No error at all: the scans are the ideal ones.
    pub fn is_ideal(&self) -> bool {
        self.range == 0.0 && self.position == 0.0 && self.heading == 0.0
    }
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
            grid_offset: 0.0,
            sensing: SensingNoise::default(),
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
    /// The paper's map refused its settings or a pose (`[map] kind = "paper"`).
    #[error("paper map: {0}")]
    Map(#[from] MapError),
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
    /// Times the follower slowed or stopped short of something the scan
    /// showed ahead that its path did not expect (the protective field).
    pub guard_stops: u64,
    /// The paper's map, when the run planned on it.
    pub paper: Option<PaperSummary>,
}

/// Casts one simulated URG-04LX scan at `pose` and integrates it into `grid`.
pub fn scan_into(world: &World, pose: &Pose, grid: &mut Grid) {
    let mut ahead = ObstaclePoints::default();
    cast_scan(world, &[], pose, pose, Sink::Grid(grid), &mut ahead, || 0.0);
}

/// Where a cast scan goes: straight into the evidence grid, or into a
/// [`LaserScan`] (sensor frame) for the paper's map to merge.
pub(crate) enum Sink<'a> {
    /// Integrate every beam into this grid.
    Grid(&'a mut Grid),
    /// Fill this scan (cleared first); no-return beams are invalid with an
    /// infinite range.
    Scan(&'a mut LaserScan),
}

/// Casts scans at the true pose and integrates them as a robot with
/// [`SensingNoise`] would: each range off by its noise, the whole scan
/// placed at a pose off by the localisation error. Seeded: repeatable.
pub(crate) struct NoisyScanner {
    noise: SensingNoise,
    rng: ChaCha8Rng,
    ahead: ObstaclePoints,
}

impl NoisyScanner {
    /// A scanner with these errors.
    pub fn new(noise: SensingNoise) -> Self {
        Self {
            noise,
            rng: ChaCha8Rng::seed_from_u64(noise.seed),
            ahead: ObstaclePoints::default(),
        }
    }

    /// The newest scan's end points in the robot frame, as read (for the
    /// follower's protective field).
    pub fn ahead(&self) -> &ObstaclePoints {
        &self.ahead
    }

    /// One scan from the true `pose` into `grid`, people walking through
    /// the room standing where `bodies` are (exactly [`scan_into`] when the
    /// noise is all zero and there is nobody).
    ///
    /// Returns the pose the scan was placed at (the true one off by the
    /// localisation error), for a [`Sink::Scan`] to be merged there.
    pub fn scan_into(&mut self, world: &World, bodies: &[Body], pose: &Pose, sink: Sink) -> Pose {
        if self.noise.is_ideal() {
            cast_scan(world, bodies, pose, pose, sink, &mut self.ahead, || 0.0);
            return *pose;
        }
        let n = self.noise;
        let dx = n.position * gauss(&mut self.rng);
        let dy = n.position * gauss(&mut self.rng);
        let dth = n.heading * gauss(&mut self.rng);
        let seen = pose_off_by(pose, Vector2::new(dx, dy), dth);
        let rng = &mut self.rng;
        cast_scan(world, bodies, pose, &seen, sink, &mut self.ahead, || {
            n.range * gauss(rng)
        });
        seen
    }
}

/// `pose` off by a localisation error: its position moved by `shift` (world
/// frame) and its heading turned by `turn` about the robot's own position.
/// (Composing an error pose on the left would turn the position about the
/// world origin as well: 1.5 mrad at 45 m from it moves the scan 7 cm.)
pub(crate) fn pose_off_by(pose: &Pose, shift: Vector2<f64>, turn: f64) -> Pose {
    Pose::new(pose.translation.vector + shift, heading(pose) + turn)
}

/// Casts one scan at the true `pose`, `bodies` standing in the room, and
/// integrates it as seen from `seen`, each hit's range plus `range_error()`;
/// `ahead` gets the hits as read, in the robot frame.
fn cast_scan(
    world: &World,
    bodies: &[Body],
    pose: &Pose,
    seen: &Pose,
    mut sink: Sink,
    ahead: &mut ObstaclePoints,
    mut range_error: impl FnMut() -> f64,
) {
    let o: Point2<f64> = pose.translation.vector.into();
    let th = heading(pose);
    let so: Point2<f64> = seen.translation.vector.into();
    let sth = heading(seen);
    ahead.clear(*pose);
    if let Sink::Scan(s) = &mut sink {
        s.beams.clear();
    }
    for k in 0..URG_BEAMS {
        let rel = URG_FIRST + k as f64 * URG_STEP;
        let a = sth + rel;
        let dir = Vector2::new(a.cos(), a.sin());
        match cast_ray_among(world, bodies, &o, th + rel, URG_MAX_RANGE) {
            Some(hit) if hit.range >= URG_MIN_RANGE => {
                let r = (hit.range + range_error()).max(URG_MIN_RANGE);
                match &mut sink {
                    Sink::Grid(g) => g.integrate_ray(&so, &(so + dir * r), true),
                    Sink::Scan(s) => {
                        let _ = s.beams.push(Beam::hit(rel, r));
                    }
                }
                ahead.push(Point2::new(r * rel.cos(), r * rel.sin()));
            }
            Some(_) => {}
            None => match &mut sink {
                Sink::Grid(g) => g.integrate_ray(&so, &(so + dir * URG_MAX_RANGE), false),
                Sink::Scan(s) => {
                    let _ = s.beams.push(Beam {
                        angle: rel,
                        range: f64::INFINITY,
                        intensity: 0.0,
                        valid: false,
                    });
                }
            },
        }
    }
}

/// A grid covering the world's walls plus `margin`, its cell boundaries
/// shifted by `offset` (m) against the world's.
pub fn grid_for(world: &World, resolution: f64, margin: f64, offset: f64) -> Grid {
    let f = &world.free;
    let lo = Point2::new(f.origin.x - margin - offset, f.origin.y - margin - offset);
    let w = ((f.width as f64 * f.resolution + 2.0 * margin) / resolution).ceil() as usize;
    let h = ((f.height as f64 * f.resolution + 2.0 * margin) / resolution).ceil() as usize;
    Grid::new(lo, resolution, w.max(1), h.max(1))
}

/// Fills `grid` from the ground truth: occupied where any part of the cell
/// is not free (sampled at nine points: its centre, the middles of its
/// sides and its corners, each pulled in to 0.45 of a cell from the
/// centre; a wall passing through a cell would leave hits in it), free
/// elsewhere.
/// On cells aligned with the world's raster this is the state at the
/// centre; on cells straddling a wall it is the conservative one.
pub fn fill_from_truth(world: &World, grid: &mut Grid) {
    let h = 0.45 * grid.resolution();
    for y in 0..grid.height() {
        for x in 0..grid.width() {
            let c = grid.centre_of((x, y));
            let free = [-h, 0.0, h].iter().all(|&dy| {
                [-h, 0.0, h]
                    .iter()
                    .all(|&dx| world.free.is_free(&(c + Vector2::new(dx, dy))))
            });
            let s = if free {
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
    let n = &opts.sensing;
    for (name, v) in [
        ("range noise", n.range),
        ("position noise", n.position),
        ("heading noise", n.heading),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(LockstepError::BadOption(format!(
                "{name} must be a finite number >= 0, got {v}"
            )));
        }
    }
    if !(opts.grid_offset.is_finite()
        && opts.grid_offset >= 0.0
        && opts.grid_offset < opts.grid_resolution)
    {
        return Err(LockstepError::BadOption(format!(
            "grid_offset must lie in 0..{} (one cell), got {}",
            opts.grid_resolution, opts.grid_offset
        )));
    }
    let robot = &config.robot;
    let mut tracker = CoverageTracker::new(world, robot.radius, robot.tool_width, &world.start)?
        .with_clearance(config.plan.safety_margin);
    let mut decomposer = Decomposer::new(&config.decomp, robot.radius)?;
    let mut planner = CoveragePlanner::new(&config.plan, robot)?;
    let mut follower = PathFollower::new(&config.control, robot)?;
    let mut grid = grid_for(
        world,
        opts.grid_resolution,
        opts.grid_margin,
        opts.grid_offset,
    );
    let mut scanner = NoisyScanner::new(opts.sensing);
    if mode == Mode::Offline {
        fill_from_truth(world, &mut grid);
    }
    let mut paper = match (mode, config.map.kind) {
        (Mode::Online, MapKind::Paper) => Some(PaperRun::new(config, &world.start, &grid)?),
        _ => None,
    };
    let mut pose = world.start;
    // The offline reference has the room to itself: with no scans, it could
    // not see a person to keep off them.
    let mut crowd = match mode {
        Mode::Online => Crowd::new(&world.walkers),
        Mode::Offline => Crowd::default(),
    };
    let mut t = 0.0;
    let mut next_scan = 0.0;
    let mut next_snapshot = 0.0;
    let mut trajectory = vec![pose];
    let mut doing = vec![(crate::plan::Motion::Other, 0)];
    let mut snapshots = Vec::new();
    let (mut decomp_seconds, mut plan_seconds) = (Vec::new(), Vec::new());
    let mut finished = false;
    let mut guard = StopCounter::default();
    let mut report = None;
    let empty = Decomposition::default();
    tracker.record(&pose, t);
    planner.record_pose(&pose);
    while t < opts.time_cap {
        if t + 1e-9 >= next_scan {
            next_scan += opts.scan_period;
            match (&mut paper, mode) {
                (Some(p), _) => {
                    let seen =
                        scanner.scan_into(world, crowd.bodies(), &pose, Sink::Scan(&mut p.scan));
                    p.merge(&seen, &mut grid)?;
                }
                (None, Mode::Online) => {
                    scanner.scan_into(world, crowd.bodies(), &pose, Sink::Grid(&mut grid));
                }
                (None, Mode::Offline) => {}
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
            planner.set_time(t);
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
        let ahead = (mode == Mode::Online).then(|| (scanner.ahead(), &pose));
        let (_, wheels) = follower.step_guarded(&pose, opts.dt, ahead);
        guard.note(follower.held_short(), t);
        let twist = Twist::from_wheels(&wheels, robot.wheel_base);
        pose = integrate(&pose, &twist, opts.dt);
        t += opts.dt;
        if !crowd.is_empty() {
            let at = Point2::from(pose.translation.vector);
            crowd.step(opts.dt, &at, robot.radius);
            tracker.record_contact(touches(crowd.bodies(), &at, robot.radius), &at, t);
        }
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
        guard_stops: guard.stops,
        paper: paper.map(|p| p.summary()),
    })
}

/// The paper's map in a lock-step run, with its cost.
struct PaperRun {
    map: PaperGrid,
    scan: LaserScan,
    seconds: Vec<f64>,
}

impl PaperRun {
    fn new(config: &Config, start: &Pose, grid: &Grid) -> Result<Self, LockstepError> {
        let map = PaperGrid::new(config.map.clone(), *start, grid.clone())?;
        Ok(Self {
            map,
            scan: LaserScan::default(),
            seconds: Vec::new(),
        })
    }

    /// Merges the cast scan, placed at `seen`, and renders the planner's grid.
    fn merge(&mut self, seen: &Pose, grid: &mut Grid) -> Result<(), LockstepError> {
        let t0 = std::time::Instant::now();
        self.map.merge(&self.scan, seen)?;
        self.map.render_into(grid);
        self.seconds.push(t0.elapsed().as_secs_f64());
        Ok(())
    }

    fn summary(self) -> PaperSummary {
        PaperSummary {
            corrections: self.map.tally(),
            points: self.map.map().points().len(),
            segments: self.map.map().segment_map().segments().len(),
            memory_bytes: self.map.memory_bytes(),
            map_seconds: self.seconds,
        }
    }
}

/// What the paper's map did in a run with `[map] kind = "paper"`.
#[derive(Clone, Debug)]
pub struct PaperSummary {
    /// The segment correction's work.
    pub corrections: CorrectionTally,
    /// Points stored.
    pub points: usize,
    /// Wall segments.
    pub segments: usize,
    /// Bytes the map holds ([`PaperGrid::memory_bytes`]).
    pub memory_bytes: usize,
    /// Wall-clock duration of each merge and render (s).
    pub map_seconds: Vec<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scan_marks_the_room_free_and_walls_occupied() {
        let w = World::parse("room 0 0 4 0 4 3 0 3\nstart 2 1.5 0\n").unwrap();
        let mut g = grid_for(&w, 0.05, 0.5, 0.0);
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
    fn a_heading_error_turns_the_scan_about_the_robot_not_the_world_origin() {
        // A floor-plan room lies tens of metres from the world origin.
        let pose = Pose::new(Vector2::new(39.4, 22.5), 0.3);
        let seen = pose_off_by(&pose, Vector2::new(0.002, -0.001), 0.0015);
        let moved = seen.translation.vector - pose.translation.vector;
        assert!(
            (moved - Vector2::new(0.002, -0.001)).norm() < 1e-12,
            "{moved}"
        );
        assert!((heading(&seen) - 0.3015).abs() < 1e-12);
        // The same turn taken as an error pose composed on the left moves
        // the scan by centimetres.
        let left = Pose::new(Vector2::zeros(), 0.0015) * pose;
        assert!((left.translation.vector - pose.translation.vector).norm() > 0.05);
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
        let noisy = LockstepOptions {
            sensing: SensingNoise {
                range: -0.01,
                ..SensingNoise::default()
            },
            ..LockstepOptions::default()
        };
        let e = run(&w, &Config::default(), &noisy, Mode::Online).unwrap_err();
        assert!(e.to_string().contains("range noise"), "{e}");
        for offset in [-0.01, 0.05, f64::NAN] {
            let shifted = LockstepOptions {
                grid_offset: offset,
                ..LockstepOptions::default()
            };
            let e = run(&w, &Config::default(), &shifted, Mode::Online).unwrap_err();
            assert!(e.to_string().contains("grid_offset"), "{e}");
        }
    }

    fn cells(g: &Grid) -> Vec<CellState> {
        (0..g.height())
            .flat_map(|y| (0..g.width()).map(move |x| (x, y)))
            .map(|c| g.state(c))
            .collect()
    }

    #[test]
    fn a_shifted_grid_moves_its_cell_boundaries_by_the_offset() {
        let w = World::parse("room 0 0 4 0 4 3 0 3\nstart 2 1.5 0\n").unwrap();
        let (a, b) = (grid_for(&w, 0.05, 0.5, 0.0), grid_for(&w, 0.05, 0.5, 0.025));
        assert!((a.origin() - b.origin() - Vector2::new(0.025, 0.025)).norm() < 1e-12);
        // Half a cell of offset puts a wall half a cell away from where it
        // lay among the cells.
        let phase = |g: &Grid| ((4.0 - g.origin().x) / 0.05).rem_euclid(1.0);
        assert!(((phase(&b) - phase(&a)).rem_euclid(1.0) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn the_known_room_marks_every_cell_a_wall_passes_through() {
        let w = World::parse("room 0 0 4 0 4 3 0 3\nstart 2 1.5 0\n").unwrap();
        for offset in [0.0, 0.025] {
            let mut g = grid_for(&w, 0.05, 0.5, offset);
            fill_from_truth(&w, &mut g);
            // Every cell whose centre lies within half a cell of the wall
            // at x = 4 holds part of it.
            let row = g.cell_of(&Point2::new(2.0, 1.5)).unwrap().1;
            for x in 0..g.width() {
                let c = g.centre_of((x, row));
                if (c.x - 4.0).abs() < 0.02 {
                    assert_eq!(
                        g.state((x, row)),
                        CellState::Occupied,
                        "offset {offset}: {c}"
                    );
                }
                if c.x < 3.9 && c.x > 0.1 {
                    assert_eq!(g.state((x, row)), CellState::Free, "offset {offset}: {c}");
                }
            }
        }
    }

    #[test]
    fn noisy_scans_are_repeatable_and_ideal_noise_is_the_ideal_scan() {
        let w = World::parse("room 0 0 4 0 4 3 0 3\nbox 2.5 1 3 1.5\nstart 1 1.5 0.3\n").unwrap();
        let scan = |noise: SensingNoise| {
            let mut g = grid_for(&w, 0.05, 0.5, 0.0);
            let mut s = NoisyScanner::new(noise);
            for _ in 0..3 {
                s.scan_into(&w, &[], &w.start, Sink::Grid(&mut g));
            }
            cells(&g)
        };
        let mut ideal = grid_for(&w, 0.05, 0.5, 0.0);
        for _ in 0..3 {
            scan_into(&w, &w.start, &mut ideal);
        }
        assert_eq!(scan(SensingNoise::default()), cells(&ideal));
        let noise = SensingNoise {
            range: 0.01,
            position: 0.005,
            heading: 0.002,
            seed: 4,
        };
        let a = scan(noise);
        assert_eq!(a, scan(noise));
        let differ = a
            .iter()
            .zip(cells(&ideal))
            .filter(|(x, y)| **x != *y)
            .count();
        assert!(differ > 0, "noise changed no cell");
        assert_ne!(a, scan(SensingNoise { seed: 5, ..noise }));
    }
}
