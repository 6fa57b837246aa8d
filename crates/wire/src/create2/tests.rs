//! Wire tests for the Create 2 OI codec. Fixtures: the research notes
//! (Drive Direct 200 mm/s = `91 00 C8 00 C8`) and the OI specification's
//! stream example (packets 29 and 13: `19 5 29 2 25 13 0 163`).

use super::packets::group_members;
use super::*;
use proptest::prelude::*;

fn frames(p: &mut StreamParser, bytes: &[u8]) -> Vec<Result<SensorFrame, StreamError>> {
    let mut v = Vec::new();
    p.feed(bytes, &mut |r| v.push(r));
    v
}

#[test]
fn drive_direct_right_wheel_first_and_clamped() {
    assert_eq!(
        &encode(&OiCommand::drive_direct(0.2, 0.2))[..],
        &[0x91, 0x00, 0xC8, 0x00, 0xC8]
    );
    // Left 0.1 m/s, right -0.05 m/s: right (-50 = FF CE) goes first.
    assert_eq!(
        &encode(&OiCommand::drive_direct(0.1, -0.05))[..],
        &[145, 0xFF, 0xCE, 0x00, 0x64]
    );
    // Clamped to ±500 mm/s, NaN to 0.
    assert_eq!(
        OiCommand::drive_direct(3.0, -9.0),
        OiCommand::DriveDirect {
            right: -500,
            left: 500
        }
    );
    assert_eq!(
        OiCommand::drive_direct(f64::NAN, f64::INFINITY),
        OiCommand::DriveDirect {
            right: 500,
            left: 0
        }
    );
}

#[test]
fn mode_and_stream_commands() {
    assert_eq!(&encode(&OiCommand::Start)[..], &[128]);
    assert_eq!(&encode(&OiCommand::Safe)[..], &[131]);
    assert_eq!(&encode(&OiCommand::Full)[..], &[132]);
    assert_eq!(&encode(&OiCommand::Stop)[..], &[173]);
    assert_eq!(&encode(&OiCommand::Baud(11))[..], &[129, 11]);
    let mut ids = HVec::new();
    ids.extend_from_slice(&[7, 43, 44]).unwrap();
    assert_eq!(&encode(&OiCommand::Stream(ids))[..], &[148, 3, 7, 43, 44]);
    assert_eq!(&encode(&OiCommand::StreamEnable(false))[..], &[150, 0]);
    assert_eq!(&encode(&OiCommand::StreamEnable(true))[..], &[150, 1]);
}

#[test]
fn spec_stream_example_parses() {
    let mut p = StreamParser::new();
    let r = frames(&mut p, &[19, 5, 29, 2, 25, 13, 0, 163]);
    assert_eq!(r, vec![Ok(SensorFrame::default())]);
    // Off by one in the checksum is rejected.
    let r = frames(&mut p, &[19, 5, 29, 2, 25, 13, 0, 164]);
    assert!(matches!(r[..], [Err(StreamError::Checksum(1))]));
}

#[test]
fn encoders_bumps_and_mode_decode() {
    let s = SensorState {
        bumps_drops: 0b0000_1010, // bump left, wheel drop left
        voltage_mv: 15_000,
        oi_mode: 2,
        left_encoder: 0xFFFE,
        right_encoder: 3,
        ..SensorState::default()
    };
    let bytes = encode_stream_frame(&[7, 43, 44, 35, 22], &s);
    // 19, n=3*... : 7(1)+43(2)+44(2)+35(1)+22(2) = 8 data + 5 ids = 13
    assert_eq!(bytes[..2], [19, 13]);
    assert_eq!(bytes[2..5], [7, 0x0A, 43]);
    assert_eq!(bytes.iter().fold(0u8, |a, &b| a.wrapping_add(b)), 0);
    let mut p = StreamParser::new();
    let r = frames(&mut p, &bytes);
    let f = r[0].unwrap();
    assert_eq!(f.left_encoder, Some(0xFFFE));
    assert_eq!(f.right_encoder, Some(3));
    assert_eq!(f.oi_mode, Some(2));
    assert_eq!(f.voltage_mv, Some(15_000));
    assert_eq!(
        f.bumps(),
        Some(super::Sides {
            left: true,
            right: false
        })
    );
    assert_eq!(
        f.wheel_drops(),
        Some(super::Sides {
            left: true,
            right: false
        })
    );
}

#[test]
fn garbage_before_and_between_frames_is_skipped() {
    let s = SensorState {
        left_encoder: 100,
        right_encoder: 200,
        ..Default::default()
    };
    let f = encode_stream_frame(&[43, 44], &s);
    let mut bytes = vec![0xAA, 0x00, 0x13];
    bytes.extend_from_slice(&f);
    bytes.extend_from_slice(&[0x55, 0x66]);
    bytes.extend_from_slice(&f);
    let mut p = StreamParser::with_payload_len(StreamParser::payload_len(&[43, 44]).unwrap());
    let r = frames(&mut p, &bytes);
    let ok: Vec<_> = r.iter().filter_map(|x| x.ok()).collect();
    assert_eq!(ok.len(), 2, "{r:?}");
    assert_eq!(ok[0].left_encoder, Some(100));
    assert!(p.discarded >= 4);
}

#[test]
fn every_single_bit_flip_is_rejected_and_next_frame_recovers() {
    let s = SensorState {
        bumps_drops: 1,
        left_encoder: 1234,
        right_encoder: 4321,
        ..Default::default()
    };
    let f = encode_stream_frame(&[7, 43, 44], &s);
    for i in 0..f.len() {
        for bit in 0..8 {
            let mut bad = f.clone();
            bad[i] ^= 1 << bit;
            let good = frames(&mut StreamParser::new(), &f)[0].unwrap();
            // Knowing the payload length, the parser is back in sync by the
            // second frame; without it, a corrupted length may swallow up to
            // MAX_PAYLOAD bytes first.
            let n = StreamParser::payload_len(&[7, 43, 44]).unwrap();
            for (mut p, copies) in [
                (StreamParser::with_payload_len(n), 2),
                (StreamParser::new(), 14),
            ] {
                let mut bytes = bad.to_vec();
                for _ in 0..copies {
                    bytes.extend_from_slice(&f);
                }
                let r = frames(&mut p, &bytes);
                // The corrupted frame never yields a wrong reading...
                for x in r.iter().flatten() {
                    assert_eq!(*x, good, "byte {i} bit {bit}");
                }
                // ...and the parser gets back in sync.
                assert!(
                    r.iter().filter(|x| x.is_ok()).count() >= 1,
                    "byte {i} bit {bit}: {r:?}"
                );
            }
        }
    }
}

#[test]
fn unknown_packet_id_is_an_error() {
    // id 99 is no single packet; checksum made valid.
    let body = [19u8, 2, 99, 0];
    let sum = body.iter().fold(0u8, |a, &b| a.wrapping_add(b));
    let mut bytes = body.to_vec();
    bytes.push(0u8.wrapping_sub(sum));
    let r = frames(&mut StreamParser::new(), &bytes);
    assert!(r.contains(&Err(StreamError::UnknownPacket(99))), "{r:?}");
}

#[test]
fn truncated_packet_is_a_length_error() {
    // n = 2 but packet 43 needs 2 data bytes after its id.
    let body = [19u8, 2, 43, 1];
    let sum = body.iter().fold(0u8, |a, &b| a.wrapping_add(b));
    let mut bytes = body.to_vec();
    bytes.push(0u8.wrapping_sub(sum));
    let r = frames(&mut StreamParser::new(), &bytes);
    assert!(r.contains(&Err(StreamError::BadLength(2))), "{r:?}");
}

/// One of every command, with data bytes that are themselves opcodes.
fn every_command() -> Vec<OiCommand> {
    let mut ids = PacketIds::new();
    ids.extend_from_slice(&[7, 35, 43, 44, 100, 6]).unwrap();
    let mut notes = Notes::new();
    notes
        .extend_from_slice(&[60, 145, 128, 131, 31, 255])
        .unwrap();
    vec![
        OiCommand::Start,
        OiCommand::Baud(11),
        OiCommand::Control,
        OiCommand::Safe,
        OiCommand::Full,
        OiCommand::Power,
        OiCommand::Spot,
        OiCommand::Clean,
        OiCommand::Max,
        OiCommand::SeekDock,
        OiCommand::drive_direct(-0.3, 0.25),
        OiCommand::Drive {
            velocity: -200,
            radius: 500,
        },
        OiCommand::DrivePwm {
            right: 255,
            left: -255,
        },
        OiCommand::Motors(0x07),
        OiCommand::PwmMotors {
            main: -127,
            side: 127,
            vacuum: 127,
        },
        OiCommand::Leds {
            bits: 0x0F,
            color: 128,
            intensity: 255,
        },
        OiCommand::SchedulingLeds {
            weekdays: 0x7F,
            scheduling: 0x1F,
        },
        OiCommand::DigitLedsRaw([0x7F, 0x06, 0x5B, 0x4F]),
        OiCommand::DigitLedsAscii(*b"ABC "),
        OiCommand::Buttons(0x80),
        OiCommand::Schedule([127, 9, 30, 10, 0, 11, 15, 12, 45, 13, 59, 14, 1, 23, 59]),
        OiCommand::SetDayTime {
            day: 6,
            hour: 23,
            minute: 59,
        },
        OiCommand::Song { number: 4, notes },
        OiCommand::Play(4),
        OiCommand::Stream(ids.clone()),
        OiCommand::QueryList(ids),
        OiCommand::Sensors(100),
        OiCommand::StreamEnable(false),
        OiCommand::Stop,
        OiCommand::Reset,
    ]
}

/// Data bytes per opcode as the specification lists them (Song: 2 + 2N,
/// Stream and Query List: 1 + N).
fn spec_data_len(c: &OiCommand) -> usize {
    match c {
        OiCommand::Song { notes, .. } => 2 + notes.len(),
        OiCommand::Stream(ids) | OiCommand::QueryList(ids) => 1 + ids.len(),
        c => match c.opcode() {
            7 | 128 | 130..=136 | 143 | 173 => 0,
            129 | 138 | 141 | 142 | 150 | 165 => 1,
            162 => 2,
            139 | 144 | 168 => 3,
            137 | 145 | 146 | 163 | 164 => 4,
            167 => 15,
            o => panic!("opcode {o} missing from the table"),
        },
    }
}

#[test]
fn every_command_has_the_specifications_length_and_round_trips() {
    let mut d = OiDecoder::new();
    for c in every_command() {
        let bytes = encode(&c);
        assert_eq!(bytes.len(), 1 + spec_data_len(&c), "{c:?}");
        assert_eq!(c.check(), Ok(()), "{c:?}");
        let got: Vec<_> = bytes.iter().filter_map(|&b| d.push(b)).collect();
        assert_eq!(got, vec![Ok(c.clone())]);
        assert!(!d.mid_command());
    }
    assert_eq!(d.skipped, 0);
}

#[test]
fn all_commands_back_to_back_decode_in_order() {
    let cmds = every_command();
    let bytes: Vec<u8> = cmds.iter().flat_map(|c| encode(c).to_vec()).collect();
    let mut d = OiDecoder::new();
    let got: Vec<_> = bytes.iter().filter_map(|&b| d.push(b)).collect();
    assert_eq!(got, cmds.into_iter().map(Ok).collect::<Vec<_>>());
}

#[test]
fn song_data_bytes_are_never_opcodes() {
    // createSong(0, [60, 145]) then drive_direct(100, 100).
    let mut d = OiDecoder::new();
    let bytes = [140, 0, 1, 60, 145, 145, 0, 100, 0, 100];
    let got: Vec<_> = bytes.iter().filter_map(|&b| d.push(b)).collect();
    let mut notes = Notes::new();
    notes.extend_from_slice(&[60, 145]).unwrap();
    assert_eq!(
        got,
        vec![
            Ok(OiCommand::Song { number: 0, notes }),
            Ok(OiCommand::DriveDirect {
                right: 100,
                left: 100
            })
        ]
    );
}

#[test]
fn unknown_opcodes_cost_one_byte_and_long_lists_are_consumed_whole() {
    let mut d = OiDecoder::new();
    assert_eq!(d.push(147), Some(Err(DecodeError::UnknownOpcode(147))));
    assert_eq!(d.push(0), Some(Err(DecodeError::UnknownOpcode(0))));
    assert_eq!(d.skipped, 2);
    // A 20-note song: 2 + 40 data bytes, all consumed, then Start decodes.
    let mut bytes = vec![140, 0, 20];
    bytes.extend(core::iter::repeat_n(128u8, 40));
    bytes.push(128);
    let got: Vec<_> = bytes.iter().filter_map(|&b| d.push(b)).collect();
    assert_eq!(
        got,
        vec![
            Err(DecodeError::TooLong {
                opcode: 140,
                count: 20
            }),
            Ok(OiCommand::Start)
        ]
    );
    // A query list of 200 ids, then Safe.
    let mut bytes = vec![149, 200];
    bytes.extend(core::iter::repeat_n(131u8, 200));
    bytes.push(131);
    let got: Vec<_> = bytes.iter().filter_map(|&b| d.push(b)).collect();
    assert_eq!(
        got,
        vec![
            Err(DecodeError::TooLong {
                opcode: 149,
                count: 200
            }),
            Ok(OiCommand::Safe)
        ]
    );
}

#[test]
fn every_group_is_the_sum_of_its_members_as_the_specification_lists() {
    // (group, first, last, bytes) from the specification's sensor table.
    let groups = [
        (0u8, 7u8, 26u8, 26usize),
        (1, 7, 16, 10),
        (2, 17, 20, 6),
        (3, 21, 26, 10),
        (4, 27, 34, 14),
        (5, 35, 42, 12),
        (6, 7, 42, 52),
        (100, 7, 58, 80),
        (101, 43, 58, 28),
        (106, 46, 51, 12),
        (107, 54, 58, 9),
    ];
    for (g, first, last, bytes) in groups {
        assert_eq!(group_members(g), Some(first..=last), "group {g}");
        let sum: usize = (first..=last).map(|i| packet_size(i).unwrap()).sum();
        assert_eq!(sum, bytes, "group {g}");
        assert_eq!(response_size(g), Some(bytes), "group {g}");
        assert_eq!(packet_bytes(g, &SensorState::default()).len(), bytes);
    }
    for id in 7..=58 {
        assert!(packet_size(id).is_some(), "{id}");
    }
    for id in (59..100).chain(102..106).chain(108..=255) {
        assert_eq!(response_size(id), None, "{id}");
    }
}

#[test]
fn out_of_range_values_are_caught() {
    let bad = [
        OiCommand::DriveDirect {
            right: 501,
            left: 0,
        },
        OiCommand::Drive {
            velocity: 0,
            radius: 2001,
        },
        OiCommand::Drive {
            velocity: -501,
            radius: i16::MIN,
        },
        OiCommand::DrivePwm {
            right: 0,
            left: -256,
        },
        OiCommand::Baud(12),
        OiCommand::Play(5),
        OiCommand::Sensors(59),
        OiCommand::DigitLedsAscii([31, 65, 65, 65]),
        OiCommand::SetDayTime {
            day: 7,
            hour: 0,
            minute: 0,
        },
        OiCommand::Song {
            number: 0,
            notes: Notes::new(),
        },
    ];
    for c in bad {
        assert!(c.check().is_err(), "{c:?}");
    }
    let ok = OiCommand::Drive {
        velocity: 500,
        radius: i16::MAX,
    };
    assert_eq!(ok.check(), Ok(()));
}

#[test]
fn group_packets_in_a_stream_frame_parse() {
    let s = SensorState {
        oi_mode: 2,
        left_encoder: 7,
        right_encoder: 9,
        bumps_drops: 3,
        ..SensorState::default()
    };
    let f = encode_stream_frame(&[100], &s);
    assert_eq!(f[1], 81);
    let mut p = StreamParser::with_payload_len(StreamParser::payload_len(&[100]).unwrap());
    let r = frames(&mut p, &f);
    let got = r[0].unwrap();
    assert_eq!(got.oi_mode, Some(2));
    assert_eq!((got.left_encoder, got.right_encoder), (Some(7), Some(9)));
    assert_eq!(got.bumps_drops, Some(3));
}

proptest! {
    #[test]
    fn stream_parser_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut p = StreamParser::new();
        let mut n = 0usize;
        p.feed(&bytes, &mut |_| n += 1);
        prop_assert!(n <= bytes.len());
    }

    #[test]
    fn stream_parser_finds_frame_after_noise(noise in proptest::collection::vec(any::<u8>(), 0..100), l in any::<u16>(), r in any::<u16>()) {
        let s = SensorState { left_encoder: l, right_encoder: r, ..Default::default() };
        let f = encode_stream_frame(&[43, 44], &s);
        let mut p = StreamParser::new();
        p.feed(&noise, &mut |_| {});
        // Noise may leave the parser inside a false frame; two copies of the
        // real frame always yield at least one correct reading.
        let mut got = Vec::new();
        for _ in 0..25 {
            p.feed(&f, &mut |x| got.push(x));
        }
        prop_assert!(got.iter().any(|x| matches!(x, Ok(fr) if fr.left_encoder == Some(l) && fr.right_encoder == Some(r))));
    }

    #[test]
    fn oi_decoder_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let mut d = OiDecoder::new();
        for b in bytes {
            let _ = d.push(b);
        }
    }

    #[test]
    fn oi_decoder_resyncs_after_any_noise(noise in proptest::collection::vec(any::<u8>(), 0..100)) {
        // Whatever came before, once the decoder is between commands every
        // command decodes exactly.
        let mut d = OiDecoder::new();
        for b in noise {
            let _ = d.push(b);
        }
        while d.mid_command() {
            let _ = d.push(0);
        }
        for c in every_command() {
            let got: Vec<_> = encode(&c).iter().filter_map(|&b| d.push(b)).collect();
            prop_assert_eq!(got, vec![Ok(c)]);
        }
    }
}
