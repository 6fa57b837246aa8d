//! Do the scans turn with the wheels? A scanner mounted upside down but
//! configured upright in `[robot]` (or the reverse) makes the scan matcher
//! see the robot turn the other way than the wheels say. The first quarter
//! turn the wheels report (the look-around at the start turns in place) is
//! compared with the turn the matched scans add up to over the same scans;
//! the localise stage stops the daemon when the ratio is far from one. A
//! wrong `scanner_yaw` does not change turns and is not caught here. Pure:
//! fed one localised scan at a time.

use crate::geom::{heading, wrap_angle, Pose};

/// Wheel turn (rad) over which the check is made.
pub const CHECK_TURN: f64 = std::f64::consts::FRAC_PI_2;

/// The scans' turn over the wheels' must lie within these bounds.
pub const AGREE: (f64, f64) = (0.5, 1.5);

/// What the check says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TurnVerdict {
    /// Not enough turn seen yet.
    Undecided,
    /// Scans and wheels agree (ratio within [`AGREE`]).
    Agree {
        /// The scans' turn over the wheels'.
        ratio: f64,
    },
    /// They disagree: `scans` rad matched while the wheels turned `wheels`.
    Disagree {
        /// Turn of the matched scans (rad).
        scans: f64,
        /// Turn of the wheel odometry over the same scans (rad).
        wheels: f64,
    },
}

/// The running comparison (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct TurnCheck {
    prev: Option<(Pose, Pose)>,
    wheels: f64,
    scans: f64,
    done: bool,
}

impl TurnCheck {
    /// Adds one scan: the wheel odometry pose and the matched pose at it
    /// (`matched` false when the matcher fell back to the odometry, which
    /// breaks the chain). Returns a verdict once, then `Undecided` for ever.
    pub fn step(&mut self, odom: &Pose, pose: &Pose, matched: bool) -> TurnVerdict {
        if self.done {
            return TurnVerdict::Undecided;
        }
        if !matched {
            self.prev = None;
            return TurnVerdict::Undecided;
        }
        if let Some((o0, p0)) = self.prev {
            self.wheels += wrap_angle(heading(odom) - heading(&o0));
            self.scans += wrap_angle(heading(pose) - heading(&p0));
        }
        self.prev = Some((*odom, *pose));
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

    fn turn(check: &mut TurnCheck, wheel_rate: f64, scan_rate: f64, n: usize) -> TurnVerdict {
        let mut last = TurnVerdict::Undecided;
        for k in 0..n {
            let t = k as f64 * 0.1;
            let v = check.step(
                &pose(0.0, 0.0, wheel_rate * t),
                &pose(1.0, 2.0, 0.3 + scan_rate * t),
                true,
            );
            if v != TurnVerdict::Undecided {
                last = v;
            }
        }
        last
    }

    #[test]
    fn scans_turning_with_the_wheels_agree_and_against_them_do_not() {
        // 0.5 rad/s for 4 s: past a quarter turn, across the ±π wrap.
        match turn(&mut TurnCheck::default(), 0.5, 0.48, 80) {
            TurnVerdict::Agree { ratio } => assert!((ratio - 0.96).abs() < 1e-9, "{ratio}"),
            v => panic!("{v:?}"),
        }
        match turn(&mut TurnCheck::default(), -0.5, 0.5, 80) {
            TurnVerdict::Disagree { scans, wheels } => assert!(scans > 1.5 && wheels < -1.5),
            v => panic!("{v:?}"),
        }
        // Scans that hardly turn (a yaw set far off makes the matcher hold on).
        assert!(matches!(
            turn(&mut TurnCheck::default(), 0.5, 0.1, 80),
            TurnVerdict::Disagree { .. }
        ));
        // Too little turn: no verdict.
        assert_eq!(
            turn(&mut TurnCheck::default(), 0.05, 0.05, 20),
            TurnVerdict::Undecided
        );
    }

    #[test]
    fn unmatched_scans_break_the_chain_and_a_verdict_comes_once() {
        let mut c = TurnCheck::default();
        for k in 0..40 {
            let a = k as f64 * 0.05;
            // Every other scan unmatched: its turn is not counted.
            let v = c.step(&pose(0.0, 0.0, a), &pose(0.0, 0.0, a), k % 2 == 0);
            assert_eq!(v, TurnVerdict::Undecided, "scan {k}");
        }
        let mut d = TurnCheck::default();
        let verdicts = (0..100)
            .map(|k| {
                let a = k as f64 * 0.05;
                d.step(&pose(0.0, 0.0, a), &pose(0.0, 0.0, a), true)
            })
            .filter(|v| *v != TurnVerdict::Undecided)
            .count();
        assert_eq!(verdicts, 1);
    }
}
