//! The driver against the emulated URG-04LX over a real pty, clean link:
//! open, identity, clock sync, streaming, stamps, clean shutdown.

mod urg_support;

use std::f64::consts::FRAC_PI_2;

use urg_support::*;

#[test]
fn clean_session_streams_every_scan_once() {
    let rig = rig("clean", "", false, test_params());
    let got = rig.collect(30, 10.0);
    assert_eq!(got.len(), 30, "scans delivered");
    let info = rig.driver().info().expect("sensor identified");
    assert_eq!(info.params.amin, 44);
    assert_eq!(info.params.amax, 725);
    assert_eq!(info.version.serial, "H0706400");
    assert_eq!(info.info.as_ref().unwrap().state, "Sensor works well.");
    let health = rig.driver().health().snapshot();
    // Every scan: 682 beams, front wall of the bench room at 2.5 m.
    for s in &got {
        assert_eq!(s.scan.beams.len(), 682);
        assert_eq!(s.readings.len(), 682);
        let front = s
            .scan
            .beams
            .iter()
            .min_by(|a, b| a.angle.abs().total_cmp(&b.angle.abs()))
            .unwrap();
        assert!(front.valid && (front.range - 2.5).abs() < 0.03, "{front:?}");
        let left = s
            .scan
            .beams
            .iter()
            .min_by(|a, b| {
                (a.angle - FRAC_PI_2)
                    .abs()
                    .total_cmp(&(b.angle - FRAC_PI_2).abs())
            })
            .unwrap();
        assert!((left.range - 1.8).abs() < 0.03, "{left:?}");
    }
    // Stamps: strictly increasing, 0.1 s apart on the (scaled) host clock,
    // and close to when the scan was measured.
    for w in got.windows(2) {
        let dt = w[1].scan.stamp - w[0].scan.stamp;
        let dms = w[1].sensor_ms - w[0].sensor_ms;
        assert_eq!(w[1].scan.seq, w[0].scan.seq + 1);
        assert!(
            (dt - dms as f64 / 1000.0).abs() < 0.003,
            "dt {dt} vs sensor {dms} ms"
        );
    }
    let log = rig.finish();
    let (n, corrupted) = check_no_loss(&log, &got);
    assert_eq!((n, corrupted), (30, 0));
    assert_eq!(health.checksum_errors, 0);
    assert_eq!(health.discarded_scans, 0);
    assert_eq!(health.reconnects, 0);
    let upto = log
        .sent
        .iter()
        .find(|s| s.stamp == got.last().unwrap().raw_stamp)
        .unwrap()
        .index;
    assert_eq!(health.dropped_scans, sent_gaps(&log, 100, upto));
    // The open sequence: LF, QT, PP, VV, II once, TM sync, MD; shutdown QT.
    let cmds: Vec<&str> = log.commands.iter().map(String::as_str).collect();
    assert_eq!(&cmds[..4], &["QT", "PP", "VV", "II"]);
    assert_eq!(cmds.iter().filter(|c| **c == "II").count(), 1);
    assert_eq!(cmds.iter().filter(|c| **c == "VV").count(), 1);
    assert!(cmds.contains(&"TM0") && cmds.contains(&"TM2"));
    assert!(cmds.contains(&"MD0044072501000"));
    assert!(
        !cmds.iter().any(|c| c.starts_with("ME")),
        "ME must never be sent to a URG-04LX"
    );
    assert_eq!(*cmds.last().unwrap(), "QT", "clean shutdown sends QT");
}

#[test]
fn bad_settings_are_refused_before_anything_starts() {
    use std::sync::Arc;
    use sweepline::serial::DeviceConnector;
    use sweepline::urg::{MonotonicClock, UrgDriver, UrgParams};
    let p = UrgParams {
        cluster: 0,
        ..UrgParams::default()
    };
    let e = UrgDriver::start(
        Box::new(DeviceConnector::new("/dev/null-urg")),
        p,
        Arc::new(MonotonicClock::new()),
    )
    .err()
    .unwrap();
    assert!(e.to_string().contains("scanner.cluster"), "{e}");
}

#[test]
fn a_missing_device_is_waited_for_then_streamed() {
    use std::sync::Arc;
    use sweepline::serial::DeviceConnector;
    use sweepline::sim::urg_emu::{Emulator, EmulatorConfig, RectRoom};
    use sweepline::urg::{ScaledClock, UrgDriver};
    let dir = temp_dir("late");
    let link = dir.join("urg");
    let clock = Arc::new(ScaledClock::new(RATE));
    // The driver starts first: the path does not exist yet.
    let driver = UrgDriver::start(
        Box::new(DeviceConnector::new(&link)),
        test_params(),
        clock.clone(),
    )
    .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(300));
    assert!(driver.scans().try_recv().is_err());
    assert!(!driver.health().snapshot().streaming);
    let cfg = EmulatorConfig {
        link: Some(link.clone()),
        ..EmulatorConfig::default()
    };
    let emu = Emulator::spawn(cfg, Box::new(RectRoom::bench(2)), clock).unwrap();
    let s = driver
        .scans()
        .recv_timeout(std::time::Duration::from_secs(10))
        .expect("a scan once the device appeared");
    assert_eq!(s.scan.beams.len(), 682);
    assert!(driver.health().snapshot().streaming);
    driver.shutdown();
    drop(emu);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_driver_left_on_a_vanished_pty_number_leaves_the_next_pty_alone() {
    use std::sync::Arc;
    use std::time::Duration;
    use sweepline::serial::DeviceConnector;
    use sweepline::sim::urg_emu::{Emulator, EmulatorConfig, RectRoom};
    use sweepline::urg::{ScaledClock, UrgDriver};
    let clock = Arc::new(ScaledClock::new(RATE));
    // A driver on a bare /dev/pts/N whose emulator then goes away.
    let gone = Emulator::spawn(
        EmulatorConfig::default(),
        Box::new(RectRoom::bench(2)),
        clock.clone(),
    )
    .unwrap();
    let number = gone.path().unwrap();
    let stale = UrgDriver::start(
        Box::new(DeviceConnector::new(&number)),
        test_params(),
        clock.clone(),
    )
    .unwrap();
    stale
        .scans()
        .recv_timeout(Duration::from_secs(10))
        .expect("the first emulator streams");
    drop(gone);
    // The next pty made on this machine gets the same number (the kernel
    // hands out the lowest free one; retry while another process holds it).
    let dir = temp_dir("reused");
    let link = dir.join("urg");
    let emu = (0..300)
        .find_map(|_| {
            let cfg = EmulatorConfig {
                link: Some(link.clone()),
                ..EmulatorConfig::default()
            };
            let e = Emulator::spawn(cfg, Box::new(RectRoom::bench(2)), clock.clone()).unwrap();
            if std::fs::read_link(&link).ok().as_deref() == Some(number.as_path()) {
                return Some(e);
            }
            drop(e);
            std::thread::sleep(Duration::from_millis(10));
            None
        })
        .expect("a new pty with the old number");
    // Give the stale driver several back-off rounds to (wrongly) take it.
    std::thread::sleep(Duration::from_millis(600));
    while stale.scans().try_recv().is_ok() {}
    let owner = UrgDriver::start(
        Box::new(DeviceConnector::new(&link)),
        test_params(),
        clock.clone(),
    )
    .unwrap();
    let s = owner
        .scans()
        .recv_timeout(Duration::from_secs(10))
        .expect("the new pty's owner streams");
    assert_eq!(s.scan.beams.len(), 682);
    assert!(stale.scans().try_recv().is_err(), "stale driver got a scan");
    let h = stale.health().snapshot();
    assert_eq!(h.reconnects, 0, "{h:?}");
    assert!(!h.streaming);
    owner.shutdown();
    stale.shutdown();
    drop(emu);
    let _ = std::fs::remove_dir_all(&dir);
}

/// With `scanner.intensity` the driver asks a URG-04LX for its `FF` mode
/// (a distance and an intensity per pair of steps); a firmware without it
/// refuses, and the driver streams plain distances instead (and says so in
/// one log line) rather than failing or retrying.
#[test]
fn intensity_mode_is_asked_for_and_a_refusal_falls_back_to_plain_distances() {
    let params = sweepline::urg::UrgParams {
        intensity: true,
        ..test_params()
    };
    let asked = rig("intensity", "", false, params.clone());
    let got = asked.collect(5, 10.0);
    let cmds = asked.finish().commands;
    assert!(
        cmds.iter().any(|c| c.starts_with("MD00440725FF")),
        "{cmds:?}"
    );
    for s in &got {
        let lit = s.scan.beams.iter().filter(|b| b.valid && b.intensity > 0.0);
        assert!(lit.count() > 200, "intensities in FF mode");
    }
    let refused = rig("intensity-refused", "no-ff", false, params);
    let got = refused.collect(5, 10.0);
    let cmds = refused.finish().commands;
    let ff = cmds
        .iter()
        .filter(|c| c.starts_with("MD00440725FF"))
        .count();
    assert_eq!(ff, 1, "asked once, then not again: {cmds:?}");
    assert!(cmds.iter().any(|c| c == "MD0044072501000"), "{cmds:?}");
    assert_eq!(got.len(), 5);
    for s in &got {
        assert_eq!(s.scan.beams.len(), 682);
        assert!(s.scan.beams.iter().all(|b| b.intensity == 0.0));
    }
}
