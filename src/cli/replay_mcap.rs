//! `sweepline replay run.mcap`: a recording of `sweepline sim` or
//! `sweepline run` through the daemon's own localise and map stages.
//!
//! Outputs in `--out`: `trajectory.txt` (`timestamp x y theta` per scan,
//! map frame, the input of `sweepline eval`) and `summary.txt`. A
//! simulator's recording carries the true poses: the summary scores the
//! replayed poses against them as the run's own report scored the live ones.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use super::CliResult;
use crate::config::Config;
use crate::daemon::replay::Replayer;
use crate::geom::Pose;
use crate::live::recording::Recording;
use crate::pipeline::clock::thread_cpu_time;
use crate::sim::eval::{format_trajectory, Stamped};

/// What a recording's replay produced.
#[derive(Debug, Default)]
pub struct McapReplay {
    /// The pose handed on for each scan (map frame).
    pub trajectory: Vec<Stamped>,
    /// The matched poses only (as the live run's report scores them).
    pub matched: Vec<(f64, Pose)>,
    /// Scans replayed.
    pub scans: usize,
    /// CPU time of the localise and map stages per scan (s).
    pub cpu: Vec<f64>,
    /// Position RMSE, heading RMSE, max position error and scored pairs
    /// against the recorded truth (`sim` recordings).
    pub score: Option<(f64, f64, f64, usize)>,
    /// The file was cut short (read up to its last whole chunk).
    pub cut_short: bool,
}

/// Replays the recording at `path`, with `config` instead of the recorded
/// configuration when given.
pub fn replay_recording(path: &Path, config: Option<Config>) -> Result<McapReplay, String> {
    let rec = Recording::read(path).map_err(|e| e.to_string())?;
    let setup = rec
        .setup
        .clone()
        .ok_or_else(|| {
            format!(
                "{}: no setup recorded (not a sweepline recording?)",
                path.display()
            )
        })?
        .map_err(|e| format!("{}: {e}", path.display()))?;
    if rec.scans.is_empty() {
        return Err(format!("{}: no scans recorded", path.display()));
    }
    let cfg = config.unwrap_or(setup.config);
    let mut replayer = Replayer::new(&cfg, setup.start, setup.frame).map_err(|e| e.to_string())?;
    let mut out = McapReplay {
        cut_short: !rec.complete,
        ..Default::default()
    };
    for r in &rec.scans {
        let tap = r.to_tap().map_err(|e| format!("{}: {e}", path.display()))?;
        let c0 = thread_cpu_time().as_secs_f64();
        let fix = replayer.step(tap.msg);
        out.cpu.push(thread_cpu_time().as_secs_f64() - c0);
        out.scans += 1;
        let Some(f) = fix else {
            return Err(format!(
                "{}: the localise stage stopped at scan {} (see the log)",
                path.display(),
                r.seq
            ));
        };
        out.trajectory.push(Stamped {
            t: f.stamp,
            pose: f.pose,
        });
        if f.matched {
            out.matched.push((f.stamp, f.pose));
        }
    }
    if let Some(to_w) = rec.map_to_world.filter(|_| !rec.truth.is_empty()) {
        out.score = Some(crate::sim::closed_loop::score_fixes(
            &out.matched,
            &rec.truth,
            &to_w,
        ));
    }
    Ok(out)
}

/// The summary text.
fn summary(path: &Path, r: &McapReplay, wall: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "recording: {}{}",
        path.display(),
        if r.cut_short {
            " (cut short: read to its last whole chunk)"
        } else {
            ""
        }
    );
    let _ = writeln!(
        s,
        "scans: {} replayed, {} matched ({:.1} %), {wall:.1} s wall",
        r.scans,
        r.matched.len(),
        100.0 * r.matched.len() as f64 / r.scans.max(1) as f64
    );
    let mut cpu = r.cpu.clone();
    cpu.sort_by(f64::total_cmp);
    if !cpu.is_empty() {
        let mean = cpu.iter().sum::<f64>() / cpu.len() as f64;
        let p99 = crate::pipeline::metrics::quantile_sorted(&cpu, 0.99);
        let _ = writeln!(
            s,
            "CPU per scan (localise + map stages): mean {:.3} ms, p99 {:.3} ms",
            mean * 1e3,
            p99 * 1e3
        );
    }
    match r.score {
        Some((pos, head, max, n)) => {
            let _ = writeln!(
                s,
                "against the recorded truth: position RMSE {:.1} mm, heading RMSE {:.2}°, max {:.1} mm ({n} poses scored)",
                pos * 1e3,
                head.to_degrees(),
                max * 1e3
            );
        }
        None => {
            let _ = writeln!(s, "no truth recorded: not scored");
        }
    }
    s
}

/// `sweepline replay` of a recording.
pub fn run(path: &Path, out: &Path, config: Option<&Path>) -> CliResult {
    let config = config.map(Config::load).transpose()?;
    let t0 = Instant::now();
    let r = replay_recording(path, config)?;
    let wall = t0.elapsed().as_secs_f64();
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let traj = out.join("trajectory.txt");
    std::fs::write(&traj, format_trajectory(&r.trajectory))
        .map_err(|e| format!("cannot write {}: {e}", traj.display()))?;
    let text = summary(path, &r, wall);
    let sum = out.join("summary.txt");
    std::fs::write(&sum, &text).map_err(|e| format!("cannot write {}: {e}", sum.display()))?;
    print!("{text}");
    println!("wrote {}, {}", traj.display(), sum.display());
    Ok(())
}
