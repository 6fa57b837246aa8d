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
    let p = encode_command(
        0x80,
        &Command::DriveSpeeds {
            m1: 1000,
            m2: -1000,
        },
    );
    assert_eq!(
        &p[..],
        &[0x80, 0x25, 0x00, 0x00, 0x03, 0xE8, 0xFF, 0xFF, 0xFC, 0x18, 0x82, 0x90]
    );
}

#[test]
fn drive_speeds_with_acceleration_bytes() {
    let p = encode_command(
        0x80,
        &Command::DriveSpeedsAccel {
            accel: 5000,
            m1: 1000,
            m2: -1000,
        },
    );
    assert_eq!(
        &p[..],
        &[
            0x80, 0x28, 0x00, 0x00, 0x13, 0x88, 0x00, 0x00, 0x03, 0xE8, 0xFF, 0xFF, 0xFC, 0x18,
            0x74, 0xCC
        ]
    );
}

#[test]
fn read_commands_bytes() {
    assert_eq!(
        &encode_command(0x80, &Command::ReadEncoders)[..],
        &[0x80, 0x4E, 0xB2, 0x92]
    );
    assert_eq!(
        &encode_command(0x80, &Command::ReadStatus)[..],
        &[0x80, 0x5A, 0xE0, 0x27]
    );
    assert_eq!(
        &encode_command(0x81, &Command::ResetEncoders)[..],
        &[0x81, 0x14, 0x7A, 0x1C]
    );
}

#[test]
fn encoder_reply_crc_covers_sent_address_and_command() {
    let mut d = ReplyDecoder::new(0x80, &Command::ReadEncoders);
    let bytes = [0x12, 0x34, 0x56, 0x78, 0xFF, 0xFF, 0xFF, 0xF0, 0x68, 0x3D];
    let r = decode_all(&mut d, &bytes);
    assert!(r[..9].iter().all(|x| matches!(x, Ok(None))));
    assert_eq!(
        r[9],
        Ok(Some(Reply::Encoders {
            m1: 0x1234_5678,
            m2: 0xFFFF_FFF0
        }))
    );
    // The same data with a CRC computed over the data alone (the classic
    // implementation bug) is rejected.
    let mut d = ReplyDecoder::new(0x80, &Command::ReadEncoders);
    let mut wrong = bytes;
    let c = crate::motor::crc16::crc16(&bytes[..8]).to_be_bytes();
    wrong[8] = c[0];
    wrong[9] = c[1];
    let r = decode_all(&mut d, &wrong);
    assert!(matches!(r[9], Err(ReplyError::Crc { .. })));
}

#[test]
fn status_battery_and_version_replies() {
    let mut d = ReplyDecoder::new(0x80, &Command::ReadStatus);
    let r = decode_all(&mut d, &[0, 0, 0, 1, 0x97, 0x9D]);
    assert_eq!(r[5], Ok(Some(Reply::Status(STATUS_ESTOP))));

    let mut d = ReplyDecoder::new(0x80, &Command::ReadMainBattery);
    let r = decode_all(&mut d, &[0x00, 0x78, 0xC8, 0x65]);
    assert_eq!(r[3], Ok(Some(Reply::MainBattery(120))));

    let mut d = ReplyDecoder::new(0x80, &Command::ReadVersion);
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
    let mut d = ReplyDecoder::new(0x80, &Command::DriveSpeeds { m1: 0, m2: 0 });
    assert_eq!(d.push(0xFF), Ok(Some(Reply::Ack)));
    assert_eq!(d.push(0x00), Err(ReplyError::NotAck(0x00)));
}

#[test]
fn corrupted_reply_is_rejected_for_every_single_bit_flip() {
    let good = encode_reply(0x80, cmd::READ_ENCODERS, &Reply::Encoders { m1: 7, m2: 9 });
    for i in 0..good.len() {
        for bit in 0..8 {
            let mut bad = good.clone();
            bad[i] ^= 1 << bit;
            let mut d = ReplyDecoder::new(0x80, &Command::ReadEncoders);
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
    let mut d = ReplyDecoder::new(0x80, &Command::ReadVersion);
    let r = decode_all(&mut d, &[b'x'; 60]);
    assert!(r.contains(&Err(ReplyError::TooLong)));
}

#[test]
fn device_decoder_round_trips_every_command() {
    let all = [
        Command::SetSerialTimeout { tenths: 3 },
        Command::ResetEncoders,
        Command::ReadVersion,
        Command::ReadMainBattery,
        Command::DriveSpeeds {
            m1: -5,
            m2: i32::MAX,
        },
        Command::ReadEncoders,
        Command::ReadStatus,
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
    let mut p = encode_command(0x80, &Command::ReadStatus);
    p[3] ^= 0x01;
    let r: Vec<_> = p.iter().filter_map(|&b| dec.push(b)).collect();
    assert!(matches!(r[..], [Err(FrameError::Crc { .. })]));
    // Unknown command number.
    dec.push(0x80);
    assert_eq!(dec.push(200), Some(Err(FrameError::UnknownCommand(200))));
    // And the decoder still works afterwards.
    let p = encode_command(0x80, &Command::ReadEncoders);
    let r: Vec<_> = p.iter().filter_map(|&b| dec.push(b)).collect();
    assert_eq!(r, vec![Ok((0x80, Command::ReadEncoders))]);
}

#[test]
fn device_replies_decode_on_host() {
    for (c, reply) in [
        (
            Command::ReadEncoders,
            Reply::Encoders {
                m1: u32::MAX,
                m2: 0,
            },
        ),
        (Command::ReadStatus, Reply::Status(0xDEAD_BEEF)),
        (Command::ReadMainBattery, Reply::MainBattery(241)),
    ] {
        let bytes = encode_reply(0x80, c.code(), &reply);
        let mut d = ReplyDecoder::new(0x80, &c);
        assert_eq!(decode_all(&mut d, &bytes).pop().unwrap(), Ok(Some(reply)));
    }
}

proptest! {
    #[test]
    fn reply_decoder_never_panics(cmdsel in 0usize..7, bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let c = [
            Command::SetSerialTimeout { tenths: 1 },
            Command::ResetEncoders,
            Command::ReadVersion,
            Command::ReadMainBattery,
            Command::DriveSpeeds { m1: 0, m2: 0 },
            Command::ReadEncoders,
            Command::ReadStatus,
        ][cmdsel];
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
        let p = encode_command(0x80, &Command::DriveSpeeds { m1, m2 });
        let r: Vec<_> = p.iter().filter_map(|&b| dec.push(b)).collect();
        prop_assert_eq!(r, vec![Ok((0x80, Command::DriveSpeeds { m1, m2 }))]);
    }
}
