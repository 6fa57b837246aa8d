//! The protective field (`control.guard`) on real scans: the four SLAM
//! benchmark logs of `../shared/datasets/` (SICK scanners in offices,
//! corridors and labs, people about; Kümmerle et al. 2009). Wherever the
//! recording robot drove straight on, the field must not have seen anything
//! in its way nearer than where the robot actually got: a stop there would
//! have been a false one (range noise, mixed pixels at edges, ghost
//! returns). A person walking away ahead of the robot counts against the
//! field here too, so the bound is a rate, not zero.
//!
//! For every scan, the distance driven straight on is the forward distance
//! to the furthest later scan pose up to which the heading stayed within
//! 3° and the robot within 2 cm of its line (scan poses: the SLAM-corrected
//! ones, or the raw odometry of `mit-csail.clf`). The field uses the
//! default robot (radius 0.17 m, smaller than these robots, so the strip it
//! watches lies inside where their bodies went) and the default side
//! clearance.

use sweepline::control::guard::{ObstaclePoints, WATCH_RANGE};
use sweepline::control::ControlParams;
use sweepline::geom::{heading, Pose};
use sweepline::robot::RobotParams;
use sweepline::sim::carmen::{self, NO_RETURN_RANGE};

/// Distance driven straight on from scan `k`'s pose (m).
fn straight_on(poses: &[Pose], k: usize) -> f64 {
    let p = poses[k];
    let mut best = 0.0f64;
    for q in &poses[k + 1..] {
        let rel = p.inverse() * q;
        let (x, y) = (rel.translation.x, rel.translation.y);
        let turn = heading(&rel).abs().to_degrees();
        if turn > 3.0 || y.abs() > 0.02 || x < best - 0.01 {
            break;
        }
        best = best.max(x);
    }
    best
}

/// What [`check`] found in one log.
struct Found {
    /// Scans in the log.
    scans: usize,
    /// Scans after which the robot drove straight on at least 0.2 m.
    driven: usize,
    /// False stops among those.
    false_stops: usize,
    /// The worst shortfall (m).
    worst: f64,
    /// Scans showing something in the watched strip within [`WATCH_RANGE`].
    seen_ahead: usize,
}

/// The field of a body of `radius` watching all but `side` of each flank
/// on every scan of the log at `path` (odometry poses when `raw`).
fn check(path: &std::path::Path, raw: bool, radius: f64, side: f64) -> Found {
    let log = carmen::read_file(path).unwrap();
    let lasers: Vec<_> = log.lasers().collect();
    let poses: Vec<Pose> = lasers
        .iter()
        .map(|l| if raw { l.odom_pose } else { l.laser_pose })
        .collect();
    let mut ahead = ObstaclePoints::default();
    let mut f = Found {
        scans: lasers.len(),
        driven: 0,
        false_stops: 0,
        worst: 0.0,
        seen_ahead: 0,
    };
    for (k, l) in lasers.iter().enumerate() {
        let scan = l.to_scan(k as u64, NO_RETURN_RANGE);
        ahead.load_scan(&scan, &Pose::identity(), poses[k]);
        let free = ahead.free_ahead(&poses[k], radius, side);
        if free < WATCH_RANGE {
            f.seen_ahead += 1;
        }
        // The field looks no further than WATCH_RANGE.
        let d = straight_on(&poses, k).min(WATCH_RANGE);
        if d < 0.2 {
            continue;
        }
        f.driven += 1;
        // 2 cm for the poses' own error.
        if free < d - 0.02 {
            f.false_stops += 1;
            f.worst = f.worst.max(d - free);
        }
    }
    f
}

#[test]
fn the_field_does_not_stop_real_robots_where_they_drove_on() {
    let logs = [
        ("datasets/mit-csail/mit-csail.clf", true),
        ("datasets/intel/intel-corrected.log.gz", false),
        ("datasets/aces/aces-corrected.log.gz", false),
        ("datasets/fr079/freiburg-079-corrected.log.gz", false),
    ];
    let radius = RobotParams::default().radius;
    let side = ControlParams::default().guard_side_clearance;
    let (mut driven, mut false_stops, mut wide_false) = (0, 0, 0);
    for (rel, raw) in logs {
        let path = sweepline::require_shared!(rel);
        let f = check(&path, raw, radius, side);
        // The same robots with the field as wide as a 0.3 m body: the
        // check can tell a field that takes door frames for obstacles.
        let wide = check(&path, raw, 0.3, 0.0);
        eprintln!(
            "{rel}: {} scans, {} with something ahead within {WATCH_RANGE} m; {} with the robot driving straight on >= 0.2 m, {} false stops, worst {:.3} m short; as wide as a 0.3 m body: {} false stops, worst {:.3} m",
            f.scans, f.seen_ahead, f.driven, f.false_stops, f.worst, wide.false_stops, wide.worst
        );
        assert!(
            f.seen_ahead * 10 >= f.scans,
            "{rel}: the field saw something ahead in only {} of {} scans",
            f.seen_ahead,
            f.scans
        );
        driven += f.driven;
        false_stops += f.false_stops;
        wide_false += wide.false_stops;
    }
    eprintln!(
        "all: {false_stops} false stops in {driven} scans; {wide_false} as wide as a 0.3 m body"
    );
    assert!(driven > 1000, "only {driven} scans to check");
    assert!(
        wide_false > 0,
        "the check finds no false stop even for a field too wide"
    );
    // Measured (2026-11-29): 0 of 1831.
    assert!(
        false_stops * 200 <= driven,
        "{false_stops} false stops in {driven} scans (at most 0.5 %)"
    );
}
