//! Bad input never panics and never yields a silent wrong pose: empty and
//! all-invalid scans, NaN/inf ranges, a single point, one straight wall, bad
//! references and guesses, each with a typed result that says what happened.

use sweepline::geom::{pose, IPoint, Pose};
use sweepline::icp::synth::{cast, cast_seeded, room, ScanSpec, Wall};
use sweepline::icp::{IcpError, IcpParams, Matcher, Outcome, Reference, Tracker};
use sweepline::scan::{Beam, LaserScan};

fn room_reference(params: &IcpParams) -> (Reference, Vec<IPoint>) {
    let walls = room(5.0, 4.0, 0.5);
    let at = pose(2.0, 1.5, 0.0);
    let scan = cast(&walls, &at, &ScanSpec::default());
    let mut r = Reference::new();
    let world: Vec<IPoint> = scan.iter().map(|p| p.transformed(&at)).collect();
    r.rebuild_ordered(&world, params).unwrap();
    (r, scan)
}

fn matcher() -> (Matcher, Reference, Vec<IPoint>) {
    let params = IcpParams::default();
    let (r, scan) = room_reference(&params);
    (Matcher::new(params).unwrap(), r, scan)
}

#[test]
fn empty_scan() {
    let (mut m, r, _) = matcher();
    assert_eq!(
        m.match_points(&r, &[], &Pose::identity()),
        Err(IcpError::EmptyScan)
    );
    let empty = LaserScan::default();
    assert_eq!(
        m.match_scan(&r, &empty, &Pose::identity()),
        Err(IcpError::EmptyScan)
    );
}

#[test]
fn all_invalid_scan() {
    let (mut m, r, _) = matcher();
    let mut scan = LaserScan::default();
    for i in 0..100 {
        let b = Beam {
            angle: i as f64 * 0.01,
            range: 2.0,
            intensity: 0.0,
            valid: false,
        };
        scan.beams.push(b).unwrap();
    }
    assert_eq!(
        m.match_scan(&r, &scan, &Pose::identity()),
        Err(IcpError::NoValidPoints { total: 100 })
    );
}

#[test]
fn nan_and_inf_values_are_dropped_not_used() {
    let (mut m, r, scan) = matcher();
    let mut all_bad = vec![IPoint::new(f64::NAN, 1.0, 0.0); 50];
    all_bad.push(IPoint::new(f64::INFINITY, 0.0, 0.0));
    all_bad.push(IPoint::new(1.0, 1.0, f64::NAN));
    assert_eq!(
        m.match_points(&r, &all_bad, &Pose::identity()),
        Err(IcpError::NoValidPoints { total: 52 })
    );

    // A good scan with garbage mixed in still matches, to the right pose.
    let mut mixed = scan.clone();
    for k in (0..mixed.len()).step_by(7) {
        mixed[k] = IPoint::new(f64::NAN, f64::INFINITY, 0.0);
    }
    let truth = pose(2.0, 1.5, 0.0);
    let res = m
        .match_points(&r, &mixed, &(truth * pose(0.05, -0.04, 0.03)))
        .unwrap();
    let d = truth.inverse() * res.pose;
    assert!(
        d.translation.vector.norm() < 0.01 && d.rotation.angle().abs() < 0.003,
        "{:?}",
        res.pose
    );

    // Beams flagged valid but carrying NaN/inf ranges are skipped too.
    let mut ls = LaserScan::default();
    for i in 0..200 {
        let range = if i % 2 == 0 { f64::NAN } else { f64::INFINITY };
        ls.beams
            .push(Beam {
                angle: i as f64 * 0.01,
                range,
                intensity: 0.0,
                valid: true,
            })
            .unwrap();
    }
    assert_eq!(
        m.match_scan(&r, &ls, &Pose::identity()),
        Err(IcpError::NoValidPoints { total: 200 })
    );
}

#[test]
fn single_point() {
    let (mut m, r, _) = matcher();
    let e = m
        .match_points(&r, &[IPoint::new(1.0, 0.5, 0.0)], &Pose::identity())
        .unwrap_err();
    assert_eq!(e, IcpError::TooFewScanPoints { have: 1, need: 20 });
    assert!(e.to_string().contains("only 1 usable points"), "{e}");
}

#[test]
fn bad_reference_and_guess() {
    let params = IcpParams::default();
    let (mut m, r, scan) = matcher();
    // Never built.
    let empty = Reference::new();
    assert!(matches!(
        m.match_points(&empty, &scan, &Pose::identity()),
        Err(IcpError::TooFewReferencePoints { have: 0, .. })
    ));
    // Built from garbage.
    let mut bad = Reference::new();
    let garbage = vec![IPoint::new(f64::NAN, 0.0, 0.0); 100];
    assert!(matches!(
        bad.rebuild(&garbage, &params),
        Err(IcpError::TooFewReferencePoints { have: 0, .. })
    ));
    assert!(matches!(
        bad.rebuild_ordered(&[IPoint::new(1.0, 1.0, 0.0)], &params),
        Err(IcpError::TooFewReferencePoints { have: 1, .. })
    ));
    assert!(bad.is_empty());
    // A non-finite guess.
    let nan_guess = pose(f64::NAN, 0.0, 0.0);
    assert_eq!(
        m.match_points(&r, &scan, &nan_guess),
        Err(IcpError::BadInitialGuess)
    );
    // A guess so far off that nothing pairs.
    let far = pose(100.0, 100.0, 0.0);
    assert!(matches!(
        m.match_points(&r, &scan, &far),
        Err(IcpError::TooFewPairs { pairs: 0, .. })
    ));
}

#[test]
fn one_straight_wall_is_degenerate_and_keeps_the_guess_along_it() {
    let params = IcpParams::default();
    let wall = [Wall::new(-20.0, 2.0, 20.0, 2.0, 0.5)];
    let spec = ScanSpec {
        max_range: 30.0,
        ..ScanSpec::default()
    };
    let at = pose(0.0, 0.0, 0.0);
    let mut r = Reference::new();
    let world: Vec<IPoint> = cast(&wall, &at, &spec)
        .iter()
        .map(|p| p.transformed(&at))
        .collect();
    r.rebuild_ordered(&world, &params).unwrap();
    let truth = pose(0.4, 0.05, 0.02);
    let scan = cast(&wall, &truth, &ScanSpec { seed: 9, ..spec });
    let guess = pose(0.1, 0.0, 0.0);
    let mut m = Matcher::new(params).unwrap();
    let res = m.match_points(&r, &scan, &guess).unwrap();
    assert!(res.quality.degenerate, "{:?}", res.quality);
    assert!(res.quality.covariance.is_none());
    assert!(res.quality.min_eigenvalue < 0.02);
    // The weak direction is along the wall (x).
    assert!(
        res.quality.weak_direction.x.abs() > 0.9,
        "{:?}",
        res.quality.weak_direction
    );
    // Along the wall the scan stays where the guess put it (nothing is
    // invented): its centroid, about which the solver rotates, keeps its x.
    let n = scan.len() as f64;
    let c = nalgebra::Point2::new(
        scan.iter().map(|p| p.x).sum::<f64>() / n,
        scan.iter().map(|p| p.y).sum::<f64>() / n,
    );
    let (cr, cg) = (res.pose * c, guess * c);
    assert!(
        (cr.x - cg.x).abs() < 0.01,
        "centroid x {} vs guess {}",
        cr.x,
        cg.x
    );
    assert!(
        (res.pose.translation.x - 0.1).abs() < 0.06,
        "x = {}",
        res.pose.translation.x
    );
    // Across the wall and in rotation the scan does constrain it.
    assert!(
        (res.pose.translation.y - 0.05).abs() < 0.02,
        "y = {}",
        res.pose.translation.y
    );
    assert!((res.pose.rotation.angle() - 0.02).abs() < 0.01);
}

#[test]
fn tracker_survives_garbage_and_recovers() {
    let walls = room(5.0, 4.0, 0.5);
    let mut t = Tracker::new(IcpParams::default(), pose(2.0, 1.5, 0.0)).unwrap();
    // Garbage before the first good scan: no map, no pose change.
    let s = t.step(&[], None);
    assert!(matches!(s.outcome, Outcome::Failed(IcpError::EmptyScan)));
    let s = t.step(&[IPoint::new(f64::NAN, 0.0, 0.0); 10], None);
    assert!(matches!(
        s.outcome,
        Outcome::Failed(IcpError::NoValidPoints { .. })
    ));
    let first = cast(&walls, &pose(2.0, 1.5, 0.0), &ScanSpec::default());
    assert!(matches!(t.step(&first, None).outcome, Outcome::First));
    // Garbage mid-run: the prediction is used and said so.
    let s = t.step(&[IPoint::new(1.0, 0.0, 0.0)], None);
    assert!(matches!(
        s.outcome,
        Outcome::Failed(IcpError::TooFewScanPoints { .. })
    ));
    // Then a good scan matches again.
    let next = cast_seeded(&walls, &pose(2.1, 1.5, 0.05), 3);
    let s = t.step(&next, None);
    assert!(matches!(s.outcome, Outcome::Matched(_)), "{:?}", s.outcome);
    let d = pose(2.1, 1.5, 0.05).inverse() * s.pose;
    assert!(
        d.translation.vector.norm() < 0.02 && d.rotation.angle().abs() < 0.01,
        "{:?}",
        s.pose
    );
}

#[test]
fn invalid_params_are_named() {
    let p = IcpParams {
        trim_fraction: 0.0,
        ..IcpParams::default()
    };
    let e = Matcher::new(p).unwrap_err();
    assert!(e.to_string().contains("icp.trim_fraction"), "{e}");
    let p = IcpParams {
        intensity_weight: f64::NAN,
        ..IcpParams::default()
    };
    assert!(Matcher::new(p)
        .unwrap_err()
        .to_string()
        .contains("icp.intensity_weight"));
}

#[test]
fn long_runs_of_predictions_stay_finite() {
    // Thousands of chained poses used to drift off unit rotation and then blow
    // up under repeated constant-velocity prediction; poses are renormalised.
    let walls = room(5.0, 4.0, 0.5);
    let start = pose(2.0, 1.5, 0.0);
    let mut t = Tracker::new(IcpParams::default(), start).unwrap();
    assert!(matches!(
        t.step(&cast(&walls, &start, &ScanSpec::default()), None)
            .outcome,
        Outcome::First
    ));
    let moved = pose(2.05, 1.5, 0.03);
    let s = t.step(&cast_seeded(&walls, &moved, 5), None);
    assert!(matches!(s.outcome, Outcome::Matched(_)), "{:?}", s.outcome);
    let mut odom = pose(0.0, 0.0, 0.0);
    for k in 0..20_000 {
        odom *= pose(0.01, 0.0, 0.013);
        let s = t.step(&[], if k % 2 == 0 { Some(&odom) } else { None });
        assert!(matches!(s.outcome, Outcome::Failed(IcpError::EmptyScan)));
    }
    let p = t.pose();
    assert!(p.translation.x.is_finite() && p.translation.y.is_finite());
    assert!(
        (p.rotation.norm() - 1.0).abs() < 1e-12,
        "{}",
        p.rotation.norm()
    );
}
