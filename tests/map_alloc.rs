//! The scan path of the map allocates nothing in steady state: after one pass
//! around the room (which sizes every buffer), a second pass of updates,
//! snapshot publications included, makes no heap allocation. Counted with a
//! global allocator that counts only on the thread that armed it.

mod map_support;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use map_support::*;
use sweepline::map::{Map, MapParams, ScanQuality};
use sweepline::sim::world::World;

struct Counting;

static ALLOCS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if ARMED.with(|a| a.get()) {
            ALLOCS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if ARMED.with(|a| a.get()) {
            ALLOCS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn second_pass_allocates_nothing() {
    // The counter works: an armed allocation is seen.
    ARMED.with(|a| a.set(true));
    let v: Vec<u64> = Vec::with_capacity(16);
    ARMED.with(|a| a.set(false));
    assert_eq!(ALLOCS.load(Ordering::Relaxed), 1);
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
        ALLOCS.store(0, Ordering::Relaxed);
        ARMED.with(|a| a.set(true));
        let rep = map.update(s, p, ScanQuality::Good);
        ARMED.with(|a| a.set(false));
        let n = ALLOCS.load(Ordering::Relaxed);
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
