//! A person in the closed loop: the scanner emulator sees them, the base
//! emulator's body runs into them, the daemon only sees bytes over the ptys.
//! In `hw/worlds/doorway.world` a person stands in the doorway between two
//! rooms from 20 s to about 224 s; the daemon must cover the first room, wait
//! for the person to go, and then cover the second, touching nobody.

use std::path::Path;

use sweepline::config::Config;
use sweepline::sim::closed_loop::{self, SimOptions};
use sweepline::sim::world::World;

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn the_daemon_waits_for_a_person_in_the_doorway_and_covers_the_far_room() {
    let _ = env_logger::builder().is_test(true).try_init();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let world = World::load(&root.join("hw/worlds/doorway.world")).unwrap();
    let config = Config::load(&root.join("hw/robot.toml")).unwrap();
    let mut opts = SimOptions::new(world, config);
    opts.speed = 8.0;
    opts.time_cap = 1200.0;
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("sim_people_doorway");
    let _ = std::fs::remove_dir_all(&d);
    opts.out = Some(d);
    let r = closed_loop::run(&opts).unwrap();
    let m = &r.metrics;
    eprintln!(
        "{}: coverage {:.2} %, overlap {:.1} %, {:.0} s, collisions {}, contacts with the person {}, bumps {}, plans {:?}",
        r.reason,
        m.coverage * 100.0,
        m.overlap * 100.0,
        m.time,
        m.collisions,
        m.person_contacts,
        r.base_emu.bumps,
        r.plan_stats
    );
    assert!(r.finished, "did not finish: {}", r.reason);
    assert_eq!(m.collisions, 0);
    assert_eq!(m.person_contacts, 0);
    assert_eq!(r.base_emu.bumps, 0);
    // The far room was covered after the person left (at about 224 s).
    assert!(m.time > 224.0, "finished at {:.0} s", m.time);
    assert!(m.coverage >= 0.99, "coverage {:.4}", m.coverage);
}
