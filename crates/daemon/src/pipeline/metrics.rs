//! Metrics: latency histograms that never allocate on record, and the
//! serialisable snapshot (per stage, per edge, whole process) that the
//! supervisor writes to `metrics.toml` in the run folder and the report reads.

use std::path::Path;
use std::time::Duration;

use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};

/// Highest latency a histogram tracks; longer values saturate at it (a stage
/// stuck this long is stalled anyway).
pub(crate) const HIGHEST_NS: u64 = 10_000_000_000;
/// Significant decimal digits kept (0.1 % value resolution).
const SIGFIG: u8 = 3;

/// Quantile `q` in [0, 1] of ascending-sorted samples by the nearest rank
/// (index `round((n - 1) q)`); NaN for no samples. The one rule the benches
/// and the replay summary print their p50/p99 with.
pub fn quantile_sorted(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// A latency histogram in nanoseconds (HdrHistogram, 1 ns .. 10 s, 3 digits).
/// Its bounds are fixed at construction, so [`LatencyHistogram::record`] never
/// allocates.
#[derive(Clone, Debug)]
pub struct LatencyHistogram(Histogram<u64>);

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self::new()
    }
}

impl LatencyHistogram {
    /// An empty histogram (allocates its ~200 KB of counters once).
    pub fn new() -> Self {
        // The bounds are constants hdrhistogram accepts (low >= 1, high >= 2 * low,
        // sigfig <= 5); the constructor is fallible only for other arguments.
        Self(Histogram::new_with_bounds(1, HIGHEST_NS, SIGFIG).expect("constant histogram bounds"))
    }

    /// Records one latency; values beyond 10 s saturate, zero counts as 1 ns.
    pub fn record(&mut self, d: Duration) {
        self.record_ns(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    }

    /// Records one latency given in nanoseconds.
    pub fn record_ns(&mut self, ns: u64) {
        self.0.saturating_record(ns.clamp(1, HIGHEST_NS));
    }

    /// Number of recorded values.
    pub fn count(&self) -> u64 {
        self.0.len()
    }

    /// The latency at quantile `q` in 0..=1 (zero when empty).
    pub fn quantile(&self, q: f64) -> Duration {
        if self.0.is_empty() {
            return Duration::ZERO;
        }
        let q = if q.is_finite() {
            q.clamp(0.0, 1.0)
        } else {
            1.0
        };
        Duration::from_nanos(self.0.highest_equivalent(self.0.value_at_quantile(q)))
    }

    /// Largest recorded latency (zero when empty).
    pub fn max(&self) -> Duration {
        if self.0.is_empty() {
            return Duration::ZERO;
        }
        Duration::from_nanos(self.0.max())
    }

    /// Values above `limit` (to the histogram's resolution: a value in the
    /// same bucket as `limit` counts as not above).
    pub fn count_above(&self, limit: Duration) -> u64 {
        let limit = u64::try_from(limit.as_nanos()).unwrap_or(u64::MAX);
        self.0
            .iter_recorded()
            .filter(|v| self.0.lowest_equivalent(v.value_iterated_to()) > limit)
            .map(|v| v.count_at_value())
            .sum()
    }

    /// Makes `self` a copy of `other` without allocating (same bounds).
    pub fn copy_from(&mut self, other: &LatencyHistogram) {
        self.0.reset();
        // Same bounds on both sides: add() is a plain memory copy and cannot fail.
        let _ = self.0.add(&other.0);
    }

    /// Forgets every recorded value.
    pub fn reset(&mut self) {
        self.0.reset();
    }

    /// The recorded values as (value ns, count) pairs, for the metrics file.
    pub(crate) fn to_buckets(&self) -> Buckets {
        Buckets(
            self.0
                .iter_recorded()
                .map(|v| (v.value_iterated_to(), v.count_at_value()))
                .collect(),
        )
    }

    /// Rebuilds a histogram from stored buckets (values are clamped into range).
    pub fn from_buckets(b: &Buckets) -> Self {
        let mut h = Self::new();
        for &(v, n) in &b.0 {
            h.0.saturating_record_n(v.clamp(1, HIGHEST_NS), n);
        }
        h
    }

    /// The underlying HdrHistogram, for iteration in reports.
    pub fn inner(&self) -> &Histogram<u64> {
        &self.0
    }
}

/// A histogram in the metrics file: (latency ns, count) pairs of the
/// non-empty HdrHistogram buckets.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Buckets(pub Vec<(u64, u64)>);

/// Quantiles of a latency distribution in seconds, for tables.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Quantiles {
    /// Values recorded.
    pub count: u64,
    /// Median (s).
    pub p50: f64,
    /// 99th percentile (s).
    pub p99: f64,
    /// Largest (s).
    pub max: f64,
}

impl Quantiles {
    /// Quantiles of `h`.
    pub fn of(h: &LatencyHistogram) -> Self {
        Self {
            count: h.count(),
            p50: h.quantile(0.5).as_secs_f64(),
            p99: h.quantile(0.99).as_secs_f64(),
            max: h.max().as_secs_f64(),
        }
    }
}

/// One stage's counters and histograms.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StageMetrics {
    /// Stage name (thread name).
    pub name: String,
    /// Latency budget (s).
    pub budget: f64,
    /// Work items processed.
    pub iterations: u64,
    /// Iterations that took longer than the budget.
    pub overruns: u64,
    /// Times the degradation level was raised.
    pub degrade_raises: u64,
    /// Degradation level at snapshot time.
    pub degrade_level: u8,
    /// Highest degradation level reached.
    pub degrade_peak: u8,
    /// Inputs older than `pipeline.late_after` when taken.
    pub late: u64,
    /// Errors the stage reported (each also logged, rate-limited).
    pub errors: u64,
    /// Thread CPU time (s).
    pub cpu: f64,
    /// Wall time spent processing (s), waiting excluded.
    pub busy: f64,
    /// Whether the thread ended on a fatal error.
    pub failed: bool,
    /// Processing latency quantiles.
    pub latency_q: Quantiles,
    /// End-to-end latency quantiles (scan's last byte → this stage's output),
    /// for the stages that record it.
    pub end_to_end_q: Quantiles,
    /// Processing latency distribution.
    pub latency: Buckets,
    /// End-to-end latency distribution.
    pub end_to_end: Buckets,
}

/// One edge's counters.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EdgeMetrics {
    /// Edge name.
    pub name: String,
    /// Overflow policy (`DropOldest`, `RejectNewest`, `Block`).
    pub policy: String,
    /// Capacity in messages.
    pub capacity: usize,
    /// Messages accepted.
    pub sent: u64,
    /// Messages taken by the consumer.
    pub received: u64,
    /// Messages dropped by the policy.
    pub dropped: u64,
    /// Queue depth at snapshot time.
    pub depth: usize,
    /// Deepest seen.
    pub max_depth: usize,
}

/// Supervisor counters.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SupervisorMetrics {
    /// `WATCHDOG=1` sent.
    pub watchdog_pets: u64,
    /// Supervisor checks that found a stalled stage (watchdog withheld).
    pub stall_checks: u64,
    /// Notifications that failed to send.
    pub notify_errors: u64,
}

/// CPU throttling of the daemon's cgroup during the run (`CPUQuota=`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct ThrottleMetrics {
    /// Quota enforcement periods elapsed (0 without a quota).
    pub periods: u64,
    /// Periods that ran out of quota.
    pub(crate) throttled: u64,
    /// Time held back (s).
    pub(crate) throttled_time: f64,
}

/// CPU time of the process's threads of one name since the pipeline
/// started (see [`super::threads`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ThreadMetrics {
    /// Thread name (15 characters at most, as the kernel keeps it).
    pub name: String,
    /// User + system CPU time (s), 10 ms ticks.
    pub cpu: f64,
}

/// Everything the report needs, at one instant of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MetricsSnapshot {
    /// Metrics file format version.
    pub version: u32,
    /// Wall time since the pipeline started (s).
    pub wall: f64,
    /// CPU cores available to the process.
    pub cores: usize,
    /// Process CPU time since the pipeline started (s), all threads.
    pub process_cpu: f64,
    /// Process CPU by thread name, largest first (empty without `/proc`).
    pub threads: Vec<ThreadMetrics>,
    /// Whole-process CPU budget, fraction of one core.
    pub cpu_budget: f64,
    /// Per stage, in spawn order.
    pub stages: Vec<StageMetrics>,
    /// Per edge, in creation order.
    pub edges: Vec<EdgeMetrics>,
    /// Supervisor counters.
    pub supervisor: SupervisorMetrics,
    /// cgroup CPU throttling, where the cgroup's `cpu.stat` is readable.
    pub(crate) throttling: Option<ThrottleMetrics>,
    /// Seconds of the run's clock per wall-clock second: 1 on a robot, the
    /// simulator's `--speed` in a simulation (0 in files written before it
    /// was recorded: read as 1).
    pub time_scale: f64,
}

/// Version written into metrics files by this build.
pub(crate) const METRICS_VERSION: u32 = 1;

/// File name of the metrics file inside a run folder.
pub const METRICS_FILE: &str = "metrics.toml";

/// Why a metrics file could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    /// File system error.
    #[error("metrics file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// OS error.
        source: std::io::Error,
    },
    /// The file is not a metrics file this build understands.
    #[error("metrics file {path} is malformed: {message}")]
    Format {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
}

impl MetricsSnapshot {
    /// Process CPU as a fraction of one core over the wall time.
    pub fn cpu_share(&self) -> f64 {
        if self.wall > 0.0 {
            self.process_cpu / self.wall
        } else {
            0.0
        }
    }

    /// The clock's rate against the wall (1 when not recorded).
    pub fn scale(&self) -> f64 {
        if self.time_scale > 0.0 {
            self.time_scale
        } else {
            1.0
        }
    }

    /// CPU seconds per second of the run's clock, as a share of one core:
    /// what a robot running the same work in real time would use, the
    /// figure the budget is about. Equals [`Self::cpu_share`] at scale 1.
    pub fn real_time_share(&self) -> f64 {
        self.cpu_share() / self.scale()
    }

    /// The end-to-end histogram merged over every stage that records it.
    pub fn end_to_end(&self) -> LatencyHistogram {
        let mut h = LatencyHistogram::new();
        for s in &self.stages {
            for &(v, n) in &s.end_to_end.0 {
                h.0.saturating_record_n(v.clamp(1, HIGHEST_NS), n);
            }
        }
        h
    }

    /// Messages dropped on every edge.
    pub fn dropped(&self) -> u64 {
        self.edges.iter().map(|e| e.dropped).sum()
    }

    /// Late inputs over every stage.
    pub fn late(&self) -> u64 {
        self.stages.iter().map(|s| s.late).sum()
    }

    /// Writes the snapshot as TOML to `path` atomically (tmp + rename).
    pub fn write(&self, path: &Path) -> Result<(), MetricsError> {
        let io = |source| MetricsError::Io {
            path: path.display().to_string(),
            source,
        };
        let text = toml::to_string(self).map_err(|e| MetricsError::Format {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        let tmp = path.with_extension("toml.tmp");
        std::fs::write(&tmp, text).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }

    /// Reads a metrics file written by [`MetricsSnapshot::write`].
    pub fn read(path: &Path) -> Result<Self, MetricsError> {
        let text = std::fs::read_to_string(path).map_err(|source| MetricsError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let snap: Self = toml::from_str(&text).map_err(|e| MetricsError::Format {
            path: path.display().to_string(),
            message: e.to_string().trim_end().replace('\n', " "),
        })?;
        if snap.version != METRICS_VERSION {
            return Err(MetricsError::Format {
                path: path.display().to_string(),
                message: format!(
                    "version {} (this build reads version {METRICS_VERSION})",
                    snap.version
                ),
            });
        }
        Ok(snap)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sorted_quantile_takes_the_nearest_rank() {
        let v = [1.0, 2.0, 3.0, 4.0, 10.0];
        assert_eq!(quantile_sorted(&v, 0.0), 1.0);
        assert_eq!(quantile_sorted(&v, 0.5), 3.0);
        assert_eq!(quantile_sorted(&v, 0.99), 10.0);
        assert_eq!(quantile_sorted(&v, 0.6), 3.0);
        assert_eq!(quantile_sorted(&v, 2.0), 10.0);
        assert!(quantile_sorted(&[], 0.5).is_nan());
    }

    #[test]
    fn quantiles_follow_the_data() {
        let mut h = LatencyHistogram::new();
        for us in 1..=100u64 {
            h.record(Duration::from_micros(us));
        }
        assert_eq!(h.count(), 100);
        let p50 = h.quantile(0.5).as_micros();
        assert!((49..=51).contains(&p50), "p50 {p50}");
        let p99 = h.quantile(0.99).as_micros();
        assert!((98..=100).contains(&p99), "p99 {p99}");
        assert_eq!(h.count_above(Duration::from_micros(90)), 10);
        h.record(Duration::from_secs(3600));
        assert_eq!(h.max(), Duration::from_nanos(h.inner().max()));
        assert!(h.max() >= Duration::from_secs(9));
    }

    #[test]
    fn buckets_round_trip_through_the_file() {
        let mut h = LatencyHistogram::new();
        for ns in [10, 2_000, 2_000, 300_000, 7_000_000] {
            h.record_ns(ns);
        }
        let snap = MetricsSnapshot {
            version: METRICS_VERSION,
            wall: 2.0,
            cores: 2,
            process_cpu: 0.1,
            cpu_budget: 0.05,
            stages: vec![StageMetrics {
                name: "map".into(),
                latency: h.to_buckets(),
                end_to_end: h.to_buckets(),
                latency_q: Quantiles::of(&h),
                ..Default::default()
            }],
            ..Default::default()
        };
        let dir = std::env::temp_dir().join(format!("sweepline-metrics-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(METRICS_FILE);
        snap.write(&path).unwrap();
        let back = MetricsSnapshot::read(&path).unwrap();
        assert_eq!(back, snap);
        let h2 = LatencyHistogram::from_buckets(&back.stages[0].latency);
        assert_eq!(h2.count(), 5);
        assert_eq!(h2.quantile(1.0), h.quantile(1.0));
        assert_eq!(back.end_to_end().count(), 5);
        assert!((back.cpu_share() - 0.05).abs() < 1e-12);
        std::fs::write(&path, "version = 99\n").unwrap();
        let e = MetricsSnapshot::read(&path).unwrap_err();
        assert!(e.to_string().contains("version 99"), "{e}");
        std::fs::write(&path, "wall = \"x\"\n").unwrap();
        let e = MetricsSnapshot::read(&path).unwrap_err();
        assert!(e.to_string().contains("wall"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn copy_from_matches_the_source() {
        let mut a = LatencyHistogram::new();
        let mut b = LatencyHistogram::new();
        b.record_ns(5);
        a.record_ns(1_000);
        a.record_ns(2_000);
        b.copy_from(&a);
        assert_eq!(b.count(), 2);
        assert_eq!(b.max(), a.max());
    }
}
