//! The driver survives EINTR: every thread of the process is hit by a signal
//! (handler installed without SA_RESTART) every millisecond while scans
//! stream over the pty; nothing is lost, nothing reconnects.

mod urg_support;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use urg_support::*;

static HANDLED: AtomicU64 = AtomicU64::new(0);

extern "C" fn on_signal(_: libc::c_int) {
    HANDLED.fetch_add(1, Ordering::Relaxed);
}

fn install_handler() {
    // SAFETY: a zeroed sigaction with a plain handler and no SA_RESTART, so
    // blocking calls fail with EINTR instead of being restarted.
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as usize;
        sa.sa_flags = 0;
        libc::sigemptyset(&mut sa.sa_mask);
        assert_eq!(libc::sigaction(libc::SIGUSR1, &sa, std::ptr::null_mut()), 0);
    }
}

fn signal_every_thread() -> usize {
    let pid = std::process::id() as libc::pid_t;
    let mut n = 0;
    if let Ok(dir) = std::fs::read_dir("/proc/self/task") {
        for e in dir.flatten() {
            if let Ok(tid) = e.file_name().to_string_lossy().parse::<libc::pid_t>() {
                // SAFETY: tgkill on our own process's threads.
                unsafe {
                    libc::syscall(libc::SYS_tgkill, pid, tid, libc::SIGUSR1);
                }
                n += 1;
            }
        }
    }
    n
}

#[test]
fn signals_storm_loses_nothing() {
    install_handler();
    let rig = rig("eintr", "", false, test_params());
    let stop = Arc::new(AtomicBool::new(false));
    let sent = Arc::new(AtomicU64::new(0));
    let (st, se) = (stop.clone(), sent.clone());
    let storm = std::thread::spawn(move || {
        while !st.load(Ordering::Relaxed) {
            se.fetch_add(signal_every_thread() as u64, Ordering::Relaxed);
            std::thread::sleep(Duration::from_millis(1));
        }
    });
    let got = rig.collect(40, 15.0);
    stop.store(true, Ordering::Relaxed);
    storm.join().unwrap();
    let h = rig.driver().health().snapshot();
    let log = rig.finish();
    assert_eq!(got.len(), 40, "{h}");
    check_no_loss(&log, &got);
    assert!(
        HANDLED.load(Ordering::Relaxed) > 1000,
        "signals handled: {}",
        HANDLED.load(Ordering::Relaxed)
    );
    assert_eq!(h.reconnects, 0, "{h}");
    assert_eq!(h.resets, 0, "{h}");
    assert_eq!(h.discarded_scans, 0, "{h}");
}
