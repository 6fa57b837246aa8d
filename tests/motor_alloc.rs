//! The wheel-base drivers allocate nothing in steady state: a counting global
//! allocator watches the control thread while it commands and polls an
//! emulated base over a pty (the emulator's own thread is not counted).

use std::sync::Arc;
use std::time::{Duration, Instant};

use sweepline::clock::{MonotonicClock, SharedClock};
use sweepline::config::Config;
use sweepline::motor::link::ConnectorOpener;
use sweepline::motor::{base_driver, BaseKind, DiffDriveBase, WheelSpeeds};
use sweepline::serial::DeviceConnector;
use sweepline::sim::base_emu::{spawn_on_pty, EmulatorConfig};

mod alloc_support;
use alloc_support::{allocs, set_counting, Counting};

#[global_allocator]
static A: Counting = Counting;

#[test]
fn steady_state_command_and_poll_do_not_allocate() {
    for kind in [BaseKind::Roboclaw, BaseKind::Create2] {
        let clock: SharedClock = Arc::new(MonotonicClock::new());
        let mut cfg = Config::default();
        cfg.motor.kind = kind;
        let emu =
            spawn_on_pty(EmulatorConfig::from_config(&cfg, kind), None, clock.clone()).unwrap();
        let opener = Box::new(ConnectorOpener(Box::new(DeviceConnector::new(
            emu.path().unwrap(),
        ))));
        let mut base: Box<dyn DiffDriveBase> =
            base_driver(kind, &cfg.motor, &cfg.robot, opener, clock.clone());
        let mut cycle = |watch: bool, i: u32| {
            let w = 0.05 + 0.001 * (i % 50) as f64;
            let now = clock.now();
            set_counting(watch);
            base.set_wheels(
                WheelSpeeds {
                    left: w,
                    right: w * 0.9,
                },
                now,
            )
            .unwrap();
            let fb = base.poll(now).unwrap();
            set_counting(false);
            fb
        };
        // Warm up: open the port, initialise, first odometry.
        let t0 = Instant::now();
        let mut i = 0;
        while t0.elapsed() < Duration::from_millis(500) {
            cycle(false, i);
            i += 1;
            std::thread::sleep(Duration::from_millis(20));
        }
        let before = allocs();
        let mut odometry = 0;
        for _ in 0..40 {
            let fb = cycle(true, i);
            assert!(fb.link_up, "{kind:?}: link down");
            odometry += usize::from(fb.odometry.is_some());
            i += 1;
            std::thread::sleep(Duration::from_millis(20));
        }
        let n = allocs() - before;
        assert!(odometry > 30, "{kind:?}: only {odometry} odometry updates");
        assert_eq!(n, 0, "{kind:?}: {n} allocations in 40 steady-state cycles");
        drop(base);
        emu.shutdown();
    }
}
