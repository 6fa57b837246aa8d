//! Map growth on real data: the MIT CSAIL log (Kümmerle et al. 2009 benchmark)
//! replayed through the scan matcher (`icp::Tracker`, default settings), every
//! scan merged into the map at the matched pose (scans the tracker could not
//! match are flagged bad and not merged). The robot drives the corridors,
//! then revisits them. "After the first pass over each corridor" is read as
//! the first scan at which the explored free area reaches 95 % of its final
//! value; stored points after the full log must stay within 2× the points at
//! that scan. Writes the points-vs-scans curve (CSV and SVG) and the map
//! picture under `target/map-pictures/`.

mod map_support;

use sweepline::icp::{IcpParams, Outcome, Tracker};
use sweepline::map::{CorrectionOutcome, Map, MapParams, ScanQuality};
use sweepline::sim::carmen::{self, NO_RETURN_RANGE};

#[test]
fn mit_csail_map_grows_with_surface_not_scans() {
    let log_path = sweepline::require_shared!("datasets/mit-csail/mit-csail.clf");
    let log = carmen::read_file(&log_path).unwrap();
    let start = log.lasers().next().unwrap().laser_pose;
    let mut tracker = Tracker::new(IcpParams::default(), start).unwrap();
    let params = MapParams {
        max_range: 30.0,
        free_clear_range: 10.0,
        grid_resolution: 0.1,
        grid_extent: 140.0,
        ..Default::default()
    };
    let mut map = Map::new(params, start).unwrap();
    let mut pts = Vec::new();
    let cell_area = map.grid().resolution().powi(2);
    let mut rows: Vec<(usize, usize, usize, f64)> = Vec::new();
    let mut bad = 0;
    let (mut applied, mut refused) = (0, 0);
    let n = log.lasers().count();
    for (i, l) in log.lasers().enumerate() {
        let scan = l.to_scan(i as u64, NO_RETURN_RANGE);
        scan.points_into(&mut pts);
        let step = tracker.step(&pts, Some(&l.odom_pose));
        let q = match step.outcome {
            Outcome::First | Outcome::Matched(_) => ScanQuality::Good,
            Outcome::Failed(_) | Outcome::Rejected(..) => ScanQuality::Bad,
        };
        if q == ScanQuality::Bad {
            bad += 1;
        }
        let r = map.update(&scan, &step.pose, q).unwrap();
        match r.correction {
            Some(CorrectionOutcome::Applied(_)) => applied += 1,
            Some(CorrectionOutcome::Refused(_)) => refused += 1,
            _ => {}
        }
        if i % 10 == 0 || i + 1 == n {
            let explored = map.grid().counts().1 as f64 * cell_area;
            rows.push((i + 1, r.points_total, r.segments_total, explored));
        }
    }
    let final_area = rows.last().unwrap().3;
    let first_pass = rows
        .iter()
        .find(|r| r.3 >= 0.95 * final_area)
        .copied()
        .unwrap();
    let last = *rows.last().unwrap();
    let ratio = last.1 as f64 / first_pass.1 as f64;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/map-pictures");
    let _ = std::fs::create_dir_all(&dir);
    let mut csv = String::from("scans,points,segments,explored_m2\n");
    for r in &rows {
        csv.push_str(&format!("{},{},{},{:.2}\n", r.0, r.1, r.2, r.3));
    }
    let _ = std::fs::write(dir.join("mit_csail_growth.csv"), csv);
    let xs: Vec<f64> = rows.iter().map(|r| r.0 as f64).collect();
    map_support::save_svg(
        "mit_csail_growth.svg",
        &map_support::plot(
            &format!(
                "MIT CSAIL: stored points vs scans (first pass ends at scan {}: {} points; end: {} points, {ratio:.2}x)",
                first_pass.0, first_pass.1, last.1
            ),
            "scans",
            &xs,
            &[
                ("stored points", "#d62728", rows.iter().map(|r| r.1 as f64).collect()),
                ("explored free area m2", "#1f77b4", rows.iter().map(|r| r.3).collect()),
                ("map segments", "#2ca02c", rows.iter().map(|r| r.2 as f64).collect()),
            ],
        ),
    );
    map.publish();
    map_support::save_svg(
        "mit_csail_map.svg",
        &sweepline::map::svg::render(&map.snapshot(), &[]),
    );
    eprintln!("segment correction applied to {applied} scans, refused (too large) for {refused}");
    eprintln!(
        "MIT CSAIL: {n} scans, {bad} not merged (matcher failed/rejected); explored {final_area:.0} m2; \
         first pass (95 % of explored area) ends at scan {} with {} points; after the full log {} points, {} segments: {ratio:.2}x",
        first_pass.0, first_pass.1, last.1, last.2
    );
    assert!(bad < n / 20, "{bad} of {n} scans not merged");
    assert!(ratio <= 2.0, "points grew {ratio:.2}x after the first pass");
}
