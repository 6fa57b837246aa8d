//! The real-time pipeline: one thread per stage, bounded channels with
//! declared overflow policies, newest-wins hand-over, budgets with
//! degradation, metrics, the supervisor with the systemd watchdog, signals,
//! and crash-safe checkpoints. The only layer of the crate that owns threads.
//!
//! A daemon builds a [`Pipeline`], creates its edges ([`edge::latest`],
//! [`edge::queue`], registered with [`Pipeline::register_edge`]), spawns one
//! [`Stage`] per box of the DESIGN data path, and hands the pipeline to a
//! [`supervisor::Supervisor`], which runs until a signal, a stop request or a
//! failed stage, then shuts down in order.
//!
//! ```
//! use std::time::Duration;
//! use sweepline_daemon::pipeline::supervisor::{NoHooks, Supervisor};
//! use sweepline_daemon::pipeline::{
//!     latest, Pipeline, PipelineParams, Poll, Recv, Rx, Stage, StageCtx, StageFault, Tx,
//! };
//!
//! /// Produces 100 numbers, then ends.
//! struct Source { left: u32, out: Tx<u32> }
//! impl Stage for Source {
//!     type Work = u32;
//!     fn wait(&mut self, _timeout: Duration) -> Poll<u32> {
//!         if self.left == 0 { return Poll::Done; }
//!         self.left -= 1;
//!         Poll::Work(self.left)
//!     }
//!     fn process(&mut self, n: u32, _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
//!         self.out.send(n).map(|_| ()).map_err(|e| StageFault::Fatal(e.to_string()))
//!     }
//! }
//!
//! /// Takes the newest number; does less work when told to degrade.
//! struct Sink { input: Rx<u32> }
//! impl Stage for Sink {
//!     type Work = u32;
//!     fn wait(&mut self, timeout: Duration) -> Poll<u32> {
//!         match self.input.recv_timeout(timeout) {
//!             Recv::Msg(n) => Poll::Work(n),
//!             Recv::Empty => Poll::Idle,
//!             Recv::Closed => Poll::Done,
//!         }
//!     }
//!     fn process(&mut self, _n: u32, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
//!         let _iterations = 20 >> ctx.degrade(); // e.g. fewer ICP iterations
//!         Ok(())
//!     }
//! }
//!
//! let params = PipelineParams::default();
//! let mut p = Pipeline::new(&params);
//! let (tx, rx) = latest::<u32>("pose");
//! p.register_edge(&tx);
//! p.spawn("localise", Source { left: 100, out: tx })?;
//! p.spawn("plan", Sink { input: rx })?;
//! let clock = std::sync::Arc::new(sweepline_io::clock::MonotonicClock::new());
//! let out = Supervisor::new(&params, clock).run(p, &mut NoHooks);
//! let e = &out.snapshot.edges[0];
//! assert_eq!(e.received + e.dropped, 100); // newest-wins: taken or counted
//! # Ok::<(), sweepline_daemon::pipeline::PipelineError>(())
//! ```

pub(crate) mod cgroup;
pub mod checkpoint;
pub mod clock;
pub mod edge;
pub mod metrics;
pub mod notify;
pub mod params;
pub mod periodic;
pub mod rt;
pub mod signals;
pub mod stage;
pub mod supervisor;
pub mod threads;
pub mod writer;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

pub use edge::{latest, queue, Overflow, Recv, Rx, Sent, Tx};
pub use params::{PipelineParams, StageBudgets};
pub use stage::{Poll, RunState, Stage, StageCtx, StageFault, StageHealth};

use clock::{core_count, process_cpu_time, Stamp};
use edge::EdgeStats;
use metrics::{
    EdgeMetrics, MetricsSnapshot, SupervisorMetrics, ThreadMetrics, ThrottleMetrics,
    METRICS_VERSION,
};
use stage::StageBudget;

/// Why the pipeline could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// A stage was spawned under a name that has no budget in `[pipeline.budget]`.
    #[error("stage `{0}` has no budget: use one of scanner, localise, map, plan, control, motor, or spawn_with_budget")]
    NoBudget(String),
    /// Two stages with the same name.
    #[error("a stage named `{0}` is already running")]
    Duplicate(String),
    /// The OS refused a thread.
    #[error("cannot start the thread of stage `{name}`: {source}")]
    Spawn {
        /// Stage name.
        name: String,
        /// OS error.
        source: std::io::Error,
    },
}

/// Counters the supervisor keeps, stored with the pipeline so every snapshot
/// carries them.
#[derive(Debug, Default)]
pub(crate) struct SupervisorCounters {
    /// `WATCHDOG=1` sent.
    pub watchdog_pets: AtomicU64,
    /// Checks that found a stalled stage.
    pub stall_checks: AtomicU64,
    /// Notifications that failed.
    pub notify_errors: AtomicU64,
}

struct EdgeEntry {
    stats: Arc<EdgeStats>,
    depth: Box<dyn Fn() -> usize + Send>,
}

struct StageEntry {
    health: Arc<StageHealth>,
    thread: Option<JoinHandle<()>>,
}

/// The running stages and edges of one daemon run.
pub struct Pipeline {
    params: PipelineParams,
    stop: Arc<AtomicBool>,
    stages: Vec<StageEntry>,
    edges: Vec<EdgeEntry>,
    started: Stamp,
    cpu0: Duration,
    threads0: std::collections::BTreeMap<u32, (String, f64)>,
    throttle0: Option<cgroup::Throttling>,
    supervisor: Arc<SupervisorCounters>,
}

impl Pipeline {
    /// An empty pipeline using the budgets and policies of `params`
    /// (validated by the config loader).
    pub fn new(params: &PipelineParams) -> Self {
        Self {
            params: params.clone(),
            stop: Arc::new(AtomicBool::new(false)),
            stages: Vec::new(),
            edges: Vec::new(),
            started: Stamp::now(),
            cpu0: process_cpu_time(),
            threads0: threads::read_threads(),
            throttle0: cgroup::read_throttling(),
            supervisor: Arc::new(SupervisorCounters::default()),
        }
    }

    /// The settings the pipeline runs with.
    pub fn params(&self) -> &PipelineParams {
        &self.params
    }

    /// Registers an edge so its counters and depth appear in snapshots.
    pub fn register_edge<T: Send + 'static>(&mut self, tx: &Tx<T>) {
        self.edges.push(EdgeEntry {
            stats: Arc::clone(tx.stats()),
            depth: Box::new(tx.depth_probe()),
        });
    }

    /// Spawns `stage` on its own thread named `name`, with the budget of that
    /// name from `[pipeline.budget]`.
    pub fn spawn<S: Stage>(
        &mut self,
        name: &str,
        stage: S,
    ) -> Result<Arc<StageHealth>, PipelineError> {
        let budget = self
            .params
            .budget
            .get(name)
            .ok_or_else(|| PipelineError::NoBudget(name.to_string()))?;
        self.spawn_with_budget(name, Duration::from_secs_f64(budget), stage)
    }

    /// Spawns `stage` on its own thread named `name` with an explicit budget
    /// (for stages outside the standard six, and tests).
    pub fn spawn_with_budget<S: Stage>(
        &mut self,
        name: &str,
        budget: Duration,
        stage: S,
    ) -> Result<Arc<StageHealth>, PipelineError> {
        if self.stages.iter().any(|s| s.health.name() == name) {
            return Err(PipelineError::Duplicate(name.to_string()));
        }
        let p = &self.params;
        let policy = StageBudget {
            budget,
            degrade_after: p.degrade_after,
            recover_after: p.recover_after,
            max_degrade: p.max_degrade,
            late_after: Duration::from_secs_f64(p.late_after),
            poll_timeout: Duration::from_secs_f64(p.poll_timeout),
        };
        let realtime = (p.realtime_priority > 0 && p.realtime_stages.iter().any(|s| s == name))
            .then_some(p.realtime_priority);
        let health = Arc::new(StageHealth::new(name, budget));
        let (h, stop) = (Arc::clone(&health), Arc::clone(&self.stop));
        let thread = std::thread::Builder::new()
            .name(name.to_string())
            .spawn(move || {
                if let Some(priority) = realtime {
                    rt::apply(h.name(), priority);
                }
                let h2 = Arc::clone(&h);
                let run =
                    std::panic::AssertUnwindSafe(move || stage::run_stage(stage, h2, policy, stop));
                if std::panic::catch_unwind(run).is_err() {
                    log::error!("stage {} panicked", h.name());
                    stage::mark_failed(&h);
                }
            })
            .map_err(|source| PipelineError::Spawn {
                name: name.to_string(),
                source,
            })?;
        self.stages.push(StageEntry {
            health: Arc::clone(&health),
            thread: Some(thread),
        });
        Ok(health)
    }

    /// The live health of every stage, in spawn order.
    pub fn stages(&self) -> impl Iterator<Item = &Arc<StageHealth>> {
        self.stages.iter().map(|s| &s.health)
    }

    /// The supervisor's counters.
    pub(crate) fn supervisor_counters(&self) -> &Arc<SupervisorCounters> {
        &self.supervisor
    }

    /// Stages whose heartbeat is older than `pipeline.stall_after` or that
    /// are not running, at time `now`.
    pub(crate) fn unhealthy(&self, now: Stamp) -> impl Iterator<Item = &Arc<StageHealth>> {
        let stall = Duration::from_secs_f64(self.params.stall_after);
        self.stages().filter(move |s| !s.is_fresh(now, stall))
    }

    /// A snapshot of every counter and histogram (histograms as last
    /// published by each stage, at most ~0.2 s old while running).
    pub fn snapshot(&self) -> MetricsSnapshot {
        let sup = &self.supervisor;
        MetricsSnapshot {
            version: METRICS_VERSION,
            wall: Stamp::now().since(self.started).as_secs_f64(),
            cores: core_count(),
            process_cpu: process_cpu_time().saturating_sub(self.cpu0).as_secs_f64(),
            threads: threads::cpu_by_name(&self.threads0)
                .into_iter()
                .map(|(name, cpu)| ThreadMetrics { name, cpu })
                .collect(),
            cpu_budget: self.params.cpu_budget,
            time_scale: self.params.time_scale,
            stages: self.stages().map(|s| s.metrics()).collect(),
            edges: self
                .edges
                .iter()
                .map(|e| EdgeMetrics {
                    name: e.stats.name().to_string(),
                    policy: e.stats.policy().to_string(),
                    capacity: e.stats.capacity(),
                    sent: e.stats.sent(),
                    received: e.stats.received(),
                    dropped: e.stats.dropped(),
                    depth: (e.depth)(),
                    max_depth: e.stats.max_depth(),
                })
                .collect(),
            supervisor: SupervisorMetrics {
                watchdog_pets: sup.watchdog_pets.load(Ordering::Relaxed),
                stall_checks: sup.stall_checks.load(Ordering::Relaxed),
                notify_errors: sup.notify_errors.load(Ordering::Relaxed),
            },
            throttling: self.throttle0.as_ref().and_then(|t0| {
                cgroup::read_throttling().map(|t| {
                    let d = t.since(t0);
                    ThrottleMetrics {
                        periods: d.periods,
                        throttled: d.throttled,
                        throttled_time: d.throttled_us as f64 * 1e-6,
                    }
                })
            }),
        }
    }

    /// Stops every stage (each sees the flag within one poll timeout, then
    /// runs its `on_stop`), joins every thread, and returns the final snapshot.
    /// A stage still stuck in `process` after `pipeline.stop_timeout` is left
    /// behind (logged, its thread detached; it dies with the process) so that
    /// shutdown finishes inside systemd's `TimeoutStopSec=`.
    pub fn stop(mut self) -> MetricsSnapshot {
        self.join_all();
        self.snapshot()
    }

    fn join_all(&mut self) {
        self.stop.store(true, Ordering::Release);
        let deadline = Stamp::now().after(Duration::from_secs_f64(self.params.stop_timeout));
        while Stamp::now() < deadline
            && self
                .stages
                .iter()
                .any(|s| s.thread.is_some() && s.health.state() == RunState::Running)
        {
            std::thread::sleep(Duration::from_millis(2));
        }
        for s in &mut self.stages {
            let Some(t) = s.thread.take() else { continue };
            if s.health.state() == RunState::Running && !t.is_finished() {
                log::error!(
                    "stage {} did not stop within {} s; leaving its thread behind",
                    s.health.name(),
                    self.params.stop_timeout
                );
                continue;
            }
            if t.join().is_err() {
                stage::mark_failed(&s.health);
            }
        }
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        self.join_all();
    }
}
