//! CPU cost of the scanner stage in real time: the driver thread streaming a
//! 10 Hz URG-04LX over a pty for 3 s, its CPU time read from
//! /proc/self/task/*/schedstat (the thread named `scanner`).

mod urg_support;

use std::sync::Arc;
use std::time::{Duration, Instant};

use sweepline::serial::DeviceConnector;
use sweepline::sim::urg_emu::{Emulator, EmulatorConfig, RectRoom};
use sweepline::urg::{MonotonicClock, UrgDriver};

/// CPU seconds used so far by the thread named `name` (nanosecond
/// resolution, from /proc/self/task/TID/schedstat).
fn thread_cpu(name: &str) -> Option<f64> {
    for e in std::fs::read_dir("/proc/self/task").ok()?.flatten() {
        let comm = std::fs::read_to_string(e.path().join("comm")).unwrap_or_default();
        if comm.trim() != name {
            continue;
        }
        let stat = std::fs::read_to_string(e.path().join("schedstat")).ok()?;
        let ns: f64 = stat.split_whitespace().next()?.parse().ok()?;
        return Some(ns * 1e-9);
    }
    None
}

#[test]
fn scanner_thread_uses_little_cpu_at_10_hz() {
    let dir = urg_support::temp_dir("cpu");
    let link = dir.join("urg");
    let clock = Arc::new(MonotonicClock::new());
    let cfg = EmulatorConfig {
        link: Some(link.clone()),
        ..EmulatorConfig::default()
    };
    let emu = Emulator::spawn(cfg, Box::new(RectRoom::bench(1)), clock.clone()).unwrap();
    let driver = UrgDriver::start(
        Box::new(DeviceConnector::new(&link)),
        urg_support::test_params(),
        clock,
    )
    .unwrap();
    // Let the open and clock sync finish first.
    driver
        .scans()
        .recv_timeout(Duration::from_secs(5))
        .expect("first scan");
    let cpu0 = thread_cpu("scanner").expect("scanner thread");
    let t0 = Instant::now();
    let mut n = 0;
    while t0.elapsed() < Duration::from_secs(3) {
        if driver.scans().recv_timeout(Duration::from_secs(1)).is_ok() {
            n += 1;
        }
    }
    let cpu = thread_cpu("scanner").unwrap() - cpu0;
    let wall = t0.elapsed().as_secs_f64();
    driver.shutdown();
    drop(emu);
    let _ = std::fs::remove_dir_all(&dir);
    let share = cpu / wall;
    println!(
        "scanner thread: {n} scans in {wall:.2} s, {:.2} ms CPU = {:.3} % of one core, {:.0} us per scan",
        cpu * 1e3,
        share * 100.0,
        cpu * 1e6 / f64::from(n.max(1))
    );
    assert!((28..=31).contains(&n), "{n} scans in {wall:.2} s");
    assert!(
        share < 0.05,
        "scanner thread used {:.1} % of a core",
        share * 100.0
    );
}
