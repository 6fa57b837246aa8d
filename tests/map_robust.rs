//! Bad input never reaches the map: a scan the matcher flags as badly
//! registered is not merged, NaN / infinite / out-of-range beams never become
//! points, a non-finite pose is refused; and snapshots stay consistent for
//! readers on other threads while the writer keeps merging.

mod map_support;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use map_support::*;
use sweepline::geom::{pose, Pose};
use sweepline::map::{Map, MapError, MapParams, ScanQuality};
use sweepline::scan::{Beam, LaserScan};
use sweepline::sim::world::World;

fn paper() -> (World, Vec<Pose>) {
    let (_, text) = &worlds()[0];
    (World::parse(text).unwrap(), path(&world_paths()[0], 0.1))
}

fn built(n: usize) -> (World, Vec<Pose>, Map) {
    let (world, poses) = paper();
    let mut r = rng(3);
    let mut map = Map::new(MapParams::default(), poses[0]).unwrap();
    for p in &poses[..n] {
        let s = urg_scan(&world, p, 0.01, &mut r);
        map.update(&s, p, ScanQuality::Good).unwrap();
    }
    (world, poses, map)
}

#[test]
fn a_badly_registered_scan_is_not_merged() {
    let (world, poses, mut map) = built(40);
    let before_points = map.points().to_vec();
    let before_segments = map.segment_map().segments().to_vec();
    let before_grid = map.grid().counts();
    let before_traj = map.trajectory().len();
    // A scan from further along the path, registered 0.4 m / 17° off.
    let truth = poses[120];
    let wrong = truth * pose(0.4, -0.3, 0.3);
    let s = urg_scan(&world, &truth, 0.01, &mut rng(9));
    let r = map.update(&s, &wrong, ScanQuality::Bad).unwrap();
    assert!(!r.merged);
    assert_eq!(r.correction, None);
    assert_eq!(map.points(), &before_points[..]);
    assert_eq!(map.segment_map().segments(), &before_segments[..]);
    assert_eq!(map.grid().counts(), before_grid);
    assert_eq!(map.trajectory().len(), before_traj);
    assert_eq!(
        before_traj, 40,
        "the path moves 10 cm per scan: every pose is kept"
    );
    assert_eq!(map.scan_counts(), (41, 40));
    // The pose still follows the caller (equation 3 continues from it).
    assert_eq!(map.pose(), wrong);
    // The same scan flagged good would have changed the map: the check above can fail.
    let r = map.update(&s, &wrong, ScanQuality::Good).unwrap();
    assert!(r.merged && r.counts.kept > 50, "{r:?}");
    assert_ne!(map.grid().counts(), before_grid);
}

#[test]
fn nan_infinite_and_out_of_range_beams_never_enter() {
    let (_, poses, mut map) = built(10);
    let before = map.points().len();
    let at = poses[10];
    let p = map.params().clone();
    let bad = [
        (f64::NAN, 0.0, 0.5, true),
        (1.0, f64::NAN, 0.5, true),
        (1.0, 0.1, f64::NAN, true),
        (f64::INFINITY, 0.2, 0.5, true),
        (f64::NEG_INFINITY, 0.3, 0.5, true),
        (-1.0, 0.4, 0.5, true),
        (0.0, 0.5, 0.5, true),
        (p.min_range * 0.5, 0.6, 0.5, true),
        (p.max_range + 0.01, 0.7, 0.5, true),
        (1e12, 0.8, 0.5, true),
        (2.0, 0.9, 0.5, false),
        (2.0, f64::INFINITY, 0.5, true),
    ];
    let mut s = LaserScan::default();
    for (range, angle, intensity, valid) in bad {
        let _ = s.beams.push(Beam {
            angle,
            range,
            intensity,
            valid,
        });
    }
    let r = map.update(&s, &at, ScanQuality::Good).unwrap();
    assert_eq!(r.rejected_beams, bad.len());
    assert_eq!(r.counts.kept, 0);
    assert_eq!(map.points().len(), before);
    // Every stored point is finite and within max_range of some pose it was seen from.
    for q in map.points() {
        assert!(q.x.is_finite() && q.y.is_finite() && q.intensity.is_finite());
        let near = map.trajectory().iter().any(|t| {
            (q.xy() - nalgebra::Point2::from(t.translation.vector)).norm() <= p.max_range + 0.05
        });
        assert!(near, "{q:?}");
    }
    // Mixed in with good beams, only the good ones are kept.
    let mut mixed = urg_scan(&paper().0, &at, 0.01, &mut rng(4));
    let good = mixed.valid_count();
    for b in mixed.beams.iter_mut().step_by(7) {
        b.range = f64::NAN;
    }
    let nan_count = mixed.beams.iter().filter(|b| b.range.is_nan()).count();
    let r = map.update(&mixed, &at, ScanQuality::Good).unwrap();
    assert!(r.rejected_beams >= nan_count);
    assert!(map
        .points()
        .iter()
        .all(|q| q.x.is_finite() && q.y.is_finite()));
    assert!(good > nan_count);
}

#[test]
fn a_non_finite_pose_is_refused_and_changes_nothing() {
    let (world, poses, mut map) = built(10);
    let n = map.points().len();
    let pose_before = map.pose();
    let s = urg_scan(&world, &poses[11], 0.01, &mut rng(1));
    for bad in [
        pose(f64::NAN, 0.0, 0.0),
        pose(0.0, f64::INFINITY, 0.0),
        pose(0.0, 0.0, f64::NAN),
    ] {
        assert!(matches!(
            map.update(&s, &bad, ScanQuality::Good),
            Err(MapError::NonFinitePose(_))
        ));
        assert!(matches!(
            map.update_with_increment(&s, &bad, ScanQuality::Good),
            Err(MapError::NonFinitePose(_))
        ));
    }
    assert_eq!(map.points().len(), n);
    assert_eq!(map.pose(), pose_before);
    assert!(Map::new(MapParams::default(), pose(f64::NAN, 0.0, 0.0)).is_err());
}

#[test]
fn readers_on_other_threads_see_whole_growing_snapshots() {
    let (world, poses) = paper();
    let params = MapParams {
        publish_every: 2,
        ..Default::default()
    };
    let mut map = Map::new(params, poses[0]).unwrap();
    let cell = map.reader();
    let done = Arc::new(AtomicBool::new(false));
    let reader = {
        let (cell, done) = (Arc::clone(&cell), Arc::clone(&done));
        std::thread::spawn(move || {
            let (mut last_version, mut last_points, mut loads) = (0u64, 0usize, 0u64);
            while !done.load(Ordering::Acquire) {
                let s = cell.load();
                assert!(s.version >= last_version, "version went back");
                assert!(s.points.len() >= last_points, "points went back");
                assert!(s.trajectory.len() as u64 <= s.scans_merged);
                last_version = s.version;
                last_points = s.points.len();
                loads += 1;
                std::thread::yield_now();
            }
            (last_version, loads)
        })
    };
    let mut r = rng(2);
    let held = {
        for p in &poses[..10] {
            map.update(&urg_scan(&world, p, 0.01, &mut r), p, ScanQuality::Good)
                .unwrap();
        }
        map.snapshot()
    };
    let held_points = held.points.clone();
    let held_version = held.version;
    for p in &poses[10..60] {
        map.update(&urg_scan(&world, p, 0.01, &mut r), p, ScanQuality::Good)
            .unwrap();
    }
    done.store(true, Ordering::Release);
    let (seen_version, loads) = reader.join().unwrap();
    assert!(loads > 0);
    // A snapshot held by a reader is never touched by later publications.
    assert_eq!(held.points, held_points);
    assert_eq!(held.version, held_version);
    let last = map.snapshot();
    assert_eq!(last.scans_merged, 60);
    assert_eq!(last.version, 1 + 30, "first scan, then every 2nd");
    assert!(seen_version <= last.version);
    assert_eq!(last.points.len(), map.points().len());
    assert_eq!(last.walls.len(), last.segments.len());
    assert!(last
        .walls
        .iter()
        .zip(&last.segments)
        .all(|(w, s)| *w == s.seg));
}

#[test]
fn random_garbage_never_panics_nor_stores_non_finite_points() {
    use rand::Rng;
    let mut r = rng(99);
    let specials = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        0.0,
        -0.0,
        1e300,
        -1e300,
        f64::MIN_POSITIVE,
    ];
    let pick = |r: &mut rand_chacha::ChaCha8Rng, scale: f64| -> f64 {
        if r.random::<f64>() < 0.1 {
            specials[r.random_range(0..specials.len())]
        } else {
            (r.random::<f64>() - 0.5) * scale
        }
    };
    let mut map = Map::new(MapParams::default(), Pose::identity()).unwrap();
    for _ in 0..300 {
        let mut s = LaserScan::default();
        let n = r.random_range(0..700);
        for _ in 0..n {
            let b = Beam {
                angle: pick(&mut r, 7.0),
                range: pick(&mut r, 12.0).abs(),
                intensity: pick(&mut r, 2.0),
                valid: r.random::<f64>() < 0.9,
            };
            let _ = s.beams.push(b);
        }
        let p = pose(pick(&mut r, 20.0), pick(&mut r, 20.0), pick(&mut r, 7.0));
        let q = if r.random::<f64>() < 0.8 {
            ScanQuality::Good
        } else {
            ScanQuality::Bad
        };
        let _ = map.update(&s, &p, q);
    }
    map.publish();
    let snap = map.snapshot();
    assert!(snap
        .points
        .iter()
        .all(|q| q.x.is_finite() && q.y.is_finite() && q.intensity.is_finite()));
    assert!(snap.segments.iter().all(|s| s
        .seg
        .a
        .coords
        .iter()
        .chain(s.seg.b.coords.iter())
        .all(|v| v.is_finite())));
    assert!(
        !snap.points.is_empty(),
        "some random beams are valid and must be stored"
    );
}
