//! The driver's scan path allocates nothing in steady state: reading bytes,
//! framing, checksums, decoding, unwrapping the clock, stamping, filling the
//! `LaserScan` and the typed readings, and handing the scan to the sink.
//! Counted with a global allocator on the driver's thread, the session
//! running lock-step over the in-process link to the emulated URG-04LX.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use sweepline::sim::urg_emu::{EmuLog, Faults, Model, ModelSpec, RectRoom, Sensor, SensorLink};
use sweepline::urg::{ManualClock, UrgHealth, UrgParams, UrgScan, UrgSession};

struct Counting;

thread_local! {
    static COUNT_HERE: Cell<bool> = const { Cell::new(false) };
}
static ALLOCS: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if COUNT_HERE.with(|c| c.get()) {
            ALLOCS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        if COUNT_HERE.with(|c| c.get()) {
            ALLOCS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn streaming_scans_allocates_nothing() {
    let clock = Arc::new(ManualClock::new(0.0));
    let log = Arc::new(Mutex::new(EmuLog::default()));
    let sensor = Sensor::new(
        ModelSpec::of(Model::Urg04lx),
        Faults::default(),
        false,
        Box::new(RectRoom::bench(9)),
        9,
        log,
        0.0,
    );
    let link = SensorLink::new(sensor, clock.clone());
    let latest = Arc::new(Mutex::new(Box::<UrgScan>::default()));
    let seen = Arc::new(AtomicU64::new(0));
    let (l2, s2) = (latest.clone(), seen.clone());
    let sink = Box::new(move |s: &UrgScan| {
        if let Ok(mut g) = l2.lock() {
            g.as_mut().clone_from(s);
        }
        s2.fetch_add(1, Ordering::Relaxed);
    });
    let mut session = UrgSession::open(
        Box::new(link),
        UrgParams::default(),
        clock.clone(),
        Arc::new(UrgHealth::default()),
        Arc::new(AtomicBool::new(false)),
        None,
        sink,
    )
    .unwrap();
    session.start_stream().unwrap();
    // The open (QT, PP, VV, II, TM0, 10 × TM1, TM2, MD) takes about 0.6 s:
    // the sensor answers once per revolution, TM1 and TM2 within 2 ms.
    let opened = clock_now(&clock);
    assert!((0.4..1.0).contains(&opened), "{opened}");
    for _ in 0..20 {
        session.next_scan().unwrap();
    }
    COUNT_HERE.with(|c| c.set(true));
    for _ in 0..200 {
        session.next_scan().unwrap();
    }
    COUNT_HERE.with(|c| c.set(false));
    assert_eq!(seen.load(Ordering::Relaxed), 220);
    assert_eq!(
        ALLOCS.load(Ordering::Relaxed),
        0,
        "allocations on the scan path"
    );
    let g = latest.lock().unwrap();
    assert_eq!(g.scan.beams.len(), 682);
    // Lock-step time: 220 scans of 100 ms after the open.
    let streamed = clock_now(&clock) - opened;
    assert!((streamed - 22.0).abs() < 0.5, "{streamed}");
}

fn clock_now(c: &ManualClock) -> f64 {
    use sweepline::urg::Clock;
    c.now()
}
