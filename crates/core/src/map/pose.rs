//! The paper's pose update (its equation 3): the matcher's increment, given in
//! the robot frame of the previous pose, composed onto that pose.

use crate::geom::{wrap_angle, Pose};

/// Pose after a scan: `prev` moved by `increment` (ΔX, ΔY in the frame of
/// `prev`, Δθ). Equation 3 of the paper written out:
/// X_k = X_{k-1} + cos θ·ΔX − sin θ·ΔY, Y_k = Y_{k-1} + sin θ·ΔX + cos θ·ΔY,
/// θ_k = θ_{k-1} + Δθ; that is exactly the isometry product `prev * increment`.
pub fn compose_increment(prev: &Pose, increment: &Pose) -> Pose {
    prev * increment
}

/// The increment that takes `from` to `to` (the inverse of
/// [`compose_increment`]): `from⁻¹ · to`, in the frame of `from`.
pub fn increment_between(from: &Pose, to: &Pose) -> Pose {
    from.inverse() * to
}

/// True when every component of the pose is a finite number.
pub(crate) fn pose_is_finite(p: &Pose) -> bool {
    p.translation.vector.iter().all(|v| v.is_finite())
        && p.rotation.re.is_finite()
        && p.rotation.im.is_finite()
}

/// Translation length and absolute rotation (wrapped) of a pose taken as a motion.
pub(crate) fn motion_size(p: &Pose) -> (f64, f64) {
    (
        p.translation.vector.norm(),
        wrap_angle(p.rotation.angle()).abs(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{heading, pose};

    #[test]
    fn matches_equation_3_written_out() {
        let prev = pose(1.0, -2.0, 0.7);
        let (dx, dy, dth) = (0.3, -0.1, 0.05);
        let k = compose_increment(&prev, &pose(dx, dy, dth));
        let th = 0.7f64;
        let x = 1.0 + th.cos() * dx - th.sin() * dy;
        let y = -2.0 + th.sin() * dx + th.cos() * dy;
        assert!((k.translation.x - x).abs() < 1e-12);
        assert!((k.translation.y - y).abs() < 1e-12);
        assert!((heading(&k) - (th + dth)).abs() < 1e-12);
    }

    #[test]
    fn increment_round_trips() {
        let a = pose(0.5, 0.2, -2.9);
        let b = pose(-1.0, 3.0, 2.8);
        let inc = increment_between(&a, &b);
        let b2 = compose_increment(&a, &inc);
        assert!((b2.translation.vector - b.translation.vector).norm() < 1e-12);
        assert!(wrap_angle(heading(&b2) - heading(&b)).abs() < 1e-12);
        assert!((motion_size(&inc).1 - wrap_angle(2.8 + 2.9).abs()).abs() < 1e-12);
    }

    #[test]
    fn non_finite_pose_is_detected() {
        assert!(pose_is_finite(&pose(1.0, 2.0, 3.0)));
        assert!(!pose_is_finite(&pose(f64::NAN, 2.0, 3.0)));
        assert!(!pose_is_finite(&pose(1.0, 2.0, f64::INFINITY)));
    }
}
