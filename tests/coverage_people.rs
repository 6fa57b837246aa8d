//! People walking through the room (`walker` lines, `--walker`), lock-step:
//! the planner covers around them, never touches them, and waits for a room
//! a person walls off to clear instead of finishing without it.

use sweepline::config::Config;
use sweepline::sim::lockstep::{run, LockstepOptions, Mode};
use sweepline::sim::walker::Walker;
use sweepline::sim::world::World;

fn world(name: &str) -> World {
    let path = format!("{}/hw/worlds/{name}", env!("CARGO_MANIFEST_DIR"));
    World::load(std::path::Path::new(&path)).unwrap()
}

#[test]
fn a_person_standing_in_the_doorway_is_waited_for_and_the_far_room_covered() {
    let w = world("doorway.world");
    assert_eq!(w.walkers.len(), 1);
    let opts = LockstepOptions::default();
    let r = run(&w, &Config::default(), &opts, Mode::Online).unwrap();
    let m = &r.metrics;
    eprintln!(
        "waiting: coverage {:.4} overlap {:.3} path {:.1} m time {:.0} s contacts {} tasks {}",
        m.coverage, m.overlap, m.path_length, m.time, m.person_contacts, r.stats.tasks
    );
    assert!(r.finished);
    assert_eq!(m.collisions, 0);
    assert_eq!(m.person_contacts, 0);
    assert!(m.coverage >= 0.99, "coverage {}", m.coverage);
    // The person left at about 224 s: the right room was covered after.
    assert!(m.time > 224.0, "finished at {} s", m.time);
    // Without the wait the run ends with the right room walled off.
    let mut cfg = Config::default();
    cfg.plan.clear_wait = 0.0;
    let r = run(&w, &cfg, &opts, Mode::Online).unwrap();
    let m = &r.metrics;
    eprintln!(
        "not waiting: coverage {:.4} time {:.0} s",
        m.coverage, m.time
    );
    assert!(r.finished);
    assert!(m.coverage < 0.6, "coverage {} without waiting", m.coverage);
}

#[test]
fn people_crossing_the_room_are_covered_around_and_never_touched() {
    let mut w = world("paper.world");
    // One across the robot's start, four times; one down the middle later.
    for spec in [
        "0.2 0.8 0.4 1.0 6.1 1.0 trips 4",
        "0.2 0.8 2.9 0.4 2.9 3.7 after 150 trips 4",
    ] {
        w.add_walker(Walker::parse(spec).unwrap()).unwrap();
    }
    let r = run(
        &w,
        &Config::default(),
        &LockstepOptions::default(),
        Mode::Online,
    )
    .unwrap();
    let m = &r.metrics;
    eprintln!(
        "coverage {:.4} overlap {:.3} path {:.1} m time {:.0} s contacts {} blocked {}",
        m.coverage, m.overlap, m.path_length, m.time, m.person_contacts, r.stats.blocked
    );
    assert!(r.finished);
    assert_eq!(m.collisions, 0);
    assert_eq!(m.person_contacts, 0);
    assert!(m.coverage >= 0.99, "coverage {}", m.coverage);
}
