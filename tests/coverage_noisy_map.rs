//! Coverage on the map as a real robot would build it: the evidence grid's
//! cell boundaries in mid-cell of the floor plans' walls (as in the daemon,
//! whose grid is centred on the start pose) and every scan off by a
//! localisation error (σ 3 mm per axis, 1.5 mrad heading, drawn anew per
//! scan) and range noise (σ 5 mm). The targets (coverage >= 99 %,
//! zero collisions, online path <= 1.25 x offline) must hold on such a map
//! too, not only on ideal scans of walls that lie on cell boundaries.
//!
//! The floor-plan rooms lie tens of metres from the world origin: a heading
//! error that turned the scan about the origin instead of the robot (the
//! noise model of 2026-11-25) moved whole scans by centimetres, and these
//! runs then ended at 94-96 %.
//!
//! The protective field (`control.guard`) must not take those noisy walls
//! for something in the robot's way.

mod coverage_support;

use sweepline::config::Config;
use sweepline::sim::floorplan;
use sweepline::sim::lockstep::{LockstepOptions, SensingNoise};
use sweepline::sim::world::World;

/// Online and offline runs of `world` on the daemon-like noisy map.
fn covered_on_noisy_map(spec: &str, world: &World) {
    let opts = LockstepOptions {
        scan_period: 0.5,
        time_cap: 2400.0,
        grid_offset: 0.025,
        sensing: SensingNoise {
            range: 0.005,
            position: 0.003,
            heading: 0.0015,
            seed: 1,
        },
        ..LockstepOptions::default()
    };
    // Measured (this build, same settings): paper 99.67 %, ratio 1.054;
    // lab_a_scan:1 99.83 %, 1.036; NLB:0 99.61 %, 0.905.
    let (on, _) =
        coverage_support::online_and_offline(spec, world, &Config::default(), &opts, 1.2, 0.99);
    // Walls read short by the noise, passed 1 cm off and met at every
    // lane's end, are what the path expects: the protective field never
    // holds the robot back here (it did not in any of the 24 rooms).
    assert_eq!(on.guard_stops, 0, "{spec}: stops of the protective field");
}

#[test]
fn paper_world_on_a_noisy_map() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/hw/worlds/paper.world");
    let world = World::load(std::path::Path::new(path)).unwrap();
    covered_on_noisy_map("paper", &world);
}

#[test]
fn lab_room_on_a_noisy_map() {
    let dir = sweepline::require_shared!(floorplan::MAPS_DIR);
    let room = floorplan::load_room(&dir, "lab_a_scan:1").unwrap();
    covered_on_noisy_map("lab_a_scan:1", &room.world());
}

#[test]
fn nlb_room_on_a_noisy_map() {
    let dir = sweepline::require_shared!(floorplan::MAPS_DIR);
    let room = floorplan::load_room(&dir, "NLB:0").unwrap();
    covered_on_noisy_map("NLB:0", &room.world());
}
