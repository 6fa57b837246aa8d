//! Bad input and missing hardware: typed errors with messages a person
//! understands, never a panic.

use std::sync::Arc;

use sweepline::clock::{MonotonicClock, SharedClock};
use sweepline::config::Config;
use sweepline::motor::link::ConnectorOpener;
use sweepline::motor::{base_driver, BaseKind, DiffDriveBase, MotorError, WheelSpeeds};
use sweepline::serial::DeviceConnector;

fn driver(kind: BaseKind, path: &str) -> Box<dyn DiffDriveBase> {
    let clock: SharedClock = Arc::new(MonotonicClock::new());
    let cfg = Config::default();
    let opener = Box::new(ConnectorOpener(Box::new(DeviceConnector::new(path))));
    base_driver(kind, &cfg.motor, &cfg.robot, opener, clock)
}

#[test]
fn missing_device_is_reported_not_fatal() {
    for kind in [BaseKind::Roboclaw, BaseKind::Create2] {
        let mut b = driver(kind, "/nonexistent/sweepline-base");
        for _ in 0..3 {
            let fb = b.poll(0.0).expect("poll never fails for a missing device");
            assert!(!fb.link_up);
            assert!(fb.odometry.is_none());
        }
        // Commands are accepted (and held) while the link is down.
        b.set_wheels(
            WheelSpeeds {
                left: 0.1,
                right: 0.1,
            },
            0.0,
        )
        .unwrap();
        let e = b.stop().unwrap_err();
        assert!(matches!(e, MotorError::NotConnected { .. }), "{e:?}");
        assert!(e.to_string().contains("/nonexistent/sweepline-base"), "{e}");
        assert_eq!(b.health().reconnects, 0);
    }
}

#[test]
fn non_finite_wheel_commands_are_refused() {
    for kind in [BaseKind::Roboclaw, BaseKind::Create2] {
        let mut b = driver(kind, "/nonexistent/sweepline-base");
        for (l, r) in [
            (f64::NAN, 0.0),
            (0.0, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NAN),
        ] {
            let e = b
                .set_wheels(WheelSpeeds { left: l, right: r }, 0.0)
                .unwrap_err();
            assert!(matches!(e, MotorError::BadCommand { .. }), "{e:?}");
            assert!(e.to_string().contains("not a finite number"), "{e}");
        }
    }
}
