//! Golden tests on real byte captures of a URG-04LX, a UTM-30LX and a
//! UXM-30LX-E (hokuyoaist logs in ../shared/datasets/hokuyo-captures): every
//! reply decodes with exact expected values, and re-encoding a decoded reply
//! gives back the sensor's bytes.

use sweepline::scip::{
    self, Command, DataKind, Decoder, DecoderOptions, Event, ModelFamily, Reading, Reply,
    ReplyBody, SensorParams, Status, StatusCode, TaggedCommand,
};

/// A decoded reply detached from the decoder, plus the exact bytes it came from.
struct Owned {
    echo: Vec<u8>,
    status: Status,
    lines: Vec<Vec<u8>>,
}

fn records(rel: &str) -> Vec<scip::CaptureRecord> {
    let path = sweepline::testdata::shared_file(rel).expect("checked by require_shared");
    let data = std::fs::read(path).expect("capture readable");
    scip::parse_capture(&data).expect("capture well formed")
}

/// Feeds the records as they were read (real read() boundaries) and collects
/// every reply; any frame error fails.
fn replies(rel: &str) -> (Vec<Owned>, scip::DecoderStats) {
    let mut dec = Decoder::new(DecoderOptions::default());
    let mut out = Vec::new();
    for rec in records(rel) {
        let mut input = &rec.bytes[..];
        while !input.is_empty() {
            let (n, ev) = dec.feed(input);
            input = &input[n..];
            match ev {
                Some(Event::Reply(r)) => out.push(Owned {
                    echo: r.echo.to_vec(),
                    status: r.status,
                    lines: r.lines().map(<[u8]>::to_vec).collect(),
                }),
                Some(Event::Error(e)) => panic!("{rel}: frame error {e}"),
                None => {}
            }
        }
    }
    assert!(dec.is_idle(), "{rel}: capture ends inside a reply");
    (out, *dec.stats())
}

/// Decodes the whole capture again and hands every typed reply to `f`.
fn for_each_typed(rel: &str, mut f: impl FnMut(usize, &Reply<'_>)) -> usize {
    let mut dec = Decoder::new(DecoderOptions::default());
    let mut i = 0;
    for rec in records(rel) {
        let mut input = &rec.bytes[..];
        while !input.is_empty() {
            let (n, ev) = dec.feed(input);
            input = &input[n..];
            if let Some(Event::Reply(r)) = ev {
                let typed = r
                    .decode()
                    .unwrap_or_else(|e| panic!("{rel}: reply {i}: {e}"));
                f(i, &typed);
                i += 1;
            }
        }
    }
    i
}

fn echoes(r: &[Owned]) -> Vec<String> {
    r.iter()
        .map(|o| String::from_utf8_lossy(&o.echo).into_owned())
        .collect()
}

const URG: &str = "datasets/hokuyo-captures/example_urg_04lx.logr";
const UTM: &str = "datasets/hokuyo-captures/example_utm_30lx.logr";
const UXM: &str = "datasets/hokuyo-captures/example_uxm_30lx_e.logr";

#[test]
fn urg_04lx_every_reply_decodes_without_a_checksum_error() {
    sweepline::require_shared!(URG);
    let (r, stats) = replies(URG);
    assert_eq!(
        echoes(&r),
        [
            "VV",
            "VV",
            "PP",
            "II",
            "BM",
            "CR00",
            "VV",
            "PP",
            "II",
            "GD0044072501"
        ]
    );
    assert_eq!(stats.checksum_errors(), 0);
    assert_eq!(stats.lenient_accepts, 0);
    assert_eq!(stats.desyncs, 0);
    assert_eq!(stats.replies, 10);
    let statuses: Vec<_> = r.iter().map(|o| o.status).collect();
    let ok = Status::Scip2(StatusCode::OK);
    assert_eq!(
        statuses,
        [
            ok,
            ok,
            ok,
            ok,
            Status::Scip2(StatusCode(*b"02")),
            Status::Scip2(StatusCode(*b"03")),
            ok,
            ok,
            ok,
            ok
        ]
    );
    assert_eq!(r[9].lines.len(), 1 + 32, "timestamp + 32 data lines");
    assert_eq!(r[9].lines[32].len(), 62);
}

#[test]
fn urg_04lx_typed_values() {
    sweepline::require_shared!(URG);
    let mut params: Option<SensorParams> = None;
    let mut times = Vec::new();
    let n = for_each_typed(URG, |i, reply| match (&reply.echo.command, &reply.body) {
        (Command::Vv, ReplyBody::Version(v)) => {
            assert_eq!(v.vendor, "Hokuyo Automatic Co.,Ltd.");
            assert_eq!(v.product, "SOKUIKI Sensor URG-04LX");
            assert_eq!(v.firmware, "3.1.04(02/Aug./2007)");
            assert_eq!(v.protocol, "SCIP 2.0");
            assert_eq!(v.serial, "H0706400");
            assert!(v.extra.is_empty());
        }
        (Command::Pp, ReplyBody::Params(p)) => {
            assert_eq!(p.model, "URG-04LX(Hokuyo Automatic Co.,Ltd.)");
            assert_eq!(
                (p.dmin, p.dmax, p.ares, p.amin, p.amax, p.afrt, p.scan_rpm),
                (20, 5600, 1024, 44, 725, 384, 600)
            );
            assert_eq!(p, &SensorParams::urg_04lx());
            params = Some(p.clone());
        }
        (Command::Ii, ReplyBody::Info(info)) => {
            assert_eq!(info.model, "URG-04LX(Hokuyo Automatic Co.,Ltd.)");
            assert_eq!(info.laser_on(), Some(true));
            assert_eq!(
                info.scan_speed,
                "Initial(600[rpm])<-Default setting by user"
            );
            assert_eq!(info.measure_mode, "CLASSIC");
            assert_eq!(info.bit_rate, "19200[bps]<-Default setting by user");
            assert_eq!(info.state, "Sensor works well.");
            times.push(info.time_ms().expect("hex TIME"));
        }
        (Command::Bm, ReplyBody::Empty) => {
            let code = reply.status.code().unwrap();
            assert_eq!(code, StatusCode(*b"02"));
            assert!(reply.status.is_success(scip::CommandKind::Bm));
            assert_eq!(code.meaning(scip::CommandKind::Bm), "laser already on");
        }
        (Command::Cr(0), ReplyBody::Empty) => {
            assert_eq!(reply.status.code(), Some(StatusCode(*b"03")));
            assert!(reply.status.is_success(scip::CommandKind::Cr));
        }
        (Command::Get(req), ReplyBody::Scan(scan)) => {
            assert_eq!(
                (req.start, req.end, req.kind),
                (44, 725, DataKind::Distance)
            );
            assert_eq!(scan.timestamp, 6_968_830);
            assert_eq!(scan.remaining, None);
            let p = params.as_ref().expect("PP before GD");
            let values: Vec<_> = scan.values().collect();
            assert_eq!(values.len(), 682);
            assert_eq!(values.iter().filter(|v| v.distance < 20).count(), 101);
            let front = values.iter().find(|v| v.step == 384).unwrap();
            assert_eq!(front.distance, 4152);
            assert_eq!(values[0].step, 44);
            assert_eq!(values[681].step, 725);
            let errors = scan
                .readings(p)
                .filter(|(_, r)| matches!(r, Reading::Error(_)))
                .count();
            assert_eq!(errors, 101);
            assert_eq!(p.family(), ModelFamily::Urg04lx);

            let mut ls = sweepline::scan::LaserScan::default();
            let n = sweepline::urg::fill_laser_scan(scan, p, 12.5, 7, &mut ls).unwrap();
            assert_eq!(n, 682);
            assert_eq!(ls.seq, 7);
            let beyond = values.iter().filter(|v| v.distance > 5600).count();
            assert_eq!(ls.valid_count(), 682 - 101 - beyond);
            let fb = ls.beams[384 - 44];
            assert_eq!(fb.angle, 0.0);
            assert!((fb.range - 4.152).abs() < 1e-12);
            let step = std::f64::consts::TAU / 1024.0;
            assert!((ls.beams[0].angle - (44.0 - 384.0) * step).abs() < 1e-12);
            assert!((ls.beams[681].angle - (725.0 - 384.0) * step).abs() < 1e-12);
            assert!(ls.beams.iter().all(|b| b.valid || b.intensity == 0.0));
            // 600 rpm, 1024 steps a turn: the 682 beams swept one step
            // (97.7 µs) apart, 66.5 ms from the first to the last.
            assert_eq!(ls.first_beam_time, 0.0);
            assert!((ls.beam_interval - 0.1 / 1024.0).abs() < 1e-15);
            assert!((ls.beam_time(681) - 681.0 * 0.1 / 1024.0).abs() < 1e-12);
        }
        other => panic!("reply {i}: unexpected {other:?}"),
    });
    assert_eq!(n, 10);
    assert_eq!(times, [0x6A5404, 6_968_824]);
}

/// The emulator's promise: re-encoding each decoded reply gives the sensor's
/// exact bytes, for all three models.
#[test]
fn replies_reencode_byte_exactly() {
    for rel in [URG, UTM, UXM] {
        sweepline::require_shared!(rel);
        let original: Vec<u8> = records(rel).into_iter().flat_map(|r| r.bytes).collect();
        let mut encoded = Vec::new();
        for_each_typed(rel, |_, reply| {
            scip::encode_reply(&reply.echo, reply.status, &reply.body, &mut encoded).unwrap();
        });
        assert_eq!(
            String::from_utf8_lossy(&encoded),
            String::from_utf8_lossy(&original),
            "{rel}"
        );
    }
}

#[test]
fn every_written_command_parses_and_reencodes() {
    for rel in [
        "datasets/hokuyo-captures/example_urg_04lx.logw",
        "datasets/hokuyo-captures/example_utm_30lx.logw",
        "datasets/hokuyo-captures/example_uxm_30lx_e.logw",
    ] {
        sweepline::require_shared!(rel);
        let written: Vec<u8> = records(rel).into_iter().flat_map(|r| r.bytes).collect();
        let mut n = 0;
        for line in written.split(|&b| b == b'\n').filter(|l| !l.is_empty()) {
            let cmd = TaggedCommand::parse(line).unwrap_or_else(|e| panic!("{rel}: {e}"));
            let mut out = Vec::new();
            cmd.encode(&mut out).unwrap();
            assert_eq!(&out[..out.len() - 1], line);
            n += 1;
        }
        assert!(n >= 10, "{rel}: only {n} commands");
    }
}

#[test]
fn utm_30lx_me_scan_with_intensities() {
    sweepline::require_shared!(UTM);
    let (r, stats) = replies(UTM);
    assert_eq!(
        echoes(&r),
        [
            "VV",
            "VV",
            "PP",
            "II",
            "BM",
            "CR00",
            "VV",
            "PP",
            "II",
            "ME0000108001101",
            "ME0000108001100"
        ]
    );
    assert_eq!(stats.checksum_errors(), 0);
    let mut params = None;
    let mut scans = 0;
    for_each_typed(UTM, |_, reply| match &reply.body {
        ReplyBody::Params(p) => {
            assert_eq!(
                (p.dmin, p.dmax, p.ares, p.amin, p.amax, p.afrt, p.scan_rpm),
                (23, 60000, 1440, 0, 1080, 540, 2400)
            );
            assert_eq!(p.family(), ModelFamily::TimeOfFlight);
            assert!((p.scan_period() - 0.025).abs() < 1e-12);
            params = Some(p.clone());
        }
        ReplyBody::Info(i) => {
            assert_eq!(i.bit_rate, "USB Full Speed");
            let t = i.time_ms().unwrap();
            assert!(t == 0x4991D0 || t == 0x49924D, "{t}");
        }
        ReplyBody::Version(v) => assert_eq!(v.firmware, "P.1.05(17/Apr./2009)"),
        ReplyBody::Scan(scan) => {
            scans += 1;
            assert_eq!(reply.status, Status::Scip2(StatusCode::DATA));
            assert_eq!(scan.remaining, Some(0));
            assert_eq!(scan.request.kind, DataKind::DistanceIntensity);
            assert_eq!(scan.timestamp, EXPECTED_UTM_TIMESTAMP);
            let values: Vec<_> = scan.values().collect();
            assert_eq!(values.len(), 1081);
            assert_eq!((values[0].distance, values[0].intensity), (45, Some(1809)));
            assert!(values.iter().all(|v| v.intensity.is_some()));
            let p = params.as_ref().unwrap();
            let mut ls = sweepline::scan::LaserScan::default();
            sweepline::urg::fill_laser_scan(scan, p, 0.0, 0, &mut ls).unwrap();
            assert_eq!(ls.beams.len(), 1081);
            assert!(ls
                .beams
                .iter()
                .filter(|b| b.valid)
                .all(|b| b.intensity > 0.0));
            assert!((ls.beams[540].angle).abs() < 1e-12);
        }
        ReplyBody::Empty => {}
        other => panic!("unexpected {other:?}"),
    });
    assert_eq!(scans, 1);
}

/// `BI9Y`, decoded by hand: 4821609 ms (the II TIME just before it was 0x49924D = 4821581).
const EXPECTED_UTM_TIMESTAMP: u32 = 4_821_609;

#[test]
fn uxm_30lx_e_time_sync_sequence() {
    sweepline::require_shared!(UXM);
    let (r, stats) = replies(UXM);
    assert_eq!(stats.checksum_errors(), 0);
    assert_eq!(r.len(), 4 + 1 + 10 + 1 + 2 + 3 + 1);
    let mut times = Vec::new();
    let mut gd = 0;
    for_each_typed(UXM, |_, reply| match (&reply.echo.command, &reply.body) {
        (Command::Tm(scip::TimeControl::Read), ReplyBody::Time(t)) => times.push(*t),
        (Command::Get(_), ReplyBody::Scan(scan)) => {
            gd += 1;
            assert_eq!(scan.values().count(), 761);
        }
        _ => {}
    });
    assert_eq!(times, EXPECTED_UXM_TIMES);
    assert_eq!(gd, 1);
}

/// `<Sfk` .. `<Sg3` decoded by hand; note the repeated stamp (two TM1 within 1 ms).
const EXPECTED_UXM_TIMES: [u32; 10] = [
    3_292_603, 3_292_604, 3_292_605, 3_292_606, 3_292_607, 3_292_607, 3_292_608, 3_292_609,
    3_292_610, 3_292_611,
];

/// Draws the real URG-04LX GD scan (valid beams as points, error readings as
/// grey rays) to `target/tmp/scip_golden_urg04lx_gd.svg`, for a person to look at.
#[test]
fn urg_04lx_scan_picture() {
    use svg::node::element::{Circle, Line, Rectangle};
    sweepline::require_shared!(URG);
    let mut doc = svg::Document::new().set("viewBox", (-6.0, -6.0, 12.0, 12.0));
    doc = doc.add(
        Rectangle::new()
            .set("x", -6)
            .set("y", -6)
            .set("width", 12)
            .set("height", 12)
            .set("fill", "white"),
    );
    let mut params = None;
    let mut drawn = 0;
    let mut picture = Some(doc);
    for_each_typed(URG, |_, reply| match &reply.body {
        ReplyBody::Params(p) => params = Some(p.clone()),
        ReplyBody::Scan(scan) => {
            let p = params.as_ref().unwrap();
            let mut ls = sweepline::scan::LaserScan::default();
            sweepline::urg::fill_laser_scan(scan, p, 0.0, 0, &mut ls).unwrap();
            let mut d = picture.take().unwrap();
            for b in ls.beams.iter() {
                // SVG y grows downwards: flip so the picture is x right, y up.
                let (s, c) = b.angle.sin_cos();
                if b.valid {
                    d = d.add(
                        Circle::new()
                            .set("cx", b.range * c)
                            .set("cy", -b.range * s)
                            .set("r", 0.03)
                            .set("fill", "black"),
                    );
                    drawn += 1;
                } else {
                    d = d.add(
                        Line::new()
                            .set("x1", 0)
                            .set("y1", 0)
                            .set("x2", 0.5 * c)
                            .set("y2", -0.5 * s)
                            .set("stroke", "#bbb")
                            .set("stroke-width", 0.01),
                    );
                }
            }
            // The sensor's front (+x) in red.
            d = d.add(
                Line::new()
                    .set("x1", 0)
                    .set("y1", 0)
                    .set("x2", 1)
                    .set("y2", 0)
                    .set("stroke", "red")
                    .set("stroke-width", 0.03),
            );
            picture = Some(d);
        }
        _ => {}
    });
    assert_eq!(drawn, 581);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    std::fs::create_dir_all(dir).unwrap();
    let out = dir.join("scip_golden_urg04lx_gd.svg");
    svg::save(&out, &picture.unwrap()).unwrap();
}
