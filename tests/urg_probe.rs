//! `sweepline probe`'s function against the emulated URG-04LX on a real pty:
//! identity, scan summary with the error codes spelled out, health counters.

mod urg_support;

use std::path::Path;
use std::sync::Arc;

use sweepline::cli::probe::probe;
use sweepline::sim::urg_emu::{Emulator, EmulatorConfig, RectRoom, ReplayScan, Scene};
use sweepline::urg::{MonotonicClock, UrgParams};

fn probe_scene(name: &str, scene: Box<dyn Scene>) -> String {
    let dir = urg_support::temp_dir(name);
    let link = dir.join("urg");
    let clock = Arc::new(MonotonicClock::new());
    let cfg = EmulatorConfig {
        link: Some(link.clone()),
        ..EmulatorConfig::default()
    };
    let emu = Emulator::spawn(cfg, scene, clock.clone()).unwrap();
    let text = probe(&link, &UrgParams::default(), clock).unwrap();
    let log = emu.log();
    drop(emu);
    let _ = std::fs::remove_dir_all(&dir);
    // Identity asked once, one finite MD, shutdown QT.
    let cmds: Vec<&str> = log.commands.iter().map(String::as_str).collect();
    assert_eq!(cmds.iter().filter(|c| **c == "VV").count(), 1, "{cmds:?}");
    assert_eq!(cmds.iter().filter(|c| **c == "II").count(), 1, "{cmds:?}");
    assert!(cmds.contains(&"MD0044072501001"), "{cmds:?}");
    assert_eq!(*cmds.last().unwrap(), "QT");
    text
}

fn field<'a>(text: &'a str, key: &str) -> &'a str {
    text.lines()
        .find_map(|l| l.trim_start().strip_prefix(key))
        .unwrap_or_else(|| panic!("no `{key}` in:\n{text}"))
        .trim()
}

#[test]
fn probe_summarises_the_bench_room() {
    let text = probe_scene("probe-room", Box::new(RectRoom::bench(5)));
    assert_eq!(field(&text, "product"), "SOKUIKI Sensor URG-04LX");
    assert_eq!(field(&text, "firmware"), "3.1.04(02/Aug./2007)");
    assert_eq!(field(&text, "serial"), "H0706400");
    assert_eq!(
        field(&text, "steps"),
        "44 .. 725 (front 384), 1024 per turn: 682 beams over 239.4 deg"
    );
    assert_eq!(field(&text, "status"), "Sensor works well.");
    let front: f64 = field(&text, "front")
        .trim_end_matches(" mm")
        .parse()
        .unwrap();
    assert!((front - 2500.0).abs() < 30.0, "{front}");
    // The room's doorway and black panel give error codes, as a real
    // office does: about one step in eight.
    let beams = field(&text, "beams");
    let invalid: usize = beams
        .split(", ")
        .nth(1)
        .and_then(|s| s.strip_suffix(" invalid of 682"))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{beams}"));
    assert!((60..=120).contains(&invalid), "{beams}");
    assert!(
        text.contains("x code 0        possibly an object at 22 m"),
        "{text}"
    );
    assert_eq!(field(&text, "scans delivered"), "1");
    assert_eq!(field(&text, "checksum errors"), "0");
    assert_eq!(field(&text, "last bad status"), "none");
}

#[test]
fn probe_spells_out_the_error_codes_of_the_real_scan() {
    let logr = sweepline::require_shared!("datasets/hokuyo-captures/example_urg_04lx.logr");
    let text = probe_scene(
        "probe-replay",
        Box::new(ReplayScan::from_capture_file(&logr).unwrap()),
    );
    assert_eq!(field(&text, "front"), "4152 mm");
    assert_eq!(field(&text, "beams"), "581 valid, 101 invalid of 682");
    assert!(
        text.contains("x code 0        possibly an object at 22 m"),
        "{text}"
    );
}

#[test]
fn probe_of_a_missing_device_says_why() {
    let e = probe(
        Path::new("/dev/does-not-exist-urg"),
        &UrgParams::default(),
        Arc::new(MonotonicClock::new()),
    )
    .unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("/dev/does-not-exist-urg"), "{msg}");
}

#[test]
fn probe_of_a_silent_device_says_it_did_not_answer() {
    // A pty nobody answers on: the device exists but says nothing.
    let pty = sweepline::serial::Pty::open().unwrap();
    let params = UrgParams {
        reply_timeout: 0.02,
        reboot_wait: 0.1,
        ..UrgParams::default()
    };
    let t0 = std::time::Instant::now();
    let e = probe(pty.slave_path(), &params, Arc::new(MonotonicClock::new())).unwrap_err();
    assert!(e.to_string().contains("no reply to QT"), "{e}");
    assert!(t0.elapsed().as_secs_f64() < 3.0);
}
