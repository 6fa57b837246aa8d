//! `sweepline run` as a process: configuration errors name the key, missing
//! devices are named with the fix, `--check-config` validates only.

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
    let out = sweepline()
        .args(["run", "--config"])
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/hw/robot.toml"))
        .arg("--scanner")
        .arg(d.join("no-urg"))
        .arg("--state-dir")
        .arg(d.join("state"))
        .env_remove("NOTIFY_SOCKET")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
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
