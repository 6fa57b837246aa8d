//! Do the scans move the way the wheels drive? A differential drive cannot
//! move sideways, so over straight driving the localised pose must advance
//! along the robot's own heading. A scanner whose `robot.scanner_yaw` is
//! configured wrong by δ makes every scan-matched step appear turned by δ
//! against the heading (the robot seems to crab), and the pose then steers
//! the robot with its heading off by δ. Over the first `CHECK_DISTANCE`
//! of straight wheel travel the pose steps are summed in the robot's frame;
//! the direction of the sum is the mount's yaw error, its length over the
//! wheels' distance the odometry's scale. Above [`YAW_TOLERANCE`] the
//! localise stage refits the mount (`daemon.fit_scanner_mount`) up to
//! [`YAW_FIT_MAX`]; with the fit off it warns up to [`YAW_STOP_UNFITTED`].
//! Beyond its limit it stops the daemon, naming the value that fits. The
//! turn of the scans ([`super::turn_check`]) does not show a yaw error;
//! this check does not show a mirrored scanner (its steps go forward too).
//! Pure: fed one localised scan at a time.

use nalgebra::Vector2;

use crate::geom::{heading, Pose};

/// Straight wheel travel (m) over which the check is made.
pub(crate) const CHECK_DISTANCE: f64 = 1.0;

/// A yaw error (rad) up to this is within the measurement's noise: the
/// mount stands (the check measured 0.0-0.3° on correctly configured runs).
pub const YAW_TOLERANCE: f64 = 1.0 * std::f64::consts::PI / 180.0;

/// With `daemon.fit_scanner_mount` off, a yaw error (rad) above this stops
/// the daemon (3° cost 1.2 points of coverage and 18 of overlap in the
/// bench room, the lanes followed with the body crabbing).
pub const YAW_STOP_UNFITTED: f64 = 3.0 * std::f64::consts::PI / 180.0;

/// A yaw error (rad) above this stops the daemon even when it may fit the
/// mount: no mounting tolerance, but a wrong value in the configuration
/// (a scanner facing sideways or back, degrees given as radians).
pub const YAW_FIT_MAX: f64 = 20.0 * std::f64::consts::PI / 180.0;

/// The scans' distance over the wheels' outside these bounds is logged as
/// a warning (wheel radius, wheel base, or slip).
pub const SCALE_WARN: (f64, f64) = (0.9, 1.1);

/// Largest wheel turn (rad) between two scans for a step to count as
/// straight: turning steps with a scanner off the axle move it sideways.
const STRAIGHT_TURN: f64 = 0.01;

/// Smallest wheel travel (m) between two scans that counts (standing still
/// adds only the matcher's jitter).
const MIN_STEP: f64 = 0.002;

/// The scans' travel against the wheels' over the checked distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TravelFit {
    /// Direction of the scans' travel in the robot frame (rad, left
    /// positive): the scanner yaw driven with minus the true one.
    pub angle: f64,
    /// The scans' distance over the wheels'.
    pub scale: f64,
    /// Wheel travel compared (m).
    pub driven: f64,
    /// The scanner yaw (rad) the robot drove with while measured.
    pub yaw: f64,
}

impl TravelFit {
    /// The `robot.scanner_yaw` (rad) the measurement fits.
    pub fn fitting_yaw(&self) -> f64 {
        crate::geom::wrap_angle(self.yaw - self.angle)
    }
}

/// The running comparison (see the module docs).
pub struct TravelCheck {
    yaw: f64,
    prev: Option<(Pose, Pose)>,
    sum: Vector2<f64>,
    driven: f64,
    done: bool,
}

impl TravelCheck {
    /// A check of a robot driving with its scanner's yaw at `yaw` (rad).
    pub fn new(yaw: f64) -> Self {
        Self {
            yaw,
            prev: None,
            sum: Vector2::zeros(),
            driven: 0.0,
            done: false,
        }
    }

    /// Adds one scan: the localised robot pose (`None` when the scan was
    /// not matched, which breaks the chain) and the wheel odometry pose at
    /// it. Returns the fit once, when `CHECK_DISTANCE` is reached.
    ///
    /// Odometry held at an older reading (none came after the scan) must
    /// come as `None` too: its step shows no wheel travel and is left out
    /// while the scans moved, and the next step's wheels carry the catch-up,
    /// so the scale reads low (4-10 % on a loaded machine).
    pub fn step(&mut self, estimate: Option<&Pose>, odom: &Pose) -> Option<TravelFit> {
        if self.done {
            return None;
        }
        let Some(est) = estimate else {
            self.prev = None;
            return None;
        };
        if let Some((e0, o0)) = self.prev.replace((*est, *odom)) {
            let wheels = o0.inverse() * odom;
            let scans = e0.inverse() * est;
            let ahead = wheels.translation.x;
            if heading(&wheels).abs() <= STRAIGHT_TURN && ahead.abs() >= MIN_STEP {
                // Backing up counts as driving forward the other way.
                self.sum += scans.translation.vector * ahead.signum();
                self.driven += ahead.abs();
            }
        }
        if self.driven < CHECK_DISTANCE {
            return None;
        }
        self.done = true;
        Some(TravelFit {
            angle: self.sum.y.atan2(self.sum.x),
            scale: self.sum.norm() / self.driven,
            driven: self.driven,
            yaw: self.yaw,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    /// Drives `n` steps of `step` m straight along heading `h` (turning by
    /// `turn` rad a step); the scans see each step turned by `yaw_error`
    /// and scaled by `scale`. `miss` scans are not matched.
    fn drive(
        check: &mut TravelCheck,
        yaw_error: f64,
        scale: f64,
        step: f64,
        turn: f64,
        n: usize,
        miss: impl Fn(usize) -> bool,
    ) -> Option<TravelFit> {
        let (mut odom, mut est) = (pose(1.0, 2.0, 0.3), pose(-4.0, 0.5, 1.2));
        let mut last = None;
        for k in 0..n {
            odom *= pose(step, 0.0, turn);
            let (s, c) = yaw_error.sin_cos();
            est *= pose(scale * step * c, scale * step * s, turn);
            let v = check.step((!miss(k)).then_some(&est), &odom);
            if v.is_some() {
                assert_eq!(last, None, "decided twice");
                last = v;
            }
        }
        last
    }

    #[test]
    fn scans_moving_along_the_heading_fit_the_configured_mount() {
        let v = drive(&mut TravelCheck::new(0.1), 0.0, 1.0, 0.02, 0.0, 80, |_| {
            false
        });
        let Some(fit) = v else { panic!("{v:?}") };
        assert!(
            fit.angle.abs() < 1e-9 && (fit.scale - 1.0).abs() < 1e-9,
            "{fit:?}"
        );
        assert!((fit.driven - CHECK_DISTANCE).abs() < 0.03, "{fit:?}");
        assert!((fit.fitting_yaw() - 0.1).abs() < 1e-9);
    }

    #[test]
    fn a_yaw_error_shows_as_travel_at_that_angle_and_names_the_yaw_that_fits() {
        for (err, back) in [(10f64, false), (-7.0, false), (90.0, false), (25.0, true)] {
            let step = if back { -0.02 } else { 0.02 };
            let e = err.to_radians();
            let v = drive(&mut TravelCheck::new(0.1), e, 0.95, step, 0.0, 80, |_| {
                false
            });
            let Some(fit) = v else { panic!("{err}: {v:?}") };
            assert!((fit.angle - e).abs() < 1e-9, "{err}: {fit:?}");
            assert!((fit.scale - 0.95).abs() < 1e-9, "{err}: {fit:?}");
            // Driven with 0.1 rad, the scans' travel at +e: the truth is 0.1 - e.
            assert!((fit.fitting_yaw() - (0.1 - e)).abs() < 1e-9);
        }
    }

    /// Every third scan's odometry held at the reading before: fed as is,
    /// the scale reads a third low; fed as unmatched, it stays true.
    #[test]
    fn held_odometry_fed_as_a_break_keeps_the_scale() {
        let run = |as_break: bool| {
            let mut c = TravelCheck::new(0.0);
            let mut fit = None;
            let mut held = pose(0.0, 0.0, 0.0);
            for k in 1..200 {
                let x = 0.02 * f64::from(k);
                let est = pose(1.1 * x, 0.0, 0.0);
                let stale = k % 3 == 0;
                if !stale {
                    held = pose(x, 0.0, 0.0);
                }
                let e = (!(stale && as_break)).then_some(&est);
                fit = fit.or(c.step(e, &held));
            }
            fit.expect("no fit").scale
        };
        assert!((run(true) - 1.1).abs() < 1e-9, "{}", run(true));
        assert!(run(false) < 1.0, "{}", run(false));
    }

    #[test]
    fn turning_standing_and_unmatched_steps_are_not_counted() {
        let mut c = TravelCheck::new(0.1);
        // Turning in place, and arcs: never straight.
        assert_eq!(drive(&mut c, 0.3, 1.0, 0.0, 0.05, 200, |_| false), None);
        assert_eq!(drive(&mut c, 0.3, 1.0, 0.02, 0.05, 200, |_| false), None);
        // Standing still.
        assert_eq!(drive(&mut c, 0.3, 1.0, 0.0, 0.0, 500, |_| false), None);
        // Every other scan unmatched: no pair of matched scans in a row.
        assert_eq!(
            drive(&mut c, 0.3, 1.0, 0.02, 0.0, 200, |k| k % 2 == 0),
            None
        );
        assert_eq!(c.driven, 0.0);
        // Every fourth unmatched: half the steps end a matched pair, so 1 m
        // takes 100 steps.
        let mut c = TravelCheck::new(0.1);
        let v = drive(&mut c, 0.2, 1.0, 0.02, 0.0, 120, |k| k % 4 == 0);
        assert!(
            matches!(v, Some(f) if (f.angle - 0.2).abs() < 1e-9),
            "{v:?}"
        );
    }
}
