//! GD is answered as a real URG-04LX answers it (found by running Hokuyo's
//! urg_library `get_distance_handshake` and `calculate_xy` against the
//! emulator and comparing with the real capture): the scan is the revolution
//! that starts after the command, stamped at its start and sent when it
//! ends. Before, the emulator answered at once with the current clock, so
//! back-to-back GDs got stamps 0-1 ms apart, which no real unit sends.

use std::sync::{Arc, Mutex};

use sweepline::sim::urg_emu::{
    capture_stream, EmuLog, Faults, Model, ModelSpec, RectRoom, ReplayScan, Scene, Sensor,
};

/// A sensor answering every other command at once: these tests are about
/// GD, which starts measuring the moment it arrives either way (the reply
/// latency of the other commands is tested with the sensor's unit tests and
/// against the capture in `urg_emulator.rs`).
fn sensor(scene: Box<dyn Scene>) -> Sensor {
    let log = Arc::new(Mutex::new(EmuLog::default()));
    let mut s = Sensor::new(
        ModelSpec::of(Model::Urg04lx),
        Faults::default(),
        false,
        scene,
        1,
        log,
        0.0,
    );
    s.set_reply_latency(false);
    s
}

fn send(s: &mut Sensor, line: &str, now: f64) -> String {
    let mut out = Vec::new();
    s.on_line(line.as_bytes(), now, &mut out);
    String::from_utf8(out).unwrap()
}

fn poll(s: &mut Sensor, now: f64) -> String {
    let mut out = Vec::new();
    s.poll(now, &mut out);
    String::from_utf8(out).unwrap()
}

/// The 4-character SCIP timestamp of a reply (its third line).
fn stamp(reply: &str) -> u32 {
    let line = reply.split('\n').nth(2).expect("a timestamp line");
    line.as_bytes()[..4]
        .iter()
        .fold(0, |a, &b| (a << 6) | u32::from(b - 0x30))
}

#[test]
fn gd_reply_is_the_next_revolution_sent_when_it_ends_byte_exact() {
    let logr = sweepline::require_shared!("datasets/hokuyo-captures/example_urg_04lx.logr");
    let real = capture_stream(&std::fs::read(&logr).unwrap()).unwrap();
    let real = String::from_utf8(real).unwrap();
    let real_gd = real
        .split("\n\n")
        .find(|b| b.starts_with("GD0044072501\n"))
        .expect("the capture holds a GD reply");
    let real_data: Vec<&str> = real_gd.split('\n').skip(3).collect();
    assert_eq!(real_data.len(), 32);

    let mut s = sensor(Box::new(ReplayScan::from_capture_file(&logr).unwrap()));
    assert_eq!(send(&mut s, "BM", 0.0), "BM\n00P\n\n");
    // Nothing while the revolution starting at 0.1 s is measured.
    assert_eq!(send(&mut s, "GD0044072501", 0.05), "");
    assert_eq!(s.next_due(), Some(0.2));
    assert_eq!(poll(&mut s, 0.1), "");
    assert_eq!(poll(&mut s, 0.199), "");
    // Sent at 0.2 s, stamped 100 ms ("001T", checksum 'U'), with the real
    // unit's data lines.
    let mut expected = String::from("GD0044072501\n00P\n001TU\n");
    for line in &real_data {
        expected.push_str(line);
        expected.push('\n');
    }
    expected.push('\n');
    assert_eq!(poll(&mut s, 0.2), expected);
    assert_eq!(s.next_due(), None);
    assert_eq!(poll(&mut s, 0.5), "", "a GD is answered once");
}

#[test]
fn lines_sent_while_gd_measures_are_answered_after_it_in_order() {
    let mut s = sensor(Box::new(RectRoom::bench(1)));
    send(&mut s, "BM", 0.0);
    assert_eq!(send(&mut s, "GD0044072501", 0.05), "");
    assert_eq!(send(&mut s, "QT", 0.06), "");
    assert_eq!(
        send(&mut s, "GD0044072501", 0.07),
        "",
        "GD refused: laser off"
    );
    let out = poll(&mut s, 0.2);
    let blocks: Vec<&str> = out.split("\n\n").filter(|b| !b.is_empty()).collect();
    assert_eq!(blocks.len(), 3, "{out}");
    assert!(blocks[0].starts_with("GD0044072501\n00P\n001TU\n"), "{out}");
    assert_eq!(blocks[1], "QT\n00P");
    // QT turned the laser off before the second GD was processed.
    assert_eq!(blocks[2], "GD0044072501\n10Q");
    assert_eq!(s.next_due(), None);
}

#[test]
fn back_to_back_gds_never_repeat_a_scan() {
    // urg_library's get_distance_handshake: BM, then GD as soon as the
    // previous reply arrived, ten times.
    let mut s = sensor(Box::new(RectRoom::bench(1)));
    send(&mut s, "BM", 0.0);
    let mut now = 0.05;
    let mut stamps = Vec::new();
    for _ in 0..10 {
        assert_eq!(send(&mut s, "GD0044072501", now), "");
        now = s.next_due().unwrap();
        let reply = poll(&mut s, now);
        assert!(reply.starts_with("GD0044072501\n00P\n"), "{reply}");
        stamps.push(stamp(&reply));
    }
    // Each GD waits for the next revolution start and its end: one scan
    // every 200 ms, each stamped at its start on the 100 ms grid.
    let expected: Vec<u32> = (0..10).map(|k| 100 + 200 * k).collect();
    assert_eq!(stamps, expected);
}

#[test]
fn md_scans_and_gd_share_the_revolution_grid() {
    let mut s = sensor(Box::new(RectRoom::bench(1)));
    s.set_revolution_phase(0.030);
    assert_eq!(
        send(&mut s, "MD0044072501001", 0.0),
        "MD0044072501001\n00P\n\n"
    );
    // The revolution starting at 30 ms is sent when it ends, stamped at its
    // start.
    let due = s.next_due().unwrap();
    assert!((due - 0.130).abs() < 1e-9, "{due}");
    assert_eq!(poll(&mut s, 0.129), "", "not before its revolution ends");
    let scan = poll(&mut s, due);
    assert!(scan.starts_with("MD0044072501000\n99b\n"), "{scan}");
    assert_eq!(stamp(&scan), 30);
    send(&mut s, "BM", 0.15);
    assert_eq!(send(&mut s, "GD0044072501", 0.15), "");
    let due = s.next_due().unwrap();
    assert!((due - 0.330).abs() < 1e-9, "{due}");
    assert_eq!(stamp(&poll(&mut s, due)), 230);
    // A phase outside one period wraps; a nonsense one is ignored.
    s.set_revolution_phase(0.330);
    s.set_revolution_phase(f64::NAN);
    assert_eq!(send(&mut s, "GD0044072501", 0.335), "");
    let due = s.next_due().unwrap();
    assert!((due - 0.530).abs() < 1e-9, "{due}");
    assert_eq!(stamp(&poll(&mut s, due)), 430);
}
