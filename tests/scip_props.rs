//! Property tests (proptest): for any valid command, encode → parse gives it
//! back; for any scan request and values, encode reply → decode gives the same
//! values, whatever the read() split; any 24-bit stamp sequence unwraps
//! monotonically when steps are small.

use proptest::prelude::*;
use sweepline::scip::{
    self, ClockUnwrapper, Cluster, Command, DataKind, Decoder, Event, ReplyBody, ScanRequest,
    Status, StatusCode, StreamRequest, Tag, TaggedCommand, TimeControl, Width,
};

fn data_kind() -> impl Strategy<Value = DataKind> {
    prop_oneof![
        Just(DataKind::Distance),
        Just(DataKind::ShortDistance),
        Just(DataKind::DistanceIntensity)
    ]
}

fn scan_request(max_len: u16) -> impl Strategy<Value = ScanRequest> {
    (
        data_kind(),
        0u16..8500,
        0u16..max_len,
        0u8..100,
        any::<bool>(),
    )
        .prop_map(|(kind, start, len, c, ff)| {
            let cluster = if ff && kind != DataKind::DistanceIntensity {
                Cluster::UrgIntensity
            } else {
                Cluster::Steps(c)
            };
            ScanRequest {
                kind,
                start,
                end: start + len,
                cluster,
            }
        })
}

fn command() -> impl Strategy<Value = Command> {
    prop_oneof![
        Just(Command::Scip20),
        Just(Command::Vv),
        Just(Command::Pp),
        Just(Command::Ii),
        Just(Command::Bm),
        Just(Command::Qt),
        Just(Command::Rs),
        prop_oneof![
            Just(TimeControl::Enter),
            Just(TimeControl::Read),
            Just(TimeControl::Leave)
        ]
        .prop_map(Command::Tm),
        (0u32..1_000_000).prop_map(Command::Ss),
        (0u8..100).prop_map(Command::Cr),
        any::<bool>().prop_map(Command::Hs),
        scan_request(999).prop_map(Command::Get),
        (scan_request(999), 0u8..10, 0u8..100)
            .prop_map(|(scan, skip, count)| Command::Stream(StreamRequest { scan, skip, count })),
    ]
}

fn tag() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(0x21u8..0x7f, 0..=16)
        .prop_map(|v| v.into_iter().filter(|&b| b != b';').collect())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn commands_round_trip(cmd in command(), tag in tag()) {
        let tc = TaggedCommand::with_tag(cmd, Tag::new(&tag).unwrap());
        let mut bytes = Vec::new();
        tc.encode(&mut bytes).unwrap();
        prop_assert_eq!(bytes.last(), Some(&b'\n'));
        let parsed = TaggedCommand::parse(&bytes[..bytes.len() - 1]).unwrap();
        prop_assert_eq!(parsed, tc);
    }

    #[test]
    fn scans_round_trip_under_any_split(
        r in scan_request(1400),
        seed in any::<u64>(),
        stamp in 0u32..(1 << 24),
        split in any::<prop::sample::Index>(),
    ) {
        let width = if r.kind == DataKind::ShortDistance { Width::Two } else { Width::Three };
        let n = r.payload_chars() / width.chars();
        let fields: Vec<u32> = (0..n as u64)
            .map(|i| ((i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ seed) % (u64::from(width.max_value()) + 1)) as u32)
            .collect();
        let mut chars = Vec::new();
        scip::scan::encode_fields(fields.iter().copied(), width, &mut chars).unwrap();
        prop_assume!(chars.len() <= sweepline::capacity::SCIP_MAX_SCAN_CHARS);
        let scan = scip::ScanData::new(r, None, stamp, &chars).unwrap();
        let mut bytes = Vec::new();
        let echo = TaggedCommand::new(Command::Get(r));
        scip::encode_reply(&echo, Status::Scip2(StatusCode::OK), &ReplyBody::Scan(scan), &mut bytes).unwrap();
        let cut = split.index(bytes.len());
        let mut dec = Decoder::default();
        let mut got = None;
        for part in [&bytes[..cut], &bytes[cut..]] {
            dec.feed_each(part, |ev| match ev {
                Event::Reply(raw) => {
                    let reply = raw.decode().unwrap();
                    let ReplyBody::Scan(s) = reply.body else { panic!("not a scan") };
                    got = Some((s.timestamp, s.chars().to_vec(), s.values().count()));
                }
                Event::Error(e) => panic!("{e}"),
            });
        }
        let (ts, got_chars, count) = got.expect("one reply");
        prop_assert_eq!(ts, stamp);
        prop_assert_eq!(got_chars, chars);
        let ff_odd = r.cluster == Cluster::UrgIntensity && r.start % 2 == 1;
        prop_assert_eq!(count + usize::from(ff_odd), r.value_count());
    }

    #[test]
    fn encoded_values_decode(v in any::<u32>(), w in prop_oneof![Just(Width::Two), Just(Width::Three), Just(Width::Four)]) {
        let mut out = Vec::new();
        let r = scip::encode_value(v, w, &mut out);
        if v <= w.max_value() {
            prop_assert!(r.is_ok());
            prop_assert_eq!(scip::decode_value(&out), Ok(v));
        } else {
            prop_assert!(r.is_err());
        }
    }

    #[test]
    fn small_forward_steps_unwrap_monotonically(start in 0u32..(1 << 24), steps in proptest::collection::vec(0u32..200_000, 1..200)) {
        let mut u = ClockUnwrapper::new();
        let mut truth = u64::from(start);
        prop_assert_eq!(u.unwrap(start), truth);
        for s in steps {
            truth += u64::from(s);
            prop_assert_eq!(u.unwrap((truth & 0xff_ffff) as u32), truth);
        }
    }
}
