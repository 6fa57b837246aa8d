//! SVG pictures of a coverage run: the cells as they evolve (open cells
//! orange, settling yellow, final green, ids written in them, the robot's
//! track so far) and the final path over the world with the per-cell pass
//! count (white never swept, light blue once, darker twice or more, red where
//! reachable floor was missed).

use std::path::Path;

use svg::node::element::{Circle, Group, Line, Polygon, Polyline, Rectangle};
use svg::Document;

use crate::decomp::{CellStatus, Decomposition};
use crate::geom::Pose;
use crate::sim::coverage_metrics::CoverageMetrics;
use crate::sim::world::{FreeRaster, World};
use crate::svg_canvas::{canvas, label};

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
        g = g.add(
            Line::new()
                .set("x1", v.x(w.seg.a.x))
                .set("y1", v.y(w.seg.a.y))
                .set("x2", v.x(w.seg.b.x))
                .set("y2", v.y(w.seg.b.y)),
        );
    }
    g
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
    caption: &str,
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
    doc.add(label(8.0, v.h + 22.0, caption, 16))
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
        if !r.free[i] {
            return Some("#bdbdbd");
        }
        match passes.get(i).copied().unwrap_or(0) {
            0 if reachable.get(i).copied().unwrap_or(false) => Some("#de2d26"),
            0 => None,
            1 => Some("#c6dbef"),
            2 => Some("#6baed6"),
            _ => Some("#2171b5"),
        }
    };
    let cells = raster_cells(r, &v, colour);
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
    let caption = format!(
        "{title}: coverage {:.1}% of reachable ({:.1}% footprint), overlap {:.1}%, path {:.1} m, {} turns, {:.0} s, {} collisions",
        m.coverage * 100.0,
        m.footprint_coverage * 100.0,
        m.overlap * 100.0,
        m.path_length,
        m.turns,
        m.time,
        m.collisions
    );
    doc.add(label(8.0, v.h + 22.0, caption, 14))
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
/// doing then (`causes`: per ground-truth cell, an index into `legend`, or
/// `u8::MAX` for floor swept at most once), with the path and a legend.
pub fn overlap_svg(
    world: &World,
    causes: &[u8],
    trajectory: &[Pose],
    legend: &[&str],
    title: &str,
) -> Document {
    let r = &world.free;
    let v = View::of(r);
    let line = 18.0;
    let mut doc = v.doc(30.0 + line * legend.len() as f64);
    let colour = |i: usize| -> Option<&'static str> {
        if !r.free[i] {
            return Some("#bdbdbd");
        }
        causes
            .get(i)
            .and_then(|&c| CAUSE_COLOURS.get(c as usize).copied())
    };
    let cells = raster_cells(r, &v, colour);
    doc = doc
        .add(cells)
        .add(walls(world, &v))
        .add(track(trajectory, &v, "#08306b", 0.8))
        .add(label(8.0, v.h + 22.0, title, 14));
    for (k, name) in legend.iter().enumerate() {
        let y = v.h + 30.0 + line * k as f64;
        doc = doc
            .add(
                Rectangle::new()
                    .set("x", 8.0)
                    .set("y", y)
                    .set("width", 14.0)
                    .set("height", 14.0)
                    .set("fill", CAUSE_COLOURS[k % CAUSE_COLOURS.len()]),
            )
            .add(label(28.0, y + 12.0, *name, 13));
    }
    doc
}

/// Writes `doc` to `path`.
pub fn save(path: &Path, doc: &Document) -> std::io::Result<()> {
    svg::save(path, doc)
}
