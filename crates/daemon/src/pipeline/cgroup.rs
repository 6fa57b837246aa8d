//! CPU throttling of the daemon's cgroup (`CPUQuota=` in the unit): how many
//! scheduler periods ran out of quota and for how long the daemon was held.
//! Throttling shows up as latency spikes in every stage at once, so the
//! report prints it beside the histograms. Reads `cpu.stat` of cgroup v2 or
//! of the v1 `cpu` controller; absent (None) where neither is readable.

use std::path::PathBuf;

/// Throttling counters of a cgroup.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Throttling {
    /// Enforcement periods that elapsed (0 without a quota).
    pub periods: u64,
    /// Periods in which the cgroup ran out of quota.
    pub(crate) throttled: u64,
    /// Total time the cgroup was held back (µs).
    pub(crate) throttled_us: u64,
}

impl Throttling {
    /// Counters accumulated since `earlier` (saturating).
    pub fn since(&self, earlier: &Throttling) -> Throttling {
        Throttling {
            periods: self.periods.saturating_sub(earlier.periods),
            throttled: self.throttled.saturating_sub(earlier.throttled),
            throttled_us: self.throttled_us.saturating_sub(earlier.throttled_us),
        }
    }
}

/// Parses a `cpu.stat` file: v2 (`nr_periods`, `nr_throttled`,
/// `throttled_usec`) or v1 (`throttled_time` in ns). Unknown lines are ignored.
pub(crate) fn parse_cpu_stat(text: &str) -> Throttling {
    let mut t = Throttling::default();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        let (Some(k), Some(v)) = (it.next(), it.next()) else {
            continue;
        };
        let Ok(v) = v.parse::<u64>() else { continue };
        match k {
            "nr_periods" => t.periods = v,
            "nr_throttled" => t.throttled = v,
            "throttled_usec" => t.throttled_us = v,
            "throttled_time" => t.throttled_us = v / 1000,
            _ => {}
        }
    }
    t
}

/// Candidate `cpu.stat` paths for this process, from `/proc/self/cgroup`.
fn candidates(proc_cgroup: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for line in proc_cgroup.lines() {
        let mut parts = line.splitn(3, ':');
        let (Some(_), Some(ctrl), Some(path)) = (parts.next(), parts.next(), parts.next()) else {
            continue;
        };
        let rel = path.trim_start_matches('/');
        if ctrl.is_empty() {
            out.push(PathBuf::from("/sys/fs/cgroup").join(rel).join("cpu.stat"));
        } else if ctrl.split(',').any(|c| c == "cpu") {
            out.push(
                PathBuf::from("/sys/fs/cgroup")
                    .join(ctrl)
                    .join(rel)
                    .join("cpu.stat"),
            );
            out.push(
                PathBuf::from("/sys/fs/cgroup/cpu")
                    .join(rel)
                    .join("cpu.stat"),
            );
        }
    }
    out
}

/// The throttling counters of this process's cgroup, if readable.
pub(crate) fn read_throttling() -> Option<Throttling> {
    let pc = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    candidates(&pc)
        .into_iter()
        .find_map(|p| std::fs::read_to_string(p).ok())
        .map(|t| parse_cpu_stat(&t))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_both_cgroup_versions() {
        let v2 =
            "usage_usec 100\nnr_periods 50\nnr_throttled 3\nthrottled_usec 1200\nnr_bursts 0\n";
        assert_eq!(
            parse_cpu_stat(v2),
            Throttling {
                periods: 50,
                throttled: 3,
                throttled_us: 1200
            }
        );
        let v1 = "nr_periods 7\nnr_throttled 2\nthrottled_time 5000000\n";
        assert_eq!(parse_cpu_stat(v1).throttled_us, 5000);
        assert_eq!(
            parse_cpu_stat("garbage\nnr_periods x\n"),
            Throttling::default()
        );
        let a = Throttling {
            periods: 10,
            throttled: 1,
            throttled_us: 5,
        };
        assert_eq!(a.since(&parse_cpu_stat(v2)).periods, 0);
    }

    #[test]
    fn finds_candidate_files() {
        let c = candidates("0::/system.slice/sweepline.service\n");
        assert_eq!(
            c,
            vec![PathBuf::from(
                "/sys/fs/cgroup/system.slice/sweepline.service/cpu.stat"
            )]
        );
        let c = candidates("4:cpu,cpuacct:/a\n3:memory:/b\n");
        assert_eq!(c[0], PathBuf::from("/sys/fs/cgroup/cpu,cpuacct/a/cpu.stat"));
        assert!(candidates("nonsense").is_empty());
    }
}
