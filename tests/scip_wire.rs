//! Wire tests in the smoltcp style: exact bytes for every command and reply,
//! every malformed command with the status a URG answers, every decoder
//! recovery path, FF intensity mode, clusters and values straddling lines.

use sweepline::scan::LaserScan;
use sweepline::scip::{
    self, checksum, ClockUnwrapper, Cluster, Command, CommandError, CommandKind, DataKind, Decoder,
    DecoderOptions, ErrorKind, Event, FrameError, Reading, Reply, ReplyBody, ReplyError, ScanError,
    ScanRequest, SensorInfo, SensorParams, Status, StatusCode, StreamRequest, Tag, TaggedCommand,
    TimeControl, VersionInfo, Width,
};

// ---------------------------------------------------------------- helpers

/// What a byte stream decodes to, detached from the decoder.
#[derive(Debug, PartialEq)]
enum Got {
    Reply(String),
    Error(FrameError),
}

fn decode_stream_with(dec: &mut Decoder, input: &[u8]) -> Vec<Got> {
    let mut out = Vec::new();
    let mut rest = input;
    while !rest.is_empty() {
        let (n, ev) = dec.feed(rest);
        rest = &rest[n..];
        match ev {
            Some(Event::Reply(r)) => {
                out.push(Got::Reply(String::from_utf8_lossy(r.echo).into_owned()))
            }
            Some(Event::Error(e)) => out.push(Got::Error(e)),
            None => {}
        }
    }
    out
}

fn decode_stream(input: &[u8]) -> Vec<Got> {
    decode_stream_with(&mut Decoder::default(), input)
}

fn reply(s: &str) -> Got {
    Got::Reply(s.to_owned())
}

/// Decodes exactly one reply from `input` and hands it to `f`.
fn with_reply<T>(input: &[u8], f: impl FnOnce(Reply<'_>) -> T) -> T {
    let mut dec = Decoder::default();
    let (n, ev) = dec.feed(input);
    assert_eq!(n, input.len(), "one reply expected");
    match ev {
        Some(Event::Reply(r)) => f(r.decode().expect("typed decode")),
        other => panic!("{other:?}"),
    }
}

fn cmd_bytes(c: Command, tag: &[u8]) -> Vec<u8> {
    let mut v = Vec::new();
    TaggedCommand::with_tag(c, Tag::new(tag).unwrap())
        .encode(&mut v)
        .unwrap();
    v
}

fn req(kind: DataKind, start: u16, end: u16, cluster: Cluster) -> ScanRequest {
    ScanRequest {
        kind,
        start,
        end,
        cluster,
    }
}

fn md(start: u16, end: u16, cluster: Cluster, skip: u8, count: u8) -> Command {
    Command::Stream(StreamRequest {
        scan: req(DataKind::Distance, start, end, cluster),
        skip,
        count,
    })
}

fn encode(cmd: Command, status: Status, body: &ReplyBody<'_>) -> Vec<u8> {
    let mut v = Vec::new();
    scip::encode_reply(&TaggedCommand::new(cmd), status, body, &mut v).unwrap();
    v
}

const OK: Status = Status::Scip2(StatusCode::OK);
const DATA: Status = Status::Scip2(StatusCode::DATA);

fn scan_reply(cmd: Command, status: Status, ts: u32, fields: &[u32], width: Width) -> Vec<u8> {
    let r = *cmd.scan_request().unwrap();
    let mut chars = Vec::new();
    scip::scan::encode_fields(fields.iter().copied(), width, &mut chars).unwrap();
    let remaining = match cmd {
        Command::Stream(s) => Some(s.count),
        _ => None,
    };
    let scan = scip::ScanData::new(r, remaining, ts, &chars).unwrap();
    encode(cmd, status, &ReplyBody::Scan(scan))
}

// ---------------------------------------------------------------- commands

#[test]
fn every_command_encodes_to_the_exact_bytes() {
    let cases: Vec<(Command, &[u8], &[u8])> = vec![
        (Command::Scip20, b"", b"SCIP2.0\n"),
        (Command::Vv, b"", b"VV\n"),
        (Command::Pp, b"", b"PP\n"),
        (Command::Ii, b"", b"II\n"),
        (Command::Bm, b"", b"BM\n"),
        (Command::Qt, b"", b"QT\n"),
        (Command::Rs, b"", b"RS\n"),
        (Command::Tm(TimeControl::Enter), b"", b"TM0\n"),
        (Command::Tm(TimeControl::Read), b"a", b"TM1;a\n"),
        (Command::Tm(TimeControl::Leave), b"", b"TM2\n"),
        (Command::Ss(115_200), b"", b"SS115200\n"),
        (Command::Ss(19_200), b"", b"SS019200\n"),
        (Command::Cr(5), b"", b"CR05\n"),
        (Command::Hs(true), b"", b"HS1\n"),
        (Command::Hs(false), b"", b"HS0\n"),
        (
            Command::Get(req(DataKind::Distance, 44, 725, Cluster::Steps(1))),
            b"",
            b"GD0044072501\n",
        ),
        (
            Command::Get(req(DataKind::ShortDistance, 0, 768, Cluster::Steps(0))),
            b"",
            b"GS0000076800\n",
        ),
        (
            Command::Get(req(DataKind::DistanceIntensity, 0, 1080, Cluster::Steps(1))),
            b"",
            b"GE0000108001\n",
        ),
        (
            Command::Get(req(DataKind::Distance, 44, 725, Cluster::UrgIntensity)),
            b"",
            b"GD00440725FF\n",
        ),
        (
            md(44, 725, Cluster::Steps(1), 0, 0),
            b"",
            b"MD0044072501000\n",
        ),
        (
            md(44, 725, Cluster::UrgIntensity, 1, 99),
            b"",
            b"MD00440725FF199\n",
        ),
        (
            Command::Stream(StreamRequest {
                scan: req(DataKind::ShortDistance, 100, 200, Cluster::Steps(10)),
                skip: 9,
                count: 5,
            }),
            b"0123456789abcdef",
            b"MS0100020010905;0123456789abcdef\n",
        ),
        (
            Command::Stream(StreamRequest {
                scan: req(DataKind::DistanceIntensity, 0, 1080, Cluster::Steps(1)),
                skip: 0,
                count: 1,
            }),
            b"",
            b"ME0000108001001\n",
        ),
    ];
    for (c, tag, want) in cases {
        let got = cmd_bytes(c, tag);
        assert_eq!(String::from_utf8_lossy(&got), String::from_utf8_lossy(want));
        // And back: the sensor side parses it to the same command.
        let parsed = TaggedCommand::parse(&got[..got.len() - 1]).unwrap();
        assert_eq!(parsed.command, c);
        assert_eq!(parsed.tag.as_bytes(), tag);
        assert_eq!(
            parsed.command.kind().mnemonic().as_bytes(),
            &want[..want.len().min(7)][..parsed.command.kind().mnemonic().len()]
        );
    }
}

#[test]
fn out_of_range_fields_are_refused_when_encoding() {
    let mut v = Vec::new();
    assert!(TaggedCommand::new(Command::Ss(1_000_000))
        .encode(&mut v)
        .is_err());
    assert!(TaggedCommand::new(Command::Cr(100))
        .encode(&mut Vec::new())
        .is_err());
    assert!(
        TaggedCommand::new(md(10_000, 10_001, Cluster::Steps(1), 0, 0))
            .encode(&mut Vec::new())
            .is_err()
    );
    assert!(TaggedCommand::new(md(0, 10, Cluster::Steps(1), 10, 0))
        .encode(&mut Vec::new())
        .is_err());
    // A fixed buffer that is too small overflows cleanly.
    let mut small: heapless::Vec<u8, 4> = heapless::Vec::new();
    assert_eq!(TaggedCommand::new(Command::Vv).encode(&mut small), Ok(()));
    let mut small: heapless::Vec<u8, 4> = heapless::Vec::new();
    assert_eq!(
        TaggedCommand::new(md(44, 725, Cluster::Steps(1), 0, 0)).encode(&mut small),
        Err(scip::EncodeError::Overflow)
    );
}

#[test]
fn malformed_commands_get_the_status_a_urg_answers() {
    let cases: &[(&[u8], CommandError, &[u8; 2])] = &[
        (b"", CommandError::Undefined, b"0E"),
        (b"X", CommandError::Undefined, b"0E"),
        (b"XX", CommandError::Undefined, b"0E"),
        (b"ND0044072501000", CommandError::Undefined, b"0E"),
        (b"SCIP2.1", CommandError::Undefined, b"0E"),
        (b"VVX", CommandError::TooLong, b"0D"),
        (b"QT0", CommandError::TooLong, b"0D"),
        (b"GD004407250", CommandError::MissingParameters, b"0C"),
        (b"GD00440725011", CommandError::TooLong, b"0D"),
        (b"GDx044072501", CommandError::BadStart, b"01"),
        (b"GD0044y72501", CommandError::BadEnd, b"02"),
        (b"GD00440725x1", CommandError::BadCluster, b"03"),
        (b"GE00440725FF", CommandError::BadCluster, b"03"),
        (b"GD0725004401", CommandError::EndBeforeStart, b"05"),
        (b"MD0044072501x00", CommandError::BadSkip, b"06"),
        (b"MD00440725010x0", CommandError::BadCount, b"07"),
        (b"MD004407250100", CommandError::MissingParameters, b"0C"),
        (b"TM3", CommandError::BadControl, b"01"),
        (b"TM", CommandError::MissingParameters, b"0C"),
        (b"HS2", CommandError::BadControl, b"01"),
        (b"SS11520x", CommandError::BadControl, b"01"),
        (b"CR-1", CommandError::BadControl, b"01"),
        (b"VV;01234567890123456", CommandError::TagTooLong(17), b"0G"),
        (b"VV;a b", CommandError::TagInvalid(b' '), b"0H"),
        (b"VV;a;b", CommandError::TagInvalid(b';'), b"0H"),
    ];
    for (line, err, status) in cases {
        let got = TaggedCommand::parse(line);
        assert_eq!(got, Err(*err), "{}", String::from_utf8_lossy(line));
        assert_eq!(err.status(), StatusCode(**status));
        assert!(!err.to_string().is_empty());
    }
    // An empty tag after ';' is allowed and is "no tag".
    assert_eq!(TaggedCommand::parse(b"VV;").unwrap().tag, Tag::none());
}

#[test]
fn scan_range_checks_against_the_sensor() {
    let r = req(DataKind::Distance, 44, 725, Cluster::Steps(1));
    assert_eq!(r.check_range(44, 725), Ok(()));
    assert_eq!(
        req(DataKind::Distance, 0, 768, Cluster::Steps(1)).check_range(44, 725),
        Err(StatusCode(*b"04"))
    );
    assert_eq!(
        req(DataKind::Distance, 10, 5, Cluster::Steps(1)).check_range(0, 725),
        Err(StatusCode(*b"05"))
    );
    assert_eq!(r.value_count(), 682);
    assert_eq!(r.payload_chars(), 2046);
    assert_eq!(
        req(DataKind::Distance, 44, 725, Cluster::Steps(3)).value_count(),
        228
    );
    assert_eq!(
        req(DataKind::Distance, 44, 725, Cluster::Steps(0)).value_count(),
        682
    );
    assert_eq!(
        req(DataKind::ShortDistance, 44, 725, Cluster::Steps(1)).payload_chars(),
        1364
    );
    assert_eq!(
        req(DataKind::DistanceIntensity, 0, 1080, Cluster::Steps(1)).payload_chars(),
        6486
    );
    assert_eq!(
        req(DataKind::Distance, 44, 725, Cluster::UrgIntensity).value_count(),
        682
    );
}

// ---------------------------------------------------------------- replies

#[test]
fn status_only_replies_are_byte_exact() {
    let mut v = Vec::new();
    scip::write_status_reply(b"BM", Status::Scip2(StatusCode(*b"02")), &mut v).unwrap();
    assert_eq!(v, b"BM\n02R\n\n");
    v.clear();
    scip::write_status_reply(b"QT;x", OK, &mut v).unwrap();
    assert_eq!(v, b"QT;x\n00P\n\n");
    v.clear();
    scip::write_status_reply(
        b"ME0000108001101",
        Status::Scip2(StatusCode::UNDEFINED),
        &mut v,
    )
    .unwrap();
    assert_eq!(v, b"ME0000108001101\n0Ee\n\n");
    v.clear();
    scip::write_status_reply(b"SCIP2.0", Status::Scip1(b'0'), &mut v).unwrap();
    assert_eq!(v, b"SCIP2.0\n0\n\n");
}

#[test]
fn tm1_reply_is_byte_exact_and_round_trips() {
    let bytes = encode(
        Command::Tm(TimeControl::Read),
        OK,
        &ReplyBody::Time(3_292_603),
    );
    assert_eq!(bytes, b"TM1\n00P\n<SfkP\n\n");
    with_reply(&bytes, |r| assert_eq!(r.body, ReplyBody::Time(3_292_603)));
}

#[test]
fn every_reply_round_trips_through_the_decoder() {
    let version = VersionInfo {
        vendor: "Hokuyo Automatic Co.,Ltd.".into(),
        product: "SOKUIKI Sensor URG-04LX".into(),
        firmware: "3.1.04(02/Aug./2007)".into(),
        protocol: "SCIP 2.0".into(),
        serial: "H0706400".into(),
        extra: [("XTRA".try_into().unwrap(), "a:b;c".into())]
            .into_iter()
            .collect(),
    };
    let mut params = SensorParams::urg_04lx();
    params
        .extra
        .push(("SDIR".try_into().unwrap(), "CCW".into()))
        .unwrap();
    let info = SensorInfo {
        model: params.model.clone(),
        laser: "OFF".into(),
        scan_speed: "Initial(600[rpm])<-Default setting by user".into(),
        measure_mode: "CLASSIC".into(),
        bit_rate: "19200[bps]<-Default setting by user".into(),
        time_raw: "6A55F8".into(),
        state: "Sensor works well.".into(),
        extra: Default::default(),
    };
    let bodies: Vec<(Command, Status, ReplyBody<'_>)> = vec![
        (Command::Vv, OK, ReplyBody::Version(version)),
        (Command::Pp, OK, ReplyBody::Params(params)),
        (Command::Ii, OK, ReplyBody::Info(info.clone())),
        (Command::Bm, OK, ReplyBody::Empty),
        (
            Command::Bm,
            Status::Scip2(StatusCode(*b"01")),
            ReplyBody::Empty,
        ),
        (
            Command::Bm,
            Status::Scip2(StatusCode(*b"02")),
            ReplyBody::Empty,
        ),
        (Command::Qt, OK, ReplyBody::Empty),
        (Command::Rs, OK, ReplyBody::Empty),
        (Command::Tm(TimeControl::Enter), OK, ReplyBody::Empty),
        (
            Command::Tm(TimeControl::Enter),
            Status::Scip2(StatusCode(*b"02")),
            ReplyBody::Empty,
        ),
        (
            Command::Tm(TimeControl::Read),
            OK,
            ReplyBody::Time(0xFF_FFFF),
        ),
        (Command::Tm(TimeControl::Leave), OK, ReplyBody::Empty),
        (Command::Ss(115_200), OK, ReplyBody::Empty),
        (
            Command::Ss(115_200),
            Status::Scip2(StatusCode(*b"04")),
            ReplyBody::Empty,
        ),
        (
            Command::Cr(0),
            Status::Scip2(StatusCode(*b"03")),
            ReplyBody::Empty,
        ),
        (Command::Hs(true), OK, ReplyBody::Empty),
        (Command::Scip20, Status::Scip1(b'0'), ReplyBody::Empty),
        (md(44, 725, Cluster::Steps(1), 0, 3), OK, ReplyBody::Empty),
        (
            md(44, 725, Cluster::Steps(1), 0, 0),
            Status::Scip2(StatusCode(*b"04")),
            ReplyBody::Empty,
        ),
        (
            Command::Get(req(DataKind::Distance, 44, 725, Cluster::Steps(1))),
            Status::Scip2(StatusCode::DENIED),
            ReplyBody::Empty,
        ),
    ];
    for (cmd, status, body) in &bodies {
        let bytes = encode(*cmd, *status, body);
        with_reply(&bytes, |r| {
            assert_eq!(r.echo.command, *cmd);
            assert_eq!(r.status, *status);
            assert_eq!(&r.body, body, "{cmd:?}");
        });
    }
    assert_eq!(info.time_ms(), Some(6_968_824));
    assert_eq!(info.laser_on(), Some(false));
}

#[test]
fn scan_replies_round_trip_for_every_scan_command() {
    let kinds = [
        (DataKind::Distance, Width::Three, 1),
        (DataKind::ShortDistance, Width::Two, 1),
        (DataKind::DistanceIntensity, Width::Three, 2),
    ];
    for (kind, width, per) in kinds {
        for cluster in [Cluster::Steps(1), Cluster::Steps(4)] {
            let r = req(kind, 44, 725, cluster);
            let n = r.value_count() * per;
            let fields: Vec<u32> = (0..n as u32)
                .map(|i| (i * 7919) % width.max_value())
                .collect();
            for (cmd, status) in [
                (Command::Get(r), OK),
                (
                    Command::Stream(StreamRequest {
                        scan: r,
                        skip: 2,
                        count: 7,
                    }),
                    DATA,
                ),
            ] {
                let bytes = scan_reply(cmd, status, 123_456, &fields, width);
                with_reply(&bytes, |rep| {
                    let ReplyBody::Scan(s) = rep.body else {
                        panic!("{:?}", rep.body)
                    };
                    assert_eq!(s.timestamp, 123_456);
                    assert_eq!(s.request, r);
                    assert_eq!(s.remaining, matches!(cmd, Command::Stream(_)).then_some(7));
                    let values: Vec<_> = s.values().collect();
                    assert_eq!(values.len(), r.value_count());
                    for (i, v) in values.iter().enumerate() {
                        assert_eq!(v.distance, fields[i * per]);
                        assert_eq!(v.intensity, (per == 2).then(|| fields[i * 2 + 1]));
                        assert_eq!(v.step, 44 + i as u16 * cluster.group());
                    }
                });
            }
        }
    }
}

#[test]
fn data_lines_are_cut_at_64_characters_and_values_straddle_them() {
    let r = req(DataKind::Distance, 44, 725, Cluster::Steps(1));
    let fields: Vec<u32> = (0..682).map(|i| 20 + i * 8).collect();
    let bytes = scan_reply(Command::Get(r), OK, 0, &fields, Width::Three);
    let text = String::from_utf8(bytes.clone()).unwrap();
    let lines: Vec<&str> = text.split('\n').collect();
    // echo, status, timestamp, 31 full lines, one of 62, empty, (after last LF)
    assert_eq!(lines.len(), 3 + 32 + 2);
    assert_eq!(lines[2].len(), 5);
    for l in &lines[3..34] {
        assert_eq!(l.len(), 65);
        assert_eq!(checksum(&l.as_bytes()[..64]), l.as_bytes()[64]);
    }
    assert_eq!(lines[34].len(), 63);
    assert_eq!(lines[35], "");
    // Value 21 occupies characters 63..66: it straddles lines 0 and 1.
    with_reply(&bytes, |rep| {
        let ReplyBody::Scan(s) = rep.body else {
            panic!()
        };
        assert_eq!(s.values().nth(21).unwrap().distance, 20 + 21 * 8);
        assert_eq!(s.values().map(|v| v.distance).collect::<Vec<_>>(), fields);
    });
}

#[test]
fn a_scan_with_the_wrong_value_count_is_rejected() {
    let r = req(DataKind::Distance, 44, 725, Cluster::Steps(1));
    // Build a reply whose data carry 681 values but echo 44..725: every
    // checksum is right, only the count is wrong.
    let mut chars = Vec::new();
    scip::scan::encode_fields((0..681).map(|_| 1000), Width::Three, &mut chars).unwrap();
    let mut bytes = b"GD0044072501\n00P\n".to_vec();
    scip::scan::write_scan_lines(5, &chars, &mut bytes).unwrap();
    bytes.push(b'\n');
    let mut dec = Decoder::default();
    let (_, ev) = dec.feed(&bytes);
    let Some(Event::Reply(raw)) = ev else {
        panic!()
    };
    assert_eq!(
        raw.decode(),
        Err(ReplyError::Scan(ScanError::CountMismatch {
            expected: 2046,
            got: 2043
        }))
    );
    assert_eq!(
        scip::ScanData::new(r, None, 0, &chars[..chars.len() - 1]).unwrap_err(),
        ScanError::CountMismatch {
            expected: 2046,
            got: 2042
        }
    );
    let mut bad = vec![b'0'; 2046];
    bad[100] = b'~';
    assert_eq!(
        scip::ScanData::new(r, None, 0, &bad).unwrap_err(),
        ScanError::BadChar {
            byte: b'~',
            offset: 100
        }
    );
}

#[test]
fn malformed_typed_replies_are_errors() {
    // An error status with data lines.
    let bad = b"BM\n01Q\n000@\n\n";
    let mut dec = Decoder::default();
    let (_, ev) = dec.feed(bad);
    let Some(Event::Reply(raw)) = ev else {
        panic!("{ev:?}")
    };
    assert!(matches!(
        raw.decode(),
        Err(ReplyError::LineCount {
            kind: CommandKind::Bm,
            got: 1,
            expected: 0
        })
    ));
    // A TM1 reply with a 3-character time.
    let mut v = b"TM1\n00P\n".to_vec();
    v.extend_from_slice(b"000");
    v.push(checksum(b"000"));
    v.extend_from_slice(b"\n\n");
    let mut dec = Decoder::default();
    let Some(Event::Reply(raw)) = dec.feed(&v).1 else {
        panic!()
    };
    assert!(matches!(raw.decode(), Err(ReplyError::Encoding(_))));
    // Unknown echo.
    let mut dec = Decoder::default();
    let Some(Event::Reply(raw)) = dec.feed(b"ND0044072501000\n0Ee\n\n").1 else {
        panic!()
    };
    assert!(matches!(raw.decode(), Err(ReplyError::UnknownEcho(_))));
    // PP without AFRT, and PP with a non-numeric value.
    for (lines, err) in [
        (
            &[
                "MODL:x",
                "DMIN:20",
                "DMAX:5600",
                "ARES:1024",
                "AMIN:44",
                "AMAX:725",
                "SCAN:600",
            ][..],
            ReplyError::MissingParameter("AFRT"),
        ),
        (
            &[
                "MODL:x",
                "DMIN:2x",
                "DMAX:5600",
                "ARES:1024",
                "AMIN:44",
                "AMAX:725",
                "AFRT:384",
                "SCAN:600",
            ][..],
            ReplyError::BadParameter("DMIN"),
        ),
        (
            &[
                "MODL:x",
                "DMIN:20",
                "DMAX:5600",
                "ARES:0",
                "AMIN:44",
                "AMAX:725",
                "AFRT:384",
                "SCAN:600",
            ][..],
            ReplyError::BadParameter("ARES"),
        ),
        (
            &[
                "MODL:x",
                "DMIN:20",
                "DMAX:5600",
                "ARES:1024",
                "AMIN:44",
                "AMAX:725",
                "AFRT:999",
                "SCAN:600",
            ][..],
            ReplyError::BadParameter("AFRT"),
        ),
        (&["MODL:x", "DMIN20"][..], ReplyError::NotKeyValue),
    ] {
        let mut v = b"PP\n00P\n".to_vec();
        for l in lines {
            match l.split_once(':') {
                Some((k, val)) => scip::KvLine::encode(k, val, &mut v).unwrap(),
                None => {
                    v.extend_from_slice(l.as_bytes());
                    v.push(b';');
                    v.push(checksum(l.as_bytes()));
                    v.push(b'\n');
                }
            }
        }
        v.push(b'\n');
        let mut dec = Decoder::default();
        let Some(Event::Reply(raw)) = dec.feed(&v).1 else {
            panic!()
        };
        assert_eq!(raw.decode().unwrap_err(), err);
    }
}

// ---------------------------------------------------------------- decoder recovery

fn md_scan_bytes(count_left: u8, ts: u32) -> Vec<u8> {
    let fields: Vec<u32> = (0..682).map(|i| 100 + i).collect();
    scan_reply(
        md(44, 725, Cluster::Steps(1), 0, count_left),
        DATA,
        ts,
        &fields,
        Width::Three,
    )
}

#[test]
fn qt_echo_in_the_middle_of_a_stream_cuts_the_scan_and_is_delivered() {
    let full = md_scan_bytes(0, 1000);
    // Cut the scan after 10 data lines (at a line end), then the QT reply.
    let cut = full
        .iter()
        .enumerate()
        .filter(|(_, &b)| b == b'\n')
        .nth(12)
        .unwrap()
        .0
        + 1;
    let mut input = md_scan_bytes(0, 900);
    input.extend_from_slice(&full[..cut]);
    input.extend_from_slice(b"QT\n00P\n\n");
    input.extend_from_slice(&md_scan_bytes(0, 1100)); // a late scan after QT is still decoded
    let mut dec = Decoder::default();
    assert_eq!(
        decode_stream_with(&mut dec, &input),
        [
            reply("MD0044072501000"),
            Got::Error(FrameError::Truncated(Some(CommandKind::Qt))),
            reply("QT"),
            reply("MD0044072501000"),
        ]
    );
    assert_eq!(dec.stats().truncated_replies, 1);
    assert_eq!(dec.stats().replies, 3);
}

#[test]
fn qt_echo_glued_to_a_cut_data_line_is_still_found() {
    let full = md_scan_bytes(0, 1000);
    let cut = full
        .iter()
        .enumerate()
        .filter(|(_, &b)| b == b'\n')
        .nth(5)
        .unwrap()
        .0
        + 30;
    let mut input = full[..cut].to_vec();
    input.extend_from_slice(b"QT\n00P\n\n");
    assert_eq!(
        decode_stream(&input),
        [
            Got::Error(FrameError::Truncated(Some(CommandKind::Qt))),
            reply("QT")
        ]
    );
}

#[test]
fn a_lost_empty_line_costs_one_scan_only() {
    let mut a = md_scan_bytes(0, 100);
    a.pop(); // the empty line's LF
    let mut input = a;
    input.extend_from_slice(&md_scan_bytes(0, 200));
    input.extend_from_slice(&md_scan_bytes(0, 300));
    assert_eq!(
        decode_stream(&input),
        [
            Got::Error(FrameError::Truncated(Some(CommandKind::Md))),
            reply("MD0044072501000"),
            reply("MD0044072501000"),
        ]
    );
}

#[test]
fn data_and_status_checksum_errors_drop_one_reply_and_are_counted() {
    let good = md_scan_bytes(0, 100);
    let mut bad_data = good.clone();
    bad_data[40] = if bad_data[40] == b'0' { b'1' } else { b'0' }; // inside the first data line
    let mut bad_status = good.clone();
    let s = good.iter().position(|&b| b == b'\n').unwrap() + 3; // status checksum char
    bad_status[s] = b'c';
    let mut input = bad_data;
    input.extend_from_slice(&good);
    input.extend_from_slice(&bad_status);
    input.extend_from_slice(&good);
    let mut dec = Decoder::default();
    let got = decode_stream_with(&mut dec, &input);
    assert!(
        matches!(got[0], Got::Error(FrameError::DataChecksum { line: 1, .. })),
        "{got:?}"
    );
    assert_eq!(got[1], reply("MD0044072501000"));
    assert!(
        matches!(got[2], Got::Error(FrameError::StatusChecksum(_))),
        "{got:?}"
    );
    assert_eq!(got[3], reply("MD0044072501000"));
    assert_eq!(got.len(), 4);
    let st = dec.stats();
    assert_eq!(
        (
            st.data_checksum_errors,
            st.status_checksum_errors,
            st.replies,
            st.dropped_replies
        ),
        (1, 1, 2, 2)
    );
}

#[test]
fn garbage_noise_and_overlong_lines_resync_at_the_next_reply() {
    let mut input = b"\x00\x13\xfe".to_vec();
    input.extend_from_slice(b"VV\n00P\n");
    input.extend_from_slice(b"QT\n00P\n\n");
    input.extend(std::iter::repeat_n(b'A', 500));
    input.extend_from_slice(b"\nmore junk\n\n");
    input.extend_from_slice(b"BM\n00P\n\n");
    input.extend_from_slice(b"0123456789\nstray data line\n\n");
    input.extend_from_slice(b"RS\n00P\n\n");
    let mut dec = Decoder::default();
    assert_eq!(
        decode_stream_with(&mut dec, &input),
        [
            Got::Error(FrameError::Garbage),
            reply("QT"),
            Got::Error(FrameError::Overlong),
            reply("BM"),
            Got::Error(FrameError::UnexpectedLine),
            reply("RS"),
        ]
    );
    let st = dec.stats();
    assert_eq!((st.garbage_lines, st.overlong_lines, st.replies), (1, 1, 3));
    assert_eq!(st.last_error, Some(FrameError::UnexpectedLine));
    assert!(dec.is_idle());
    // The callback form sees the same events.
    let mut seen = Vec::new();
    Decoder::default().feed_each(&input, |ev| {
        seen.push(match ev {
            Event::Reply(r) => Got::Reply(String::from_utf8_lossy(r.echo).into_owned()),
            Event::Error(e) => Got::Error(e),
        })
    });
    assert_eq!(seen, decode_stream(&input));
}

#[test]
fn a_guessed_echo_without_a_status_is_skipped_silently() {
    let input = b"junk line\nVV\nnot a status\nmore\n\nBM\n00P\n\n";
    let mut dec = Decoder::default();
    assert_eq!(
        decode_stream_with(&mut dec, input),
        [Got::Error(FrameError::UnexpectedLine), reply("BM")]
    );
    assert_eq!(dec.stats().desyncs, 1);
}

#[test]
fn reset_forgets_a_partial_reply() {
    let full = md_scan_bytes(0, 1);
    let mut dec = Decoder::default();
    assert_eq!(decode_stream_with(&mut dec, &full[..500]), []);
    assert!(!dec.is_idle());
    dec.reset();
    assert!(dec.is_idle());
    assert_eq!(
        decode_stream_with(&mut dec, &full),
        [reply("MD0044072501000")]
    );
    // Options can change between replies.
    dec.set_options(DecoderOptions { lenient_kv: true });
    assert!(dec.options().lenient_kv);
}

#[test]
fn cr_and_crlf_streams_decode_like_lf() {
    let mut lf = md_scan_bytes(0, 1);
    lf.extend_from_slice(b"QT\n00P\n\n");
    for end in [&b"\r"[..], b"\r\n"] {
        let other: Vec<u8> = lf
            .iter()
            .flat_map(|&b| if b == b'\n' { end.to_vec() } else { vec![b] })
            .collect();
        assert_eq!(decode_stream(&other), decode_stream(&lf));
    }
    assert_eq!(decode_stream(&lf), [reply("MD0044072501000"), reply("QT")]);
}

#[test]
fn scip_1_1_status_is_typed() {
    let mut dec = Decoder::default();
    let Some(Event::Reply(raw)) = dec.feed(b"QT\nE\n\n").1 else {
        panic!()
    };
    assert_eq!(raw.status, Status::Scip1(b'E'));
    assert!(!raw.status.is_success(CommandKind::Qt));
    assert_eq!(raw.decode().unwrap().body, ReplyBody::Empty);
    assert_eq!(dec.stats().scip1_statuses, 1);
}

#[test]
fn lenient_mode_is_only_for_vv_and_ii_and_is_counted() {
    // VV with the URG-04LX SERI quirk (a wrong checksum on SERI).
    let vv = b"VV\n00P\nVEND:Hokuyo Automatic Co.,Ltd.;[\nSERI:H0706400;!\n\n";
    let mut strict = Decoder::default();
    assert!(matches!(
        decode_stream_with(&mut strict, vv)[..],
        [Got::Error(FrameError::KvChecksum { line: 1, .. })]
    ));
    assert_eq!(strict.stats().kv_checksum_errors, 1);
    let mut lenient = Decoder::new(DecoderOptions { lenient_kv: true });
    let (_, ev) = lenient.feed(vv);
    let Some(Event::Reply(raw)) = ev else {
        panic!("{ev:?}")
    };
    assert_eq!(raw.quirks, 1);
    let ReplyBody::Version(v) = raw.decode().unwrap().body else {
        panic!()
    };
    assert_eq!(v.serial, "H0706400");
    assert_eq!(lenient.stats().lenient_accepts, 1);
    // II with the checksum over `KEY:value;` (n-1).
    let mut ii = b"II\n00P\n".to_vec();
    ii.extend_from_slice(b"LASR:ON;");
    ii.push(checksum(b"LASR:ON;"));
    ii.extend_from_slice(b"\n\n");
    assert_eq!(
        decode_stream_with(&mut Decoder::new(DecoderOptions { lenient_kv: true }), &ii),
        [reply("II")]
    );
    assert!(matches!(
        decode_stream(&ii)[..],
        [Got::Error(FrameError::KvChecksum { .. })]
    ));
    // PP never gets leniency.
    let pp = [b"PP\n00P\n".as_slice(), &ii[7..]].concat();
    assert!(matches!(
        decode_stream_with(&mut Decoder::new(DecoderOptions { lenient_kv: true }), &pp)[..],
        [Got::Error(FrameError::KvChecksum { .. })]
    ));
}

#[test]
fn every_split_of_a_stream_gives_the_same_events() {
    let mut input = md_scan_bytes(5, 10);
    input.extend_from_slice(b"QT\n00P\n\n");
    let want = decode_stream(&input);
    for cut in 0..input.len() {
        let mut dec = Decoder::default();
        let mut got = decode_stream_with(&mut dec, &input[..cut]);
        got.extend(decode_stream_with(&mut dec, &input[cut..]));
        assert_eq!(got, want, "cut at {cut}");
    }
}

// ---------------------------------------------------------------- FF mode, clusters, readings

#[test]
fn ff_intensity_mode_pairs_even_and_odd_steps() {
    // Steps 44..=51: pairs (44,45) (46,47) (48,49) (50,51).
    let distances = [1000, 0, 2000, 0, 15, 0, 3000, 0];
    let intensities = [0, 111, 0, 222, 0, 333, 0, 444];
    let fields: Vec<u32> = scip::scan::ff_fields(44, &distances, &intensities).collect();
    assert_eq!(fields, [1000, 111, 2000, 222, 15, 333, 3000, 444]);
    let cmd = md(44, 51, Cluster::UrgIntensity, 0, 0);
    let bytes = scan_reply(cmd, DATA, 7, &fields, Width::Three);
    assert!(bytes.starts_with(b"MD00440051FF000\n99b\n"));
    let params = SensorParams::urg_04lx();
    with_reply(&bytes, |r| {
        let ReplyBody::Scan(s) = r.body else { panic!() };
        assert!(s.is_ff_intensity());
        let v: Vec<_> = s
            .values()
            .map(|v| (v.step, v.distance, v.intensity))
            .collect();
        assert_eq!(
            v,
            [
                (44, 1000, Some(111)),
                (45, 1000, Some(111)),
                (46, 2000, Some(222)),
                (47, 2000, Some(222)),
                (48, 15, Some(333)),
                (49, 15, Some(333)),
                (50, 3000, Some(444)),
                (51, 3000, Some(444)),
            ]
        );
        let mut ls = LaserScan::default();
        sweepline::urg::fill_laser_scan(&s, &params, 0.0, 0, &mut ls).unwrap();
        assert_eq!(ls.beams.len(), 8);
        assert_eq!(ls.beams[0].intensity, 111.0);
        // An error code gives no intensity (and no range).
        assert!(!ls.beams[4].valid);
        assert_eq!(ls.beams[4].intensity, 0.0);
    });
}

#[test]
fn ff_mode_with_odd_start_skips_the_orphan_and_keeps_a_trailing_distance() {
    // Steps 45..=50: 45 is the intensity of pair (44,45) whose distance was not
    // requested; 50 is a distance whose intensity (step 51) was not requested.
    let fields = [999, 1000, 111, 2000, 222, 3000];
    let cmd = md(45, 50, Cluster::UrgIntensity, 0, 0);
    let bytes = scan_reply(cmd, DATA, 7, &fields, Width::Three);
    with_reply(&bytes, |r| {
        let ReplyBody::Scan(s) = r.body else { panic!() };
        let v: Vec<_> = s
            .values()
            .map(|v| (v.step, v.distance, v.intensity))
            .collect();
        assert_eq!(
            v,
            [
                (46, 1000, Some(111)),
                (47, 1000, Some(111)),
                (48, 2000, Some(222)),
                (49, 2000, Some(222)),
                (50, 3000, None)
            ]
        );
    });
}

#[test]
fn clustered_beams_point_at_the_centre_of_their_steps() {
    let params = SensorParams::urg_04lx();
    let cmd = Command::Get(req(DataKind::Distance, 44, 725, Cluster::Steps(3)));
    let fields: Vec<u32> = vec![1000; 228];
    let bytes = scan_reply(cmd, OK, 0, &fields, Width::Three);
    with_reply(&bytes, |r| {
        let ReplyBody::Scan(s) = r.body else { panic!() };
        let mut ls = LaserScan::default();
        sweepline::urg::fill_laser_scan(&s, &params, 1.0, 2, &mut ls).unwrap();
        assert_eq!(ls.beams.len(), 228);
        let inc = std::f64::consts::TAU / 1024.0;
        assert!((ls.beams[0].angle - (45.0 - 384.0) * inc).abs() < 1e-12);
        // The last value covers step 725 alone.
        assert!((ls.beams[227].angle - (725.0 - 384.0) * inc).abs() < 1e-12);
        // Three steps a beam, each beam at its middle step: 97.7 µs after
        // the first step, then 293 µs apart.
        let tps = params.time_per_step();
        assert!((ls.first_beam_time - tps).abs() < 1e-15);
        assert!((ls.beam_interval - 3.0 * tps).abs() < 1e-15);
        assert!(ls
            .beams
            .iter()
            .all(|b| b.valid && (b.range - 1.0).abs() < 1e-12));
    });
}

#[test]
fn readings_use_the_model_table() {
    let params = SensorParams::urg_04lx();
    let cmd = Command::Get(req(DataKind::Distance, 44, 49, Cluster::Steps(1)));
    let bytes = scan_reply(cmd, OK, 0, &[0, 6, 18, 19, 20, 5601], Width::Three);
    with_reply(&bytes, |r| {
        let ReplyBody::Scan(s) = r.body else { panic!() };
        let readings: Vec<Reading> = s.readings(&params).map(|(_, r)| r).collect();
        let kinds: Vec<_> = readings
            .iter()
            .map(|r| match r {
                Reading::Error(e) => Some(e.kind),
                _ => None,
            })
            .collect();
        assert_eq!(
            kinds,
            [
                Some(ErrorKind::PossibleObjectAt22m),
                Some(ErrorKind::PossibleObjectAt5_7m),
                Some(ErrorKind::StrongReflector),
                Some(ErrorKind::NonMeasurable),
                None,
                None
            ]
        );
        assert_eq!(readings[4], Reading::Range(20));
        assert_eq!(readings[5], Reading::BeyondMax(5601));
    });
}

#[test]
fn pp_geometry_helpers_use_the_sensors_own_values() {
    let p = SensorParams::urg_04lx();
    assert_eq!(p.step_count(), 682);
    assert!((p.scan_period() - 0.1).abs() < 1e-15);
    assert!((p.time_per_step() - 0.1 / 1024.0).abs() < 1e-15);
    assert_eq!(p.time_of_step(44.0), 0.0);
    assert!((p.time_of_step(725.0) - 681.0 * 0.1 / 1024.0).abs() < 1e-15);
    assert_eq!(p.angle_of_step(384.0), 0.0);
    assert!((p.angle_of_step(640.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    assert_eq!(p.step_of_angle(0.0), 384);
    assert_eq!(p.step_of_angle(std::f64::consts::FRAC_PI_2), 640);
    assert_eq!(p.step_of_angle(10.0), 725);
    assert_eq!(p.step_of_angle(f64::NAN), 384);
    assert!((p.field_of_view().to_degrees() - 239.4140625).abs() < 1e-9);
    let mut other = p.clone();
    other.afrt = 400;
    assert!(
        other.angle_of_step(384.0) < 0.0,
        "angles follow AFRT, not a constant"
    );
}

#[test]
fn clock_unwrapping_over_stream_timestamps() {
    let mut u = ClockUnwrapper::new();
    let stamps = [0xFF_FF9C, 0x00_0000, 0x00_0064, 0x00_00C8];
    let got: Vec<u64> = stamps.iter().map(|&s| u.unwrap(s)).collect();
    assert_eq!(got, [0xFF_FF9C, 1 << 24, (1 << 24) + 100, (1 << 24) + 200]);
}
