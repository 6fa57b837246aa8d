//! Wheel-base codec and odometry costs: encoding a RoboClaw speed packet,
//! decoding an encoder reply, parsing a Create 2 sensor-stream frame, and one
//! odometry update.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;

use sweepline::motor::create2::codec::{encode_stream_frame, SensorState, StreamParser};
use sweepline::motor::odometry::{CounterWidth, Odometer};
use sweepline::motor::roboclaw::codec::{
    cmd, encode_command, encode_reply, Command, Query, Reply, ReplyDecoder,
};

fn codecs(c: &mut Criterion) {
    c.bench_function("roboclaw_encode_drive_speeds", |b| {
        b.iter(|| encode_command(0x80, black_box(&Command::speeds(1234, -987))))
    });
    let reply = encode_reply(0x80, cmd::READ_ENCODERS, &Reply::Pair32(5, 7));
    c.bench_function("roboclaw_decode_encoder_reply", |b| {
        b.iter(|| {
            let mut d = ReplyDecoder::new(0x80, &Command::Query(Query::Encoders));
            let mut out = None;
            for &x in black_box(&reply[..]) {
                out = d.push(x).ok().flatten();
            }
            out
        })
    });
    let frame = encode_stream_frame(
        &[7, 35, 43, 44],
        &SensorState {
            left_encoder: 100,
            right_encoder: 200,
            ..Default::default()
        },
    );
    let mut p =
        StreamParser::with_payload_len(StreamParser::payload_len(&[7, 35, 43, 44]).unwrap());
    c.bench_function("create2_parse_stream_frame", |b| {
        b.iter(|| {
            let mut n = 0;
            p.feed(black_box(&frame[..]), &mut |r| n += usize::from(r.is_ok()));
            n
        })
    });
    let mut o = Odometer::new(CounterWidth::Bits16, 2250.0, 0.235, 0.5);
    let mut t = 0.0;
    let mut k: u32 = 0;
    c.bench_function("odometry_update", |b| {
        b.iter(|| {
            t += 0.015;
            k = k.wrapping_add(7);
            o.update(black_box(k), black_box(k + 1), t).ok()
        })
    });
}

criterion_group!(benches, codecs);
criterion_main!(benches);
