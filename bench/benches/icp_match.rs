//! Scan-matching speed on the MIT CSAIL benchmark log (361-beam scans):
//! one match against the keyframe local map, one scan-to-scan match, and the
//! whole log through the tracker with the default settings and with the
//! daemon's (`hw/robot.toml`) (per-scan cost = time / 1987 scans).
//! Skips with one line when `../shared/datasets/mit-csail/mit-csail.clf` is missing.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use sweepline::geom::{IPoint, Pose};
use sweepline::icp::{IcpParams, Matcher, Reference, Tracker};
use sweepline::sim::carmen::{self, CarmenLog, NO_RETURN_RANGE};

fn load() -> Option<CarmenLog> {
    let path = sweepline::testdata::shared_file("datasets/mit-csail/mit-csail.clf")?;
    carmen::read_file(&path).ok()
}

fn scans(log: &CarmenLog) -> Vec<(Vec<IPoint>, Pose)> {
    log.lasers()
        .enumerate()
        .map(|(i, l)| {
            let mut pts = Vec::new();
            l.to_scan(i as u64, NO_RETURN_RANGE).points_into(&mut pts);
            (pts, l.odom_pose)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let Some(log) = load() else {
        eprintln!("skipped: shared data datasets/mit-csail/mit-csail.clf not found");
        return;
    };
    let data = scans(&log);
    let params = IcpParams::default();

    // Track the whole log once for the poses; a second tracker stops at scan
    // 300 and keeps its local map as the reference.
    let mut poses = Vec::new();
    let mut full = Tracker::new(params.clone(), data[0].1).unwrap();
    for (pts, odom) in &data {
        poses.push(full.step(pts, Some(odom)).pose);
    }
    let mut tracker = Tracker::new(params.clone(), data[0].1).unwrap();
    for (pts, odom) in &data[..=300] {
        tracker.step(pts, Some(odom));
    }
    // Scans 301..=306 with the realistic prior: previous pose + odometry increment.
    let cases: Vec<(&[IPoint], Pose)> = (301..=306)
        .map(|k| {
            let guess = poses[k - 1] * (data[k - 1].1.inverse() * data[k].1);
            (data[k].0.as_slice(), guess)
        })
        .collect();
    let mut m = Matcher::new(params.clone()).unwrap();
    let mut g = c.benchmark_group("icp_match");
    g.bench_function("scan_to_map_361_beams", |b| {
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) % cases.len();
            m.match_points(tracker.map().reference(), cases[k].0, &cases[k].1)
        })
    });

    // Scan-to-scan: reference = scan k in the world frame at its tracked pose.
    let refs: Vec<Reference> = (250..260)
        .map(|k| {
            let world: Vec<IPoint> = data[k].0.iter().map(|p| p.transformed(&poses[k])).collect();
            let mut r = Reference::new();
            r.rebuild_ordered(&world, &params).unwrap();
            r
        })
        .collect();
    g.bench_function("scan_to_scan_361_beams", |b| {
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) % refs.len();
            let j = 251 + k;
            let guess = poses[j - 1] * (data[j - 1].1.inverse() * data[j].1);
            m.match_points(&refs[k], &data[j].0, &guess)
        })
    });
    // The same matches against the bearing-indexed reference that
    // `scan_fusion` rebuilds from every scan (rebuild included).
    let mut fan = Reference::new();
    let prepared: Vec<Vec<IPoint>> = (250..260)
        .map(|k| {
            let mut pm = Matcher::new(params.clone()).unwrap();
            pm.prepare_points(&data[k].0).unwrap();
            pm.prepared_points().to_vec()
        })
        .collect();
    g.bench_function("scan_to_scan_bearing_index_361_beams", |b| {
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) % prepared.len();
            let j = 251 + k;
            fan.rebuild_scan(&prepared[k], &poses[250 + k], &params)
                .unwrap();
            let guess = poses[j - 1] * (data[j - 1].1.inverse() * data[j].1);
            m.match_points(&fan, &data[j].0, &guess)
        })
    });
    g.finish();

    let mut g = c.benchmark_group("icp_track");
    g.sample_size(10);
    g.throughput(Throughput::Elements(data.len() as u64 - 1));
    // The defaults, and the daemon's matcher: hw/robot.toml's [icp] table
    // (40 keyframes, so a larger k-d tree to query and to rebuild at each
    // keyframe).
    let path = sweepline::testdata::repo_file("hw/robot.toml");
    let daemon = sweepline::config::Config::load(&path)
        .expect("hw/robot.toml loads")
        .icp;
    for (name, p) in [
        ("mit_csail_whole_log", &params),
        ("mit_csail_whole_log_robot_toml", &daemon),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut t = Tracker::new(p.clone(), data[0].1).unwrap();
                for (pts, odom) in &data {
                    t.step(pts, Some(odom));
                }
                t.pose()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
