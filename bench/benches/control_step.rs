//! Cost of the protective field (`control.guard`): loading one 682-beam
//! URG-04LX scan into the robot frame (the localise stage's share, once per
//! scan), the free distance ahead over it, and one follower step with and
//! without the field (the control stage's share, 20 times a second and once
//! per scan). Compare the two steps' ratio within one run.

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Point2;
use sweepline::control::guard::ObstaclePoints;
use sweepline::control::{ControlParams, PathFollower};
use sweepline::geom::pose;
use sweepline::robot::RobotParams;
use sweepline::scan::{Beam, LaserScan};

/// A scan of a room about 2 m around, 682 beams over 240°.
fn scan() -> LaserScan {
    let mut s = LaserScan::default();
    for k in 0..682 {
        let angle = -2.0944 + k as f64 * 0.006_144;
        let _ = s.beams.push(Beam {
            angle,
            range: 2.0 + 0.5 * (3.0 * angle).sin(),
            intensity: 0.0,
            valid: true,
        });
    }
    s
}

fn bench(c: &mut Criterion) {
    let scan = scan();
    let mount = pose(0.05, 0.0, 0.0);
    let here = pose(1.0, 1.0, 0.3);
    let mut ahead = ObstaclePoints::default();
    c.bench_function("control/guard_load_scan", |b| {
        b.iter(|| ahead.load_scan(std::hint::black_box(&scan), &mount, here))
    });
    let moved = pose(1.02, 1.01, 0.31);
    c.bench_function("control/guard_free_ahead", |b| {
        b.iter(|| ahead.free_ahead(std::hint::black_box(&moved), 0.17, 0.03))
    });
    let robot = RobotParams::default();
    let mut f = PathFollower::new(&ControlParams::default(), &robot).unwrap();
    let lane = [Point2::new(1.0, 1.0), Point2::new(400.0, 1.0)];
    let at = pose(1.5, 1.0, 0.0);
    f.set_path(&lane, None);
    c.bench_function("control/follower_step", |b| {
        b.iter(|| f.step(std::hint::black_box(&at), 0.05))
    });
    f.set_path(&lane, None);
    c.bench_function("control/follower_step_guarded", |b| {
        b.iter(|| f.step_guarded(std::hint::black_box(&at), 0.05, Some((&ahead, &moved))))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
