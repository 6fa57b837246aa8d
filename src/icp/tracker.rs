//! Scan-to-map tracking over a sequence of scans: predict from odometry or a
//! constant-velocity prior, match against the keyframe local map, accept or
//! fall back to the prediction, add keyframes as the robot moves.

use super::{IcpError, IcpParams, KeyframeMap, Matcher, Prior, Quality, Rejection};
use crate::config::ConfigError;
use crate::geom::{IPoint, Pose};

/// What happened to one scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outcome {
    /// The first scan: it became the map; the pose is the start pose.
    First,
    /// The match was accepted.
    Matched(Quality),
    /// The match failed; the pose is the prior's prediction.
    Failed(IcpError),
    /// The match ran but was judged unreliable; the pose is the prediction.
    Rejected(Rejection, Quality),
}

/// The result of one tracking step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// Estimated pose of the scanner in the world frame after this scan.
    pub pose: Pose,
    /// How it was obtained.
    pub outcome: Outcome,
    /// True when the scan was added to the local map as a keyframe.
    pub keyframe: bool,
}

/// Tracks the scanner pose over a sequence of scans (scan-to-map odometry).
#[derive(Debug)]
pub struct Tracker {
    matcher: Matcher,
    map: KeyframeMap,
    pose: Pose,
    velocity: Pose,
    last_odom: Option<Pose>,
    started: bool,
}

impl Tracker {
    /// A tracker starting at `start` with `params` (checked).
    pub fn new(params: IcpParams, start: Pose) -> Result<Self, ConfigError> {
        let map = KeyframeMap::new(&params);
        Ok(Self {
            matcher: Matcher::new(params)?,
            map,
            pose: start,
            velocity: Pose::identity(),
            last_odom: None,
            started: false,
        })
    }

    /// The current pose estimate.
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// The local map (keyframes and the reference built from them).
    pub fn map(&self) -> &KeyframeMap {
        &self.map
    }

    /// The matcher's parameters.
    pub fn params(&self) -> &IcpParams {
        self.matcher.params()
    }

    /// Processes one scan given as sensor-frame points in beam order, with the
    /// wheel odometry pose at the same time when there is one.
    pub fn step(&mut self, points: &[IPoint], odom: Option<&Pose>) -> Step {
        let odom_delta = match (odom, self.last_odom) {
            (Some(now), Some(before)) => Some(before.inverse() * now),
            _ => None,
        };
        if let Some(o) = odom {
            self.last_odom = Some(*o);
        }
        let prepared = self.matcher.prepare_points(points);
        if !self.started {
            return match prepared {
                Ok(_) => {
                    let params = self.matcher.params().clone();
                    let kf = self
                        .map
                        .insert(&self.pose, self.matcher.prepared_points(), &params);
                    match kf {
                        Ok(()) => {
                            self.started = true;
                            Step {
                                pose: self.pose,
                                outcome: Outcome::First,
                                keyframe: true,
                            }
                        }
                        Err(e) => self.fallback(Outcome::Failed(e)),
                    }
                }
                Err(e) => self.fallback(Outcome::Failed(e)),
            };
        }
        let delta = match (self.matcher.params().prior, odom_delta) {
            (Prior::Odometry, Some(d)) => d,
            _ => self.velocity,
        };
        let guess = self.pose * delta;
        if let Err(e) = prepared {
            return self.predict(guess, Outcome::Failed(e));
        }
        let result = self.matcher.match_prepared(self.map.reference(), &guess);
        let m = match result {
            Ok(m) => m,
            Err(e) => return self.predict(guess, Outcome::Failed(e)),
        };
        if let Err(r) = m.quality.check(self.matcher.params()) {
            return self.predict(guess, Outcome::Rejected(r, m.quality));
        }
        self.velocity = self.pose.inverse() * m.pose;
        self.pose = m.pose;
        let keyframe = self.maybe_keyframe();
        Step {
            pose: self.pose,
            outcome: Outcome::Matched(m.quality),
            keyframe,
        }
    }

    fn predict(&mut self, guess: Pose, outcome: Outcome) -> Step {
        self.velocity = self.pose.inverse() * guess;
        self.pose = guess;
        Step {
            pose: guess,
            outcome,
            keyframe: false,
        }
    }

    fn fallback(&self, outcome: Outcome) -> Step {
        Step {
            pose: self.pose,
            outcome,
            keyframe: false,
        }
    }

    fn maybe_keyframe(&mut self) -> bool {
        let params = self.matcher.params();
        let due = match self.map.last_pose() {
            None => true,
            Some(k) => {
                let d = k.inverse() * self.pose;
                d.translation.vector.norm() >= params.keyframe_distance
                    || d.rotation.angle().abs() >= params.keyframe_angle
            }
        };
        if !due {
            return false;
        }
        let params = params.clone();
        self.map
            .insert(&self.pose, self.matcher.prepared_points(), &params)
            .is_ok()
    }
}
