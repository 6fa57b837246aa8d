//! One test per fault the emulated URG-04LX can inject, each over a real pty
//! with the real driver: the driver recovers, every scan it delivers is
//! exactly one the emulator sent, no good scan is lost or duplicated, and the
//! scans it discarded are exactly the ones corrupted on the wire.

mod urg_support;

use std::io::{Read, Write};
use std::time::Duration;

use sweepline::serial::open_device;
use urg_support::*;

/// Runs `faults` for `n` scans and checks the no-loss bookkeeping; returns
/// the scans, the log and the health.
fn run(
    name: &str,
    faults: &str,
    n: usize,
) -> (
    Vec<sweepline::urg::UrgScan>,
    sweepline::sim::urg_emu::EmuLog,
    sweepline::urg::HealthSnapshot,
) {
    let rig = rig(name, faults, false, test_params());
    let got = rig.collect(n, 15.0);
    let health = rig.driver().health().snapshot();
    let log = rig.finish();
    assert_eq!(got.len(), n, "{name}: scans delivered; health:\n{health}");
    let (_, corrupted) = check_no_loss(&log, &got);
    // Every corrupted scan before the last delivered one was discarded and
    // counted, and nothing else was.
    assert_eq!(
        health.discarded_scans as usize, corrupted,
        "{name}: discarded vs corrupted; health:\n{health}"
    );
    (got, log, health)
}

#[test]
fn corrupted_checksums_are_discarded_and_counted() {
    let (_, log, h) = run("checksum", "checksum=5", 30);
    assert!(log.corrupted() >= 6);
    assert!(h.checksum_errors >= 6);
    assert_eq!(h.reconnects, 0);
}

#[test]
fn dropped_bytes_lose_only_their_scan() {
    let (_, log, h) = run("drop", "drop=6", 30);
    assert!(log.corrupted() >= 5);
    assert_eq!(h.reconnects, 0);
}

#[test]
fn extra_bytes_lose_only_their_scan() {
    let (_, log, h) = run("extra", "extra=7", 30);
    assert!(log.corrupted() >= 4);
    assert_eq!(h.reconnects, 0);
}

#[test]
fn line_noise_between_replies_loses_nothing() {
    let (_, _, h) = run("noise", "noise=4", 30);
    assert!(h.desyncs >= 6, "{h}");
    assert_eq!(h.discarded_scans, 0, "{h}");
}

#[test]
fn crlf_line_ends_are_accepted() {
    let (_, _, h) = run("crlf", "crlf", 20);
    assert_eq!(h.checksum_errors + h.desyncs, 0);
}

#[test]
fn writes_split_at_random_points_are_reassembled() {
    let (_, _, h) = run("split", "split,checksum=9", 25);
    assert!(h.checksum_errors >= 2);
    assert_eq!(h.desyncs, 0);
}

#[test]
fn error_statuses_are_reported_and_streaming_goes_on() {
    let (got, _, h) = run("status", "status=8", 30);
    assert_eq!(h.last_status, Some(*b"50"));
    // The missing scans show as gaps, reported both per scan and in total.
    let gaps: u64 = got.iter().map(|s| s.dropped_before).sum();
    assert!(gaps >= 3, "{gaps}");
    assert_eq!(h.dropped_scans, gaps);
}

#[test]
fn stuck_clock_is_detected() {
    let (got, _, h) = run("stuck", "stuck=6", 20);
    assert!(h.stuck_clock >= 3, "{h}");
    assert!(got.windows(2).any(|w| w[0].raw_stamp == w[1].raw_stamp));
}

#[test]
fn clock_wrap_is_unwrapped_and_stamps_stay_continuous() {
    let (got, _, _) = run("wrap", "wrap", 40);
    assert!(
        got.windows(2).any(|w| w[1].raw_stamp < w[0].raw_stamp),
        "the 24-bit clock should have wrapped"
    );
    for w in got.windows(2) {
        let dms = w[1].sensor_ms - w[0].sensor_ms;
        assert!((90..=110).contains(&dms) || dms % 100 < 10, "{dms}");
        let dt = w[1].scan.stamp - w[0].scan.stamp;
        assert!((dt - dms as f64 / 1000.0).abs() < 0.003, "{dt} vs {dms}");
    }
}

#[test]
fn stall_times_out_restarts_and_loses_nothing() {
    let (got, log, h) = run("stall", "stall=10:1.0", 25);
    assert!(log.stalls >= 1);
    assert!(h.timeouts >= 1, "{h}");
    // The stall shows as a gap in the sensor clock, then scans flow again.
    assert!(got.iter().any(|s| s.dropped_before > 0) || h.restarts >= 1);
}

#[test]
fn unplug_and_replug_reconnects_and_loses_nothing() {
    let (got, log, h) = run("unplug", "unplug=10:0.4", 25);
    assert!(log.unplugs >= 1);
    assert!(h.reconnects >= 1, "{h}");
    // The replugged sensor restarted its clock: a new epoch.
    assert!(got.last().unwrap().epoch > got[0].epoch);
}

#[test]
fn long_stall_climbs_to_reset_and_reopen() {
    let mut p = test_params();
    p.failures_before_reset = 2;
    p.reply_timeout = 0.2;
    let rig = rig("longstall", "stall=8:3.0", false, p);
    let got = rig.collect(20, 15.0);
    let h = rig.driver().health().snapshot();
    let log = rig.finish();
    assert_eq!(got.len(), 20, "{h}");
    assert!(h.resets >= 1, "{h}");
    check_no_loss(&log, &got);
    assert!(log.commands.iter().any(|c| c == "RS"));
}

#[test]
fn scip1_boot_is_switched_to_scip2() {
    let rig = rig("scip1", "", true, test_params());
    let got = rig.collect(10, 10.0);
    let log = rig.finish();
    assert_eq!(got.len(), 10);
    let cmds: Vec<&str> = log.commands.iter().map(String::as_str).collect();
    assert_eq!(&cmds[..3], &["QT", "SCIP2.0", "QT"]);
    check_no_loss(&log, &got);
}

fn exchange(port: &mut sweepline::serial::device::DevicePort, line: &str) -> Vec<u8> {
    port.write_all(format!("{line}\n").as_bytes()).unwrap();
    std::thread::sleep(Duration::from_millis(30));
    let mut v = vec![0u8; 8192];
    let n = port.read(&mut v).unwrap_or(0);
    v.truncate(n);
    v
}

#[test]
fn sensor_left_in_time_adjust_or_streaming_is_recovered() {
    use sweepline::sim::urg_emu::{Emulator, EmulatorConfig, RectRoom};
    use sweepline::urg::{ScaledClock, UrgDriver};
    for leftover in ["TM0", "MD0044072501000"] {
        let dir = temp_dir(&format!("leftover-{}", &leftover[..2]));
        let link = dir.join("urg");
        let clock = std::sync::Arc::new(ScaledClock::new(RATE));
        let cfg = EmulatorConfig {
            link: Some(link.clone()),
            ..EmulatorConfig::default()
        };
        let emu = Emulator::spawn(cfg, Box::new(RectRoom::bench(1)), clock.clone()).unwrap();
        // A previous client leaves the sensor in a bad state and goes away.
        {
            let mut port = open_device(&link, 115_200, Duration::from_millis(50)).unwrap();
            assert!(
                open_device(&link, 115_200, Duration::from_millis(50)).is_err(),
                "a second opener must be refused"
            );
            let reply = exchange(&mut port, leftover);
            assert!(
                reply.starts_with(leftover.as_bytes()),
                "{:?}",
                String::from_utf8_lossy(&reply)
            );
        }
        let driver = UrgDriver::start(
            Box::new(sweepline::serial::DeviceConnector::new(&link)),
            test_params(),
            clock.clone(),
        )
        .unwrap();
        let mut got = Vec::new();
        while got.len() < 10 {
            got.push(
                driver
                    .scans()
                    .recv_timeout(Duration::from_secs(10))
                    .expect("scan"),
            );
        }
        driver.shutdown();
        let log = emu.log();
        drop(emu);
        let cmds: Vec<&str> = log.commands.iter().map(String::as_str).collect();
        if leftover == "TM0" {
            assert!(cmds.contains(&"TM2"), "{cmds:?}");
        }
        assert!(got.iter().all(|s| s.scan.beams.len() == 682));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn hung_firmware_is_rebooted_as_the_last_resort() {
    let mut p = test_params();
    // Above the 100 ms a real URG may take to answer (once per revolution).
    p.reply_timeout = 0.25;
    p.failures_before_reset = 2;
    p.reboot_wait = 0.5;
    let rig = rig("hang", "hang=10", false, p);
    let got = rig.collect(20, 20.0);
    let h = rig.driver().health().snapshot();
    let log = rig.finish();
    assert_eq!(got.len(), 20, "{h}");
    assert!(h.reboots >= 1, "{h}");
    assert!(log.boots >= 2);
    assert!(log.commands.iter().filter(|c| *c == "RB").count() >= 2);
    check_no_loss(&log, &got);
}
