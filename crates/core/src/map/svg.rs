//! An SVG picture of a map snapshot: explored free space, points coloured by
//! intensity, wall segments, curves, the robot's trajectory, and optionally
//! reference walls (ground truth) to compare with.

use std::fmt::Write as _;

use nalgebra::Point2;
use svg::node::element::{Circle, Group, Line, Polyline, Rectangle};
use svg::Document;

use super::snapshot::PointMapSnapshot;
use crate::geom::Segment;
use crate::grid::CellState;
use crate::svg_canvas::{canvas, label};

/// Pixels per metre at which pictures are drawn.
const PX_PER_M: f64 = 100.0;
/// Margin around the drawing (px).
const MARGIN: f64 = 20.0;

/// Maps world coordinates to picture pixels (y up in the world, down in SVG).
struct View {
    min: Point2<f64>,
    max: Point2<f64>,
}

impl View {
    fn x(&self, x: f64) -> f64 {
        (x - self.min.x) * PX_PER_M + MARGIN
    }
    fn y(&self, y: f64) -> f64 {
        (self.max.y - y) * PX_PER_M + MARGIN
    }
    fn size(&self) -> (f64, f64) {
        (
            (self.max.x - self.min.x) * PX_PER_M + 2.0 * MARGIN,
            (self.max.y - self.min.y) * PX_PER_M + 2.0 * MARGIN + 20.0,
        )
    }
}

/// A viridis-like colour for intensity `v` in 0..1 (clamped).
pub(crate) fn intensity_colour(v: f64) -> String {
    const STOPS: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let v = if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let f = v * (STOPS.len() - 1) as f64;
    let i = (f.floor() as usize).min(STOPS.len() - 2);
    let t = f - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let c = |x: f64, y: f64| (x + (y - x) * t).round() as u8;
    format!("#{:02x}{:02x}{:02x}", c(a.0, b.0), c(a.1, b.1), c(a.2, b.2))
}

/// Renders `snap` as an SVG document; `reference` walls (e.g. the simulated
/// world's) are drawn thin and green underneath, for comparison.
pub fn render(snap: &PointMapSnapshot, reference: &[Segment]) -> Document {
    let mut min = Point2::new(f64::INFINITY, f64::INFINITY);
    let mut max = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    let mut grow = |p: Point2<f64>| {
        if p.x.is_finite() && p.y.is_finite() {
            min = min.inf(&p);
            max = max.sup(&p);
        }
    };
    snap.points.iter().for_each(|p| grow(p.xy()));
    snap.trajectory
        .iter()
        .for_each(|t| grow(Point2::from(t.translation.vector)));
    reference.iter().for_each(|s| {
        grow(s.a);
        grow(s.b);
    });
    if !min.x.is_finite() {
        min = Point2::new(-1.0, -1.0);
        max = Point2::new(1.0, 1.0);
    }
    let view = View {
        min: min - nalgebra::Vector2::new(0.2, 0.2),
        max: max + nalgebra::Vector2::new(0.2, 0.2),
    };
    let (w, h) = view.size();
    let mut doc = canvas(w, h, "#f4f4f4");
    // Explored free space, as runs of free cells per row.
    let g = &snap.grid;
    let r = g.resolution();
    let mut free = Group::new().set("fill", "#ffffff");
    let mut occ = Group::new().set("fill", "#c8c8c8");
    for cy in 0..g.height() {
        for (start, end, st) in g.state_runs(cy, 0..g.width()) {
            if st == CellState::Unknown {
                continue;
            }
            let x0 = g.origin().x + start as f64 * r;
            let y1 = g.origin().y + (cy + 1) as f64 * r;
            let rect = Rectangle::new()
                .set("x", view.x(x0))
                .set("y", view.y(y1))
                .set("width", (end - start) as f64 * r * PX_PER_M)
                .set("height", r * PX_PER_M);
            if st == CellState::Free {
                free = free.add(rect);
            } else {
                occ = occ.add(rect);
            }
        }
    }
    doc = doc.add(free).add(occ);
    let mut refs = Group::new()
        .set("stroke", "#2ca02c")
        .set("stroke-width", 5)
        .set("stroke-opacity", 0.35);
    for s in reference {
        refs = refs.add(line(&view, s));
    }
    doc = doc.add(refs);
    let mut pts = Group::new();
    for p in &snap.points {
        pts = pts.add(
            Circle::new()
                .set("cx", view.x(p.x))
                .set("cy", view.y(p.y))
                .set("r", 1.2)
                .set("fill", intensity_colour(p.intensity)),
        );
    }
    doc = doc.add(pts);
    let mut segs = Group::new()
        .set("stroke", "#d62728")
        .set("stroke-width", 1.5);
    for s in &snap.segments {
        segs = segs.add(line(&view, &s.seg));
        for e in [s.seg.a, s.seg.b] {
            segs = segs.add(
                Circle::new()
                    .set("cx", view.x(e.x))
                    .set("cy", view.y(e.y))
                    .set("r", 2.5)
                    .set("fill", "#d62728"),
            );
        }
    }
    doc = doc.add(segs);
    let mut curves = Group::new()
        .set("stroke", "#9467bd")
        .set("stroke-width", 2)
        .set("fill", "none");
    for c in &snap.curves {
        curves = curves.add(Polyline::new().set("points", polyline(&view, c.vertices.iter())));
    }
    doc = doc.add(curves);
    let traj: Vec<Point2<f64>> = snap
        .trajectory
        .iter()
        .map(|t| Point2::from(t.translation.vector))
        .collect();
    doc = doc.add(
        Polyline::new()
            .set("points", polyline(&view, traj.iter()))
            .set("fill", "none")
            .set("stroke", "#1f77b4")
            .set("stroke-width", 1.2),
    );
    let caption = format!(
        "{} points (colour = intensity), {} segments (red), {} curves, {} scans merged, trajectory blue{}",
        snap.points.len(),
        snap.segments.len(),
        snap.curves.len(),
        snap.scans_merged,
        if reference.is_empty() {
            ""
        } else {
            ", reference walls green"
        }
    );
    doc.add(label(MARGIN, h - 6.0, caption, 12))
}

fn line(view: &View, s: &Segment) -> Line {
    Line::new()
        .set("x1", view.x(s.a.x))
        .set("y1", view.y(s.a.y))
        .set("x2", view.x(s.b.x))
        .set("y2", view.y(s.b.y))
}

fn polyline<'a>(view: &View, pts: impl Iterator<Item = &'a Point2<f64>>) -> String {
    let mut s = String::new();
    for p in pts {
        let _ = write!(s, "{:.1},{:.1} ", view.x(p.x), view.y(p.y));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_points_segments_and_trajectory() {
        use crate::geom::{pose, IPoint};
        use crate::map::fit::Moments;
        let grid = crate::grid::Grid::new(Point2::new(0.0, 0.0), 0.1, 10, 10);
        let mut snap = PointMapSnapshot::empty(grid, pose(0.0, 0.0, 0.0));
        snap.points = vec![
            IPoint::new(0.1, 0.2, 0.0),
            IPoint::new(0.5, 0.2, 1.0),
            IPoint::new(0.9, 0.2, f64::NAN),
        ];
        let pts = [
            Point2::new(0.0, 1.0),
            Point2::new(1.0, 1.0),
            Point2::new(0.5, 1.0),
        ];
        let m = Moments::of(pts.iter().copied());
        let fit = m.fit(0.01).unwrap();
        snap.segments = vec![crate::map::MapSegment {
            seg: Segment::new(pts[0], pts[1]),
            residual: 0.0,
            observations: 2,
            moments: m,
            fit,
        }];
        snap.trajectory = vec![pose(0.0, 0.0, 0.0), pose(0.5, 0.5, 0.0)];
        let text = render(&snap, &[Segment::new(pts[0], pts[1])]).to_string();
        // 3 points + 2 segment end points.
        assert_eq!(text.matches("<circle").count(), 5, "{text}");
        assert!(text.contains("#440154") && text.contains("#fde725"));
        assert_eq!(
            text.matches("<line").count(),
            2,
            "segment and reference wall"
        );
        assert!(text.contains("3 points"));
        let empty = render(
            &PointMapSnapshot::empty(
                crate::grid::Grid::new(Point2::new(0.0, 0.0), 0.1, 0, 0),
                pose(0.0, 0.0, 0.0),
            ),
            &[],
        )
        .to_string();
        assert!(empty.contains("0 points"));
    }

    #[test]
    fn colours_span_the_map() {
        assert_eq!(intensity_colour(0.0), "#440154");
        assert_eq!(intensity_colour(1.0), "#fde725");
        assert_eq!(intensity_colour(f64::NAN), "#440154");
        assert_eq!(intensity_colour(7.0), "#fde725");
    }
}
