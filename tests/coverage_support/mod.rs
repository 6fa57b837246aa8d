//! The coverage targets shared by the room tests: one online and one
//! offline lock-step run of a world, checked for finishing, collisions,
//! coverage, the online/offline path ratio and the drive back to the start.

use sweepline::config::Config;
use sweepline::plan::planner::HOME_NEAR;
use sweepline::plan::HomeOutcome;
use sweepline::sim::lockstep::{run, LockstepOptions, Mode, RunResult};
use sweepline::sim::world::World;

/// Runs `world` online and offline with the configuration `cfg`, prints
/// one line of figures, asserts both finished with zero collisions, >= 99 %
/// coverage of the floor reachable with the safety margin, at least
/// `online_min` (0.99 offline) of the strictly reachable floor, and the
/// online path at most `ratio_bound` x the offline one, and both back
/// at the start at the end; returns both runs.
pub fn online_and_offline(
    spec: &str,
    world: &World,
    cfg: &Config,
    opts: &LockstepOptions,
    ratio_bound: f64,
    online_min: f64,
) -> (RunResult, RunResult) {
    let on = run(world, cfg, opts, Mode::Online).unwrap();
    let off = run(world, cfg, opts, Mode::Offline).unwrap();
    let (m, o) = (&on.metrics, &off.metrics);
    let ratio = m.path_length / o.path_length;
    eprintln!(
        "{spec}: free {:.1} m² reachable {:.1} m² (with margin {:.1} m²) | online coverage {:.4} (with margin {:.4}) overlap {:.3} path {:.1} m | offline coverage {:.4} overlap {:.3} path {:.1} m | ratio {ratio:.3} | ways out {} escapes {}",
        m.free_area, m.reachable_area, m.clear_reachable_area, m.coverage, m.clear_coverage, m.overlap, m.path_length, o.coverage, o.overlap, o.path_length,
        on.stats.ways_out, on.stats.escapes
    );
    assert!(on.finished, "{spec}: online finishes before the cap");
    assert!(off.finished, "{spec}: offline finishes before the cap");
    assert_eq!(m.collisions, 0, "{spec}: online collisions");
    assert_eq!(o.collisions, 0, "{spec}: offline collisions");
    assert!(
        m.coverage >= online_min,
        "{spec}: online coverage {}",
        m.coverage
    );
    for (run, c) in [("online", m.clear_coverage), ("offline", o.clear_coverage)] {
        assert!(
            c >= 0.99,
            "{spec}: {run} coverage of the floor reachable with the margin {c}"
        );
    }
    assert!(
        o.coverage >= 0.99,
        "{spec}: offline coverage {}",
        o.coverage
    );
    assert!(ratio <= ratio_bound, "{spec}: online/offline path {ratio}");
    // Coverage done, both drove back to the start (plan.return_home; its
    // collisions are in the counts above).
    for (run, r) in [("online", &on), ("offline", &off)] {
        let home = r.report.map(|d| d.home);
        assert_eq!(home, Some(HomeOutcome::Back), "{spec}: {run} drive back");
        let end = r.trajectory.last().unwrap().translation.vector;
        let from = (end - world.start.translation.vector).norm();
        assert!(
            from <= HOME_NEAR,
            "{spec}: {run} ended {from:.3} m from the start"
        );
    }
    (on, off)
}
