//! The messages on the daemon's edges. Each carries the monotonic stamp of
//! the scan it descends from (`t0`, taken when the scan arrived) so the
//! motor stage can record the end-to-end latency of the wheel command a scan
//! produced.

use std::sync::Arc;

use nalgebra::Point2;

use crate::geom::Pose;
use crate::grid::Grid;
use crate::motor::WheelSpeeds;
use crate::pipeline::clock::Stamp;
use crate::scan::LaserScan;

/// scanner → localise: one scan with the robot's odometry at its time.
#[derive(Clone, Debug)]
pub struct ScanMsg {
    /// When the scan arrived (monotonic).
    pub t0: Stamp,
    /// The scan's time on the daemon clock (s).
    pub stamp: f64,
    /// Odometry pose of the robot at `stamp` (odometry frame); the localise
    /// stage, which owns the scanner's mount, composes the scanner's.
    pub odom: Pose,
    /// Whether an odometry reading came at or after `stamp`
    /// ([`ScanOdometry::current`]): only then is `odom` measured at the
    /// scan's time, and an `odom` equal to the previous scan's says the robot
    /// stood still.
    ///
    /// [`ScanOdometry::current`]: crate::daemon::shared::ScanOdometry::current
    pub(crate) odom_current: bool,
    /// Time between two scans when none is lost (s; 0 when unknown).
    pub interval: f64,
    /// The robot's odometry motion over `MOTION_WINDOW` ending at the
    /// scan's last beam (or the newest odometry reading before it): its
    /// velocity while the scanner swept the beams, for deskewing.
    pub motion: Pose,
    /// The scan.
    pub scan: LaserScan,
}

/// Over how long (s) the scanner stage measures the odometry's motion
/// ([`ScanMsg::motion`]): one scan period of the URG-04LX, longer than its
/// sweep, short enough that the velocity has hardly changed.
pub(crate) const MOTION_WINDOW: f64 = 0.1;

/// localise → control: the robot's pose at a scan's time.
#[derive(Clone, Copy, Debug)]
pub struct PoseFix {
    /// When the scan arrived (monotonic).
    pub t0: Stamp,
    /// The scan's time on the daemon clock (s).
    pub stamp: f64,
    /// Robot pose in the map frame.
    pub pose: Pose,
    /// Robot odometry pose at the same time (odometry frame).
    pub odom: Pose,
    /// False when the match was rejected and the odometry prediction used.
    pub matched: bool,
}

/// localise or motor → map.
// The scan travels by value (no allocation per scan); contacts are rare.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum MapMsg {
    /// A registered scan: the scanner pose in the map frame and the scan.
    Scan {
        /// Scanner pose.
        pose: Pose,
        /// The scan.
        scan: LaserScan,
    },
    /// A bumper contact: an obstacle the scanner did not see.
    Contact(super::contact::ContactMark),
    /// plan → map: the contact marked at this point (map frame, m) walls
    /// off floor; it is taken out so the robot can try that floor once.
    Retire(nalgebra::Point2<f64>),
}

/// map → plan: a map snapshot.
#[derive(Clone, Debug)]
pub struct MapSnapshot {
    /// The explored-area grid, contact marks included.
    pub grid: Arc<Grid>,
    /// New bumper contacts marked in it so far (a planner that saw fewer
    /// must give up its current path: it ran into something).
    pub contacts: u64,
    /// Requests to take a contact mark out handled so far (a planner that
    /// sent more waits for the snapshot without the mark).
    pub(crate) retired: u64,
}

/// plan → control: a path to follow.
#[derive(Clone, Debug)]
pub struct PathMsg {
    /// Sequence number (increases with every new path).
    pub seq: u64,
    /// Waypoints (m, map frame).
    pub points: Vec<Point2<f64>>,
    /// Heading to turn to at the end, if any (rad).
    pub final_heading: Option<f64>,
}

/// control → motor: wheel speeds.
#[derive(Clone, Copy, Debug)]
pub struct CmdMsg {
    /// Left and right wheel speeds (m/s).
    pub wheels: WheelSpeeds,
    /// The scan this command answers, when it was produced by a new pose fix.
    pub t0: Option<Stamp>,
}
