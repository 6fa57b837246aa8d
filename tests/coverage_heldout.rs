//! Rooms nobody tuned the planner on, each of which once made the online
//! planner fail (the coverage targets: coverage >= 99 % of the reachable floor, zero
//! collisions, online path <= 1.25 x the offline reference, in every room).
//! Lock-step simulation at the default 0.2 s scan period, online and
//! offline, real floor plans from `../shared/maps/`; one test per room, so
//! that they run side by side.
//!
//! What each room did on the build before these fixes (same settings):
//!
//! * `lab_c_scan:0`: online stopped "done" at 2.7 % with 32 m² reported
//!   unreachable: the robot ended a lane on a cell whose only traversable
//!   neighbour was diagonal, between two chair groups (fixed by the way out
//!   of `plan::unbox`);
//! * `lab_a_scan:30`: 96.0 %, done with 12.5 m² reported unreachable, the
//!   robot cut off from the rest by a passage as wide as its body (way out;
//!   still 96.0 % with `plan.way_out_passage = 0`);
//! * `NLB:12`: online never finished (time cap): it walked along a wall
//!   seen at a grazing angle whose cells kept flipping between free and
//!   occupied (frontier given up with its neighbours, and all of it after
//!   eight fruitless explorations in a row);
//! * `lab_c_scan:11`: 89.4 %: the transits into a ring of chairs kept being
//!   blocked by chair legs seen from closer, and the floor inside was given
//!   up after two (blocked transits forgiven, within a bound). Its online
//!   path measured 1.34 x the offline one on 2026-11-22 and `lab_c_scan:0`'s
//!   1.305; since travel is priced by the overlap it adds (2026-11-25) they
//!   measure 0.905 and 1.033, and both are held to the 1.25 target.
//!
//! `lab_a_scan:8`: 1.5 m² (9 %) of its reachable floor lies behind a gap
//! between chair legs 0.35 m wide, 5 mm a side for the 0.34 m body. Until
//! 2026-11-25 the online map put the hits on the legs' faces into the free
//! cells in front of them half the time (every wall of these rasters lies on
//! a cell boundary), the gap showed narrower than the body, the robot left
//! the floor behind it and measured 97.9 %. With the hit in the surface's
//! cell the way out finds the gap online too (99.89 %); the room is held to
//! the 99 % target like the others.

mod coverage_support;

use sweepline::config::Config;
use sweepline::sim::floorplan;
use sweepline::sim::lockstep::LockstepOptions;

/// Runs `spec` online and offline and checks the targets, with
/// `ratio_bound` on online / offline path length.
fn covered(spec: &str, ratio_bound: f64) {
    covered_min(spec, ratio_bound, 0.99);
}

/// [`covered`] with the online coverage of the strictly reachable floor
/// held to `online_min`.
fn covered_min(spec: &str, ratio_bound: f64, online_min: f64) {
    let dir = sweepline::require_shared!(floorplan::MAPS_DIR);
    let opts = LockstepOptions {
        time_cap: 3600.0,
        ..LockstepOptions::default()
    };
    // Ways out of a configuration-space pocket are off by default (they
    // leave millimetres of clearance); these rooms need them.
    let mut cfg = Config::default();
    cfg.plan.way_out_passage = 1.0;
    let room = floorplan::load_room(&dir, spec).unwrap();
    coverage_support::online_and_offline(spec, &room.world(), &cfg, &opts, ratio_bound, online_min);
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn lab_c_scan_0_started_inside_a_ring_of_chairs() {
    covered("lab_c_scan:0", 1.25);
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn lab_a_scan_30_cut_off_by_a_passage_as_wide_as_the_body() {
    covered("lab_a_scan:30", 1.25);
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn nlb_12_finishes_beside_a_wall_seen_at_a_grazing_angle() {
    covered("NLB:12", 1.25);
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn lab_c_scan_11_covers_the_inside_of_a_ring_of_chairs() {
    covered("lab_c_scan:11", 1.25);
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn lab_a_scan_8_floor_behind_a_gap_with_5_mm_a_side() {
    covered("lab_a_scan:8", 1.25);
}
