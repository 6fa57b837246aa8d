//! SVG latency histograms: log-spaced bins on a log time axis (10 per
//! decade), with the median, p99, maximum and the stage budget marked.

use std::time::Duration;

use svg::node::element::{Group, Line, Rectangle, Text};
use svg::Document;

use crate::pipeline::metrics::LatencyHistogram;
use crate::svg_canvas::{canvas, label};

const W: f64 = 720.0;
const H: f64 = 340.0;
const LEFT: f64 = 70.0;
const RIGHT: f64 = 40.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 60.0;
const BINS_PER_DECADE: f64 = 10.0;

/// A time in engineering units: `850 ns`, `12.3 µs`, `4.56 ms`, `1.20 s`.
pub(crate) fn fmt_duration(secs: f64) -> String {
    let a = secs.abs();
    if a == 0.0 {
        "0".into()
    } else if a < 1e-6 {
        format!("{:.0} ns", secs * 1e9)
    } else if a < 1e-3 {
        format!("{:.1} µs", secs * 1e6)
    } else if a < 1.0 {
        format!("{:.2} ms", secs * 1e3)
    } else {
        format!("{secs:.2} s")
    }
}

fn text(x: f64, y: f64, s: &str, size: u32, anchor: &str) -> Text {
    label(x, y, s, size).set("text-anchor", anchor)
}

/// Histogram of `hist` titled `title`, with a limit (a stage budget, a
/// target) marked and labelled when given.
pub(crate) fn latency_svg(
    title: &str,
    hist: &LatencyHistogram,
    limit: Option<(&str, Duration)>,
) -> Document {
    let budget = limit.map(|l| l.1);
    let mut doc = canvas(W, H, "white").add(text(W / 2.0, 22.0, title, 16, "middle"));
    let pw = W - LEFT - RIGHT;
    let ph = H - TOP - BOTTOM;
    if hist.count() == 0 {
        return doc.add(text(W / 2.0, H / 2.0, "no samples", 14, "middle"));
    }
    let min_ns = hist.inner().min().max(1) as f64;
    let mut max_ns = hist.max().as_nanos() as f64;
    if let Some(b) = budget {
        max_ns = max_ns.max(b.as_nanos() as f64);
    }
    let lo = min_ns.log10().floor();
    let hi = (max_ns.log10() + 1e-9).ceil().max(lo + 1.0);
    let nbins = ((hi - lo) * BINS_PER_DECADE).round() as usize;
    let mut bins = vec![0u64; nbins.max(1)];
    for v in hist.inner().iter_recorded() {
        let x = (v.value_iterated_to().max(1) as f64).log10();
        let i = (((x - lo) * BINS_PER_DECADE).floor().max(0.0) as usize).min(bins.len() - 1);
        bins[i] += v.count_at_value();
    }
    let peak = bins.iter().copied().max().unwrap_or(1).max(1) as f64;
    let xpos = |ns: f64| LEFT + (ns.max(1.0).log10() - lo) / (hi - lo) * pw;
    let bw = pw / bins.len() as f64;

    let mut bars = Group::new().set("fill", "#4a7ab5");
    for (i, &c) in bins.iter().enumerate() {
        if c == 0 {
            continue;
        }
        // At least 1.5 px, so a single sample in the tail stays visible.
        let h = (c as f64 / peak * ph).max(1.5);
        bars = bars.add(
            Rectangle::new()
                .set("x", LEFT + i as f64 * bw + 0.5)
                .set("y", TOP + ph - h)
                .set("width", (bw - 1.0).max(0.5))
                .set("height", h),
        );
    }
    doc = doc.add(bars);

    // Axes, decade ticks, count scale.
    let mut axes = Group::new().set("stroke", "black").set("stroke-width", 1);
    axes = axes
        .add(
            Line::new()
                .set("x1", LEFT)
                .set("y1", TOP + ph)
                .set("x2", LEFT + pw)
                .set("y2", TOP + ph),
        )
        .add(
            Line::new()
                .set("x1", LEFT)
                .set("y1", TOP)
                .set("x2", LEFT)
                .set("y2", TOP + ph),
        );
    doc = doc.add(axes);
    let mut d = lo;
    while d <= hi + 1e-9 {
        let x = LEFT + (d - lo) / (hi - lo) * pw;
        doc = doc
            .add(
                Line::new()
                    .set("x1", x)
                    .set("y1", TOP + ph)
                    .set("x2", x)
                    .set("y2", TOP + ph + 5.0)
                    .set("stroke", "black"),
            )
            .add(text(
                x,
                TOP + ph + 18.0,
                &fmt_duration(10f64.powf(d) * 1e-9),
                11,
                "middle",
            ));
        d += 1.0;
    }
    doc = doc
        .add(text(
            LEFT + pw / 2.0,
            H - 12.0,
            "latency (log scale), 10 bins per decade",
            12,
            "middle",
        ))
        .add(text(
            LEFT - 8.0,
            TOP + 4.0,
            &format!("{}", peak as u64),
            11,
            "end",
        ))
        .add(text(LEFT - 8.0, TOP + ph, "0", 11, "end"))
        .add(
            text(18.0, TOP + ph / 2.0, "samples", 12, "middle")
                .set("transform", format!("rotate(-90 18 {})", TOP + ph / 2.0)),
        );

    // Markers: p50, p99, max (grey), budget (red, dashed).
    let mut marks: Vec<(&str, f64, &str, bool)> = vec![
        ("p50", hist.quantile(0.5).as_nanos() as f64, "#333", false),
        ("p99", hist.quantile(0.99).as_nanos() as f64, "#333", false),
        ("max", hist.max().as_nanos() as f64, "#333", false),
    ];
    if let Some((label, b)) = limit {
        marks.push((label, b.as_nanos() as f64, "#c0392b", true));
    }
    for (k, (label, ns, colour, dashed)) in marks.into_iter().enumerate() {
        let x = xpos(ns);
        let mut line = Line::new()
            .set("x1", x)
            .set("y1", TOP)
            .set("x2", x)
            .set("y2", TOP + ph)
            .set("stroke", colour)
            .set("stroke-width", if dashed { 2 } else { 1 });
        if dashed {
            line = line.set("stroke-dasharray", "6 4");
        }
        // Labels near the right edge go to the left of their line.
        let (lx, anchor) = if x > LEFT + 0.75 * pw {
            (x - 3.0, "end")
        } else {
            (x + 3.0, "start")
        };
        doc = doc.add(line).add(
            text(
                lx,
                TOP + 12.0 + 13.0 * k as f64,
                &format!("{label} {}", fmt_duration(ns * 1e-9)),
                11,
                anchor,
            )
            .set("fill", colour),
        );
    }
    doc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_read_naturally() {
        assert_eq!(fmt_duration(0.0), "0");
        assert_eq!(fmt_duration(850e-9), "850 ns");
        assert_eq!(fmt_duration(12.34e-6), "12.3 µs");
        assert_eq!(fmt_duration(4.561e-3), "4.56 ms");
        assert_eq!(fmt_duration(1.2), "1.20 s");
    }

    #[test]
    fn svg_has_one_bar_per_occupied_bin_and_the_budget() {
        let mut h = LatencyHistogram::new();
        for _ in 0..100 {
            h.record(Duration::from_micros(50));
        }
        h.record(Duration::from_millis(3));
        let s = latency_svg("map", &h, Some(("budget", Duration::from_millis(2)))).to_string();
        assert_eq!(s.matches("<rect").count(), 1 + 2, "background + two bars");
        assert!(s.contains("budget 2.00 ms"));
        assert!(s.contains("max 3.00 ms"));
        let empty = latency_svg("x", &LatencyHistogram::new(), None).to_string();
        assert!(empty.contains("no samples"));
    }
}
