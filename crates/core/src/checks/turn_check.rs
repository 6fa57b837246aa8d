//! Do the scans turn with the wheels? A scanner mounted upside down but
//! configured upright in `[robot]` (or the reverse) sees the room turn the
//! wrong way as the robot turns. Over the first quarter turn the wheels
//! report (the look-around at the start turns in place), the turn of the
//! dominant wall axes from scan to scan ([`super::align`], independent of
//! the scan matcher, which fails often on mirrored scans) is compared with
//! the wheels'; the localise stage stops the daemon when the ratio is far
//! from one. A wrong `scanner_yaw` does not change turns and is not caught
//! here. Pure: fed one scan at a time.

use super::align::{turn_to_axes, WallAlign, MIN_AGREEMENT, MIN_WALL_EVIDENCE};
use crate::geom::{heading, wrap_angle, IPoint, Pose};

/// Wheel turn (rad) over which the check is made.
pub(crate) const CHECK_TURN: f64 = std::f64::consts::FRAC_PI_2;

/// The scans' turn over the wheels' must lie within these bounds.
pub(crate) const AGREE: (f64, f64) = (0.5, 1.5);

/// A ratio that agrees but lies outside these bounds is logged as a
/// warning naming the wheel base it fits (the wheels' turn is the wheel
/// speeds' difference over `robot.wheel_base`: a base configured 10 % too
/// short makes the wheels report 10 % more turn than the scans see).
pub const SCALE_WARN: (f64, f64) = (0.9, 1.1);

/// The wheel base (m) a ratio of the scans' turn over the wheels' fits,
/// given the configured one.
pub fn fitting_wheel_base(ratio: f64, configured: f64) -> f64 {
    configured / ratio
}

/// Scans after which an undecided check stops looking (no quarter turn
/// with walls in view: nothing to compare, and no cost from then on).
pub(crate) const MAX_SCANS: u32 = 600;

/// Largest wheel turn (rad) between two scans that is compared: the wall
/// axes repeat every 90°, so larger steps could alias.
const MAX_STEP: f64 = 0.5;

/// What the check says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TurnVerdict {
    /// Not enough turn seen yet.
    Undecided,
    /// Scans and wheels agree (ratio within `AGREE`).
    Agree {
        /// The scans' turn over the wheels'.
        ratio: f64,
    },
    /// They disagree: the scans turned `scans` rad while the wheels turned
    /// `wheels`.
    Disagree {
        /// Turn of the scans' walls (rad).
        scans: f64,
        /// Turn of the wheel odometry over the same scans (rad).
        wheels: f64,
    },
}

/// The running comparison (see the module docs).
#[derive(Default)]
pub struct TurnCheck {
    walls: WallAlign,
    prev: Option<(Pose, f64)>,
    wheels: f64,
    scans: f64,
    seen: u32,
    done: bool,
}

impl TurnCheck {
    /// Adds one scan (its points in the scanner frame) with the wheel
    /// odometry pose at it. Returns a verdict once, then `Undecided`.
    pub fn step(&mut self, points: &[IPoint], odom: &Pose) -> TurnVerdict {
        if self.done {
            return TurnVerdict::Undecided;
        }
        self.seen += 1;
        if self.seen > MAX_SCANS {
            self.done = true;
            return TurnVerdict::Undecided;
        }
        let axis = match self.walls.wall_axis(points) {
            Some((a, share)) if a.evidence >= MIN_WALL_EVIDENCE && share >= MIN_AGREEMENT => {
                a.angle
            }
            // Too few walls in this scan: the chain breaks here.
            _ => {
                self.prev = None;
                return TurnVerdict::Undecided;
            }
        };
        self.step_axis(axis, odom)
    }

    /// [`TurnCheck::step`] with the scan's wall axis (rad, scanner frame,
    /// modulo 90°) already found.
    pub(crate) fn step_axis(&mut self, axis: f64, odom: &Pose) -> TurnVerdict {
        if self.done {
            return TurnVerdict::Undecided;
        }
        if let Some((o0, a0)) = self.prev {
            let dw = wrap_angle(heading(odom) - heading(&o0));
            if dw.abs() <= MAX_STEP {
                self.wheels += dw;
                // The robot turning left turns its walls right in the
                // scanner's frame by as much: the least turn that maps the
                // new axis back onto the old one.
                self.scans += turn_to_axes(axis - a0);
            }
        }
        self.prev = Some((*odom, axis));
        if self.wheels.abs() < CHECK_TURN {
            return TurnVerdict::Undecided;
        }
        self.done = true;
        let ratio = self.scans / self.wheels;
        if (AGREE.0..=AGREE.1).contains(&ratio) {
            TurnVerdict::Agree { ratio }
        } else {
            TurnVerdict::Disagree {
                scans: self.scans,
                wheels: self.wheels,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;
    use crate::icp::synth::{cast, room, ScanSpec};

    /// Turns at `rate` rad per scan for `n` scans; the walls seen turn at
    /// `-rate * seen` (1 = a correct mount, -1 = mirrored).
    fn turn(check: &mut TurnCheck, rate: f64, seen: f64, n: usize) -> TurnVerdict {
        let mut last = TurnVerdict::Undecided;
        for k in 0..n {
            let a = rate * k as f64;
            let axis = turn_to_axes(-(0.2 - seen * a));
            let v = check.step_axis(axis, &pose(0.0, 0.0, a));
            if v != TurnVerdict::Undecided {
                last = v;
            }
        }
        last
    }

    #[test]
    fn a_wheel_base_configured_short_shows_as_scans_turning_less() {
        // True base 0.25 m, configured 0.22: the wheels report 0.25/0.22
        // of the true turn, the walls turn by the true amount.
        let ratio = 0.22 / 0.25;
        match turn(&mut TurnCheck::default(), 0.05 / ratio, ratio, 40) {
            TurnVerdict::Agree { ratio: r } => {
                assert!((r - ratio).abs() < 1e-9, "{r}");
                assert!((fitting_wheel_base(r, 0.22) - 0.25).abs() < 1e-9);
                assert!(!(SCALE_WARN.0..=SCALE_WARN.1).contains(&r));
            }
            v => panic!("{v:?}"),
        }
    }

    #[test]
    fn walls_turning_with_the_wheels_agree_and_against_them_do_not() {
        // 0.05 rad a scan for 40 scans: past a quarter turn, the axes
        // wrapping every 90° and the heading at ±π.
        match turn(&mut TurnCheck::default(), 0.05, 1.0, 40) {
            TurnVerdict::Agree { ratio } => assert!((ratio - 1.0).abs() < 1e-9, "{ratio}"),
            v => panic!("{v:?}"),
        }
        match turn(&mut TurnCheck::default(), -0.05, -1.0, 40) {
            TurnVerdict::Disagree { scans, wheels } => assert!(scans > 1.5 && wheels < -1.5),
            v => panic!("{v:?}"),
        }
        assert_eq!(
            turn(&mut TurnCheck::default(), 0.005, 1.0, 40),
            TurnVerdict::Undecided
        );
        // Steps too large to compare are left out.
        assert_eq!(
            turn(&mut TurnCheck::default(), 0.6, -1.0, 40),
            TurnVerdict::Undecided
        );
    }

    #[test]
    fn real_scans_of_a_turning_robot_agree_and_mirrored_ones_do_not() {
        let walls = room(6.5, 4.1, 0.5);
        let mut right = TurnCheck::default();
        let mut mirrored = TurnCheck::default();
        let (mut r, mut m) = (TurnVerdict::Undecided, TurnVerdict::Undecided);
        for k in 0..40 {
            let a = 0.3 + 0.06 * k as f64;
            let pts = cast(&walls, &pose(2.0, 1.5, a), &ScanSpec::default());
            let flipped: Vec<IPoint> = pts
                .iter()
                .rev()
                .map(|p| IPoint::new(p.x, -p.y, p.intensity))
                .collect();
            let odom = pose(0.0, 0.0, a);
            if let v @ (TurnVerdict::Agree { .. } | TurnVerdict::Disagree { .. }) =
                right.step(&pts, &odom)
            {
                r = v;
            }
            if let v @ (TurnVerdict::Agree { .. } | TurnVerdict::Disagree { .. }) =
                mirrored.step(&flipped, &odom)
            {
                m = v;
            }
        }
        assert!(
            matches!(r, TurnVerdict::Agree { ratio } if (ratio - 1.0).abs() < 0.05),
            "{r:?}"
        );
        assert!(
            matches!(m, TurnVerdict::Disagree { scans, .. } if scans < -1.4),
            "{m:?}"
        );
        // No walls: no verdict.
        let mut none = TurnCheck::default();
        for k in 0..40 {
            assert_eq!(
                none.step(&[], &pose(0.0, 0.0, 0.06 * k as f64)),
                TurnVerdict::Undecided
            );
        }
    }
}
