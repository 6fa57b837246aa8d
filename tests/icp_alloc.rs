//! Zero heap allocations per match in steady state, counted by a global
//! allocator. Its own test binary (the allocator is process-wide) with a
//! single test, so no other test allocates concurrently.
//!
//! What is proven: once buffers have grown, (1) `Matcher::match_points` and
//! `Matcher::match_scan` against a built `Reference` allocate nothing; (2) a
//! `Tracker` step that does not add a keyframe allocates nothing, including
//! the scan-to-scan match of `scan_fusion` and the rebuild of its
//! bearing-indexed reference from every scan. Adding a
//! keyframe rebuilds the k-d tree, and kiddo's tree owns fresh storage: that
//! step allocates (the tree, plus the keyframe's own buffers until the window
//! is full and they start being recycled), which is measured and bounded here.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use sweepline::geom::{pose, IPoint};
use sweepline::icp::synth::{cast_seeded, cast_world, ScanSpec, Wall};
use sweepline::icp::{IcpParams, Matcher, Outcome, Reference, Tracker};
use sweepline::scan::{Beam, LaserScan};

struct Counting;

static ALLOCS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocs() -> usize {
    ALLOCS.load(Ordering::Relaxed)
}

fn scene() -> Vec<Wall> {
    vec![
        Wall::new(0.0, 0.0, 6.0, 0.0, 0.4),
        Wall::new(6.0, 0.0, 6.0, 2.5, 0.9),
        Wall::new(6.0, 2.5, 3.5, 2.5, 0.4),
        Wall::new(3.5, 2.5, 3.5, 4.0, 0.4),
        Wall::new(3.5, 4.0, 0.0, 4.0, 0.7),
        Wall::new(0.0, 4.0, 0.0, 0.0, 0.4),
    ]
}

#[test]
fn steady_state_matching_does_not_allocate() {
    let walls = scene();
    let params = IcpParams {
        intensity_weight: 0.5,
        ..IcpParams::default()
    };
    let at = pose(2.0, 1.5, 0.2);
    let refpts = cast_world(&walls, &at, ScanSpec::default().seed);
    let mut reference = Reference::new();
    reference.rebuild_ordered(&refpts, &params).unwrap();
    let scans: Vec<Vec<IPoint>> = (0..5)
        .map(|k| {
            cast_seeded(
                &walls,
                &pose(2.0 + 0.02 * k as f64, 1.5, 0.2 + 0.01 * k as f64),
                k,
            )
        })
        .collect();
    let mut laser = LaserScan::default();
    for i in 0..682 {
        let a = -2.0 + 4.0 * i as f64 / 681.0;
        laser
            .beams
            .push(Beam {
                angle: a,
                range: 2.0 + 0.3 * (a * 3.0).sin(),
                intensity: 0.5,
                valid: i % 5 != 0,
            })
            .unwrap();
    }
    let mut m = Matcher::new(params.clone()).unwrap();
    // Warm-up: buffers grow, kiddo's per-thread query scratch is set up.
    for s in &scans {
        m.match_points(&reference, s, &at).unwrap();
    }
    let _ = m.match_scan(&reference, &laser, &at);

    let before = allocs();
    let mut ok = 0;
    for round in 0..20 {
        for s in &scans {
            let guess = at * pose(0.01 * (round % 3) as f64, -0.01, 0.005);
            if m.match_points(&reference, s, &guess).is_ok() {
                ok += 1;
            }
        }
        let _ = m.match_scan(&reference, &laser, &at);
    }
    let during = allocs() - before;
    assert_eq!(ok, 100);
    assert_eq!(during, 0, "{during} allocations in 120 matches");

    // Tracker: steps without a new keyframe allocate nothing.
    assert!(
        params.scan_fusion > 0.0,
        "the default fuses scan-to-scan matches"
    );
    let mut t = Tracker::new(params, at).unwrap();
    let still = &scans[0];
    assert!(matches!(t.step(still, Some(&at)).outcome, Outcome::First));
    for _ in 0..3 {
        t.step(still, Some(&at));
    }
    let before = allocs();
    for _ in 0..50 {
        let s = t.step(still, Some(&at));
        assert!(
            matches!(s.outcome, Outcome::Matched(_)) && !s.keyframe,
            "{:?}",
            s.outcome
        );
    }
    assert_eq!(
        allocs() - before,
        0,
        "tracker steps without a keyframe allocated"
    );

    // A keyframe step rebuilds the tree (and, before the window is full,
    // grows a new keyframe's buffers): a bounded number of allocations.
    let moved = pose(2.5, 1.5, 0.2);
    let far = cast_seeded(&walls, &moved, 42);
    let before = allocs();
    let s = t.step(&far, Some(&moved));
    let kf_allocs = allocs() - before;
    assert!(s.keyframe, "{:?}", s.outcome);
    assert!(
        kf_allocs > 0 && kf_allocs < 64,
        "{kf_allocs} allocations in a keyframe step"
    );
    eprintln!("keyframe step: {kf_allocs} allocations (k-d tree rebuild, new keyframe buffers)");
}
