//! The "Checkpoint and resume" part of a run's report: how often the run was
//! resumed, from which checkpoint, how old that checkpoint was when the
//! daemon before died and how much progress that cost.

use std::fmt::Write as _;

use crate::pipeline::checkpoint::{ProgressMark, ResumeEntry, ResumeLog};

/// `unix` (s since 1970) as `YYYY-MM-DD hh:mm:ss.s UTC`.
pub fn utc(unix: f64) -> String {
    if !unix.is_finite() || unix < 0.0 {
        return "unknown time".into();
    }
    let tenths = (unix * 10.0).round() as i64;
    let secs = tenths.div_euclid(10);
    let days = secs.div_euclid(86_400);
    let sod = secs.rem_euclid(86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02}.{} UTC",
        sod / 3600,
        sod / 60 % 60,
        sod % 60,
        tenths.rem_euclid(10)
    )
}

fn when(m: &ProgressMark) -> String {
    match m.unix {
        Some(u) => format!("{}, run clock {:.1} s", utc(u), m.elapsed),
        None => format!("run clock {:.1} s (wall time not recorded)", m.elapsed),
    }
}

fn entry_markdown(md: &mut String, e: &ResumeEntry) {
    let cp = &e.checkpoint;
    let _ = writeln!(md, "### Restart {}\n", e.restart);
    let _ = writeln!(md, "- resumed at: {}", utc(e.resumed_unix));
    let _ = writeln!(
        md,
        "- checkpoint: #{}, written at {}",
        cp.sequence,
        when(cp)
    );
    if let Some(why) = &e.fell_back {
        let _ = writeln!(
            md,
            "- the newest checkpoint was unusable ({why}): its previous copy was used"
        );
    }
    let _ = writeln!(
        md,
        "- coverage at checkpoint: {:.1} % (daemon's record)",
        cp.coverage * 100.0
    );
    match e.last_alive {
        Some(a) => {
            let _ = writeln!(md, "- last sign of life: {}", when(&a));
            let _ = writeln!(md, "- coverage at crash: {:.1} %", a.coverage * 100.0);
            let wall = e
                .checkpoint_age_wall()
                .map(|w| format!(" ({w:.2} s wall)"))
                .unwrap_or_default();
            let _ = writeln!(
                md,
                "- checkpoint age at crash: {:.1} s run clock{wall}",
                e.checkpoint_age().unwrap_or(0.0)
            );
            let _ = writeln!(
                md,
                "- progress lost: **{:.1} points of coverage**, {} scans, {:.2} m of path",
                e.coverage_lost().unwrap_or(0.0) * 100.0,
                a.scans.saturating_sub(cp.scans),
                (a.path_length - cp.path_length).max(0.0)
            );
        }
        None => {
            let _ = writeln!(
                md,
                "- last sign of life: unknown (no heartbeat after the checkpoint)"
            );
            let _ = writeln!(md, "- coverage at crash: unknown");
            let _ = writeln!(
                md,
                "- progress lost: unknown (at most what was done in one checkpoint period)"
            );
        }
    }
    if let Some(d) = e.downtime() {
        let _ = writeln!(md, "- down for: {d:.1} s wall");
    }
    let _ = writeln!(md);
}

/// The Markdown section for a run's resumes (`None`: a fresh start).
pub(crate) fn resume_markdown(log: Option<&ResumeLog>) -> String {
    let mut md = String::from("## Checkpoint and resume\n\n");
    let Some(log) = log.filter(|l| !l.resume.is_empty()) else {
        md += "Restarts: **0**. The run started fresh (it did not resume from a checkpoint).\n";
        return md;
    };
    let lost: f64 = log
        .resume
        .iter()
        .filter_map(ResumeEntry::coverage_lost)
        .sum();
    let restarts = log.resume.iter().map(|e| e.restart).max().unwrap_or(0);
    let _ = writeln!(
        md,
        "Restarts: **{restarts}**. The daemon was restarted and resumed its coverage from its \
         last checkpoint; progress made after that checkpoint was lost and done again \
         ({:.1} points of coverage in all, where the crashed daemon's heartbeat tells).\n",
        lost * 100.0
    );
    let _ = writeln!(
        md,
        "Coverage here is the daemon's own record (swept floor over the free floor it had \
         mapped). The checkpoint's age at the crash is measured to the crashed daemon's last \
         heartbeat (`pipeline.heartbeat_period`), so the true age is at most one heartbeat \
         period more.\n"
    );
    for e in &log.resume {
        entry_markdown(&mut md, e);
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_dates() {
        assert_eq!(utc(0.0), "1970-01-01 00:00:00.0 UTC");
        assert_eq!(utc(951_782_400.25), "2000-02-29 00:00:00.3 UTC");
        assert_eq!(utc(1_795_400_000.0), "2026-11-23 02:13:20.0 UTC");
        assert_eq!(utc(f64::NAN), "unknown time");
    }

    fn mark(seq: u64, elapsed: f64, coverage: f64) -> ProgressMark {
        ProgressMark {
            sequence: seq,
            unix: Some(1_795_400_000.0 + elapsed / 10.0),
            elapsed,
            coverage,
            scans: (elapsed * 10.0) as u64,
            path_length: elapsed * 0.2,
        }
    }

    #[test]
    fn report_says_what_was_lost() {
        let fresh = resume_markdown(None);
        assert!(fresh.contains("Restarts: **0**"), "{fresh}");
        let log = ResumeLog {
            resume: vec![
                ResumeEntry {
                    restart: 1,
                    resumed_unix: 1_795_400_012.0,
                    checkpoint: mark(12, 109.0, 0.307),
                    last_alive: Some(mark(12, 110.0, 0.312)),
                    fell_back: None,
                },
                ResumeEntry {
                    restart: 2,
                    resumed_unix: 1_795_400_030.0,
                    checkpoint: mark(20, 200.0, 0.6),
                    last_alive: None,
                    fell_back: Some("file checksum mismatch".into()),
                },
            ],
        };
        let md = resume_markdown(Some(&log));
        for line in [
            "Restarts: **2**",
            "### Restart 1",
            "- checkpoint: #12, written at 2026-11-23 02:13:30.9 UTC, run clock 109.0 s",
            "- coverage at checkpoint: 30.7 %",
            "- last sign of life: 2026-11-23 02:13:31.0 UTC, run clock 110.0 s",
            "- coverage at crash: 31.2 %",
            "- checkpoint age at crash: 1.0 s run clock (0.10 s wall)",
            "- progress lost: **0.5 points of coverage**, 10 scans, 0.20 m of path",
            "- down for: 1.0 s wall",
            "### Restart 2",
            "its previous copy was used",
            "- coverage at crash: unknown",
        ] {
            assert!(md.contains(line), "missing {line:?} in\n{md}");
        }
    }
}
