//! Property test: the framer, decoder and typed decoders fed well over a
//! million random and mutated byte strings (mutations of the real captures and
//! of encoded replies: bit flips, byte swaps, truncation, insertion, deletion,
//! duplication, line-end rewrites, splices, random read() splits). Never a
//! panic; every event is a typed error or a verified reply; the decoder always
//! makes progress and never loses count of its input. Seeded: a failure
//! prints its case number and reproduces.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sweepline::scan::LaserScan;
use sweepline::scip::{
    self, Cluster, Command, DataKind, Decoder, DecoderOptions, Event, LineEvent, LineFramer,
    ReplyBody, ScanRequest, SensorInfo, SensorParams, Status, StatusCode, StreamRequest, Tag,
    TaggedCommand, TimeControl, VersionInfo, Width,
};

/// Total cases across the tests in this file (≥ 1,000,000).
const CASES: usize = 1_050_000;

fn capture_corpus(out: &mut Vec<Vec<u8>>) {
    for name in ["example_urg_04lx", "example_utm_30lx", "example_uxm_30lx_e"] {
        let rel = format!("datasets/hokuyo-captures/{name}.logr");
        let Some(path) = sweepline::testdata::shared_file(&rel) else {
            assert!(!sweepline::testdata::under_ci(), "{rel} missing under CI");
            eprintln!("note: {rel} not found; fuzzing encoded replies only");
            continue;
        };
        let data = std::fs::read(path).unwrap();
        let bytes: Vec<u8> = scip::parse_capture(&data)
            .unwrap()
            .into_iter()
            .flat_map(|r| r.bytes)
            .collect();
        // Each reply on its own, and pairs of neighbouring replies.
        let mut replies: Vec<Vec<u8>> = Vec::new();
        let mut start = 0;
        for i in 1..bytes.len() {
            if bytes[i] == b'\n' && bytes[i - 1] == b'\n' {
                replies.push(bytes[start..=i].to_vec());
                start = i + 1;
            }
        }
        for w in replies.windows(2) {
            out.push([w[0].clone(), w[1].clone()].concat());
        }
        out.extend(replies);
        out.push(bytes);
    }
}

fn scan_request(kind: DataKind, start: u16, end: u16, cluster: Cluster) -> ScanRequest {
    ScanRequest {
        kind,
        start,
        end,
        cluster,
    }
}

fn encoded_corpus(rng: &mut ChaCha8Rng, out: &mut Vec<Vec<u8>>) {
    let ok = Status::Scip2(StatusCode::OK);
    let data = Status::Scip2(StatusCode::DATA);
    let mut push = |cmd: Command, status: Status, body: ReplyBody<'_>| {
        let mut v = Vec::new();
        scip::encode_reply(&TaggedCommand::new(cmd), status, &body, &mut v).unwrap();
        out.push(v);
    };
    let version = VersionInfo {
        vendor: "Hokuyo Automatic Co.,Ltd.".into(),
        product: "SOKUIKI Sensor URG-04LX".into(),
        firmware: "3.1.04(02/Aug./2007)".into(),
        protocol: "SCIP 2.0".into(),
        serial: "H0706400".into(),
        extra: Default::default(),
    };
    push(Command::Vv, ok, ReplyBody::Version(version));
    push(Command::Pp, ok, ReplyBody::Params(SensorParams::urg_04lx()));
    let info = SensorInfo {
        model: "URG-04LX(Hokuyo Automatic Co.,Ltd.)".into(),
        laser: "OFF".into(),
        time_raw: "6A55F8".into(),
        ..SensorInfo::default()
    };
    push(Command::Ii, ok, ReplyBody::Info(info));
    push(
        Command::Tm(TimeControl::Read),
        ok,
        ReplyBody::Time(0xABCDEF),
    );
    push(Command::Qt, ok, ReplyBody::Empty);
    push(
        Command::Bm,
        Status::Scip2(StatusCode(*b"02")),
        ReplyBody::Empty,
    );
    push(Command::Scip20, Status::Scip1(b'0'), ReplyBody::Empty);
    for (kind, width, cluster) in [
        (DataKind::Distance, Width::Three, Cluster::Steps(1)),
        (DataKind::ShortDistance, Width::Two, Cluster::Steps(3)),
        (DataKind::DistanceIntensity, Width::Three, Cluster::Steps(0)),
        (DataKind::Distance, Width::Three, Cluster::UrgIntensity),
    ] {
        let start = rng.random_range(0..100u16);
        let end = start + rng.random_range(0..700u16);
        let req = scan_request(kind, start, end, cluster);
        let n = req.payload_chars() / width.chars();
        let mut chars = Vec::new();
        scip::scan::encode_fields(
            (0..n).map(|_| rng.random_range(0..=width.max_value())),
            width,
            &mut chars,
        )
        .unwrap();
        let scan = scip::ScanData::new(req, None, rng.random_range(0..1 << 24), &chars).unwrap();
        push(Command::Get(req), ok, ReplyBody::Scan(scan));
        let stream = StreamRequest {
            scan: req,
            skip: 0,
            count: 0,
        };
        let s2 = scip::ScanData::new(req, Some(0), scan.timestamp, &chars).unwrap();
        push(Command::Stream(stream), data, ReplyBody::Scan(s2));
    }
}

/// Encoded characters, line ends and separators: the bytes SCIP replies are made of.
const ALPHABET: &[u8] = b"0123456789:;<=>?@ABCDEFGHIJKLMNOPQRSTUVWXYZ[\\]^_`abcdefghijklmno\n\r;";

fn mutate(rng: &mut ChaCha8Rng, corpus: &[Vec<u8>], buf: &mut Vec<u8>) {
    buf.clear();
    if rng.random_range(0..20) == 0 {
        let n = rng.random_range(0..300);
        buf.extend((0..n).map(|_| {
            if rng.random_bool(0.5) {
                rng.random()
            } else {
                ALPHABET[rng.random_range(0..ALPHABET.len())]
            }
        }));
        return;
    }
    let base = &corpus[rng.random_range(0..corpus.len())];
    buf.extend_from_slice(base);
    for _ in 0..rng.random_range(0..5) {
        let len = buf.len();
        match rng.random_range(0..9) {
            0 if len > 0 => {
                let i = rng.random_range(0..len);
                buf[i] ^= 1 << rng.random_range(0..8);
            }
            1 if len > 0 => {
                let i = rng.random_range(0..len);
                buf[i] = rng.random();
            }
            2 if len > 0 => buf.truncate(rng.random_range(0..len)),
            3 => {
                let i = rng.random_range(0..=len);
                let b = [b'\n', b'\r', b';', b'0', rng.random()][rng.random_range(0..5)];
                buf.insert(i, b);
            }
            4 if len > 0 => {
                let i = rng.random_range(0..len);
                let j = (i + rng.random_range(1..80)).min(len);
                buf.drain(i..j);
            }
            5 if len > 0 => {
                let i = rng.random_range(0..len);
                let j = (i + rng.random_range(1..80)).min(len);
                let dup = buf[i..j].to_vec();
                buf.splice(i..i, dup);
            }
            6 => {
                let crlf: &[u8] = if rng.random_bool(0.5) { b"\r" } else { b"\r\n" };
                let mut v = Vec::with_capacity(len + len / 20);
                for &b in buf.iter() {
                    if b == b'\n' && rng.random_bool(0.7) {
                        v.extend_from_slice(crlf);
                    } else {
                        v.push(b);
                    }
                }
                *buf = v;
            }
            7 => {
                let other = &corpus[rng.random_range(0..corpus.len())];
                let i = rng.random_range(0..=len);
                let j = rng.random_range(0..=other.len());
                buf.truncate(i);
                buf.extend_from_slice(&other[j..]);
            }
            _ if len > 1 => {
                let i = rng.random_range(0..len - 1);
                buf.swap(i, i + 1);
            }
            _ => {}
        }
    }
}

/// Feeds `input` in random chunks; checks the invariants; returns replies seen.
fn run(
    dec: &mut Decoder,
    rng: &mut ChaCha8Rng,
    input: &[u8],
    scan: &mut LaserScan,
    params: &SensorParams,
) -> usize {
    let before = dec.stats().bytes;
    let mut replies = 0;
    let mut rest = input;
    while !rest.is_empty() {
        let chunk = rng.random_range(1..=rest.len().min(97));
        let mut piece = &rest[..chunk];
        rest = &rest[chunk..];
        while !piece.is_empty() {
            let (n, ev) = dec.feed(piece);
            assert!(n >= 1 && n <= piece.len(), "feed must make progress");
            piece = &piece[n..];
            match ev {
                Some(Event::Reply(raw)) => {
                    replies += 1;
                    assert!(!raw.echo.is_empty());
                    if let Ok(reply) = raw.decode() {
                        if let ReplyBody::Scan(s) = &reply.body {
                            let n = s.values().count();
                            let want = s.request.value_count();
                            let ff_odd = s.is_ff_intensity() && s.request.start % 2 == 1;
                            assert_eq!(n + usize::from(ff_odd), want);
                            if want <= sweepline::capacity::MAX_BEAMS {
                                sweepline::urg::fill_laser_scan(s, params, 0.0, 0, scan).unwrap();
                                assert!(scan.beams.iter().all(|b| b.angle.is_finite()));
                            }
                        }
                    }
                }
                Some(Event::Error(e)) => {
                    assert!(!e.to_string().is_empty());
                }
                None => {}
            }
        }
    }
    assert_eq!(dec.stats().bytes - before, input.len() as u64);
    replies
}

fn framer_event(ev: Option<LineEvent<'_>>, out: &mut Vec<Result<Vec<u8>, u8>>) {
    match ev {
        Some(LineEvent::Line(l)) => out.push(Ok(l.to_vec())),
        Some(LineEvent::Garbage) => out.push(Err(0)),
        Some(LineEvent::Overlong) => out.push(Err(1)),
        None => {}
    }
}

fn framer_bytewise(input: &[u8]) -> Vec<Result<Vec<u8>, u8>> {
    let mut f = LineFramer::new();
    let mut out = Vec::new();
    for &b in input {
        framer_event(f.push(b), &mut out);
    }
    out
}

fn framer_bulk(input: &[u8]) -> Vec<Result<Vec<u8>, u8>> {
    let mut f = LineFramer::new();
    let mut out = Vec::new();
    let mut rest = input;
    while !rest.is_empty() {
        let (n, ev) = f.push_slice(rest);
        rest = &rest[n..];
        framer_event(ev, &mut out);
    }
    out
}

fn fuzz(seed: u64, cases: usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut corpus = Vec::new();
    capture_corpus(&mut corpus);
    encoded_corpus(&mut rng, &mut corpus);
    let params = SensorParams::urg_04lx();
    let mut dec = Decoder::new(DecoderOptions {
        lenient_kv: seed.is_multiple_of(2),
    });
    let mut scan = LaserScan::default();
    let mut buf = Vec::new();
    let mut replies = 0;
    for case in 0..cases {
        mutate(&mut rng, &corpus, &mut buf);
        if case % 4 == 0 {
            dec.reset();
        }
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let n = run(&mut dec, &mut rng, &buf, &mut scan, &params);
            // Line-level decoders on arbitrary slices.
            let cut = buf.len().min(40);
            let _ = TaggedCommand::parse(&buf[..cut]);
            let _ = scip::decode_value(&buf[..buf.len().min(4)]);
            let _ = scip::checksum::verify_kv_line(&buf[..cut], true);
            let _ = Tag::new(&buf[..buf.len().min(20)]);
            if case % 8 == 0 {
                assert_eq!(framer_bytewise(&buf), framer_bulk(&buf));
            }
            n
        }));
        match r {
            Ok(n) => replies += n,
            Err(_) => panic!(
                "seed {seed} case {case} panicked on input {:?}",
                String::from_utf8_lossy(&buf)
            ),
        }
    }
    // The corpus is mostly valid: many replies must still get through.
    assert!(
        replies > cases / 10,
        "only {replies} replies in {cases} cases"
    );
    let s = dec.stats();
    eprintln!("seed {seed:#x}: {cases} cases, {replies} replies; {s:?}");
    assert!(
        s.checksum_errors() > 0 && s.desyncs > 0 && s.truncated_replies > 0,
        "{s:?}"
    );
}

#[test]
fn fuzz_decoder_half_a() {
    fuzz(0x5C1B_0001, CASES / 2);
}

#[test]
fn fuzz_decoder_half_b() {
    fuzz(0x5C1B_0002, CASES - CASES / 2);
}

/// Valid replies survive any read() split and any line-end style unchanged.
#[test]
fn valid_replies_survive_splits_and_line_ends() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut corpus = Vec::new();
    encoded_corpus(&mut rng, &mut corpus);
    for base in &corpus {
        let mut reference = Vec::new();
        let mut dec = Decoder::default();
        let (_, ev) = dec.feed(base);
        match ev {
            Some(Event::Reply(r)) => reference.push(format!("{:?}", r.decode().unwrap())),
            other => panic!("{other:?}"),
        }
        for style in [&b"\n"[..], b"\r", b"\r\n"] {
            let mut input = Vec::new();
            for &b in base {
                if b == b'\n' {
                    input.extend_from_slice(style);
                } else {
                    input.push(b);
                }
            }
            for _ in 0..50 {
                let mut dec = Decoder::default();
                let mut got = Vec::new();
                let mut rest = &input[..];
                while !rest.is_empty() {
                    let chunk = rng.random_range(1..=rest.len());
                    let mut piece = &rest[..chunk];
                    rest = &rest[chunk..];
                    while !piece.is_empty() {
                        let (n, ev) = dec.feed(piece);
                        piece = &piece[n..];
                        if let Some(Event::Reply(r)) = ev {
                            got.push(format!("{:?}", r.decode().unwrap()));
                        } else {
                            assert!(ev.is_none(), "{ev:?}");
                        }
                    }
                }
                assert_eq!(got, reference);
            }
        }
    }
}
