//! The paper's intensity-ICP in the closed loop, where it decides:
//! `hw/worlds/corridor.world` is 16 m of plaster with strips of reflective
//! tape, and between x = 5.6 and 10.4 m the scanner sees no end wall. The
//! walls alone do not say where along the corridor the robot is; the tape's
//! borders, matched edge to edge, do. The daemon runs as configured in
//! `hw/robot.toml` with the scanner's intensity mode (`FF`) and the
//! intensity weight turned on; its keyframe store keeps the heading from
//! drifting over the lanes. Figures for every seed, and for plain ICP, are
//! in docs/localisation.md#the-local-map-a-keyframe-store.

use std::path::Path;

use sweepline::config::Config;
use sweepline::sim::closed_loop::{self, SimOptions};
use sweepline::sim::world::World;

/// The corridor covered with intensity weight `w`, seed 1.
fn corridor(w: f64) -> closed_loop::SimReport {
    let _ = env_logger::builder().is_test(true).try_init();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let world = World::load(&root.join("hw/worlds/corridor.world")).unwrap();
    let mut config = Config::load(&root.join("hw/robot.toml")).unwrap();
    config.scanner.intensity = true;
    config.icp.intensity_weight = w;
    let mut opts = SimOptions::new(world, config);
    opts.seed = 1;
    opts.time_cap = 1800.0;
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("sim_intensity_w{w}"));
    let _ = std::fs::remove_dir_all(&d);
    opts.out = Some(d);
    let r = closed_loop::run(&opts).unwrap();
    eprintln!(
        "w = {w}: {}: coverage {:.2} %, overlap {:.1} %, position RMSE {:.1} mm (max {:.1}), heading {:.2}°",
        r.reason,
        r.metrics.coverage * 100.0,
        r.metrics.overlap * 100.0,
        r.position_rmse * 1e3,
        r.position_max * 1e3,
        r.heading_rmse.to_degrees()
    );
    r
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn tape_on_the_walls_holds_the_robot_along_a_featureless_corridor() {
    let with = corridor(0.05);
    assert!(with.finished, "did not finish: {}", with.reason);
    assert!(
        with.metrics.coverage >= 0.99,
        "coverage {:.4}",
        with.metrics.coverage
    );
    assert_eq!(with.metrics.collisions, 0);
    // Runs of seeds 1-3 gave 16-47 mm; plain ICP 32-104 mm, spread too
    // widely between runs of one seed to be compared with (nothing holds it
    // along the corridor but the wheels): docs/localisation.md gives both.
    assert!(
        with.position_rmse <= 0.06,
        "position RMSE {:.1} mm with intensity",
        with.position_rmse * 1e3
    );
}
