//! The binary end to end: `sweepline emulate urg --link …` in its own
//! process, `sweepline probe --port …` against it, then SIGINT stops the
//! emulator cleanly with its summary.

mod urg_support;

use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[test]
fn emulate_then_probe_with_the_binary() {
    let exe = env!("CARGO_BIN_EXE_sweepline");
    let dir = urg_support::temp_dir("cli");
    let link = dir.join("urg");
    let mut emu = Command::new(exe)
        .args(["emulate", "urg", "--link"])
        .arg(&link)
        .args(["--faults", "checksum=50"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !link.exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "emulator did not start"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let svg = dir.join("scan.svg");
    let probe = Command::new(exe)
        .args(["probe", "--scanner"])
        .arg(&link)
        .arg("--svg")
        .arg(&svg)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&probe.stdout);
    assert!(probe.status.success(), "{text}");
    assert!(
        text.contains("product    SOKUIKI Sensor URG-04LX"),
        "{text}"
    );
    assert!(
        text.contains("beams      ") && text.contains(" invalid of 682"),
        "{text}"
    );
    assert!(std::fs::read_to_string(&svg).unwrap().contains("<svg"));
    // A missing device: one clear line and a non-zero exit.
    let bad = Command::new(exe)
        .args(["probe", "--port", "/dev/does-not-exist-urg"])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.starts_with("sweepline: error: ") && err.contains("/dev/does-not-exist-urg"),
        "{err}"
    );
    // SAFETY: signalling the child we started.
    unsafe {
        libc::kill(emu.id() as libc::pid_t, libc::SIGINT);
    }
    let status = emu.wait().unwrap();
    let mut out = String::new();
    emu.stdout.take().unwrap().read_to_string(&mut out).unwrap();
    assert!(status.success(), "{out}");
    assert!(
        out.contains("SOKUIKI Sensor URG-04LX emulated (100 ms scans) at /dev/pts/"),
        "{out}"
    );
    assert!(out.contains("stopped: 1 scans sent"), "{out}");
    assert!(!link.exists(), "the symlink is removed on exit");
    let _ = std::fs::remove_dir_all(&dir);
}
