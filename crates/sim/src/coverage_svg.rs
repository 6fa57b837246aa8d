//! SVG pictures of a coverage run: the cells as they evolve (open cells
//! orange, settling yellow, final green, ids written in them, the robot's
//! track so far) and the final path over the world with the per-cell pass
//! count (white never swept, light blue once, darker twice or more, red where
//! reachable floor was missed).

use std::path::Path;

use svg::node::element::{Circle, Group, Line, Polygon, Polyline, Rectangle};
use svg::Document;

use crate::coverage_metrics::{CoverageMetrics, OVERLAP_CAUSES};
use crate::decomp::{CellStatus, Decomposition};
use crate::geom::Pose;
use crate::plan::Motion;
use crate::svg_canvas::{canvas, caption, label};
use crate::world::{FreeRaster, World};

/// Pixels per metre.
const SCALE: f64 = 100.0;

struct View {
    x0: f64,
    y1: f64,
    w: f64,
    h: f64,
}

impl View {
    fn of(raster: &FreeRaster) -> Self {
        let (w, h) = (
            raster.width as f64 * raster.resolution,
            raster.height as f64 * raster.resolution,
        );
        Self {
            x0: raster.origin.x,
            y1: raster.origin.y + h,
            w: w * SCALE,
            h: h * SCALE,
        }
    }
    fn x(&self, x: f64) -> f64 {
        (x - self.x0) * SCALE
    }
    fn y(&self, y: f64) -> f64 {
        (self.y1 - y) * SCALE
    }
    fn doc(&self, extra_h: f64) -> Document {
        canvas(self.w, self.h + extra_h, "#ffffff")
    }
}

fn walls(world: &World, v: &View) -> Group {
    let mut g = Group::new()
        .set("stroke", "#000000")
        .set("stroke-width", 2.5);
    for w in &world.walls {
        g = g.add(segment(w, v));
    }
    // Obstacles below the scanner's plane: dashed, the scanner never saw them.
    for w in &world.low {
        g = g.add(segment(w, v).set("stroke-dasharray", "4 3"));
    }
    // People walking through: their way, dotted purple, and their size at
    // the way in.
    for p in &world.walkers {
        let pts: Vec<String> = p
            .path
            .iter()
            .map(|q| format!("{:.1},{:.1}", v.x(q.x), v.y(q.y)))
            .collect();
        g = g
            .add(
                Polyline::new()
                    .set("points", pts.join(" "))
                    .set("fill", "none")
                    .set("stroke", WALKER_COLOUR)
                    .set("stroke-width", 1.5)
                    .set("stroke-dasharray", "2 4"),
            )
            .add(
                Circle::new()
                    .set("cx", v.x(p.path[0].x))
                    .set("cy", v.y(p.path[0].y))
                    .set("r", p.radius * SCALE)
                    .set("fill", "none")
                    .set("stroke", WALKER_COLOUR)
                    .set("stroke-width", 1.5),
            );
    }
    g
}

/// Colour of the people walking through (`walker` lines) in the pictures.
const WALKER_COLOUR: &str = "#8e44ad";

fn segment(w: &crate::world::Wall, v: &View) -> Line {
    Line::new()
        .set("x1", v.x(w.seg.a.x))
        .set("y1", v.y(w.seg.a.y))
        .set("x2", v.x(w.seg.b.x))
        .set("y2", v.y(w.seg.b.y))
}

fn track(poses: &[Pose], v: &View, colour: &str, width: f64) -> Polyline {
    let step = (poses.len() / 20_000).max(1);
    let pts: Vec<String> = poses
        .iter()
        .step_by(step)
        .map(|p| format!("{:.1},{:.1}", v.x(p.translation.x), v.y(p.translation.y)))
        .collect();
    Polyline::new()
        .set("points", pts.join(" "))
        .set("fill", "none")
        .set("stroke", colour)
        .set("stroke-width", width)
}

fn robot(p: &Pose, radius: f64, v: &View) -> Circle {
    Circle::new()
        .set("cx", v.x(p.translation.x))
        .set("cy", v.y(p.translation.y))
        .set("r", radius * SCALE)
        .set("fill", "none")
        .set("stroke", "#d62728")
        .set("stroke-width", 2)
}

/// The cells of one decomposition with the track so far and the robot.
pub fn cells_svg(
    world: &World,
    decomp: &Decomposition,
    track_so_far: &[Pose],
    robot_radius: f64,
    caption_text: &str,
) -> Document {
    let v = View::of(&world.free);
    let mut doc = v.doc(30.0);
    for c in &decomp.cells {
        let fill = match c.status {
            CellStatus::Open => "#fdae6b",
            CellStatus::Settling => "#fee391",
            CellStatus::Final => "#a1d99b",
        };
        let pts: Vec<String> = c
            .polygon
            .iter()
            .map(|p| format!("{:.1},{:.1}", v.x(p.x), v.y(p.y)))
            .collect();
        doc = doc.add(
            Polygon::new()
                .set("points", pts.join(" "))
                .set("fill", fill)
                .set("fill-opacity", 0.7)
                .set("stroke", "#31a354")
                .set("stroke-width", 1.5),
        );
        if !c.polygon.is_empty() {
            let n = c.polygon.len() as f64;
            let cx = c.polygon.iter().map(|p| p.x).sum::<f64>() / n;
            let cy = c.polygon.iter().map(|p| p.y).sum::<f64>() / n;
            doc = doc.add(
                label(v.x(cx), v.y(cy), format!("{}", c.id.0), 16).set("text-anchor", "middle"),
            );
        }
    }
    doc = doc.add(walls(world, &v));
    if let Some(last) = track_so_far.last() {
        doc = doc
            .add(track(track_so_far, &v, "#3182bd", 1.5))
            .add(robot(last, robot_radius, &v));
    }
    doc.add(caption(v.w, v.h + 22.0, caption_text, 16))
}

/// The final path over the world, with pass counts per ground-truth cell.
pub fn path_svg(
    world: &World,
    passes: &[u16],
    reachable: &[bool],
    trajectory: &[Pose],
    m: &CoverageMetrics,
    title: &str,
) -> Document {
    let r = &world.free;
    let v = View::of(r);
    let mut doc = v.doc(30.0);
    // Run-length rows of equal colour.
    let colour = |i: usize| -> Option<&'static str> {
        match passes.get(i).copied().unwrap_or(0) {
            0 if reachable.get(i).copied().unwrap_or(false) => Some("#de2d26"),
            0 => None,
            1 => Some("#c6dbef"),
            2 => Some("#6baed6"),
            _ => Some("#2171b5"),
        }
    };
    let cells = floor_cells(r, &v, colour);
    doc = doc
        .add(cells)
        .add(walls(world, &v))
        .add(track(trajectory, &v, "#08306b", 1.2));
    if let Some(first) = trajectory.first() {
        doc = doc.add(
            Circle::new()
                .set("cx", v.x(first.translation.x))
                .set("cy", v.y(first.translation.y))
                .set("r", 6)
                .set("fill", "#31a354"),
        );
    }
    let caption_text = format!(
        "{title}: coverage {:.1}% of reachable ({:.1}% footprint), overlap {:.1}%, path {:.1} m, {} turns, {:.0} s, {} collisions",
        m.coverage * 100.0,
        m.footprint_coverage * 100.0,
        m.overlap * 100.0,
        m.path_length,
        m.turns,
        m.time,
        m.collisions
    );
    doc.add(caption(v.w, v.h + 22.0, caption_text, 14))
}

/// [`raster_cells`] with every non-free cell grey and `colour` deciding the
/// free ones: the ground of the path, overlap and motions pictures.
fn floor_cells(r: &FreeRaster, v: &View, colour: impl Fn(usize) -> Option<&'static str>) -> Group {
    raster_cells(r, v, |i| {
        if r.free[i] {
            colour(i)
        } else {
            Some("#bdbdbd")
        }
    })
}

/// The raster's cells as run-length rows of equal colour (`colour` of a
/// cell index; `None` leaves the cell blank).
fn raster_cells(r: &FreeRaster, v: &View, colour: impl Fn(usize) -> Option<&'static str>) -> Group {
    let mut cells = Group::new().set("shape-rendering", "crispEdges");
    for y in 0..r.height {
        let mut x = 0;
        while x < r.width {
            let c = colour(y * r.width + x);
            let start = x;
            while x < r.width && colour(y * r.width + x) == c {
                x += 1;
            }
            if let Some(col) = c {
                let x0 = r.origin.x + start as f64 * r.resolution;
                let y0 = r.origin.y + (y + 1) as f64 * r.resolution;
                cells = cells.add(
                    Rectangle::new()
                        .set("x", v.x(x0))
                        .set("y", v.y(y0))
                        .set("width", (x - start) as f64 * r.resolution * SCALE)
                        .set("height", r.resolution * SCALE)
                        .set("fill", col),
                );
            }
        }
    }
    cells
}

/// Colours of the overlap causes (index as in `coverage_metrics::OVERLAP_CAUSES`).
const CAUSE_COLOURS: [&str; 7] = [
    "#e41a1c", "#ff7f00", "#984ea3", "#4daf4a", "#377eb8", "#17becf", "#404040",
];

/// Where floor was swept a second time, coloured by what the robot was
/// doing then (`causes`: per ground-truth cell, an index into
/// [`OVERLAP_CAUSES`], or `u8::MAX` for floor swept at most once), with the
/// path, a legend and a title naming `subject` and the `overlap` share.
pub fn overlap_svg(
    world: &World,
    causes: &[u8],
    trajectory: &[Pose],
    subject: &str,
    overlap: f64,
) -> Document {
    let legend = &OVERLAP_CAUSES;
    let title = format!(
        "{subject}: floor swept again ({:.1}% of swept), by what the robot was doing",
        overlap * 100.0
    );
    let r = &world.free;
    let v = View::of(r);
    let line = 18.0;
    let mut doc = v.doc(30.0 + line * legend.len() as f64);
    let colour = |i: usize| -> Option<&'static str> {
        causes
            .get(i)
            .and_then(|&c| CAUSE_COLOURS.get(c as usize).copied())
    };
    let cells = floor_cells(r, &v, colour);
    doc = doc
        .add(cells)
        .add(walls(world, &v))
        .add(track(trajectory, &v, "#08306b", 0.8))
        .add(caption(v.w, v.h + 22.0, &title, 14));
    let entries = legend
        .iter()
        .enumerate()
        .map(|(k, name)| (CAUSE_COLOURS[k % CAUSE_COLOURS.len()], *name));
    add_legend(doc, v.h + 30.0, line, 14.0, entries)
}

/// `doc` with one legend line per `(colour, name)` from `y0` down, `line`
/// apart, each with a swatch `swatch` high (a square, or a bar for a path).
fn add_legend<'a>(
    mut doc: Document,
    y0: f64,
    line: f64,
    swatch: f64,
    entries: impl Iterator<Item = (&'a str, &'a str)>,
) -> Document {
    for (k, (colour, name)) in entries.enumerate() {
        let y = y0 + line * k as f64;
        doc = doc
            .add(
                Rectangle::new()
                    .set("x", 8.0)
                    .set("y", y + (14.0 - swatch) / 2.0)
                    .set("width", 14.0)
                    .set("height", swatch)
                    .set("fill", colour),
            )
            .add(label(28.0, y + 12.0, name, 13));
    }
    doc
}

/// Motions of [`motions_svg`] with their colour and legend, in drawing order.
const MOTION_STYLES: [(Motion, &str, &str); 7] = [
    (Motion::Lane, "#252525", "lane"),
    (Motion::FixUp, "#984ea3", "fix-up lane"),
    (Motion::Connection, "#31a354", "connection between lanes"),
    (Motion::Transit, "#2171b5", "transit to a region"),
    (Motion::Explore, "#17becf", "exploration"),
    (
        Motion::Other,
        "#e6550d",
        "turns in place, look-around, escape, idle",
    ),
    (Motion::Home, "#c51b8a", "drive back to the start"),
];

/// The path coloured by what the robot was doing (`doing`: per pose of
/// `trajectory`, its motion and task number), over the floor swept once
/// (light grey) and more (darker), each task's number written where it
/// began: where a lane's order or a transit went wrong, at a glance.
pub fn motions_svg(
    world: &World,
    passes: &[u16],
    trajectory: &[Pose],
    doing: &[(Motion, u32)],
    title: &str,
) -> Document {
    let r = &world.free;
    let v = View::of(r);
    let line = 18.0;
    let mut doc = v.doc(30.0 + line * MOTION_STYLES.len() as f64);
    let colour = |i: usize| -> Option<&'static str> {
        match passes.get(i).copied().unwrap_or(0) {
            0 => None,
            1 => Some("#f0f0f0"),
            _ => Some("#d0d0d0"),
        }
    };
    doc = doc.add(floor_cells(r, &v, colour)).add(walls(world, &v));
    let n = trajectory.len().min(doing.len());
    let style = |m: Motion| MOTION_STYLES.iter().position(|s| s.0 == m).unwrap_or(5);
    let mut start = 0;
    while start + 1 < n {
        // One polyline per run of equal motion, sharing its first pose with
        // the run before so that the path has no gaps.
        let k = style(doing[start + 1].0);
        let mut end = start + 1;
        while end + 1 < n && style(doing[end + 1].0) == k {
            end += 1;
        }
        doc = doc.add(track(
            &trajectory[start..=end],
            &v,
            MOTION_STYLES[k].1,
            if k == 0 { 1.0 } else { 1.6 },
        ));
        start = end;
    }
    let mut last_task = u32::MAX;
    for (p, &(_, task)) in trajectory.iter().zip(doing).take(n) {
        if task != last_task && task > 0 {
            doc = doc.add(
                label(
                    v.x(p.translation.x) + 3.0,
                    v.y(p.translation.y) - 3.0,
                    task.to_string(),
                    9,
                )
                .set("fill", "#a50f15"),
            );
        }
        last_task = task;
    }
    doc = doc.add(caption(v.w, v.h + 22.0, title, 14));
    let entries = MOTION_STYLES.iter().map(|(_, col, name)| (*col, *name));
    add_legend(doc, v.h + 30.0, line, 3.0, entries)
}

/// Writes `doc` to `path`.
pub fn save(path: &Path, doc: &Document) -> std::io::Result<()> {
    svg::save(path, doc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    #[test]
    fn motions_picture_colours_each_run_and_numbers_each_task() {
        let w = World::parse("room 0 0 4 0 4 3 0 3\nstart 0.5 0.5 0\n").unwrap();
        let traj: Vec<Pose> = (0..30)
            .map(|k| pose(0.5 + 0.1 * f64::from(k), 0.5, 0.0))
            .collect();
        // A look-around, a transit and a lane of task 1, a connection and a
        // lane of task 2.
        let doing: Vec<(Motion, u32)> = (0..30)
            .map(|k| match k {
                0..=2 => (Motion::Other, 0),
                3..=9 => (Motion::Transit, 1),
                10..=19 => (Motion::Lane, 1),
                20..=22 => (Motion::Connection, 2),
                _ => (Motion::Lane, 2),
            })
            .collect();
        let text = motions_svg(&w, &[], &traj, &doing, "t").to_string();
        let runs = text.matches("<polyline").count();
        assert_eq!(runs, 5, "{text}");
        for colour in ["#2171b5", "#252525", "#31a354", "#e6550d"] {
            assert!(text.contains(colour), "{colour}");
        }
        assert!(
            text.contains(">\n1\n</text>") && text.contains(">\n2\n</text>"),
            "{text}"
        );
    }
}
