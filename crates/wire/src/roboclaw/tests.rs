//! Wire tests for the RoboClaw codec. Byte fixtures follow the manual's packet
//! layouts; their CRCs were computed independently (Python's
//! `binascii.crc_hqx(data, 0)`, the same CRC-16/XMODEM).

use super::*;
use proptest::prelude::*;

fn decode_all(dec: &mut ReplyDecoder, bytes: &[u8]) -> Vec<Result<Option<Reply>, ReplyError>> {
    bytes.iter().map(|&b| dec.push(b)).collect()
}

#[test]
fn set_serial_timeout_bytes() {
    let p = encode_command(0x80, &Command::SetSerialTimeout { tenths: 5 });
    assert_eq!(&p[..], &[0x80, 0x0E, 0x05, 0x48, 0xF0]);
}

#[test]
fn drive_speeds_bytes_signed_big_endian() {
    let p = encode_command(0x80, &Command::speeds(1000, -1000));
    assert_eq!(
        &p[..],
        &[0x80, 0x25, 0x00, 0x00, 0x03, 0xE8, 0xFF, 0xFF, 0xFC, 0x18, 0x82, 0x90]
    );
}

#[test]
fn drive_speeds_with_acceleration_bytes() {
    let p = encode_command(0x80, &Command::speeds_accel(5000, 1000, -1000));
    assert_eq!(
        &p[..],
        &[
            0x80, 0x28, 0x00, 0x00, 0x13, 0x88, 0x00, 0x00, 0x03, 0xE8, 0xFF, 0xFF, 0xFC, 0x18,
            0x74, 0xCC
        ]
    );
}

#[test]
fn read_commands_are_address_and_command_alone() {
    // The manual: "Send: [Address, 78]"; no CRC goes with a read.
    assert_eq!(
        &encode_command(0x80, &Command::Query(Query::Encoders))[..],
        &[0x80, 0x4E]
    );
    assert_eq!(
        &encode_command(0x80, &Command::Query(Query::Status))[..],
        &[0x80, 0x5A]
    );
    assert_eq!(
        &encode_command(0x81, &Command::ResetEncoders)[..],
        &[0x81, 0x14, 0x7A, 0x1C]
    );
}

#[test]
fn encoder_reply_crc_covers_sent_address_and_command() {
    let mut d = ReplyDecoder::new(0x80, &Command::Query(Query::Encoders));
    let bytes = [0x12, 0x34, 0x56, 0x78, 0xFF, 0xFF, 0xFF, 0xF0, 0x68, 0x3D];
    let r = decode_all(&mut d, &bytes);
    assert!(r[..9].iter().all(|x| matches!(x, Ok(None))));
    assert_eq!(r[9], Ok(Some(Reply::Pair32(0x1234_5678, 0xFFFF_FFF0))));
    // The same data with a CRC computed over the data alone (the classic
    // implementation bug) is rejected.
    let mut d = ReplyDecoder::new(0x80, &Command::Query(Query::Encoders));
    let mut wrong = bytes;
    let c = crate::crc16::crc16(&bytes[..8]).to_be_bytes();
    wrong[8] = c[0];
    wrong[9] = c[1];
    let r = decode_all(&mut d, &wrong);
    assert!(matches!(r[9], Err(ReplyError::Crc { .. })));
}

#[test]
fn status_battery_and_version_replies() {
    let mut d = ReplyDecoder::new(0x80, &Command::Query(Query::Status));
    let r = decode_all(&mut d, &[0, 0, 0, 1, 0x97, 0x9D]);
    assert_eq!(r[5], Ok(Some(Reply::U32(STATUS_ESTOP))));

    let mut d = ReplyDecoder::new(0x80, &Command::Query(Query::MainBattery));
    let r = decode_all(&mut d, &[0x00, 0x78, 0xC8, 0x65]);
    assert_eq!(r[3], Ok(Some(Reply::U16(120))));

    let mut d = ReplyDecoder::new(0x80, &Command::Query(Query::Version));
    let mut bytes = b"USB Roboclaw 2x7a v4.1.34\n\0".to_vec();
    bytes.extend_from_slice(&[0x0B, 0xF6]);
    let r = decode_all(&mut d, &bytes);
    assert!(r[..bytes.len() - 1].iter().all(|x| matches!(x, Ok(None))));
    match &r[bytes.len() - 1] {
        Ok(Some(Reply::Version(v))) => assert_eq!(&v[..], b"USB Roboclaw 2x7a v4.1.34"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn ack_and_nack() {
    let mut d = ReplyDecoder::new(0x80, &Command::speeds(0, 0));
    assert_eq!(d.push(0xFF), Ok(Some(Reply::Ack)));
    assert_eq!(d.push(0x00), Err(ReplyError::NotAck(0x00)));
}

#[test]
fn corrupted_reply_is_rejected_for_every_single_bit_flip() {
    let good = encode_reply(0x80, cmd::READ_ENCODERS, &Reply::Pair32(7, 9));
    for i in 0..good.len() {
        for bit in 0..8 {
            let mut bad = good.clone();
            bad[i] ^= 1 << bit;
            let mut d = ReplyDecoder::new(0x80, &Command::Query(Query::Encoders));
            let last = decode_all(&mut d, &bad).pop().unwrap();
            assert!(
                matches!(last, Err(ReplyError::Crc { .. })),
                "byte {i} bit {bit}"
            );
        }
    }
}

#[test]
fn version_without_terminator_is_too_long() {
    let mut d = ReplyDecoder::new(0x80, &Command::Query(Query::Version));
    let r = decode_all(&mut d, &[b'x'; 60]);
    assert!(r.contains(&Err(ReplyError::TooLong)));
}

#[test]
fn device_decoder_round_trips_every_command() {
    let all = [
        Command::SetSerialTimeout { tenths: 3 },
        Command::ResetEncoders,
        Command::Query(Query::Version),
        Command::Query(Query::MainBattery),
        Command::speeds(-5, i32::MAX),
        Command::Query(Query::Encoders),
        Command::Query(Query::Status),
    ];
    let mut dec = CommandDecoder::new();
    for c in all {
        let p = encode_command(0x82, &c);
        let mut out = None;
        for (i, &b) in p.iter().enumerate() {
            let r = dec.push(b);
            if i + 1 < p.len() {
                assert!(r.is_none());
            } else {
                out = r;
            }
        }
        assert_eq!(out, Some(Ok((0x82, c))));
    }
}

#[test]
fn device_decoder_skips_garbage_and_rejects_bad_crc() {
    let mut dec = CommandDecoder::new();
    for b in [0x00, 0x13, 0x7F, 0xFF] {
        assert!(dec.push(b).is_none());
    }
    assert_eq!(dec.skipped, 4);
    let mut p = encode_command(0x80, &Command::SetSerialTimeout { tenths: 2 });
    p[3] ^= 0x01;
    let r: Vec<_> = p.iter().filter_map(|&b| dec.push(b)).collect();
    assert!(matches!(r[..], [Err(FrameError::Crc { .. })]));
    // Unknown command number.
    dec.push(0x80);
    assert_eq!(dec.push(200), Some(Err(FrameError::UnknownCommand(200))));
    // And the decoder still works afterwards.
    let p = encode_command(0x80, &Command::Query(Query::Encoders));
    let r: Vec<_> = p.iter().filter_map(|&b| dec.push(b)).collect();
    assert_eq!(r, vec![Ok((0x80, Command::Query(Query::Encoders)))]);
}

#[test]
fn device_replies_decode_on_host() {
    for (c, reply) in [
        (Command::Query(Query::Encoders), Reply::Pair32(u32::MAX, 0)),
        (Command::Query(Query::Status), Reply::U32(0xDEAD_BEEF)),
        (Command::Query(Query::MainBattery), Reply::U16(241)),
    ] {
        let bytes = encode_reply(0x80, c.code(), &reply);
        let mut d = ReplyDecoder::new(0x80, &c);
        assert_eq!(decode_all(&mut d, &bytes).pop().unwrap(), Ok(Some(reply)));
    }
}

proptest! {
    #[test]
    fn reply_decoder_never_panics(code in any::<u8>(), bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let c = Query::from_code(code).map_or(Command::speeds(0, 0), Command::Query);
        let mut d = ReplyDecoder::new(0x80, &c);
        for b in bytes {
            let _ = d.push(b);
        }
    }

    #[test]
    fn command_decoder_never_panics_and_resyncs(noise in proptest::collection::vec(any::<u8>(), 0..200), m1 in any::<i32>(), m2 in any::<i32>()) {
        let mut dec = CommandDecoder::new();
        for b in &noise {
            let _ = dec.push(*b);
        }
        // After noise and a reset (the controller's inter-packet gap), a valid packet decodes.
        dec.reset();
        let p = encode_command(0x80, &Command::speeds(m1, m2));
        let r: Vec<_> = p.iter().filter_map(|&b| dec.push(b)).collect();
        prop_assert_eq!(r, vec![Ok((0x80, Command::speeds(m1, m2)))]);
    }
}

/// One command of every write layout, for the round-trip tests.
fn every_write() -> Vec<Command> {
    let d = |counts, buffered| Some(Distance { counts, buffered });
    let mut v = vec![
        Command::SetSerialTimeout { tenths: 3 },
        Command::ResetEncoders,
        Command::Duties {
            m1: -3,
            m2: DUTY_MAX,
            accel: None,
        },
        Command::Duties {
            m1: 7,
            m2: -DUTY_MAX,
            accel: Some((9, 10)),
        },
    ];
    for motor in [Motor::M1, Motor::M2] {
        v.push(Command::SetEncoder { motor, count: 77 });
        v.push(Command::SetVelocityPid {
            motor,
            pid: VelocityPid {
                p: 1,
                i: 2,
                d: 3,
                qpps: 4,
            },
        });
        for accel in [None, Some(99)] {
            v.push(Command::Duty {
                motor,
                duty: -1234,
                accel,
            });
            for distance in [None, d(5, true), d(6, false)] {
                v.push(Command::Speed {
                    motor,
                    speed: -42,
                    accel,
                    distance,
                });
            }
        }
    }
    for accel in [Accel::None, Accel::Both(11), Accel::Each(12, 13)] {
        for distance in [None, Some((1, 2, true)), Some((3, 4, false))] {
            v.push(Command::Speeds {
                m1: -8,
                m2: 9,
                accel,
                distance,
            });
        }
    }
    v
}

#[test]
fn every_write_has_the_manuals_length_and_round_trips() {
    let mut codes = std::collections::BTreeSet::new();
    for c in every_write() {
        let p = encode_command(0x80, &c);
        assert_eq!(p.len(), 2 + write_len(c.code()).unwrap() + 2, "{c:?}");
        let mut dec = CommandDecoder::strict();
        let r: Vec<_> = p.iter().filter_map(|&b| dec.push(b)).collect();
        assert_eq!(r, vec![Ok((0x80, c))]);
        codes.insert(c.code());
    }
    // 14, 20, 22/23, 28/29, 32-46, 50-54: 26 write commands.
    assert_eq!(codes.len(), 26, "{codes:?}");
}

#[test]
fn speed_accel_distance_bytes_follow_the_manual() {
    // 46: [Accel(4), Speed1(4), Distance1(4), Speed2(4), Distance2(4), Buffer, CRC(2)].
    let c = Command::Speeds {
        m1: 1,
        m2: -1,
        accel: Accel::Both(2),
        distance: Some((3, 4, false)),
    };
    let p = encode_command(0x80, &c);
    assert_eq!(
        &p[..23],
        &[0x80, 46, 0, 0, 0, 2, 0, 0, 0, 1, 0, 0, 0, 3, 0xFF, 0xFF, 0xFF, 0xFF, 0, 0, 0, 4, 1]
    );
    assert_eq!(p.len(), 25);
}

#[test]
fn every_query_has_one_code_and_decodes_its_layout() {
    for code in 0..=255u8 {
        let Some(q) = Query::from_code(code) else {
            continue;
        };
        assert_eq!(q.code(), code);
        assert!(write_len(code).is_none(), "{code} both read and write");
        let data: Vec<u8> = match q.layout().data_len() {
            Some(n) => (0..n as u8).collect(),
            None => b"v1\n\0".to_vec(),
        };
        let mut bytes = data.clone();
        let mut c = crate::crc16::Crc16::new();
        c.push(0x80);
        c.push(code);
        c.extend(&data);
        bytes.extend_from_slice(&c.value().to_be_bytes());
        let mut d = ReplyDecoder::new(0x80, &Command::Query(q));
        let last = decode_all(&mut d, &bytes).pop().unwrap();
        let reply = last.unwrap().unwrap();
        assert_eq!(&encode_reply(0x80, code, &reply)[..], &bytes[..], "{q:?}");
    }
}

#[test]
fn strict_decoder_refuses_values_outside_the_manual() {
    let p = encode_command(
        0x80,
        &Command::Duty {
            motor: Motor::M1,
            duty: i16::MIN,
            accel: None,
        },
    );
    let mut dec = CommandDecoder::strict();
    let r: Vec<_> = p.iter().filter_map(|&b| dec.push(b)).collect();
    assert_eq!(r, vec![Err(FrameError::OutsideManual(cmd::DUTY_M1))]);
    let mut dec = CommandDecoder::new();
    let r: Vec<_> = p.iter().filter_map(|&b| dec.push(b)).collect();
    assert_eq!(r.len(), 1);
    assert!(r[0].is_ok());
}
