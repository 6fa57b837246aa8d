//! The matcher's covariance against the spread it claims to describe: many
//! matches of one scene, each with fresh range noise, give an empirical
//! covariance of the pose error; the reported covariance should agree.
//!
//! The consistency test is the normalised estimation error squared (NEES):
//! for a consistent estimate, eᵀ P⁻¹ e averages the number of dimensions
//! (3 for x, y, θ). Much more means the covariance is overconfident (a
//! fusion trusting it would over-weight the match), much less that it is
//! too cautious.

use nalgebra::{Matrix3, Vector3};
use sweepline::geom::{pose, IPoint, Pose};
use sweepline::icp::synth::{cast, l_room_with_pillar, wall_points, ScanSpec, Wall};
use sweepline::icp::{IcpParams, Matcher, Reference};

/// A corridor 2 m wide with a doorway recess 1 m wide and 0.6 m deep:
/// along it only the recess's two short faces pin the position, so the
/// along-corridor variance is large and the across one small.
fn corridor() -> Vec<Wall> {
    vec![
        Wall::new(-8.0, -1.0, 8.0, -1.0, 0.5),
        Wall::new(-8.0, 1.0, 0.0, 1.0, 0.5),
        Wall::new(0.0, 1.0, 0.0, 1.6, 0.5),
        Wall::new(0.0, 1.6, 1.0, 1.6, 0.5),
        Wall::new(1.0, 1.6, 1.0, 1.0, 0.5),
        Wall::new(1.0, 1.0, 8.0, 1.0, 0.5),
    ]
}

/// The pose error `truth⁻¹ · estimate` as (x, y, θ), in the truth's frame.
fn error(truth: &Pose, est: &Pose) -> Vector3<f64> {
    let d = truth.inverse() * est;
    Vector3::new(d.translation.x, d.translation.y, d.rotation.angle())
}

/// What `trials` matches of noisy scans against one reference give.
struct Spread {
    /// Mean NEES of the errors about their mean (3 when the covariance
    /// describes the spread).
    nees: f64,
    /// Empirical covariance of the errors about their mean.
    empirical: Matrix3<f64>,
    /// Mean reported covariance, in the truth's frame.
    reported: Matrix3<f64>,
    /// Mean error: the matcher's bias, which no covariance describes.
    bias: Vector3<f64>,
    /// Mean residual RMS the matches reported (m).
    residual: f64,
}

/// Matches `trials` scans of `walls` taken at `truth` (range noise σ =
/// `noise`, a fresh seed each) against `reference`, each from a guess off by
/// a few centimetres and a degree.
fn spread(walls: &[Wall], truth: &Pose, reference: &Reference, noise: f64, trials: u64) -> Spread {
    let mut m = Matcher::new(IcpParams::default()).unwrap();
    let mut errors = Vec::new();
    let mut covs = Vec::new();
    let mut residual = 0.0;
    // The covariance is of the pose in the world frame; the error is taken in
    // the truth's frame, so rotate it there.
    let r = truth.rotation.to_rotation_matrix();
    let mut rot = Matrix3::identity();
    rot.fixed_view_mut::<2, 2>(0, 0).copy_from(r.matrix());
    let off = [
        (0.03, -0.02, 0.015),
        (-0.02, 0.03, -0.01),
        (0.01, 0.01, 0.02),
    ];
    for k in 0..trials {
        let spec = ScanSpec {
            range_noise: noise,
            seed: 1000 + k,
            ..ScanSpec::default()
        };
        let scan: Vec<IPoint> = cast(walls, truth, &spec);
        let (dx, dy, dt) = off[(k % 3) as usize];
        let guess = truth * pose(dx, dy, dt);
        let res = m.match_points(reference, &scan, &guess).unwrap();
        let cov = res.quality.covariance.expect("a constrained scene");
        covs.push(rot.transpose() * cov * rot);
        errors.push(error(truth, &res.pose));
        residual += res.quality.residual_rms;
    }
    let n = trials as f64;
    let bias = errors.iter().sum::<Vector3<f64>>() / n;
    let (mut nees, mut empirical) = (0.0, Matrix3::zeros());
    for (e, cov) in errors.iter().zip(&covs) {
        let d = e - bias;
        nees += (d.transpose() * cov.try_inverse().unwrap() * d)[(0, 0)];
        empirical += d * d.transpose();
    }
    Spread {
        nees: nees / n,
        empirical: empirical / n,
        reported: covs.iter().sum::<Matrix3<f64>>() / n,
        bias,
        residual: residual / n,
    }
}

/// A reference of the walls alone, dense and noise-free: the map the
/// matcher is meant to run against once it has settled.
fn wall_reference(walls: &[Wall]) -> Reference {
    let mut r = Reference::new();
    r.rebuild(&wall_points(walls, 0.01), &IcpParams::default())
        .unwrap();
    r
}

fn report(name: &str, s: &Spread) {
    let sd = |m: &Matrix3<f64>| {
        (
            m[(0, 0)].sqrt() * 1e3,
            m[(1, 1)].sqrt() * 1e3,
            m[(2, 2)].sqrt().to_degrees(),
        )
    };
    let (ex, ey, et) = sd(&s.empirical);
    let (rx, ry, rt) = sd(&s.reported);
    println!(
        "{name}: NEES {:.2} (3 when consistent); σ x / y / θ empirical {ex:.2} / {ey:.2} mm / {et:.3}°, reported {rx:.2} / {ry:.2} mm / {rt:.3}°; bias {:.2} / {:.2} mm / {:.3}°; residual RMS {:.2} mm",
        s.nees,
        s.bias.x * 1e3,
        s.bias.y * 1e3,
        s.bias.z.to_degrees(),
        s.residual * 1e3
    );
}

/// The covariance describes the spread about the mean: a mean NEES near 3
/// (at most twice it), and every axis's reported standard deviation within
/// a factor of two of the one seen. The bias is `max_bias` × the range
/// noise at most (the matcher's thinning of the scan causes it; see the
/// `docs/evaluation.md`).
fn assert_consistent(name: &str, s: &Spread, noise: f64, max_bias: f64) {
    report(name, s);
    let bias = s.bias.xy().norm();
    assert!(bias < max_bias * noise, "{name}: bias {:.2} mm", bias * 1e3);
    assert!(
        (1.5..6.0).contains(&s.nees),
        "{name}: NEES {:.2}: the covariance does not describe the spread",
        s.nees
    );
    for (k, axis) in ["x", "y", "θ"].iter().enumerate() {
        let ratio = (s.reported[(k, k)] / s.empirical[(k, k)]).sqrt();
        assert!(
            (0.5..2.0).contains(&ratio),
            "{name}: reported σ{axis} is {ratio:.2} of the spread's"
        );
    }
}

#[test]
fn the_covariance_matches_the_spread_against_a_wall_map() {
    let walls = l_room_with_pillar();
    let reference = wall_reference(&walls);
    for truth in [pose(2.0, 1.5, 0.3), pose(4.5, 1.0, 2.0)] {
        let s = spread(&walls, &truth, &reference, 0.01, 300);
        assert_consistent("room, 10 mm noise", &s, 0.01, 0.1);
    }
}

#[test]
fn the_covariance_follows_the_range_noise() {
    let walls = l_room_with_pillar();
    let reference = wall_reference(&walls);
    let truth = pose(2.0, 1.5, 0.3);
    let small = spread(&walls, &truth, &reference, 0.005, 200);
    let large = spread(&walls, &truth, &reference, 0.02, 200);
    assert_consistent("room, 5 mm noise", &small, 0.005, 0.1);
    assert_consistent("room, 20 mm noise", &large, 0.02, 0.1);
    // Four times the noise: sixteen times the variance, reported and seen.
    let ratio = large.reported.trace() / small.reported.trace();
    assert!(
        (10.0..25.0).contains(&ratio),
        "reported variance ×{ratio:.1}"
    );
}

#[test]
fn the_covariance_is_long_along_a_corridor() {
    let walls = corridor();
    let reference = wall_reference(&walls);
    let truth = pose(-0.5, 0.0, 0.0);
    let s = spread(&walls, &truth, &reference, 0.01, 300);
    assert_consistent("corridor with a recess, 10 mm noise", &s, 0.01, 0.5);
    // Along the corridor (x) far less pins the pose than across it (y).
    assert!(
        s.reported[(0, 0)] > 4.0 * s.reported[(1, 1)],
        "reported σx {:.2} mm, σy {:.2} mm",
        s.reported[(0, 0)].sqrt() * 1e3,
        s.reported[(1, 1)].sqrt() * 1e3
    );
}
