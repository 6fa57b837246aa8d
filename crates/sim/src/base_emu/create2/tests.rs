//! The emulated Create 2 against the OI specification.

use super::*;
use crate::motor::create2::codec::{encode, response_size, Notes, StreamParser};
use crate::motor::Sides;

const CPM: f64 = 2250.0;
const BASE: f64 = 0.235;

fn device() -> Create2Device {
    Create2Device::new(CPM, BASE, true)
}

fn send(d: &mut Create2Device, c: OiCommand, now: f64, out: &mut Vec<u8>) {
    d.on_bytes(&encode(&c), now, &BodyState::default(), out);
}

/// A device started in `mode` (Passive, Safe or Full), no rejections yet.
fn started(mode: OiMode) -> Create2Device {
    let mut d = device();
    let mut out = Vec::new();
    send(&mut d, OiCommand::Start, 0.0, &mut out);
    match mode {
        OiMode::Safe => send(&mut d, OiCommand::Safe, 0.0, &mut out),
        OiMode::Full => send(&mut d, OiCommand::Full, 0.0, &mut out),
        _ => {}
    }
    assert_eq!(d.mode(), mode);
    d
}

fn speeds(d: &mut Create2Device) -> WheelSpeeds {
    d.tick(0.0, &BodyState::default(), &mut Vec::new())
}

fn query(d: &mut Create2Device, id: u8, body: &BodyState) -> Vec<u8> {
    let mut out = Vec::new();
    d.on_bytes(&encode(&OiCommand::Sensors(id)), 0.0, body, &mut out);
    out
}

fn word(b: &[u8]) -> i16 {
    i16::from_be_bytes([b[0], b[1]])
}

/// A body that moved its wheels by `l`, `r` metres.
fn moved(l: f64, r: f64) -> BodyState {
    BodyState {
        encoder: (l, r),
        wheels: WheelSpeeds {
            left: 0.1,
            right: 0.1,
        },
        ..BodyState::default()
    }
}

#[test]
fn drive_needs_safe_or_full_mode_and_refusals_are_counted() {
    let mut d = device();
    let mut out = Vec::new();
    send(&mut d, OiCommand::drive_direct(0.1, 0.2), 0.0, &mut out);
    assert_eq!(speeds(&mut d), WheelSpeeds::STOP);
    send(&mut d, OiCommand::Start, 0.0, &mut out);
    send(&mut d, OiCommand::drive_direct(0.1, 0.2), 0.0, &mut out);
    assert_eq!(speeds(&mut d), WheelSpeeds::STOP);
    assert_eq!(d.stats().packets_rejected, 2);
    send(&mut d, OiCommand::Safe, 0.0, &mut out);
    send(&mut d, OiCommand::drive_direct(0.1, 0.2), 0.0, &mut out);
    let want = WheelSpeeds {
        left: 0.1,
        right: 0.2,
    };
    assert_eq!(speeds(&mut d), want);
    assert_eq!(d.stats().packets_rejected, 2);
}

#[test]
fn song_with_high_data_bytes_then_drive_direct_drives_straight() {
    // pycreate2's createSong(0, [60, 145]) then drive_direct(100, 100): the
    // duration 145 is Drive Direct's opcode, and must stay a data byte.
    let mut d = started(OiMode::Safe);
    let mut bytes = vec![140, 0, 1, 60, 145];
    bytes.extend_from_slice(&[145, 0, 100, 0, 100]);
    d.on_bytes(&bytes, 0.0, &BodyState::default(), &mut Vec::new());
    let w = speeds(&mut d);
    assert_eq!(
        w,
        WheelSpeeds {
            left: 0.1,
            right: 0.1
        }
    );
    assert_eq!(d.stats().packets_rejected, 0);
    assert_eq!(d.stats().packets_ok, 4);
}

#[test]
fn leds_with_0x80_data_do_not_change_the_mode() {
    for mode in [OiMode::Safe, OiMode::Full] {
        let mut d = started(mode);
        // led(0, 128, 255): 0x80 is Start's opcode, as a data byte here.
        d.on_bytes(
            &[139, 0, 128, 255],
            0.0,
            &BodyState::default(),
            &mut Vec::new(),
        );
        assert_eq!(d.mode(), mode);
        d.on_bytes(
            &[164, 72, 73, 32, 32],
            0.0,
            &BodyState::default(),
            &mut Vec::new(),
        );
        assert_eq!(d.mode(), mode);
        assert_eq!(d.stats().packets_rejected, 0);
    }
}

#[test]
fn every_packet_and_group_is_answered_with_its_size() {
    let mut d = started(OiMode::Passive);
    let ids = (0..=58u8).chain([100, 101, 106, 107]);
    for id in ids {
        let r = query(&mut d, id, &BodyState::default());
        assert_eq!(Some(r.len()), response_size(id), "packet {id}");
    }
    assert_eq!(query(&mut d, 100, &BodyState::default()).len(), 80);
    assert_eq!(d.stats().packets_rejected, 0);
    // Undefined ids are refused and counted.
    for id in [59u8, 99, 102, 105, 108, 255] {
        assert!(query(&mut d, id, &BodyState::default()).is_empty());
    }
    assert_eq!(d.stats().packets_rejected, 6);
}

#[test]
fn bumps_and_wheel_drops_use_the_specifications_bit_order() {
    let mut d = started(OiMode::Full);
    let body = BodyState {
        bumper: Sides {
            left: false,
            right: true,
        },
        wheel_drop: Sides {
            left: true,
            right: false,
        },
        ..BodyState::default()
    };
    // Bit 0 bump right, bit 3 wheel drop left.
    assert_eq!(query(&mut d, 7, &body), vec![0b1001]);
    // Group 100 starts with packet 7.
    assert_eq!(query(&mut d, 100, &body)[0], 0b1001);
}

#[test]
fn distance_and_angle_count_since_last_read_and_reset() {
    let mut d = started(OiMode::Passive);
    let body = moved(0.5, 0.5);
    assert_eq!(word(&query(&mut d, 19, &body)), 500);
    assert_eq!(word(&query(&mut d, 19, &body)), 0);
    // A quarter turn counter-clockwise: the right wheel ahead by base * pi/2.
    let arc = BASE * std::f64::consts::FRAC_PI_2;
    let body = moved(0.5 - arc / 2.0, 0.5 + arc / 2.0);
    let g2 = query(&mut d, 2, &body);
    // Group 2: 17, 18, 19 (distance), 20 (angle).
    assert_eq!(word(&g2[2..4]), 0);
    assert_eq!(word(&g2[4..6]), 90);
    assert_eq!(word(&query(&mut d, 20, &body)), 0);
    // Backwards and clockwise are negative.
    let body = moved(0.4 - arc / 2.0, 0.4 + arc / 2.0);
    assert_eq!(word(&query(&mut d, 19, &body)), -100);
}

#[test]
fn encoders_count_only_while_the_wheels_turn() {
    let mut d = started(OiMode::Passive);
    let mut body = moved(0.1, 0.2);
    d.tick(0.0, &body, &mut Vec::new());
    let q = query(&mut d, 101, &body);
    let (l, r) = (word(&q[0..2]) as u16, word(&q[2..4]) as u16);
    assert_eq!((l, r), (225, 450));
    // Standing still: the body's encoder noise is no wheel motion.
    body.wheels = WheelSpeeds::STOP;
    d.tick(0.1, &body, &mut Vec::new());
    body.encoder = (0.1001, 0.1999);
    d.tick(0.2, &body, &mut Vec::new());
    let q = query(&mut d, 101, &body);
    assert_eq!((word(&q[0..2]) as u16, word(&q[2..4]) as u16), (225, 450));
    // Backwards past zero wraps.
    body.wheels = WheelSpeeds {
        left: -0.1,
        right: -0.1,
    };
    body.encoder = (0.0, -0.1);
    d.tick(0.3, &body, &mut Vec::new());
    let q = query(&mut d, 101, &body);
    assert_eq!(word(&q[0..2]) as u16, 0);
    assert_eq!(word(&q[2..4]) as u16, 225u16.wrapping_neg());
}

#[test]
fn requested_velocities_follow_the_last_drive_command() {
    let mut d = started(OiMode::Safe);
    let mut out = Vec::new();
    send(
        &mut d,
        OiCommand::DriveDirect {
            right: 200,
            left: 100,
        },
        0.0,
        &mut out,
    );
    let g5 = query(&mut d, 5, &BodyState::default());
    // Group 5: 35 mode, 36 song, 37 playing, 38 stream count, 39-42.
    assert_eq!(g5[0], 2);
    assert_eq!(word(&g5[4..6]), 150);
    assert_eq!(word(&g5[8..10]), 200);
    assert_eq!(word(&g5[10..12]), 100);
    send(
        &mut d,
        OiCommand::Drive {
            velocity: -200,
            radius: 500,
        },
        0.0,
        &mut out,
    );
    let g5 = query(&mut d, 5, &BodyState::default());
    assert_eq!(word(&g5[4..6]), -200);
    assert_eq!(word(&g5[6..8]), 500);
    let w = speeds(&mut d);
    assert!(w.right < w.left && w.left < 0.0, "{w:?}");
    // Drive PWM is obeyed too.
    send(
        &mut d,
        OiCommand::DrivePwm {
            right: 255,
            left: 255,
        },
        0.0,
        &mut out,
    );
    assert_eq!(
        speeds(&mut d),
        WheelSpeeds {
            left: 0.5,
            right: 0.5
        }
    );
}

#[test]
fn mode_transitions_follow_the_specification() {
    let mut out = Vec::new();
    for c in [
        OiCommand::Power,
        OiCommand::Spot,
        OiCommand::Clean,
        OiCommand::Max,
        OiCommand::SeekDock,
    ] {
        let mut d = started(OiMode::Full);
        send(&mut d, OiCommand::drive_direct(0.1, 0.1), 0.0, &mut out);
        send(&mut d, c.clone(), 0.0, &mut out);
        assert_eq!(d.mode(), OiMode::Passive, "{c:?}");
        assert_eq!(speeds(&mut d), WheelSpeeds::STOP, "{c:?}");
    }
    let mut d = started(OiMode::Safe);
    send(&mut d, OiCommand::Control, 0.0, &mut out);
    assert_eq!(d.mode(), OiMode::Safe);
    send(&mut d, OiCommand::Full, 0.0, &mut out);
    send(&mut d, OiCommand::Start, 0.0, &mut out);
    assert_eq!(d.mode(), OiMode::Passive);
    // Stop: Off, and no more answers until Start.
    send(&mut d, OiCommand::Stop, 0.0, &mut out);
    assert_eq!(d.mode(), OiMode::Off);
    out.clear();
    assert!(query(&mut d, 35, &BodyState::default()).is_empty());
    send(&mut d, OiCommand::Safe, 0.0, &mut out);
    assert_eq!(d.mode(), OiMode::Off);
    send(&mut d, OiCommand::Start, 0.0, &mut out);
    assert_eq!(query(&mut d, 35, &BodyState::default()), vec![1]);
    // Reset: Off, with the boot message.
    out.clear();
    send(&mut d, OiCommand::Reset, 0.0, &mut out);
    assert_eq!(d.mode(), OiMode::Off);
    assert_eq!(out, RESET_MESSAGE);
}

#[test]
fn wheel_drop_or_cliff_in_safe_mode_drops_to_passive() {
    let mut d = started(OiMode::Safe);
    let mut out = Vec::new();
    send(&mut d, OiCommand::drive_direct(0.1, 0.1), 0.0, &mut out);
    let mut body = BodyState::default();
    body.wheel_drop.left = true;
    assert_eq!(d.tick(0.1, &body, &mut out), WheelSpeeds::STOP);
    assert_eq!(d.mode(), OiMode::Passive);
    let mut d = started(OiMode::Safe);
    send(&mut d, OiCommand::drive_direct(0.1, 0.1), 0.0, &mut out);
    let body = BodyState {
        cliff: [false, true, false, false],
        ..BodyState::default()
    };
    assert_eq!(d.tick(0.1, &body, &mut out), WheelSpeeds::STOP);
    assert_eq!(d.mode(), OiMode::Passive);
    assert_eq!(query(&mut d, 10, &body), vec![1]);
}

#[test]
fn full_mode_has_no_reflex() {
    let mut d = started(OiMode::Full);
    let mut out = Vec::new();
    send(&mut d, OiCommand::drive_direct(0.1, 0.1), 0.0, &mut out);
    let body = BodyState {
        wheel_drop: Sides {
            left: true,
            right: true,
        },
        cliff: [true; 4],
        ..BodyState::default()
    };
    let w = d.tick(0.1, &body, &mut out);
    assert_eq!(
        w,
        WheelSpeeds {
            left: 0.1,
            right: 0.1
        }
    );
    assert_eq!(d.mode(), OiMode::Full);
}

#[test]
fn strict_mode_refuses_out_of_range_values_lenient_clamps_both_count() {
    for strict in [true, false] {
        let mut d = Create2Device::new(CPM, BASE, strict);
        let mut out = Vec::new();
        send(&mut d, OiCommand::Start, 0.0, &mut out);
        send(&mut d, OiCommand::Full, 0.0, &mut out);
        send(
            &mut d,
            OiCommand::DriveDirect {
                right: 600,
                left: 100,
            },
            0.0,
            &mut out,
        );
        let want = if strict {
            WheelSpeeds::STOP
        } else {
            WheelSpeeds {
                left: 0.1,
                right: 0.5,
            }
        };
        assert_eq!(speeds(&mut d), want, "strict {strict}");
        assert_eq!(d.stats().packets_rejected, 1);
        // An unknown opcode costs one byte and is counted.
        d.on_bytes(&[200, 131], 0.0, &BodyState::default(), &mut out);
        assert_eq!(d.mode(), OiMode::Safe);
        assert_eq!(d.stats().packets_rejected, 2);
        assert_eq!(d.stats().bytes_skipped, 1);
    }
}

#[test]
fn query_list_and_stream_carry_groups() {
    let mut d = started(OiMode::Passive);
    let mut ids = PacketIds::new();
    ids.extend_from_slice(&[35, 106, 43]).unwrap();
    let mut out = Vec::new();
    let body = moved(0.258 / CPM * 1000.0, 0.0);
    d.on_bytes(&encode(&OiCommand::QueryList(ids)), 0.0, &body, &mut out);
    // Mode 1 (Passive), group 106 (12 zero bytes), left encoder 258.
    assert_eq!(out.len(), 1 + 12 + 2);
    assert_eq!(out[0], 1);
    assert_eq!(&out[13..], &[0x01, 0x02]);
    let mut ids = PacketIds::new();
    ids.extend_from_slice(&[100]).unwrap();
    out.clear();
    send(&mut d, OiCommand::Stream(ids), 0.0, &mut out);
    d.tick(0.0, &body, &mut out);
    assert_eq!(out.len(), 3 + 81);
    let mut frames = Vec::new();
    StreamParser::new().feed(&out, &mut |r| frames.push(r));
    assert_eq!(frames.len(), 1);
    let f = frames[0].unwrap();
    assert_eq!(f.oi_mode, Some(1));
    assert_eq!(f.left_encoder, Some(258));
}

#[test]
fn stream_every_15_ms_with_pause_and_resume() {
    let mut d = started(OiMode::Passive);
    let mut out = Vec::new();
    let mut ids = PacketIds::new();
    ids.extend_from_slice(&[7, 43, 44]).unwrap();
    send(&mut d, OiCommand::Stream(ids), 0.0, &mut out);
    let body = moved(1.0, -1.0);
    let mut t = 0.0;
    while t < 0.15 - 1e-9 {
        d.tick(t, &body, &mut out);
        t += 0.001;
    }
    let mut frames = Vec::new();
    StreamParser::new().feed(&out, &mut |r| frames.push(r.unwrap()));
    assert_eq!(frames.len(), 10);
    assert_eq!(frames[0].left_encoder, Some(2250));
    assert_eq!(frames[0].right_encoder, Some(2250u16.wrapping_neg()));
    out.clear();
    send(&mut d, OiCommand::StreamEnable(false), t, &mut out);
    d.tick(t + 0.1, &body, &mut out);
    assert!(out.is_empty());
    send(&mut d, OiCommand::StreamEnable(true), t + 0.1, &mut out);
    d.tick(t + 0.1, &body, &mut out);
    assert!(!out.is_empty());
}

#[test]
fn battery_drains_with_use_and_songs_play() {
    let mut d = started(OiMode::Full);
    let mut out = Vec::new();
    let g3 = |d: &mut Create2Device| query(d, 3, &BodyState::default());
    let before = g3(&mut d);
    // Group 3: 21 state, 22 voltage, 23 current, 24 temperature, 25, 26.
    assert_eq!(word(&before[8..10]) as u16, 3000);
    assert!(word(&before[3..5]) < 0, "discharging");
    let body = moved(0.0, 0.0);
    let mut t = 0.0;
    while t < 120.0 {
        d.tick(t, &body, &mut out);
        t += 0.5;
    }
    let after = g3(&mut d);
    assert!(word(&after[6..8]) < word(&before[6..8]) - 5, "{after:?}");
    let mut notes = Notes::new();
    notes.extend_from_slice(&[60, 64]).unwrap();
    send(&mut d, OiCommand::Song { number: 2, notes }, t, &mut out);
    send(&mut d, OiCommand::Play(2), t, &mut out);
    let g5 = query(&mut d, 5, &BodyState::default());
    assert_eq!(&g5[1..3], &[2, 1]);
    assert_eq!(d.stats().packets_rejected, 0);
}

proptest::proptest! {
    /// Any bytes, in any chunks: the robot answers what it answers and
    /// never panics, strict or not.
    #[test]
    fn garbage_never_panics(
        chunks in proptest::collection::vec(proptest::collection::vec(proptest::prelude::any::<u8>(), 0..40), 0..40),
        strict in proptest::prelude::any::<bool>(),
    ) {
        let mut d = Create2Device::new(CPM, BASE, strict);
        let mut out = Vec::new();
        let mut t = 0.0;
        for c in &chunks {
            t += 0.004;
            d.on_bytes(c, t, &BodyState::default(), &mut out);
            d.tick(t, &BodyState::default(), &mut out);
        }
    }
}
