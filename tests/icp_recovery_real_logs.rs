//! Recovery from a poor prior on real logs: the benchmark's corrected
//! Freiburg 079, Intel and ACES logs replayed without their odometry (it is
//! the SLAM result), each scan predicted by repeating the last motion, with
//! `hw/replay-no-odometry.toml`. Scored with the Kümmerle et al. relations on
//! the time base of `../shared/datasets/README.md`. The thresholds are
//! Censi's CSM on the same logs (that README), which a matcher that tracks
//! must beat; the figures reached are in `docs/localisation.md`.

use sweepline::cli::replay::{replay_log, ReplayResult};
use sweepline::config::Config;
use sweepline::icp::IcpParams;
use sweepline::sim::carmen;
use sweepline::sim::eval::{align, evaluate, parse_relations, read_text, Report};

fn no_odometry() -> IcpParams {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("hw/replay-no-odometry.toml");
    Config::load(&path).unwrap().icp
}

fn replay(log: &std::path::Path, params: &IcpParams) -> ReplayResult {
    replay_log(&carmen::read_file(log).unwrap(), params).unwrap()
}

fn score(res: &ReplayResult, relations: &std::path::Path, offset: f64, tolerance: f64) -> Report {
    let rels = parse_relations(&read_text(relations).unwrap(), "relations").unwrap();
    let r = evaluate(
        &align(&rels, &res.trajectory, offset, tolerance),
        &res.trajectory,
    )
    .unwrap();
    eprintln!("{r}");
    r
}

#[test]
fn freiburg_079_without_odometry_is_tracked_throughout_and_beats_csm() {
    let log = sweepline::require_shared!("datasets/fr079/freiburg-079-corrected.log.gz");
    let rels = sweepline::require_shared!("datasets/fr079/fr079.relations");
    let params = no_odometry();
    let res = replay(&log, &params);
    eprintln!("{}", sweepline::cli::replay::summary(&res));
    // Every window tracked: no long run of unmatched scans, none at the end.
    assert!(
        res.longest_unmatched <= 20,
        "{} unmatched in a row",
        res.longest_unmatched
    );
    assert_eq!(res.unmatched_at_end, 0);
    let r = score(&res, &rels, 1211.43, 0.1);
    assert_eq!(r.all.count, 1652, "the relations scored on this time base");
    // CSM (sm2): <= 1 s 0.034 m / 0.62°, all 1.47 m / 9.6°.
    assert!(r.local.trans.mean <= 0.034, "{r}");
    assert!(r.local.rot_deg.mean <= 0.62, "{r}");
    assert!(r.all.trans.mean < 1.47 && r.all.rot_deg.mean < 9.6, "{r}");

    // Without the search the same prior loses the track at about 898 s of
    // log time (139 scans unmatched in a row; the keyframe store takes it
    // up again, in the wrong place) and the relations show it.
    let mut blind = params.clone();
    blind.search.window = 0.0;
    blind.search.window_angle = 0.0;
    let lost = replay(&log, &blind);
    assert!(
        lost.longest_unmatched > 100,
        "{}",
        sweepline::cli::replay::summary(&lost)
    );
    let r = score(&lost, &rels, 1211.43, 0.1);
    assert!(r.local.rot_deg.mean > 2.0, "{r}");
}

/// The thinned Intel and ACES logs (0.67 m / 21.8° and 0.97 m / 10.6°
/// between scans, median): without the search almost nothing matches (28
/// and 45 scans); with it and the keyframe store at least 90 % of each. A
/// match accepted is not yet a match right: the corrected logs' poses (the
/// SLAM result) say how many scan-to-scan steps are right to 0.1 m and 2°
/// (measured 82.8 % and 69.9 %; with the six-keyframe window 86.8 % and
/// 33.3 %, docs/evaluation.md).
#[test]
fn thinned_intel_and_aces_logs_without_odometry_are_matched() {
    let params = no_odometry();
    let mut blind = params.clone();
    blind.search.window = 0.0;
    blind.search.window_angle = 0.0;
    for (log, rels, offset, scans, right) in [
        (
            "datasets/intel/intel-corrected.log.gz",
            "datasets/intel/intel.relations",
            976052857.337,
            910,
            0.78,
        ),
        (
            "datasets/aces/aces-corrected.log.gz",
            "datasets/aces/aces.relations",
            70.179,
            440,
            0.65,
        ),
    ] {
        let log = sweepline::require_shared!(log);
        let rels = sweepline::require_shared!(rels);
        let res = replay(&log, &params);
        let without = replay(&log, &blind).matched;
        eprintln!(
            "{}\n{}without the search: {without} matched",
            log.display(),
            sweepline::cli::replay::summary(&res)
        );
        assert_eq!(res.trajectory.len(), scans);
        assert!(
            res.matched >= 4 * without,
            "{} matched, {without} without the search",
            res.matched
        );
        // At least 90 % of the scans matched (the first is the map).
        assert!(
            res.matched * 10 >= (scans - 1) * 9,
            "{} of {scans} matched",
            res.matched
        );
        let share = right_steps(&res);
        eprintln!("steps right to 0.1 m and 2°: {:.1} %", 100.0 * share);
        assert!(share >= right, "{:.1} % of the steps right", 100.0 * share);
        // Scored for the record; CSM fails here too (Intel 5.52 m / 35.2°,
        // ACES 38.7 m / 48.7° over 3 relations).
        score(&res, &rels, offset, 0.006);
    }
}

/// The share of scan-to-scan steps of the trajectory that agree with the
/// log's own poses (in a corrected log, the SLAM result) to 0.1 m and 2°.
fn right_steps(res: &ReplayResult) -> f64 {
    let (t, o) = (&res.trajectory, &res.odometry);
    assert_eq!(t.len(), o.len());
    let right = t
        .windows(2)
        .zip(o.windows(2))
        .filter(|(a, b)| {
            let got = a[0].pose.inverse() * a[1].pose;
            let want = b[0].pose.inverse() * b[1].pose;
            let d = want.inverse() * got;
            d.translation.vector.norm() < 0.1 && d.rotation.angle().abs().to_degrees() < 2.0
        })
        .count();
    right as f64 / (t.len() - 1) as f64
}
