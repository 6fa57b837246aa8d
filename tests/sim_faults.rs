//! Faults through the ptys during a closed-loop coverage run: the scanner
//! unplugged for 2 s, the motor link silent for 1 s, bursts of corrupted
//! bytes on both links, and a bumper hit on an obstacle the scanner cannot
//! see. The robot must stop when it must, recover, and still cover the room.

use std::path::Path;

use sweepline::config::Config;
use sweepline::sim::base_emu::Fault;
use sweepline::sim::closed_loop::{self, SimOptions, TimedFault};
use sweepline::sim::world::World;

const ROOM: &str = "name faults\nresolution 0.02\n\
room 0 0 3.2 0 3.2 2.6 0 2.6 refl 0.55\n\
box 1.8 1.0 2.3 1.5 refl 0.8\n\
start 0.5 0.5 0.0\n";

/// The same room plus a low box (a step stool) the scanner's plane misses.
const ROOM_WITH_STOOL: &str = "name faults-body\nresolution 0.02\n\
room 0 0 3.2 0 3.2 2.6 0 2.6 refl 0.55\n\
box 1.8 1.0 2.3 1.5 refl 0.8\n\
low box 0.9 1.9 1.1 2.1\n\
start 0.5 0.5 0.0\n";

/// Farthest a contact mark may lie from an obstacle (m): a one-bit
/// bumper's straight-ahead guess at a contact at its arc's end, 2 (r + gap)
/// sin 40° = 0.23 m, and a centimetre (see [`assert_marks_on_obstacles`]).
const MARK_BOUND: f64 = 0.24;

fn config() -> Config {
    Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("hw/robot.toml")).unwrap()
}

/// Runs one closed loop at a time. Each run is a real-time daemon at ×8
/// with its emulators, and three at once on a 2-core CI machine starve each
/// other's pipeline: once, with other load besides, a run finished at
/// 98.25 % (99.3-99.8 % alone).
fn run_alone(opts: &SimOptions) -> closed_loop::SimReport {
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _turn = ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    closed_loop::run(opts).unwrap()
}

/// A run that failed a bound (`held` false) keeps its folder (pictures,
/// summary, state) under a name the next run does not delete, so the
/// outlier can be read afterwards; returns `held`.
fn kept_unless(opts: &SimOptions, held: bool) -> bool {
    if held {
        return true;
    }
    if let Some(d) = &opts.out {
        let secs = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |t| t.as_secs());
        let keep = d.with_extension(format!("failed-{secs}"));
        match std::fs::rename(d, &keep) {
            Ok(()) => eprintln!("run folder kept in {}", keep.display()),
            Err(e) => eprintln!("could not keep {}: {e}", d.display()),
        }
    }
    false
}

fn out(name: &str) -> Option<std::path::PathBuf> {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    Some(d)
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn coverage_survives_scanner_unplug_motor_silence_and_corruption() {
    let _ = env_logger::builder().is_test(true).try_init();
    let mut opts = SimOptions::new(World::parse(ROOM).unwrap(), config());
    opts.speed = 8.0;
    opts.time_cap = 1200.0;
    // Every 250th scan (25 s at 10 Hz) the scanner's cable is pulled for 2 s.
    opts.urg_faults = "unplug=250:2".parse().unwrap();
    opts.base_faults = vec![
        TimedFault {
            at: 20.0,
            fault: Fault::Silence { secs: 1.0 },
        },
        TimedFault {
            at: 35.0,
            fault: Fault::CorruptOut { bytes: 30 },
        },
        TimedFault {
            at: 40.0,
            fault: Fault::CorruptIn { bytes: 30 },
        },
    ];
    opts.out = out("sim_faults_links");
    let r = run_alone(&opts);
    let m = &r.metrics;
    eprintln!(
        "{}: coverage {:.2} %, pose RMSE {:.1} mm (max {:.1}), urg reconnects {}, wheels held {}, base {:?}, emu {:?}",
        r.reason,
        m.coverage * 100.0,
        r.position_rmse * 1e3,
        r.position_max * 1e3,
        r.urg.reconnects,
        r.scan_holds,
        r.base,
        r.base_emu,
    );
    assert!(r.finished, "did not finish: {}", r.reason);
    assert!(
        kept_unless(&opts, m.coverage >= 0.97),
        "coverage {:.3}",
        m.coverage
    );
    // Across each outage the odometry carried the pose whole: before the
    // tracker heard of gaps, a match after one locked on up to 1.4 m off.
    assert!(
        kept_unless(&opts, r.position_rmse <= 0.03 && r.position_max <= 0.05),
        "pose RMSE {:.1} mm, max {:.1} mm",
        r.position_rmse * 1e3,
        r.position_max * 1e3
    );
    // The scanner came back after being unplugged, and while it was gone
    // the wheels were held (the outage outlasts daemon.scan_timeout).
    assert!(r.urg.reconnects >= 1, "{}", r.urg);
    assert!(r.scan_holds >= 1, "{}", r.scan_holds);
    // The silent motor link was noticed (timeouts) and the run went on.
    assert!(r.base.timeouts >= 1, "{:?}", r.base);
    // Corrupted bytes were caught by the CRC checks on both sides.
    assert!(r.base_emu.corrupted_bytes > 0);
    assert!(
        r.base.checksum_errors + r.base.discarded_bytes > 0,
        "{:?}",
        r.base
    );
    assert!(r.base_emu.device.packets_rejected > 0 || r.base.nacks > 0);
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_bumper_hit_on_an_unseen_obstacle_stops_and_the_run_goes_on() {
    let _ = env_logger::builder().is_test(true).try_init();
    let mut opts = SimOptions::new(World::parse(ROOM_WITH_STOOL).unwrap(), config());
    opts.speed = 8.0;
    opts.time_cap = 1200.0;
    opts.out = out("sim_faults_bump");
    let r = run_alone(&opts);
    let m = &r.metrics;
    eprintln!(
        "{}: coverage {:.2} %, bumps {}, safety events {}, collisions {}, marks taken out {}",
        r.reason,
        m.coverage * 100.0,
        r.base_emu.bumps,
        r.safety_events,
        m.collisions,
        r.marks_taken_out
    );
    // The stool was bumped: the base stopped and the daemon heard of it.
    assert!(r.base_emu.bumps >= 1, "{:?}", r.base_emu);
    assert!(r.safety_events >= 1);
    assert!(r.base.safety_stops >= 1, "{:?}", r.base);
    // It recovered, planned around the marks and finished the room: the
    // marks cover only what the bumper proved, and the floor the bumped path
    // was after was not given up.
    assert!(r.finished, "did not finish: {}", r.reason);
    assert!(
        kept_unless(&opts, m.coverage >= 0.99),
        "coverage {:.4}",
        m.coverage
    );
    assert!(r.position_rmse <= 0.03, "{}", r.position_rmse);
    assert_marks_on_obstacles(&opts, &r);
}

/// Every contact mark lies near an obstacle: a mark out in open floor walls
/// off floor that is there. Before the marks took the measured motion, the
/// pose carried on to the contact's time and the marks already made, 8 of
/// 37 marks in ten runs of this room lay 0.16-0.31 m from any obstacle (the
/// shell's wrong side), one walling off the strip above the stool. The
/// bound is what a bumper that cannot tell its sides allows: a contact at
/// the end of the ±80° arc marked straight ahead is 2 (r + gap) sin 40° =
/// 0.23 m from where it is; seen since: up to 0.13 m (a stool's corner
/// 35° to the side), and 0.20 m with the corner 67° to the side of a robot
/// turning in place (2026-11-27; the bound was 0.2 m until then, below its
/// own worst case). A mark at the leading end of that turn was 0.32-0.36 m
/// off, so a one-bit bumper is no longer marked there.
fn assert_marks_on_obstacles(opts: &SimOptions, r: &closed_loop::SimReport) {
    let astray: Vec<_> = r
        .contacts
        .iter()
        .filter(|c| opts.world.disk_is_free(&c.at, MARK_BOUND))
        .collect();
    assert!(!r.contacts.is_empty());
    assert!(
        kept_unless(opts, astray.is_empty()),
        "marks in open floor: {astray:?} of {:?}",
        r.contacts
    );
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn create2_bumper_sides_place_the_contact_and_the_run_goes_on() {
    // The Create 2 reports which side closed: the contact is marked on that
    // side of the shell instead of straight ahead.
    let _ = env_logger::builder().is_test(true).try_init();
    let mut opts = SimOptions::new(World::parse(ROOM_WITH_STOOL).unwrap(), config());
    opts.base = sweepline::motor::BaseKind::Create2;
    opts.speed = 8.0;
    opts.time_cap = 1200.0;
    opts.out = out("sim_faults_bump_create2");
    let r = run_alone(&opts);
    let m = &r.metrics;
    eprintln!(
        "{}: coverage {:.2} %, bumps {}, safety events {}",
        r.reason,
        m.coverage * 100.0,
        r.base_emu.bumps,
        r.safety_events,
    );
    assert!(r.base_emu.bumps >= 1, "{:?}", r.base_emu);
    assert!(r.base.safety_stops >= 1, "{:?}", r.base);
    assert!(r.finished, "did not finish: {}", r.reason);
    assert!(
        kept_unless(&opts, m.coverage >= 0.99),
        "coverage {:.4}",
        m.coverage
    );
    assert_marks_on_obstacles(&opts, &r);
}
