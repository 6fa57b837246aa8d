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

    // Without the search the same prior loses the track for good (at about
    // 898 s of log time) and the relations show it.
    let mut blind = params.clone();
    blind.search.window = 0.0;
    blind.search.window_angle = 0.0;
    let lost = replay(&log, &blind);
    assert!(
        lost.unmatched_at_end > 100,
        "{}",
        sweepline::cli::replay::summary(&lost)
    );
    let r = score(&lost, &rels, 1211.43, 0.1);
    assert!(r.local.rot_deg.mean > 2.0, "{r}");
}

/// The thinned Intel and ACES logs (0.67 m / 21.8° and 0.97 m / 10.6°
/// between scans, median): without the search almost nothing matches (28
/// and 45 scans). Intel reaches the 90 % the issue asks for; ACES does not
/// (228 of 440 as configured; see docs/evaluation.md, where the settings
/// tried are listed), and is held to four times its blind count so that a
/// regression shows.
#[test]
fn thinned_intel_and_aces_logs_without_odometry_are_matched() {
    let params = no_odometry();
    let mut blind = params.clone();
    blind.search.window = 0.0;
    blind.search.window_angle = 0.0;
    for (log, rels, offset, scans) in [
        (
            "datasets/intel/intel-corrected.log.gz",
            "datasets/intel/intel.relations",
            976052857.337,
            910,
        ),
        (
            "datasets/aces/aces-corrected.log.gz",
            "datasets/aces/aces.relations",
            70.179,
            440,
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
        if scans == 910 {
            // Intel: at least 90 % of the scans matched (the first is the map).
            assert!(
                res.matched * 10 >= (scans - 1) * 9,
                "{} of {scans} matched",
                res.matched
            );
        }
        // Scored for the record; CSM fails here too (Intel 5.52 m / 35.2°,
        // ACES 38.7 m / 48.7° over 3 relations).
        score(&res, &rels, offset, 0.006);
    }
}
