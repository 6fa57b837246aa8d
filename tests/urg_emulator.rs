//! The emulated URG-04LX answers like the real one: byte-exact against the
//! real capture (`../shared/datasets/hokuyo-captures/example_urg_04lx.*`)
//! when replaying its scan at the same clock values, and the exact replies
//! of the vendor library's open sequence.

use std::sync::{Arc, Mutex};

use sweepline::sim::urg_emu::{
    capture_stream, EmuLog, Faults, Model, ModelSpec, RectRoom, ReplayScan, Scene, Sensor,
};

fn sensor(model: Model, scene: Box<dyn Scene>, scip1: bool) -> Sensor {
    let log = Arc::new(Mutex::new(EmuLog::default()));
    Sensor::new(
        ModelSpec::of(model),
        Faults::default(),
        scip1,
        scene,
        1,
        log,
        0.0,
    )
}

/// A sensor that answers every line at once (these tests check content;
/// the timing tests are below and in the sensor's unit tests).
fn instant(model: Model, scene: Box<dyn Scene>, scip1: bool) -> Sensor {
    let mut s = sensor(model, scene, scip1);
    s.set_reply_latency(false);
    s
}

fn ask(s: &mut Sensor, line: &str, now: f64) -> String {
    let mut out = Vec::new();
    s.on_line(line.as_bytes(), now, &mut out);
    String::from_utf8(out).unwrap()
}

/// Sends a GD and returns its reply, sent when the measured revolution ends.
fn ask_gd(s: &mut Sensor, line: &str, now: f64) -> String {
    let mut out = Vec::new();
    s.on_line(line.as_bytes(), now, &mut out);
    assert!(out.is_empty(), "GD answered before its scan was measured");
    let due = s.next_due().expect("a GD reply is pending");
    s.poll(due, &mut out);
    String::from_utf8(out).unwrap()
}

/// The records of a hokuyoaist capture file: (time in s, bytes).
fn records(file: &[u8]) -> Vec<(f64, Vec<u8>)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i + 12 <= file.len() {
        let word = |k: usize| u32::from_be_bytes([file[k], file[k + 1], file[k + 2], file[k + 3]]);
        let (sec, usec, len) = (word(i), word(i + 4), word(i + 8) as usize);
        out.push((
            f64::from(sec) + f64::from(usec) * 1e-6,
            file[i + 12..i + 12 + len].to_vec(),
        ));
        i += 12 + len;
    }
    out
}

/// For each command of a capture: when its line end was written and when
/// the first byte of its reply was read (s).
fn command_timing(logw: &[u8], logr: &[u8]) -> Vec<(f64, f64)> {
    let sends: Vec<f64> = records(logw)
        .iter()
        .filter(|(_, b)| b.ends_with(b"\n"))
        .map(|(t, _)| *t)
        .collect();
    let mut firsts = Vec::new();
    let mut start = true;
    let mut prev = 0u8;
    for (t, bytes) in records(logr) {
        for &b in &bytes {
            if start {
                firsts.push(t);
                start = false;
            }
            if b == b'\n' && prev == b'\n' {
                start = true;
            }
            prev = b;
        }
    }
    sends.into_iter().zip(firsts).collect()
}

#[test]
fn replies_are_byte_exact_and_timed_as_the_real_capture() {
    let logw = sweepline::require_shared!("datasets/hokuyo-captures/example_urg_04lx.logw");
    let logr = sweepline::require_shared!("datasets/hokuyo-captures/example_urg_04lx.logr");
    let wfile = std::fs::read(logw).unwrap();
    let rfile = std::fs::read(&logr).unwrap();
    let sent = capture_stream(&wfile).unwrap();
    let expected = capture_stream(&rfile).unwrap();
    let real = command_timing(&wfile, &rfile);
    let scene = ReplayScan::from_capture_file(&logr).unwrap();
    assert_eq!(scene.len(), 682);
    let mut s = sensor(Model::Urg04lx, Box::new(scene), false);
    // The captured unit had its laser on already (BM answered 02).
    s.set_reply_latency(false);
    ask(&mut s, "BM", 0.0);
    s.set_reply_latency(true);
    // Its revolutions started at clock values ending in 30 ms (the GD
    // stamp, 6968830 ms), and it answered the other commands at values
    // ending in 24 ms (the II TIME fields 0x6A5404 and 0x6A55F8).
    s.set_revolution_phase(0.030);
    // The host sends each command about 1 ms after the previous reply, as
    // in the capture; the first one as long before a tick as there.
    let lines: Vec<&[u8]> = sent
        .split(|&b| b == b'\n')
        .filter(|l| !l.is_empty())
        .collect();
    assert_eq!(lines.len(), real.len());
    let mut now = 6_968.024 - (real[0].1 - real[0].0);
    let mut out = Vec::new();
    for (line, (w, r)) in lines.iter().zip(&real) {
        let asked = now;
        let before = out.len();
        s.on_line(line, asked, &mut out);
        while !out[before..].ends_with(b"\n\n") {
            now = s.next_due().expect("a reply is pending");
            s.poll(now, &mut out);
        }
        let (emulated, captured) = (now - asked, r - w);
        assert!(
            (emulated - captured).abs() < 0.003,
            "{}: answered after {:.1} ms, the real unit after {:.1} ms",
            String::from_utf8_lossy(line),
            emulated * 1e3,
            captured * 1e3
        );
        now += 0.001;
    }
    assert_eq!(
        String::from_utf8_lossy(&out),
        String::from_utf8_lossy(&expected),
        "emulator replies differ from the real URG-04LX"
    );
}

#[test]
fn vendor_open_sequence_replies() {
    let mut s = instant(Model::Urg04lx, Box::new(RectRoom::bench(1)), false);
    assert_eq!(ask(&mut s, "", 0.0), "");
    assert_eq!(ask(&mut s, "QT", 0.0), "QT\n00P\n\n");
    let pp = ask(&mut s, "PP", 0.0);
    assert!(pp.starts_with("PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nDMIN:20;4\n"));
    assert!(pp.ends_with("AFRT:384;6\nSCAN:600;e\n\n"));
    let vv = ask(&mut s, "VV", 0.0);
    assert!(vv.contains("FIRM:3.1.04(02/Aug./2007);a\n") && vv.ends_with("SERI:H0706400;F\n\n"));
    let ii = ask(&mut s, "II", 0.0);
    assert!(ii.contains("LASR:OFF;7\n") && ii.contains("TIME:000000;"));
    // GD needs the laser.
    assert_eq!(ask(&mut s, "GD0044072501", 0.0), "GD0044072501\n10Q\n\n");
    assert_eq!(ask(&mut s, "BM", 0.0), "BM\n00P\n\n");
    assert_eq!(ask(&mut s, "BM", 0.0), "BM\n02R\n\n");
    let gd = ask_gd(&mut s, "GD0044072501", 0.05);
    let lines: Vec<&str> = gd.split('\n').collect();
    assert_eq!(&lines[..2], &["GD0044072501", "00P"]);
    assert_eq!(lines.len(), 2 + 1 + 32 + 2, "{gd}");
    assert_eq!(lines[3 + 31].len(), 62 + 1);
    // ME is not a URG-04LX command.
    assert_eq!(
        ask(&mut s, "ME0044072501000", 0.2),
        "ME0044072501000\n0Ee\n\n"
    );
    // MD: ack, then one block per scan with the remaining count in the echo.
    assert_eq!(
        ask(&mut s, "MD0044072502001", 0.2),
        "MD0044072502001\n00P\n\n"
    );
    let mut out = Vec::new();
    s.poll(0.45, &mut out);
    let scan = String::from_utf8(out).unwrap();
    assert!(scan.starts_with("MD0044072502000\n99b\n"), "{scan}");
    assert_eq!(s.next_due(), None, "a one-scan request ends by itself");
    assert_eq!(ask(&mut s, "QT", 0.3), "QT\n00P\n\n");
    // Time adjust mode.
    assert_eq!(ask(&mut s, "TM1", 0.3), "TM1\n04T\n\n");
    assert_eq!(ask(&mut s, "TM0", 0.3), "TM0\n00P\n\n");
    assert_eq!(ask(&mut s, "QT", 0.3), "QT\n0Ee\n\n", "stuck in TM mode");
    let tm1 = ask(&mut s, "TM1;ab", 1.0);
    assert!(
        tm1.starts_with("TM1;ab\n00P\n") && tm1.ends_with("\n\n"),
        "{tm1}"
    );
    assert_eq!(tm1.len(), "TM1;ab\n00P\n".len() + 6 + 1);
    assert_eq!(ask(&mut s, "TM2", 1.0), "TM2\n00P\n\n");
    assert_eq!(ask(&mut s, "TM2", 1.0), "TM2\n03S\n\n");
    assert_eq!(ask(&mut s, "RS", 2.0), "RS\n00P\n\n");
    assert_eq!(s.clock_ms(2.5), 500, "RS restarts the clock");
    // Reboot needs RB twice within a second.
    assert_eq!(ask(&mut s, "RB", 3.0), "RB\n01Q\n\n");
    assert_eq!(ask(&mut s, "RB", 3.5), "RB\n00P\n\n");
    // Bad input: typed statuses, never silence.
    assert_eq!(ask(&mut s, "XX", 4.0), "XX\n0Ee\n\n");
    assert_eq!(ask(&mut s, "MD00440725", 4.0), "MD00440725\n0Cc\n\n");
    assert_eq!(ask(&mut s, "GD0725004401", 4.0), "GD0725004401\n05U\n\n");
    assert_eq!(ask(&mut s, "GD0044099901", 4.0), "GD0044099901\n04T\n\n");
    // Steps up to 768 (step D) are accepted, as on the real firmware.
    assert_eq!(ask(&mut s, "GD0044076901", 4.0), "GD0044076901\n04T\n\n");
    assert_eq!(ask(&mut s, "SCIP2.0", 4.0), "SCIP2.0\n0Ee\n\n");
}

#[test]
fn scip1_boot_answers_one_character_statuses() {
    let mut s = instant(Model::Urg04lx, Box::new(RectRoom::bench(1)), true);
    assert_eq!(ask(&mut s, "QT", 0.0), "QT\nE\n\n");
    assert_eq!(ask(&mut s, "SCIP2.0", 0.0), "SCIP2.0\n0\n\n");
    assert_eq!(ask(&mut s, "QT", 0.0), "QT\n00P\n\n");
}

#[test]
fn utm_answers_me_and_urg_ff_mode_pairs_steps() {
    let mut s = instant(Model::Utm30lx, Box::new(RectRoom::bench(1)), false);
    let pp = ask(&mut s, "PP", 0.0);
    assert!(
        pp.contains("MODL:UTM-30LX(Hokuyo Automatic Co.,Ltd.);U\n") && pp.contains("SCAN:2400;U\n")
    );
    assert_eq!(
        ask(&mut s, "ME0000108001101", 0.0),
        "ME0000108001101\n00P\n\n"
    );
    let mut out = Vec::new();
    s.poll(0.06, &mut out);
    let text = String::from_utf8(out).unwrap();
    assert!(text.starts_with("ME0000108001100\n99b\n"), "{text}");
    // 1081 steps x 6 characters.
    let chars: usize = text
        .split('\n')
        .skip(3)
        .filter(|l| !l.is_empty())
        .map(|l| l.len() - 1)
        .sum();
    assert_eq!(chars, 1081 * 6);

    let mut u = instant(Model::Urg04lx, Box::new(RectRoom::bench(1)), false);
    ask(&mut u, "BM", 0.0);
    let gd = ask_gd(&mut u, "GD03840387FF", 0.0);
    let data: String = gd
        .split('\n')
        .skip(3)
        .filter(|l| !l.is_empty())
        .map(|l| &l[..l.len() - 1])
        .collect();
    // Steps 384..387: distance, intensity, distance, intensity.
    let v: Vec<u32> = data
        .as_bytes()
        .chunks(3)
        .map(|c| c.iter().fold(0, |a, &b| (a << 6) | u32::from(b - 0x30)))
        .collect();
    assert_eq!(v.len(), 4);
    assert!((2490..=2510).contains(&v[0]), "{v:?}");
    assert!(v[1] > 0 && v[1] < 20_000, "{v:?}");
    assert_eq!(
        ask(&mut s, "GD03840387FF", 0.1).split('\n').nth(1),
        Some("03S")
    );
}
