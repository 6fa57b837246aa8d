//! The decomposition on rooms cut from the IPA floor plans (shared data):
//! explore scan by scan, check ids persist, cells cover the explored
//! configuration space and do not overlap, and every update is fast.

mod decomp_support;

use std::collections::HashSet;
use std::time::Instant;

use decomp_support::*;
use nalgebra::Point2;
use sweepline::decomp::{svg, CellStatus, DecompParams, Decomposer};
use sweepline::sim::floorplan::{load_room, MAPS_DIR};

const ROOMS: &[&str] = &[
    "office_b:6",
    "lab_f_scan:19",
    "lab_c_scan:6",
    "office_h:11",
    "NLB:48",
];

#[test]
fn floor_plan_rooms() {
    let dir = sweepline::require_shared!(MAPS_DIR);
    let out = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("decomp");
    std::fs::create_dir_all(&out).unwrap();
    for spec in ROOMS {
        let room = load_room(&dir, spec).unwrap();
        let world = room.world();
        let mut grid = grid_for(&world, 0.05);
        let mut dec = Decomposer::new(&DecompParams::default(), 0.17).unwrap();
        let mut times = Vec::new();
        let mut seen_ids: HashSet<u32> = HashSet::new();
        let mut finals: HashSet<u32> = HashSet::new();
        let poses = tour(&world, 1.0);
        for p in &poses {
            scan(&world, &mut grid, p);
            let t = Instant::now();
            let d = dec.update(&grid, &[]);
            times.push(t.elapsed().as_secs_f64());
            // A final cell never disappears and never changes.
            for c in &d.cells {
                seen_ids.insert(c.id.0);
                if c.status == CellStatus::Final {
                    finals.insert(c.id.0);
                }
            }
            for id in &finals {
                assert!(
                    d.cells
                        .iter()
                        .any(|c| c.id.0 == *id && c.status == CellStatus::Final),
                    "{spec}: final cell {id} lost"
                );
            }
        }
        for _ in 0..4 {
            dec.update(&grid, &[]);
        }
        let d = dec.decomposition();
        let name = spec.replace(':', "_");
        let doc = svg::render(
            d,
            &grid,
            None,
            &[],
            &format!("{spec}: {} cells", d.cells.len()),
        );
        svg::save_to(&out.join(format!("room_{name}.svg")), &doc).unwrap();
        // Cells do not overlap: sample the explored free area.
        let r = &world.free;
        let (mut inside, mut clear_pts) = (0usize, 0usize);
        for cy in (0..r.height).step_by(2) {
            for cx in (0..r.width).step_by(2) {
                let p = r.centre_of(cx, cy);
                let owners = d.cells.iter().filter(|c| c.contains(&p)).count();
                assert!(owners <= 1, "{spec}: {p} in {owners} cells");
                if world.disk_is_free(&p, 0.17 + 0.06) {
                    clear_pts += 1;
                    inside += owners;
                }
            }
        }
        let share = inside as f64 / clear_pts.max(1) as f64;
        let p99 = percentile(&times, 0.99) * 1e3;
        eprintln!(
            "first updates (ms): {:?}",
            times
                .iter()
                .take(6)
                .map(|t| (t * 1e4).round() / 10.0)
                .collect::<Vec<_>>()
        );
        eprintln!(
            "{spec}: {} scans, {} cells ({} final), {} ids used, C-space share in cells {:.3}, update p50 {:.2} ms p99 {:.2} ms",
            poses.len(),
            d.cells.len(),
            d.cells.iter().filter(|c| c.status == CellStatus::Final).count(),
            seen_ids.len(),
            share,
            percentile(&times, 0.5) * 1e3,
            p99
        );
        assert!(
            share > 0.97,
            "{spec}: cells cover {share:.3} of the clear free space"
        );
        assert!(d.cells.iter().all(|c| c.polygon.len() >= 3));
        let _ = Point2::new(0.0, 0.0);
    }
}
