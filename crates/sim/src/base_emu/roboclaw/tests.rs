//! The emulated RoboClaw against the manual's packet rules and the
//! behaviour of a real controller driving real wheels.

use super::*;
use crate::motor::roboclaw::codec::Motor;
use crate::motor::roboclaw::codec::{encode_command, ReplyDecoder};

const CPM: f64 = 1000.0;

fn ask(d: &mut RoboClawDevice, c: Command, now: f64, body: &BodyState) -> Option<Reply> {
    let mut out = Vec::new();
    d.on_bytes(&encode_command(0x80, &c), now, body, &mut out);
    let mut dec = ReplyDecoder::new(0x80, &c);
    out.iter().find_map(|&b| dec.push(b).ok().flatten())
}

fn q(q: Query) -> Command {
    Command::Query(q)
}

/// Runs the device for `secs` with the wheels following its set-points
/// exactly (encoder travel integrated), in 5 ms steps from `t`.
fn run(d: &mut RoboClawDevice, body: &mut BodyState, t: &mut f64, secs: f64) {
    let mut out = Vec::new();
    let end = *t + secs;
    while *t < end - 1e-9 {
        *t += 0.005;
        let w = d.tick(*t, body, &mut out);
        body.encoder.0 += w.left * 0.005;
        body.encoder.1 += w.right * 0.005;
    }
}

#[test]
fn a_read_is_address_and_command_alone_and_the_next_write_is_not_swallowed() {
    let mut d = RoboClawDevice::new(0x80, CPM, true).strict(true);
    let body = BodyState::default();
    let mut out = Vec::new();
    // ReadMainBatteryVoltage as Basicmicro's libraries send it: 80 18.
    d.on_bytes(&[0x80, 0x18], 0.0, &body, &mut out);
    assert_eq!(out.len(), 4, "two data bytes and the CRC: {out:02x?}");
    // A stop 5 ms later is acknowledged.
    out.clear();
    let stop = encode_command(0x80, &Command::speeds(0, 0));
    d.on_bytes(&stop, 0.005, &body, &mut out);
    assert_eq!(out, vec![0xFF]);
    assert_eq!(d.stats().packets_rejected, 0);
    assert_eq!(d.stats().bytes_skipped, 0);
}

#[test]
fn a_crc_after_a_read_is_what_the_manual_does_not_send_and_strict_mode_shows_it() {
    let mut d = RoboClawDevice::new(0x80, CPM, true).strict(true);
    let body = BodyState::default();
    let mut out = Vec::new();
    // GetEncoders with a CRC appended (b2 92): answered, then two stray bytes.
    d.on_bytes(&[0x80, 0x4E, 0xB2, 0x92], 0.0, &body, &mut out);
    assert_eq!(out.len(), 10);
    assert_eq!(d.stats().bytes_skipped, 2);
    // A stray CRC byte that looks like an address eats the next packet's
    // first byte; the partial packet then dies in the 10 ms gap.
    out.clear();
    d.on_bytes(&[0x80, 0x5A, 0x81], 0.0, &body, &mut out);
    d.line_silent(0.02);
    d.on_bytes(&[0x80], 0.05, &body, &mut out);
    assert_eq!(d.stats().packets_cut, 1);
    assert_eq!(d.stats().packets_rejected, 0);
}

#[test]
fn a_packet_is_cut_only_by_silence_seen_not_by_bytes_read_late() {
    let body = BodyState::default();
    let stop = encode_command(0x80, &Command::speeds(0, 0));
    let (head, tail) = stop.split_at(2);
    // The emulator read the head, then was kept off the CPU: the tail was
    // waiting when it read again 50 ms later. The host did nothing wrong.
    let mut d = RoboClawDevice::new(0x80, CPM, true).strict(true);
    let mut out = Vec::new();
    d.on_bytes(head, 0.0, &body, &mut out);
    d.line_silent(0.009);
    d.on_bytes(tail, 0.05, &body, &mut out);
    assert_eq!(out, vec![0xFF]);
    assert_eq!((d.stats().packets_cut, d.stats().packets_rejected), (0, 0));
    // Silence seen for longer than the gap: the controller drops the head,
    // and the tail is noise.
    let mut d = RoboClawDevice::new(0x80, CPM, true).strict(true);
    out.clear();
    d.on_bytes(head, 0.0, &body, &mut out);
    d.line_silent(0.011);
    d.on_bytes(tail, 0.05, &body, &mut out);
    assert!(out.is_empty(), "{out:02x?}");
    assert_eq!(d.stats().packets_cut, 1);
}

#[test]
fn speeds_encoders_and_serial_timeout() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let mut body = BodyState::default();
    assert_eq!(
        ask(&mut d, Command::SetSerialTimeout { tenths: 3 }, 0.0, &body),
        Some(Reply::Ack)
    );
    assert_eq!(
        ask(&mut d, q(Query::SerialTimeout), 0.0, &body),
        Some(Reply::U8(3))
    );
    assert_eq!(
        ask(&mut d, Command::speeds(200, -100), 0.0, &body),
        Some(Reply::Ack)
    );
    let mut out = Vec::new();
    let w = d.tick(0.1, &body, &mut out);
    assert_eq!(
        w,
        WheelSpeeds {
            left: 0.2,
            right: -0.1
        }
    );
    body.encoder = (0.5, -0.001);
    d.tick(0.2, &body, &mut out);
    assert_eq!(
        ask(&mut d, q(Query::Encoders), 0.2, &body),
        Some(Reply::Pair32(500, u32::MAX))
    );
    // Silence beyond 0.3 s stops the motors by themselves.
    assert_ne!(d.tick(0.45, &body, &mut out), WheelSpeeds::STOP);
    assert_eq!(d.tick(0.55, &body, &mut out), WheelSpeeds::STOP);
    assert_eq!(d.stats().device_timeouts, 1);
}

#[test]
fn command_40_ramps_at_its_acceleration() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let body = BodyState::default();
    let mut out = Vec::new();
    d.tick(0.0, &body, &mut out);
    let c = Command::speeds_accel(500, 200, 200);
    assert_eq!(ask(&mut d, c, 0.0, &body), Some(Reply::Ack));
    // 500 counts/s² = 0.5 m/s²: 0.05 m/s after 0.1 s, capped at 0.2.
    let w = d.tick(0.1, &body, &mut out);
    assert!((w.left - 0.05).abs() < 1e-12, "{w:?}");
    let w = d.tick(1.0, &body, &mut out);
    assert!((w.left - 0.2).abs() < 1e-12, "{w:?}");
    // Command 37 stops at once.
    assert_eq!(
        ask(&mut d, Command::speeds(0, 0), 1.0, &body),
        Some(Reply::Ack)
    );
    assert_eq!(d.tick(1.01, &body, &mut out), WheelSpeeds::STOP);
}

#[test]
fn counters_and_speeds_stand_still_with_the_wheels() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let mut body = BodyState::default();
    let mut t = 0.0;
    run(&mut d, &mut body, &mut t, 1.0);
    let still = ask(&mut d, q(Query::Encoders), t, &body);
    run(&mut d, &mut body, &mut t, 1.0);
    assert_eq!(ask(&mut d, q(Query::Encoders), t, &body), still);
    assert_eq!(
        ask(&mut d, q(Query::Speeds), t, &body),
        Some(Reply::Pair32(0, 0))
    );
    assert_eq!(
        ask(&mut d, q(Query::Currents), t, &body),
        Some(Reply::Pair16(0, 0))
    );
}

#[test]
fn driving_shows_in_every_read() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let mut body = BodyState::default();
    let mut t = 0.0;
    assert_eq!(
        ask(&mut d, Command::speeds(300, -300), t, &body),
        Some(Reply::Ack)
    );
    run(&mut d, &mut body, &mut t, 2.0);
    let Some(Reply::CountStatus { value, status }) =
        ask(&mut d, q(Query::Encoder(Motor::M2)), t, &body)
    else {
        panic!("no M2 encoder reply");
    };
    assert!((value as i32 + 600).abs() <= 2, "{}", value as i32);
    assert_eq!(status & 0b010, 0b010, "backwards");
    let Some(Reply::CountStatus { value, status }) =
        ask(&mut d, q(Query::Speed(Motor::M1)), t, &body)
    else {
        panic!("no speed reply");
    };
    // Counts arrive whole (1 or 2 per 5 ms step at 300 counts/s): the
    // measured speed is within a few percent.
    assert!(
        (value as i32 - 300).abs() <= 15 && status == 0,
        "{}",
        value as i32
    );
    let Some(Reply::Pair16(p1, p2)) = ask(&mut d, q(Query::Pwms), t, &body) else {
        panic!("no PWM reply");
    };
    // 0.3 m/s of a 1 m/s top speed: 30 % duty, signed.
    assert!(((p1 as i16) as i32 - 9830).abs() < 10 && (p2 as i16) < 0);
    let Some(Reply::Pair16(c1, _)) = ask(&mut d, q(Query::Currents), t, &body) else {
        panic!("no current reply");
    };
    assert!((c1 as i16) > 0, "a turning motor draws current");
    let Some(Reply::U16(before)) = ask(&mut d, q(Query::MainBattery), 0.0, &body) else {
        panic!("no battery reply");
    };
    assert!((99..=127).contains(&before));
    let Some(Reply::U16(temp)) = ask(&mut d, q(Query::Temperature), t, &body) else {
        panic!("no temperature");
    };
    assert!((250..400).contains(&temp), "{temp}");
}

#[test]
fn duty_drives_a_fraction_of_top_speed() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let body = BodyState::default();
    let c = Command::Duties {
        m1: DUTY_MAX / 2,
        m2: -DUTY_MAX,
        accel: None,
    };
    assert_eq!(ask(&mut d, c, 0.0, &body), Some(Reply::Ack));
    let w = d.tick(0.01, &body, &mut Vec::new());
    assert!(
        (w.left - 0.5).abs() < 1e-3 && (w.right + 1.0).abs() < 1e-9,
        "{w:?}"
    );
}

#[test]
fn distance_moves_run_in_order_and_the_buffer_says_so() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let mut body = BodyState::default();
    let mut t = 0.0;
    assert_eq!(
        ask(&mut d, q(Query::Buffers), t, &body),
        Some(Reply::Pair8(BUFFER_EMPTY, BUFFER_EMPTY))
    );
    let go = |distance, buffered| Command::Speed {
        motor: Motor::M1,
        speed: 500,
        accel: None,
        distance: Some(Distance {
            counts: distance,
            buffered,
        }),
    };
    assert_eq!(ask(&mut d, go(100, true), t, &body), Some(Reply::Ack));
    assert_eq!(ask(&mut d, go(150, true), t, &body), Some(Reply::Ack));
    assert_eq!(
        ask(&mut d, q(Query::Buffers), t, &body),
        Some(Reply::Pair8(1, BUFFER_EMPTY))
    );
    run(&mut d, &mut body, &mut t, 1.0);
    let Some(Reply::CountStatus { value, .. }) =
        ask(&mut d, q(Query::Encoder(Motor::M1)), t, &body)
    else {
        panic!("no encoder reply");
    };
    assert!((250..=260).contains(&value), "two moves: {value}");
    assert_eq!(
        ask(&mut d, q(Query::Buffers), t, &body),
        Some(Reply::Pair8(BUFFER_EMPTY, BUFFER_EMPTY))
    );
}

#[test]
fn set_and_reset_encoders_and_pid() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let body = BodyState::default();
    let c = Command::SetEncoder {
        motor: Motor::M2,
        count: 1234,
    };
    assert_eq!(ask(&mut d, c, 0.0, &body), Some(Reply::Ack));
    assert_eq!(
        ask(&mut d, q(Query::Encoders), 0.0, &body),
        Some(Reply::Pair32(0, 1234))
    );
    assert_eq!(
        ask(&mut d, Command::ResetEncoders, 0.0, &body),
        Some(Reply::Ack)
    );
    assert_eq!(
        ask(&mut d, q(Query::Encoders), 0.0, &body),
        Some(Reply::Pair32(0, 0))
    );
    let pid = VelocityPid {
        p: 1,
        i: 2,
        d: 3,
        qpps: 4,
    };
    let c = Command::SetVelocityPid {
        motor: Motor::M1,
        pid,
    };
    assert_eq!(ask(&mut d, c, 0.0, &body), Some(Reply::Ack));
    assert_eq!(
        ask(&mut d, q(Query::VelocityPid(Motor::M1)), 0.0, &body),
        Some(Reply::Quad32([1, 2, 3, 4]))
    );
}

#[test]
fn bad_crc_gets_no_reply_and_is_counted() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let mut p = encode_command(0x80, &Command::speeds(1, 1));
    p[4] ^= 0x10;
    let mut out = Vec::new();
    d.on_bytes(&p, 0.0, &BodyState::default(), &mut out);
    assert!(out.is_empty());
    assert_eq!(d.stats().packets_rejected, 1);
    assert_eq!(
        d.tick(0.0, &BodyState::default(), &mut out),
        WheelSpeeds::STOP
    );
}

#[test]
fn strict_mode_refuses_a_buffer_flag_the_manual_does_not_define() {
    let mut p = encode_command(
        0x80,
        &Command::Speed {
            motor: Motor::M1,
            speed: 10,
            accel: None,
            distance: Some(Distance {
                counts: 5,
                buffered: false,
            }),
        },
    );
    // Buffer argument 2, CRC made right again.
    let n = p.len();
    p[n - 3] = 2;
    let mut c = crate::motor::crc16::Crc16::new();
    c.extend(&p[..n - 2]);
    p[n - 2..].copy_from_slice(&c.value().to_be_bytes());
    let body = BodyState::default();
    for (strict, answered) in [(false, true), (true, false)] {
        let mut d = RoboClawDevice::new(0x80, CPM, true).strict(strict);
        let mut out = Vec::new();
        d.on_bytes(&p, 0.0, &body, &mut out);
        assert_eq!(out == [0xFF], answered, "strict {strict}");
        assert_eq!(d.stats().packets_rejected, u64::from(strict));
    }
}

#[test]
fn bumper_sets_the_estop_status_bit() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let mut body = BodyState::default();
    assert_eq!(
        ask(&mut d, q(Query::Status), 0.0, &body),
        Some(Reply::U32(0))
    );
    body.bumper.left = true;
    assert_eq!(
        ask(&mut d, q(Query::Status), 0.0, &body),
        Some(Reply::U32(STATUS_ESTOP))
    );
}

#[test]
fn every_query_is_answered_with_its_layout() {
    let mut d = RoboClawDevice::new(0x80, CPM, true);
    let body = BodyState::default();
    for code in 0..=255u8 {
        let Some(query) = Query::from_code(code) else {
            continue;
        };
        let r = ask(&mut d, q(query), 0.0, &body);
        assert!(r.is_some(), "query {code} unanswered");
    }
}

proptest::proptest! {
    /// Any bytes, in any chunks, at any times: the controller answers what
    /// it answers and never panics, strict or not, whatever its wheels do.
    #[test]
    fn garbage_never_panics(
        chunks in proptest::collection::vec(proptest::collection::vec(proptest::prelude::any::<u8>(), 0..40), 0..40),
        strict in proptest::prelude::any::<bool>(),
        travel in -1e4f64..1e4,
    ) {
        let mut d = RoboClawDevice::new(0x80, CPM, true).strict(strict);
        let mut out = Vec::new();
        let mut t = 0.0;
        for (i, c) in chunks.iter().enumerate() {
            t += 0.003 * (i % 7) as f64;
            let body = BodyState {
                encoder: (travel * i as f64, -travel),
                ..BodyState::default()
            };
            d.on_bytes(c, t, &body, &mut out);
            d.tick(t, &body, &mut out);
        }
    }
}
