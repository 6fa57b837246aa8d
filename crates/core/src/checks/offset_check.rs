//! Does the scanner sit where `[robot]` says? Turning in place, a
//! differential drive's axle centre stays put and the scanner circles it at
//! its mounting offset. A `robot.scanner_offset_x`/`_y` configured wrong by
//! e makes the localised robot position swing on a circle of radius |e| as
//! the robot turns: lanes laid centimetres off, inside the planner's 1 cm
//! safety margin. Over the first `CHECK_TURN` of turning in place (the
//! look-around at the start) the scanner positions the matcher found are
//! fitted, by linear least squares, to a fixed centre plus the offset
//! turned with the robot's heading. The localise stage takes an offset off
//! by more than [`OFFSET_TOLERANCE`] into the mount (`daemon.fit_scanner_mount`)
//! or stops the daemon where it is too far off to be a measuring error.
//! Pure: fed one localised scan at a time.

use nalgebra::{Matrix2, Vector2};

use crate::geom::{heading, Pose};

/// Turning in place (rad) over which the fit is made.
pub(crate) const CHECK_TURN: f64 = std::f64::consts::PI;

/// An offset error (m) up to this is within the fit's noise: the mount
/// stands (correctly configured runs fitted 0-4 mm off).
pub const OFFSET_TOLERANCE: f64 = 0.015;

/// With `daemon.fit_scanner_mount` off, an offset error (m) above this stops
/// the daemon (the lanes would be laid that far off, three safety margins).
pub const OFFSET_STOP_UNFITTED: f64 = 0.03;

/// An offset error (m) above this stops the daemon even when it may fit
/// the mount: no measuring error but a wrong value (a sign, centimetres
/// given as metres).
pub const OFFSET_FIT_MAX: f64 = 0.15;

/// Largest wheel travel (m) between two scans for the robot to count as
/// turning in place (or standing).
const IN_PLACE: f64 = 0.003;

/// The fit, once made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffsetFit {
    /// The scanner's offset from the axle centre (m, robot frame: ahead,
    /// left) that the turns fit, under the yaw configured when fitted.
    pub offset: Vector2<f64>,
    /// Turning in place the fit is made over (rad).
    pub turned: f64,
}

/// Sums of one stretch of turning in place about one centre: the scanner
/// positions `p` and the rotations `R` of the robot's heading.
#[derive(Default)]
struct Station {
    n: f64,
    sum_r: Matrix2<f64>,
    sum_p: Vector2<f64>,
    sum_rtp: Vector2<f64>,
}

/// The running fit (see the module docs).
pub struct OffsetCheck {
    /// Configured yaw of the scanner (rad): the robot's heading is the
    /// scanner's minus this.
    yaw: f64,
    station: Station,
    /// Normal equations of all closed stations, each with its own centre
    /// eliminated: `a * offset = b`.
    a: Matrix2<f64>,
    b: Vector2<f64>,
    turned: f64,
    prev: Option<Pose>,
    done: bool,
}

impl OffsetCheck {
    /// A check for a scanner mounted at yaw `yaw` (rad).
    pub fn new(yaw: f64) -> Self {
        Self {
            yaw,
            station: Station::default(),
            a: Matrix2::zeros(),
            b: Vector2::zeros(),
            turned: 0.0,
            prev: None,
            done: false,
        }
    }

    /// Adds one scan: the scanner pose the matcher found (`None` when the
    /// scan was not matched, which ends the stretch) and the robot's wheel
    /// odometry pose at it. Returns the fit once, after `CHECK_TURN`.
    pub fn step(&mut self, scanner: Option<&Pose>, odom: &Pose) -> Option<OffsetFit> {
        if self.done {
            return None;
        }
        let Some(s) = scanner else {
            self.close_station();
            self.prev = None;
            return None;
        };
        if let Some(o0) = self.prev.replace(*odom) {
            let d = o0.inverse() * odom;
            if d.translation.vector.norm() > IN_PLACE {
                // The robot drove: a new centre from this scan on.
                self.close_station();
            } else {
                self.turned += heading(&d).abs();
            }
        }
        let r = *nalgebra::Rotation2::new(heading(s) - self.yaw).matrix();
        let p = s.translation.vector;
        let st = &mut self.station;
        st.n += 1.0;
        st.sum_r += r;
        st.sum_p += p;
        st.sum_rtp += r.transpose() * p;
        if self.turned < CHECK_TURN {
            return None;
        }
        self.close_station();
        let offset = self.a.try_inverse()? * self.b;
        self.done = true;
        Some(OffsetFit {
            offset,
            turned: self.turned,
        })
    }

    /// Folds the current stretch into the normal equations, its centre
    /// eliminated: minimising Σ|p − c − R t|² over c leaves
    /// (nI − ΣRᵀΣR/n) t = ΣRᵀp − ΣRᵀΣp/n.
    fn close_station(&mut self) {
        let st = std::mem::take(&mut self.station);
        if st.n < 2.0 {
            return;
        }
        self.a += Matrix2::identity() * st.n - st.sum_r.transpose() * st.sum_r / st.n;
        self.b += st.sum_rtp - st.sum_r.transpose() * st.sum_p / st.n;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    /// Turns the robot in place at `centre` by `step` rad a scan for `n`
    /// scans, its scanner at `mount`; returns the fit, if any.
    fn turn_at(
        check: &mut OffsetCheck,
        centre: Pose,
        mount: Pose,
        step: f64,
        n: usize,
    ) -> Option<OffsetFit> {
        let mut fit = None;
        for k in 0..n {
            let robot = centre * pose(0.0, 0.0, step * k as f64);
            let odom = pose(0.3, -0.2, 1.0) * pose(0.0, 0.0, step * k as f64);
            if let Some(f) = check.step(Some(&(robot * mount)), &odom) {
                assert!(fit.is_none(), "fitted twice");
                fit = Some(f);
            }
        }
        fit
    }

    #[test]
    fn turning_in_place_fits_the_scanners_offset() {
        for (x, y, yaw) in [(0.0, 0.0, 0.0), (0.08, -0.04, 0.35), (-0.12, 0.05, -2.0)] {
            let mount = pose(x, y, yaw);
            let mut c = OffsetCheck::new(yaw);
            let f = turn_at(&mut c, pose(2.0, 1.0, 0.4), mount, 0.06, 80).expect("no fit");
            assert!((f.offset - Vector2::new(x, y)).norm() < 1e-9, "{f:?}");
            assert!(
                f.turned >= CHECK_TURN && f.turned < CHECK_TURN + 0.07,
                "{f:?}"
            );
        }
    }

    #[test]
    fn turns_at_several_places_add_up_and_driving_is_left_out() {
        let mount = pose(0.1, 0.03, 0.0);
        let mut c = OffsetCheck::new(0.0);
        // Two quarter turns at two places, a straight drive between.
        assert_eq!(turn_at(&mut c, pose(0.0, 0.0, 0.0), mount, 0.05, 32), None);
        let mut odom = pose(0.0, 0.0, 0.0);
        for k in 0..20 {
            odom *= pose(0.05, 0.0, 0.0);
            let robot = pose(0.05 * k as f64, 0.5, 0.0);
            assert_eq!(c.step(Some(&(robot * mount)), &odom), None);
        }
        let f = turn_at(&mut c, pose(3.0, -1.0, 1.0), mount, -0.05, 40).expect("no fit");
        assert!((f.offset - Vector2::new(0.1, 0.03)).norm() < 1e-9, "{f:?}");
    }

    #[test]
    fn a_yaw_off_turns_the_fitted_offset_by_as_much() {
        // Configured yaw 0, true 0.1 rad: the robot's heading is read 0.1
        // rad too high, and the offset comes out turned by -0.1 rad.
        let mount = pose(0.1, 0.0, 0.1);
        let mut c = OffsetCheck::new(0.0);
        let f = turn_at(&mut c, pose(1.0, 1.0, 0.0), mount, 0.05, 70).expect("no fit");
        let want = nalgebra::Rotation2::new(-0.1) * Vector2::new(0.1, 0.0);
        assert!((f.offset - want).norm() < 1e-9, "{f:?}");
    }

    #[test]
    fn unmatched_scans_and_standing_still_give_no_fit() {
        let mut c = OffsetCheck::new(0.0);
        let mount = pose(0.1, 0.0, 0.0);
        // Standing: no turn.
        for _ in 0..200 {
            assert_eq!(c.step(Some(&mount), &pose(0.0, 0.0, 0.0)), None);
        }
        // Every other scan unmatched while turning: no stretch of two.
        for k in 0..200 {
            let odom = pose(0.0, 0.0, 0.05 * k as f64);
            let s = (k % 2 == 0).then(|| odom * mount);
            assert_eq!(c.step(s.as_ref(), &odom), None);
        }
        assert_eq!(c.turned, 0.0);
    }
}
