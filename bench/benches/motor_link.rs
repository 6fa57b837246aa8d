//! One control cycle (set wheels + poll) of each driver against its emulator
//! through a real pty: RoboClaw = three request/reply exchanges (speeds,
//! encoders, status); Create 2 = one Drive Direct plus reading the stream.

use std::sync::Arc;

use criterion::{criterion_group, criterion_main, Criterion};
use sweepline::clock::{MonotonicClock, SharedClock};
use sweepline::config::Config;
use sweepline::motor::link::ConnectorOpener;
use sweepline::motor::{base_driver, BaseKind, DiffDriveBase, WheelSpeeds};
use sweepline::serial::DeviceConnector;
use sweepline::sim::base_emu::{spawn_on_pty, EmulatorConfig};

fn cycle(c: &mut Criterion) {
    for kind in [BaseKind::Roboclaw, BaseKind::Create2] {
        let clock: SharedClock = Arc::new(MonotonicClock::new());
        let mut cfg = Config::default();
        cfg.motor.kind = kind;
        // A benchmark loop commands far faster than the dead-man needs.
        let emu = spawn_on_pty(EmulatorConfig::from_config(&cfg, kind), None, clock.clone())
            .expect("emulator");
        let opener = Box::new(ConnectorOpener(Box::new(DeviceConnector::new(
            emu.path().expect("pty path"),
        ))));
        let mut base: Box<dyn DiffDriveBase> =
            base_driver(kind, &cfg.motor, &cfg.robot, opener, clock.clone());
        for _ in 0..50 {
            let _ = base.poll(clock.now());
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        let name = format!("{kind:?}_set_wheels_and_poll_over_pty").to_lowercase();
        let ahead = WheelSpeeds {
            left: 0.1,
            right: 0.1,
        };
        c.bench_function(&name, |b| {
            b.iter(|| {
                let now = clock.now();
                base.set_wheels(ahead, now).expect("finite");
                base.poll(now).expect("poll")
            })
        });
        drop(base);
        emu.shutdown();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = cycle
}
criterion_main!(benches);
