//! Unit tests of the emulated sensor's timing, error codes and step range.

use std::sync::{Arc, Mutex};

use super::*;
use crate::urg_emu::scene::RectRoom;

fn urg(scene: RectRoom) -> Sensor {
    let log = Arc::new(Mutex::new(EmuLog::default()));
    let spec = ModelSpec::of(Model::Urg04lx);
    Sensor::new(spec, Faults::default(), false, Box::new(scene), 1, log, 0.0)
}

/// Sends `line` at `at` and steps a manual clock from event to event until
/// its reply is complete; returns the reply and when it was sent.
fn exchange(s: &mut Sensor, line: &str, at: f64) -> (String, f64) {
    let mut out = Vec::new();
    s.on_line(line.as_bytes(), at, &mut out);
    let mut now = at;
    while !out.ends_with(b"\n\n") {
        now = s.next_due().expect("a reply is pending");
        s.poll(now, &mut out);
    }
    (String::from_utf8(out).unwrap_or_default(), now)
}

/// The distance values of a GD reply.
fn values(reply: &str) -> Vec<u32> {
    let data: Vec<u8> = reply
        .split('\n')
        .skip(3)
        .filter(|l| !l.is_empty())
        .flat_map(|l| l.as_bytes()[..l.len() - 1].to_vec())
        .collect();
    data.chunks(3)
        .map(|c| c.iter().fold(0, |a, &b| (a << 6) | u32::from(b - 0x30)))
        .collect()
}

/// One GD of `first..=last` in `room`; the values by step.
fn scan(room: RectRoom, first: u16, last: u16) -> Vec<u32> {
    let mut s = urg(room);
    s.set_reply_latency(false);
    exchange(&mut s, "BM", 0.0);
    let (reply, _) = exchange(&mut s, &format!("GD{first:04}{last:04}01"), 0.01);
    assert!(reply.contains("\n00P\n"), "{reply}");
    values(&reply)
}

#[test]
fn vv_is_answered_about_one_scan_period_later() {
    let mut s = urg(RectRoom::bench(1));
    // Revolutions start at k × 100 ms, so the firmware answers at 94, 194 ms…
    let (vv, at) = exchange(&mut s, "VV", 0.0945);
    assert!(vv.starts_with("VV\n00P\nVEND:"), "{vv}");
    let wait = at - 0.0945;
    assert!(
        (0.095..=0.1).contains(&wait),
        "VV took {:.1} ms",
        wait * 1e3
    );
    // A line sent mid-revolution waits only for the next tick (the first
    // VV of the capture was answered after 10 ms).
    let (_, at) = exchange(&mut s, "PP", 0.28);
    assert!((at - 0.294).abs() < 1e-9, "PP at {at}");
    // Nothing is sent early.
    let mut out = Vec::new();
    s.on_line(b"II", 0.3, &mut out);
    s.poll(0.39, &mut out);
    assert!(out.is_empty());
    s.poll(0.394, &mut out);
    assert!(out.starts_with(b"II\n00P\n"));
}

#[test]
fn tm1_is_answered_at_the_next_clock_edge() {
    let mut s = urg(RectRoom::bench(1));
    let (tm0, at) = exchange(&mut s, "TM0", 0.05);
    assert_eq!(tm0, "TM0\n00P\n\n");
    assert!((at - 0.094).abs() < 1e-9);
    let sent = at + 0.0002;
    let (tm1, back) = exchange(&mut s, "TM1", sent);
    let wait = back - sent;
    assert!(wait > 0.0 && wait <= 0.001, "TM1 took {:.2} ms", wait * 1e3);
    // It reads the clock at that edge: 95 ms, 4 characters "001O" + sum.
    assert_eq!(tm1, "TM1\n00P\n001OP\n\n");
    let (tm2, done) = exchange(&mut s, "TM2", back);
    assert_eq!(tm2, "TM2\n00P\n\n");
    assert!(
        (done - back - 0.002).abs() < 1e-9,
        "TM2 took {}",
        done - back
    );
    // Out of adjust mode, back to one reply per revolution.
    let (_, at) = exchange(&mut s, "QT", done);
    assert!((at - 0.194).abs() < 1e-9, "QT at {at}");
}

#[test]
fn latency_can_be_switched_off() {
    let mut s = urg(RectRoom::bench(1));
    s.set_reply_latency(false);
    let mut out = Vec::new();
    s.on_line(b"VV", 0.0945, &mut out);
    assert!(out.starts_with(b"VV\n00P\n"));
    assert_eq!(s.next_due(), None);
}

#[test]
fn lines_wait_for_a_pending_gd_then_for_the_tick() {
    let mut s = urg(RectRoom::bench(1));
    exchange(&mut s, "BM", 0.0);
    let mut out = Vec::new();
    s.on_line(b"GD0044072501", 0.1, &mut out);
    s.on_line(b"VV", 0.101, &mut out);
    // The GD measures the revolution from 0.2 s and is sent at 0.3 s.
    let due = s.next_due().unwrap_or(0.0);
    assert!((due - 0.3).abs() < 1e-9, "{due}");
    s.poll(due, &mut out);
    assert!(out.starts_with(b"GD0044072501\n00P\n") && out.ends_with(b"\n\n"));
    let n = out.len();
    // VV then waits for the next command tick.
    assert!((s.next_due().unwrap_or(0.0) - 0.394).abs() < 1e-9);
    s.poll(0.394, &mut out);
    assert!(out[n..].starts_with(b"VV\n00P\n"));
}

#[test]
fn beyond_dmax_is_code_zero() {
    // Front wall 7 m away: beyond the URG-04LX's 5.6 m.
    let room = RectRoom::new(8.0, 3.0, (1.0, 1.5, 0.0), 1);
    let v = scan(room, 384, 384);
    assert_eq!(v, vec![0]);
    let near = RectRoom::new(6.0, 3.0, (1.0, 1.5, 0.0), 1);
    assert_eq!(scan(near, 384, 384), vec![5000]);
}

#[test]
fn black_surface_at_glancing_incidence_gives_error_codes() {
    // A long room: steps 20-30° left of the front meet the left wall (1.5 m
    // to the side) 3-4.4 m away, 60-70° off its normal.
    let room = |refl: f64| {
        let mut r = RectRoom::new(10.0, 3.0, (0.5, 1.5, 0.0), 1);
        r.reflectivity[1] = refl;
        r
    };
    let (first, last) = (384 + 57, 384 + 85);
    let black = scan(room(0.05), first, last);
    let white = scan(room(0.9), first, last);
    assert_eq!(black.len(), white.len());
    let errors = black.iter().filter(|&&v| v < 20).count();
    assert!(
        errors == black.len(),
        "{errors} of {}: {black:?}",
        black.len()
    );
    assert!(black.iter().all(|&v| v == 0 || v == 7), "{black:?}");
    assert!(white.iter().all(|&v| v >= 20), "{white:?}");
    // Head-on, the same black wall is measured.
    let mut r = room(0.05);
    r.pose.2 = std::f64::consts::FRAC_PI_2;
    let v = scan(r, 384, 384);
    assert!((1490..=1510).contains(&v[0]), "{v:?}");
}

#[test]
fn bench_room_has_some_error_codes() {
    let v = scan(RectRoom::bench(1), 44, 725);
    let errors = v.iter().filter(|&&x| x < 20).count();
    let share = errors as f64 / v.len() as f64;
    assert!((0.08..0.2).contains(&share), "{errors} of {}", v.len());
    assert!(v.iter().all(|&x| x >= 20 || x == 0 || x == 7), "{v:?}");
}

#[test]
fn end_step_768_is_accepted_and_769_refused() {
    let mut s = urg(RectRoom::bench(1));
    s.set_reply_latency(false);
    exchange(&mut s, "BM", 0.0);
    let (gd, _) = exchange(&mut s, "GD0000076801", 0.01);
    assert!(gd.starts_with("GD0000076801\n00P\n"), "{gd}");
    let v = values(&gd);
    assert_eq!(v.len(), 769);
    // Outside AMIN..AMAX the steps look at the housing.
    assert!(v[..44].iter().chain(&v[726..]).all(|&x| x == 19), "{v:?}");
    assert!(v[384] > 2400, "{}", v[384]);
    assert_eq!(
        exchange(&mut s, "GD0000076901", 0.5).0,
        "GD0000076901\n04T\n\n"
    );
    assert_eq!(
        exchange(&mut s, "MD0044076900000", 0.5).0,
        "MD0044076900000\n04T\n\n"
    );
    let (md, _) = exchange(&mut s, "MD0044076800001", 0.5);
    assert_eq!(md, "MD0044076800001\n00P\n\n");
}

#[test]
fn through_the_in_process_link_vv_takes_a_scan_period_of_manual_clock() {
    use crate::clock::{Clock, ManualClock};
    use crate::urg_emu::link::SensorLink;
    use std::io::{Read, Write};

    let clock = Arc::new(ManualClock::new(0.0));
    let mut link = SensorLink::new(urg(RectRoom::bench(1)), clock.clone());
    let mut reply = Vec::new();
    let mut buf = [0u8; 256];
    clock.set(0.0945);
    link.write_all(b"VV\n").unwrap_or_default();
    while !reply.ends_with(b"\n\n") {
        // A timed-out read moves the clock on; a reply moves it to its time.
        if let Ok(n) = link.read(&mut buf) {
            reply.extend_from_slice(&buf[..n]);
        }
        assert!(clock.now() < 1.0, "no reply");
    }
    assert!(reply.starts_with(b"VV\n00P\n"));
    let took = clock.now() - 0.0945;
    assert!(
        (0.095..=0.1).contains(&took),
        "VV took {:.1} ms",
        took * 1e3
    );
    // TM1 in adjust mode: about a millisecond.
    link.write_all(b"TM0\nTM1\n").unwrap_or_default();
    let start = clock.now();
    let mut got = Vec::new();
    let mut tm1_at = None;
    while tm1_at.is_none() {
        if let Ok(n) = link.read(&mut buf) {
            got.extend_from_slice(&buf[..n]);
        }
        if got.windows(4).any(|w| w == b"TM1\n") && got.ends_with(b"\n\n") {
            tm1_at = Some(clock.now());
        }
        assert!(clock.now() < start + 1.0, "no reply");
    }
    let tm0_at = 0.294;
    let tm1 = tm1_at.unwrap_or(0.0) - tm0_at;
    assert!(
        tm1 > 0.0 && tm1 <= 0.001 + 1e-9,
        "TM1 took {:.2} ms",
        tm1 * 1e3
    );
}
