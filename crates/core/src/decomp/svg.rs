//! SVG pictures of a decomposition over the explored area (like the paper's
//! Fig. 9): unknown space grey, explored free white, occupied black; cells
//! coloured by state with their ids; virtual edges dashed; frontiers red.

use nalgebra::Point2;
use svg::node::element::{Circle, Line, Polygon, Rectangle};
use svg::Document;

use crate::geom::Segment;
use crate::grid::{CellState, Grid};
use crate::svg_canvas::{canvas, label};

use super::cell::{CellStatus, Decomposition};

/// Pixels per metre in the pictures.
pub const SCALE: f64 = 80.0;

/// Size in pixels of a picture of the world rectangle `view` (with its caption).
pub fn picture_size(view: (Point2<f64>, Point2<f64>)) -> (f64, f64) {
    (
        (view.1.x - view.0.x) * SCALE,
        (view.1.y - view.0.y) * SCALE + 30.0,
    )
}

/// Fill colour of a cell by state.
fn status_colour(s: CellStatus) -> &'static str {
    match s {
        CellStatus::Open => "#f4a259",
        CellStatus::Settling => "#f6e27f",
        CellStatus::Final => "#7bc67b",
    }
}

/// The world rectangle `(lower-left, upper-right)` around the explored part
/// of `grid`, with a half-metre margin (the whole grid when nothing is explored).
pub fn explored_bounds(grid: &Grid) -> (Point2<f64>, Point2<f64>) {
    let (o, r) = (grid.origin(), grid.resolution());
    let ((x0, y0), (x1, y1)) = grid
        .explored_cells()
        .unwrap_or(((0, 0), (grid.width().max(1) - 1, grid.height().max(1) - 1)));
    (
        Point2::new(o.x + x0 as f64 * r - 0.5, o.y + y0 as f64 * r - 0.5),
        Point2::new(
            o.x + (x1 + 1) as f64 * r + 0.5,
            o.y + (y1 + 1) as f64 * r + 0.5,
        ),
    )
}

/// Picture of `d` over `grid`, limited to the explored part of the grid; an
/// optional robot position, segments to draw and a caption.
pub fn render(
    d: &Decomposition,
    grid: &Grid,
    robot: Option<Point2<f64>>,
    segments: &[Segment],
    caption: &str,
) -> Document {
    render_view(d, grid, robot, segments, caption, explored_bounds(grid))
}

/// [`render`] over a given world rectangle `(lower-left, upper-right)`, so
/// that pictures of successive updates line up.
pub fn render_view(
    d: &Decomposition,
    grid: &Grid,
    robot: Option<Point2<f64>>,
    segments: &[Segment],
    caption: &str,
    view: (Point2<f64>, Point2<f64>),
) -> Document {
    let (o, r) = (grid.origin(), grid.resolution());
    let (wx0, wy0, wx1, wy1) = (view.0.x, view.0.y, view.1.x, view.1.y);
    let cell_range = |lo: f64, hi: f64, org: f64, n: usize| {
        let a = (((lo - org) / r).floor().max(0.0) as usize).min(n.saturating_sub(1));
        let b = (((hi - org) / r).ceil().max(0.0) as usize).min(n.saturating_sub(1));
        (a, b)
    };
    let (x0, x1) = cell_range(wx0, wx1, o.x, grid.width());
    let (y0, y1) = cell_range(wy0, wy1, o.y, grid.height());
    let sx = |x: f64| (x - wx0) * SCALE;
    let sy = |y: f64| (wy1 - y) * SCALE;
    let (w, h) = ((wx1 - wx0) * SCALE, (wy1 - wy0) * SCALE + 30.0);
    let mut doc = canvas(w, h, "#9a9a9a");
    // The grid, one rectangle per run of equal state in a row.
    for y in y0..=y1 {
        for (start, end, s) in grid.state_runs(y, x0..x1 + 1) {
            let fill = match s {
                CellState::Unknown => continue,
                CellState::Free => "#ffffff",
                CellState::Occupied => "#000000",
            };
            doc = doc.add(
                Rectangle::new()
                    .set("x", sx(o.x + start as f64 * r))
                    .set("y", sy(o.y + (y + 1) as f64 * r))
                    .set("width", (end - start) as f64 * r * SCALE)
                    .set("height", r * SCALE)
                    .set("fill", fill),
            );
        }
    }
    for c in &d.cells {
        let pts: Vec<String> = c
            .polygon
            .iter()
            .map(|p| format!("{:.1},{:.1}", sx(p.x), sy(p.y)))
            .collect();
        doc = doc.add(
            Polygon::new()
                .set("points", pts.join(" "))
                .set("fill", status_colour(c.status))
                .set("fill-opacity", 0.6)
                .set("stroke", "#333333")
                .set("stroke-width", 1),
        );
    }
    for s in segments {
        doc = doc.add(line(s, &sx, &sy, "#1f4fa0", 2.0, None));
    }
    for e in &d.virtual_edges {
        doc = doc.add(line(e, &sx, &sy, "#2060ff", 2.0, Some("6,4")));
    }
    for f in &d.frontiers {
        doc = doc.add(line(&f.boundary, &sx, &sy, "#e00000", 2.5, None));
    }
    for c in &d.cells {
        if c.polygon.is_empty() {
            continue;
        }
        let n = c.polygon.len() as f64;
        let cx = c.polygon.iter().map(|p| p.x).sum::<f64>() / n;
        let cy = c.polygon.iter().map(|p| p.y).sum::<f64>() / n;
        doc =
            doc.add(label(sx(cx), sy(cy), format!("{}", c.id.0), 16).set("text-anchor", "middle"));
    }
    if let Some(p) = robot {
        doc = doc.add(
            Circle::new()
                .set("cx", sx(p.x))
                .set("cy", sy(p.y))
                .set("r", 0.17 * SCALE)
                .set("fill", "none")
                .set("stroke", "#8000c0")
                .set("stroke-width", 3),
        );
    }
    doc.add(label(8.0, h - 8.0, caption.to_string(), 16))
}

fn line(
    s: &Segment,
    sx: &dyn Fn(f64) -> f64,
    sy: &dyn Fn(f64) -> f64,
    colour: &str,
    width: f64,
    dash: Option<&str>,
) -> Line {
    let l = Line::new()
        .set("x1", sx(s.a.x))
        .set("y1", sy(s.a.y))
        .set("x2", sx(s.b.x))
        .set("y2", sy(s.b.y))
        .set("stroke", colour)
        .set("stroke-width", width);
    match dash {
        Some(d) => l.set("stroke-dasharray", d),
        None => l,
    }
}

/// Panels side by side, `columns` per row, each labelled (a), (b), ... like
/// the paper's Fig. 9; every panel keeps its own size.
pub fn panels(docs: Vec<Document>, columns: usize, panel_size: (f64, f64)) -> Document {
    let columns = columns.max(1);
    let (pw, ph) = panel_size;
    let rows = docs.len().div_ceil(columns);
    let (w, h) = (pw * columns as f64, (ph + 24.0) * rows as f64);
    let mut out = Document::new()
        .set("viewBox", (0.0, 0.0, w, h))
        .set("width", w)
        .set("height", h);
    for (i, d) in docs.into_iter().enumerate() {
        let (cx, cy) = (
            (i % columns) as f64 * pw,
            (i / columns) as f64 * (ph + 24.0),
        );
        let letter = format!("({})", (b'a' + (i % 26) as u8) as char);
        out = out
            .add(label(cx + pw / 2.0, cy + 18.0, letter, 18).set("text-anchor", "middle"))
            .add(d.set("x", cx).set("y", cy + 24.0));
    }
    out
}

/// Writes `doc` to `path`.
pub fn save_to(path: &std::path::Path, doc: &Document) -> std::io::Result<()> {
    svg::save(path, doc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decomp::cell::{Cell, CellId};

    #[test]
    fn picture_has_cells_ids_edges_and_caption() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 40, 30);
        for y in 5..25 {
            for x in 5..35 {
                g.set_state((x, y), CellState::Free);
            }
        }
        let cell = |id: u32, y0: f64, status| Cell {
            id: CellId(id),
            polygon: vec![
                Point2::new(1.0, y0),
                Point2::new(3.0, y0),
                Point2::new(3.0, y0 + 0.8),
                Point2::new(1.0, y0 + 0.8),
            ],
            status,
            sweep_angle: 0.0,
            width: 0.8,
            length: 2.0,
        };
        let d = Decomposition {
            cells: vec![
                cell(7, 0.6, CellStatus::Final),
                cell(9, 1.4, CellStatus::Open),
            ],
            virtual_edges: vec![Segment::new(Point2::new(1.0, 1.4), Point2::new(3.0, 1.4))],
            ..Decomposition::default()
        };
        let s = render(&d, &g, Some(Point2::new(2.0, 1.0)), &[], "two cells").to_string();
        assert_eq!(s.matches("<polygon").count(), 2);
        assert!(s.contains("\n7\n") && s.contains("\n9\n") && s.contains("two cells"));
        assert!(s.contains("stroke-dasharray"));
        assert!(s.contains(status_colour(CellStatus::Final)));
        let both = panels(
            vec![
                render(&d, &g, None, &[], "a"),
                render(&d, &g, None, &[], "b"),
            ],
            2,
            (100.0, 80.0),
        )
        .to_string();
        assert!(both.contains("(a)") && both.contains("(b)"));
    }
}
