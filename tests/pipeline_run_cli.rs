//! `sweepline run` as a process: configuration errors name the key, missing
//! devices are named with the fix, `--check-config` validates only, a
//! finished run is not resumed and `--fresh` starts a new one, and a new
//! run keeps the last run's folder as `run.prev`.

use std::process::Command;

fn sweepline() -> Command {
    Command::new(env!("CARGO_BIN_EXE_sweepline"))
}

fn temp(tag: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("sweepline-run-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn check_config_accepts_the_shipped_file() {
    let out = sweepline()
        .args(["run", "--check-config", "--config"])
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/hw/robot.toml"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("configuration is valid"));
}

#[test]
fn a_bad_value_is_named_and_fails() {
    let d = temp("badcfg");
    let cfg = d.join("robot.toml");
    std::fs::write(&cfg, "[pipeline.budget]\nlocalise = -2\n").unwrap();
    let out = sweepline()
        .args(["run", "--config"])
        .arg(&cfg)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("pipeline.budget.localise"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn missing_devices_are_named_with_the_fix() {
    let d = temp("nodev");
    let err = run_log(&d, &d.join("state"), &[]);
    assert!(
        err.contains("scanner device") && err.contains("no-urg"),
        "{err}"
    );
    assert!(err.contains("99-sweepline.rules"), "{err}");
    assert!(d.join("state").is_dir(), "state folder created");
    // A regular file is not a serial device.
    let f = d.join("plain");
    std::fs::write(&f, b"").unwrap();
    let out = sweepline()
        .args(["run", "--config"])
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/hw/robot.toml"))
        .arg("--scanner")
        .arg(&f)
        .arg("--state-dir")
        .arg(d.join("state"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not a character device"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// The log of `sweepline run` on the state folder `state` (no devices: it
/// stops at the device check, after deciding whether to resume), with
/// `extra` arguments.
fn run_log(d: &std::path::Path, state: &std::path::Path, extra: &[&str]) -> String {
    let out = sweepline()
        .args(["run", "--config"])
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/hw/robot.toml"))
        .arg("--scanner")
        .arg(d.join("no-urg"))
        .arg("--state-dir")
        .arg(state)
        .args(extra)
        .env_remove("NOTIFY_SOCKET")
        .env("RUST_LOG", "info")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn a_finished_run_is_not_resumed_and_fresh_starts_a_new_one() {
    use sweepline::grid::Grid;
    use sweepline::pipeline::checkpoint::{Checkpoint, CheckpointStore, RunFinished, RunProgress};
    let d = temp("finished");
    let state = d.join("state");
    std::fs::create_dir_all(&state).unwrap();
    let store = CheckpointStore::new(&state);
    let mut cp = Checkpoint::new();
    let progress = RunProgress {
        sequence: 40,
        elapsed: 80.0,
        coverage: 0.4,
        ..RunProgress::default()
    };
    cp.put(&progress).unwrap();
    cp.put(&sweepline::geom::pose(1.0, 1.0, 0.0)).unwrap();
    cp.put(&Grid::new(nalgebra::Point2::new(0.0, 0.0), 0.05, 20, 20))
        .unwrap();
    // Stopped before it finished: resumed, unless --fresh.
    store.save(&cp).unwrap();
    let log = run_log(&d, &state, &[]);
    assert!(log.contains("resuming"), "{log}");
    let log = run_log(&d, &state, &["--fresh"]);
    assert!(
        log.contains("--fresh: a new run") && !log.contains("resuming"),
        "{log}"
    );
    // Finished: the next start is a new run, and the last run's reports
    // are kept as run.prev (replacing the run before).
    let run = state.join("run");
    std::fs::create_dir_all(&run).unwrap();
    std::fs::write(run.join("summary.md"), "the last run").unwrap();
    std::fs::create_dir_all(state.join("run.prev")).unwrap();
    std::fs::write(state.join("run.prev/summary.md"), "the run before").unwrap();
    cp.put(&RunFinished { elapsed: 700.0 }).unwrap();
    store.save(&cp).unwrap();
    let log = run_log(&d, &state, &[]);
    assert!(
        log.contains("the last run finished its coverage after 700 s: starting a new run")
            && !log.contains("resuming"),
        "{log}"
    );
    assert!(log.contains("the last run's reports are kept in"), "{log}");
    let kept = std::fs::read_to_string(state.join("run.prev/summary.md")).unwrap();
    assert_eq!(kept, "the last run");
    assert!(!run.exists());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_last_run_folder_that_cannot_be_kept_is_logged_and_the_run_goes_on() {
    let d = temp("keepfail");
    let state = d.join("state");
    let run = state.join("run");
    std::fs::create_dir_all(&run).unwrap();
    std::fs::write(run.join("summary.md"), "the last run").unwrap();
    // Something that is not a folder stands where run.prev would go.
    std::fs::write(state.join("run.prev"), "not a folder").unwrap();
    let log = run_log(&d, &state, &["--fresh"]);
    assert!(
        log.contains("cannot keep the last run's reports as") && log.contains("overwritten"),
        "{log}"
    );
    // Nothing was lost on the way: the last run's folder is where it was,
    // and the start went on to the device check.
    assert_eq!(
        std::fs::read_to_string(run.join("summary.md")).unwrap(),
        "the last run"
    );
    assert!(log.contains("scanner device"), "{log}");
    std::fs::remove_dir_all(&d).unwrap();
}
