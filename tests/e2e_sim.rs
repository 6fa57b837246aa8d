//! End to end through the real pty path: the emulated URG-04LX and RoboClaw
//! on ptys, the daemon opening both, covering a small world time-scaled.
//! Asserts ground-truth coverage, localisation error, scan stamps against
//! the emulator's sampling times and that both links carried traffic.
//! Wall-clock figures are not asserted (shared machine).

mod ros_map_support;

use std::path::Path;

use sweepline::checks::{offset_check, travel_check};
use sweepline::config::Config;
use sweepline::motor::BaseKind;
use sweepline::sim::closed_loop::{self, SimOptions};
use sweepline::sim::ros_map;
use sweepline::sim::world::World;

/// A 3.2 m × 2.6 m room with a box: small enough for a test run.
const SMALL: &str = "name e2e-small\nresolution 0.02\n\
room 0 0 3.2 0 3.2 2.6 0 2.6 refl 0.55\n\
box 1.8 1.0 2.3 1.5 refl 0.8\n\
start 0.5 0.5 0.0\n";

fn config() -> Config {
    Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("hw/robot.toml")).unwrap()
}

/// The folder [`out_dir`] gives `name`, without clearing it.
fn out_dir_path(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join(name)
}

fn out_dir(name: &str) -> std::path::PathBuf {
    let d = out_dir_path(name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Runs the small world (speed 8, 15 min cap) with `cfg` and `set` applied
/// to the options and prints the run's line.
fn small_report(cfg: Config, set: impl FnOnce(&mut SimOptions)) -> closed_loop::SimReport {
    let mut opts = SimOptions::new(World::parse(SMALL).unwrap(), cfg);
    opts.speed = 8.0;
    opts.time_cap = 900.0;
    set(&mut opts);
    let r = closed_loop::run(&opts).unwrap();
    let m = &r.metrics;
    eprintln!(
        "{}: frame turned {:?}°, turn ratio {:?}, offset {:?}, travel {:?}, refitted mount {:?}, coverage {:.2} %, overlap {:.1} %, pose RMSE {:.1} mm / {:.2}°, {:.0} s sim in {:.1} s wall",
        r.reason,
        r.frame_turn.map(f64::to_degrees),
        r.turn_ratio,
        r.offset_fit,
        r.travel_fit,
        r.refitted_mount,
        m.coverage * 100.0,
        m.overlap * 100.0,
        r.position_rmse * 1e3,
        r.heading_rmse.to_degrees(),
        r.sim_time,
        r.wall
    );
    r
}

/// What every finished run must hold: finished, ≥ 97 % covered, no
/// collision, the robot's position within 3 cm RMSE.
fn assert_covered(r: &closed_loop::SimReport) {
    let m = &r.metrics;
    assert!(r.finished, "did not finish: {}", r.reason);
    assert!(m.coverage >= 0.97, "coverage {:.3}", m.coverage);
    assert_eq!(m.collisions, 0);
    assert!(r.position_rmse <= 0.03, "position RMSE {}", r.position_rmse);
}

/// [`small_report`], checking what every such run must hold: finished, ≥ 97 % covered, no collision, the robot's pose
/// within 3 cm / 1° RMSE.
fn small_run(cfg: Config, set: impl FnOnce(&mut SimOptions)) -> closed_loop::SimReport {
    let r = small_report(cfg, set);
    assert_covered(&r);
    assert!(
        r.heading_rmse.to_degrees() <= 1.0,
        "heading RMSE {}°",
        r.heading_rmse.to_degrees()
    );
    r
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn daemon_covers_a_small_world_through_the_ptys() {
    let dir = out_dir("e2e_small");
    let d = dir.clone();
    let r = small_run(config(), |o| o.out = Some(d));
    assert!(r.scored_fixes > 100, "{} fixes scored", r.scored_fixes);
    // Scan stamps are the times the emulator sampled the world: the shift
    // that fits the truth best is zero within a few milliseconds.
    assert!(
        r.stamp_offset.abs() <= 0.006,
        "scan stamps off by {:.0} ms",
        r.stamp_offset * 1e3
    );
    assert!(r.urg.scans > 100 && r.urg.checksum_errors == 0);
    assert!(r.base.received > 100, "{:?}", r.base);
    for f in [
        "summary.md",
        "map.svg",
        "path.svg",
        "overlap.svg",
        "metrics.toml",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    // The overlap is split by what the daemon's plan had the robot doing
    // (lanes, connections, transits), not all booked as turning in place.
    let m = &r.metrics;
    let by_motion: f64 = m.overlap_by[..6].iter().sum();
    assert!(
        m.overlap > 0.05 && by_motion > 0.5 * m.overlap,
        "overlap {:.3}, by cause {:?}",
        m.overlap,
        m.overlap_by
    );
    let summary = std::fs::read_to_string(dir.join("summary.md")).unwrap();
    assert!(
        summary.contains("| connection between lanes |"),
        "{summary}"
    );
    // The daemon's planner counters reach the report.
    assert!(r.plan_stats.tasks > 0, "{:?}", r.plan_stats);
    let row = format!(
        "| tasks planned (started over: path blocked / new floor near the robot) | {} ({} / {}) |",
        r.plan_stats.tasks, r.plan_stats.blocked, r.plan_stats.retours
    );
    assert!(summary.contains(&row), "{row}\n{summary}");
    // The daemon left a checkpoint a restart could resume from.
    assert!(dir.join("state").read_dir().unwrap().next().is_some());
    // Coverage done, it drove back to where it started (by the truth, not
    // its own estimate), and said so in the run folder.
    assert_eq!(r.home, Some(sweepline::plan::HomeOutcome::Back));
    assert!(
        r.ended_from_start <= sweepline::plan::planner::HOME_NEAR + 0.05,
        "ended {:.3} m from the start",
        r.ended_from_start
    );
    let events = std::fs::read_to_string(dir.join("events.toml")).unwrap();
    assert!(
        events.contains("drive_back = \"back at the start\""),
        "{events}"
    );
}

/// A robot switched on at an angle to the walls (its map frame is its start
/// pose): the daemon lays its map frame along the walls of the first scan,
/// and the lanes run along them. With `daemon.align_to_walls = false` the
/// same run crosses the room in slanted lanes (`docs/localisation.md`, the map frame).
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_robot_switched_on_at_an_angle_to_the_walls_lays_its_map_along_them() {
    let r = small_run(config(), |o| o.heading_error = 27f64.to_radians());
    let turn = r.frame_turn.expect("the frame was not decided");
    assert!(
        (turn.to_degrees() + 27.0).abs() < 0.5,
        "turned {}°",
        turn.to_degrees()
    );
}

/// A scanner mounted upside down, 8 cm ahead of and 4 cm right of the axle,
/// turned 20° left: the daemon reads its scans through that mount (as set
/// in `[robot]`), and the poses it reports are the robot's.
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_scanner_mounted_upside_down_and_turned_is_read_through_its_mount() {
    let mut cfg = config();
    cfg.robot.scanner_offset_x = 0.08;
    cfg.robot.scanner_offset_y = -0.04;
    cfg.robot.scanner_yaw = 20f64.to_radians();
    cfg.robot.scanner_upside_down = true;
    let r = small_run(cfg, |_| {});
    let ratio = r.turn_ratio.expect("no quarter turn checked");
    assert!(
        (0.9..=1.1).contains(&ratio),
        "scans turned {ratio} of the wheels' turn"
    );
    // Configured as mounted: the scans move along the heading, the yaw stands.
    let fit = r.travel_fit.expect("no metre driven straight");
    assert!(fit.angle.to_degrees().abs() <= 1.0, "{fit:?}");
    assert_eq!(r.refitted_mount, None);
}

/// The same scanner upside down, but the configuration says upright: the
/// scans turn against the wheels, and the daemon stops at its first
/// quarter turn, naming the key, instead of mapping nonsense (without the
/// check the run ended "coverage finished" at 1.19 %).
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_scanner_upside_down_but_configured_upright_stops_the_daemon() {
    let mut opts = SimOptions::new(World::parse(SMALL).unwrap(), config());
    opts.speed = 8.0;
    opts.time_cap = 300.0;
    opts.scanner_truth = Some((sweepline::geom::Pose::identity(), true));
    let r = closed_loop::run(&opts).unwrap();
    eprintln!(
        "{}: turn ratio {:?}, coverage {:.2} %, {:.0} s sim",
        r.reason,
        r.turn_ratio,
        r.metrics.coverage * 100.0,
        r.sim_time
    );
    assert!(!r.finished);
    assert!(r.reason.contains("localise"), "{}", r.reason);
    let ratio = r.turn_ratio.expect("no quarter turn checked");
    assert!(ratio < 0.0, "scans turned {ratio} of the wheels' turn");
    assert!(r.sim_time < 60.0, "stopped only after {} s", r.sim_time);
}

/// Runs the small world with the emulated scanner mounted at `truth` (on
/// the robot) while the configuration says it sits at the axle centre,
/// facing ahead; `fit` is `daemon.fit_scanner_mount`. The report folder
/// is `name` under the test's temporary folder.
fn mount_off_run(
    name: &str,
    truth: sweepline::geom::Pose,
    fit: bool,
    cap: f64,
) -> closed_loop::SimReport {
    let mut cfg = config();
    cfg.daemon.fit_scanner_mount = fit;
    small_report(cfg, |o| {
        o.time_cap = cap;
        o.scanner_truth = Some((truth, false));
        o.out = Some(out_dir(name));
    })
}

/// The `[robot]` value of `key` in the run folder `name`'s `mount.toml`.
fn mount_toml_value(name: &str, key: &str) -> f64 {
    let path = out_dir_path(name).join("mount.toml");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let v: toml::Table = text.parse().unwrap();
    v["robot"][key]
        .as_float()
        .unwrap_or_else(|| panic!("no {key} in\n{text}"))
}

/// [`mount_off_run`] with the scanner turned `deg` degrees left.
fn yaw_off_run(deg: f64, fit: bool, cap: f64) -> closed_loop::SimReport {
    let name = format!("e2e_yaw_{deg}_{fit}");
    mount_off_run(
        &name,
        sweepline::geom::pose(0.0, 0.0, deg.to_radians()),
        fit,
        cap,
    )
}

/// The scanner turned 4° off what `robot.scanner_yaw` says (a mounting
/// tolerance): the scans move 4° off the robot's heading over the first
/// metre, the daemon takes the error into the mount and covers the room as
/// with the right value (without the fit, 3° in the bench room cost 1.2
/// points of coverage and 18 of overlap).
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_scanner_yaw_a_few_degrees_off_is_refitted_on_the_first_metre() {
    let r = yaw_off_run(4.0, true, 900.0);
    let fit = r.travel_fit.expect("no metre driven straight");
    assert!(
        (fit.angle.to_degrees() + 4.0).abs() <= 0.7,
        "scans' travel {:.2}° off the heading",
        fit.angle.to_degrees()
    );
    assert!((0.95..=1.05).contains(&fit.scale), "{fit:?}");
    let yaw = sweepline::geom::heading(&r.refitted_mount.expect("mount not refitted")).to_degrees();
    assert!((yaw - 4.0).abs() <= 0.7, "refitted to {yaw:.2}°");
    // The run folder says what to configure.
    let written = mount_toml_value("e2e_yaw_4_true", "scanner_yaw").to_degrees();
    assert!(
        (written - yaw).abs() < 0.01,
        "mount.toml {written}°, refitted {yaw}°"
    );
    assert_covered(&r);
}

/// Off by 30° (no mounting tolerance), or by 4° with the fit turned off:
/// the daemon stops after its first metre instead of steering crabwise.
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_scanner_yaw_far_off_or_unfitted_stops_the_daemon() {
    for (deg, fit) in [(30.0, true), (4.0, false)] {
        let r = yaw_off_run(deg, fit, 300.0);
        assert!(!r.finished);
        assert!(r.reason.contains("localise"), "{}", r.reason);
        let f = r.travel_fit.expect("no metre driven straight");
        assert!(
            (f.angle.to_degrees() + deg).abs() <= 1.5,
            "{deg}°: scans' travel {:.2}° off the heading",
            f.angle.to_degrees()
        );
        assert_eq!(r.refitted_mount, None);
    }
}

/// The base's wheels 28 cm apart, configured 23.5 cm: the wheel odometry
/// reports 19 % more turn than the robot makes, and the turn check
/// measures the scans' share of it (a warning names the base that fits).
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_wheel_base_configured_short_shows_in_the_turn_check() {
    let r = small_report(config(), |o| {
        o.time_cap = 40.0;
        o.wheel_base_truth = Some(0.28);
    });
    let ratio = r.turn_ratio.expect("no quarter turn checked");
    let want = 0.235 / 0.28;
    assert!(
        (ratio - want).abs() <= 0.04,
        "scans turned {ratio:.3} of the wheels' turn, expected {want:.3}"
    );
}

/// The RoboClaw's motors (and their encoders) wired left for right: every
/// turn the daemon commands turns the robot the other way while the
/// encoders report the commanded turn. The quarter-turn check sees the
/// scans turn against the wheels and stops the daemon (its message names
/// `motor.roboclaw.m1_is_left` beside `robot.scanner_upside_down`).
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn wheels_swapped_left_for_right_stop_the_daemon() {
    let r = small_report(config(), |o| {
        o.time_cap = 120.0;
        o.wheels_swapped = true;
    });
    assert!(!r.finished);
    assert!(r.reason.contains("localise"), "{}", r.reason);
    let ratio = r.turn_ratio.expect("no quarter turn checked");
    assert!(ratio < 0.0, "scans turned {ratio} of the wheels' turn");
    assert!(r.sim_time < 60.0, "stopped only after {} s", r.sim_time);
}

/// [`mount_off_run`] with the scanner `dx`, `dy` m (ahead, left) off.
fn offset_off_run(dx: f64, dy: f64, fit: bool, cap: f64) -> closed_loop::SimReport {
    let name = format!("e2e_offset_{dx}_{dy}_{fit}");
    mount_off_run(&name, sweepline::geom::pose(dx, dy, 0.0), fit, cap)
}

/// The scanner 10 cm ahead of and 5 cm left of the axle, configured at the
/// axle: the look-around's half turn in place shows it circling the axle,
/// the daemon takes the fitted offset into the mount and covers the room
/// with its pose where the robot is.
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_scanner_offset_off_is_refitted_on_the_first_half_turn() {
    let r = offset_off_run(0.10, 0.05, true, 900.0);
    let fit = r.offset_fit.expect("no half turn in place");
    assert!(
        (fit.offset.x - 0.10).abs() <= 0.01 && (fit.offset.y - 0.05).abs() <= 0.01,
        "{fit:?}"
    );
    let m = r.refitted_mount.expect("mount not refitted");
    assert!((m.translation.vector - fit.offset).norm() < 1e-9, "{m:?}");
    // The run folder says what to configure (the yaw as measured, near 0).
    let name = "e2e_offset_0.1_0.05_true";
    let x = mount_toml_value(name, "scanner_offset_x");
    assert!((x - 0.10).abs() <= 0.01, "mount.toml scanner_offset_x {x}");
    assert!(mount_toml_value(name, "scanner_yaw").abs() < 0.0175);
    assert_covered(&r);
}

/// Off by 25 cm (no measuring error), or by 4 cm with the fit turned off:
/// the daemon stops at its first half turn in place.
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_scanner_offset_far_off_or_unfitted_stops_the_daemon() {
    for (dx, fit) in [(0.25, true), (-0.04, false)] {
        let r = offset_off_run(dx, 0.0, fit, 120.0);
        assert!(!r.finished);
        assert!(r.reason.contains("localise"), "{}", r.reason);
        let f = r.offset_fit.expect("no half turn in place");
        assert!((f.offset.x - dx).abs() <= 0.01, "{dx}: {f:?}");
        assert_eq!(r.refitted_mount, None);
        assert!(r.sim_time < 60.0, "stopped only after {} s", r.sim_time);
    }
}

/// The base's wheels 4.0 cm in radius, configured 3.6 cm: the robot drives
/// 11 % farther than the odometry says, which the travel check's scale
/// shows over the first metre; mount.toml notes the radius that fits.
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_wheel_radius_configured_small_shows_in_the_travel_scale() {
    let name = "e2e_wheel_radius";
    let r = small_report(config(), |o| {
        o.time_cap = 60.0;
        o.wheel_radius_truth = Some(0.040);
        o.out = Some(out_dir(name));
    });
    let fit = r.travel_fit.expect("no metre driven straight");
    let want = 0.040 / 0.036;
    assert!(
        (fit.scale - want).abs() <= 0.03,
        "scans moved {:.3} of the wheels' distance, expected {want:.3}",
        fit.scale
    );
    let text = std::fs::read_to_string(out_dir_path(name).join("mount.toml")).unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("# wheel_radius = "))
        .unwrap_or_else(|| panic!("no wheel radius in\n{text}"));
    let fitted: f64 = line["# wheel_radius = ".len()..]
        .split_whitespace()
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!((fitted - 0.040).abs() <= 0.0012, "{line}");
    // The turn is off by the same factor: the base fitted from it, with
    // the first metre's scale taken out, is the configured (true) one, to
    // within what that scale itself is off by (the base is the turn ratio
    // divided by the scale) and 4 mm.
    let base = mount_toml_value(name, "wheel_base");
    let scale_error = (fit.scale - want).abs() / want;
    assert!(
        (base - 0.235).abs() <= 0.004 + 0.235 * scale_error,
        "wheel_base {base} (distance scale off by {:.1} %)\n{text}",
        scale_error * 100.0
    );
}

/// The large room of the lab_ipa building (shared `map.pgm`, a gmapping
/// map nobody here drew; 9 m × 12 m), the robot put down in its middle:
/// two walls lie beyond the scanner's 5.6 m, and the first matches let the
/// position slide along one axis. A scanner mounted as configured must be
/// neither refitted nor stop the daemon there. Before the checks counted
/// only scans that pin the pose down, seeds 1-6 (at the default ×5) read
/// +1.2 to +3.9° and -2.4° of yaw error over the first metre (the daemon
/// took it into the mount; with the fit off, 3.9° stopped it) and up to
/// 2 cm of offset. The checks are now made later, nearer the walls (in
/// all six seeds within 150 s, but not always: the closed loop's timing
/// varies). Without the gate this test failed in 4 of 4 runs; with it, it
/// passed 3 of 3 (the offset read up to 10 mm, under the 15 mm tolerance).
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_large_room_does_not_refit_a_scanner_mounted_right() {
    let image = sweepline::require_shared!(ros_map_support::MAP);
    let yaml = ros_map_support::write_yaml(&out_dir("e2e_large_room"), "map.yaml", &image);
    let region: ros_map::Region = "16.5,9.0,25.5,21.2".parse().unwrap();
    let world = ros_map::load_world(&yaml, Some(&region), None).unwrap();
    let mut made = 0;
    for seed in [1, 4, 6] {
        let mut opts = SimOptions::new(world.clone(), config());
        opts.time_cap = 180.0;
        opts.seed = seed;
        let r = closed_loop::run(&opts).unwrap();
        eprintln!(
            "seed {seed}: {}: offset {:?}, travel {:?}, refitted mount {:?}",
            r.reason, r.offset_fit, r.travel_fit, r.refitted_mount
        );
        assert!(r.reason.contains("time cap"), "seed {seed}: {}", r.reason);
        assert_eq!(r.refitted_mount, None, "seed {seed}");
        // A check is made once the robot reaches firm matches, which the
        // closed loop's timing may put past the cap: each check made must
        // agree with the mount, and some must be made.
        if let Some(travel) = r.travel_fit {
            assert!(
                travel.angle.abs() <= travel_check::YAW_TOLERANCE,
                "seed {seed}: scans' travel {:.2}° off the heading",
                travel.angle.to_degrees()
            );
            made += 1;
        }
        if let Some(offset) = r.offset_fit {
            assert!(
                offset.offset.norm() <= offset_check::OFFSET_TOLERANCE,
                "seed {seed}: {offset:?}"
            );
            made += 1;
        }
    }
    assert!(made >= 3, "{made} of the 6 checks made in 180 s");
}

/// The emulated URG-04LX measures its 682 beams one after another over
/// 67 ms, as the sensor does; the daemon moves each beam to where the
/// scanner was at the scan's stamp by the wheel odometry
/// (`daemon.deskew_scans`). Without that, scans taken while turning at
/// 0.78 rad/s are skewed by 3° across and the pose drifts.
#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn scans_swept_while_turning_are_deskewed_by_the_odometry() {
    let run = |deskew: bool| {
        let mut cfg = config();
        cfg.daemon.deskew_scans = deskew;
        small_report(cfg, |o| o.time_cap = 150.0)
    };
    let on = run(true);
    let off = run(false);
    assert_eq!(on.metrics.collisions, 0);
    assert!(
        on.heading_rmse.to_degrees() <= 0.25 && on.position_rmse <= 0.01,
        "deskewed: {:.1} mm / {:.2}°",
        on.position_rmse * 1e3,
        on.heading_rmse.to_degrees()
    );
    // The test has teeth only while the emulator sweeps its beams.
    assert!(
        off.heading_rmse >= 3.0 * on.heading_rmse && off.heading_rmse.to_degrees() >= 0.3,
        "not deskewed: {:.2}°, deskewed: {:.2}°",
        off.heading_rmse.to_degrees(),
        on.heading_rmse.to_degrees()
    );
}

#[test]
fn bad_speed_is_refused() {
    let mut opts = SimOptions::new(World::parse(SMALL).unwrap(), config());
    opts.speed = 0.0;
    let e = closed_loop::run(&opts).unwrap_err();
    assert!(e.to_string().contains("--speed"), "{e}");
    opts.speed = f64::NAN;
    assert!(closed_loop::run(&opts).is_err());
    let _ = BaseKind::Create2;
}
