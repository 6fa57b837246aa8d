//! The daemon's supervisor hooks: the `STATUS=` line with the coverage
//! estimate, a checkpoint (progress, pose, map) every
//! `pipeline.checkpoint_period`, a heartbeat (progress, wall time) every
//! `pipeline.heartbeat_period`, and the ordered shutdown (wheels stopped
//! first, then the stages joined, then the final checkpoint). The files
//! are put on disk by a [`StateWriter`] thread: the supervisor only takes
//! the snapshot, so a slow disk delays a checkpoint, never supervision.

use std::path::Path;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use super::shared::Shared;
use super::snapshot::RunSnapshot;
use crate::clock::SharedClock;
use crate::pipeline::checkpoint::{
    Checkpoint, CheckpointStore, RunFinished, RunProgress, WrittenAt,
};
use crate::pipeline::metrics::MetricsSnapshot;
use crate::pipeline::periodic::Every;
use crate::pipeline::supervisor::{Hooks, StopReason};
use crate::pipeline::writer::{StateWriter, WriteStats};
use crate::pipeline::Pipeline;

/// The writer's slot for checkpoints.
const CHECKPOINT: &str = "checkpoint";
/// The writer's slot for heartbeats.
const HEARTBEAT: &str = "heartbeat";
/// How often the pipeline's metrics are handed to the live view (clock s).
const METRICS_PERIOD: f64 = 1.0;

/// Hooks of a daemon run.
pub struct DaemonHooks {
    shared: Arc<Shared>,
    clock: SharedClock,
    store: Option<CheckpointStore>,
    every: Every,
    heartbeat: Option<CheckpointStore>,
    beat: Every,
    started: f64,
    base: RunProgress,
    sequence: u64,
    /// Puts checkpoints and heartbeats on disk (none: no state folder).
    writer: Option<StateWriter>,
    /// The checkpoint period (s), to tell a slow disk in the log.
    period: f64,
    /// Whether the slow disk was logged.
    warned_slow: bool,
    /// Kind of the planner's task last logged.
    task_kind: String,
    /// The robot as configured, for the run folder's `mount.toml`.
    robot: Option<crate::robot::RobotParams>,
    /// When the metrics are next handed to the live view.
    metrics_every: Every,
}

impl DaemonHooks {
    /// Hooks checkpointing into `state_dir` (none: no checkpoints) every
    /// `period` seconds and noting a heartbeat there every `heartbeat`
    /// seconds, both of `clock` (the daemon's injected clock, as the stages
    /// run on: robot time, also in a time-scaled simulation), continuing the
    /// progress of `resumed` if given.
    pub fn new(
        shared: Arc<Shared>,
        clock: SharedClock,
        state_dir: Option<&Path>,
        period: f64,
        heartbeat: f64,
        resumed: Option<RunProgress>,
    ) -> Self {
        let base = resumed
            .map(|p| RunProgress {
                resumes: p.resumes + 1,
                ..p
            })
            .unwrap_or_default();
        let writer = state_dir.map(|_| StateWriter::spawn("state-writer"));
        Self {
            started: clock.now(),
            shared,
            clock,
            writer,
            period,
            warned_slow: false,
            store: state_dir.map(CheckpointStore::new),
            every: Every::new(period),
            metrics_every: Every::new(METRICS_PERIOD),
            heartbeat: state_dir.map(super::resume::heartbeat_store),
            beat: Every::new(heartbeat),
            sequence: base.sequence,
            base,
            task_kind: String::new(),
            robot: None,
        }
    }

    /// Writes the run folder's `mount.toml` (what the mount and wheel
    /// checks measured) for a robot configured as `robot`.
    pub(crate) fn with_robot(mut self, robot: crate::robot::RobotParams) -> Self {
        self.robot = Some(robot);
        self
    }

    /// The run's progress now.
    pub fn progress(&self) -> RunProgress {
        let (scans, path, covered, grid) = self
            .shared
            .with_status(|s| (s.scans, s.path_length, s.covered_area, s.map.grid.clone()));
        let free = grid
            .map(|g| g.counts().1 as f64 * g.resolution() * g.resolution())
            .unwrap_or(0.0);
        RunProgress {
            sequence: self.sequence,
            elapsed: self.base.elapsed + (self.clock.now() - self.started),
            coverage: if free > 0.0 {
                (covered / free).min(1.0)
            } else {
                0.0
            },
            scans: self.base.scans + scans,
            path_length: path,
            resumes: self.base.resumes,
        }
    }

    /// Takes a checkpoint of the run now and hands it to the writer (when a
    /// state folder is set). Its `WrittenAt` is when the snapshot was taken,
    /// not when the disk finished.
    pub fn checkpoint(&mut self) {
        let Some(store) = &self.store else { return };
        self.sequence += 1;
        let taken = WrittenAt::now();
        let progress = self.progress();
        let finished = self.shared.done.load(Ordering::Relaxed);
        let (pose, map, plan, localise) = self
            .shared
            .with_status(|s| (s.pose, s.map.clone(), s.plan.clone(), s.localise.clone()));
        let run = RunSnapshot {
            progress,
            pose,
            finished: finished.then_some(RunFinished {
                elapsed: progress.elapsed,
            }),
        };
        let mut cp = Checkpoint::new();
        let r = run
            .put(&mut cp)
            .and_then(|()| cp.put(&taken))
            .and_then(|()| map.put(&mut cp))
            .and_then(|()| plan.put(&mut cp))
            .and_then(|()| localise.put(&mut cp));
        let store = store.clone();
        self.write(
            CHECKPOINT,
            Box::new(move || r.and_then(|()| store.save(&cp)).map_err(|e| e.to_string())),
        );
    }

    /// Notes the run's progress and the wall time in the heartbeat file now
    /// (when a state folder is set): what a resumed daemon compares its
    /// checkpoint with to tell how much progress the crash lost.
    pub fn heartbeat(&mut self) {
        let Some(store) = &self.heartbeat else { return };
        let beat = super::resume::heartbeat(&self.progress(), WrittenAt::now());
        let store = store.clone();
        self.write(
            HEARTBEAT,
            Box::new(move || {
                beat.and_then(|cp| store.save_unsynced(&cp))
                    .map_err(|e| e.to_string())
            }),
        );
    }

    /// Hands `job` to the writer (there is one whenever there is a state
    /// folder to write to), and logs once when checkpoints are slower than
    /// their period.
    fn write(&mut self, kind: &'static str, job: crate::pipeline::writer::Job) {
        let Some(w) = &self.writer else { return };
        w.submit(kind, job);
        // Wall seconds on the run's clock (a simulation may run faster than
        // the wall).
        let slowest = w.stats(kind).slowest * self.clock.speed();
        if kind == CHECKPOINT && slowest > self.period && !self.warned_slow {
            self.warned_slow = true;
            log::warn!(
                "a checkpoint took {slowest:.1} s to write, longer than pipeline.checkpoint_period ({:.1} s): the state folder's disk is slow; the newest checkpoint is written whenever the disk is free again",
                self.period
            );
        }
    }

    /// What the writer did with the checkpoints and heartbeats so far.
    pub fn write_stats(&self) -> (WriteStats, WriteStats) {
        self.writer.as_ref().map_or_else(Default::default, |w| {
            (w.stats(CHECKPOINT), w.stats(HEARTBEAT))
        })
    }
}

impl DaemonHooks {
    /// Logs the planner's task when its kind changes (a stalled run then
    /// shows in the log what the planner was doing).
    fn log_task_change(&mut self) {
        let (task, pose) = self.shared.with_status(|s| (s.task.clone(), s.pose));
        let kind = task
            .split(|c: char| !c.is_alphanumeric())
            .next()
            .unwrap_or("");
        if kind != self.task_kind {
            self.task_kind = kind.to_string();
            log::info!(
                "planner: {task} (robot at {:.2}, {:.2})",
                pose.translation.x,
                pose.translation.y
            );
        }
    }
}

impl Hooks for DaemonHooks {
    fn status(&mut self) -> String {
        let p = self.progress();
        let task = self.shared.with_status(|s| s.task.clone());
        format!(
            "coverage ~{:.1} %, {:.0} s, {} scans, task {task}",
            p.coverage * 100.0,
            p.elapsed,
            p.scans
        )
    }

    fn tick(&mut self, pipeline: &Pipeline, now: f64) {
        if self.metrics_every.due(now) {
            let m = std::sync::Arc::new(pipeline.snapshot());
            if let Ok(mut slot) = self.shared.metrics.lock() {
                *slot = Some(m);
            }
        }
        if self.every.due(now) {
            self.checkpoint();
        }
        if self.beat.due(now) {
            self.heartbeat();
            self.log_task_change();
        }
    }

    fn before_stop(&mut self, _reason: &StopReason, _pipeline: &Pipeline) {
        self.shared.halt.store(true, Ordering::Relaxed);
    }

    fn after_stop(&mut self, _reason: &StopReason, _final: &MetricsSnapshot) {
        // What is pending goes first; the final checkpoint is then written
        // on this thread, before the process exits.
        if let Some(w) = self.writer.as_mut() {
            w.finish();
        }
        self.checkpoint();
        self.heartbeat();
        let (c, h) = self.write_stats();
        if c.done > 0 {
            log::info!(
                "state writes: {} checkpoint(s) ({} failed, {} superseded by a newer one while the disk was busy, slowest {:.3} s), {} heartbeat(s) ({} failed, slowest {:.3} s)",
                c.done,
                c.failed,
                c.superseded,
                c.slowest,
                h.done,
                h.failed,
                h.slowest
            );
        }
    }

    fn run_folder_files(&self) -> Vec<(&'static str, String)> {
        let mut files = vec![(
            super::events_report::EVENTS_FILE,
            super::events_report::events_toml(&self.shared),
        )];
        if let Some(robot) = &self.robot {
            files.extend(
                self.shared
                    .with_status(|s| super::mount_report::mount_toml(robot, s))
                    .map(|t| (super::mount_report::MOUNT_FILE, t)),
            );
        }
        files
    }
}
