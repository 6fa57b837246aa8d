//! Odometry against ground truth on the simulated base with its default slip,
//! wheel-scale error and encoder noise: a 1 m square driven open-loop three
//! times, encoders read as 16-bit Create 2 counters every 15 ms. Draws truth
//! and odometry into an SVG (in Cargo's test temp dir) for a person to look at.

use sweepline::geom::{heading, pose, Pose};
use sweepline::motor::odometry::{CounterWidth, Odometer};
use sweepline::motor::WheelSpeeds;
use sweepline::sim::kinematics::{DiffDriveSim, KinematicsParams};

struct Run {
    truth: Vec<Pose>,
    odom: Vec<Pose>,
}

fn drive_squares(seed: u64) -> Run {
    let params = KinematicsParams {
        seed,
        ..KinematicsParams::default()
    };
    let b = params.wheel_base;
    let mut sim = DiffDriveSim::new(params, pose(0.0, 0.0, 0.0));
    let cpm = 508.8 / (std::f64::consts::PI * 0.072);
    let mut odo = Odometer::new(CounterWidth::Bits16, cpm, b, 0.5);
    let counts = |m: f64| (m * cpm).round() as i64 as u16 as u32;
    let dt = 0.005;
    let mut t = 0.0;
    let mut est = Pose::identity();
    let mut run = Run {
        truth: vec![sim.pose()],
        odom: vec![est],
    };
    let mut segment = |sim: &mut DiffDriveSim, cmd: WheelSpeeds, secs: f64, t: &mut f64| {
        let steps = (secs / dt).round() as usize;
        for i in 0..steps {
            sim.step(cmd, dt, None);
            *t += dt;
            if i % 3 == 0 {
                let (l, r) = sim.encoder_travel();
                if let Some(o) = odo.update(counts(l), counts(r), *t).unwrap() {
                    est *= o.delta;
                    run.truth.push(sim.pose());
                    run.odom.push(est);
                }
            }
        }
    };
    for _ in 0..12 {
        segment(
            &mut sim,
            WheelSpeeds {
                left: 0.2,
                right: 0.2,
            },
            5.0,
            &mut t,
        );
        segment(
            &mut sim,
            WheelSpeeds::from_body(0.0, 0.5, b),
            std::f64::consts::PI,
            &mut t,
        );
        segment(&mut sim, WheelSpeeds::STOP, 0.5, &mut t);
    }
    run
}

fn write_svg(run: &Run, path: &std::path::Path) {
    use svg::node::element::{Path as SvgPath, Text};
    use svg::Document;
    // Fit both paths into a 400 x 340 area below the legend.
    let all = run.truth.iter().chain(run.odom.iter());
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for p in all {
        x0 = x0.min(p.translation.x);
        y0 = y0.min(p.translation.y);
        x1 = x1.max(p.translation.x);
        y1 = y1.max(p.translation.y);
    }
    let scale = (400.0 / (x1 - x0).max(1e-3)).min(330.0 / (y1 - y0).max(1e-3));
    let (ox, oy) = (30.0 - x0 * scale, 385.0 + y0 * scale);
    let line = |poses: &[Pose], colour: &str| {
        let mut d = String::new();
        for (i, p) in poses.iter().enumerate() {
            let (x, y) = (ox + p.translation.x * scale, oy - p.translation.y * scale);
            d.push_str(&format!("{}{x:.1},{y:.1} ", if i == 0 { "M" } else { "L" }));
        }
        SvgPath::new()
            .set("d", d)
            .set("fill", "none")
            .set("stroke", colour)
            .set("stroke-width", 1.5)
    };
    let doc = Document::new()
        .set("viewBox", (0, 0, 460, 420))
        .add(line(&run.truth, "#1f77b4"))
        .add(line(&run.odom, "#d62728"))
        .add(
            Text::new("truth")
                .set("x", 10)
                .set("y", 20)
                .set("fill", "#1f77b4"),
        )
        .add(
            Text::new("wheel odometry")
                .set("x", 10)
                .set("y", 40)
                .set("fill", "#d62728"),
        )
        .add(
            Text::new("1 m open-loop square x3, default slip/scale/noise")
                .set("x", 10)
                .set("y", 410)
                .set("font-size", 12),
        );
    svg::save(path, &doc).unwrap();
}

#[test]
fn odometry_drifts_like_a_real_base_and_deterministically() {
    let a = drive_squares(3);
    let b = drive_squares(3);
    assert_eq!(a.odom.last(), b.odom.last(), "same seed, same odometry");
    let (t, o) = (*a.truth.last().unwrap(), *a.odom.last().unwrap());
    let pos_err = (t.translation.vector - o.translation.vector).norm();
    let head_err = (heading(&t) - heading(&o)).abs();
    // 12 m travelled and 12 quarter turns: drift is there, but a few percent at most.
    assert!(
        pos_err > 0.002 && pos_err < 0.4,
        "position drift {pos_err} m"
    );
    assert!(
        head_err > 1e-4 && head_err < 0.3,
        "heading drift {head_err} rad"
    );
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("motor-odometry-drift.svg");
    write_svg(&a, &out);
    eprintln!(
        "drift after 3 squares: {pos_err:.3} m, {head_err:.4} rad; picture: {}",
        out.display()
    );
}
