//! Supervisor hooks that keep a run folder up to date: `metrics.toml`
//! rewritten every `pipeline.metrics_period` while the run goes on (so a
//! crash leaves recent metrics behind), and at the end the final metrics and
//! the budget report. Wraps the daemon's own hooks and delegates to them.
//! A resumed run also records its restart in `resume.toml`
//! ([`RunFolderHooks::with_resume`]), which the report includes.

use std::path::{Path, PathBuf};

use super::budget::write_budget_report;
use crate::pipeline::checkpoint::{ResumeEntry, ResumeLog};
use crate::pipeline::metrics::{MetricsSnapshot, METRICS_FILE};
use crate::pipeline::periodic::Every;
use crate::pipeline::supervisor::{Hooks, StopReason};
use crate::pipeline::{Pipeline, PipelineParams};

/// [`Hooks`] writing metrics and the report into a run folder around `inner`.
pub struct RunFolderHooks<H> {
    inner: H,
    dir: PathBuf,
    every: Every,
    writes: u64,
    errors: u64,
    report: Option<PathBuf>,
}

impl<H: Hooks> RunFolderHooks<H> {
    /// Wraps `inner`, writing into `dir` (created at the first write) every
    /// `params.metrics_period` seconds of the daemon's clock (the `now` the
    /// supervisor passes to [`Hooks::tick`]), counted from the first tick.
    pub fn new(inner: H, dir: &Path, params: &PipelineParams) -> Self {
        Self {
            inner,
            dir: dir.to_path_buf(),
            every: Every::new(params.metrics_period),
            writes: 0,
            errors: 0,
            report: None,
        }
    }

    /// Records how the run started: `Some` appends the resume to the run
    /// folder's `resume.toml` (keeping earlier restarts of the same run),
    /// `None` (a fresh start) removes a stale one.
    pub fn with_resume(self, entry: Option<ResumeEntry>) -> Self {
        let r = match entry {
            Some(e) => ResumeLog::append(&self.dir, e).map(|_| ()),
            None => ResumeLog::clear(&self.dir),
        };
        if let Err(e) = r {
            log::warn!("cannot record the resume in the run folder: {e}");
        }
        self
    }

    fn write(&mut self, snap: &MetricsSnapshot) {
        let r = std::fs::create_dir_all(&self.dir)
            .map_err(|e| e.to_string())
            .and_then(|()| {
                snap.write(&self.dir.join(METRICS_FILE))
                    .map_err(|e| e.to_string())
            });
        match r {
            Ok(()) => self.writes += 1,
            Err(e) => {
                self.errors += 1;
                if self.errors <= 3 {
                    log::warn!("cannot write metrics into {}: {e}", self.dir.display());
                }
            }
        }
    }

    /// Metrics files written so far.
    pub fn writes(&self) -> u64 {
        self.writes
    }

    /// Path of the final report, once written.
    pub fn report(&self) -> Option<&Path> {
        self.report.as_deref()
    }

    /// The wrapped hooks.
    pub fn into_inner(self) -> H {
        self.inner
    }
}

impl<H: Hooks> Hooks for RunFolderHooks<H> {
    fn status(&mut self) -> String {
        self.inner.status()
    }

    fn tick(&mut self, pipeline: &Pipeline, now: f64) {
        self.inner.tick(pipeline, now);
        if self.every.due(now) {
            self.write(&pipeline.snapshot());
        }
    }

    fn before_stop(&mut self, reason: &StopReason, pipeline: &Pipeline) {
        self.inner.before_stop(reason, pipeline);
    }

    fn run_folder_files(&self) -> Vec<(&'static str, String)> {
        self.inner.run_folder_files()
    }

    fn after_stop(&mut self, reason: &StopReason, snap: &MetricsSnapshot) {
        self.inner.after_stop(reason, snap);
        self.write(snap);
        for (name, text) in self.inner.run_folder_files() {
            let path = self.dir.join(name);
            if let Err(e) = std::fs::write(&path, text) {
                log::warn!("cannot write {}: {e}", path.display());
            }
        }
        match write_budget_report(&self.dir, snap) {
            Ok(p) => self.report = Some(p),
            Err(e) => log::warn!("cannot write the budget report: {e}"),
        }
    }
}
