//! Decoding a scan in steady state allocates nothing: a counting global
//! allocator watches 200 MD scans go from bytes (in awkward read() chunks)
//! through the decoder, the typed reply and into a `LaserScan`.

mod alloc_support;

use sweepline::scan::LaserScan;
use sweepline::scip::{
    self, Cluster, Command, DataKind, Decoder, Event, ReplyBody, ScanRequest, SensorParams, Status,
    StatusCode, StreamRequest, TaggedCommand, Width,
};

use alloc_support::{allocs, set_counting, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

/// An MD stream of `n` URG-04LX scans (682 steps) as the sensor sends it.
fn md_stream(n: usize) -> Vec<u8> {
    let req = ScanRequest {
        kind: DataKind::Distance,
        start: 44,
        end: 725,
        cluster: Cluster::Steps(1),
    };
    let stream = StreamRequest {
        scan: req,
        skip: 0,
        count: 0,
    };
    let mut out = Vec::new();
    let ok = TaggedCommand::new(Command::Stream(stream));
    scip::encode_reply(
        &ok,
        Status::Scip2(StatusCode::OK),
        &ReplyBody::Empty,
        &mut out,
    )
    .unwrap();
    for k in 0..n {
        let mut chars = Vec::new();
        let values = (0..682u32).map(|i| {
            if i % 7 == 0 {
                7
            } else {
                300 + (i * 13 + k as u32) % 5000
            }
        });
        scip::scan::encode_fields(values, Width::Three, &mut chars).unwrap();
        let scan = scip::ScanData::new(req, Some(0), (k as u32 * 100) & 0xff_ffff, &chars).unwrap();
        scip::encode_reply(
            &ok,
            Status::Scip2(StatusCode::DATA),
            &ReplyBody::Scan(scan),
            &mut out,
        )
        .unwrap();
    }
    out
}

fn decode_all(
    dec: &mut Decoder,
    bytes: &[u8],
    params: &SensorParams,
    out: &mut LaserScan,
) -> (usize, usize) {
    let mut scans = 0;
    let mut valid = 0;
    // Awkward read() sizes, as a USB-CDC port delivers them.
    for chunk in bytes.chunks(61) {
        let mut rest = chunk;
        while !rest.is_empty() {
            let (n, ev) = dec.feed(rest);
            rest = &rest[n..];
            if let Some(Event::Reply(raw)) = ev {
                match raw.decode() {
                    Ok(reply) => {
                        if let ReplyBody::Scan(s) = &reply.body {
                            sweepline::urg::fill_laser_scan(s, params, 0.0, scans as u64, out)
                                .unwrap();
                            valid += out.valid_count();
                            scans += 1;
                        }
                    }
                    Err(e) => panic!("{e}"),
                }
            }
        }
    }
    (scans, valid)
}

#[test]
fn decoding_md_scans_allocates_nothing_in_steady_state() {
    let bytes = md_stream(200);
    let params = SensorParams::urg_04lx();
    let mut dec = Decoder::default();
    let mut scan = LaserScan::default();
    // Warm-up pass (first use of every buffer).
    let (warm, _) = decode_all(&mut dec, &bytes, &params, &mut scan);
    assert_eq!(warm, 200);

    let before = allocs();
    set_counting(true);
    let (scans, valid) = decode_all(&mut dec, &bytes, &params, &mut scan);
    set_counting(false);
    let allocs = allocs() - before;

    assert_eq!(scans, 200);
    assert_eq!(valid, 200 * (682 - 98), "every 7th step is error code 7");
    assert_eq!(allocs, 0, "allocations while decoding scans");
}

/// The counter really counts (so the zero above means something).
#[test]
fn the_counting_allocator_sees_allocations() {
    let before = allocs();
    set_counting(true);
    let v: Vec<u64> = std::hint::black_box(Vec::with_capacity(16));
    set_counting(false);
    drop(v);
    assert!(allocs() > before);
}
