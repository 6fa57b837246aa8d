//! `sweepline replay`: runs the scan matcher over a recorded CARMEN log and writes the trajectory and a picture.
//!
//! Outputs in `--out` (default `out/replay`): `trajectory.txt` (`timestamp x y
//! theta` per scan, the input of `sweepline eval`), `replay.svg` (registered
//! points, estimated trajectory, raw odometry) and `summary.txt` (outcomes and
//! per-scan timing, also printed).

use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use svg::node::element::{Group, Path as SvgPath, Rectangle};
use svg::Document;

use super::CliResult;
use crate::config::Config;
use crate::geom::{IPoint, Pose};
use crate::icp::{IcpParams, Outcome, SearchCounts, Tracker};
use crate::pipeline::clock::thread_cpu_time;
use crate::pipeline::metrics::quantile_sorted;
use crate::sim::carmen::{self, NO_RETURN_RANGE};
use crate::sim::eval::{format_trajectory, Stamped};

/// Arguments of `sweepline replay`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The CARMEN log (FLASER / ROBOTLASER1 / ODOM lines; .gz accepted), or
    /// a sweepline recording (`run.mcap`), replayed through the daemon's
    /// own localise and map stages with the recorded configuration.
    pub log: PathBuf,
    /// Output folder for trajectory.txt, replay.svg and summary.txt.
    #[arg(long, default_value = "out/replay")]
    pub out: PathBuf,
    /// Config file whose `[icp]` table sets the matcher (default: built-in
    /// defaults; for a recording: the whole configuration, default the
    /// recorded one).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Everything a replay produced.
#[derive(Debug, Default)]
pub struct ReplayResult {
    /// Estimated pose per laser scan.
    pub trajectory: Vec<Stamped>,
    /// Raw odometry pose per laser scan.
    pub odometry: Vec<Stamped>,
    /// Wall-clock time of each tracking step after the first (s).
    pub step_times: Vec<f64>,
    /// CPU time of this thread for each tracking step after the first (s):
    /// unlike wall-clock time, not inflated when other processes share the cores.
    pub step_cpu_times: Vec<f64>,
    /// Accepted matches.
    pub matched: usize,
    /// Failed matches (prediction used).
    pub failed: usize,
    /// Rejected matches (prediction used).
    pub rejected: usize,
    /// Matches flagged degenerate (pose kept at the prior along the weak direction).
    pub degenerate: usize,
    /// Sum of iterations of accepted matches.
    pub iterations: u64,
    /// One line per scan: stamp, outcome and quality figures (`steps.txt`).
    pub steps: Vec<String>,
    /// Keyframe points, world frame, thinned to a 5 cm grid (for the picture).
    pub points: Vec<IPoint>,
    /// How often the correlative search ran and found the pose.
    pub searches: SearchCounts,
    /// CPU time of each step in which the search ran (s).
    pub search_cpu_times: Vec<f64>,
    /// The longest run of successive scans without an accepted match.
    pub longest_unmatched: usize,
    /// Scans without an accepted match at the end of the log (a run that
    /// never ended in a recovered pose).
    pub unmatched_at_end: usize,
}

/// Runs the tracker over every laser record of a log.
pub fn replay_log(log: &carmen::CarmenLog, params: &IcpParams) -> Result<ReplayResult, String> {
    let start = log
        .lasers()
        .next()
        .map(|l| l.laser_pose)
        .ok_or("the log holds no laser scans")?;
    let mut tracker = Tracker::new(params.clone(), start).map_err(|e| e.to_string())?;
    let mut res = ReplayResult::default();
    let mut pts: Vec<IPoint> = Vec::with_capacity(crate::capacity::MAX_BEAMS);
    let mut seen: HashSet<(i64, i64)> = HashSet::new();
    for (i, l) in log.lasers().enumerate() {
        let scan = l.to_scan(i as u64, NO_RETURN_RANGE);
        scan.points_into(&mut pts);
        let c0 = thread_cpu_time().as_secs_f64();
        let t0 = Instant::now();
        let step = tracker.step(&pts, Some(&l.odom_pose));
        let dt = t0.elapsed().as_secs_f64();
        let dc = thread_cpu_time().as_secs_f64() - c0;
        let line = match step.outcome {
            Outcome::First => format!("{:.6} first", l.stamp),
            Outcome::Matched(q) | Outcome::Rejected(_, q) => format!(
                "{:.6} {} it={} pairs={} inl={:.2} rms={:.4} eig={:.4} deg={} dt={:.3} dr={:.4} kf={} ms={:.3} cpu_ms={:.3}",
                l.stamp,
                if matches!(step.outcome, Outcome::Matched(_)) { "ok" } else { "rejected" },
                q.iterations,
                q.pairs,
                q.inlier_ratio,
                q.residual_rms,
                q.min_eigenvalue,
                q.degenerate,
                q.correction_translation,
                q.correction_rotation,
                step.keyframe,
                dt * 1e3,
                dc * 1e3
            ),
            Outcome::Failed(e) => format!("{:.6} failed {e}", l.stamp),
        };
        res.steps.push(if step.searched {
            line + " searched"
        } else {
            line
        });
        if step.searched {
            res.search_cpu_times.push(dc);
        }
        match step.outcome {
            Outcome::Matched(_) | Outcome::First => res.unmatched_at_end = 0,
            _ => {
                res.unmatched_at_end += 1;
                res.longest_unmatched = res.longest_unmatched.max(res.unmatched_at_end);
            }
        }
        match step.outcome {
            Outcome::First => {}
            Outcome::Matched(q) => {
                res.matched += 1;
                res.iterations += q.iterations as u64;
                if q.degenerate {
                    res.degenerate += 1;
                }
            }
            Outcome::Failed(_) => res.failed += 1,
            Outcome::Rejected(..) => res.rejected += 1,
        }
        if i > 0 {
            res.step_times.push(dt);
            res.step_cpu_times.push(dc);
        }
        if step.keyframe {
            for p in tracker.map().points() {
                let key = ((p.x / 0.05).floor() as i64, (p.y / 0.05).floor() as i64);
                if seen.insert(key) {
                    res.points.push(*p);
                }
            }
        }
        res.trajectory.push(Stamped {
            t: l.stamp,
            pose: step.pose,
        });
        res.odometry.push(Stamped {
            t: l.stamp,
            pose: l.odom_pose,
        });
    }
    res.searches = tracker.search_counts();
    Ok(res)
}

/// How much later the odd beams of the log's scans were measured than the
/// even ones, estimated without ground truth. A SICK LMS 2xx in 0.5° mode
/// builds a scan from two interleaved sweeps; while the robot turns, the odd
/// beams then see the world rotated against the even ones. Per scan, the
/// odd-beam points are matched against the even-beam points (rotation δ),
/// and δ is regressed through the origin on the turn rate ω of `trajectory`
/// at that scan (δ = lag · ω). Returns the lag (s) and the scans used; `None`
/// when no scan turns.
pub fn interlace_lag(
    log: &carmen::CarmenLog,
    trajectory: &[Stamped],
    params: &IcpParams,
) -> Option<(f64, usize)> {
    let lasers: Vec<&carmen::LaserRecord> = log.lasers().collect();
    if lasers.len() != trajectory.len() || lasers.len() < 3 {
        return None;
    }
    let mut matcher = crate::icp::Matcher::new(params.clone()).ok()?;
    let mut reference = crate::icp::Reference::new();
    let (mut even, mut odd) = (Vec::new(), Vec::new());
    let (mut swd, mut sww, mut used) = (0.0, 0.0, 0);
    for k in 1..lasers.len() - 1 {
        let (a, b) = (&trajectory[k - 1], &trajectory[k + 1]);
        let dt = b.t - a.t;
        if dt <= 0.0 {
            continue;
        }
        let w = crate::geom::wrap_angle(b.pose.rotation.angle() - a.pose.rotation.angle()) / dt;
        let l = lasers[k];
        even.clear();
        odd.clear();
        for (i, &r) in l.ranges.iter().enumerate() {
            if r.is_finite() && r > 0.0 && r < NO_RETURN_RANGE {
                let (sn, cs) = l.beam_angle(i).sin_cos();
                let p = IPoint::new(r * cs, r * sn, 0.0);
                if i % 2 == 0 {
                    even.push(p)
                } else {
                    odd.push(p)
                }
            }
        }
        if reference
            .rebuild_scan(&even, &Pose::identity(), params)
            .is_err()
        {
            continue;
        }
        let Ok(m) = matcher.match_points(&reference, &odd, &Pose::identity()) else {
            continue;
        };
        if m.quality.check(params).is_err() || m.quality.degenerate {
            continue;
        }
        swd += w * m.pose.rotation.angle();
        sww += w * w;
        used += 1;
    }
    (sww > 0.0).then(|| (swd / sww, used))
}

/// The text summary of a replay.
pub fn summary(res: &ReplayResult) -> String {
    let mut t = res.step_times.clone();
    t.sort_by(f64::total_cmp);
    let mut c = res.step_cpu_times.clone();
    c.sort_by(f64::total_cmp);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "scans: {}  matched: {}  failed: {}  rejected: {}  degenerate: {}",
        res.trajectory.len(),
        res.matched,
        res.failed,
        res.rejected,
        res.degenerate
    );
    if res.matched > 0 {
        let _ = writeln!(
            s,
            "mean iterations per accepted match: {:.1}",
            res.iterations as f64 / res.matched as f64
        );
    }
    let _ = writeln!(
        s,
        "longest run of scans without an accepted match: {}  still unmatched at the end: {}",
        res.longest_unmatched, res.unmatched_at_end
    );
    let n = res.searches;
    let mut sc = res.search_cpu_times.clone();
    sc.sort_by(f64::total_cmp);
    let _ = writeln!(
        s,
        "correlative search: ran {} times, found a candidate {}, recovered the match {}; CPU per searching step median {:.3} ms  max {:.3} ms; {:.0} candidates scored per search",
        n.calls,
        n.found,
        n.recovered,
        quantile_sorted(&sc, 0.5) * 1e3,
        sc.last().copied().unwrap_or(0.0) * 1e3,
        n.scored as f64 / n.found.max(1) as f64
    );
    for (name, v) in [("wall-clock", &t), ("thread CPU", &c)] {
        let _ = writeln!(
            s,
            "{name} time per scan (match incl. keyframe updates): median {:.3} ms  p99 {:.3} ms  max {:.3} ms  mean {:.3} ms",
            quantile_sorted(v, 0.5) * 1e3,
            quantile_sorted(v, 0.99) * 1e3,
            v.last().copied().unwrap_or(f64::NAN) * 1e3,
            v.iter().sum::<f64>() / v.len().max(1) as f64 * 1e3
        );
    }
    s
}

fn path_of(poses: &[Stamped]) -> String {
    let mut d = String::new();
    for (i, p) in poses.iter().enumerate() {
        let _ = write!(
            d,
            "{}{:.3} {:.3} ",
            if i == 0 { "M" } else { "L" },
            p.pose.translation.x,
            -p.pose.translation.y
        );
    }
    d
}

/// An SVG of the registered points (grey), the estimated trajectory (blue) and
/// raw odometry (orange, dashed). World y points up.
pub fn picture(res: &ReplayResult) -> Document {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    let mut grow = |x: f64, y: f64| {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(-y);
        y1 = y1.max(-y);
    };
    for p in &res.points {
        grow(p.x, p.y);
    }
    for p in &res.trajectory {
        grow(p.pose.translation.x, p.pose.translation.y);
    }
    if x0 > x1 {
        (x0, y0, x1, y1) = (-1.0, -1.0, 1.0, 1.0);
    }
    let m = 1.0;
    let (w, h) = (x1 - x0 + 2.0 * m, y1 - y0 + 2.0 * m);
    let mut pts = String::with_capacity(res.points.len() * 24);
    for p in &res.points {
        let _ = write!(pts, "M{:.3} {:.3}h0.05", p.x, -p.y);
    }
    let pose_of = |p: &Pose| (p.translation.x, p.translation.y);
    let _ = pose_of;
    let scale = 1200.0 / w.max(h);
    Document::new()
        .set("viewBox", (x0 - m, y0 - m, w, h))
        .set("width", w * scale)
        .set("height", h * scale)
        .add(
            Rectangle::new()
                .set("x", x0 - m)
                .set("y", y0 - m)
                .set("width", w)
                .set("height", h)
                .set("fill", "white"),
        )
        .add(
            Group::new()
                .add(
                    SvgPath::new()
                        .set("d", pts)
                        .set("stroke", "#444")
                        .set("stroke-width", 0.05),
                )
                .add(
                    SvgPath::new()
                        .set("d", path_of(&res.odometry))
                        .set("fill", "none")
                        .set("stroke", "#e08000")
                        .set("stroke-width", 0.06)
                        .set("stroke-dasharray", "0.3 0.2"),
                )
                .add(
                    SvgPath::new()
                        .set("d", path_of(&res.trajectory))
                        .set("fill", "none")
                        .set("stroke", "#0050d0")
                        .set("stroke-width", 0.08),
                ),
        )
}

fn load_params(config: Option<&Path>) -> Result<IcpParams, String> {
    match config {
        None => Ok(IcpParams::default()),
        Some(p) => Config::load(p).map(|c| c.icp).map_err(|e| e.to_string()),
    }
}

/// Runs `sweepline replay`.
pub fn run(args: Args) -> CliResult {
    if args.log.extension().is_some_and(|e| e == "mcap") {
        return super::replay_mcap::run(&args.log, &args.out, args.config.as_deref());
    }
    let params = load_params(args.config.as_deref())?;
    let log = carmen::read_file(&args.log).map_err(|e| match e {
        carmen::CarmenError::Malformed { .. } => format!("{}: {e}", args.log.display()),
        other => other.to_string(),
    })?;
    let res = replay_log(&log, &params)?;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let traj = args.out.join("trajectory.txt");
    std::fs::write(&traj, format_trajectory(&res.trajectory))
        .map_err(|e| format!("cannot write {}: {e}", traj.display()))?;
    let svg_path = args.out.join("replay.svg");
    svg::save(&svg_path, &picture(&res))
        .map_err(|e| format!("cannot write {}: {e}", svg_path.display()))?;
    let steps = args.out.join("steps.txt");
    std::fs::write(&steps, res.steps.join("\n") + "\n")
        .map_err(|e| format!("cannot write {}: {e}", steps.display()))?;
    let mut text = summary(&res);
    if let Some((lag, used)) = interlace_lag(&log, &res.trajectory, &params) {
        let _ = writeln!(
            text,
            "interlace: odd beams measured {:.1} ms after even ones (odd-vs-even match rotation regressed on turn rate, {used} scans; 0 = one sweep)",
            lag * 1e3
        );
    }
    let sum = args.out.join("summary.txt");
    std::fs::write(&sum, &text).map_err(|e| format!("cannot write {}: {e}", sum.display()))?;
    print!("{text}");
    println!(
        "wrote {}, {}, {}",
        traj.display(),
        svg_path.display(),
        sum.display()
    );
    Ok(())
}
