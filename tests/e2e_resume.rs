//! Crash test: the daemon as a separate `sweepline run` process against the
//! emulated URG-04LX and RoboClaw on ptys (in this test process, on one
//! scaled clock whose epoch the child gets through `run --sim-clock`),
//! killed with SIGKILL at about 40 % ground-truth coverage and started again
//! on the same state folder. The second daemon must resume from the last
//! checkpoint (map, pose, swept floor), finish the coverage, and not have
//! lost more than the last checkpoint period. Its report (`state/run/
//! report.md`) must say which checkpoint it resumed from, how old it was at
//! the crash and how much progress that lost, consistently with what this
//! test saw. The emulated scanner sits 5 cm ahead of where the
//! configuration says: the first daemon refits its mount on its first half
//! turn, and the second must drive with the refitted mount from its
//! checkpoint at once. A second case restarts with the mount corrected in
//! the configuration (as an operator would after reading the first run's
//! mount report): the configured mount then wins over the checkpointed one.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use sweepline::clock::{ScaledClock, SharedClock};
use sweepline::config::Config;
use sweepline::daemon::resume::HEARTBEAT_FILE;
use sweepline::geom::{pose, Pose};
use sweepline::motor::BaseKind;
use sweepline::pipeline::checkpoint::{
    CheckpointStore, MountRecord, ResumeLog, RunFinished, RunProgress, WrittenAt,
};
use sweepline::plan::LatticePhase;
use sweepline::sim::closed_loop::{self, SimOptions, DEADMAN_WALL, SAMPLE_PERIOD};
use sweepline::sim::coverage_metrics::CoverageTracker;
use sweepline::sim::world::World;

/// The in-process e2e world: 3.2 m × 2.6 m with a box.
const SMALL: &str = "name e2e-small\nresolution 0.02\n\
room 0 0 3.2 0 3.2 2.6 0 2.6 refl 0.55\n\
box 1.8 1.0 2.3 1.5 refl 0.8\n\
start 0.5 0.5 0.0\n";

/// Simulated seconds per wall second.
const SPEED: f64 = 10.0;
/// Checkpoint period (simulated s: the daemon times it on its injected
/// clock): 0.1 s wall at [`SPEED`].
const CHECKPOINT_PERIOD: f64 = 1.0;
/// Heartbeat period (simulated s).
const HEARTBEAT_PERIOD: f64 = 0.2;
/// Supervision period (wall s: the supervisor's own tick, which the
/// watchdog counts in): one heartbeat period at [`SPEED`].
const SUPERVISE_WALL: f64 = HEARTBEAT_PERIOD / SPEED;
/// Ground-truth coverage at which the daemon is killed.
const KILL_AT: f64 = 0.40;
/// Set to run the same world without the kill: the uninterrupted baseline
/// the resumed run's time is compared with (`docs/checkpoints.md`, "Crash test").
const NO_KILL_ENV: &str = "SWEEPLINE_E2E_NO_KILL";
/// Coverage the whole run must reach (the in-process e2e test's bound).
const MIN_COVERAGE: f64 = 0.97;
/// How much older than its checkpoint a checkpointed pose may be (s
/// simulated): the control stage publishes the pose at every scan (0.1 s),
/// and the snapshot's wall stamp is read a moment before the pose.
const POSE_AGE: f64 = 0.3;
/// How much later than its checkpoint's stamp the pose may be (s
/// simulated): the stamp is read just before the pose.
const STAMP_SLACK: f64 = 0.1;
/// Scans the resumed daemon tracks before its pose is scored (1 s).
const SETTLE_SCANS: u64 = 10;
/// Largest median checkpointed pose error allowed after the resume (m):
/// the tracker's keyframes are restored, so the resumed daemon tracks in
/// the crashed one's frame (without them it was ~0.12 m off for the rest
/// of the run, a lasting offset the median shows). A single checkpoint
/// may be further off, as in any run (up to 56 mm seen, before a kill as
/// well as after), which the median does not let decide.
const MAX_RESUMED_MEDIAN_POSE_ERROR: f64 = 0.03;
/// Largest checkpointed pose error allowed at any time after the resume
/// (m): a jump to another frame shows here.
const MAX_RESUMED_POSE_ERROR: f64 = 0.10;
/// Simulated time after which the test gives up (s).
const TIME_CAP: f64 = 900.0;
/// How far ahead of its configured place (the axle centre) the emulated
/// scanner sits (m).
const SCANNER_AHEAD: f64 = 0.05;

fn config() -> Config {
    Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("hw/robot.toml")).unwrap()
}

fn unix_now() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// Kills the child on drop (a failed assertion leaves no daemon behind).
struct Daemon(Child);

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn spawn(dir: &Path, links: &Path, n: u32, sim_clock: &str) -> Daemon {
    let log = std::fs::File::create(dir.join(format!("daemon{n}.log"))).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_sweepline"))
        .arg("run")
        .arg("--config")
        .arg(dir.join("robot.toml"))
        .arg("--scanner")
        .arg(links.join("urg"))
        .arg("--base")
        .arg(links.join("base"))
        .arg("--state-dir")
        .arg(dir.join("state"))
        .arg("--sim-clock")
        .arg(sim_clock)
        .env("RUST_LOG", "info")
        .env_remove("NOTIFY_SOCKET")
        .env_remove("WATCHDOG_USEC")
        .stdout(Stdio::null())
        .stderr(log)
        .spawn()
        .unwrap();
    Daemon(child)
}

fn latest(store: &CheckpointStore) -> Option<RunProgress> {
    latest_with_pose(store).map(|(p, _, _)| p)
}

fn latest_with_pose(store: &CheckpointStore) -> Option<(RunProgress, Pose, WrittenAt)> {
    let l = store.load().ok()??;
    let p = l.checkpoint.get::<RunProgress>().ok()??;
    let q = l.checkpoint.get::<Pose>().ok()??;
    let w = l.checkpoint.get::<WrittenAt>().ok()??;
    Some((p, q, w))
}

/// Distance (m) from `est` to the true path near simulated time `t`: the
/// nearest of the true poses sampled between `t - POSE_AGE` and
/// `t + STAMP_SLACK`, and of the last one before and the first one after
/// that window (so a gap in the sampling widens the window rather than
/// leaving it empty).
fn error_at(truth: &[(f64, Pose)], t: f64, est: &Pose) -> f64 {
    let lo = truth.partition_point(|(s, _)| *s < t - POSE_AGE);
    let hi = truth.partition_point(|(s, _)| *s <= t + STAMP_SLACK);
    truth[lo.saturating_sub(1)..(hi + 1).min(truth.len())]
        .iter()
        .map(|(_, q)| (est.translation.vector - q.translation.vector).norm())
        .fold(f64::INFINITY, f64::min)
}

/// What the configuration says between the crash and the restart.
#[derive(Clone, Copy, PartialEq)]
enum Restart {
    /// The same file: the refitted mount of the checkpoint is driven with.
    SameConfig,
    /// `robot.scanner_offset_x` corrected to the true mount: it is driven
    /// with, not the checkpoint's.
    MountCorrected,
}

/// One closed loop at a time: two at once on 2 cores starve the ×10 clock.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn killed_daemon_resumes_its_coverage() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    crash_and_resume("e2e_resume", Restart::SameConfig);
}

#[test]
#[ignore = "slow tier: a whole simulated run; cargo test --release -- --ignored"]
fn a_mount_corrected_in_the_configuration_wins_over_the_checkpointed_one() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    crash_and_resume("e2e_resume_mount", Restart::MountCorrected);
}

fn crash_and_resume(name: &str, restart: Restart) {
    if restart == Restart::MountCorrected && std::env::var_os(NO_KILL_ENV).is_some() {
        eprintln!("{NO_KILL_ENV}: no restart, so no corrected mount to test");
        return;
    }
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("state")).unwrap();
    let links = dir.join("dev");

    let world = World::parse(SMALL).unwrap();
    let base_cfg = config();
    let robot = base_cfg.robot.clone();
    let mut tracker =
        CoverageTracker::new(&world, robot.radius, robot.tool_width, &world.start).unwrap();
    let mut opts = SimOptions::new(world.clone(), base_cfg.clone());
    let mount_truth = pose(SCANNER_AHEAD, 0.0, 0.0);
    opts.scanner_truth = Some((mount_truth, false));
    // The daemon's map frame starts at its scanner's configured place; the
    // scanner's true start is the world's start through the true mount.
    let map_to_world = world.start * mount_truth * base_cfg.robot.scanner_mount().inverse();

    // One time base for the emulators here and the daemon in the child.
    let epoch = unix_now();
    let clock: SharedClock = Arc::new(ScaledClock::since_unix(SPEED, epoch));
    let (base, urg) = closed_loop::spawn_emulators(&opts, &clock, &links).unwrap();

    let mut cfg = base_cfg;
    cfg.motor.kind = BaseKind::Roboclaw;
    cfg.motor.deadman = cfg.motor.deadman.max(DEADMAN_WALL * SPEED);
    let sim_clock = format!("{SPEED},{epoch}");
    cfg.pipeline.checkpoint_period = CHECKPOINT_PERIOD;
    cfg.pipeline.heartbeat_period = HEARTBEAT_PERIOD;
    cfg.pipeline.supervise_period = SUPERVISE_WALL;
    std::fs::write(dir.join("robot.toml"), toml::to_string(&cfg).unwrap()).unwrap();

    let store = CheckpointStore::new(&dir.join("state"));
    let wall0 = Instant::now();
    let t0 = clock.now();
    let mut daemon = spawn(&dir, &links, 1, &sim_clock);
    // (sequence, daemon coverage, ground-truth coverage when first seen)
    let mut last_seen: Option<(RunProgress, f64)> = None;
    let mut killed: Option<(f64, f64)> = None; // (truth coverage, sim time) at the kill
    let mut at_kill: Option<RunProgress> = None;
    let mut lattice_at_kill: Option<LatticePhase> = None;
    let mut mount_at_kill: Option<MountRecord> = None;
    let mut first_resumed: Option<(RunProgress, f64)> = None;
    let mut last_poll = Instant::now();
    // Largest distance between a checkpointed pose and the true path when
    // the checkpoint was taken (see `error_at`), before and after the kill:
    // how late the disk put it there does not count (a busy disk delays a
    // write by up to a second of wall time, ten simulated seconds here).
    let mut pose_err = [0.0f64; 2];
    // The checkpoint last scored.
    let mut scored: Option<u64> = None;
    // Every true pose sampled, with its simulated time.
    let mut truth_path: Vec<(f64, Pose)> = Vec::new();
    // Every error scored after the resume, for its median.
    let mut resumed_errs: Vec<f64> = Vec::new();
    // The same per 20 s of simulated time, for the output.
    let mut err_by_time: Vec<f64> = Vec::new();
    // Ground-truth coverage every 20 s simulated, for the output.
    let mut timeline = String::new();
    let mut next_mark = 0.0;
    let kill_at = if std::env::var_os(NO_KILL_ENV).is_some() {
        f64::INFINITY
    } else {
        KILL_AT
    };
    let mut last_truth;
    let status = loop {
        clock.sleep(SAMPLE_PERIOD);
        let t = clock.now() - t0;
        let truth_pose = base.truth();
        tracker.record(&truth_pose, t);
        last_truth = truth_pose;
        truth_path.push((t, truth_pose));
        let truth = tracker.metrics().coverage;
        if t >= next_mark {
            timeline += &format!(" {t:.0}s:{:.0}%", truth * 100.0);
            next_mark += 20.0;
        }
        if last_poll.elapsed() >= Duration::from_millis(50) {
            last_poll = Instant::now();
            if let Some((p, est, taken)) = latest_with_pose(&store) {
                // The daemon's frame is the world frame moved to the start.
                let est = map_to_world * est;
                // When the checkpoint was taken, on this test's clock (the
                // daemon's runs on the same epoch and speed).
                let t_taken = (taken.unix - epoch) * SPEED - t0;
                let e = error_at(&truth_path, t_taken, &est);
                let new = scored != Some(p.sequence);
                scored = Some(p.sequence);
                // After the restart, once the second daemon has tracked
                // SETTLE_SCANS scans: until its first scans are processed
                // (process start, device opening) its checkpoints still hold
                // the pose restored from the crashed one's.
                let k = usize::from(killed.is_some());
                let tracking = match (killed, at_kill) {
                    (None, _) => true,
                    (Some(_), Some(a)) => p.resumes >= 1 && p.scans >= a.scans + SETTLE_SCANS,
                    (Some(_), None) => false,
                };
                if tracking && new {
                    pose_err[k] = pose_err[k].max(e);
                    if k == 1 {
                        resumed_errs.push(e);
                    }
                    let bucket = (t / 20.0) as usize;
                    if err_by_time.len() <= bucket {
                        err_by_time.resize(bucket + 1, 0.0);
                    }
                    err_by_time[bucket] = err_by_time[bucket].max(e);
                }
                match killed {
                    None if last_seen.map(|(q, _)| q.sequence) != Some(p.sequence) => {
                        last_seen = Some((p, truth));
                    }
                    Some(_) if p.resumes >= 1 && first_resumed.is_none() => {
                        first_resumed = Some((p, truth));
                    }
                    _ => {}
                }
            }
        }
        if killed.is_none() && truth >= kill_at {
            // SIGKILL: no final checkpoint, no stop command.
            daemon.0.kill().unwrap();
            daemon.0.wait().unwrap();
            killed = Some((truth, t));
            timeline += &format!(" [kill -9 at {t:.0}s:{:.0}%]", truth * 100.0);
            // The crashed daemon kept its heartbeat (what the report's
            // "coverage at crash" comes from).
            assert!(
                dir.join("state").join(HEARTBEAT_FILE).exists(),
                "the first daemon wrote no heartbeat"
            );
            at_kill = latest(&store);
            lattice_at_kill = lattice(&store);
            mount_at_kill = mount(&store);
            std::thread::sleep(Duration::from_millis(200));
            if restart == Restart::MountCorrected {
                cfg.robot.scanner_offset_x = SCANNER_AHEAD;
                std::fs::write(dir.join("robot.toml"), toml::to_string(&cfg).unwrap()).unwrap();
            }
            daemon = spawn(&dir, &links, 2, &sim_clock);
            continue;
        }
        if let Some(s) = daemon.0.try_wait().unwrap() {
            break Some(s);
        }
        if t >= TIME_CAP {
            break None; // reported below, after the figures
        }
    };
    let sim_time = clock.now() - t0;
    drop(urg);
    let m = tracker.metrics();
    if kill_at.is_infinite() {
        eprintln!(
            "uninterrupted ({NO_KILL_ENV}): finished at {:.1} % true coverage, {sim_time:.0} s sim; \
             true coverage by simulated time:{timeline}",
            m.coverage * 100.0
        );
        let status = status.unwrap_or_else(|| panic!("no end after {TIME_CAP} s simulated"));
        assert!(status.success(), "daemon failed: {status}");
        assert!(m.coverage >= MIN_COVERAGE, "coverage {:.3}", m.coverage);
        return;
    }
    let log2 = std::fs::read_to_string(dir.join("daemon2.log")).unwrap_or_default();
    let (kill_truth, kill_t) = killed.expect("the daemon finished before it could be killed");
    let at_kill = at_kill.expect("no checkpoint before the kill");
    let (_seen, seen_truth) = last_seen.expect("no checkpoint seen");
    let (resumed, resumed_truth) = first_resumed.expect("the second daemon wrote no checkpoint");
    let final_progress = latest(&store).unwrap();
    eprintln!(
        "killed at {kill_t:.1} s sim with {:.1} % true coverage; last checkpoint #{} \
         (written ~{:.1} s before): {:.1} % by the daemon's record, {:.1} % true when seen -> \
         at most {:.1} points of true coverage to redo",
        kill_truth * 100.0,
        at_kill.sequence,
        kill_t - at_kill.elapsed.min(kill_t),
        at_kill.coverage * 100.0,
        seen_truth * 100.0,
        (kill_truth - seen_truth) * 100.0,
    );
    eprintln!(
        "resumed: first checkpoint #{} of the second daemon {:.1} % by its record \
         ({:.1} % true); finished at {:.1} % true coverage, {:.0} s sim in {:.1} s wall, \
         exit {status:?}, {} resume(s)",
        resumed.sequence,
        resumed.coverage * 100.0,
        resumed_truth * 100.0,
        m.coverage * 100.0,
        sim_time,
        wall0.elapsed().as_secs_f64(),
        final_progress.resumes
    );
    resumed_errs.sort_by(f64::total_cmp);
    let resumed_median = resumed_errs
        .get(resumed_errs.len() / 2)
        .copied()
        .unwrap_or(f64::INFINITY);
    eprintln!(
        "checkpointed pose vs truth: max {:.3} m before the kill, {:.3} m (median {:.3} m of {}) after the resumed daemon's first {SETTLE_SCANS} scans",
        pose_err[0],
        pose_err[1],
        resumed_median,
        resumed_errs.len()
    );
    let errs: String = err_by_time
        .iter()
        .enumerate()
        .map(|(i, e)| format!(" {}s:{:.0}mm", i * 20, e * 1e3))
        .collect();
    eprintln!("largest checkpointed pose error per 20 s of simulated time:{errs}");
    eprintln!(
        "true coverage by simulated time:{timeline} end {sim_time:.0}s:{:.0}%",
        m.coverage * 100.0
    );
    let status = status.unwrap_or_else(|| panic!("no end after {TIME_CAP} s simulated"));
    assert!(status.success(), "second daemon failed: {status}\n{log2}");
    assert!(
        log2.contains("resuming"),
        "second daemon did not resume:\n{log2}"
    );
    assert_eq!(final_progress.resumes, 1);
    assert!(final_progress.sequence > at_kill.sequence);
    assert!(
        resumed.coverage >= at_kill.coverage - 0.02,
        "coverage lost on restart: {:.3} checkpointed, {:.3} after resume",
        at_kill.coverage,
        resumed.coverage
    );
    assert!(m.coverage >= MIN_COVERAGE, "coverage {:.3}", m.coverage);
    assert_eq!(m.collisions, 0);
    // The start was checkpointed: the resumed daemon drove back to where
    // the first one started, by the truth.
    let from_start = (last_truth.translation.vector - world.start.translation.vector).norm();
    assert!(
        from_start <= sweepline::plan::planner::HOME_NEAR + 0.05,
        "ended {from_start:.3} m from the start\n{log2}"
    );
    assert!(log2.contains("back at the start"), "{log2}");
    // Its last checkpoint says the run finished: the next start is a new
    // run, not a resume with nothing left to do.
    let last = store.load().unwrap().unwrap().checkpoint;
    let fin = last.get::<RunFinished>().unwrap();
    assert!(fin.is_some_and(|f| f.elapsed > 0.0), "{fin:?}");
    assert!(
        resumed_median <= MAX_RESUMED_MEDIAN_POSE_ERROR,
        "median pose error after the resume {resumed_median:.3} m"
    );
    assert!(
        pose_err[1] <= MAX_RESUMED_POSE_ERROR,
        "pose error after the resume {:.3} m",
        pose_err[1]
    );
    // The resumed planner kept the lane lattice of the lanes driven before.
    let lattice_at_kill = lattice_at_kill.expect("no lane lattice checkpointed before the kill");
    assert_eq!(lattice(&store), Some(lattice_at_kill));
    // The first daemon refitted the scanner's mount before the kill, and
    // the second drove with it from its checkpoint.
    let m = mount_at_kill.expect("no refitted mount checkpointed before the kill");
    let ahead = m.refitted.translation.vector;
    assert!(
        (ahead.x - SCANNER_AHEAD).abs() <= 0.01 && ahead.y.abs() <= 0.01,
        "refitted mount {ahead:?}"
    );
    let (expected, other) = (
        "driving with the scanner mount refitted before the checkpoint",
        "the configured scanner mount changed since the checkpoint; driving with the configured one",
    );
    let (expected, other) = match restart {
        Restart::SameConfig => (expected, other),
        Restart::MountCorrected => (other, expected),
    };
    assert!(
        log2.contains(expected) && !log2.contains(other),
        "second daemon did not say {expected:?}:\n{log2}"
    );
    check_report(&dir.join("state/run"), &at_kill, kill_t);
    check_recordings(&dir.join("state/recordings"));
}

/// Each daemon recorded its part of the run (`[record]` is on by
/// default): the killed one's file reads up to the kill without a footer,
/// the resumed one's is closed; both hold scans and their setup.
fn check_recordings(dir: &Path) {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    files.sort();
    assert_eq!(files.len(), 2, "{files:?}");
    let killed = sweepline::live::Recording::read(&files[0]).unwrap();
    let resumed = sweepline::live::Recording::read(&files[1]).unwrap();
    assert!(!killed.complete && resumed.complete);
    for r in [&killed, &resumed] {
        assert!(r.scans.len() > 100, "{} scans", r.scans.len());
        assert!(r.setup.as_ref().is_some_and(|s| s.is_ok()));
    }
}

/// The refitted scanner mount of the newest checkpoint.
fn mount(store: &CheckpointStore) -> Option<MountRecord> {
    store.load().ok()??.checkpoint.get::<MountRecord>().ok()?
}

/// The lane lattice phase of the newest checkpoint.
fn lattice(store: &CheckpointStore) -> Option<LatticePhase> {
    store.load().ok()??.checkpoint.get::<LatticePhase>().ok()?
}

/// The resumed run's report says what the crash lost, consistently with the
/// checkpoint this test saw last before the kill at `kill_t` (run clock).
fn check_report(run: &Path, at_kill: &RunProgress, kill_t: f64) {
    let md = std::fs::read_to_string(run.join("report.md")).expect("no report.md");
    let section = &md[md
        .find("## Checkpoint and resume")
        .expect("no resume section")..];
    eprintln!("{section}");
    let log = ResumeLog::read(run).unwrap().expect("no resume.toml");
    assert_eq!(log.resume.len(), 1, "{log:?}");
    let e = &log.resume[0];
    assert_eq!(e.restart, 1);
    assert_eq!(e.checkpoint.sequence, at_kill.sequence);
    assert_eq!(e.checkpoint.coverage, at_kill.coverage);
    assert!(e.checkpoint.unix.is_some(), "checkpoint without wall time");
    let Some(alive) = e.last_alive else {
        // No heartbeat between the last checkpoint and the kill: both are
        // timed, and a starved daemon (seen in 3 of 15 runs beside two
        // busy loops and other simulations on 2 cores) can write none in
        // that gap. Then the report must not guess.
        eprintln!("no heartbeat after the last checkpoint: the report says unknown");
        assert!(
            section.contains("- coverage at crash: unknown"),
            "report guesses without a heartbeat:\n{section}"
        );
        return;
    };
    let age = e.checkpoint_age().unwrap();
    let lost = e.coverage_lost().unwrap();
    // The last heartbeat lies between the checkpoint and the kill.
    assert!(alive.elapsed >= at_kill.elapsed && alive.elapsed <= kill_t + 1e-6);
    assert!(age <= kill_t - at_kill.elapsed + 1e-6, "age {age:.2} s");
    assert!((0.0..=0.05).contains(&lost), "lost {lost:.3}");
    assert!(alive.scans >= at_kill.scans);
    for line in [
        "Restarts: **1**".to_string(),
        format!(
            "- checkpoint: #{}, written at {}, run clock {:.1} s",
            at_kill.sequence,
            sweepline::report::resume::utc(e.checkpoint.unix.unwrap()),
            at_kill.elapsed
        ),
        format!(
            "- coverage at checkpoint: {:.1} %",
            at_kill.coverage * 100.0
        ),
        format!("- coverage at crash: {:.1} %", alive.coverage * 100.0),
        format!("- checkpoint age at crash: {age:.1} s run clock"),
        format!(
            "- progress lost: **{:.1} points of coverage**",
            lost * 100.0
        ),
    ] {
        assert!(section.contains(&line), "report lacks {line:?}:\n{section}");
    }
}
