//! The latency / CPU-budget report of a run: `report.md` (per-stage table of
//! p50, p99, max, budget and overruns; CPU share against the budget; drops,
//! late inputs, channel depths; supervisor counters) and one SVG latency
//! histogram per stage plus the end-to-end one, written into the run folder,
//! and, from the folder's `resume.toml`, what restarts of the run lost.
//! Built from a [`MetricsSnapshot`] and that record alone, so `sweepline report RUN_DIR` can
//! regenerate it from `metrics.toml` at any time.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use super::histogram::{fmt_duration, latency_svg};
use super::resume::resume_markdown;
use crate::pipeline::checkpoint::ResumeLog;
use crate::pipeline::metrics::{LatencyHistogram, MetricsSnapshot, Quantiles, METRICS_FILE};

/// Target p99 of the end-to-end latency (scan's last byte → wheel command), s.
pub(crate) const END_TO_END_P99_TARGET: f64 = 0.005;

/// File name of the Markdown report.
pub const REPORT_FILE: &str = "report.md";

/// Why a report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// File system error.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// OS error.
        source: std::io::Error,
    },
    /// The metrics file is missing or unreadable.
    #[error(transparent)]
    Metrics(#[from] crate::pipeline::metrics::MetricsError),
}

fn pct(x: f64) -> String {
    format!("{:.2} %", x * 100.0)
}

/// `cpu` seconds as a share of one core over `wall` seconds ("–" for none).
fn core_share(cpu: f64, wall: f64) -> String {
    if wall > 0.0 {
        pct(cpu / wall)
    } else {
        "–".into()
    }
}

fn ok_mark(ok: bool) -> &'static str {
    if ok {
        "within"
    } else {
        "OVER"
    }
}

/// File name of a stage's histogram picture.
pub fn histogram_file(stage: &str) -> String {
    let safe: String = stage
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("latency-{safe}.svg")
}

/// The Markdown text of the report.
pub(crate) fn budget_markdown(s: &MetricsSnapshot) -> String {
    let mut md = String::new();
    let share = s.cpu_share();
    let _ = writeln!(md, "# Latency and CPU budget\n");
    if s.scale() == 1.0 {
        let _ = writeln!(
            md,
            "Run of {:.1} s wall time on {} core{}. Process CPU {:.2} s = **{} of one core** \
             ({} of the machine) against a budget of {} of one core: **{}** budget.\n",
            s.wall,
            s.cores,
            if s.cores == 1 { "" } else { "s" },
            s.process_cpu,
            pct(share),
            pct(share / s.cores.max(1) as f64),
            pct(s.cpu_budget),
            ok_mark(share <= s.cpu_budget),
        );
    } else {
        // A simulation at N times real time does N seconds of robot work
        // per wall second: the budget is about one second of robot time.
        let real = s.real_time_share();
        let _ = writeln!(
            md,
            "Run of {:.1} s wall time on {} core{}, the clock at {} × real time. Process CPU \
             {:.2} s = {} of one core per wall second; **{} of one core per second of robot \
             time** against a budget of {} of one core: **{}** budget.\n",
            s.wall,
            s.cores,
            if s.cores == 1 { "" } else { "s" },
            s.scale(),
            s.process_cpu,
            pct(share),
            pct(real),
            pct(s.cpu_budget),
            ok_mark(real <= s.cpu_budget),
        );
    }

    match &s.throttling {
        Some(t) if t.periods > 0 => {
            let _ = writeln!(
                md,
                "cgroup CPU quota: {} of {} enforcement periods throttled, {} held back in all \
                 (throttling delays every stage at once).\n",
                t.throttled,
                t.periods,
                fmt_duration(t.throttled_time)
            );
        }
        Some(_) => {
            let _ = writeln!(md, "cgroup CPU quota: none in force during this run.\n");
        }
        None => {}
    }

    let e2e = s.end_to_end();
    let q = Quantiles::of(&e2e);
    let _ = writeln!(md, "## End-to-end latency\n");
    if q.count == 0 {
        let _ = writeln!(md, "No stage recorded end-to-end latency in this run.\n");
    } else {
        let _ = writeln!(
            md,
            "Scan's last byte → the wheel command it produced, {} commands: \
             p50 {}, p99 **{}**, max {} (target p99 ≤ {}: **{}**).\n",
            q.count,
            fmt_duration(q.p50),
            fmt_duration(q.p99),
            fmt_duration(q.max),
            fmt_duration(END_TO_END_P99_TARGET),
            ok_mark(q.p99 <= END_TO_END_P99_TARGET),
        );
        let _ = writeln!(
            md,
            "![end-to-end latency]({})\n",
            histogram_file("end-to-end")
        );
    }

    let _ = writeln!(md, "## Stages\n");
    let _ = writeln!(
        md,
        "| stage | items | p50 | p99 | max | budget | overruns | degrade raises / peak / now | late | errors | CPU | CPU share of one core |"
    );
    let _ = writeln!(md, "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|");
    for st in &s.stages {
        let over_pct = if st.iterations > 0 {
            format!(
                " ({:.1} %)",
                st.overruns as f64 / st.iterations as f64 * 100.0
            )
        } else {
            String::new()
        };
        let _ = writeln!(
            md,
            "| {}{} | {} | {} | {} | {} | {} | {}{} | {} / {} / {} | {} | {} | {:.3} s | {} |",
            st.name,
            if st.failed { " (FAILED)" } else { "" },
            st.iterations,
            fmt_duration(st.latency_q.p50),
            fmt_duration(st.latency_q.p99),
            fmt_duration(st.latency_q.max),
            fmt_duration(st.budget),
            st.overruns,
            over_pct,
            st.degrade_raises,
            st.degrade_peak,
            st.degrade_level,
            st.late,
            st.errors,
            st.cpu,
            core_share(st.cpu, s.wall),
        );
    }
    let _ = writeln!(
        md,
        "\nLatency is the wall time of one work item, from taking it to handing the results \
         on to the next stages (waiting excluded; so is the wake-up of the next stage, which \
         may take the core during the send); an overrun is an item \
         over the stage budget; repeated overruns raise the stage's degradation level (the \
         stage does less work per item) and good runs lower it again. CPU is the thread's own \
         CPU time (`CLOCK_THREAD_CPUTIME_ID`), waiting included.\n"
    );

    if !s.threads.is_empty() {
        write_threads(&mut md, s);
    }

    let _ = writeln!(md, "## Channels\n");
    if s.edges.is_empty() {
        let _ = writeln!(md, "No channels were registered.\n");
    } else {
        let _ = writeln!(
            md,
            "| edge | policy | capacity | sent | received | dropped | depth now / max |"
        );
        let _ = writeln!(md, "|---|---|--:|--:|--:|--:|--:|");
        for e in &s.edges {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} / {} |",
                e.name, e.policy, e.capacity, e.sent, e.received, e.dropped, e.depth, e.max_depth
            );
        }
        let _ = writeln!(
            md,
            "\nDropped messages in all: **{}**; late inputs (older than `pipeline.late_after` when \
             taken): **{}**.\n",
            s.dropped(),
            s.late()
        );
    }

    let sup = &s.supervisor;
    let _ = writeln!(md, "## Supervisor\n");
    let _ = writeln!(
        md,
        "Watchdog pets {}, checks that found a stalled stage {}, failed notifications {}.\n",
        sup.watchdog_pets, sup.stall_checks, sup.notify_errors
    );

    let _ = writeln!(md, "## Latency histograms\n");
    for st in &s.stages {
        let _ = writeln!(md, "![{}]({})", st.name, histogram_file(&st.name));
    }
    md
}

/// The "CPU by thread" section: every thread name's CPU, and the share of
/// in-process device emulators (the simulator's), which a robot does not run.
fn write_threads(md: &mut String, s: &MetricsSnapshot) {
    let share = |cpu: f64| core_share(cpu, s.wall);
    let _ = writeln!(md, "## CPU by thread\n");
    let emulated: f64 = s
        .threads
        .iter()
        .filter(|t| crate::pipeline::threads::is_emulator(&t.name))
        .map(|t| t.cpu)
        .sum();
    if emulated > 0.0 {
        let rest = (s.process_cpu - emulated).max(0.0);
        // At a time scale other than 1 the figure judged is per second of
        // robot time, the one the budget is about.
        let judged = if s.scale() == 1.0 {
            format!("{} of one core", share(rest))
        } else {
            format!(
                "{} of one core per second of robot time ({} per wall second)",
                core_share(rest / s.scale(), s.wall),
                share(rest)
            )
        };
        let _ = writeln!(
            md,
            "In-process device emulators (threads `{}`…, the simulator's, not run on a robot): \
             {:.2} s = {} of one core; **the process without them: {judged}** \
             (against the budget of {}: **{}**).\n",
            crate::pipeline::threads::EMULATOR_PREFIXES.join("`…, `"),
            emulated,
            share(emulated),
            pct(s.cpu_budget),
            ok_mark(s.wall > 0.0 && rest / s.wall / s.scale() <= s.cpu_budget),
        );
    }
    let _ = writeln!(md, "| thread | CPU | share of one core |");
    let _ = writeln!(md, "|---|--:|--:|");
    let staged = |n: &str| s.stages.iter().any(|st| st.name == n);
    for t in s.threads.iter().filter(|t| !staged(&t.name)) {
        let _ = writeln!(md, "| {} | {:.2} s | {} |", t.name, t.cpu, share(t.cpu));
    }
    let _ = writeln!(
        md,
        "\nThreads besides the stages (whose CPU is in the table above), live when the \
         snapshot was taken: user + system time since the pipeline started \
         (`/proc/self/task/*/stat`, 10 ms ticks), summed over threads of one name. The \
         process figure counts ended threads too.\n"
    );
}

/// Writes `report.md` and the SVG histograms into `dir` (created if needed);
/// returns the report's path.
pub fn write_budget_report(dir: &Path, s: &MetricsSnapshot) -> Result<PathBuf, ReportError> {
    let io = |p: &Path| {
        let p = p.display().to_string();
        move |source| ReportError::Io { path: p, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    for st in &s.stages {
        let h = LatencyHistogram::from_buckets(&st.latency);
        let budget = (st.budget.is_finite() && st.budget > 0.0)
            .then(|| ("budget", Duration::from_secs_f64(st.budget.min(1e6))));
        let doc = latency_svg(
            &format!("stage {}: processing latency", st.name),
            &h,
            budget,
        );
        let path = dir.join(histogram_file(&st.name));
        svg::save(&path, &doc).map_err(io(&path))?;
    }
    let e2e = s.end_to_end();
    if e2e.count() > 0 {
        let doc = latency_svg(
            "end-to-end: scan's last byte → wheel command",
            &e2e,
            Some(("p99 target", Duration::from_secs_f64(END_TO_END_P99_TARGET))),
        );
        let path = dir.join(histogram_file("end-to-end"));
        svg::save(&path, &doc).map_err(io(&path))?;
    }
    let mut md = budget_markdown(s);
    md.push('\n');
    match ResumeLog::read(dir) {
        Ok(log) => md += &resume_markdown(log.as_ref()),
        Err(e) => {
            let _ = writeln!(
                md,
                "## Checkpoint and resume\n\nThe resume record is unreadable: {e}"
            );
        }
    }
    let path = dir.join(REPORT_FILE);
    std::fs::write(&path, md).map_err(io(&path))?;
    Ok(path)
}

/// `sweepline report RUN_DIR`: reads `RUN_DIR/metrics.toml` and writes the
/// report beside it.
pub fn report_run_dir(run_dir: &Path) -> Result<PathBuf, ReportError> {
    let snap = MetricsSnapshot::read(&run_dir.join(METRICS_FILE))?;
    write_budget_report(run_dir, &snap)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::metrics::{StageMetrics, ThreadMetrics};

    fn snapshot(threads: &[(&str, f64)]) -> MetricsSnapshot {
        MetricsSnapshot {
            wall: 60.0,
            cores: 2,
            process_cpu: 6.0,
            cpu_budget: 0.05,
            stages: vec![StageMetrics {
                name: "localise".into(),
                ..Default::default()
            }],
            threads: threads
                .iter()
                .map(|(n, c)| ThreadMetrics {
                    name: n.to_string(),
                    cpu: *c,
                })
                .collect(),
            ..Default::default()
        }
    }

    #[test]
    fn the_emulators_threads_are_told_apart_from_the_daemons() {
        let md = budget_markdown(&snapshot(&[
            ("emu-roboclaw", 3.0),
            ("localise", 1.0),
            ("urg-emulator", 0.6),
            ("supervisor", 0.2),
        ]));
        assert!(md.contains("**10.00 % of one core**"), "{md}");
        assert!(
            md.contains("3.60 s = 6.00 % of one core; **the process without them: 4.00 % of one core** (against the budget of 5.00 %: **within**)"),
            "{md}"
        );
        assert!(md.contains("| emu-roboclaw | 3.00 s | 5.00 % |"), "{md}");
        assert!(md.contains("| supervisor | 0.20 s | 0.33 % |"), "{md}");
        // A stage's thread is in the stage table, not listed again.
        assert!(!md.contains("| localise | 1.00 s"), "{md}");
        // Over the budget without the emulators too.
        let md = budget_markdown(&snapshot(&[("emu-create2", 1.0)]));
        assert!(md.contains("without them: 8.33 % of one core"), "{md}");
        assert!(md.contains("5.00 %: **OVER**"), "{md}");
        // At 5 × real time, 10 % of one core per wall second is 2 % per
        // second of robot time: within the 5 % budget.
        let mut fast = snapshot(&[("supervisor", 0.2)]);
        fast.time_scale = 5.0;
        let md = budget_markdown(&fast);
        assert!(
            md.contains("**2.00 % of one core per second of robot time** against a budget of 5.00 % of one core: **within**"),
            "{md}"
        );
        // The daemon without the emulators, at 5 x: 4.8 s of 60 s is 8 %
        // per wall second, 1.6 % per robot second: within.
        let mut fast = snapshot(&[("emu-roboclaw", 1.2)]);
        fast.time_scale = 5.0;
        let md = budget_markdown(&fast);
        assert!(
            md.contains("**the process without them: 1.60 % of one core per second of robot time (8.00 % per wall second)** (against the budget of 5.00 %: **within**)"),
            "{md}"
        );
        // On a robot: no emulator line, the thread table only.
        let md = budget_markdown(&snapshot(&[("supervisor", 0.2)]));
        assert!(
            md.contains("## CPU by thread") && !md.contains("emulators"),
            "{md}"
        );
        assert!(!budget_markdown(&snapshot(&[])).contains("## CPU by thread"));
    }
}
