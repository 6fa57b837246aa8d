//! Cost of the pipeline machinery per item: edges, clocks, histograms, the
//! cross-thread hand-over, and checkpoints of a realistic size.
//! `cargo bench -p sweepline-bench --bench pipeline_machinery -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Point2;
use sweepline::geom::pose;
use sweepline::grid::Grid;
use sweepline::pipeline::checkpoint::{Checkpoint, CheckpointStore, RunProgress};
use sweepline::pipeline::clock::{process_cpu_time, thread_cpu_time, Stamp};
use sweepline::pipeline::metrics::LatencyHistogram;
use sweepline::pipeline::{latest, queue, Overflow, Recv};

fn edges(c: &mut Criterion) {
    let (tx, rx) = latest::<[u16; 682]>("scan");
    c.bench_function("latest: send onto a full slot (drop oldest)", |b| {
        tx.send([0; 682]).unwrap();
        b.iter(|| tx.send(black_box([1; 682])).unwrap())
    });
    c.bench_function("latest: send + try_recv", |b| {
        b.iter(|| {
            tx.send(black_box([2; 682])).unwrap();
            black_box(rx.try_recv())
        })
    });
    let (qtx, qrx) = queue::<u64>("q", 4, Overflow::DropOldest);
    c.bench_function("queue(4): send + try_recv", |b| {
        b.iter(|| {
            qtx.send(black_box(7)).unwrap();
            black_box(qrx.try_recv())
        })
    });
}

fn clocks_and_histograms(c: &mut Criterion) {
    c.bench_function("Stamp::now (CLOCK_MONOTONIC)", |b| b.iter(Stamp::now));
    c.bench_function("thread_cpu_time (CLOCK_THREAD_CPUTIME_ID)", |b| {
        b.iter(thread_cpu_time)
    });
    c.bench_function("process_cpu_time (getrusage)", |b| b.iter(process_cpu_time));
    let mut h = LatencyHistogram::new();
    let mut v = 1u64;
    c.bench_function("LatencyHistogram::record", |b| {
        b.iter(|| {
            v = v
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            h.record_ns(black_box(v >> 40));
        })
    });
    let mut copy = LatencyHistogram::new();
    c.bench_function("LatencyHistogram::copy_from (stage publish)", |b| {
        b.iter(|| copy.copy_from(black_box(&h)))
    });
}

/// One-way hand-over latency between two threads through a newest-wins edge
/// (producer stamps, consumer measures), the per-edge cost inside the
/// end-to-end latency.
fn hand_over(c: &mut Criterion) {
    c.bench_function("latest: cross-thread round trip", |b| {
        b.iter_custom(|iters| {
            let (ptx, prx) = latest::<Stamp>("ping");
            let (qtx, qrx) = latest::<Stamp>("pong");
            let echo = std::thread::spawn(move || loop {
                match prx.recv_timeout(Duration::from_secs(1)) {
                    Recv::Msg(s) => {
                        if qtx.send(s).is_err() {
                            return;
                        }
                    }
                    _ => return,
                }
            });
            let t = Instant::now();
            for _ in 0..iters {
                ptx.send(Stamp::now()).unwrap();
                loop {
                    if let Recv::Msg(_) = qrx.recv_timeout(Duration::from_secs(1)) {
                        break;
                    }
                }
            }
            let took = t.elapsed();
            drop(ptx);
            echo.join().unwrap();
            took
        })
    });
}

fn checkpoints(c: &mut Criterion) {
    // 20 m x 20 m at 5 cm: 400 x 400 cells.
    let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 400, 400);
    for i in 0..400 {
        g.integrate_ray(
            &Point2::new(10.0, 10.0),
            &Point2::new(i as f64 * 0.05, 19.9),
            true,
        );
    }
    let mut cp = Checkpoint::new();
    cp.put(&pose(1.0, 2.0, 0.3)).unwrap();
    cp.put(&g).unwrap();
    cp.put(&RunProgress::default()).unwrap();
    let bytes = cp.to_bytes();
    c.bench_function("checkpoint 400x400 grid: to_bytes", |b| {
        b.iter(|| black_box(cp.to_bytes()))
    });
    c.bench_function("checkpoint 400x400 grid: from_bytes", |b| {
        b.iter(|| black_box(Checkpoint::from_bytes(&bytes).unwrap()))
    });
    let dir = std::env::temp_dir().join(format!("sweepline-bench-{}", std::process::id()));
    let store = CheckpointStore::new(&dir);
    c.bench_function("checkpoint 400x400 grid: atomic save (fsync)", |b| {
        b.iter(|| store.save(&cp).unwrap())
    });
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(
    benches,
    edges,
    clocks_and_histograms,
    hand_over,
    checkpoints
);
criterion_main!(benches);
