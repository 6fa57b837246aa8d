//! The daemon's own settings: the `[daemon]` table (how the control loop
//! gives a path up, where bumper contacts are marked).

use serde::{Deserialize, Serialize};

use super::contact::ContactParams;
use super::stuck::STUCK_AFTER;
use crate::param_check::{invalid, ParamError};

/// Longest `daemon.stuck_after` accepted (clock s).
pub(crate) const MAX_STUCK_AFTER: f64 = 3600.0;

/// Default of `daemon.scan_timeout` (clock s): ten scan periods of the
/// URG-04LX.
pub(crate) const SCAN_TIMEOUT: f64 = 1.0;

/// Longest `daemon.scan_timeout` accepted (clock s).
pub(crate) const MAX_SCAN_TIMEOUT: f64 = 10.0;

/// Default of `daemon.plan_interval` (clock s): five plans a second.
pub(crate) const PLAN_INTERVAL: f64 = 0.2;

/// Longest `daemon.plan_interval` accepted (clock s).
pub(crate) const MAX_PLAN_INTERVAL: f64 = 10.0;

/// Default of `daemon.lost_after` (clock s): twenty URG-04LX scans.
pub(crate) const LOST_AFTER: f64 = 2.0;

/// Longest `daemon.lost_after` accepted (clock s).
pub(crate) const MAX_LOST_AFTER: f64 = 60.0;

/// Default of `daemon.relocalise_radius` (m): a large room.
pub(crate) const RELOCALISE_RADIUS: f64 = 10.0;

/// The `[daemon]` table.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DaemonParams {
    /// Clock seconds without headway after which the control stage gives a
    /// path up (see [`super::stuck::ProgressWatch`]).
    pub stuck_after: f64,
    /// Clock seconds without a new scan after which the control stage holds
    /// the wheels until scans return: the robot drives on odometry across
    /// a short gap but not blind for long (no obstacle sensing).
    pub scan_timeout: f64,
    /// Shortest clock time between two planner updates: a slower robot PC
    /// may plan less often, leaving new obstacles to the protective field
    /// (`control.guard`) for longer.
    pub plan_interval: f64,
    /// At a fresh start, turn the map frame so the walls of the first scan
    /// run along its axes (the lanes run along the axes; see
    /// [`super::align`]).
    pub align_to_walls: bool,
    /// Take the scanner's offset error measured over the first half turn in
    /// place and its yaw error measured over the first metre driven
    /// straight into the mount for the run (a mount a few centimetres or
    /// degrees off what `[robot]` says); off, such errors only warn, and
    /// stop the daemon above 3 cm or 3° (see [`super::offset_check`],
    /// [`super::travel_check`]).
    pub fit_scanner_mount: bool,
    /// Move every beam of a scan to where the scanner was at the scan's
    /// stamp, by the wheel odometry's motion, before matching and mapping:
    /// the scanner measures its beams one after another (the URG-04LX's
    /// sweep takes 67 ms), and a robot turning at 0.78 rad/s turns 3° in
    /// that time (see [`crate::scan::LaserScan::deskew`]).
    pub deskew_scans: bool,
    /// Clock seconds without an accepted match after which the robot is
    /// lost: the wheels are held and each scan is searched for over the
    /// whole map until it fits somewhere (a robot lifted and put down
    /// elsewhere, or a slip the local search cannot span); 0 = never.
    pub lost_after: f64,
    /// How far from the last estimate the whole-map search looks (m).
    pub relocalise_radius: f64,
    /// Bumper contact marks.
    pub contact: ContactParams,
}

impl Default for DaemonParams {
    fn default() -> Self {
        Self {
            stuck_after: STUCK_AFTER,
            scan_timeout: SCAN_TIMEOUT,
            plan_interval: PLAN_INTERVAL,
            align_to_walls: true,
            fit_scanner_mount: true,
            deskew_scans: true,
            lost_after: LOST_AFTER,
            relocalise_radius: RELOCALISE_RADIUS,
            contact: ContactParams::default(),
        }
    }
}

impl DaemonParams {
    /// Checks every value's range; the error names the dotted key.
    pub fn validate(&self) -> Result<(), ParamError> {
        let s = self.stuck_after;
        if !(s.is_finite() && (1.0..=MAX_STUCK_AFTER).contains(&s)) {
            return Err(invalid(
                "daemon.stuck_after",
                &format!("must be a finite number of seconds in 1..={MAX_STUCK_AFTER}, got {s:?}"),
            ));
        }
        let t = self.scan_timeout;
        if !(t.is_finite() && t > 0.0 && t <= MAX_SCAN_TIMEOUT) {
            return Err(invalid(
                "daemon.scan_timeout",
                &format!(
                    "must be a finite number of seconds in (0, {MAX_SCAN_TIMEOUT}], got {t:?}"
                ),
            ));
        }
        let p = self.plan_interval;
        if !(p.is_finite() && (0.01..=MAX_PLAN_INTERVAL).contains(&p)) {
            return Err(invalid(
                "daemon.plan_interval",
                &format!(
                    "must be a finite number of seconds in 0.01..={MAX_PLAN_INTERVAL}, got {p:?}"
                ),
            ));
        }
        let l = self.lost_after;
        if !(l.is_finite() && (0.0..=MAX_LOST_AFTER).contains(&l)) {
            return Err(invalid(
                "daemon.lost_after",
                &format!("must be a finite number of seconds in 0..={MAX_LOST_AFTER} (0 = never), got {l:?}"),
            ));
        }
        let r = self.relocalise_radius;
        if !(r.is_finite() && r > 0.0 && r <= 50.0) {
            return Err(invalid(
                "daemon.relocalise_radius",
                &format!("must be a finite number of metres in (0, 50], got {r:?}"),
            ));
        }
        self.contact.validate()
    }
}
