//! The channels of the live view and of `run.mcap`: topic names, and what
//! each carries. Frames: `map` (the daemon's map frame), `base_link` (the
//! robot), `world` (the simulator's world, `sim` only).

/// `foxglove.LaserScan` in `base_link`: each scan as delivered (before
/// deskewing), intensities where the sensor gives them.
pub const SCAN: &str = "/scan";
/// JSON [`sweepline_daemon::daemon::taps::ScanRecord`]: each scan exactly as
/// the localise stage got it, with the sensor's raw values and clock and the
/// wheel odometry; what `sweepline replay run.mcap` reads.
pub const SCAN_INPUT: &str = "/sweepline/scan_input";
/// JSON [`sweepline_daemon::daemon::taps::OdometryRecord`]: each wheel
/// odometry reading (50 Hz) exactly as the motor stage got it.
pub const ODOMETRY_INPUT: &str = "/sweepline/odometry_input";
/// `foxglove.PoseInFrame` in `map`: the localised robot pose of each scan.
pub const POSE: &str = "/pose";
/// `foxglove.PoseInFrame` in `odom`: the wheel odometry at each scan.
pub const ODOM: &str = "/odom";
/// `foxglove.FrameTransform` `map` → `base_link`, so a 3D panel follows the robot.
pub const TF: &str = "/tf";
/// `foxglove.Grid` in `map`: the evidence grid (1 Hz; int8 `occupancy`,
/// −1 unknown, 0-100).
pub const MAP: &str = "/map";
/// `foxglove.Grid` in `map`: the floor swept by the tool (1 Hz; uint8 `passes`).
pub const SWEPT: &str = "/swept";
/// `foxglove.SceneUpdate` in `map`: the cells (polygons coloured by state)
/// and the planned path, when they change.
pub const PLAN: &str = "/plan";
/// `foxglove.Log`: the daemon's log lines.
pub const LOG: &str = "/log";
/// JSON: coverage, task, link health, stage latencies and CPU (2 Hz).
pub const STATUS: &str = "/sweepline/status";
/// `foxglove.PoseInFrame` in `world`: the simulated robot's true pose (`sim` only).
pub const TRUTH: &str = "/sim/truth";
/// The `run.mcap` metadata record with the map frame's pose in the world
/// (`sim` only): keys `x`, `y`, `theta`.
pub const MAP_TO_WORLD: &str = "map_to_world";
