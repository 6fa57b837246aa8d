//! The supervisor against a real `NOTIFY_SOCKET` (a unix datagram socket in a
//! temp folder, as systemd would provide): `READY=1` when told, `WATCHDOG=1`
//! only while every stage is alive, `STATUS=` with the daemon's text and the
//! health, and SIGTERM → ordered shutdown with `STOPPING=1`.
//!
//! One test in its own binary: it sets process-wide environment variables and
//! raises a real signal.

use std::os::unix::net::UnixDatagram;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::sleep;
use std::time::{Duration, Instant};

use sweepline::pipeline::signals::SignalForwarder;
use sweepline::pipeline::supervisor::{Hooks, StopReason, Supervisor};
use sweepline::pipeline::{Pipeline, PipelineParams, Poll, Stage, StageCtx, StageFault};

/// The injected clock of these runs: real time.
fn wall_clock() -> sweepline::clock::SharedClock {
    std::sync::Arc::new(sweepline::clock::MonotonicClock::new())
}

/// Ticks every 10 ms; stalls inside `process` for as long as it is told.
struct Stallable {
    stall_ms: Arc<AtomicU64>,
}

impl Stage for Stallable {
    type Work = ();
    fn wait(&mut self, timeout: Duration) -> Poll<()> {
        sleep(timeout.min(Duration::from_millis(10)));
        Poll::Work(())
    }
    fn process(&mut self, _: (), _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        let ms = self.stall_ms.swap(0, Ordering::SeqCst);
        if ms > 0 {
            sleep(Duration::from_millis(ms));
        }
        Ok(())
    }
}

struct Status;

impl Hooks for Status {
    fn status(&mut self) -> String {
        "coverage 42.0 %".into()
    }
}

/// Every datagram received within `window`, with when it was received.
fn collect_timed(sock: &UnixDatagram, window: Duration) -> Vec<(Instant, String)> {
    let mut out = Vec::new();
    let mut buf = [0u8; 4096];
    let t = Instant::now();
    while t.elapsed() < window {
        if let Ok(n) = sock.recv(&mut buf) {
            out.push((
                Instant::now(),
                String::from_utf8_lossy(&buf[..n]).trim_end().to_string(),
            ));
        }
    }
    out
}

/// Every datagram received within `window`.
fn collect(sock: &UnixDatagram, window: Duration) -> Vec<String> {
    collect_timed(sock, window)
        .into_iter()
        .map(|(_, s)| s)
        .collect()
}

/// Reads datagrams until one satisfies `pred` (or `limit` passes).
fn wait_for(sock: &UnixDatagram, limit: Duration, pred: impl Fn(&str) -> bool) -> Option<String> {
    let mut buf = [0u8; 4096];
    let t = Instant::now();
    while t.elapsed() < limit {
        if let Ok(n) = sock.recv(&mut buf) {
            let s = String::from_utf8_lossy(&buf[..n]).trim_end().to_string();
            if pred(&s) {
                return Some(s);
            }
        }
    }
    None
}

#[test]
fn watchdog_is_withheld_while_a_stage_stalls() {
    let dir = std::env::temp_dir().join(format!("sweepline-notify-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("notify.sock");
    let sock = UnixDatagram::bind(&path).unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(20)))
        .unwrap();
    // What systemd sets for a Type=notify unit with WatchdogSec=0.2.
    std::env::set_var("NOTIFY_SOCKET", &path);
    std::env::set_var("WATCHDOG_USEC", "200000");
    std::env::set_var("WATCHDOG_PID", std::process::id().to_string());

    let params = PipelineParams {
        poll_timeout: 0.02,
        stall_after: 0.3,
        supervise_period: 0.02,
        ..PipelineParams::default()
    };
    let mut p = Pipeline::new(&params);
    let stall_ms = Arc::new(AtomicU64::new(0));
    p.spawn(
        "scanner",
        Stallable {
            stall_ms: Arc::new(AtomicU64::new(0)),
        },
    )
    .unwrap();
    p.spawn(
        "localise",
        Stallable {
            stall_ms: Arc::clone(&stall_ms),
        },
    )
    .unwrap();
    let sup = Supervisor::new(&params, wall_clock());
    assert_eq!(sup.watchdog(), Some(Duration::from_millis(200)));
    let control = sup.control();
    let signals = SignalForwarder::install(sup.control()).unwrap();
    let runner = std::thread::spawn(move || sup.run(p, &mut Status));

    control.ready();
    assert!(
        wait_for(&sock, Duration::from_secs(20), |s| s == "READY=1").is_some(),
        "READY=1 never arrived"
    );
    let healthy = collect(&sock, Duration::from_millis(500));
    let pets = healthy.iter().filter(|s| *s == "WATCHDOG=1").count();
    assert!(pets >= 2, "a healthy pipeline is petted: {healthy:?}");
    let status = wait_for(&sock, Duration::from_secs(10), |s| s.starts_with("STATUS="))
        .expect("STATUS= is sent every second");
    assert_eq!(status, "STATUS=coverage 42.0 %; health ok");

    // Stall localise for 3.5 s. After stall_after (0.3 s) plus slack, no pet
    // may arrive while it is still stuck.
    stall_ms.store(3500, Ordering::SeqCst);
    let t_stall = Instant::now();
    sleep(Duration::from_millis(600));
    let _ = collect(&sock, Duration::from_millis(1)); // flush the 0.3 s grace period
                                                      // The stall lasts at least 3.5 s from `t_stall` (sleep never returns early),
                                                      // so only datagrams received before that count, however slow the machine.
    let stall_end = t_stall + Duration::from_millis(3500);
    let during: Vec<String> = collect_timed(&sock, Duration::from_millis(1800))
        .into_iter()
        .filter(|(t, _)| *t < stall_end)
        .map(|(_, s)| s)
        .collect();
    assert!(
        during.iter().all(|s| s != "WATCHDOG=1"),
        "watchdog petted while localise was stalled: {during:?}"
    );
    assert!(
        during
            .iter()
            .any(|s| s == "STATUS=coverage 42.0 %; health stalled: localise"),
        "status names the stalled stage: {during:?}"
    );
    // Once the stall ends the pets resume.
    assert!(
        wait_for(&sock, Duration::from_secs(20), |s| s == "WATCHDOG=1").is_some(),
        "watchdog never resumed after the stall"
    );

    // SIGTERM: ordered shutdown, STOPPING=1.
    // SAFETY: raise() with a handled signal; signal-hook installed the handler.
    assert_eq!(unsafe { libc::raise(libc::SIGTERM) }, 0);
    let out = runner.join().unwrap();
    assert_eq!(out.reason, StopReason::Signal(libc::SIGTERM));
    assert!(!out.reason.is_failure());
    assert!(
        wait_for(&sock, Duration::from_secs(5), |s| s == "STOPPING=1").is_some(),
        "STOPPING=1 missing"
    );
    assert!(out.snapshot.supervisor.watchdog_pets >= 2);
    assert!(out.snapshot.supervisor.stall_checks >= 1);
    assert_eq!(out.snapshot.supervisor.notify_errors, 0);
    let loc = out
        .snapshot
        .stages
        .iter()
        .find(|s| s.name == "localise")
        .unwrap();
    assert!(loc.latency_q.max >= 3.5, "the stall shows as max latency");
    assert!(loc.overruns >= 1);
    drop(signals);
    let _ = std::fs::remove_dir_all(&dir);
}
