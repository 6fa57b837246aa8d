//! The report folder of a closed-loop run: `summary.md` (coverage, pose
//! error, links, pipeline), `map.svg` (the daemon's map with the true and
//! estimated trajectories), `cells.svg` (the last decomposition), `path.svg`
//! (the driven path with pass counts). The latency/CPU budget report and
//! `metrics.toml` are written beside them by the run-folder hooks.

use std::fmt::Write as _;
use std::path::Path;

use svg::node::element::{Polyline, Rectangle};
use svg::Document;

use super::base_emu::Fault;
use super::closed_loop::{FixPair, SimOptions, SimReport};
use super::coverage_metrics::{CoverageTracker, OVERLAP_CAUSES};
use super::coverage_svg;
use crate::daemon::Shared;
use crate::geom::{heading, Pose};
use crate::grid::{CellState, Grid};
use crate::plan::HomeOutcome;

fn polyline(poses: &[Pose], g: &Grid, scale: f64, colour: &str) -> Polyline {
    let (o, h) = (g.origin(), g.height() as f64 * g.resolution());
    let pts: Vec<String> = poses
        .iter()
        .map(|p| {
            format!(
                "{:.1},{:.1}",
                (p.translation.x - o.x) * scale,
                (h - (p.translation.y - o.y)) * scale
            )
        })
        .collect();
    Polyline::new()
        .set("points", pts.join(" "))
        .set("fill", "none")
        .set("stroke", colour)
        .set("stroke-width", 1.2)
}

/// The map as the daemon built it (free light, occupied black, unknown
/// grey), with the true trajectory (green) and the estimate (red, dashed).
pub(crate) fn map_svg(g: &Grid, truth: &[Pose], estimate: &[Pose]) -> Document {
    let scale = 100.0;
    let r = g.resolution() * scale;
    let (w, h) = (g.width(), g.height());
    let mut doc = Document::new()
        .set("viewBox", (0, 0, w as f64 * r, h as f64 * r))
        .set("width", w as f64 * r)
        .set("height", h as f64 * r)
        .add(
            Rectangle::new()
                .set("width", "100%")
                .set("height", "100%")
                .set("fill", "#bdbdbd"),
        );
    for y in 0..h {
        let mut x = 0;
        while x < w {
            let s = g.state((x, y));
            let mut e = x + 1;
            while e < w && g.state((e, y)) == s {
                e += 1;
            }
            let fill = match s {
                CellState::Free => Some("#ffffff"),
                CellState::Occupied => Some("#000000"),
                CellState::Unknown => None,
            };
            if let Some(fill) = fill {
                doc = doc.add(
                    Rectangle::new()
                        .set("x", x as f64 * r)
                        .set("y", (h - 1 - y) as f64 * r)
                        .set("width", (e - x) as f64 * r)
                        .set("height", r)
                        .set("fill", fill)
                        .set("shape-rendering", "crispEdges"),
                );
            }
            x = e;
        }
    }
    doc.add(polyline(truth, g, scale, "#31a354"))
        .add(polyline(estimate, g, scale, "#de2d26").set("stroke-dasharray", "4 3"))
}

/// Writes the report folder.
pub fn write(
    dir: &Path,
    opts: &SimOptions,
    r: &SimReport,
    tracker: &CoverageTracker,
    shared: &Shared,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let (grid, decomp) = shared.with_status(|s| (s.map.grid.clone(), s.decomposition.clone()));
    // The map and the cells are in the daemon's frame, the world in its own
    // (they differ when the daemon was told a wrong start heading).
    let to_world = r.map_to_world;
    if let Some(g) = &grid {
        let world_to_map = to_world.inverse();
        let truth: Vec<Pose> = r.truth.iter().map(|p| world_to_map * p).collect();
        svg::save(dir.join("map.svg"), &map_svg(g, &truth, &r.estimate))?;
    }
    let radius = opts.config.robot.radius;
    if let Some(d) = &decomp {
        let mut d = (**d).clone();
        for c in &mut d.cells {
            for q in &mut c.polygon {
                *q = to_world * *q;
            }
        }
        let estimate: Vec<Pose> = r.estimate.iter().map(|p| to_world * p).collect();
        let doc = coverage_svg::cells_svg(
            &opts.world,
            &d,
            &estimate,
            radius,
            &format!("{} cells, estimated track", d.cells.len()),
        );
        coverage_svg::save(&dir.join("cells.svg"), &doc)?;
    }
    let doc = coverage_svg::path_svg(
        &opts.world,
        tracker.passes(),
        tracker.reachable(),
        &r.truth,
        &r.metrics,
        &format!("{}: closed loop through the ptys", opts.world.name),
    );
    coverage_svg::save(&dir.join("path.svg"), &doc)?;
    let doc = coverage_svg::overlap_svg(
        &opts.world,
        tracker.repeat_causes(),
        &r.truth,
        &opts.world.name,
        r.metrics.overlap,
    );
    coverage_svg::save(&dir.join("overlap.svg"), &doc)?;
    std::fs::write(dir.join("fixes.csv"), fixes_csv(&r.fixes))?;
    std::fs::write(dir.join("summary.md"), summary(opts, r))
}

/// One line per scored localised pose: its stamp, the fix, the truth and
/// the errors, for plotting where localisation went wrong.
pub(crate) fn fixes_csv(pairs: &[FixPair]) -> String {
    let mut s = String::from("t_s,fix_x_m,fix_y_m,fix_theta_rad,true_x_m,true_y_m,true_theta_rad,error_m,heading_error_rad\n");
    for p in pairs {
        let _ = writeln!(
            s,
            "{:.4},{:.4},{:.4},{:.5},{:.4},{:.4},{:.5},{:.4},{:.5}",
            p.t,
            p.fix.translation.x,
            p.fix.translation.y,
            heading(&p.fix),
            p.truth.translation.x,
            p.truth.translation.y,
            heading(&p.truth),
            p.position_error(),
            p.heading_error()
        );
    }
    s
}

/// The Markdown summary of a run.
pub fn summary(opts: &SimOptions, r: &SimReport) -> String {
    let m = &r.metrics;
    let mut s = String::new();
    let _ = writeln!(s, "# sweepline sim: {}\n", opts.world.name);
    let _ =
        writeln!(
        s,
        "Closed loop through the ptys: emulated URG-04LX + emulated {} base, speed ×{}, seed {}.\n",
        opts.base.name(), opts.speed, opts.seed
    );
    let _ = writeln!(s, "| figure | value |\n|---|---|");
    let rows = [
        (
            "finished by itself",
            format!("{} ({})", r.finished, r.reason),
        ),
        (
            "coverage of reachable floor",
            format!("{:.2} %", m.coverage * 100.0),
        ),
        (
            "footprint coverage",
            format!("{:.2} %", m.footprint_coverage * 100.0),
        ),
        ("reachable area", format!("{:.2} m²", m.reachable_area)),
        (
            "coverage of floor reachable with the safety margin",
            format!(
                "{:.2} % of {:.2} m²",
                m.clear_coverage * 100.0,
                m.clear_reachable_area
            ),
        ),
        ("covered area", format!("{:.2} m²", m.covered_area)),
        ("overlap", format!("{:.1} %", m.overlap * 100.0)),
        ("path length", format!("{:.1} m", m.path_length)),
        ("turns (> 30°)", format!("{}", m.turns)),
        (
            "drive back to the start (not in the figures above); where the robot ended (truth)",
            format!(
                "{}; {:.1} m, {:.0} s; {:.2} m from where it started",
                HomeOutcome::describe_run(r.home),
                m.home_length,
                m.home_time,
                r.ended_from_start
            ),
        ),
        ("collisions (truth)", format!("{}", m.collisions)),
        (
            "contacts with people walking through (truth)",
            format!("{}", m.person_contacts),
        ),
        (
            "localisation error at scan times: position RMSE / max, heading RMSE",
            format!(
                "{:.1} mm / {:.1} mm, {:.2}° ({} scans scored; best stamp shift {:+.0} ms)",
                r.position_rmse * 1e3,
                r.position_max * 1e3,
                r.heading_rmse.to_degrees(),
                r.scored_fixes,
                r.stamp_offset * 1e3
            ),
        ),
        (
            "map frame laid along the walls (start heading turned by; heading told off by)",
            format!(
                "{}; {:+.1}°",
                r.frame_turn.map_or("not turned".to_string(), |t| format!(
                    "{:+.1}°",
                    t.to_degrees()
                )),
                opts.heading_error.to_degrees()
            ),
        ),
        (
            "scanner checks: scans' turn / wheels' (first quarter turn); offset fitted turning in place; scans' travel off the heading, distance / wheels' (first metre straight); mount driven with",
            format!(
                "{}; {}; {}; {}",
                r.turn_ratio
                    .map_or("not reached".to_string(), |t| format!("{:.0} %", t * 100.0)),
                r.offset_fit.map_or("not reached".to_string(), |f| format!(
                    "({:.3}, {:.3}) m over {:.0}°",
                    f.offset.x,
                    f.offset.y,
                    f.turned.to_degrees()
                )),
                r.travel_fit.map_or("not reached".to_string(), |f| format!(
                    "{:+.2}°, {:.1} % over {:.2} m",
                    f.angle.to_degrees(),
                    f.scale * 100.0,
                    f.driven
                )),
                r.refitted_mount.map_or("as configured".to_string(), |m| format!(
                    "refitted to ({:.3}, {:.3}) m, {:+.2}°",
                    m.translation.x,
                    m.translation.y,
                    crate::geom::heading(&m).to_degrees()
                ))
            ),
        ),
        (
            "live estimate (20 Hz, incl. lag): position RMSE / max, heading RMSE",
            format!(
                "{:.1} mm / {:.1} mm, {:.2}°",
                r.live_position_rmse * 1e3,
                r.live_position_max * 1e3,
                r.live_heading_rmse.to_degrees()
            ),
        ),
        ("simulated time", format!("{:.1} s", r.sim_time)),
        ("wall time", format!("{:.1} s", r.wall)),
        ("simulated clock", pace_line(r)),
        (
            "scans localised / odometry fallbacks",
            format!("{} / {}", r.scans.0, r.scans.1),
        ),
        ("correlative searches (icp.search)", search_line(r)),
        ("after the motion faults (--fault)", fault_lines(r)),
        (
            "robot lost and found again over the whole map (daemon.lost_after)",
            format!(
                "{} time(s){}",
                r.relocalisations.0,
                if r.relocalisations.1 { "; lost at the end" } else { "" }
            ),
        ),
        ("safety events", format!("{}", r.safety_events)),
        (
            "paths given up for lack of headway",
            format!("{}", r.stuck_paths),
        ),
        (
            "stops short of something unplanned straight ahead (control.guard)",
            format!("{}", r.guard_stops),
        ),
        ("wheels held for lack of scans", format!("{}", r.scan_holds)),
        (
            "tasks planned (started over: path blocked / new floor near the robot)",
            format!(
                "{} ({} / {})",
                r.plan_stats.tasks, r.plan_stats.blocked, r.plan_stats.retours
            ),
        ),
        (
            "bumper contacts marked (marks taken out to try the floor they walled off)",
            format!("{} ({})", r.contacts.len(), r.marks_taken_out),
        ),
        (
            "process CPU per second of robot time (per wall second)",
            format!(
                "{:.1} % of one core ({:.1} %)",
                100.0 * r.pipeline.real_time_share(),
                100.0 * r.pipeline.cpu_share()
            ),
        ),
        ("end-to-end latency p50 / p99 / max", {
            let e = r.pipeline.end_to_end();
            format!(
                "{:.2} / {:.2} / {:.2} ms",
                e.quantile(0.5).as_secs_f64() * 1e3,
                e.quantile(0.99).as_secs_f64() * 1e3,
                e.max().as_secs_f64() * 1e3
            )
        }),
        (
            "dropped messages (edges)",
            format!("{}", r.pipeline.dropped()),
        ),
    ];
    for (k, v) in rows {
        let _ = writeln!(s, "| {k} | {v} |");
    }
    let _ = writeln!(
        s,
        "\n## Overlap by what the robot was doing\n\nWhen floor was swept a second time, from the daemon's plan and the waypoint its control stage headed for (% of swept area; `overlap.svg` shows where):\n\n| cause | share |\n|---|---|"
    );
    for (cause, v) in OVERLAP_CAUSES.iter().zip(m.overlap_by) {
        let _ = writeln!(s, "| {cause} | {:.1} % |", v * 100.0);
    }
    let _ = writeln!(
        s,
        "\n## Edges\n\n| edge | policy | sent | received | dropped | max depth |\n|---|---|---|---|---|---|"
    );
    for e in &r.pipeline.edges {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            e.name, e.policy, e.sent, e.received, e.dropped, e.max_depth
        );
    }
    let _ = writeln!(
        s,
        "\nNewest-wins edges drop superseded messages by design (the planner only \
         wants the newest map); `scans` dropped = scans the localiser never saw."
    );
    let _ = writeln!(s, "\n## Scanner link\n\n```\n{}\n```", r.urg);
    write_base_health(&mut s, r);
    let _ = writeln!(
        s,
        "\nPictures: `map.svg` (map, true track green, estimate red), `cells.svg`, `path.svg`. \
         Latency/CPU budget: see the budget report beside this file (`sweepline report {}` rewrites it).",
        opts.out
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_default()
    );
    s
}

/// The wheel-base link as the daemon counted it and as the emulator did,
/// as two tables.
fn write_base_health(s: &mut String, r: &SimReport) {
    let b = &r.base;
    write_counts(
        s,
        "Wheel-base link (daemon side)",
        &[
            ("requests or frames sent", b.sent),
            ("valid replies or frames received", b.received),
            ("replies with a bad CRC or checksum", b.checksum_errors),
            ("bytes thrown away resynchronising", b.discarded_bytes),
            ("requests unanswered in time", b.timeouts),
            ("writes not acknowledged", b.nacks),
            ("link losses", b.link_losses),
            ("reconnects", b.reconnects),
            ("dead-man stops", b.deadman_stops),
            ("safety stops", b.safety_stops),
            ("odometry readings rejected as jumps", b.odometry_glitches),
            ("odometry re-based on a counter reset", b.odometry_rebases),
        ],
    );
    let e = &r.base_emu;
    let d = &e.device;
    write_counts(
        s,
        "Wheel-base emulator",
        &[
            ("bytes received", d.bytes_in),
            ("bytes skipped (no packet start)", d.bytes_skipped),
            ("packets or commands handled", d.packets_ok),
            (
                "packets refused (what the manual does not allow)",
                d.packets_rejected,
            ),
            ("packets cut short by an inter-byte pause", d.packets_cut),
            ("sensor frames sent", d.frames_out),
            ("motor stops by the device's own timeout", d.device_timeouts),
            ("bytes corrupted by fault injection", e.corrupted_bytes),
            ("bytes swallowed by a silence fault", e.silenced_bytes),
            ("bumper closures", e.bumps),
            ("kinematics steps refused by a collision", e.blocked_steps),
            ("cable pulls", e.unplugs),
        ],
    );
}

/// A section `title` with a two-column table of counters.
fn write_counts(s: &mut String, title: &str, rows: &[(&str, u64)]) {
    let _ = writeln!(s, "\n## {title}\n\n| counter | count |\n|---|--:|");
    for (k, v) in rows {
        let _ = writeln!(s, "| {k} | {v} |");
    }
}

/// Per injected motion fault: the largest error of a matched scan after
/// it, when the error was last at least 2 cm, and the longest time without
/// a matched scan (see [`crate::closed_loop::FaultRecovery`]).
fn fault_lines(r: &SimReport) -> String {
    if r.fault_recovery.is_empty() {
        return "none injected".to_string();
    }
    let lines: Vec<String> = r
        .fault_recovery
        .iter()
        .map(|f| {
            let what = match f.fault {
                Fault::Slip { secs, left, right } => format!(
                    "slip {secs:.1} s (wheels lose {:.0} / {:.0} %)",
                    left * 100.0,
                    right * 100.0
                ),
                Fault::Displace { dx, dy, turn } if dx == 0.0 && dy == 0.0 => {
                    format!("knock {:.0}°", turn.to_degrees())
                }
                Fault::Displace { dx, dy, turn } => format!(
                    "kidnap {:.2} m, {:.0}°",
                    dx.hypot(dy),
                    turn.to_degrees()
                ),
                other => format!("{other:?}"),
            };
            format!(
                "{what} at {:.0} s: peak error {:.1} mm, under {:.0} mm for {:.0} s {}, longest time without a matched scan {:.1} s ({} matched in {:.0} s)",
                f.at,
                f.peak * 1e3,
                crate::closed_loop::FAULT_SETTLED * 1e3,
                crate::closed_loop::FAULT_HOLD,
                f.settled_after.map_or("not within the horizon".to_string(), |s| {
                    format!("from {s:.1} s after it")
                }),
                f.longest_gap,
                f.scans,
                crate::closed_loop::FAULT_HORIZON
            )
        })
        .collect();
    lines.join("; ")
}

/// How often the scan tracker searched for a pose its matches missed, what
/// it found and what a searching scan cost.
fn search_line(r: &SimReport) -> String {
    let (n, (sum, max)) = r.searches;
    if n.calls == 0 {
        return "none ran".to_string();
    }
    format!(
        "ran {}, found a candidate {}, recovered the match {}; CPU per searching scan mean {:.2} ms, max {:.2} ms",
        n.calls,
        n.found,
        n.recovered,
        sum / n.calls as f64 * 1e3,
        max * 1e3
    )
}

/// How the simulated clock ran: paced by the daemon (how often and how long
/// it waited for a scan) or at a fixed scale.
fn pace_line(r: &SimReport) -> String {
    match r.pace {
        Some(p) => format!(
            "paced by the daemon: waited for {} of {} scans ({:.1} s wall in all), {} waits given up",
            p.holds, p.scans, p.held_wall, p.timeouts
        ),
        None => "fixed time scale".to_string(),
    }
}
