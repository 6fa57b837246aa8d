//! Segment correction stops error from accumulating: poses are chained with
//! the paper's equation 3 from drifting increments (heading bias 0.05° and
//! 1 % scale error per step, plus noise), and the map's corrected pose is what
//! the next increment is composed onto. With correction the pose stays close
//! to the truth around a whole loop of the room; without it, it drifts away.

mod map_support;

use map_support::*;
use sweepline::geom::{pose, wrap_angle, Pose};
use sweepline::map::pose::increment_between;
use sweepline::map::{Map, MapParams, ScanQuality};
use sweepline::sim::world::World;

/// Runs the loop; returns (max translation error m, max heading error rad,
/// number of scans whose correction was applied).
fn run(correction: bool) -> (f64, f64, usize, Map) {
    let (_, text) = &worlds()[0];
    let world = World::parse(text).unwrap();
    let mut waypoints = world_paths()[0].clone();
    waypoints.push(waypoints[0]);
    let poses = path(&waypoints, 0.1);
    let params = MapParams {
        correction,
        ..Default::default()
    };
    let mut map = Map::new(params, poses[0]).unwrap();
    let mut r = rng(21);
    let (mut max_t, mut max_r, mut applied) = (0.0f64, 0.0f64, 0usize);
    let mut prev = poses[0];
    for (k, truth) in poses.iter().enumerate() {
        let s = urg_scan(&world, truth, 0.01, &mut r);
        let inc: Pose = if k == 0 {
            Pose::identity()
        } else {
            let t = increment_between(&prev, truth);
            pose(
                t.translation.x * 1.01 + 0.003 * gauss(&mut r),
                t.translation.y * 1.01 + 0.003 * gauss(&mut r),
                t.rotation.angle() + 0.05f64.to_radians() + 0.05f64.to_radians() * gauss(&mut r),
            )
        };
        prev = *truth;
        let rep = map
            .update_with_increment(&s, &inc, ScanQuality::Good)
            .unwrap();
        if rep.correction.and_then(|c| c.applied().copied()).is_some() {
            applied += 1;
        }
        let est = map.pose();
        max_t = max_t.max((est.translation.vector - truth.translation.vector).norm());
        max_r = max_r.max(wrap_angle(est.rotation.angle() - truth.rotation.angle()).abs());
    }
    (max_t, max_r, applied, map)
}

#[test]
fn correction_keeps_drifting_poses_on_the_map() {
    let (t_on, r_on, applied, map) = run(true);
    let (t_off, r_off, _, _) = run(false);
    eprintln!(
        "max pose error with correction {t_on:.3} m / {:.2} deg ({applied} corrections applied); without {t_off:.3} m / {:.2} deg",
        r_on.to_degrees(),
        r_off.to_degrees()
    );
    map_support::save_svg(
        "correction_paper_loop.svg",
        &sweepline::map::svg::render(&map.snapshot(), &[]),
    );
    assert!(applied > 100, "correction applied only {applied} times");
    assert!(
        t_on < 0.05 && r_on < 1f64.to_radians(),
        "{t_on} m, {r_on} rad"
    );
    assert!(
        t_off > 3.0 * t_on && r_off > 3.0 * r_on,
        "drift without correction too small to tell: {t_off} m, {r_off} rad"
    );
}
