//! Time and intensity through the real driver over a pty: host stamps match
//! when the emulator measured each scan (TM sync), sensor clock drift is
//! estimated across periodic re-syncs, and the experimental URG-04LX FF
//! intensity mode and the UTM-30LX ME mode deliver intensities.

mod urg_support;

use std::f64::consts::FRAC_PI_2;

use sweepline::scan::Beam;
use sweepline::sim::urg_emu::{EmulatorConfig, Model};
use urg_support::*;

fn nearest(beams: &[Beam], angle: f64) -> Beam {
    *beams
        .iter()
        .min_by(|a, b| (a.angle - angle).abs().total_cmp(&(b.angle - angle).abs()))
        .unwrap()
}

#[test]
fn host_stamps_match_the_measurement_time() {
    // Real time over the pty: round trips are real, so allow a few ms.
    let rig = rig_cfg("stamps", EmulatorConfig::default(), 2.0, test_params());
    let got = rig.collect(20, 10.0);
    let log = rig.finish();
    check_no_loss(&log, &got);
    for g in &got {
        let sent = log.sent.iter().find(|s| s.stamp == g.raw_stamp).unwrap();
        let err = g.scan.stamp - sent.at;
        assert!(err.abs() < 0.005, "stamp off by {:.2} ms", err * 1e3);
    }
}

/// Lock-step (no pty, no thread): the session over the in-process link on a
/// manual clock, so round trips are exact and only the 1 ms tick limits the
/// estimate.
#[test]
fn drift_is_estimated_across_resyncs() {
    use std::sync::atomic::AtomicBool;
    use std::sync::{Arc, Mutex};
    use sweepline::sim::urg_emu::{EmuLog, Faults, ModelSpec, RectRoom, Sensor, SensorLink};
    use sweepline::urg::{ManualClock, UrgHealth, UrgParams, UrgSession};

    let clock = Arc::new(ManualClock::new(0.0));
    let log = Arc::new(Mutex::new(EmuLog::default()));
    let mut sensor = Sensor::new(
        ModelSpec::of(Model::Urg04lx),
        Faults::default(),
        false,
        Box::new(RectRoom::bench(1)),
        1,
        log.clone(),
        0.0,
    );
    sensor.set_drift_ppm(400.0);
    let stamps = Arc::new(Mutex::new(Vec::new()));
    let st = stamps.clone();
    let health = Arc::new(UrgHealth::default());
    let mut session = UrgSession::open(
        Box::new(SensorLink::new(sensor, clock.clone())),
        UrgParams::default(),
        clock.clone(),
        health.clone(),
        Arc::new(AtomicBool::new(false)),
        None,
        Box::new(move |s: &sweepline::urg::UrgScan| {
            st.lock().unwrap().push((s.raw_stamp, s.scan.stamp))
        }),
    )
    .unwrap();
    session.start_stream().unwrap();
    for i in 1..=600 {
        session.next_scan().unwrap();
        if i % 50 == 0 {
            session.resync().unwrap();
        }
    }
    let h = health.snapshot();
    assert!(
        (h.clock_drift_ppm - 400.0).abs() < 60.0,
        "drift estimate {:.0} ppm",
        h.clock_drift_ppm
    );
    // Late in the run every stamp is within a tick of the measurement time.
    let log = log.lock().unwrap();
    let stamps = stamps.lock().unwrap();
    for (raw, stamp) in stamps.iter().skip(500) {
        let sent = log.sent.iter().find(|s| s.stamp == *raw).unwrap();
        assert!(
            (stamp - sent.at).abs() < 0.0015,
            "{:.2} ms",
            (stamp - sent.at) * 1e3
        );
    }
}

#[test]
fn urg_ff_intensity_mode_delivers_intensities() {
    let mut p = test_params();
    p.intensity = true;
    let rig = rig("ff", "", false, p);
    let got = rig.collect(5, 10.0);
    let log = rig.finish();
    assert_eq!(got.len(), 5);
    assert!(
        log.commands.iter().any(|c| c == "MD00440725FF000"),
        "{:?}",
        log.commands
    );
    assert!(!log.commands.iter().any(|c| c.starts_with("ME")));
    let b = &got[4].scan.beams;
    assert_eq!(b.len(), 682);
    // Both steps of a pair carry the pair's distance and intensity.
    assert_eq!(b[0].range, b[1].range);
    assert_eq!(b[0].intensity, b[1].intensity);
    // Front wall: reflectivity 0.8 at 2.5 m; left wall 0.5 at 1.8 m, both
    // head-on; the emulator reports 5305 · ρ · r^-0.18 (its intensity
    // model, fitted to a real UTM-30LX scan: docs/scanner.md#intensities).
    let model = |rho: f64, r: f64| 2918.0 / 0.55 * rho * r.powf(-0.18);
    let front = nearest(b, 0.0);
    let left = nearest(b, FRAC_PI_2);
    assert!(
        (front.intensity - model(0.8, 2.5)).abs() < 60.0,
        "{front:?}"
    );
    assert!((left.intensity - model(0.5, 1.8)).abs() < 60.0, "{left:?}");
}

#[test]
fn utm_me_mode_delivers_1081_beams_with_intensity() {
    let cfg = EmulatorConfig {
        model: Model::Utm30lx,
        ..EmulatorConfig::default()
    };
    let mut p = test_params();
    p.intensity = true;
    let rig = rig_cfg("utm", cfg, RATE, p);
    let got = rig.collect(20, 10.0);
    let log = rig.finish();
    assert_eq!(got.len(), 20);
    assert!(
        log.commands.iter().any(|c| c == "ME0000108001000"),
        "{:?}",
        log.commands
    );
    check_no_loss(&log, &got);
    let s = &got[10];
    assert_eq!(s.scan.beams.len(), 1081);
    let front = nearest(&s.scan.beams, 0.0);
    assert!(
        (front.range - 2.5).abs() < 0.03 && front.intensity > 3000.0,
        "{front:?}"
    );
    // 40 Hz: 25 ms between scans; a revolution the emulator could not send
    // in time (a loaded machine) shows as a gap the driver reports.
    for w in got.windows(2) {
        let d = w[1].sensor_ms - w[0].sensor_ms;
        assert_eq!(d % 25, 0, "{d}");
        assert_eq!(w[1].dropped_before, d / 25 - 1);
    }
}

#[test]
fn cluster_and_skip_from_the_settings() {
    let mut p = test_params();
    p.cluster = 3;
    p.skip = 1;
    let rig = rig("cluster", "", false, p);
    let got = rig.collect(10, 10.0);
    let h = rig.driver().health().snapshot();
    let log = rig.finish();
    assert_eq!(got.len(), 10);
    assert!(
        log.commands.iter().any(|c| c == "MD0044072503100"),
        "{:?}",
        log.commands
    );
    check_no_loss(&log, &got);
    // 682 steps in groups of 3: 228 beams, each at its group's centre.
    let s = &got[5];
    assert_eq!(s.scan.beams.len(), 228);
    let step = std::f64::consts::TAU / 1024.0;
    assert!((s.scan.beams[0].angle - (45.0 - 384.0) * step).abs() < 1e-9);
    // One scan in two: 200 ms apart, and that is not counted as dropped
    // (a longer gap only if the emulator fell behind on a loaded machine).
    let mut gaps = 0;
    for w in got.windows(2) {
        let d = w[1].sensor_ms - w[0].sensor_ms;
        assert_eq!(d % 200, 0, "{d}");
        gaps += d / 200 - 1;
    }
    assert_eq!(h.dropped_scans, gaps);
}
