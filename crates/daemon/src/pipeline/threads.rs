//! CPU time of every thread of the process, by name, from
//! `/proc/self/task/*/stat` (Linux): which threads share the process's CPU.
//! In the simulator the emulated devices run inside the daemon's process,
//! so the whole-process figure is the daemon's plus theirs; the report
//! tells the two apart by thread name. Elsewhere (no `/proc`) the list is
//! empty. Read only when a metrics snapshot is taken, never on the scan path.

use std::collections::BTreeMap;

/// Name prefixes of the threads of in-process device emulators (the
/// simulator's RoboClaw and Create 2 bases, its URG-04LX): not part of the
/// daemon that runs on a robot.
pub(crate) const EMULATOR_PREFIXES: [&str; 2] = ["emu-", "urg-emulator"];

/// Whether `name` is an in-process device emulator's thread.
pub(crate) fn is_emulator(name: &str) -> bool {
    EMULATOR_PREFIXES.iter().any(|p| name.starts_with(p))
}

/// Name and CPU time (user + system, s) from the text of one
/// `/proc/<pid>/task/<tid>/stat` file; `ticks` is the kernel's clock ticks
/// per second. `None` when the text is not such a line.
pub(crate) fn parse_stat(text: &str, ticks: f64) -> Option<(String, f64)> {
    // The name (comm) is in parentheses and may itself hold ") ".
    let open = text.find('(')?;
    let close = text.rfind(')')?;
    let name = text.get(open + 1..close)?.to_string();
    // After the name: state (field 3), ..., utime (14), stime (15).
    let rest: Vec<&str> = text.get(close + 1..)?.split_whitespace().collect();
    let utime: f64 = rest.get(11)?.parse().ok()?;
    let stime: f64 = rest.get(12)?.parse().ok()?;
    (ticks > 0.0).then(|| (name, (utime + stime) / ticks))
}

/// CPU time (s) of each live thread of this process, by thread id.
pub(crate) fn read_threads() -> BTreeMap<u32, (String, f64)> {
    let mut out = BTreeMap::new();
    let ticks = sweepline_io::os::clock_ticks_per_second().map_or(0.0, |t| t as f64);
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return out;
    };
    for entry in dir.flatten() {
        let Some(tid) = entry.file_name().to_str().and_then(|s| s.parse().ok()) else {
            continue;
        };
        if let Ok(text) = std::fs::read_to_string(entry.path().join("stat")) {
            if let Some(v) = parse_stat(&text, ticks) {
                out.insert(tid, v);
            }
        }
    }
    out
}

/// CPU (s) by thread name since `base` (an earlier [`read_threads`]),
/// summed over threads of one name, largest first.
pub(crate) fn cpu_by_name(base: &BTreeMap<u32, (String, f64)>) -> Vec<(String, f64)> {
    let mut by_name: BTreeMap<String, f64> = BTreeMap::new();
    for (tid, (name, cpu)) in read_threads() {
        let before = base
            .get(&tid)
            .filter(|(n, _)| *n == name)
            .map_or(0.0, |(_, c)| *c);
        *by_name.entry(name).or_default() += (cpu - before).max(0.0);
    }
    let mut v: Vec<(String, f64)> = by_name.into_iter().collect();
    v.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stat_line_gives_name_and_user_plus_system_time() {
        let line =
            "4242 (emu-roboclaw) S 1 4240 4240 0 -1 4194624 12 0 0 0 250 130 0 0 20 0 9 0 100 0 0";
        let (name, cpu) = parse_stat(line, 100.0).unwrap();
        assert_eq!(name, "emu-roboclaw");
        assert!((cpu - 3.8).abs() < 1e-12, "{cpu}");
        // A name with a parenthesis and a space in it.
        let odd = "7 (a) b) R 1 1 1 0 -1 0 0 0 0 0 5 5 0 0 20 0 1 0 1 0 0";
        assert_eq!(parse_stat(odd, 100.0).unwrap(), ("a) b".to_string(), 0.1));
        assert_eq!(parse_stat("garbage", 100.0), None);
        assert_eq!(parse_stat("1 (x) R 1 2", 100.0), None);
        assert_eq!(parse_stat(line, 0.0), None);
    }

    #[test]
    fn this_threads_cpu_is_found_by_its_name() {
        let base = read_threads();
        let t = std::thread::Builder::new()
            .name("emu-cputest".into())
            .spawn(move || {
                let t0 = std::time::Instant::now();
                let mut x = 0u64;
                while t0.elapsed().as_millis() < 200 {
                    x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
                }
                let by = cpu_by_name(&base);
                std::hint::black_box(x);
                by
            })
            .unwrap();
        let by = t.join().unwrap();
        let me = by.iter().find(|(n, _)| n == "emu-cputest");
        if std::path::Path::new("/proc/self/task").exists() {
            let (_, cpu) = me.expect("the spinning thread is listed");
            assert!(*cpu >= 0.05, "{cpu} s");
            assert!(is_emulator("emu-cputest") && !is_emulator("localise"));
        }
    }
}
