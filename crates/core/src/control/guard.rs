//! The protective field: what the newest scan shows straight ahead of the
//! body, so the follower can stop short of something its path does not
//! expect (a person stepping in, a chair pushed into a lane) within one
//! scan, without waiting for the map and the planner.
//!
//! The field is the strip the body sweeps when it drives straight on, less
//! a side clearance along each flank: the planner runs lanes and transits
//! about a centimetre from walls, and a flank band of the scanner's range
//! noise would see those walls "ahead" and stop the robot beside every one.
//! [`ObstaclePoints`] holds one scan's end points in the robot frame at the
//! scan's time (fixed capacity, no allocation) with the odometry pose they
//! were seen from; [`ObstaclePoints::free_ahead`] is the distance the body
//! can drive straight on from the robot's current odometry pose before it
//! touches one. Pure and deterministic.

use nalgebra::Point2;

use crate::capacity::MAX_BEAMS;
use crate::geom::Pose;
use crate::scan::LaserScan;

/// Longest free distance reported (m): nothing further matters to a robot
/// that stops within a few centimetres.
pub const WATCH_RANGE: f64 = 2.0;

/// A point further than this inside the body's outline (m) is the robot
/// itself (a mast, a cable, a bumper in the scanner's view) or a reading
/// of a covered window, never something in its way: left out, or it would
/// hold the robot for good. Nearer the outline it may be something
/// touching the body, read a little short: kept.
pub(crate) const SELF_INSIDE: f64 = 0.03;

/// One scan's end points in the robot frame, and where the robot was.
#[derive(Clone, Debug, Default)]
pub struct ObstaclePoints {
    points: heapless::Vec<[f32; 2], MAX_BEAMS>,
    /// Odometry pose of the robot when the scan was taken (any frame, the
    /// same one as the poses later passed to [`ObstaclePoints::free_ahead`]).
    pub at: Pose,
    /// Whether the last scan loaded by [`ObstaclePoints::load_scan`] spans
    /// the robot's straight-ahead direction (a scanner turned to face
    /// backwards does not: the field then watches nothing); `None` when it
    /// had no beams.
    pub covers_ahead: Option<bool>,
}

impl ObstaclePoints {
    /// Forgets the points: a new scan seen from odometry pose `at` follows.
    pub fn clear(&mut self, at: Pose) {
        self.points.clear();
        self.at = at;
    }

    /// Adds a point of the current scan (robot frame, m). Non-finite points
    /// and points past the capacity of one scan are dropped.
    pub fn push(&mut self, p: Point2<f64>) {
        if p.x.is_finite() && p.y.is_finite() {
            let _ = self.points.push([p.x as f32, p.y as f32]);
        }
    }

    /// Loads `scan` (scanner frame) seen from a scanner at `mount` in the
    /// robot frame, the robot at odometry pose `at`. Invalid beams are left
    /// out; no allocation.
    pub fn load_scan(&mut self, scan: &LaserScan, mount: &Pose, at: Pose) {
        self.clear(at);
        // Straight ahead of the robot, in the scanner's frame.
        let ahead = crate::geom::wrap_angle(-crate::geom::heading(mount));
        self.covers_ahead = match (scan.beams.first(), scan.beams.last()) {
            (Some(a), Some(b)) => {
                Some((a.angle.min(b.angle)..=a.angle.max(b.angle)).contains(&ahead))
            }
            _ => None,
        };
        for b in scan.beams.iter().filter(|b| b.valid) {
            let (s, c) = b.angle.sin_cos();
            self.push(mount * Point2::new(b.range * c, b.range * s));
        }
    }

    /// Number of points held.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether no point is held.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// How far (m, at most [`WATCH_RANGE`]) the body of radius `radius`
    /// can drive straight ahead from odometry pose `now` before it touches
    /// a point of the scan lying within `radius - side_clearance` of its
    /// centre line. A point at the front of the body gives 0; points more
    /// than `SELF_INSIDE` inside it (the robot itself) and points behind
    /// the axle do not stop forward motion. With no scan loaded nothing is
    /// known ahead: [`WATCH_RANGE`].
    pub fn free_ahead(&self, now: &Pose, radius: f64, side_clearance: f64) -> f64 {
        let half = radius - side_clearance;
        if half <= 0.0 {
            return WATCH_RANGE;
        }
        // The points move into the robot's frame now: the robot has driven
        // on since the scan (at most a scan period and a control period).
        let back = now.inverse() * self.at;
        let mut free = WATCH_RANGE;
        for &[x, y] in self.points.iter() {
            let p = back * Point2::new(f64::from(x), f64::from(y));
            if p.y.abs() >= half
                || p.x <= 0.0
                || p.x > free + radius
                || p.coords.norm() < radius - SELF_INSIDE
            {
                continue;
            }
            let reach = (radius * radius - p.y * p.y).sqrt();
            free = free.min((p.x - reach).max(0.0));
        }
        free
    }
}

/// Seconds of clear way that end a stop of the protective field.
pub(crate) const CLEAR_AFTER: f64 = 1.0;

/// A change in the follower's stop short of something ahead.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopEvent {
    /// The follower began to slow or stop for something unplanned ahead.
    Began,
    /// The way has been clear for `CLEAR_AFTER` seconds.
    Ended,
}

/// Counts stops of the protective field: one stop lasts until the way has
/// been clear for `CLEAR_AFTER` seconds, so a speed cap that comes and
/// goes from step to step is one stop, not many.
#[derive(Clone, Copy, Debug, Default)]
pub struct StopCounter {
    held: Option<f64>,
    /// Stops begun so far.
    pub stops: u64,
}

impl StopCounter {
    /// Notes whether the follower held short at time `now` (s); tells when a
    /// stop began or ended.
    pub fn note(&mut self, held_short: bool, now: f64) -> Option<StopEvent> {
        match (held_short, self.held) {
            (true, None) => {
                self.held = Some(now);
                self.stops += 1;
                Some(StopEvent::Began)
            }
            (true, Some(_)) => {
                self.held = Some(now);
                None
            }
            (false, Some(t)) if now - t >= CLEAR_AFTER => {
                self.held = None;
                Some(StopEvent::Ended)
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;
    use crate::scan::Beam;

    fn points(at: Pose, pts: &[(f64, f64)]) -> ObstaclePoints {
        let mut o = ObstaclePoints::default();
        o.clear(at);
        for &(x, y) in pts {
            o.push(Point2::new(x, y));
        }
        o
    }

    #[test]
    fn nothing_loaded_or_nothing_ahead_is_the_whole_watch_range() {
        let o = ObstaclePoints::default();
        assert_eq!(o.free_ahead(&pose(0.0, 0.0, 0.0), 0.17, 0.03), WATCH_RANGE);
        // Behind the axle, beside the flank band, and beyond the range.
        let o = points(
            pose(0.0, 0.0, 0.0),
            &[(-0.5, 0.0), (0.4, 0.15), (0.4, -0.15), (3.0, 0.0)],
        );
        assert_eq!(o.free_ahead(&pose(0.0, 0.0, 0.0), 0.17, 0.03), WATCH_RANGE);
    }

    #[test]
    fn a_point_on_the_centre_line_is_reached_by_the_front_of_the_body() {
        let o = points(pose(0.0, 0.0, 0.0), &[(0.67, 0.0)]);
        let f = o.free_ahead(&pose(0.0, 0.0, 0.0), 0.17, 0.03);
        assert!((f - 0.5).abs() < 1e-6, "{f}");
        // Off the centre line the round front reaches it later.
        let o = points(pose(0.0, 0.0, 0.0), &[(0.67, 0.10)]);
        let f = o.free_ahead(&pose(0.0, 0.0, 0.0), 0.17, 0.03);
        let want = 0.67 - (0.17f64.powi(2) - 0.01).sqrt();
        assert!((f - want).abs() < 1e-6, "{f} vs {want}");
        // Something touching the front, read a centimetre short: nothing
        // is free.
        let o = points(pose(0.0, 0.0, 0.0), &[(0.16, 0.0), (0.5, 0.0)]);
        assert_eq!(o.free_ahead(&pose(0.0, 0.0, 0.0), 0.17, 0.03), 0.0);
        // Points well inside the body are the robot's own (a mast in
        // view): they hold nothing back.
        let o = points(
            pose(0.0, 0.0, 0.0),
            &[(0.1, 0.0), (0.05, 0.02), (0.67, 0.0)],
        );
        let f = o.free_ahead(&pose(0.0, 0.0, 0.0), 0.17, 0.03);
        assert!((f - 0.5).abs() < 1e-6, "{f}");
    }

    #[test]
    fn a_wall_along_the_flank_at_the_planners_clearance_stops_nothing() {
        // A wall 1 cm beside the body, its points read up to 2 cm short.
        let wall: Vec<(f64, f64)> = (0..60)
            .map(|k| (k as f64 * 0.05 - 1.0, 0.18 - 0.02 * ((k % 3) as f64) / 2.0))
            .collect();
        let o = points(pose(0.0, 0.0, 0.0), &wall);
        assert_eq!(o.free_ahead(&pose(0.0, 0.0, 0.0), 0.17, 0.03), WATCH_RANGE);
    }

    #[test]
    fn the_points_follow_the_robot_driven_on_since_the_scan() {
        // Seen at odometry (1, 1) heading +90°: a point 0.6 m ahead.
        let at = pose(1.0, 1.0, std::f64::consts::FRAC_PI_2);
        let o = points(at, &[(0.6, 0.0)]);
        let f0 = o.free_ahead(&at, 0.17, 0.03);
        assert!((f0 - 0.43).abs() < 1e-6, "{f0}");
        // 0.1 m further along: 0.1 m less free.
        let f1 = o.free_ahead(&pose(1.0, 1.1, std::f64::consts::FRAC_PI_2), 0.17, 0.03);
        assert!((f1 - 0.33).abs() < 1e-6, "{f1}");
        // Turned to face away from it: nothing ahead.
        let f2 = o.free_ahead(&pose(1.0, 1.0, -std::f64::consts::FRAC_PI_2), 0.17, 0.03);
        assert_eq!(f2, WATCH_RANGE);
    }

    #[test]
    fn a_stop_lasts_until_the_way_has_been_clear_for_a_second() {
        let mut c = StopCounter::default();
        assert_eq!(c.note(false, 0.0), None);
        assert_eq!(c.note(true, 0.1), Some(StopEvent::Began));
        // The cap comes and goes: still the same stop.
        assert_eq!(c.note(false, 0.2), None);
        assert_eq!(c.note(true, 0.3), None);
        assert_eq!(c.note(false, 1.2), None);
        assert_eq!(c.note(false, 1.3), Some(StopEvent::Ended));
        assert_eq!(c.note(true, 2.0), Some(StopEvent::Began));
        assert_eq!(c.stops, 2);
    }

    #[test]
    fn a_scan_is_loaded_through_the_mount_without_its_invalid_beams() {
        let mut scan = LaserScan::default();
        for (angle, range, valid) in [(0.0, 0.5, true), (0.1, 0.02, false), (f64::NAN, 1.0, true)] {
            scan.beams
                .push(Beam {
                    angle,
                    range,
                    intensity: 0.0,
                    valid,
                })
                .unwrap();
        }
        // The scanner 0.1 m ahead of the axle.
        let mount = pose(0.1, 0.0, 0.0);
        let mut o = ObstaclePoints::default();
        o.load_scan(&scan, &mount, pose(0.0, 0.0, 0.0));
        assert_eq!(o.len(), 1);
        let f = o.free_ahead(&pose(0.0, 0.0, 0.0), 0.17, 0.03);
        assert!((f - 0.43).abs() < 1e-6, "{f}");
        assert_eq!(o.covers_ahead, Some(true));
        // Loading again replaces the points.
        o.load_scan(&LaserScan::default(), &mount, pose(0.0, 0.0, 0.0));
        assert!(o.is_empty());
        assert_eq!(o.covers_ahead, None);
        // A scanner facing backwards (its 0.0..0.1 rad beams point behind
        // the robot) does not cover the way ahead.
        o.load_scan(
            &scan,
            &pose(0.0, 0.0, std::f64::consts::PI),
            pose(0.0, 0.0, 0.0),
        );
        assert_eq!(o.covers_ahead, Some(false));
    }
}
