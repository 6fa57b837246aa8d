//! A recording is test data: a simulated run recorded to MCAP and replayed
//! through the daemon's own localise and map stages (`sweepline replay
//! run.mcap`) tracks the robot as the live run did, scored against the
//! truth recorded beside it.

use std::path::Path;

use sweepline::cli::replay_mcap::replay_recording;
use sweepline::config::Config;
use sweepline::sim::closed_loop::{self, SimOptions};
use sweepline::sim::world::World;

fn config() -> Config {
    Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("hw/robot.toml")).unwrap()
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_replayed_recording_tracks_the_robot_as_the_live_run_did() {
    let world =
        World::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("hw/worlds/paper.world")).unwrap();
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("live-roundtrip");
    let _ = std::fs::remove_dir_all(&out);
    let mut opts = SimOptions::new(world, config());
    opts.out = Some(out.clone());
    opts.time_cap = 600.0;
    let live = closed_loop::run(&opts).unwrap();
    let replay = replay_recording(&out.join("run.mcap"), None).unwrap();
    let (pos, head, _, pairs) = replay.score.expect("the sim recorded its truth");
    eprintln!(
        "live: {:.2} mm / {:.3}° over {} poses; replay: {:.2} mm / {:.3}° over {pairs} poses",
        live.position_rmse * 1e3,
        live.heading_rmse.to_degrees(),
        live.scored_fixes,
        pos * 1e3,
        head.to_degrees()
    );
    assert!(pairs + 20 >= live.scored_fixes, "{pairs} poses scored");
    assert!(
        (pos - live.position_rmse).abs() <= 0.1 * live.position_rmse,
        "replay {pos} m against live {} m",
        live.position_rmse
    );
}
