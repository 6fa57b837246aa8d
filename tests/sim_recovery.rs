//! The wheels wrong, the scans right: motion faults through the ptys in a
//! closed-loop run of the default room, as `hw/robot.toml` configures the
//! daemon. A slip burst (the left wheel loses 45 % of its travel for a
//! second), a knock that turns the robot 10°, a 3 % odometry scale error,
//! and a kidnap (the robot carried 1 m and turned 30°, the daemon not
//! told). The pose must be back under 2 cm within 5 s of each fault and
//! the room still covered; the kidnap must be noticed and the robot found
//! again, never left lost. Figures for three seeds:
//! `python3 scripts/results.py motion-faults`.

use std::path::Path;

use sweepline::config::Config;
use sweepline::sim::base_emu::faults::parse_motion;
use sweepline::sim::closed_loop::{self, SimOptions, TimedFault};
use sweepline::sim::world::World;

fn run(name: &str, faults: &[&str], scale_error: f64) -> closed_loop::SimReport {
    let _ = env_logger::builder().is_test(true).try_init();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let world = World::load(&root.join("hw/worlds/paper.world")).unwrap();
    let config = Config::load(&root.join("hw/robot.toml")).unwrap();
    let mut opts = SimOptions::new(world, config);
    opts.seed = 1;
    opts.time_cap = 1500.0;
    opts.odometry_scale_error = scale_error;
    for f in faults {
        let (at, fault) = parse_motion(f).unwrap();
        opts.base_faults.push(TimedFault { at, fault });
    }
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    opts.out = Some(d);
    let r = closed_loop::run(&opts).unwrap();
    eprintln!(
        "{name}: {}: coverage {:.2} %, position RMSE {:.1} mm, relocalised {:?}, {:?}",
        r.reason,
        r.metrics.coverage * 100.0,
        r.position_rmse * 1e3,
        r.relocalisations,
        r.fault_recovery
    );
    r
}

fn assert_recovered(r: &closed_loop::SimReport, faults: usize) {
    assert!(r.finished, "did not finish: {}", r.reason);
    assert!(
        r.metrics.coverage >= 0.99,
        "coverage {}",
        r.metrics.coverage
    );
    assert_eq!(r.fault_recovery.len(), faults);
    for f in &r.fault_recovery {
        let settled = f.settled_after.expect("the pose is under 2 cm again");
        assert!(settled <= 5.0, "{f:?}");
    }
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn slip_knock_and_scale_error_are_taken_up_by_the_scans() {
    let r = run(
        "sim_recovery_wheels",
        &["slip=150:1:0.45:0", "knock=300:10"],
        0.03,
    );
    assert_recovered(&r, 2);
    assert_eq!(r.relocalisations, (0, false), "never lost");
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_carried_robot_is_noticed_and_found_again() {
    let r = run("sim_recovery_kidnap", &["kidnap=200:1:0:30"], 0.0);
    assert_recovered(&r, 1);
    // Noticed: no scan matched for a while (the wheels' pose was wrong) ...
    assert!(
        r.fault_recovery[0].longest_gap >= 1.0,
        "{:?}",
        r.fault_recovery
    );
    // ... and found again: by the whole-map search once no scan matched
    // for `daemon.lost_after`, or by a match from the wheels' pose as the
    // live-correction limit grew just before; never left lost.
    assert!(
        r.relocalisations.0 <= 1 && !r.relocalisations.1,
        "{:?}",
        r.relocalisations
    );
}
