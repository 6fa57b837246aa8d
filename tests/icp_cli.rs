//! `sweepline replay` and `sweepline eval` end to end on a generated CARMEN log
//! of a known path: the files appear, and the trajectory scores near zero
//! against relations made from the true path.

use std::fmt::Write as _;
use std::process::Command;

use sweepline::geom::{pose, Pose};
use sweepline::icp::synth::{cast, ScanSpec, Wall};

fn scene() -> Vec<Wall> {
    vec![
        Wall::new(0.0, 0.0, 8.0, 0.0, 0.5),
        Wall::new(8.0, 0.0, 8.0, 3.0, 0.5),
        Wall::new(8.0, 3.0, 5.0, 3.0, 0.5),
        Wall::new(5.0, 3.0, 5.0, 5.0, 0.5),
        Wall::new(5.0, 5.0, 0.0, 5.0, 0.5),
        Wall::new(0.0, 5.0, 0.0, 0.0, 0.5),
        Wall::new(2.0, 2.0, 2.5, 2.0, 0.5),
        Wall::new(2.5, 2.0, 2.5, 2.6, 0.5),
        Wall::new(2.5, 2.6, 2.0, 2.6, 0.5),
        Wall::new(2.0, 2.6, 2.0, 2.0, 0.5),
    ]
}

fn sweepline(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_sweepline"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn replay_then_eval_on_a_generated_log() {
    let dir = std::env::temp_dir().join(format!("sweepline-icp-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let walls = scene();
    let spec = ScanSpec {
        beams: 361,
        start_angle: -std::f64::consts::FRAC_PI_2,
        end_angle: std::f64::consts::FRAC_PI_2,
        max_range: 80.0,
        range_noise: 0.005,
        seed: 0,
    };
    let mut truth: Vec<(f64, Pose)> = Vec::new();
    let mut log = String::from("# generated\nPARAM robot_frontlaser_offset 0.0 host 0\n");
    let mut p = pose(1.0, 1.0, 0.3);
    let mut odom = pose(0.0, 0.0, 0.0);
    for k in 0..60 {
        let t = 1000.0 + 0.2 * k as f64;
        if k > 0 {
            let d = pose(0.06, 0.0, if k < 30 { 0.02 } else { -0.03 });
            p *= d;
            odom *= pose(0.066, 0.0, 0.8 * d.rotation.angle());
        }
        let pts = cast(&walls, &p, &ScanSpec { seed: k, ..spec });
        assert_eq!(pts.len(), 361, "closed room: every beam hits");
        let ranges: Vec<String> = pts
            .iter()
            .map(|q| format!("{:.4}", q.x.hypot(q.y)))
            .collect();
        let (ox, oy, oth) = (
            odom.translation.x,
            odom.translation.y,
            odom.rotation.angle(),
        );
        writeln!(
            log,
            "FLASER 361 {} {ox:.5} {oy:.5} {oth:.5} {ox:.5} {oy:.5} {oth:.5} {t:.6} host {t:.6}",
            ranges.join(" ")
        )
        .unwrap();
        writeln!(
            log,
            "ODOM {ox:.5} {oy:.5} {oth:.5} 0.3 0.1 0 {t:.6} host {t:.6}"
        )
        .unwrap();
        truth.push((t, p));
    }
    let log_path = dir.join("gen.clf");
    std::fs::write(&log_path, log).unwrap();
    let mut rel = String::new();
    for k in 0..truth.len() - 2 {
        for j in [k + 1, k + 2] {
            let d = truth[k].1.inverse() * truth[j].1;
            writeln!(
                rel,
                "{:.6} {:.6} {:.6} {:.6} 0 0 0 {:.6}",
                truth[k].0,
                truth[j].0,
                d.translation.x,
                d.translation.y,
                d.rotation.angle()
            )
            .unwrap();
        }
    }
    let rel_path = dir.join("gen.relations");
    std::fs::write(&rel_path, rel).unwrap();

    let out = dir.join("out");
    let (ok, stdout, stderr) = sweepline(&[
        "replay",
        log_path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "replay failed: {stderr}");
    assert!(stdout.contains("scans: 60  matched: 59"), "{stdout}");
    assert!(stdout.contains("thread CPU time per scan"), "{stdout}");
    for f in ["trajectory.txt", "replay.svg", "steps.txt", "summary.txt"] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let traj = std::fs::read_to_string(out.join("trajectory.txt")).unwrap();
    assert_eq!(traj.lines().count(), 60);
    let svg = std::fs::read_to_string(out.join("replay.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("path"));

    let (ok, stdout, stderr) = sweepline(&[
        "eval",
        "--relations",
        rel_path.to_str().unwrap(),
        out.join("trajectory.txt").to_str().unwrap(),
    ]);
    assert!(ok, "eval failed: {stderr}");
    let all = stdout.lines().find(|l| l.starts_with("all")).unwrap();
    let fields: Vec<&str> = all.split_whitespace().collect();
    let trans: f64 = fields[2].parse().unwrap();
    let rot: f64 = fields[8].parse().unwrap();
    assert!(trans < 0.01 && rot < 0.3, "{stdout}");
    assert!(stdout.contains("0 not found"), "{stdout}");

    // Bad input: a malformed log names file and line; a missing file fails.
    let bad = dir.join("bad.clf");
    std::fs::write(&bad, "FLASER 361 1.0 2.0\n").unwrap();
    let (ok, _, stderr) = sweepline(&[
        "replay",
        bad.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        !ok && stderr.contains("bad.clf: line 1") && stderr.contains("expected 361 ranges"),
        "{stderr}"
    );
    let (ok, _, stderr) = sweepline(&[
        "eval",
        "--relations",
        bad.to_str().unwrap(),
        out.join("trajectory.txt").to_str().unwrap(),
    ]);
    assert!(!ok && stderr.contains("line 1"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}
