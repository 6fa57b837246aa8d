//! Path following for a differential drive within the robot's speed limits.
//!
//! The follower drives a polyline of waypoints: it turns in place whenever
//! the heading error to the next waypoint is large (lane ends, corners of
//! transit paths), otherwise it drives along the current segment with a
//! heading and cross-track correction, slowing down before waypoints where a
//! turn follows. It produces a body twist (v, ω) and the left/right wheel
//! speeds for the configured wheel base, both clipped so that neither wheel
//! nor the turn rate exceeds the robot's limits. Pure and deterministic: the
//! caller passes the pose and the time step.
//!
//! Given what the newest scan shows straight ahead ([`guard`]), the follower
//! also stops short of something its path does not expect: nearer than the
//! next waypoint, it brakes to stand `guard_gap` before it.

pub mod guard;

use nalgebra::Point2;

use crate::geom::{heading, wrap_angle, Pose};
use crate::robot::RobotParams;

/// Path follower settings.
/// Loaded from the `[control]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlParams {
    /// Distance at which a waypoint counts as reached (m).
    pub(crate) waypoint_tolerance: f64,
    /// Heading error above which the robot stops and turns in place (rad).
    pub(crate) turn_in_place_above: f64,
    /// Heading error below which a turn in place is finished (rad).
    pub(crate) aligned_below: f64,
    /// Proportional gain from heading error to turn rate (1/s).
    pub heading_gain: f64,
    /// Gain from cross-track error to turn rate (rad/(m·s)).
    pub(crate) cross_track_gain: f64,
    /// Deceleration used to slow down before a stop (m/s²).
    pub max_accel: f64,
    /// Angular deceleration used to end turns in place without overshoot (rad/s²).
    pub(crate) max_angular_accel: f64,
    /// Whether the follower stops short of something the newest scan shows
    /// ahead, nearer than its next waypoint (the protective field).
    pub guard: bool,
    /// Gap kept short of such a thing (m).
    pub guard_gap: f64,
    /// Strip along each flank of the body the field does not watch (m): a
    /// wall passed at the planner's clearance, read short by the scanner's
    /// noise, must not stop the robot.
    pub guard_side_clearance: f64,
    /// Something at most this much nearer than the next waypoint is what
    /// the path expects (the wall at a lane's end, read short) (m).
    pub(crate) guard_slack: f64,
}

impl Default for ControlParams {
    fn default() -> Self {
        Self {
            waypoint_tolerance: 0.01,
            turn_in_place_above: 0.25,
            aligned_below: 0.01,
            heading_gain: 3.0,
            cross_track_gain: 8.0,
            max_accel: 0.5,
            max_angular_accel: 2.0,
            guard: true,
            guard_gap: 0.05,
            guard_side_clearance: 0.03,
            guard_slack: 0.02,
        }
    }
}

/// Why a follower could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ControlError {
    /// A setting is out of its allowed range.
    #[error("control.{key}: {message}")]
    BadParam {
        /// The key in the `[control]` table.
        key: &'static str,
        /// What is wrong.
        message: String,
    },
}

impl ControlParams {
    /// Checks every value range, naming the key that is wrong.
    pub fn validate(&self) -> Result<(), ControlError> {
        for (key, v) in [
            ("waypoint_tolerance", self.waypoint_tolerance),
            ("turn_in_place_above", self.turn_in_place_above),
            ("aligned_below", self.aligned_below),
            ("heading_gain", self.heading_gain),
            ("cross_track_gain", self.cross_track_gain),
            ("max_accel", self.max_accel),
            ("max_angular_accel", self.max_angular_accel),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(ControlError::BadParam {
                    key,
                    message: format!("must be a finite number > 0, got {v}"),
                });
            }
        }
        for (key, v) in [
            ("guard_gap", self.guard_gap),
            ("guard_side_clearance", self.guard_side_clearance),
            ("guard_slack", self.guard_slack),
        ] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return Err(ControlError::BadParam {
                    key,
                    message: format!("must be a finite number in 0..=1 m, got {v}"),
                });
            }
        }
        if self.aligned_below >= self.turn_in_place_above {
            return Err(ControlError::BadParam {
                key: "aligned_below",
                message: "must be smaller than turn_in_place_above".into(),
            });
        }
        Ok(())
    }
}

/// Left and right wheel ground speeds (m/s), positive forward.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WheelCmd {
    /// Left wheel (m/s).
    pub left: f64,
    /// Right wheel (m/s).
    pub right: f64,
}

/// Body velocity: forward speed and turn rate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Twist {
    /// Forward speed (m/s).
    pub v: f64,
    /// Turn rate (rad/s, counter-clockwise).
    pub w: f64,
}

impl Twist {
    /// The wheel speeds of this twist for a wheel base `b` (m).
    pub(crate) fn to_wheels(self, b: f64) -> WheelCmd {
        WheelCmd {
            left: self.v - self.w * b / 2.0,
            right: self.v + self.w * b / 2.0,
        }
    }

    /// The twist of wheel speeds `cmd` for a wheel base `b` (m).
    pub fn from_wheels(cmd: &WheelCmd, b: f64) -> Self {
        Self {
            v: (cmd.left + cmd.right) / 2.0,
            w: (cmd.right - cmd.left) / b,
        }
    }
}

/// What the follower is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FollowState {
    /// No path, or the path is done: standing still.
    Idle,
    /// Turning in place towards the next waypoint or the final heading.
    Turning,
    /// Driving along a segment.
    Driving,
}

/// Tracks a polyline with turn-in-place at sharp corners.
#[derive(Clone, Debug)]
pub struct PathFollower {
    params: ControlParams,
    max_speed: f64,
    max_turn_rate: f64,
    wheel_base: f64,
    path: Vec<Point2<f64>>,
    final_heading: Option<f64>,
    next: usize,
    state: FollowState,
    last: Twist,
    horizon: f64,
    radius: f64,
    held_short: bool,
}

/// Integrates unicycle kinematics exactly over `dt` (arc motion).
pub fn integrate(pose: &Pose, twist: &Twist, dt: f64) -> Pose {
    let th = heading(pose);
    let (x, y) = (pose.translation.x, pose.translation.y);
    let dth = twist.w * dt;
    let (nx, ny) = if dth.abs() < 1e-9 {
        (x + twist.v * dt * th.cos(), y + twist.v * dt * th.sin())
    } else {
        let r = twist.v / twist.w;
        (
            x + r * ((th + dth).sin() - th.sin()),
            y - r * ((th + dth).cos() - th.cos()),
        )
    };
    crate::geom::pose(nx, ny, wrap_angle(th + dth))
}

impl PathFollower {
    /// A follower with `params` for the robot `robot` (speed limits, wheel base).
    pub fn new(params: &ControlParams, robot: &RobotParams) -> Result<Self, ControlError> {
        params.validate()?;
        if params.guard_side_clearance >= robot.radius {
            return Err(ControlError::BadParam {
                key: "guard_side_clearance",
                message: format!(
                    "must be smaller than robot.radius ({} m), got {}",
                    robot.radius, params.guard_side_clearance
                ),
            });
        }
        for (key, v) in [
            ("robot.max_speed", robot.max_speed),
            ("robot.max_turn_rate", robot.max_turn_rate),
            ("robot.wheel_base", robot.wheel_base),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(ControlError::BadParam {
                    key,
                    message: format!("must be a finite number > 0, got {v}"),
                });
            }
        }
        Ok(Self {
            params: params.clone(),
            max_speed: robot.max_speed,
            max_turn_rate: robot.max_turn_rate,
            wheel_base: robot.wheel_base,
            path: Vec::new(),
            final_heading: None,
            next: 0,
            state: FollowState::Idle,
            last: Twist::default(),
            horizon: 0.0,
            radius: robot.radius,
            held_short: false,
        })
    }

    /// Bounds the speed near a stop so that a command left in force for
    /// `horizon` seconds (the base's dead-man time: a host that stalls
    /// sends no newer one) still does not carry the robot past the stop.
    /// Without it a stall at a lane's end ran the robot 5 cm on into the
    /// wall in a loaded CI run. Costs about 0.2 s per stop.
    pub fn with_command_horizon(mut self, horizon: f64) -> Self {
        self.horizon = if horizon.is_finite() {
            horizon.max(0.0)
        } else {
            0.0
        };
        self
    }

    /// Replaces the path: drive through `points` in order, then, if given,
    /// turn in place to `final_heading` (rad). Non-finite points are dropped.
    pub fn set_path(&mut self, points: &[Point2<f64>], final_heading: Option<f64>) {
        self.path.clear();
        self.path
            .extend(points.iter().filter(|p| p.x.is_finite() && p.y.is_finite()));
        self.final_heading = final_heading.filter(|h| h.is_finite());
        self.next = 0;
        self.state = if self.path.is_empty() && self.final_heading.is_none() {
            FollowState::Idle
        } else {
            FollowState::Turning
        };
    }

    /// Whether the path (and the final turn) is finished.
    pub fn is_done(&self) -> bool {
        self.state == FollowState::Idle
    }

    /// What the follower is doing now.
    pub fn state(&self) -> FollowState {
        self.state
    }

    /// Index of the waypoint being driven to.
    pub fn next_index(&self) -> usize {
        self.next
    }

    /// The path being followed.
    pub fn path(&self) -> &[Point2<f64>] {
        &self.path
    }

    /// One control step at `pose` for a period of `dt` seconds: the twist and
    /// wheel speeds to apply until the next step.
    pub fn step(&mut self, pose: &Pose, dt: f64) -> (Twist, WheelCmd) {
        self.step_guarded(pose, dt, None)
    }

    /// [`PathFollower::step`] with the protective field: `ahead` holds the
    /// newest scan's points and `odom` is the robot's odometry pose in their
    /// frame. The robot stops `guard_gap` short of a point the body would
    /// touch driving straight on when that is nearer than the next waypoint
    /// (less `guard_slack`); [`PathFollower::held_short`] tells when it did.
    pub fn step_guarded(
        &mut self,
        pose: &Pose,
        dt: f64,
        ahead: Option<(&guard::ObstaclePoints, &Pose)>,
    ) -> (Twist, WheelCmd) {
        self.held_short = false;
        let ahead = ahead.filter(|_| self.params.guard);
        let twist = self.compute(pose, dt, ahead);
        let twist = self.limit(twist);
        self.last = twist;
        (twist, twist.to_wheels(self.wheel_base))
    }

    /// Whether the protective field is on (`control.guard`).
    pub fn guards(&self) -> bool {
        self.params.guard
    }

    /// Whether the last step slowed or stopped for something its path does
    /// not expect ahead (the protective field).
    pub fn held_short(&self) -> bool {
        self.held_short
    }

    fn limit(&self, t: Twist) -> Twist {
        let mut v = t.v.clamp(-self.max_speed, self.max_speed);
        let w = t.w.clamp(-self.max_turn_rate, self.max_turn_rate);
        // Neither wheel may exceed max_speed: shrink v first, keep the turn.
        let half = w.abs() * self.wheel_base / 2.0;
        if v.abs() + half > self.max_speed {
            v = v.signum() * (self.max_speed - half).max(0.0);
        }
        Twist { v, w }
    }

    fn turn_rate_towards(&self, err: f64) -> f64 {
        // Rate that still stops at the target with the angular deceleration.
        let stop = (2.0 * self.params.max_angular_accel * err.abs()).sqrt();
        let w = (self.params.heading_gain * err.abs())
            .min(stop)
            .min(self.max_turn_rate);
        w.max(0.05_f64.min(self.max_turn_rate)) * err.signum()
    }

    fn compute(
        &mut self,
        pose: &Pose,
        dt: f64,
        ahead: Option<(&guard::ObstaclePoints, &Pose)>,
    ) -> Twist {
        let p: Point2<f64> = pose.translation.vector.into();
        let th = heading(pose);
        // Skip reached waypoints.
        while self.next < self.path.len()
            && (self.path[self.next] - p).norm() <= self.params.waypoint_tolerance
        {
            self.next += 1;
            self.state = FollowState::Turning;
        }
        if self.next >= self.path.len() {
            if let Some(h) = self.final_heading {
                let err = wrap_angle(h - th);
                if err.abs() <= self.params.aligned_below {
                    self.final_heading = None;
                    self.state = FollowState::Idle;
                    return Twist::default();
                }
                self.state = FollowState::Turning;
                return Twist {
                    v: 0.0,
                    w: self.exact_turn(err, dt),
                };
            }
            self.state = FollowState::Idle;
            return Twist::default();
        }
        let goal = self.path[self.next];
        let from = if self.next > 0 {
            self.path[self.next - 1]
        } else {
            p
        };
        let to_goal = goal - p;
        let dist = to_goal.norm();
        let bearing = to_goal.y.atan2(to_goal.x);
        let err = wrap_angle(bearing - th);
        if self.state == FollowState::Turning {
            if err.abs() > self.params.aligned_below && dist > self.params.waypoint_tolerance {
                return Twist {
                    v: 0.0,
                    w: self.exact_turn(err, dt),
                };
            }
            self.state = FollowState::Driving;
        } else if err.abs() > self.params.turn_in_place_above {
            self.state = FollowState::Turning;
            return Twist {
                v: 0.0,
                w: self.exact_turn(err, dt),
            };
        }
        // Drive: heading along the segment plus cross-track correction. A
        // robot already past the waypoint along its segment (an overshoot)
        // drives straight back to it instead: the segment has nothing left.
        let seg = goal - from;
        let past = seg.norm() > 1e-6 && to_goal.dot(&seg) <= 0.0;
        let seg = if past { to_goal } else { seg };
        let (seg_heading, cross) = if seg.norm() > 1e-6 && !past {
            let d = seg / seg.norm();
            let off = p - from;
            (d.y.atan2(d.x), d.x * off.y - d.y * off.x)
        } else {
            (bearing, 0.0)
        };
        let herr = if dist > 0.05 && !past {
            wrap_angle(seg_heading - th)
        } else {
            err
        };
        let w = self.params.heading_gain * herr - self.params.cross_track_gain * cross;
        // Speed: slow down so the robot stops at a waypoint followed by a sharp turn.
        let stop_here = self.stops_at(self.next);
        let mut v = self.max_speed;
        let dist_along = to_goal.dot(&(seg / seg.norm().max(1e-9))).max(0.0);
        if stop_here {
            v = v.min(self.stopping_speed(dist_along, dt));
        }
        // Something ahead that the segment does not reach for: stop short.
        // Only driving needs the field: it is looked at here, not per step.
        let free = ahead.map_or(f64::INFINITY, |(points, odom)| {
            points.free_ahead(odom, self.radius, self.params.guard_side_clearance)
        });
        if free < dist_along - self.params.guard_slack {
            let cap = self.stopping_speed((free - self.params.guard_gap).max(0.0), dt);
            if cap < v {
                v = cap;
                self.held_short = true;
            }
        }
        let v = v.min(self.last.v.abs() + self.params.max_accel * dt);
        Twist { v, w }
    }

    /// The highest speed that still stops within `room` (m) with the
    /// deceleration, and within one step or the command horizon.
    fn stopping_speed(&self, room: f64, dt: f64) -> f64 {
        (2.0 * self.params.max_accel * room)
            .sqrt()
            .min(room / dt.max(self.horizon).max(1e-6))
    }

    /// Turn rate that reaches a heading error `err` without overshooting in one step.
    fn exact_turn(&self, err: f64, dt: f64) -> f64 {
        let w = self.turn_rate_towards(err);
        if w.abs() * dt > err.abs() {
            err / dt.max(1e-6)
        } else {
            w
        }
    }

    /// Whether the robot must stop at waypoint `i` (last one, or a corner
    /// sharper than the turn-in-place threshold).
    fn stops_at(&self, i: usize) -> bool {
        if i + 1 >= self.path.len() {
            return true;
        }
        let prev = if i > 0 {
            self.path[i - 1]
        } else {
            self.path[i]
        };
        let (a, b) = (self.path[i] - prev, self.path[i + 1] - self.path[i]);
        if a.norm() < 1e-9 || b.norm() < 1e-9 {
            return true;
        }
        let turn = wrap_angle(b.y.atan2(b.x) - a.y.atan2(a.x));
        turn.abs() > self.params.turn_in_place_above
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    fn robot() -> RobotParams {
        RobotParams::default()
    }

    fn run(f: &mut PathFollower, mut p: Pose, steps: usize) -> (Pose, f64, f64) {
        let (mut max_v, mut max_w) = (0.0f64, 0.0f64);
        for _ in 0..steps {
            let (t, wheels) = f.step(&p, 0.05);
            max_v = max_v.max(wheels.left.abs()).max(wheels.right.abs());
            max_w = max_w.max(t.w.abs());
            p = integrate(&p, &t, 0.05);
            if f.is_done() {
                break;
            }
        }
        (p, max_v, max_w)
    }

    /// Drives `f` for `steps` steps of 0.05 s from `p`, a scan every other
    /// step seeing the world points `seen(step)`; returns the end pose, the
    /// nearest the robot's centre came to `near`, and whether it held short.
    fn run_seeing(
        f: &mut PathFollower,
        mut p: Pose,
        steps: usize,
        near: Point2<f64>,
        seen: impl Fn(usize) -> Vec<Point2<f64>>,
    ) -> (Pose, f64, bool) {
        let mut ahead = guard::ObstaclePoints::default();
        let (mut closest, mut held) = (f64::INFINITY, false);
        for k in 0..steps {
            if k % 2 == 0 {
                ahead.clear(p);
                for q in seen(k) {
                    ahead.push(p.inverse() * q);
                }
            }
            let (t, _) = f.step_guarded(&p, 0.05, Some((&ahead, &p)));
            held |= f.held_short();
            p = integrate(&p, &t, 0.05);
            closest = closest.min((Point2::from(p.translation.vector) - near).norm());
        }
        (p, closest, held)
    }

    /// The front half of a person's disc of radius 0.2 m at `c`, as a
    /// scanner at the origin sees it.
    fn person(c: Point2<f64>) -> Vec<Point2<f64>> {
        (0..=20)
            .map(|k| {
                let a = std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * k as f64 / 20.0;
                c + 0.2 * nalgebra::Vector2::new(a.cos(), a.sin())
            })
            .collect()
    }

    #[test]
    fn stops_short_of_a_person_in_its_lane_and_goes_on_once_they_are_gone() {
        let body = robot().radius;
        let c = Point2::new(1.5, 0.0);
        let lane = [Point2::new(3.0, 0.0)];
        let mut f = PathFollower::new(&ControlParams::default(), &robot()).unwrap();
        f.set_path(&lane, None);
        let start = pose(0.0, 0.0, 0.0);
        let (stood, closest, held) = run_seeing(&mut f, start, 200, c, |_| person(c));
        assert!(held);
        assert!(!f.is_done());
        // It stands about control.guard_gap short of touching, still.
        let gap = closest - body - 0.2;
        assert!((0.03..0.08).contains(&gap), "gap {gap}");
        let mut ahead = guard::ObstaclePoints::default();
        ahead.clear(stood);
        for q in person(c) {
            ahead.push(stood.inverse() * q);
        }
        let (t, _) = f.step_guarded(&stood, 0.05, Some((&ahead, &stood)));
        assert!(t.v.abs() < 1e-9, "{t:?}");
        // The person walks off: the lane is driven to its end.
        let (end, _, _) = run_seeing(&mut f, stood, 400, c, |_| Vec::new());
        assert!(f.is_done(), "{end:?}");
        // Without the field the body runs into the person.
        let off = ControlParams {
            guard: false,
            ..ControlParams::default()
        };
        let mut f = PathFollower::new(&off, &robot()).unwrap();
        f.set_path(&lane, None);
        let (_, closest, held) = run_seeing(&mut f, start, 200, c, |_| person(c));
        assert!(!held);
        assert!(closest < body + 0.2, "{closest}");
    }

    #[test]
    fn a_wall_at_a_lanes_end_read_short_and_walls_along_it_do_not_stop_it() {
        // A lane ending 1 cm before a wall and passing 1 cm beside another,
        // both read up to 2 cm short.
        let body = robot().radius;
        let end = Point2::new(2.0, 0.0);
        let walls = |k: usize| -> Vec<Point2<f64>> {
            let short = |i: usize| 0.02 * (((i + k) % 5) as f64) / 4.0;
            let mut w: Vec<Point2<f64>> = (0..100)
                .map(|i| Point2::new(2.0 + body + 0.01 - short(i), -1.0 + 0.02 * i as f64))
                .collect();
            w.extend((0..110).map(|i| Point2::new(0.02 * i as f64, body + 0.01 - short(i))));
            w
        };
        let mut f = PathFollower::new(&ControlParams::default(), &robot()).unwrap();
        f.set_path(&[end], None);
        let (at, _, held) = run_seeing(&mut f, pose(0.0, 0.0, 0.0), 400, end, walls);
        assert!(!held);
        assert!(f.is_done());
        assert!(
            (Point2::from(at.translation.vector) - end).norm() <= 0.011,
            "{at:?}"
        );
    }

    #[test]
    fn drives_a_square_within_limits_and_ends_on_the_corner() {
        let mut f = PathFollower::new(&ControlParams::default(), &robot()).unwrap();
        let pts = [
            Point2::new(1.0, 0.0),
            Point2::new(1.0, 1.0),
            Point2::new(0.0, 1.0),
            Point2::new(0.0, 0.0),
        ];
        f.set_path(&pts, Some(0.0));
        let (end, max_v, max_w) = run(&mut f, pose(0.0, 0.0, 0.0), 2000);
        assert!(f.is_done());
        assert!(end.translation.vector.norm() < 0.015, "{end:?}");
        assert!(heading(&end).abs() < 0.02);
        assert!(max_v <= robot().max_speed + 1e-9, "{max_v}");
        assert!(max_w <= robot().max_turn_rate + 1e-9, "{max_w}");
    }

    #[test]
    fn a_command_left_in_force_for_the_horizon_stops_short_of_the_end() {
        let mut f = PathFollower::new(&ControlParams::default(), &robot())
            .unwrap()
            .with_command_horizon(0.25);
        let end = Point2::new(1.0, 0.0);
        f.set_path(&[Point2::new(0.0, 0.0), end], None);
        let mut p = pose(0.0, 0.0, 0.0);
        let mut checked = 0;
        for _ in 0..2000 {
            let (t, _) = f.step(&p, 0.05);
            // Were this the last command for 0.25 s, where would it end?
            let stalled = integrate(&p, &t, 0.25);
            assert!(
                stalled.translation.x <= end.x + 1e-9,
                "at {:.3} m a stall ends at {:.3} m",
                p.translation.x,
                stalled.translation.x
            );
            checked += usize::from(t.v > 0.0);
            p = integrate(&p, &t, 0.05);
            if f.is_done() {
                break;
            }
        }
        assert!(f.is_done() && checked > 50);
        assert!((p.translation.x - end.x).abs() < 0.015, "{p:?}");
        // Without the horizon the same approach would overshoot a stall.
        let mut f = PathFollower::new(&ControlParams::default(), &robot()).unwrap();
        f.set_path(&[Point2::new(0.0, 0.0), end], None);
        let mut p = pose(0.0, 0.0, 0.0);
        let mut worst = f64::NEG_INFINITY;
        for _ in 0..2000 {
            let (t, _) = f.step(&p, 0.05);
            worst = worst.max(integrate(&p, &t, 0.25).translation.x - end.x);
            p = integrate(&p, &t, 0.05);
            if f.is_done() {
                break;
            }
        }
        assert!(worst > 0.01, "{worst}");
    }

    #[test]
    fn stays_on_a_long_lane() {
        let mut f = PathFollower::new(&ControlParams::default(), &robot()).unwrap();
        f.set_path(&[Point2::new(0.0, 0.0), Point2::new(4.0, 0.0)], None);
        let mut p = pose(0.0, 0.02, 0.05);
        let mut worst = 0.0f64;
        for _ in 0..2000 {
            let (t, _) = f.step(&p, 0.05);
            p = integrate(&p, &t, 0.05);
            if p.translation.x > 0.5 {
                worst = worst.max(p.translation.y.abs());
            }
            if f.is_done() {
                break;
            }
        }
        assert!(f.is_done());
        assert!(worst < 0.01, "cross-track {worst}");
    }

    #[test]
    fn wheel_speeds_round_trip() {
        let t = Twist { v: 0.1, w: 0.5 };
        let w = t.to_wheels(0.235);
        let back = Twist::from_wheels(&w, 0.235);
        assert!((back.v - 0.1).abs() < 1e-12 && (back.w - 0.5).abs() < 1e-12);
        // Turning in place: wheels opposite.
        let w = Twist { v: 0.0, w: 0.78 }.to_wheels(0.235);
        assert!((w.left + w.right).abs() < 1e-12 && w.right > 0.0);
    }

    #[test]
    fn bad_params_and_empty_paths() {
        let p = ControlParams {
            heading_gain: f64::NAN,
            ..ControlParams::default()
        };
        let e = PathFollower::new(&p, &robot()).unwrap_err();
        assert!(e.to_string().contains("heading_gain"), "{e}");
        for (p, key) in [
            (
                ControlParams {
                    guard_gap: -0.01,
                    ..ControlParams::default()
                },
                "guard_gap",
            ),
            (
                ControlParams {
                    guard_slack: f64::INFINITY,
                    ..ControlParams::default()
                },
                "guard_slack",
            ),
            (
                ControlParams {
                    guard_side_clearance: 0.2,
                    ..ControlParams::default()
                },
                "guard_side_clearance",
            ),
        ] {
            let e = PathFollower::new(&p, &robot()).unwrap_err();
            assert!(e.to_string().contains(key), "{e}");
        }
        let mut f = PathFollower::new(&ControlParams::default(), &robot()).unwrap();
        f.set_path(&[], None);
        assert!(f.is_done());
        f.set_path(&[Point2::new(f64::NAN, 0.0)], None);
        let (t, _) = f.step(&pose(0.0, 0.0, 0.0), 0.05);
        assert_eq!(t, Twist::default());
        assert!(f.is_done());
    }

    #[test]
    fn a_robot_past_its_waypoint_drives_back_to_it() {
        // The lane runs south to (1, 1); the robot overshot it by 7 cm (a
        // stalled control step) and stands facing south. It used to turn to
        // face the waypoint, then steer back along the lane's heading with
        // no forward speed (nothing left "along" the lane), for ever.
        let mut f = PathFollower::new(&ControlParams::default(), &robot()).unwrap();
        f.set_path(&[Point2::new(1.0, 2.0), Point2::new(1.0, 1.0)], None);
        let mut p = pose(1.0, 2.0, -std::f64::consts::FRAC_PI_2);
        f.step(&p, 0.05);
        assert_eq!(f.next_index(), 1);
        p = pose(1.0, 0.93, -std::f64::consts::FRAC_PI_2);
        let (end, _, _) = run(&mut f, p, 400);
        assert!(f.is_done(), "still at {:?}", end.translation.vector);
        assert!(
            (end.translation.y - 1.0).abs() <= 0.011,
            "{:?}",
            end.translation.vector
        );
    }

    #[test]
    fn exact_integration_of_an_arc() {
        let p = integrate(
            &pose(0.0, 0.0, 0.0),
            &Twist {
                v: std::f64::consts::PI / 2.0,
                w: std::f64::consts::PI / 2.0,
            },
            1.0,
        );
        assert!((p.translation.x - 1.0).abs() < 1e-9 && (p.translation.y - 1.0).abs() < 1e-9);
    }
}
