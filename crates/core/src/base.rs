//! The plain data a wheel base exchanges with the rest of the robot: wheel
//! set-points, odometry increments and which side a contact is on. The
//! drivers (`sweepline-io`) produce and take them; the algorithms (contact
//! marks, the mount checks) read them, so they live here, below both.

use crate::geom::Pose;

/// Left and right wheel surface velocities (m/s, forward positive).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WheelSpeeds {
    /// Left wheel (m/s).
    pub left: f64,
    /// Right wheel (m/s).
    pub right: f64,
}

impl WheelSpeeds {
    /// Both wheels at rest.
    pub const STOP: WheelSpeeds = WheelSpeeds {
        left: 0.0,
        right: 0.0,
    };

    /// Wheel speeds from body velocities: forward `v` (m/s) and turn rate `w`
    /// (rad/s, counter-clockwise) for wheels `wheel_base` metres apart.
    pub fn from_body(v: f64, w: f64, wheel_base: f64) -> Self {
        Self {
            left: v - w * wheel_base / 2.0,
            right: v + w * wheel_base / 2.0,
        }
    }

    /// Whether both speeds are finite numbers.
    pub fn is_finite(&self) -> bool {
        self.left.is_finite() && self.right.is_finite()
    }
}

/// One odometry increment from the wheel encoders: how the base moved between
/// two encoder readings, in the base frame of the earlier reading. This is the
/// ICP prior.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Odometry {
    /// Time of the earlier reading (s, daemon monotonic clock).
    pub t0: f64,
    /// Time of the later reading (s).
    pub t1: f64,
    /// Motion from the earlier to the later reading, in the earlier base frame.
    pub delta: Pose,
    /// Left wheel travel (m).
    pub left: f64,
    /// Right wheel travel (m).
    pub right: f64,
}

/// Which side of the robot a contact or drop is on: a bumper's or the
/// wheel drops' pair (the Create 2 driver fills it from its codec's own).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sides {
    /// Left side.
    pub left: bool,
    /// Right side.
    pub right: bool,
}

impl Sides {
    /// Whether either side is active.
    pub fn any(&self) -> bool {
        self.left || self.right
    }
}
