//! `[pipeline]` settings: stage budgets, degradation policy, watchdog and
//! checkpoint timing. Every key is documented in `hw/robot.toml`.

use serde::{Deserialize, Serialize};

use crate::param_check::{invalid, positive, ParamError};

/// Per-stage latency budgets in seconds (the DESIGN stage table at 10 Hz scans).
/// A stage iteration that takes longer than its budget is an overrun.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct StageBudgets {
    /// Scanner stage: decode one scan (s).
    pub scanner: f64,
    /// Localise stage: one intensity-ICP registration (s).
    pub localise: f64,
    /// Map stage: merge one registered scan (s).
    pub map: f64,
    /// Plan stage: one decomposition / planning event (s).
    pub plan: f64,
    /// Control stage: one path-following step (s).
    pub control: f64,
    /// Motor stage: encode and send one wheel command, read odometry (s).
    pub motor: f64,
}

impl Default for StageBudgets {
    fn default() -> Self {
        Self {
            scanner: 0.000_2,
            localise: 0.002,
            map: 0.002,
            plan: 0.005,
            control: 0.000_1,
            motor: 0.001,
        }
    }
}

impl StageBudgets {
    /// The budget of the stage called `name` (seconds), if it is one of the
    /// standard stages.
    pub fn get(&self, name: &str) -> Option<f64> {
        Some(match name {
            "scanner" => self.scanner,
            "localise" => self.localise,
            "map" => self.map,
            "plan" => self.plan,
            "control" => self.control,
            "motor" => self.motor,
            _ => return None,
        })
    }

    fn validate(&self) -> Result<(), ParamError> {
        for (k, v) in [
            ("pipeline.budget.scanner", self.scanner),
            ("pipeline.budget.localise", self.localise),
            ("pipeline.budget.map", self.map),
            ("pipeline.budget.plan", self.plan),
            ("pipeline.budget.control", self.control),
            ("pipeline.budget.motor", self.motor),
        ] {
            positive(k, v)?;
            if v > 10.0 {
                return Err(invalid(k, &format!("must be at most 10 s, got {v:?}")));
            }
        }
        Ok(())
    }
}

/// The clock's speed on a robot.
fn real_time() -> f64 {
    1.0
}

/// Pipeline budgets and rates.
/// Loaded from the `[pipeline]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct PipelineParams {
    /// Longest a stage waits for input before it checks for shutdown and
    /// refreshes its heartbeat (s).
    pub poll_timeout: f64,
    /// A stage whose heartbeat is older than this is stalled: the watchdog is
    /// not petted and the health turns bad (s).
    pub stall_after: f64,
    /// Watchdog petting period when systemd gives none (`WATCHDOG_USEC`
    /// unset): 0 disables petting then (s).
    pub watchdog_period: f64,
    /// How often the supervisor checks heartbeats and sends `STATUS=` (wall
    /// s: the watchdog counts in wall time).
    pub supervise_period: f64,
    /// Longest shutdown waits for a stage to finish its current item before
    /// leaving it behind (s); keep it below the unit's `TimeoutStopSec=`.
    pub stop_timeout: f64,
    /// Whole-process CPU budget as a fraction of one core (0.05 = 5 %).
    pub cpu_budget: f64,
    /// Consecutive overruns that raise a stage's degradation level by one.
    pub degrade_after: u32,
    /// Consecutive in-budget iterations that lower the level by one again.
    pub recover_after: u32,
    /// Highest degradation level a stage can be told (0 disables degradation).
    pub max_degrade: u8,
    /// A message older than this when a stage takes it is counted late (s).
    pub late_after: f64,
    /// Capacity of the scan queue between scanner and localise (messages).
    pub scan_queue: usize,
    /// How often a checkpoint is written during a run (s of the daemon's
    /// injected clock, as the stages run on).
    pub checkpoint_period: f64,
    /// How often the metrics file of the run folder is rewritten (s of the
    /// daemon's injected clock).
    pub metrics_period: f64,
    /// How often the daemon notes its progress in `heartbeat.swc` of the
    /// state folder (s of the daemon's injected clock): unsynced and cheap, it tells a resumed daemon how
    /// far the crashed one had got after its last checkpoint.
    pub heartbeat_period: f64,
    /// Speed of the daemon's clock against the wall clock: 1 on a robot.
    /// Not a config key: a simulator driving `sweepline run` as a separate
    /// process sets it with `--sim-clock`, so both read one simulated time.
    #[serde(skip, default = "real_time")]
    pub time_scale: f64,
    /// UNIX time (s) at which the daemon's clock reads 0; 0 = when the daemon
    /// starts. Not a config key: set with `--sim-clock` beside `time_scale`.
    #[serde(skip)]
    pub clock_epoch: f64,
    /// Real-time (`SCHED_FIFO`) priority for the threads of
    /// [`PipelineParams::realtime_stages`], 1..=99; 0 = normal scheduling.
    pub realtime_priority: u8,
    /// Stages whose thread asks for `realtime_priority` (the scan path; the
    /// motor stage waits on its device and is left out by default).
    pub realtime_stages: Vec<String>,
    /// Per-stage latency budgets.
    pub budget: StageBudgets,
}

impl Default for PipelineParams {
    fn default() -> Self {
        Self {
            poll_timeout: 0.05,
            stall_after: 1.0,
            watchdog_period: 0.0,
            supervise_period: 0.1,
            stop_timeout: 2.0,
            cpu_budget: 0.05,
            degrade_after: 3,
            recover_after: 50,
            max_degrade: 3,
            late_after: 0.3,
            scan_queue: 4,
            checkpoint_period: 2.0,
            metrics_period: 5.0,
            heartbeat_period: 0.5,
            time_scale: 1.0,
            clock_epoch: 0.0,
            realtime_priority: 0,
            realtime_stages: ["scanner", "localise", "control"]
                .map(String::from)
                .to_vec(),
            budget: StageBudgets::default(),
        }
    }
}

impl PipelineParams {
    /// Checks ranges the types cannot express; errors name the dotted key.
    pub fn validate(&self) -> Result<(), ParamError> {
        crate::check_keys!(
            self,
            "pipeline",
            positive: [
                poll_timeout,
                stall_after,
                supervise_period,
                stop_timeout,
                cpu_budget,
                late_after,
                checkpoint_period,
                metrics_period,
                heartbeat_period,
            ],
        );
        if self.realtime_priority > 99 {
            return Err(invalid(
                "pipeline.realtime_priority",
                &format!(
                    "must be 0 (off) or a SCHED_FIFO priority 1..=99, got {}",
                    self.realtime_priority
                ),
            ));
        }
        if let Some(bad) = self
            .realtime_stages
            .iter()
            .find(|s| self.budget.get(s).is_none())
        {
            return Err(invalid(
                "pipeline.realtime_stages",
                &format!("`{bad}` is not a stage (scanner, localise, map, plan, control, motor)"),
            ));
        }
        if !(self.watchdog_period.is_finite() && self.watchdog_period >= 0.0) {
            return Err(invalid(
                "pipeline.watchdog_period",
                &format!(
                    "must be a finite number >= 0, got {:?}",
                    self.watchdog_period
                ),
            ));
        }
        if self.poll_timeout > 1.0 {
            return Err(invalid(
                "pipeline.poll_timeout",
                "must be at most 1 s (shutdown waits for it)",
            ));
        }
        if self.stall_after <= 2.0 * self.poll_timeout {
            return Err(invalid(
                "pipeline.stall_after",
                "must be more than twice pipeline.poll_timeout, or idle stages look stalled",
            ));
        }
        if self.cpu_budget > 64.0 {
            return Err(invalid(
                "pipeline.cpu_budget",
                "is a fraction of one core; more than 64 cores makes no sense",
            ));
        }
        if self.degrade_after == 0 {
            return Err(invalid("pipeline.degrade_after", "must be at least 1"));
        }
        if self.recover_after == 0 {
            return Err(invalid("pipeline.recover_after", "must be at least 1"));
        }
        if self.scan_queue == 0 || self.scan_queue > 1024 {
            return Err(invalid(
                "pipeline.scan_queue",
                &format!("must be in 1..=1024, got {}", self.scan_queue),
            ));
        }
        for (k, v) in [
            ("pipeline.late_after", self.late_after),
            ("pipeline.checkpoint_period", self.checkpoint_period),
            ("pipeline.metrics_period", self.metrics_period),
            ("pipeline.supervise_period", self.supervise_period),
            ("pipeline.watchdog_period", self.watchdog_period),
            ("pipeline.stall_after", self.stall_after),
            ("pipeline.stop_timeout", self.stop_timeout),
        ] {
            if v > 3600.0 {
                return Err(invalid(k, &format!("must be at most 3600 s, got {v:?}")));
            }
        }
        self.budget.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realtime_settings_are_checked() {
        let mut p = PipelineParams::default();
        assert_eq!(p.realtime_priority, 0, "off by default");
        p.validate().unwrap();
        p.realtime_priority = 20;
        p.validate().unwrap();
        p.realtime_priority = 100;
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains("pipeline.realtime_priority"), "{e}");
        p.realtime_priority = 20;
        p.realtime_stages.push("vacuum".into());
        let e = p.validate().unwrap_err().to_string();
        assert!(
            e.contains("pipeline.realtime_stages") && e.contains("vacuum"),
            "{e}"
        );
    }
}
