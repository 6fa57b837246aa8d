//! The matcher on synthetic scenes: convergence, exactness of w = 0 as plain
//! point-to-point ICP, quality report.

use sweepline::geom::{pose, IPoint, Pose};
use sweepline::icp::synth::{
    cast, cast_seeded, cast_world, l_room_with_pillar, wall_points, ScanSpec, Wall,
};
use sweepline::icp::{IcpParams, Matcher, Metric, Reference};

fn err(a: &Pose, b: &Pose) -> (f64, f64) {
    let d = a.inverse() * b;
    (d.translation.vector.norm(), d.rotation.angle().abs())
}

#[test]
fn converges_to_the_true_pose_with_both_metrics() {
    let walls = l_room_with_pillar();
    let truth = pose(2.0, 1.5, 0.3);
    let refpts = cast_world(&walls, &pose(2.2, 1.4, 0.2), 7);
    let scan = cast_seeded(&walls, &truth, 8);
    for metric in [Metric::PointToLine, Metric::PointToPoint] {
        // Point-to-point ICP converges linearly (slowly); give it room.
        let params = IcpParams {
            metric,
            min_point_spacing: 0.0,
            max_iterations: 200,
            ..IcpParams::default()
        };
        let mut reference = Reference::new();
        reference.rebuild(&refpts, &params).unwrap();
        let mut m = Matcher::new(params).unwrap();
        let guess = truth * pose(0.15, -0.1, 0.08);
        let r = m.match_points(&reference, &scan, &guess).unwrap();
        let (et, er) = err(&r.pose, &truth);
        assert!(
            et < 0.01 && er < 0.005,
            "{metric:?}: error {et} m {er} rad, {:?}",
            r.quality
        );
        assert!(r.quality.converged, "{metric:?}: {:?}", r.quality);
        assert!(!r.quality.degenerate);
        assert!(r.quality.inlier_ratio > 0.9);
        assert!(r.quality.covariance.is_some());
        if metric == Metric::PointToLine {
            assert!(r.quality.iterations < 15, "{:?}", r.quality);
        }
    }
}

#[test]
fn converges_far_from_the_origin() {
    // World coordinates hundreds of metres away (as in the benchmark logs).
    let walls: Vec<Wall> = l_room_with_pillar()
        .into_iter()
        .map(|mut w| {
            for p in [&mut w.segment.a, &mut w.segment.b] {
                p.x += 580.0;
                p.y -= 30.0;
            }
            w
        })
        .collect();
    let truth = pose(582.0, -28.5, -1.2);
    let params = IcpParams::default();
    let mut reference = Reference::new();
    reference
        .rebuild_ordered(&cast_world(&walls, &truth, 3), &params)
        .unwrap();
    let scan = cast_seeded(&walls, &truth, 4);
    let mut m = Matcher::new(params).unwrap();
    let r = m
        .match_points(&reference, &scan, &(truth * pose(0.05, 0.05, 0.02)))
        .unwrap();
    let (et, er) = err(&r.pose, &truth);
    assert!(
        et < 0.01 && er < 0.003,
        "error {et} m {er} rad, {:?}",
        r.quality
    );
    assert!(
        r.quality.converged && r.quality.iterations < 15,
        "{:?}",
        r.quality
    );
}

#[test]
fn tracker_follows_a_path_against_an_external_map() {
    // The map layer's points stand in as the reference: dense points along
    // every wall of the scene (with their reflectivity).
    use sweepline::icp::{Outcome, Tracker};
    let walls = l_room_with_pillar();
    let map = wall_points(&walls, 0.02);
    let params = IcpParams::default();
    let mut reference = Reference::new();
    reference.rebuild(&map, &params).unwrap();
    let start = pose(1.0, 0.8, 0.0);
    let mut t = Tracker::new(params, start).unwrap();
    let mut truth = start;
    let mut odom = pose(0.0, 0.0, 0.0);
    for k in 0..40 {
        let step = pose(0.08, 0.0, 0.03);
        truth *= step;
        // Odometry that over-reads distance by 10 % and under-reads turns.
        odom *= pose(0.088, 0.0, 0.025);
        let scan = cast(
            &walls,
            &truth,
            &ScanSpec {
                seed: 100 + k,
                ..ScanSpec::default()
            },
        );
        let s = t.step_with_reference(&scan, Some(&odom), &reference);
        assert!(
            matches!(s.outcome, Outcome::Matched(_)),
            "scan {k}: {:?}",
            s.outcome
        );
        let (et, er) = err(&s.pose, &truth);
        assert!(et < 0.02 && er < 0.01, "scan {k}: error {et} m {er} rad");
        assert!(!s.keyframe);
    }
    assert!(t.map().is_empty(), "the keyframe map is not used");
}

#[test]
fn prior_weight_holds_the_translation_to_the_guess() {
    let walls = l_room_with_pillar();
    let truth = pose(2.0, 1.5, 0.3);
    let params = IcpParams::default();
    let mut reference = Reference::new();
    reference
        .rebuild_ordered(&cast_world(&walls, &truth, 11), &params)
        .unwrap();
    let scan = cast_seeded(&walls, &truth, 12);
    let guess = truth * pose(0.06, -0.04, 0.0);
    let mut m = Matcher::new(params).unwrap();
    let free = m.match_prepared_weighted(&reference, &guess, 0.0);
    assert!(free.is_err(), "nothing prepared yet");
    m.prepare_points(&scan).unwrap();
    let free = m.match_prepared_weighted(&reference, &guess, 0.0).unwrap();
    let held = m.match_prepared_weighted(&reference, &guess, 1e6).unwrap();
    assert!(err(&free.pose, &truth).0 < 0.01, "{:?}", free.pose);
    // A huge prior weight keeps the translation at the guess.
    let d = (held.pose.translation.vector - guess.translation.vector).norm();
    assert!(d < 0.005, "moved {d} m from the guess");
}

/// Along a featureless corridor the scans say nothing about travel, so the
/// tracker keeps the odometry prior there. Logged odometry with timing jitter
/// (the MIT CSAIL log alternates short and long steps) then puts that jitter
/// into the trajectory; `odometry_smoothing` removes most of it.
#[test]
fn smoothed_odometry_reduces_jitter_along_a_corridor() {
    use sweepline::icp::{Outcome, Tracker};
    let walls = vec![
        Wall::new(-60.0, -1.0, 60.0, -1.0, 0.5),
        Wall::new(-60.0, 1.0, 60.0, 1.0, 0.5),
    ];
    let run = |smoothing: f64| -> (f64, usize) {
        let params = IcpParams {
            odometry_smoothing: smoothing,
            ..IcpParams::default()
        };
        let start = pose(0.0, 0.0, 0.0);
        let mut t = Tracker::new(params, start).unwrap();
        let (mut truth, mut last) = (start, start);
        let (mut sum, mut degenerate) = (0.0, 0);
        for k in 0..40u64 {
            truth *= pose(0.24, 0.0, 0.0);
            // The odometry reading lags or leads by a quarter of a step.
            let jitter = if k % 2 == 0 { -0.06 } else { 0.06 };
            let odom = pose(truth.translation.x + jitter, 0.0, 0.0);
            let scan = cast(
                &walls,
                &truth,
                &ScanSpec {
                    seed: 300 + k,
                    ..ScanSpec::default()
                },
            );
            let s = t.step(&scan, Some(&odom));
            if let Outcome::Matched(q) = s.outcome {
                degenerate += usize::from(q.degenerate);
            }
            if k >= 10 {
                // Error of the estimated step against the true 0.24 m.
                let step = last.inverse() * s.pose;
                sum += (step.translation.x - 0.24).abs();
            }
            last = s.pose;
        }
        (sum / 30.0, degenerate)
    };
    let (raw, deg_raw) = run(0.0);
    let (smooth, deg_smooth) = run(0.5);
    eprintln!("step error along the corridor: raw {raw:.4} m, smoothed {smooth:.4} m");
    assert!(
        deg_raw > 30 && deg_smooth > 30,
        "the corridor is degenerate"
    );
    assert!(raw > 0.04, "raw odometry jitter shows: {raw} m per step");
    assert!(
        smooth < 0.5 * raw,
        "smoothed {smooth} m per step vs raw {raw} m"
    );
}

/// `scan_fusion`: against a noisy map (each wall point off by up to ±2 cm, as
/// in a map built from many registered scans) every scan-to-map pose carries
/// its own small error; matching each scan against the previous one as well
/// makes consecutive poses more consistent, while the reported pose stays
/// within a bounded offset of the scan-to-map pose.
#[test]
fn scan_fusion_makes_consecutive_poses_consistent() {
    use sweepline::icp::{Outcome, Tracker};
    let walls = l_room_with_pillar();
    let mut state = 5u64;
    let mut noise = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.04
    };
    let mut map = Vec::new();
    for w in &walls {
        let n = (w.segment.length() / 0.05).ceil() as usize;
        let d = w.segment.b - w.segment.a;
        let normal = nalgebra::Vector2::new(-d.y, d.x) / d.norm();
        for k in 0..=n {
            let p = w.segment.a + d * (k as f64 / n as f64) + normal * noise();
            map.push(IPoint::new(p.x, p.y, w.intensity));
        }
    }
    let run = |share: f64| -> (f64, f64, f64) {
        let params = IcpParams {
            scan_fusion: share,
            ..IcpParams::default()
        };
        let mut reference = Reference::new();
        reference.rebuild(&map, &params).unwrap();
        let start = pose(1.0, 0.8, 0.0);
        let mut t = Tracker::new(params, start).unwrap();
        let (mut truth, mut odom) = (start, pose(0.0, 0.0, 0.0));
        let (mut last, mut last_truth) = (start, start);
        let (mut et, mut er, mut offset) = (0.0, 0.0, 0.0f64);
        for k in 0..40u64 {
            let step = pose(0.08, 0.0, 0.03);
            truth *= step;
            odom *= pose(0.088, 0.0, 0.025);
            let scan = cast(
                &walls,
                &truth,
                &ScanSpec {
                    seed: 500 + k,
                    ..ScanSpec::default()
                },
            );
            let s = t.step_with_reference(&scan, Some(&odom), &reference);
            assert!(matches!(s.outcome, Outcome::Matched(_)), "{:?}", s.outcome);
            assert_eq!(s.pose, t.pose());
            if k > 0 {
                let (dt, dr) = err(&(last_truth.inverse() * truth), &(last.inverse() * s.pose));
                et += dt / 39.0;
                er += dr / 39.0;
            }
            offset = offset.max(err(&s.pose, &t.map_pose()).0);
            let (at, ar) = err(&s.pose, &truth);
            assert!(at < 0.03 && ar < 0.02, "scan {k}: {at} m {ar} rad off");
            (last, last_truth) = (s.pose, truth);
        }
        (et, er, offset)
    };
    let (t0, r0, off0) = run(0.0);
    let (t1, r1, off1) = run(0.7);
    eprintln!(
        "step error: map only {t0:.4} m {:.3} deg; fused {t1:.4} m {:.3} deg; offset {off1:.4} m",
        r0.to_degrees(),
        r1.to_degrees()
    );
    assert_eq!(
        off0, 0.0,
        "without fusion the reported pose is the map pose"
    );
    assert!(off1 > 0.0 && off1 < 0.02, "offset {off1} m");
    assert!(t1 < 0.8 * t0, "translation per step {t1} vs {t0}");
    assert!(r1 < 0.8 * r0, "rotation per step {r1} vs {r0}");
}
