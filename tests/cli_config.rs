//! The binary's configuration and command-line rules, each tried as a user
//! would: the config's device keys are honoured unless a flag is given, the
//! config is found where systemd puts it, `--check-config` refuses what
//! `run` refuses, negative numbers are numbers, a floor plan may be named by
//! its file, and `--help` names RUST_LOG and the exit codes.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn sweepline() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_sweepline"));
    c.env_remove("CONFIGURATION_DIRECTORY")
        .env_remove("STATE_DIRECTORY")
        .env_remove("NOTIFY_SOCKET");
    c
}

fn temp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sweepline-cli-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn shipped() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/hw/robot.toml")).unwrap()
}

/// The shipped config with `key = value` put into `[table]`.
fn with(table: &str, key: &str, value: &str) -> String {
    let text = shipped();
    let header = format!("[{table}]\n");
    let at = text.find(&header).expect("table in robot.toml") + header.len();
    let end = text[at..].find("\n[").map_or(text.len(), |e| at + e + 1);
    let body: Vec<&str> = text[at..end]
        .lines()
        .filter(|l| !l.trim_start().starts_with(&format!("{key} =")))
        .collect();
    format!(
        "{}{key} = {value}\n{}\n{}",
        &text[..at],
        body.join("\n"),
        &text[end..]
    )
}

fn err(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn write(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("robot.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn check_config_refuses_what_run_refuses() {
    let d = temp("overlap");
    // A lane overlap as wide as the tool: every table parses, but no
    // planner can be built from it.
    let cfg = write(&d, &with("plan", "lane_overlap", "0.5"));
    let out = sweepline()
        .args(["run", "--check-config", "--config"])
        .arg(&cfg)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(err(&out).contains("plan.lane_overlap"), "{}", err(&out));
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn the_configs_device_keys_are_used_unless_a_flag_is_given() {
    let d = temp("devices");
    let text = with(
        "scanner",
        "port",
        &format!("\"{}\"", d.join("cfg-urg").display()),
    );
    let cfg = write(&d, &text);
    let run = |extra: &[&str]| {
        sweepline()
            .args(["run", "--config"])
            .arg(&cfg)
            .arg("--state-dir")
            .arg(d.join("state"))
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&[]);
    assert!(err(&out).contains("cfg-urg"), "{}", err(&out));
    let flag = d.join("flag-urg");
    let out = run(&["--scanner", flag.to_str().unwrap()]);
    assert!(
        err(&out).contains("flag-urg") && !err(&out).contains("cfg-urg"),
        "{}",
        err(&out)
    );
    let out = sweepline()
        .args(["run", "--check-config", "--config"])
        .arg(&cfg)
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("cfg-urg") && said.contains("/dev/sweepline-base"),
        "{said}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn the_config_is_found_in_systemds_configuration_directory() {
    let d = temp("confdir");
    write(&d, "[robot]\nradius = -1\n");
    let out = sweepline()
        .args(["run", "--check-config"])
        .env("CONFIGURATION_DIRECTORY", &d)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let e = err(&out);
    assert!(e.contains("robot.radius"), "{e}");
    // Without it: /etc/sweepline/robot.toml, named when missing.
    let out = sweepline()
        .args(["run", "--check-config"])
        .output()
        .unwrap();
    if !Path::new("/etc/sweepline/robot.toml").exists() {
        assert!(
            err(&out).contains("/etc/sweepline/robot.toml"),
            "{}",
            err(&out)
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn negative_numbers_are_numbers() {
    // Parsed as a value (then refused by the emulator's own check, which
    // names it), not taken for an unknown option.
    let out = sweepline()
        .args(["emulate", "urg", "--drift-ppm", "-50", "--rate", "-1"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(
        err(&out).contains("--rate must be a positive number"),
        "{}",
        err(&out)
    );
}

#[test]
fn a_floor_plan_may_be_named_by_its_file_and_an_unknown_one_lists_the_plans() {
    let dir = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/maps/ipa_coverage_planning_test_maps"
    ));
    if !dir.is_dir() {
        assert!(
            std::env::var("CI").is_err(),
            "CI=true but the shared floor plans are missing: {}",
            dir.display()
        );
        println!("skipped: shared floor plans not found at {}", dir.display());
        return;
    }
    let list = |name: &str| {
        sweepline()
            .args(["coverage", "--list-rooms", name, "--maps"])
            .arg(dir)
            .output()
            .unwrap()
    };
    let base = list("lab_c_scan");
    assert!(base.status.success(), "{}", err(&base));
    let file = list("lab_c_scan_furnitures");
    assert!(file.status.success(), "{}", err(&file));
    assert_eq!(base.stdout, file.stdout);
    let none = list("no_such_plan");
    assert_eq!(none.status.code(), Some(1));
    assert!(
        err(&none).contains("no floor plan `no_such_plan`") && err(&none).contains("lab_c_scan"),
        "{}",
        err(&none)
    );
}

#[test]
fn help_names_rust_log_and_the_exit_codes() {
    let out = sweepline().arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(help.contains("RUST_LOG"), "{help}");
    assert!(
        help.contains("Exit codes") && help.contains("--time-cap"),
        "{help}"
    );
}

#[test]
fn reaching_the_time_cap_is_its_own_exit_code() {
    let d = temp("cap");
    let out = sweepline()
        .args(["sim", "--time-cap", "2", "--speed", "2", "--out"])
        .arg(d.join("out"))
        .env("RUST_LOG", "error")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "{}", err(&out));
    assert!(err(&out).contains("time cap"), "{}", err(&out));
    assert!(d.join("out/summary.md").is_file(), "the report is written");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn under_the_journal_lines_carry_their_priority_and_no_timestamp() {
    let d = temp("journal");
    let run = |journal: bool| {
        let mut c = sweepline();
        c.args(["run", "--fresh", "--config"])
            .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/hw/robot.toml"))
            .arg("--scanner")
            .arg(d.join("no-urg"))
            .arg("--state-dir")
            .arg(d.join("state"))
            .env("RUST_LOG", "info")
            .env_remove("JOURNAL_STREAM");
        if journal {
            c.env("JOURNAL_STREAM", "8:12345");
        }
        err(&c.output().unwrap())
    };
    let plain = run(false);
    let line = plain
        .lines()
        .find(|l| l.contains("--fresh: a new run"))
        .unwrap_or_else(|| panic!("{plain}"));
    assert!(line.starts_with("[20"), "a timestamp first: {line}");
    let journal = run(true);
    let line = journal
        .lines()
        .find(|l| l.contains("--fresh: a new run"))
        .unwrap_or_else(|| panic!("{journal}"));
    assert!(line.starts_with("<6>sweepline::cli::run: "), "{line}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_wrong_choice_lists_the_possible_values_and_exits_2() {
    for args in [
        &["sim", "--base", "roomba2"][..],
        &["emulate", "motor"][..],
        &["emulate", "urg", "--model", "lms100"][..],
    ] {
        let out = sweepline().args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {out:?}");
        let e = err(&out);
        assert!(e.contains("possible values"), "{args:?}: {e}");
    }
}

/// The simulator's clock is not the robot's configuration: a config file
/// that sets it is refused naming the key, and the run flag that replaces
/// it checks its values.
#[test]
fn the_simulated_clock_is_a_flag_not_a_config_key() {
    let d = temp("simclock");
    let cfg = write(&d, &with("pipeline", "time_scale", "5.0"));
    let o = sweepline()
        .args(["run", "--check-config", "--config"])
        .arg(&cfg)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", err(&o));
    assert!(err(&o).contains("time_scale"), "{}", err(&o));
    for bad in ["0,0", "5", "2000,0", "5,-1", "x,1"] {
        let o = sweepline()
            .args(["run", "--check-config", "--config"])
            .arg(write(&d, &shipped()))
            .args(["--sim-clock", bad])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "--sim-clock {bad}: {}", err(&o));
        assert!(err(&o).contains("SCALE,EPOCH"), "{}", err(&o));
    }
    let o = sweepline()
        .args(["run", "--check-config", "--config"])
        .arg(write(&d, &shipped()))
        .args(["--sim-clock", "10,1700000000"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", err(&o));
    let _ = std::fs::remove_dir_all(&d);
}
