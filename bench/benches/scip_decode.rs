//! Decoding one full 682-step URG-04LX MD scan: bytes → framer → checksums →
//! typed reply → values (and → `LaserScan`, and deskewed). Prints its own median/p99 over
//! 10,000 timed runs before criterion's estimate.
//!
//! `cargo bench -p sweepline-bench --bench scip_decode -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, Throughput};
use sweepline::pipeline::clock::thread_cpu_time;
use sweepline::scan::LaserScan;
use sweepline::scip::{
    self, Cluster, Command, DataKind, Decoder, Event, ReplyBody, ScanData, ScanRequest,
    SensorParams, Status, StatusCode, StreamRequest, TaggedCommand, Width,
};

/// One MD scan reply of a URG-04LX (682 steps, 3-character values), as sent.
fn md_scan_bytes() -> Vec<u8> {
    let req = ScanRequest {
        kind: DataKind::Distance,
        start: 44,
        end: 725,
        cluster: Cluster::Steps(1),
    };
    let echo = TaggedCommand::new(Command::Stream(StreamRequest {
        scan: req,
        skip: 0,
        count: 0,
    }));
    let mut chars = Vec::new();
    let values = (0..682u32).map(|i| if i % 9 == 0 { 0 } else { 20 + (i * 37) % 5500 });
    scip::scan::encode_fields(values, Width::Three, &mut chars).unwrap();
    let scan = scip::ScanData::new(req, Some(0), 6_968_830, &chars).unwrap();
    let mut out = Vec::new();
    scip::encode_reply(
        &echo,
        Status::Scip2(StatusCode::DATA),
        &ReplyBody::Scan(scan),
        &mut out,
    )
    .unwrap();
    out
}

/// Feeds `bytes` to the decoder and hands every scan reply that decodes to `f`.
fn each_scan(dec: &mut Decoder, bytes: &[u8], mut f: impl FnMut(&ScanData<'_>)) {
    let mut rest = bytes;
    while !rest.is_empty() {
        let (n, ev) = dec.feed(rest);
        rest = &rest[n..];
        if let Some(Event::Reply(raw)) = ev {
            if let Ok(reply) = raw.decode() {
                if let ReplyBody::Scan(s) = reply.body {
                    f(&s);
                }
            }
        }
    }
}

/// Decodes one reply and sums its values (so nothing is optimised away).
fn decode_sum(dec: &mut Decoder, bytes: &[u8]) -> u64 {
    let mut sum = 0u64;
    each_scan(dec, bytes, |s| {
        sum += s.values().map(|v| u64::from(v.distance)).sum::<u64>();
    });
    sum
}

fn decode_fill(
    dec: &mut Decoder,
    bytes: &[u8],
    params: &SensorParams,
    out: &mut LaserScan,
) -> usize {
    let mut n_beams = 0;
    each_scan(dec, bytes, |s| {
        n_beams = sweepline::urg::fill_laser_scan(s, params, 0.0, 0, out).unwrap_or(0);
    });
    n_beams
}

fn report(what: &str, mut t: Vec<f64>) {
    t.sort_by(f64::total_cmp);
    let n = t.len();
    println!(
        "{what}: median {:.2} us, p99 {:.2} us, max {:.2} us over {n} runs",
        t[n / 2],
        t[n * 99 / 100],
        t[n - 1]
    );
}

fn percentiles(what: &str, mut routine: impl FnMut() -> usize) {
    for _ in 0..1000 {
        black_box(routine());
    }
    let mut wall = Vec::with_capacity(10_000);
    let mut cpu = Vec::with_capacity(10_000);
    for _ in 0..10_000 {
        let (c0, w0) = (thread_cpu_time().as_secs_f64(), Instant::now());
        black_box(routine());
        let (w, c) = (
            w0.elapsed().as_nanos() as f64 / 1000.0,
            (thread_cpu_time().as_secs_f64() - c0) * 1e6,
        );
        wall.push(w);
        cpu.push(c);
    }
    println!("{what}:");
    report("  wall time      ", wall);
    report("  thread CPU time", cpu);
}

/// The GD reply of the real URG-04LX capture, when ../shared is present.
fn real_gd_reply() -> Option<Vec<u8>> {
    let path = sweepline::testdata::shared_file("datasets/hokuyo-captures/example_urg_04lx.logr")?;
    let data = std::fs::read(path).ok()?;
    let bytes: Vec<u8> = scip::parse_capture(&data)
        .ok()?
        .into_iter()
        .flat_map(|r| r.bytes)
        .collect();
    let at = bytes.windows(3).position(|w| w == b"GD0")?;
    Some(bytes[at..].to_vec())
}

fn main() {
    let bytes = md_scan_bytes();
    let params = SensorParams::urg_04lx();
    let mut dec = Decoder::default();
    let mut out = LaserScan::default();
    percentiles(
        "md_scan_682 decode (bytes -> verified typed scan -> values)",
        || decode_sum(&mut dec, black_box(&bytes)) as usize,
    );
    percentiles("md_scan_682 to LaserScan (bytes -> LaserScan)", || {
        decode_fill(&mut dec, black_box(&bytes), &params, &mut out)
    });
    // The same scan deskewed as the daemon does for a robot turning at
    // 0.78 rad/s and driving at 0.226 m/s (the scan decoded again each
    // time: deskewing clears its beam timing).
    let mount = sweepline::geom::pose(0.1, 0.0, 0.0);
    let motion = sweepline::geom::pose(0.0226, 0.0009, 0.078);
    percentiles("md_scan_682 to LaserScan, deskewed", || {
        let n = decode_fill(&mut dec, black_box(&bytes), &params, &mut out);
        sweepline::daemon::stages::deskew(&mut out, &motion, &mount);
        n
    });
    if let Some(gd) = real_gd_reply() {
        percentiles("real URG-04LX GD capture to LaserScan", || {
            decode_fill(&mut dec, black_box(&gd), &params, &mut out)
        });
    }

    let mut c = Criterion::default().configure_from_args();
    let mut g = c.benchmark_group("scip");
    g.throughput(Throughput::Bytes(bytes.len() as u64));
    g.bench_function("md_scan_682_decode", |b| {
        b.iter(|| decode_sum(&mut dec, black_box(&bytes)))
    });
    g.bench_function("md_scan_682_to_laserscan", |b| {
        b.iter(|| decode_fill(&mut dec, black_box(&bytes), &params, &mut out))
    });
    g.bench_function("md_scan_682_to_laserscan_deskewed", |b| {
        b.iter(|| {
            decode_fill(&mut dec, black_box(&bytes), &params, &mut out);
            sweepline::daemon::stages::deskew(&mut out, &motion, &mount);
        })
    });
    g.finish();
    c.final_summary();
}
