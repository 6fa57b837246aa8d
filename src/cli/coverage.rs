//! `sweepline coverage`: runs the online decomposition and coverage planner in a deterministic lock-step simulation (ideal localisation) and writes metrics and pictures.
//!
//! ```text
//! sweepline coverage --world hw/worlds/paper.world --out out/paper --offline
//! sweepline coverage --room office_f:3 --out out/office_f_3
//! sweepline coverage --list-rooms lab_c_scan
//! sweepline coverage --map lab.yaml --region 2,3,9,8 --offline   # a ROS map_server map
//! ```
//!
//! Writes `metrics.md` and `metrics.csv` (one row per run: online, and with
//! `--offline` the reference run with the room known in advance; the overlap
//! broken down by cause), `path_{online,offline}.svg` (the final path over
//! the world with pass counts), `overlap_{online,offline}.svg` (floor swept
//! again, coloured by what the robot was doing) and `cells_NN.svg` (the
//! cells as they evolve) and `trajectory_{online,offline}.csv` (the driven
//! path in the world / map frame, to replay on a robot of one's own) into
//! `--out`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::world_args::WorldArgs;
use super::CliResult;
use crate::config::Config;
use crate::sim::coverage_metrics::{CoverageMetrics, CoverageTracker, OVERLAP_CAUSES};
use crate::sim::coverage_svg;
use crate::sim::floorplan;
use crate::sim::lockstep::{self, LockstepOptions, Mode, RunResult, SensingNoise};
use crate::sim::world::World;

/// Arguments of `sweepline coverage`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The world to cover.
    #[command(flatten)]
    pub world: WorldArgs,
    /// Lists the rooms of a floor plan (MAP) with their areas, then exits.
    #[arg(long, value_name = "MAP")]
    pub list_rooms: Option<String>,
    /// Output folder for metrics and pictures (every command writes under out/).
    #[arg(long, default_value = "out/coverage")]
    pub out: PathBuf,
    /// Also run the offline reference (room known in advance) and compare.
    #[arg(long)]
    pub offline: bool,
    /// Configuration file (robot, decomposition, planner, control tables).
    #[arg(long, default_value = "hw/robot.toml")]
    pub config: PathBuf,
    /// Simulated seconds after which the run stops unfinished (default:
    /// 3600, or 60 per m² of free floor where that is longer).
    #[arg(long)]
    pub time_cap: Option<f64>,
    /// Scan / decomposition / planning period (s).
    #[arg(long, default_value_t = 0.2)]
    pub scan_period: f64,
    /// Simulated seconds between cell pictures.
    #[arg(long, default_value_t = 60.0)]
    pub picture_every: f64,
    /// Shift of the evidence grid's cell boundaries against the world (m,
    /// 0 to under one cell): 0 puts the floor plans' walls on cell
    /// boundaries, 0.025 in mid-cell, as in the daemon's grid.
    #[arg(long, default_value_t = 0.0)]
    pub grid_offset: f64,
    /// Range noise of the simulated scans, standard deviation (m; online run).
    #[arg(long, default_value_t = 0.0)]
    pub range_noise: f64,
    /// Position error of each scan's pose, standard deviation per axis (m; online run).
    #[arg(long, default_value_t = 0.0)]
    pub pose_noise: f64,
    /// Heading error of each scan's pose, standard deviation (rad; online run).
    #[arg(long, default_value_t = 0.0)]
    pub heading_noise: f64,
    /// Seed of the scan noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Runs `sweepline coverage`.
pub fn run(args: Args) -> CliResult {
    if let Some(map) = &args.list_rooms {
        let rooms = floorplan::rooms(&args.world.maps_dir(), map, floorplan::MIN_ROOM_PIXELS)?;
        println!("room\tfree m2\tbox m");
        for r in rooms {
            println!(
                "{}:{}\t{:.1}\t{:.1} x {:.1}",
                r.map,
                r.index,
                r.free_area(),
                r.width as f64 * floorplan::PIXEL_SIZE,
                r.height as f64 * floorplan::PIXEL_SIZE
            );
        }
        return Ok(());
    }
    let world = args.world.load(None)?;
    let config = if args.config.exists() {
        Config::load(&args.config)?
    } else {
        return Err(format!("config {} not found", args.config.display()).into());
    };
    let opts = LockstepOptions {
        time_cap: super::world_args::time_cap(args.time_cap, &world),
        scan_period: args.scan_period,
        snapshot_every: args.picture_every,
        grid_offset: args.grid_offset,
        sensing: SensingNoise {
            range: args.range_noise,
            position: args.pose_noise,
            heading: args.heading_noise,
            seed: args.seed,
        },
        ..LockstepOptions::default()
    };
    std::fs::create_dir_all(&args.out)?;
    let online = lockstep::run(&world, &config, &opts, Mode::Online)?;
    let offline = if args.offline {
        Some(lockstep::run(&world, &config, &opts, Mode::Offline)?)
    } else {
        None
    };
    for (run, tag) in
        std::iter::once((&online, "online")).chain(offline.iter().map(|o| (o, "offline")))
    {
        write_pictures(&args.out, &world, &config, run, tag)?;
        std::fs::write(
            args.out.join(format!("trajectory_{tag}.csv")),
            trajectory_csv(run, opts.dt),
        )?;
    }
    let mut md = markdown(&world.name, &online, offline.as_ref());
    md += &conditions(&opts);
    md += &people(&world, &online);
    md += &format!(
        "\nProtective field (control.guard): the robot slowed or stopped short of something the scan showed ahead that its path did not expect {} time(s) online.\n",
        online.guard_stops
    );
    std::fs::write(args.out.join("metrics.md"), &md)?;
    std::fs::write(
        args.out.join("metrics.csv"),
        csv(&world.name, &online, offline.as_ref()),
    )?;
    print!("{md}");
    Ok(())
}

/// The line of metrics.md about people walking through the room (empty
/// when nobody does).
fn people(world: &World, online: &RunResult) -> String {
    if world.walkers.is_empty() {
        return String::new();
    }
    format!(
        "\nPeople walking through the room (online run only; the offline reference has the room to itself): {}; contacts with them: {}.\n",
        world.walkers.len(),
        online.metrics.person_contacts
    )
}

/// The line of metrics.md that says how the map was sensed.
fn conditions(opts: &LockstepOptions) -> String {
    let n = &opts.sensing;
    let scans = if n.is_ideal() {
        "ideal scans".to_string()
    } else {
        format!(
            "online scans with range noise σ {:.1} mm, pose noise σ {:.1} mm / {:.3}° (seed {})",
            n.range * 1e3,
            n.position * 1e3,
            n.heading.to_degrees(),
            n.seed
        )
    };
    format!(
        "\nMap: {:.0} mm cells, boundaries shifted {:.1} mm against the world; {scans}.\n",
        opts.grid_resolution * 1e3,
        opts.grid_offset * 1e3
    )
}

fn write_pictures(
    out: &Path,
    world: &World,
    config: &Config,
    r: &RunResult,
    tag: &str,
) -> std::io::Result<()> {
    let tracker = CoverageTracker::new(
        world,
        config.robot.radius,
        config.robot.tool_width,
        &world.start,
    )
    .map_err(std::io::Error::other)?;
    let doc = coverage_svg::path_svg(
        world,
        &r.passes,
        tracker.reachable(),
        &r.trajectory,
        &r.metrics,
        &format!("{} ({tag})", world.name),
    );
    coverage_svg::save(&out.join(format!("path_{tag}.svg")), &doc)?;
    let doc = coverage_svg::overlap_svg(
        world,
        &r.repeat_causes,
        &r.trajectory,
        &format!("{} ({tag})", world.name),
        r.metrics.overlap,
    );
    coverage_svg::save(&out.join(format!("overlap_{tag}.svg")), &doc)?;
    let doc = coverage_svg::motions_svg(
        world,
        &r.passes,
        &r.trajectory,
        &r.doing,
        &format!(
            "{} ({tag}): path by motion, numbers where each task began",
            world.name
        ),
    );
    coverage_svg::save(&out.join(format!("motions_{tag}.svg")), &doc)?;
    if tag == "online" {
        for (k, s) in r.snapshots.iter().enumerate() {
            let n = r.trajectory.len().min((s.time / 0.05).round() as usize + 1);
            let doc = coverage_svg::cells_svg(
                world,
                &s.decomposition,
                &r.trajectory[..n],
                config.robot.radius,
                &format!(
                    "{}: t = {:.0} s, {} cells",
                    world.name,
                    s.time,
                    s.decomposition.cells.len()
                ),
            );
            coverage_svg::save(&out.join(format!("cells_{k:02}.svg")), &doc)?;
        }
    }
    Ok(())
}

fn p99(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() as f64 * 0.99).ceil() as usize).clamp(1, s.len()) - 1]
}

/// One table row: label and how to format it from the metrics.
type Row = (&'static str, fn(&CoverageMetrics) -> String);

/// The metrics of a run (and its offline reference) as a Markdown table.
pub fn markdown(name: &str, online: &RunResult, offline: Option<&RunResult>) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Coverage: {name}\n");
    let _ = writeln!(
        s,
        "| figure | online | {} |",
        if offline.is_some() {
            "offline reference"
        } else {
            ""
        }
    );
    let _ = writeln!(s, "|---|---|---|");
    let rows: [Row; 15] = [
        ("coverage of reachable area", |m| {
            format!("{:.2} %", m.coverage * 100.0)
        }),
        ("coverage of footprint-reachable area", |m| {
            format!("{:.2} %", m.footprint_coverage * 100.0)
        }),
        ("reachable area", |m| format!("{:.2} m²", m.reachable_area)),
        ("coverage of area reachable with the safety margin", |m| {
            format!("{:.2} %", m.clear_coverage * 100.0)
        }),
        ("area reachable with the safety margin", |m| {
            format!("{:.2} m²", m.clear_reachable_area)
        }),
        ("free area", |m| format!("{:.2} m²", m.free_area)),
        ("unreachable area", |m| {
            format!("{:.2} m²", m.unreachable_area)
        }),
        ("covered area", |m| format!("{:.2} m²", m.covered_area)),
        ("overlap", |m| format!("{:.1} %", m.overlap * 100.0)),
        ("path length", |m| format!("{:.1} m", m.path_length)),
        ("turns (> 30°)", |m| format!("{}", m.turns)),
        ("rotation", |m| format!("{:.0} rad", m.rotation)),
        ("time", |m| format!("{:.0} s", m.time)),
        ("collisions", |m| format!("{}", m.collisions)),
        ("finished", |_| String::new()),
    ];
    for (label, f) in rows.iter() {
        if *label == "finished" {
            let _ = writeln!(
                s,
                "| finished before the time cap | {} | {} |",
                online.finished,
                offline.map(|o| o.finished.to_string()).unwrap_or_default()
            );
            continue;
        }
        let _ = writeln!(
            s,
            "| {label} | {} | {} |",
            f(&online.metrics),
            offline.map(|o| f(&o.metrics)).unwrap_or_default()
        );
    }
    let _ = writeln!(
        s,
        "| drive back to the start (not in the figures above) | {} | {} |",
        home_drive(online),
        offline.map(home_drive).unwrap_or_default()
    );
    let _ = writeln!(
        s,
        "| cells covered / patches / explorations | {} / {} / {} | {} |",
        online.stats.cells,
        online.stats.patches,
        online.stats.explores,
        offline
            .map(|o| format!(
                "{} / {} / {}",
                o.stats.cells, o.stats.patches, o.stats.explores
            ))
            .unwrap_or_default()
    );
    let _ = writeln!(
        s,
        "| tasks planned (started over: path blocked / new floor near the robot) | {} ({} / {}) | {} |",
        online.stats.tasks,
        online.stats.blocked,
        online.stats.retours,
        offline
            .map(|o| format!("{} ({} / {})", o.stats.tasks, o.stats.blocked, o.stats.retours))
            .unwrap_or_default()
    );
    let _ = writeln!(
        s,
        "| decomposition update p99 (wall clock) | {:.2} ms | |",
        p99(&online.decomp_seconds) * 1e3
    );
    let _ = writeln!(
        s,
        "| planner update p99 (wall clock) | {:.2} ms | |",
        p99(&online.plan_seconds) * 1e3
    );
    let paper_bytes = online.paper.as_ref().map_or(0, |p| p.memory_bytes);
    let _ = writeln!(
        s,
        "| map memory (the planner's grid, and the paper map's points, segments and grid) | {:.2} MB | |",
        (online.grid.memory_bytes() + paper_bytes) as f64 / 1e6
    );
    if let Some(p) = &online.paper {
        paper_rows(&mut s, p);
    }
    let _ = writeln!(
        s,
        "\nOverlap by what the robot was doing when floor was swept a second time (% of swept area):\n\n| cause | online | {} |\n|---|---|---|",
        if offline.is_some() { "offline" } else { "" }
    );
    for (k, cause) in OVERLAP_CAUSES.iter().enumerate() {
        let _ = writeln!(
            s,
            "| {cause} | {:.1} % | {} |",
            online.metrics.overlap_by[k] * 100.0,
            offline
                .map(|o| format!("{:.1} %", o.metrics.overlap_by[k] * 100.0))
                .unwrap_or_default()
        );
    }
    if let Some(o) = offline {
        let ratio = online.metrics.path_length / o.metrics.path_length.max(1e-9);
        let _ = writeln!(
            s,
            "\nOnline path length / offline reference: **{ratio:.3}**"
        );
    }
    let angle = |r: &RunResult| {
        r.snapshots
            .last()
            .map(|k| format!("{:.1}°", k.decomposition.sweep_angle.to_degrees()))
            .unwrap_or_else(|| "-".into())
    };
    let _ = writeln!(
        s,
        "\nLane direction (from x): online {}{}",
        angle(online),
        offline
            .map(|o| format!(", offline {}", angle(o)))
            .unwrap_or_default()
    );
    if let Some(r) = online.report {
        let _ = writeln!(
            s,
            "\nPlanner report: unreachable seen floor {:.2} m², floor behind passages tighter than the clearance {:.2} m², floor given up {:.2} m², leftovers declined {:.2} m², frontier left unexplored {:.2} m (no reachable place sees past it, or given up).",
            r.unreachable_area, r.behind_tight_passages, r.abandoned_area, r.declined_area, r.unexplored_frontier
        );
    }
    s
}

/// The drive back to the start of a run, in a few words.
fn home_drive(r: &RunResult) -> String {
    let Some(rep) = r.report else {
        return "-".into();
    };
    if rep.home == crate::plan::HomeOutcome::NotAsked {
        return rep.home.describe().into();
    }
    format!(
        "{:.1} m, {:.0} s: {}, {:.2} m from it",
        r.metrics.home_length,
        r.metrics.home_time,
        rep.home.describe(),
        rep.home_distance
    )
}

/// The metrics as CSV, one row per run.
pub fn csv(name: &str, online: &RunResult, offline: Option<&RunResult>) -> String {
    let mut s = String::from(
        "world,mode,coverage,footprint_coverage,reachable_m2,free_m2,unreachable_m2,covered_m2,overlap,path_m,turns,rotation_rad,time_s,collisions,finished\n",
    );
    for (mode, r) in std::iter::once(("online", online)).chain(offline.map(|o| ("offline", o))) {
        let m = &r.metrics;
        let _ = writeln!(
            s,
            "{name},{mode},{:.5},{:.5},{:.3},{:.3},{:.3},{:.3},{:.5},{:.3},{},{:.2},{:.1},{},{}",
            m.coverage,
            m.footprint_coverage,
            m.reachable_area,
            m.free_area,
            m.unreachable_area,
            m.covered_area,
            m.overlap,
            m.path_length,
            m.turns,
            m.rotation,
            m.time,
            m.collisions,
            r.finished
        );
    }
    s
}

/// The driven path as CSV (`t_s,x_m,y_m,heading_rad,motion,task`): a row
/// where the pose moved 1 cm or turned 0.02 rad since the last row, or the
/// motion or task changed, and the last pose; `dt` is the control period
/// (the first pose is the one after the first step, at `dt`).
pub fn trajectory_csv(run: &RunResult, dt: f64) -> String {
    use crate::plan::Motion;
    let name = |m: Motion| match m {
        Motion::Lane => "lane",
        Motion::FixUp => "fix-up",
        Motion::Connection => "connection",
        Motion::Transit => "transit",
        Motion::Explore => "explore",
        Motion::Other => "other",
        Motion::Home => "home",
    };
    let mut out = String::from("t_s,x_m,y_m,heading_rad,motion,task\n");
    let mut last: Option<(crate::geom::Pose, crate::plan::Motion, u32)> = None;
    let n = run.trajectory.len();
    for (k, p) in run.trajectory.iter().enumerate() {
        let (m, task) = run.doing.get(k).copied().unwrap_or_default();
        let keep = last.is_none_or(|(q, lm, lt)| {
            (p.translation.vector - q.translation.vector).norm() >= 0.01
                || crate::geom::wrap_angle(crate::geom::heading(p) - crate::geom::heading(&q)).abs()
                    >= 0.02
                || lm != m
                || lt != task
        });
        if keep || k + 1 == n {
            let _ = writeln!(
                out,
                "{:.2},{:.4},{:.4},{:.4},{},{task}",
                (k + 1) as f64 * dt,
                p.translation.vector.x,
                p.translation.vector.y,
                crate::geom::heading(p),
                name(m)
            );
            last = Some((*p, m, task));
        }
    }
    out
}

/// The paper map's rows of the metrics table (`[map] kind = "paper"`).
fn paper_rows(s: &mut String, p: &lockstep::PaperSummary) {
    let c = &p.corrections;
    let mean_ms = p.map_seconds.iter().sum::<f64>() / p.map_seconds.len().max(1) as f64 * 1e3;
    let _ = writeln!(
        s,
        "| paper map: merge and render per scan, mean / p99 (wall clock) | {mean_ms:.2} / {:.2} ms | |",
        p99(&p.map_seconds) * 1e3
    );
    let _ = writeln!(
        s,
        "| paper map: points / wall segments | {} / {} | |",
        p.points, p.segments
    );
    let _ = writeln!(
        s,
        "| paper map: segment corrections applied / refused of scans (mean / largest shift) | {} / {} of {} ({:.1} / {:.1} mm, {:.2}°) | |",
        c.applied,
        c.refused,
        c.scans,
        c.translation_mean() * 1e3,
        c.translation_max * 1e3,
        c.rotation_max.to_degrees()
    );
}
