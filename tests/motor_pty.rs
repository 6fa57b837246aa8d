//! The wheel-base drivers against the emulated bases through real ptys: the
//! driver opens the emulator's pty path exactly as it opens a device.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use sweepline::clock::{MonotonicClock, ScaledClock, SharedClock};
use sweepline::config::Config;
use sweepline::geom::{heading, pose, Pose};
use sweepline::motor::create2::driver::Create2Driver;
use sweepline::motor::link::ConnectorOpener;
use sweepline::motor::roboclaw::driver::RoboClawDriver;
use sweepline::motor::{BaseKind, DiffDriveBase, SafetyEvent, WheelSpeeds};
use sweepline::serial::DeviceConnector;
use sweepline::sim::base_emu::{spawn_on_pty, EmulatorConfig, EmulatorHandle, Fault};
use sweepline::sim::kinematics::KinematicsParams;
use sweepline::sim::world::World;

const KINDS: [BaseKind; 2] = [BaseKind::Roboclaw, BaseKind::Create2];

struct Rig {
    clock: SharedClock,
    emu: EmulatorHandle,
    base: Box<dyn DiffDriveBase>,
    odom: Pose,
    events: Vec<SafetyEvent>,
    _dir: Option<TempDir>,
}

struct TempDir(PathBuf);
impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn rig(kind: BaseKind, world: Option<World>, start: Pose, symlink: bool) -> Rig {
    rig_on(Arc::new(MonotonicClock::new()), kind, world, start, symlink)
}

fn rig_on(
    clock: SharedClock,
    kind: BaseKind,
    world: Option<World>,
    start: Pose,
    symlink: bool,
) -> Rig {
    let mut cfg = Config::default();
    cfg.motor.kind = kind;
    let mut ecfg = EmulatorConfig::from_config(&cfg, kind);
    ecfg.start = start;
    ecfg.world = world.map(Arc::new);
    ecfg.kinematics = KinematicsParams {
        slip: 0.0,
        encoder_noise: 0.0,
        ..ecfg.kinematics
    };
    let dir = symlink.then(|| {
        let d = std::env::temp_dir().join(format!(
            "sweepline-motor-{}-{:?}-{}",
            std::process::id(),
            kind,
            Instant::now().elapsed().as_nanos() ^ (start.translation.x.to_bits() as u128)
        ));
        std::fs::create_dir_all(&d).unwrap();
        TempDir(d)
    });
    let link = dir.as_ref().map(|d| d.0.join("base"));
    let emu = spawn_on_pty(ecfg, link, clock.clone()).unwrap();
    let path = emu.path().unwrap();
    let opener = Box::new(ConnectorOpener(Box::new(DeviceConnector::new(path))));
    let base: Box<dyn DiffDriveBase> = match kind {
        BaseKind::Roboclaw => Box::new(RoboClawDriver::new(
            &cfg.motor,
            &cfg.robot,
            opener,
            clock.clone(),
        )),
        BaseKind::Create2 => Box::new(Create2Driver::new(
            &cfg.motor,
            &cfg.robot,
            opener,
            clock.clone(),
        )),
    };
    Rig {
        clock,
        emu,
        base,
        odom: Pose::identity(),
        events: Vec::new(),
        _dir: dir,
    }
}

impl Rig {
    /// Runs the 20 Hz control loop for `secs` of clock time, commanding `cmd`
    /// (or nothing).
    fn run(&mut self, secs: f64, cmd: Option<WheelSpeeds>) {
        let t0 = self.clock.now();
        while self.clock.now() - t0 < secs {
            let tick = self.clock.now();
            if let Some(c) = cmd {
                self.base.set_wheels(c).unwrap();
            }
            let fb = self.base.poll().unwrap();
            if let Some(o) = fb.odometry {
                self.odom *= o.delta;
            }
            self.events.extend(fb.events.iter().copied());
            let spent = self.clock.now() - tick;
            self.clock.sleep(0.05 - spent);
        }
    }

    fn saw(&self, f: impl Fn(&SafetyEvent) -> bool) -> bool {
        self.events.iter().any(f)
    }
}

#[test]
fn commands_move_the_robot_and_odometry_follows() {
    for kind in KINDS {
        let mut r = rig(kind, None, pose(0.0, 0.0, 0.0), false);
        r.run(
            1.0,
            Some(WheelSpeeds {
                left: 0.2,
                right: 0.2,
            }),
        );
        r.run(1.0, Some(WheelSpeeds::from_body(0.0, 0.5, 0.235)));
        r.run(0.3, Some(WheelSpeeds::STOP));
        let t = r.emu.truth();
        assert!(t.translation.x > 0.15, "{kind:?}: robot did not move: {t}");
        assert!(heading(&t) > 0.3, "{kind:?}: robot did not turn: {t}");
        let e = (t.translation.vector - r.odom.translation.vector).norm();
        let eh = (heading(&t) - heading(&r.odom)).abs();
        assert!(
            e < 0.01 && eh < 0.02,
            "{kind:?}: odometry {} vs truth {t}",
            r.odom
        );
        let h = r.base.health();
        assert!(h.received > 20, "{kind:?}: {h:?}");
        assert_eq!(h.checksum_errors, 0, "{kind:?}: {h:?}");
        assert_eq!(h.link_losses, 0, "{kind:?}: {h:?}");
        assert!(!r.saw(|e| matches!(e, SafetyEvent::LinkLost)));
    }
}

#[test]
fn deadman_stops_the_wheels_when_commands_stop() {
    for kind in KINDS {
        let mut r = rig(kind, None, pose(0.0, 0.0, 0.0), false);
        r.run(
            0.6,
            Some(WheelSpeeds {
                left: 0.2,
                right: 0.2,
            }),
        );
        assert!(r.emu.wheels().left > 0.1, "{kind:?}: not moving");
        // Polling goes on, commands do not.
        r.run(0.6, None);
        assert!(
            r.saw(|e| matches!(e, SafetyEvent::DeadMan)),
            "{kind:?}: {:?}",
            r.events
        );
        assert_eq!(r.emu.wheels(), WheelSpeeds::STOP, "{kind:?}");
        assert_eq!(r.base.health().deadman_stops, 1);
        // Fresh commands move it again.
        r.run(
            0.4,
            Some(WheelSpeeds {
                left: 0.1,
                right: 0.1,
            }),
        );
        assert!(r.emu.wheels().left > 0.05, "{kind:?}");
    }
}

fn check_silent_link(kind: BaseKind) {
    let mut r = rig(kind, None, pose(0.0, 0.0, 0.0), false);
    let cmd = Some(WheelSpeeds {
        left: 0.1,
        right: 0.1,
    });
    r.run(0.5, cmd);
    r.emu.inject(Fault::Silence { secs: 1.0 });
    r.run(0.8, cmd);
    assert!(
        r.saw(|e| matches!(e, SafetyEvent::LinkLost)),
        "{kind:?}: {:?}",
        r.events
    );
    if kind == BaseKind::Roboclaw {
        // The controller's own serial timeout stopped the motors.
        assert_eq!(r.emu.wheels(), WheelSpeeds::STOP, "{kind:?}");
        assert!(r.emu.stats().device.device_timeouts >= 1);
    }
    r.run(1.5, cmd);
    assert!(
        r.saw(|e| matches!(e, SafetyEvent::LinkRestored)),
        "{kind:?}: {:?}",
        r.events
    );
    let before = r.emu.truth().translation.x;
    r.run(0.5, cmd);
    assert!(
        r.emu.truth().translation.x > before + 0.02,
        "{kind:?}: not driving after recovery"
    );
    let h = r.base.health();
    assert_eq!(h.link_losses, 1, "{kind:?}: {h:?}");
    assert!(
        h.timeouts > 0 || kind == BaseKind::Create2,
        "{kind:?}: {h:?}"
    );
}

#[test]
fn silent_link_for_one_second_is_detected_and_recovered_roboclaw() {
    check_silent_link(BaseKind::Roboclaw);
}

#[test]
fn silent_link_for_one_second_is_detected_and_recovered_create2() {
    check_silent_link(BaseKind::Create2);
}

fn check_corrupted_bytes(kind: BaseKind) {
    let mut r = rig(kind, None, pose(0.0, 0.0, 0.0), false);
    let cmd = Some(WheelSpeeds {
        left: 0.15,
        right: 0.12,
    });
    r.run(0.4, cmd);
    r.emu.inject(Fault::CorruptOut { bytes: 40 });
    r.emu.inject(Fault::CorruptIn { bytes: 40 });
    r.run(1.5, cmd);
    r.run(0.3, Some(WheelSpeeds::STOP));
    let h = r.base.health();
    // A burst garbles whole replies/frames: they fail their CRC/checksum
    // or, with the header itself garbled, are skipped as noise.
    assert!(
        h.checksum_errors + h.nacks + h.discarded_bytes >= 5,
        "{kind:?}: {h:?}"
    );
    if kind == BaseKind::Roboclaw {
        assert!(h.checksum_errors > 0, "{kind:?}: {h:?}");
    }
    assert_eq!(h.odometry_glitches, 0, "{kind:?}: {h:?}");
    let es = r.emu.stats();
    assert!(es.corrupted_bytes >= 80, "{kind:?}: {es:?}");
    if kind == BaseKind::Roboclaw {
        assert!(es.device.packets_rejected > 0, "{kind:?}: {es:?}");
    }
    // No corrupted reading reached the odometry.
    let t = r.emu.truth();
    let e = (t.translation.vector - r.odom.translation.vector).norm();
    assert!(e < 0.02, "{kind:?}: odometry {} vs truth {t}", r.odom);
}

#[test]
fn corrupted_bytes_are_rejected_and_counted_roboclaw() {
    check_corrupted_bytes(BaseKind::Roboclaw);
}

#[test]
fn corrupted_bytes_are_rejected_and_counted_create2() {
    check_corrupted_bytes(BaseKind::Create2);
}

fn check_bumper_hit(kind: BaseKind) {
    let world = || World::parse("room 0 0 1.2 0 1.2 2 0 2\n").unwrap();
    let mut r = rig(kind, Some(world()), pose(0.7, 1.0, 0.0), false);
    let fwd = Some(WheelSpeeds {
        left: 0.2,
        right: 0.2,
    });
    r.run(2.0, fwd);
    assert!(
        r.saw(|e| matches!(e, SafetyEvent::Bumper(_))),
        "{kind:?}: {:?}",
        r.events
    );
    let x = r.emu.truth().translation.x;
    assert!(
        x > 1.0 && x < 1.2 - 0.17 + 0.021,
        "{kind:?}: stopped at {x}"
    );
    assert!(
        r.emu.wheels().left.abs() < 1e-9,
        "{kind:?}: {:?}",
        r.emu.wheels()
    );
    r.run(0.5, fwd);
    assert!(
        r.emu.truth().translation.x <= x + 1e-9,
        "{kind:?}: pushed on"
    );
    r.run(
        1.0,
        Some(WheelSpeeds {
            left: -0.1,
            right: -0.1,
        }),
    );
    assert!(
        r.emu.truth().translation.x < x - 0.03,
        "{kind:?}: did not back off"
    );
    assert!(
        r.saw(|e| matches!(e, SafetyEvent::BumperReleased)),
        "{kind:?}"
    );
    assert!(r.base.health().safety_stops >= 1);
}

#[test]
fn bumper_hit_stops_the_robot_and_only_reversing_is_allowed_roboclaw() {
    check_bumper_hit(BaseKind::Roboclaw);
}

#[test]
fn bumper_hit_stops_the_robot_and_only_reversing_is_allowed_create2() {
    check_bumper_hit(BaseKind::Create2);
}

#[test]
fn injected_bump_while_driving_in_the_open() {
    for kind in KINDS {
        let mut r = rig(kind, None, pose(0.0, 0.0, 0.0), false);
        let fwd = Some(WheelSpeeds {
            left: 0.2,
            right: 0.2,
        });
        r.run(0.5, fwd);
        r.emu.inject(Fault::Bump { secs: 0.5 });
        r.run(0.3, fwd);
        assert!(r.saw(|e| matches!(e, SafetyEvent::Bumper(_))), "{kind:?}");
        assert!(
            r.emu.wheels().left.abs() < 0.05,
            "{kind:?}: {:?}",
            r.emu.wheels()
        );
        r.run(0.8, fwd);
        assert!(
            r.saw(|e| matches!(e, SafetyEvent::BumperReleased)),
            "{kind:?}"
        );
        assert!(r.emu.wheels().left > 0.1, "{kind:?}: did not resume");
    }
}

#[test]
fn create2_wheel_drop_stops_and_safe_mode_is_re_entered() {
    let mut r = rig(BaseKind::Create2, None, pose(0.0, 0.0, 0.0), false);
    let fwd = Some(WheelSpeeds {
        left: 0.2,
        right: 0.2,
    });
    r.run(0.4, fwd);
    r.emu.inject(Fault::WheelDrop { secs: 0.4 });
    r.run(0.3, fwd);
    assert!(
        r.saw(|e| matches!(e, SafetyEvent::WheelDrop(_))),
        "{:?}",
        r.events
    );
    assert_eq!(r.emu.motor_targets(), WheelSpeeds::STOP);
    r.run(1.0, fwd);
    assert!(r.saw(|e| matches!(e, SafetyEvent::WheelDropCleared)));
    assert!(
        r.emu.motor_targets().left > 0.1,
        "Safe mode not re-entered: {:?}",
        r.emu.motor_targets()
    );
}

fn check_unplugged_base(kind: BaseKind) {
    let mut r = rig(kind, None, pose(0.0, 0.0, 0.0), true);
    let cmd = Some(WheelSpeeds {
        left: 0.1,
        right: 0.1,
    });
    r.run(0.4, cmd);
    r.emu.inject(Fault::Unplug { secs: 0.5 });
    r.run(2.0, cmd);
    let h = r.base.health();
    assert!(
        r.saw(|e| matches!(e, SafetyEvent::LinkLost)),
        "{kind:?}: {:?}",
        r.events
    );
    assert!(
        r.saw(|e| matches!(e, SafetyEvent::LinkRestored)),
        "{kind:?}: {:?} {h:?}",
        r.events
    );
    assert!(h.reconnects >= 2, "{kind:?}: {h:?}");
    assert!(
        r.emu.wheels().left > 0.05,
        "{kind:?}: not driving after replug"
    );
}

#[test]
fn unplugged_base_is_reopened_through_its_symlink_roboclaw() {
    check_unplugged_base(BaseKind::Roboclaw);
}

#[test]
fn unplugged_base_is_reopened_through_its_symlink_create2() {
    check_unplugged_base(BaseKind::Create2);
}

#[test]
fn time_scaled_clock_runs_the_same_code_path() {
    // Daemon side and emulator share one clock running 4x real time.
    for kind in KINDS {
        let clock: SharedClock = Arc::new(ScaledClock::new(4.0));
        let mut r = rig_on(clock, kind, None, pose(0.0, 0.0, 0.0), false);
        r.run(
            2.0,
            Some(WheelSpeeds {
                left: 0.2,
                right: 0.2,
            }),
        );
        let x = r.emu.truth().translation.x;
        assert!(x > 0.3, "{kind:?}: only {x} m in 2 s of clock time");
        let e = (r.emu.truth().translation.vector - r.odom.translation.vector).norm();
        assert!(e < 0.03, "{kind:?}: odometry off by {e}");
        r.run(0.8, None);
        assert!(r.saw(|e| matches!(e, SafetyEvent::DeadMan)), "{kind:?}");
        assert_eq!(r.emu.motor_targets(), WheelSpeeds::STOP, "{kind:?}");
        assert_eq!(
            r.base.health().link_losses,
            0,
            "{kind:?}: {:?}",
            r.base.health()
        );
    }
}
