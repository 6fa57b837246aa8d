//! A ROS `map_server` map nobody here drew: `map.pgm` of the shared maps, a
//! gmapping scan of the lab_ipa building (free 254, unknown 205, walls 0;
//! rooms turned about 3° off the image axes, walls one or two pixels thick
//! and ragged). Loaded through a map YAML as a user would, one room cut out
//! with a region box, and covered in the lock-step simulation online and
//! offline against the targets.

mod coverage_support;
mod ros_map_support;

use std::path::{Path, PathBuf};

use ros_map_support::MAP;
use sweepline::config::Config;
use sweepline::sim::lockstep::LockstepOptions;
use sweepline::sim::ros_map::{self, Region};

/// Writes a map_server YAML into the test's scratch folder naming the
/// shared image.
fn yaml(image: &Path, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ros_map");
    ros_map_support::write_yaml(&dir, name, image)
}

#[test]
fn the_whole_map_loads_with_the_free_area_the_shared_metadata_states() {
    let image = sweepline::require_shared!(MAP);
    let world = ros_map::load_world(&yaml(&image, "whole.yaml"), None, None).unwrap();
    // maps.csv: 309.4 m² of pixels above 250; map_server's free_thresh
    // 0.196 also takes the 96 pixels of 206-250 (0.24 m²).
    let a = world.free.free_area();
    assert!((a - 309.6).abs() < 0.1, "free area {a} m²");
    assert_eq!(world.name, "whole");
    assert!(world.free.is_free(&world.start.translation.vector.into()));
}

#[test]
fn a_room_of_a_gmapping_map_is_covered_online_and_offline() {
    let image = sweepline::require_shared!(MAP);
    let region: Region = "2.3,25.9,7.5,29.8".parse().unwrap();
    let world = ros_map::load_world(&yaml(&image, "room.yaml"), Some(&region), None).unwrap();
    let opts = LockstepOptions {
        time_cap: 3600.0,
        ..LockstepOptions::default()
    };
    let (on, _) = coverage_support::online_and_offline(
        "map.pgm room",
        &world,
        &Config::default(),
        &opts,
        1.25,
        0.99,
    );
    // The room is about 4.4 m x 3.3 m: what the robot's centre can reach is
    // most of it (the rest is wall thickness, the corridor strip below the
    // room's wall and the unknown band above it).
    assert!(
        (9.0..13.0).contains(&on.metrics.reachable_area),
        "{}",
        on.metrics.reachable_area
    );
    // The driven path exported for a robot of one's own: rows in time
    // order, in the map frame, inside the region, ending where the run ended,
    // rows no farther apart than the thinning allows at top speed.
    let csv = sweepline::cli::coverage::trajectory_csv(&on, opts.dt);
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("t_s,x_m,y_m,heading_rad,motion,task"));
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    assert!(rows.len() > 100, "{} rows", rows.len());
    let num = |r: &Vec<String>, k: usize| r[k].parse::<f64>().unwrap();
    let (mut lane_m, mut all_m) = (0.0, 0.0);
    for w in rows.windows(2) {
        assert!(num(&w[1], 0) > num(&w[0], 0));
        let step = ((num(&w[1], 1) - num(&w[0], 1)).powi(2)
            + (num(&w[1], 2) - num(&w[0], 2)).powi(2))
        .sqrt();
        assert!(step < 0.05, "{step} m between rows");
        all_m += step;
        if w[1][4] == "lane" {
            lane_m += step;
        }
    }
    for r in &rows {
        assert_eq!(r.len(), 6);
        let (x, y) = (num(r, 1), num(r, 2));
        assert!(
            (region.lo.x..=region.hi.x).contains(&x) && (region.lo.y..=region.hi.y).contains(&y)
        );
    }
    // The rows add up to the path the metrics measured and the drive back
    // to the start (its rows marked "home"), most of it on lanes.
    let path = on.metrics.path_length + on.metrics.home_length;
    let home_m: f64 = rows
        .windows(2)
        .filter(|w| w[1][4] == "home")
        .map(|w| {
            ((num(&w[1], 1) - num(&w[0], 1)).powi(2) + (num(&w[1], 2) - num(&w[0], 2)).powi(2))
                .sqrt()
        })
        .sum();
    assert!(
        on.metrics.home_length > 0.5 && (home_m - on.metrics.home_length).abs() < 0.05,
        "{home_m} m of home rows, drive back {} m",
        on.metrics.home_length
    );
    assert!(
        (all_m - path).abs() < 0.01 * path,
        "{all_m} m of rows, path {path} m"
    );
    assert!(lane_m > 0.5 * all_m, "{lane_m} of {all_m} m on lanes");
    let end = on.trajectory.last().unwrap().translation.vector;
    let last = rows.last().unwrap();
    assert!((num(last, 1) - end.x).abs() < 1e-3 && (num(last, 2) - end.y).abs() < 1e-3);
    assert!((num(last, 0) - on.trajectory.len() as f64 * opts.dt).abs() < 1e-6);
}

#[test]
fn bad_maps_are_refused_with_the_file_and_the_reason() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ros_map_bad");
    std::fs::create_dir_all(&dir).unwrap();
    // A minimal map YAML in `dir` naming `image` (relative to it), and the
    // error loading it gives.
    let refused = |name: &str, image: &str| {
        let y = dir.join(name);
        std::fs::write(
            &y,
            format!("image: {image}\nresolution: 0.05\norigin: [0, 0, 0]\n"),
        )
        .unwrap();
        (
            y.clone(),
            ros_map::load_world(&y, None, None).unwrap_err().to_string(),
        )
    };
    let (_, e) = refused("missing.yaml", "nowhere.pgm");
    assert!(e.contains("nowhere.pgm"), "{e}");
    std::fs::write(dir.join("short.pgm"), b"P5\n10 10\n255\n\x00\x00").unwrap();
    let (y, e) = refused("short.yaml", "short.pgm");
    assert!(e.contains("short.pgm") && e.contains("truncated"), "{e}");
    // A map with no floor at all (every pixel black).
    let mut bytes = b"P5\n4 4\n255\n".to_vec();
    bytes.extend([0u8; 16]);
    std::fs::write(dir.join("dark.pgm"), bytes).unwrap();
    let (_, e) = refused("dark.yaml", "dark.pgm");
    assert!(e.contains("no free floor in the map"), "{e}");
    // A region with no floor in it.
    let image = sweepline::require_shared!(MAP);
    let empty: Region = "0,0,1,1".parse().unwrap();
    let e = ros_map::load_world(&yaml(&image, "empty.yaml"), Some(&empty), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no free floor inside the region"), "{e}");
    // The command line says it in one line and exits non-zero.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_sweepline"))
        .args(["coverage", "--map"])
        .arg(&y)
        .args(["--out"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("truncated"), "{err}");
}
