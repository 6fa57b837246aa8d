//! An SVG picture of one scan, seen from above: the sensor at the origin
//! facing right, valid beams as dots coloured by intensity, invalid beams as
//! short grey ticks at the edge of the view (so the holes in a scan are
//! visible), and a 1 m grid.

use std::path::Path;

use svg::node::element::{Circle, Line, Rectangle, Text};
use svg::Document;

use super::driver::UrgScan;
use crate::scip::Reading;

/// Pixels per metre.
const SCALE: f64 = 80.0;

/// Draws `scan` into an SVG document `size_m` metres across.
pub(crate) fn scan_svg(scan: &UrgScan, size_m: f64, title: &str) -> Document {
    let half = size_m / 2.0;
    let px = |m: f64| (m + half) * SCALE;
    let py = |m: f64| (half - m) * SCALE;
    let side = size_m * SCALE;
    let mut doc = Document::new()
        .set("viewBox", (0.0, 0.0, side, side + 24.0))
        .set("width", side)
        .set("height", side + 24.0)
        .add(
            Rectangle::new()
                .set("width", side)
                .set("height", side + 24.0)
                .set("fill", "white"),
        );
    let mut g = -half.floor();
    while g <= half {
        for (x1, y1, x2, y2) in [(px(g), 0.0, px(g), side), (0.0, py(g), side, py(g))] {
            doc = doc.add(
                Line::new()
                    .set("x1", x1)
                    .set("y1", y1)
                    .set("x2", x2)
                    .set("y2", y2)
                    .set("stroke", "#e4e4e4")
                    .set("stroke-width", 1),
            );
        }
        g += 1.0;
    }
    let max_i = scan
        .scan
        .beams
        .iter()
        .filter(|b| b.valid)
        .map(|b| b.intensity)
        .fold(0.0f64, f64::max);
    for (b, r) in scan.scan.beams.iter().zip(scan.readings.iter()) {
        let (s, c) = b.angle.sin_cos();
        if b.valid {
            let shade = if max_i > 0.0 {
                (b.intensity / max_i).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let red = (40.0 + 200.0 * shade) as u8;
            doc = doc.add(
                Circle::new()
                    .set("cx", px(b.range * c))
                    .set("cy", py(b.range * s))
                    .set("r", 2)
                    .set(
                        "fill",
                        format!("rgb({red},40,{})", 200 - (150.0 * shade) as u8),
                    ),
            );
        } else {
            let edge = half * 0.95;
            let colour = match r {
                Reading::Error(e) if e.kind.suggests_no_return() => "#9ecae1",
                Reading::BeyondMax(_) => "#9ecae1",
                _ => "#bbbbbb",
            };
            doc = doc.add(
                Line::new()
                    .set("x1", px(edge * 0.93 * c))
                    .set("y1", py(edge * 0.93 * s))
                    .set("x2", px(edge * c))
                    .set("y2", py(edge * s))
                    .set("stroke", colour)
                    .set("stroke-width", 1),
            );
        }
    }
    doc = doc
        .add(
            Circle::new()
                .set("cx", px(0.0))
                .set("cy", py(0.0))
                .set("r", 5)
                .set("fill", "black"),
        )
        .add(
            Line::new()
                .set("x1", px(0.0))
                .set("y1", py(0.0))
                .set("x2", px(0.3))
                .set("y2", py(0.0))
                .set("stroke", "black")
                .set("stroke-width", 2),
        )
        .add(
            Text::new(format!(
                "{title}: {} of {} beams valid; grey ticks = error codes, blue = no return; grid 1 m",
                scan.scan.valid_count(),
                scan.scan.beams.len()
            ))
            .set("x", 6)
            .set("y", side + 17.0)
            .set("font-family", "sans-serif")
            .set("font-size", 12),
        );
    doc
}

/// Writes `scan_svg` to `path`.
pub fn write_scan_svg(
    scan: &UrgScan,
    size_m: f64,
    title: &str,
    path: &Path,
) -> std::io::Result<()> {
    svg::save(path, &scan_svg(scan, size_m, title))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::Beam;
    use crate::scip::{ErrorKind, ErrorReading};

    #[test]
    fn draws_a_dot_per_valid_beam_and_a_tick_per_invalid_one() {
        let mut s = UrgScan::default();
        for i in 0..10 {
            let valid = i % 3 != 0;
            let _ = s.scan.beams.push(Beam {
                angle: -1.0 + 0.2 * f64::from(i),
                range: 2.0,
                intensity: f64::from(i),
                valid,
            });
            let _ = s.readings.push(if valid {
                Reading::Range(2000)
            } else {
                Reading::Error(ErrorReading {
                    code: 0,
                    kind: ErrorKind::PossibleObjectAt22m,
                })
            });
        }
        let text = scan_svg(&s, 6.0, "t").to_string();
        // 6 valid dots + the sensor's own dot.
        assert_eq!(text.matches("<circle").count(), 7);
        assert!(text.contains("6 of 10 beams valid"));
        assert_eq!(text.matches("#9ecae1").count(), 4);
    }
}
