//! The scan path of the map allocates nothing in steady state: after one pass
//! around the room (which sizes every buffer), a second pass of updates,
//! snapshot publications included, makes no heap allocation. Counted with a
//! global allocator that counts only on the thread that armed it.

mod alloc_support;
mod map_support;

use alloc_support::{count_allocs, Counting};
use map_support::*;
use sweepline::map::{Map, MapParams, ScanQuality};
use sweepline::sim::world::World;

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn second_pass_allocates_nothing() {
    // The counter works: an armed allocation is seen.
    let (v, n) = count_allocs(|| Vec::<u64>::with_capacity(16));
    assert_eq!(n, 1);
    drop(v);
    let (_, text) = &worlds()[0];
    let world = World::parse(text).unwrap();
    let mut waypoints = world_paths()[0].clone();
    waypoints.push(waypoints[0]);
    let poses = path(&waypoints, 0.1);
    let mut r = rng(8);
    // Scans are made before counting: only the map's own work is measured.
    let scans: Vec<_> = (0..2)
        .flat_map(|_| {
            poses
                .iter()
                .map(|p| (urg_scan(&world, p, 0.01, &mut r), *p))
                .collect::<Vec<_>>()
        })
        .collect();
    let mut map = Map::new(MapParams::default(), poses[0]).unwrap();
    let (first, second) = scans.split_at(poses.len());
    for (s, p) in first {
        map.update(s, p, ScanQuality::Good).unwrap();
    }
    let points_before = map.points().len();
    let mut allocating_updates = 0;
    for (s, p) in second {
        let (rep, n) = count_allocs(|| map.update(s, p, ScanQuality::Good));
        rep.unwrap();
        if n > 0 {
            allocating_updates += 1;
        }
    }
    eprintln!(
        "second pass: {} updates, {allocating_updates} allocated; points {} -> {}",
        second.len(),
        points_before,
        map.points().len()
    );
    assert_eq!(allocating_updates, 0);
}
