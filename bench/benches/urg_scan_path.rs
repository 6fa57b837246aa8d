//! Cost of one scan on the driver side: the session reading, framing,
//! verifying, decoding, unwrapping, stamping and publishing one 682-step
//! URG-04LX MD scan, measured lock-step over the in-process link to the
//! emulated sensor; and the emulator's cost of producing that scan alone,
//! so the driver's share is the difference. The room is noise-free so the
//! emulator's share stays small.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use criterion::{criterion_group, criterion_main, Criterion};
use sweepline::sim::urg_emu::{EmuLog, Faults, Model, ModelSpec, RectRoom, Sensor, SensorLink};
use sweepline::urg::{ManualClock, UrgHealth, UrgParams, UrgScan, UrgSession};

fn sensor() -> Sensor {
    Sensor::new(
        ModelSpec::of(Model::Urg04lx),
        Faults::default(),
        false,
        Box::new(RectRoom::new(4.0, 3.0, (1.5, 1.2, 0.0), 1)),
        1,
        Arc::new(Mutex::new(EmuLog::default())),
        0.0,
    )
}

fn bench(c: &mut Criterion) {
    let clock = Arc::new(ManualClock::new(0.0));
    let link = SensorLink::new(sensor(), clock.clone());
    let mut session = UrgSession::open(
        Box::new(link),
        UrgParams::default(),
        clock.clone(),
        Arc::new(UrgHealth::default()),
        Arc::new(AtomicBool::new(false)),
        None,
        Box::new(|s: &UrgScan| {
            std::hint::black_box(s.scan.beams.len());
        }),
    )
    .unwrap();
    session.start_stream().unwrap();
    c.bench_function("urg/session_next_scan_incl_emulator", |b| {
        b.iter(|| session.next_scan().unwrap())
    });

    let mut s = sensor();
    let mut out = Vec::with_capacity(8192);
    s.on_line(b"MD0044072501000", 0.0, &mut out);
    let mut t = 0.0;
    c.bench_function("urg/emulator_scan_only", |b| {
        b.iter(|| {
            t += 0.1;
            out.clear();
            s.poll(t, &mut out);
            std::hint::black_box(out.len())
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
