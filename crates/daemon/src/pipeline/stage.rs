//! The stage runner: one named thread per stage, a loop that waits for work
//! with a timeout, measures each work item's latency and the thread's CPU
//! time, counts overruns against the stage budget, tells the stage how much to
//! degrade, and beats a heartbeat the supervisor watches.
//!
//! A stage is anything implementing [`Stage`]: `wait` blocks (at most the poll
//! timeout) on its inputs (edges, a serial port, a timer), `process` does the
//! work. Only `process` counts against the budget; the heartbeat is refreshed
//! after every return from `wait`, so an idle stage is alive and a stage stuck
//! inside `process` (or inside a `wait` that ignores its timeout) is stalled.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::clock::{thread_cpu_time, Stamp};
use super::metrics::{LatencyHistogram, Quantiles, StageMetrics};

/// What [`Stage::wait`] found.
#[derive(Debug)]
pub enum Poll<W> {
    /// A unit of work to process.
    Work(W),
    /// Nothing within the timeout: loop again (heartbeat still beats).
    Idle,
    /// The stage's inputs are closed for good: the stage ends normally.
    Done,
}

/// How a stage's `process` failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum StageFault {
    /// A problem with this item only (bad scan, lost reply): counted, logged
    /// (rate-limited), the stage carries on.
    #[error("{0}")]
    Transient(String),
    /// The stage cannot go on (device gone for good, broken invariant): the
    /// thread ends and the supervisor shuts the daemon down with an error.
    #[error("{0}")]
    Fatal(String),
}

/// One stage of the pipeline: its inputs, its work, its outputs. Implemented
/// by the scanner, localise, map, plan, control and motor stages.
pub trait Stage: Send + 'static {
    /// One unit of work (a scan, a pose, a timer tick...).
    type Work;

    /// Waits at most `timeout` for the next unit of work. Must honour the
    /// timeout: the runner checks for shutdown and beats the heartbeat between
    /// calls.
    fn wait(&mut self, timeout: Duration) -> Poll<Self::Work>;

    /// Processes one unit of work; `ctx` gives the degradation level and
    /// records lateness and end-to-end latency.
    fn process(&mut self, work: Self::Work, ctx: &mut StageCtx<'_>) -> Result<(), StageFault>;

    /// Called once in the stage's thread when it stops (release a port, send a
    /// final message).
    fn on_stop(&mut self) {}
}

/// Run state of a stage thread.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunState {
    /// The loop is running.
    Running,
    /// Ended normally (stop requested or inputs closed).
    Stopped,
    /// Ended on a fatal fault or a panic.
    Failed,
}

const RUNNING: u8 = 0;
const STOPPED: u8 = 1;
const FAILED: u8 = 2;

/// How often a stage copies its histograms to where the supervisor can read them.
const PUBLISH_EVERY: Duration = Duration::from_millis(200);

/// Degradation policy and budget of one stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct StageBudget {
    /// Longest a work item may take.
    pub budget: Duration,
    /// Consecutive overruns that raise the level by one.
    pub degrade_after: u32,
    /// Consecutive in-budget items that lower it by one.
    pub recover_after: u32,
    /// Highest level.
    pub max_degrade: u8,
    /// Inputs older than this are late.
    pub late_after: Duration,
    /// Longest wait before the loop checks for shutdown.
    pub poll_timeout: Duration,
}

/// Histograms a stage publishes for the supervisor (copied, never shared live).
#[derive(Debug, Default)]
pub(crate) struct Published {
    pub latency: LatencyHistogram,
    pub end_to_end: LatencyHistogram,
}

/// The stage's live counters, shared with the supervisor (atomics only).
#[derive(Debug)]
pub struct StageHealth {
    name: String,
    budget: Duration,
    heartbeat: AtomicU64,
    iterations: AtomicU64,
    overruns: AtomicU64,
    degrade_raises: AtomicU64,
    degrade_level: AtomicU8,
    degrade_peak: AtomicU8,
    late: AtomicU64,
    errors: AtomicU64,
    cpu_ns: AtomicU64,
    busy_ns: AtomicU64,
    state: AtomicU8,
    /// When the stage failed (a [`Stamp`]; `u64::MAX` while it has not):
    /// the first failure is the cause, later ones its consequences.
    failed_at: AtomicU64,
    pub(crate) published: Mutex<Published>,
}

impl StageHealth {
    /// The health record of stage `name`, whose iterations have a CPU
    /// budget of `budget` each.
    pub fn new(name: &str, budget: Duration) -> Self {
        Self {
            name: name.to_string(),
            budget,
            heartbeat: AtomicU64::new(Stamp::now().0),
            iterations: AtomicU64::new(0),
            overruns: AtomicU64::new(0),
            degrade_raises: AtomicU64::new(0),
            degrade_level: AtomicU8::new(0),
            degrade_peak: AtomicU8::new(0),
            late: AtomicU64::new(0),
            errors: AtomicU64::new(0),
            cpu_ns: AtomicU64::new(0),
            busy_ns: AtomicU64::new(0),
            state: AtomicU8::new(RUNNING),
            failed_at: AtomicU64::new(u64::MAX),
            published: Mutex::new(Published::default()),
        }
    }

    /// Notes the time of the stage's failure (the first one counts).
    fn note_failure(&self) {
        let _ = self.failed_at.compare_exchange(
            u64::MAX,
            Stamp::now().0,
            Ordering::AcqRel,
            Ordering::Acquire,
        );
    }

    /// Stage name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// When the loop last came back from `wait` or finished an item.
    pub fn heartbeat(&self) -> Stamp {
        Stamp(self.heartbeat.load(Ordering::Relaxed))
    }

    /// Items processed.
    pub fn iterations(&self) -> u64 {
        self.iterations.load(Ordering::Relaxed)
    }

    /// Items over budget.
    pub fn overruns(&self) -> u64 {
        self.overruns.load(Ordering::Relaxed)
    }

    /// Current degradation level.
    pub fn degrade_level(&self) -> u8 {
        self.degrade_level.load(Ordering::Relaxed)
    }

    /// Run state.
    pub fn state(&self) -> RunState {
        match self.state.load(Ordering::Acquire) {
            RUNNING => RunState::Running,
            STOPPED => RunState::Stopped,
            _ => RunState::Failed,
        }
    }

    /// When the stage failed; `None` while it has not.
    pub(crate) fn failed_at(&self) -> Option<Stamp> {
        let t = self.failed_at.load(Ordering::Acquire);
        (t != u64::MAX).then_some(Stamp(t))
    }

    /// Whether the stage is running and its heartbeat is younger than `stall_after`.
    pub(crate) fn is_fresh(&self, now: Stamp, stall_after: Duration) -> bool {
        self.state() == RunState::Running && now.since(self.heartbeat()) <= stall_after
    }

    /// The counters and (last published) histograms as a snapshot entry.
    pub fn metrics(&self) -> StageMetrics {
        let (latency, end_to_end, latency_q, end_to_end_q) = match self.published.lock() {
            Ok(p) => (
                p.latency.to_buckets(),
                p.end_to_end.to_buckets(),
                Quantiles::of(&p.latency),
                Quantiles::of(&p.end_to_end),
            ),
            Err(_) => Default::default(),
        };
        StageMetrics {
            name: self.name.clone(),
            budget: self.budget.as_secs_f64(),
            iterations: self.iterations(),
            overruns: self.overruns(),
            degrade_raises: self.degrade_raises.load(Ordering::Relaxed),
            degrade_level: self.degrade_level(),
            degrade_peak: self.degrade_peak.load(Ordering::Relaxed),
            late: self.late.load(Ordering::Relaxed),
            errors: self.errors.load(Ordering::Relaxed),
            cpu: self.cpu_ns.load(Ordering::Relaxed) as f64 * 1e-9,
            busy: self.busy_ns.load(Ordering::Relaxed) as f64 * 1e-9,
            failed: self.state() == RunState::Failed,
            latency_q,
            end_to_end_q,
            latency,
            end_to_end,
        }
    }
}

/// What a stage's `process` can see and report for the current item.
pub struct StageCtx<'a> {
    started: Stamp,
    degrade: u8,
    late_after: Duration,
    late: u32,
    end_to_end: &'a mut LatencyHistogram,
    handed_off: Option<Stamp>,
}

impl<'a> StageCtx<'a> {
    /// A context for driving a stage by hand, outside the pipeline (a
    /// replay): full quality, nothing ever late, latencies into
    /// `end_to_end`.
    pub(crate) fn offline(end_to_end: &'a mut LatencyHistogram) -> Self {
        Self {
            started: Stamp::now(),
            degrade: 0,
            late_after: Duration::MAX,
            late: 0,
            end_to_end,
            handed_off: None,
        }
    }
}

impl StageCtx<'_> {
    /// Degradation level the stage should work at: 0 = full quality; each
    /// level up means "do less" (fewer ICP iterations, rate-limited
    /// decomposition...), as the stage defines.
    pub fn degrade(&self) -> u8 {
        self.degrade
    }

    /// When this item's processing started.
    pub fn started(&self) -> Stamp {
        self.started
    }

    /// Checks the age of an input stamped `t0`: counts it late (and returns
    /// true) when it is older than `pipeline.late_after`.
    pub fn note_age(&mut self, t0: Stamp) -> bool {
        let late = self.started.since(t0) > self.late_after;
        if late {
            self.late += 1;
        }
        late
    }

    /// Marks the end of this item's own work, just before its results are
    /// handed to the next stages: the item's latency (against the budget)
    /// ends here. A send wakes the receiving thread, which may take this
    /// core at once; the time until this thread runs again is the next
    /// stage's work, not this one's. The first mark counts.
    pub fn hand_off(&mut self) {
        self.handed_off.get_or_insert_with(Stamp::now);
    }

    /// Records the end-to-end latency from `t0` (a scan's last byte) to now:
    /// called by the stage that emits the wheel command the scan produced.
    pub fn end_to_end(&mut self, t0: Stamp) {
        self.end_to_end.record(Stamp::now().since(t0));
    }
}

/// Rate limit for error logs: the first few, then every this many.
const LOG_EVERY: u64 = 100;

/// The body of a stage thread; returns when `stop` is set, the stage is done,
/// or it fails.
pub(crate) fn run_stage<S: Stage>(
    mut stage: S,
    health: Arc<StageHealth>,
    budget: StageBudget,
    stop: Arc<AtomicBool>,
) {
    let mut latency = LatencyHistogram::new();
    let mut end_to_end = LatencyHistogram::new();
    let mut level: u8 = 0;
    let mut over_run_len: u32 = 0;
    let mut ok_run_len: u32 = 0;
    let mut last_publish = Stamp::now();
    let cpu0 = thread_cpu_time();
    let mut final_state = STOPPED;
    health.heartbeat.store(Stamp::now().0, Ordering::Relaxed);

    while !stop.load(Ordering::Acquire) {
        let work = stage.wait(budget.poll_timeout);
        let started = Stamp::now();
        health.heartbeat.store(started.0, Ordering::Relaxed);
        let work = match work {
            Poll::Work(w) => w,
            Poll::Idle => {
                if started.since(last_publish) >= PUBLISH_EVERY {
                    publish(&health, &latency, &end_to_end);
                    last_publish = started;
                }
                continue;
            }
            Poll::Done => break,
        };
        let mut ctx = StageCtx {
            started,
            degrade: level,
            late_after: budget.late_after,
            late: 0,
            end_to_end: &mut end_to_end,
            handed_off: None,
        };
        let result = stage.process(work, &mut ctx);
        let late = ctx.late;
        let finished = Stamp::now();
        let took = ctx.handed_off.unwrap_or(finished).since(started);
        latency.record(took);
        let cpu = thread_cpu_time().saturating_sub(cpu0);

        health.heartbeat.store(finished.0, Ordering::Relaxed);
        health.iterations.fetch_add(1, Ordering::Relaxed);
        health.busy_ns.fetch_add(
            u64::try_from(took.as_nanos()).unwrap_or(u64::MAX),
            Ordering::Relaxed,
        );
        health.cpu_ns.store(
            u64::try_from(cpu.as_nanos()).unwrap_or(u64::MAX),
            Ordering::Relaxed,
        );
        if late > 0 {
            health.late.fetch_add(u64::from(late), Ordering::Relaxed);
        }

        if took > budget.budget {
            health.overruns.fetch_add(1, Ordering::Relaxed);
            ok_run_len = 0;
            over_run_len += 1;
            if over_run_len >= budget.degrade_after && level < budget.max_degrade {
                level += 1;
                over_run_len = 0;
                health.degrade_raises.fetch_add(1, Ordering::Relaxed);
                health.degrade_peak.fetch_max(level, Ordering::Relaxed);
            }
        } else {
            over_run_len = 0;
            ok_run_len += 1;
            if ok_run_len >= budget.recover_after && level > 0 {
                level -= 1;
                ok_run_len = 0;
            }
        }
        health.degrade_level.store(level, Ordering::Relaxed);

        match result {
            Ok(()) => {}
            Err(StageFault::Transient(msg)) => {
                let n = health.errors.fetch_add(1, Ordering::Relaxed) + 1;
                if n <= 3 || n.is_multiple_of(LOG_EVERY) {
                    log::warn!("stage {}: {msg} (error #{n})", health.name);
                }
            }
            Err(StageFault::Fatal(msg)) => {
                health.errors.fetch_add(1, Ordering::Relaxed);
                health.note_failure();
                log::error!("stage {} failed: {msg}", health.name);
                final_state = FAILED;
                break;
            }
        }
        if finished.since(last_publish) >= PUBLISH_EVERY {
            publish(&health, &latency, &end_to_end);
            last_publish = finished;
        }
    }
    stage.on_stop();
    let cpu = thread_cpu_time().saturating_sub(cpu0);
    health.cpu_ns.store(
        u64::try_from(cpu.as_nanos()).unwrap_or(u64::MAX),
        Ordering::Relaxed,
    );
    // The final copy must land: wait for the lock here (the thread is ending).
    if let Ok(mut p) = health.published.lock() {
        p.latency.copy_from(&latency);
        p.end_to_end.copy_from(&end_to_end);
    }
    health.state.store(final_state, Ordering::Release);
}

/// Copies the thread's histograms for the supervisor, skipping this round if
/// the supervisor holds the lock (the stage never waits for it).
fn publish(health: &StageHealth, latency: &LatencyHistogram, end_to_end: &LatencyHistogram) {
    if let Ok(mut p) = health.published.try_lock() {
        p.latency.copy_from(latency);
        p.end_to_end.copy_from(end_to_end);
    }
}

/// Marks a stage failed (used when its thread panicked).
pub(crate) fn mark_failed(health: &StageHealth) {
    health.note_failure();
    health.state.store(FAILED, Ordering::Release);
}
