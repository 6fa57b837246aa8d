//! The stage runner with real threads and channels: newest-wins hand-over,
//! overruns and degradation, end-to-end latency, faults, ordered shutdown.
//! Assertions are on counts and orderings with generous bounds, never on
//! timings, so they hold on a busy 2-core machine.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::sleep;
use std::time::{Duration, Instant};

use sweepline::pipeline::clock::Stamp;
use sweepline::pipeline::metrics::MetricsSnapshot;
use sweepline::pipeline::supervisor::{Hooks, NoHooks, StopReason, Supervisor};
use sweepline::pipeline::{
    latest, queue, Overflow, Pipeline, PipelineParams, Poll, Recv, RunState, Rx, Stage, StageCtx,
    StageFault, Tx,
};

/// The injected clock of these runs: real time.
fn wall_clock() -> sweepline::clock::SharedClock {
    std::sync::Arc::new(sweepline::clock::MonotonicClock::new())
}

fn params() -> PipelineParams {
    PipelineParams {
        poll_timeout: 0.01,
        stall_after: 5.0,
        supervise_period: 0.01,
        ..PipelineParams::default()
    }
}

/// Waits (up to a generous limit) until `cond` holds.
fn eventually(limit: Duration, cond: impl Fn() -> bool) -> bool {
    let t = Instant::now();
    while t.elapsed() < limit {
        if cond() {
            return true;
        }
        sleep(Duration::from_millis(5));
    }
    cond()
}

/// Emits the numbers 0..n as fast as it can, then reports itself done.
struct Counter {
    next: u64,
    n: u64,
    out: Tx<(u64, Stamp)>,
}

impl Stage for Counter {
    type Work = u64;
    fn wait(&mut self, _timeout: Duration) -> Poll<u64> {
        if self.next >= self.n {
            return Poll::Done;
        }
        self.next += 1;
        Poll::Work(self.next - 1)
    }
    fn process(&mut self, i: u64, _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        self.out
            .send((i, Stamp::now()))
            .map(|_| ())
            .map_err(|e| StageFault::Fatal(e.to_string()))
    }
}

/// Takes numbers slowly and records what it saw.
struct Slow {
    input: Rx<(u64, Stamp)>,
    seen: Arc<Mutex<Vec<u64>>>,
    delay: Duration,
    end_to_end: bool,
}

impl Stage for Slow {
    type Work = (u64, Stamp);
    fn wait(&mut self, timeout: Duration) -> Poll<(u64, Stamp)> {
        match self.input.recv_timeout(timeout) {
            Recv::Msg(m) => Poll::Work(m),
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }
    fn process(&mut self, (i, t0): (u64, Stamp), ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        sleep(self.delay);
        self.seen.lock().unwrap().push(i);
        if self.end_to_end {
            ctx.end_to_end(t0);
        }
        Ok(())
    }
}

#[test]
fn newest_wins_drops_the_oldest_and_counts_it() {
    let mut p = Pipeline::new(&params());
    let (tx, rx) = latest::<(u64, Stamp)>("numbers");
    p.register_edge(&tx);
    let seen = Arc::new(Mutex::new(Vec::new()));
    let n = 2000;
    p.spawn_with_budget(
        "producer",
        Duration::from_millis(10),
        Counter {
            next: 0,
            n,
            out: tx,
        },
    )
    .unwrap();
    let consumer = p
        .spawn_with_budget(
            "consumer",
            Duration::from_millis(10),
            Slow {
                input: rx,
                seen: Arc::clone(&seen),
                delay: Duration::from_millis(2),
                end_to_end: true,
            },
        )
        .unwrap();
    // The consumer ends by itself once the producer is done and the slot drained.
    assert!(eventually(Duration::from_secs(60), || consumer.state()
        == RunState::Stopped));
    let snap = p.stop();
    let seen = seen.lock().unwrap().clone();
    assert!(!seen.is_empty());
    assert!(
        seen.windows(2).all(|w| w[0] < w[1]),
        "out of order: {seen:?}"
    );
    assert_eq!(
        *seen.last().unwrap(),
        n - 1,
        "the newest message must arrive"
    );
    let e = &snap.edges[0];
    assert_eq!(e.name, "numbers");
    assert_eq!(e.sent, n);
    assert_eq!(e.received, seen.len() as u64);
    assert_eq!(
        e.dropped + e.received,
        e.sent,
        "every message is taken or counted"
    );
    assert!(
        e.dropped > 0,
        "a 2 ms consumer cannot keep up with a tight loop"
    );
    assert_eq!(e.max_depth, 1);
    let c = snap.stages.iter().find(|s| s.name == "consumer").unwrap();
    assert_eq!(c.iterations, seen.len() as u64);
    assert_eq!(c.end_to_end_q.count, seen.len() as u64);
    assert!(
        c.latency_q.p50 >= 0.002,
        "process sleeps 2 ms: {:?}",
        c.latency_q
    );
}

#[test]
fn drop_oldest_queue_between_threads_keeps_order_and_counts() {
    let mut p = Pipeline::new(&params());
    let (tx, rx) = queue::<(u64, Stamp)>("scan", 4, Overflow::DropOldest);
    p.register_edge(&tx);
    let seen = Arc::new(Mutex::new(Vec::new()));
    let n = 500;
    p.spawn_with_budget(
        "scanner",
        Duration::from_millis(1),
        Counter {
            next: 0,
            n,
            out: tx,
        },
    )
    .unwrap();
    let c = p
        .spawn_with_budget(
            "localise",
            Duration::from_millis(10),
            Slow {
                input: rx,
                seen: Arc::clone(&seen),
                delay: Duration::from_millis(1),
                end_to_end: false,
            },
        )
        .unwrap();
    assert!(eventually(Duration::from_secs(60), || c.state() == RunState::Stopped));
    let snap = p.stop();
    let seen = seen.lock().unwrap().clone();
    assert!(seen.windows(2).all(|w| w[0] < w[1]));
    // The last four are always delivered: the queue keeps the newest four.
    assert_eq!(&seen[seen.len() - 4..], &[n - 4, n - 3, n - 2, n - 1]);
    let e = &snap.edges[0];
    assert_eq!(e.dropped + e.received, n);
    assert!(e.max_depth <= 4 && e.max_depth >= 1);
}

/// One more work item while `ticks` last, then done.
fn tick(ticks: &mut u64) -> Poll<()> {
    if *ticks == 0 {
        return Poll::Done;
    }
    *ticks -= 1;
    Poll::Work(())
}

/// A stage that is too slow at full quality and fast once degraded.
struct Heavy {
    ticks: u64,
    levels: Arc<Mutex<Vec<u8>>>,
}

impl Stage for Heavy {
    type Work = ();
    fn wait(&mut self, _timeout: Duration) -> Poll<()> {
        tick(&mut self.ticks)
    }
    fn process(&mut self, _: (), ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        self.levels.lock().unwrap().push(ctx.degrade());
        // Full quality: 4 ms against a 1 ms budget. Degraded to the top level: nothing.
        if ctx.degrade() < 2 {
            sleep(Duration::from_millis(4));
        }
        Ok(())
    }
}

#[test]
fn slow_stage_overruns_degrades_and_is_counted() {
    let mut prm = params();
    prm.degrade_after = 2;
    prm.max_degrade = 2;
    prm.recover_after = 1_000_000;
    let mut p = Pipeline::new(&prm);
    let levels = Arc::new(Mutex::new(Vec::new()));
    let h = p
        .spawn_with_budget(
            "plan",
            Duration::from_millis(1),
            Heavy {
                ticks: 40,
                levels: Arc::clone(&levels),
            },
        )
        .unwrap();
    assert!(eventually(Duration::from_secs(60), || h.state() == RunState::Stopped));
    let snap = p.stop();
    let levels = levels.lock().unwrap().clone();
    let s = &snap.stages[0];
    assert_eq!(s.iterations, 40);
    // Two overruns at level 0, two at level 1: then level 2, where it is fast.
    assert_eq!(&levels[..5], &[0, 0, 1, 1, 2], "levels seen: {levels:?}");
    assert!(
        levels.windows(2).all(|w| w[0] <= w[1]),
        "never recovers: {levels:?}"
    );
    assert!(s.overruns >= 4, "{s:?}");
    assert!(
        s.overruns < 40,
        "degraded iterations should mostly fit: {}",
        s.overruns
    );
    assert_eq!(s.degrade_raises, 2);
    assert_eq!(s.degrade_peak, 2);
    assert_eq!(s.degrade_level, 2);
    assert!(s.latency_q.max >= 0.004);
    assert!(s.cpu >= 0.0 && s.busy >= 0.016);
}

/// A stage whose own work is quick and whose hand-over to the next stage
/// takes 4 ms (as when the send wakes a thread that takes the core).
struct QuickThenHandOver {
    ticks: u64,
    mark: bool,
}

impl Stage for QuickThenHandOver {
    type Work = ();
    fn wait(&mut self, _timeout: Duration) -> Poll<()> {
        tick(&mut self.ticks)
    }
    fn process(&mut self, _w: (), ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        if self.mark {
            ctx.hand_off();
        }
        sleep(Duration::from_millis(4));
        Ok(())
    }
}

#[test]
fn time_after_the_hand_off_is_not_the_stages_latency() {
    let mut counts = Vec::new();
    for mark in [false, true] {
        let mut p = Pipeline::new(&params());
        let h = p
            .spawn_with_budget(
                "scanner",
                Duration::from_millis(1),
                QuickThenHandOver { ticks: 20, mark },
            )
            .unwrap();
        assert!(eventually(Duration::from_secs(60), || h.state() == RunState::Stopped));
        let snap = p.stop();
        let s = &snap.stages[0];
        assert_eq!(s.iterations, 20);
        counts.push((s.overruns, s.latency_q.max));
    }
    let ((unmarked, unmarked_max), (marked, marked_max)) = (counts[0], counts[1]);
    assert_eq!(unmarked, 20, "every unmarked item sleeps past its budget");
    assert!(unmarked_max >= 0.004, "{unmarked_max}");
    // The marked items' own work is nothing; a busy machine may still
    // stretch one or two past 1 ms.
    assert!(marked <= 2, "marked items over budget: {marked}");
    assert!(marked_max < 0.004, "{marked_max}");
}

#[test]
fn degradation_recovers_after_enough_good_iterations() {
    let mut prm = params();
    prm.degrade_after = 1;
    prm.max_degrade = 3;
    prm.recover_after = 5;
    let mut p = Pipeline::new(&prm);
    let levels = Arc::new(Mutex::new(Vec::new()));
    // Level < 2 is slow: 0 → 1 → 2 (fast), after 5 fast ones → 1 (slow) → 2 ...
    let h = p
        .spawn_with_budget(
            "map",
            Duration::from_millis(1),
            Heavy {
                ticks: 30,
                levels: Arc::clone(&levels),
            },
        )
        .unwrap();
    assert!(eventually(Duration::from_secs(60), || h.state() == RunState::Stopped));
    p.stop();
    let levels = levels.lock().unwrap().clone();
    assert_eq!(&levels[..3], &[0, 1, 2]);
    assert!(
        levels.windows(2).any(|w| w[0] == 2 && w[1] == 1),
        "level must come back down: {levels:?}"
    );
    assert!(levels.iter().all(|&l| l <= 2));
}

/// Idles until stopped; counts its `on_stop`.
struct Idle {
    stops: Arc<AtomicUsize>,
}

impl Stage for Idle {
    type Work = ();
    fn wait(&mut self, timeout: Duration) -> Poll<()> {
        sleep(timeout);
        Poll::Idle
    }
    fn process(&mut self, _: (), _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        Ok(())
    }
    fn on_stop(&mut self) {
        self.stops.fetch_add(1, Ordering::SeqCst);
    }
}

#[test]
fn stop_joins_every_thread_and_runs_on_stop() {
    let mut p = Pipeline::new(&params());
    let stops = Arc::new(AtomicUsize::new(0));
    let names = ["scanner", "localise", "map", "plan", "control", "motor"];
    let mut healths = Vec::new();
    for n in names {
        healths.push(
            p.spawn(
                n,
                Idle {
                    stops: Arc::clone(&stops),
                },
            )
            .unwrap(),
        );
    }
    assert!(matches!(
        p.spawn(
            "map",
            Idle {
                stops: Arc::clone(&stops)
            }
        ),
        Err(sweepline::pipeline::PipelineError::Duplicate(_))
    ));
    assert!(matches!(
        p.spawn(
            "nonsense",
            Idle {
                stops: Arc::clone(&stops)
            }
        ),
        Err(sweepline::pipeline::PipelineError::NoBudget(_))
    ));
    let snap = p.stop();
    assert_eq!(stops.load(Ordering::SeqCst), names.len());
    assert!(healths.iter().all(|h| h.state() == RunState::Stopped));
    let got: Vec<&str> = snap.stages.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(got, names);
    assert_eq!(snap.stages[2].budget, params().budget.map);
}

/// Fails after a few items: transiently, then fatally (or by panicking).
struct Faulty {
    n: u32,
    panic: bool,
}

impl Stage for Faulty {
    type Work = u32;
    fn wait(&mut self, _timeout: Duration) -> Poll<u32> {
        self.n += 1;
        Poll::Work(self.n)
    }
    fn process(&mut self, i: u32, _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        match i {
            1..=3 => Err(StageFault::Transient(format!("bad item {i}"))),
            4 if self.panic => panic!("deliberate test panic"),
            4 => Err(StageFault::Fatal("device gone".into())),
            _ => Ok(()),
        }
    }
}

#[test]
fn fatal_fault_stops_the_run_with_failure() {
    for panic in [false, true] {
        let mut p = Pipeline::new(&params());
        let stops = Arc::new(AtomicUsize::new(0));
        p.spawn("scanner", Faulty { n: 0, panic }).unwrap();
        p.spawn(
            "map",
            Idle {
                stops: Arc::clone(&stops),
            },
        )
        .unwrap();
        let sup = Supervisor::new(p.params(), wall_clock());
        let out = sup.run(p, &mut NoHooks);
        assert_eq!(out.reason, StopReason::StageFailed("scanner".into()));
        assert!(out.reason.is_failure());
        let s = &out.snapshot.stages[0];
        assert!(s.failed);
        let expect_errors = if panic { 3 } else { 4 };
        assert_eq!(s.errors, expect_errors, "panic={panic}");
        assert_eq!(
            stops.load(Ordering::SeqCst),
            1,
            "the other stage was stopped"
        );
        assert!(!out.snapshot.stages[1].failed);
    }
}

/// Fails at once, dropping the sender its neighbour listens on.
struct Cause {
    _tx: crossbeam_channel::Sender<()>,
}

impl Stage for Cause {
    type Work = ();
    fn wait(&mut self, _timeout: Duration) -> Poll<()> {
        Poll::Work(())
    }
    fn process(&mut self, _: (), _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        Err(StageFault::Fatal("device gone".into()))
    }
}

/// Fails when its neighbour has gone (as a stage whose input closed).
struct Consequence {
    rx: crossbeam_channel::Receiver<()>,
}

impl Stage for Consequence {
    type Work = ();
    fn wait(&mut self, timeout: Duration) -> Poll<()> {
        match self.rx.recv_timeout(timeout) {
            Err(crossbeam_channel::RecvTimeoutError::Disconnected) => Poll::Work(()),
            _ => Poll::Idle,
        }
    }
    fn process(&mut self, _: (), _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        Err(StageFault::Fatal("the map stage is gone".into()))
    }
}

/// Two stages failed when the supervisor looks: the one that failed first
/// is named, not the first in the list (the second failed because the
/// first had gone).
#[test]
fn the_stage_that_failed_first_is_the_reason() {
    for _ in 0..5 {
        let mut p = Pipeline::new(&params());
        let (tx, rx) = crossbeam_channel::bounded(1);
        p.spawn("scanner", Consequence { rx }).unwrap();
        p.spawn("map", Cause { _tx: tx }).unwrap();
        let out = Supervisor::new(p.params(), wall_clock()).run(p, &mut NoHooks);
        assert_eq!(out.reason, StopReason::StageFailed("map".into()));
    }
}

/// Records the order of shutdown steps.
struct Recorder {
    log: Vec<String>,
    running_in_before_stop: bool,
    final_iterations: u64,
}

impl Hooks for Recorder {
    fn status(&mut self) -> String {
        "coverage 12.5 %".into()
    }
    fn before_stop(&mut self, reason: &StopReason, pipeline: &Pipeline) {
        self.running_in_before_stop = pipeline.stages().all(|s| s.state() == RunState::Running);
        self.log.push(format!("before_stop: {reason}"));
    }
    fn after_stop(&mut self, reason: &StopReason, snap: &MetricsSnapshot) {
        self.final_iterations = snap.stages.iter().map(|s| s.iterations).sum();
        self.log.push(format!("after_stop: {reason}"));
    }
}

/// Asks the supervisor to stop after `n` items.
struct Finisher {
    n: u64,
    control: sweepline::pipeline::supervisor::Control,
    done: Arc<AtomicBool>,
    count: Arc<AtomicU64>,
}

impl Stage for Finisher {
    type Work = ();
    fn wait(&mut self, timeout: Duration) -> Poll<()> {
        if self.done.load(Ordering::SeqCst) {
            sleep(timeout);
            return Poll::Idle;
        }
        Poll::Work(())
    }
    fn process(&mut self, _: (), _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        if self.count.fetch_add(1, Ordering::SeqCst) + 1 == self.n {
            self.done.store(true, Ordering::SeqCst);
            self.control.stop("coverage complete");
        }
        Ok(())
    }
}

#[test]
fn stop_request_runs_the_hooks_in_order() {
    let mut p = Pipeline::new(&params());
    let sup = Supervisor::new(p.params(), wall_clock());
    let count = Arc::new(AtomicU64::new(0));
    p.spawn(
        "plan",
        Finisher {
            n: 100,
            control: sup.control(),
            done: Arc::new(AtomicBool::new(false)),
            count: Arc::clone(&count),
        },
    )
    .unwrap();
    let stops = Arc::new(AtomicUsize::new(0));
    p.spawn(
        "control",
        Idle {
            stops: Arc::clone(&stops),
        },
    )
    .unwrap();
    let mut rec = Recorder {
        log: Vec::new(),
        running_in_before_stop: false,
        final_iterations: 0,
    };
    let out = sup.run(p, &mut rec);
    assert_eq!(
        out.reason,
        StopReason::Requested("coverage complete".into())
    );
    assert!(!out.reason.is_failure());
    assert_eq!(
        rec.log,
        vec![
            "before_stop: stop requested: coverage complete".to_string(),
            "after_stop: stop requested: coverage complete".to_string()
        ]
    );
    assert!(
        rec.running_in_before_stop,
        "before_stop runs while stages are alive"
    );
    assert_eq!(rec.final_iterations, 100);
    assert_eq!(stops.load(Ordering::SeqCst), 1);
}

/// A three-stage chain carrying `t0`: every message's end-to-end latency is
/// recorded once, by the last stage.
#[test]
fn end_to_end_latency_is_carried_through_a_chain() {
    struct Relay {
        input: Rx<(u64, Stamp)>,
        out: Tx<(u64, Stamp)>,
    }
    impl Stage for Relay {
        type Work = (u64, Stamp);
        fn wait(&mut self, timeout: Duration) -> Poll<(u64, Stamp)> {
            match self.input.recv_timeout(timeout) {
                Recv::Msg(m) => Poll::Work(m),
                Recv::Empty => Poll::Idle,
                Recv::Closed => Poll::Done,
            }
        }
        fn process(&mut self, m: (u64, Stamp), ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
            ctx.note_age(m.1);
            self.out
                .send(m)
                .map(|_| ())
                .map_err(|e| StageFault::Fatal(e.to_string()))
        }
    }
    let mut p = Pipeline::new(&params());
    let (tx1, rx1) = queue::<(u64, Stamp)>("scan", 64, Overflow::Block);
    let (tx2, rx2) = queue::<(u64, Stamp)>("pose", 64, Overflow::Block);
    p.register_edge(&tx1);
    p.register_edge(&tx2);
    let seen = Arc::new(Mutex::new(Vec::new()));
    p.spawn(
        "scanner",
        Counter {
            next: 0,
            n: 300,
            out: tx1,
        },
    )
    .unwrap();
    p.spawn(
        "localise",
        Relay {
            input: rx1,
            out: tx2,
        },
    )
    .unwrap();
    let last = p
        .spawn(
            "control",
            Slow {
                input: rx2,
                seen: Arc::clone(&seen),
                delay: Duration::ZERO,
                end_to_end: true,
            },
        )
        .unwrap();
    assert!(eventually(Duration::from_secs(60), || last.state()
        == RunState::Stopped));
    let snap = p.stop();
    assert_eq!(
        seen.lock().unwrap().len(),
        300,
        "blocking edges lose nothing"
    );
    assert_eq!(snap.dropped(), 0);
    assert_eq!(snap.end_to_end().count(), 300);
    assert_eq!(snap.stages[2].end_to_end_q.count, 300);
    assert_eq!(snap.stages[1].end_to_end_q.count, 0);
    assert!(snap.stages[2].end_to_end_q.p99 > 0.0);
    assert_eq!(snap.late(), 0, "nothing is 0.3 s old here");
}

/// Stuck inside `process` far longer than any shutdown may take.
struct Stuck;

impl Stage for Stuck {
    type Work = ();
    fn wait(&mut self, _timeout: Duration) -> Poll<()> {
        Poll::Work(())
    }
    fn process(&mut self, _: (), _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        sleep(Duration::from_secs(60));
        Ok(())
    }
}

#[test]
fn shutdown_leaves_a_stuck_stage_behind_after_the_stop_timeout() {
    let mut prm = params();
    prm.stop_timeout = 0.2;
    let mut p = Pipeline::new(&prm);
    let stops = Arc::new(AtomicUsize::new(0));
    p.spawn("map", Stuck).unwrap();
    p.spawn(
        "control",
        Idle {
            stops: Arc::clone(&stops),
        },
    )
    .unwrap();
    sleep(Duration::from_millis(50));
    let t = Instant::now();
    let snap = p.stop();
    assert!(
        t.elapsed() < Duration::from_secs(30),
        "stop must not wait for the 60 s item"
    );
    assert_eq!(
        stops.load(Ordering::SeqCst),
        1,
        "the healthy stage stopped in order"
    );
    assert_eq!(
        snap.stages[0].iterations, 0,
        "the stuck item never finished"
    );
    assert!(!snap.stages[1].failed);
}
