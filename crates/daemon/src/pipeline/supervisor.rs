//! The supervisor: runs on the daemon's main thread, watches every stage's
//! heartbeat, pets the systemd watchdog only while all of them are fresh
//! (never from a free-running timer), sends `READY=1` when told and a short
//! `STATUS=` line, and turns a signal, a stop request or a failed stage into
//! an ordered shutdown: `STOPPING=1`, the daemon's `before_stop` hook (stop
//! the wheels, stop the scanner stream), the pipeline joined, then the
//! `after_stop` hook (final checkpoint, metrics) with the final snapshot.
//!
//! Two clocks meet on this thread, each for its own purpose: the watchdog,
//! the stall check and `STATUS=` run on `CLOCK_MONOTONIC` ([`Stamp`]),
//! because systemd and the OS count in wall time; the hooks' periods
//! (checkpoints, heartbeats, metrics files) run on the daemon's injected
//! clock, read once per tick and handed to [`Hooks::tick`] as a value.

use std::sync::atomic::Ordering;
use std::time::Duration;

use crossbeam_channel::{select, tick, unbounded, Receiver, Sender};

use super::clock::Stamp;
use super::metrics::MetricsSnapshot;
use super::notify::{watchdog_period, Notifier};
use super::signals::signal_name;
use super::stage::RunState;
use super::Pipeline;
use crate::clock::SharedClock;

/// How often `STATUS=` is refreshed.
const STATUS_EVERY: Duration = Duration::from_secs(1);

/// Why the supervisor ended the run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// A termination signal (SIGTERM, SIGINT, SIGHUP).
    Signal(i32),
    /// Someone asked through [`Control::stop`] (e.g. coverage finished).
    Requested(String),
    /// A stage ended on a fatal fault or panicked.
    StageFailed(String),
    /// Every stage ended by itself (inputs closed).
    AllStagesDone,
}

impl StopReason {
    /// Whether the daemon should exit with a failure status (so that
    /// `Restart=on-failure` restarts it).
    pub fn is_failure(&self) -> bool {
        matches!(self, StopReason::StageFailed(_))
    }
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StopReason::Signal(s) => write!(f, "{} received", signal_name(*s)),
            StopReason::Requested(why) => write!(f, "stop requested: {why}"),
            StopReason::StageFailed(name) => write!(f, "stage {name} failed"),
            StopReason::AllStagesDone => f.write_str("all stages finished"),
        }
    }
}

/// An event for the supervisor.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Event {
    Ready,
    Stop(StopReason),
}

/// A cloneable handle stages and the daemon use to talk to the supervisor.
#[derive(Clone, Debug)]
pub struct Control(Sender<Event>);

impl Control {
    /// Start-up is complete: the supervisor sends `READY=1` (once).
    pub fn ready(&self) {
        let _ = self.0.send(Event::Ready);
    }

    /// Asks for an orderly shutdown.
    pub fn stop(&self, why: &str) {
        let _ = self
            .0
            .send(Event::Stop(StopReason::Requested(why.to_string())));
    }

    /// Forwards a termination signal.
    pub fn signal(&self, sig: i32) {
        let _ = self.0.send(Event::Stop(StopReason::Signal(sig)));
    }
}

/// What the daemon plugs into the supervisor. Every method has a default.
pub trait Hooks {
    /// Extra text for `STATUS=`, e.g. `coverage 42.0 %`.
    fn status(&mut self) -> String {
        String::new()
    }

    /// Called every supervisor period with the live pipeline and the time
    /// `now` on the daemon's injected clock (s): write periodic checkpoints
    /// and metrics here, timed by `now`.
    fn tick(&mut self, _pipeline: &Pipeline, _now: f64) {}

    /// Shutdown, first step, with every stage still running: stop the wheels,
    /// stop the scanner stream.
    fn before_stop(&mut self, _reason: &StopReason, _pipeline: &Pipeline) {}

    /// Shutdown, last step, after every stage thread has been joined: write
    /// the final checkpoint and metrics.
    fn after_stop(&mut self, _reason: &StopReason, _final: &MetricsSnapshot) {}

    /// Files for the run folder beside the metrics, written at the end
    /// (name, text): what the run found out besides its metrics.
    fn run_folder_files(&self) -> Vec<(&'static str, String)> {
        Vec::new()
    }
}

/// Hooks that do nothing (tests, tools).
#[derive(Debug, Default)]
pub struct NoHooks;

impl Hooks for NoHooks {}

/// How a supervised run ended.
#[derive(Debug)]
pub struct Outcome {
    /// Why it stopped.
    pub reason: StopReason,
    /// Counters and histograms after every thread was joined.
    pub snapshot: MetricsSnapshot,
}

/// The supervisor of one pipeline.
pub struct Supervisor {
    events: Receiver<Event>,
    control: Control,
    notifier: Notifier,
    period: Duration,
    watchdog: Option<Duration>,
    clock: SharedClock,
}

impl Supervisor {
    /// A supervisor checking every `pipeline.supervise_period`, petting the
    /// watchdog at half the period systemd asks for (`WATCHDOG_USEC`), or at
    /// half `pipeline.watchdog_period` when systemd gives none. `clock` is
    /// the daemon's injected clock, which times the hooks' periods.
    pub fn new(params: &super::PipelineParams, clock: SharedClock) -> Self {
        let (tx, events) = unbounded();
        let watchdog = watchdog_period(params.watchdog_period);
        let mut period = Duration::from_secs_f64(params.supervise_period);
        if let Some(w) = watchdog {
            period = period.min(w / 4).max(Duration::from_millis(1));
        }
        Self {
            events,
            control: Control(tx),
            notifier: Notifier::new(),
            period,
            watchdog,
            clock,
        }
    }

    /// A handle to signal readiness or ask for a stop.
    pub fn control(&self) -> Control {
        self.control.clone()
    }

    /// The watchdog period in force, if any.
    pub fn watchdog(&self) -> Option<Duration> {
        self.watchdog
    }

    /// Supervises `pipeline` until a stop, then shuts it down in order and
    /// returns why and the final snapshot.
    pub fn run(self, pipeline: Pipeline, hooks: &mut dyn Hooks) -> Outcome {
        let counters = std::sync::Arc::clone(pipeline.supervisor_counters());
        let ticker = tick(self.period);
        let pet_every = self.watchdog.map(|w| w / 2);
        let mut last_pet: Option<Stamp> = None;
        let mut last_status: Option<Stamp> = None;
        let mut ready = false;
        let mut stalled_before = false;
        let reason = loop {
            select! {
                recv(self.events) -> ev => match ev {
                    Ok(Event::Ready) => {
                        if !ready {
                            ready = true;
                            self.notifier.ready();
                        }
                    }
                    Ok(Event::Stop(r)) => break r,
                    Err(_) => {}
                },
                recv(ticker) -> _ => {}
            }
            let now = Stamp::now();
            // The stage that failed first is the cause: a stage whose
            // neighbour has gone fails after it.
            if let Some(f) = pipeline
                .stages()
                .filter(|s| s.state() == RunState::Failed)
                .min_by_key(|s| s.failed_at().map_or(u64::MAX, |t| t.0))
            {
                break StopReason::StageFailed(f.name().to_string());
            }
            let mut stages = pipeline.stages().peekable();
            if stages.peek().is_some() && stages.all(|s| s.state() == RunState::Stopped) {
                break StopReason::AllStagesDone;
            }
            let stalled: Option<String> = pipeline.unhealthy(now).next().map(|s| {
                let what = if s.state() == RunState::Running {
                    "stalled"
                } else {
                    "stopped"
                };
                format!("{what}: {}", s.name())
            });
            match &stalled {
                None => {
                    stalled_before = false;
                    if let Some(every) = pet_every {
                        if last_pet.is_none_or(|t| now.since(t) >= every) {
                            if self.notifier.watchdog() {
                                counters.watchdog_pets.fetch_add(1, Ordering::Relaxed);
                            }
                            last_pet = Some(now);
                        }
                    }
                }
                Some(what) => {
                    counters.stall_checks.fetch_add(1, Ordering::Relaxed);
                    if !stalled_before {
                        log::warn!("stage {what}: withholding the watchdog");
                        stalled_before = true;
                    }
                }
            }
            if last_status.is_none_or(|t| now.since(t) >= STATUS_EVERY) {
                let extra = hooks.status();
                let health = match &stalled {
                    None => "ok".to_string(),
                    Some(n) => n.clone(),
                };
                let text = if extra.is_empty() {
                    format!("health {health}")
                } else {
                    format!("{extra}; health {health}")
                };
                self.notifier.status(&text);
                last_status = Some(now);
            }
            counters
                .notify_errors
                .store(self.notifier.errors(), Ordering::Relaxed);
            hooks.tick(&pipeline, self.clock.now());
        };
        log::info!("shutting down: {reason}");
        self.notifier.stopping();
        self.notifier.status(&format!("stopping: {reason}"));
        hooks.before_stop(&reason, &pipeline);
        let snapshot = pipeline.stop();
        hooks.after_stop(&reason, &snapshot);
        Outcome { reason, snapshot }
    }
}
