//! Bumper contacts: where an obstacle the scanner did not see must be, from
//! what the bumper proves and nothing more.
//!
//! A closed bumper proves that something touches the front half of the body
//! shell. The switches say which side (a Create 2 has two; a RoboClaw base
//! wires its bumper to one E-stop input, so both sides read closed), and the
//! motion at the time narrows it further: a robot turning in place can only
//! close its bumper with the shell's leading end. The contact is marked as a
//! short arc (a few centimetres) of the shell at that bearing, just outside
//! the body: small enough not to wall off floor beside the obstacle, and
//! repeated contacts with the same obstacle add further arcs until the
//! planner's path no longer touches it.

use nalgebra::{Point2, Vector2};

use crate::geom::{heading, Pose};
use crate::motor::{Sides, WheelSpeeds};

/// Bearing of a contact on one side only (rad from straight ahead): the
/// middle of that side's half of the front shell.
pub const SIDE_BEARING: f64 = 0.7;
/// Bearing of a contact closed by turning in place (rad): the leading end of
/// the front shell (the bumper covers ±80°).
pub const TURN_BEARING: f64 = 1.3;
/// Distance of the contact outside the body (m): half the bumper's travel.
pub const CONTACT_GAP: f64 = 0.01;
/// Half length of the marked arc (m).
pub const ARC_HALF_LENGTH: f64 = 0.02;
/// A contact closer than this to an earlier one is the same contact (m).
pub const SAME_CONTACT: f64 = 0.03;

/// One bumper contact: the robot centre at the time and the contact point
/// on the shell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactMark {
    /// Robot centre when the bumper closed (map frame, m).
    pub centre: Point2<f64>,
    /// The contact point (map frame, m).
    pub at: Point2<f64>,
}

impl ContactMark {
    /// The contact of a bumper closing on `sides` with the robot of radius
    /// `radius` at `pose`, commanded to `wheels` (wheel base `wheel_base`).
    pub fn estimate(
        pose: &Pose,
        sides: Sides,
        wheels: WheelSpeeds,
        radius: f64,
        wheel_base: f64,
    ) -> Self {
        let v = 0.5 * (wheels.left + wheels.right);
        let w = if wheel_base > 0.0 {
            (wheels.right - wheels.left) / wheel_base
        } else {
            0.0
        };
        // Turning in place: the shell's leading end sweeps new space.
        let turning = w.is_finite() && v.is_finite() && w.abs() * radius > 2.0 * v.abs();
        let bearing = match (sides.left, sides.right) {
            (true, false) => SIDE_BEARING,
            (false, true) => -SIDE_BEARING,
            _ if turning => TURN_BEARING * w.signum(),
            _ => 0.0,
        };
        let a = heading(pose) + bearing;
        let centre: Point2<f64> = pose.translation.vector.into();
        let at = centre + Vector2::new(a.cos(), a.sin()) * (radius + CONTACT_GAP);
        Self { centre, at }
    }

    /// Whether `other` is the same contact as this one.
    pub fn same_as(&self, other: &ContactMark) -> bool {
        (self.at - other.at).norm() <= SAME_CONTACT
    }

    /// Points along the marked arc, at most `step` apart (ends included).
    pub fn arc(&self, step: f64) -> impl Iterator<Item = Point2<f64>> + '_ {
        let d = self.at - self.centre;
        let r = d.norm().max(1e-6);
        let a0 = d.y.atan2(d.x);
        let half = ARC_HALF_LENGTH / r;
        let n = ((2.0 * ARC_HALF_LENGTH / step.max(1e-3)).ceil() as usize).max(1);
        (0..=n).map(move |k| {
            let a = a0 - half + 2.0 * half * k as f64 / n as f64;
            self.centre + Vector2::new(a.cos(), a.sin()) * r
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    const R: f64 = 0.17;
    const B: f64 = 0.235;

    fn both() -> Sides {
        Sides {
            left: true,
            right: true,
        }
    }

    #[test]
    fn a_head_on_contact_is_straight_ahead_just_outside_the_body() {
        let m = ContactMark::estimate(
            &pose(1.0, 2.0, std::f64::consts::FRAC_PI_2),
            both(),
            WheelSpeeds::from_body(0.2, 0.0, B),
            R,
            B,
        );
        assert!((m.at.x - 1.0).abs() < 1e-9, "{:?}", m.at);
        assert!(
            (m.at.y - (2.0 + R + CONTACT_GAP)).abs() < 1e-9,
            "{:?}",
            m.at
        );
    }

    #[test]
    fn one_side_or_a_turn_moves_the_contact_to_that_side() {
        let p = pose(0.0, 0.0, 0.0);
        let fwd = WheelSpeeds::from_body(0.2, 0.0, B);
        let left = ContactMark::estimate(
            &p,
            Sides {
                left: true,
                right: false,
            },
            fwd,
            R,
            B,
        );
        assert!(left.at.y > 0.05 && left.at.x > 0.05, "{:?}", left.at);
        let right = ContactMark::estimate(
            &p,
            Sides {
                left: false,
                right: true,
            },
            fwd,
            R,
            B,
        );
        assert!(right.at.y < -0.05, "{:?}", right.at);
        // A RoboClaw E-stop (both sides) while turning right in place.
        let turn = ContactMark::estimate(&p, both(), WheelSpeeds::from_body(0.0, -1.0, B), R, B);
        assert!(turn.at.y < -0.15, "{:?}", turn.at);
    }

    #[test]
    fn the_arc_is_a_few_centimetres_of_the_shell() {
        let m = ContactMark::estimate(&pose(0.0, 0.0, 0.3), both(), WheelSpeeds::STOP, R, B);
        let pts: Vec<_> = m.arc(0.01).collect();
        assert!(pts.len() >= 4);
        for q in &pts {
            assert!(((q - m.centre).norm() - (R + CONTACT_GAP)).abs() < 1e-9);
            assert!((q - m.at).norm() <= ARC_HALF_LENGTH + 1e-9);
        }
        let ends = (pts[0] - pts[pts.len() - 1]).norm();
        assert!(ends > 1.5 * ARC_HALF_LENGTH, "{ends}");
        assert!(m.same_as(&m));
    }
}
