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
use sweepline::motor::{
    base_driver, BaseKind, DiffDriveBase, MotorParams, SafetyEvent, WheelSpeeds,
};
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
    battery: Option<f64>,
    _dir: Option<TempDir>,
}

struct TempDir(PathBuf);
impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn rig(kind: BaseKind, world: Option<World>, start: Pose, symlink: bool) -> Rig {
    rig_on(
        Arc::new(MonotonicClock::new()),
        kind,
        world,
        start,
        symlink,
        tolerant,
    )
}

/// Timings with headroom for a heavily loaded test machine; tests of a
/// specific timing set it themselves.
fn tolerant(m: &mut MotorParams) {
    m.deadman = 0.6;
    m.link_timeout = 0.6;
    m.roboclaw.reply_timeout = 0.05;
    m.roboclaw.serial_timeout = 1.0;
}

fn rig_on(
    clock: SharedClock,
    kind: BaseKind,
    world: Option<World>,
    start: Pose,
    symlink: bool,
    tweak: impl FnOnce(&mut MotorParams),
) -> Rig {
    let mut cfg = Config::default();
    cfg.motor.kind = kind;
    tweak(&mut cfg.motor);
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
    let base: Box<dyn DiffDriveBase> =
        base_driver(kind, &cfg.motor, &cfg.robot, opener, clock.clone());
    let mut r = Rig {
        clock,
        emu,
        base,
        odom: Pose::identity(),
        events: Vec::new(),
        battery: None,
        _dir: dir,
    };
    // Wait for the link to come up (how long depends on the machine's load).
    let t0 = r.clock.now();
    loop {
        let fb = r.base.poll(r.clock.now()).unwrap();
        r.events.extend(fb.events.iter().copied());
        if fb.link_up {
            break;
        }
        assert!(r.clock.now() - t0 < 5.0, "{kind:?}: link never came up");
        r.clock.sleep(0.02);
    }
    r
}

impl Rig {
    /// Runs the 20 Hz control loop for `secs` of clock time, commanding `cmd`
    /// (or nothing).
    fn run(&mut self, secs: f64, cmd: Option<WheelSpeeds>) {
        let t0 = self.clock.now();
        while self.clock.now() - t0 < secs {
            let tick = self.clock.now();
            if let Some(c) = cmd {
                self.base.set_wheels(c, tick).unwrap();
            }
            let fb = self.base.poll(tick).unwrap();
            if let Some(o) = fb.odometry {
                self.odom *= o.delta;
            }
            self.events.extend(fb.events.iter().copied());
            self.battery = fb.battery.or(self.battery);
            let spent = self.clock.now() - tick;
            self.clock.sleep(0.05 - spent);
        }
    }

    /// Runs the control loop until `done` holds (checked every cycle) or
    /// `max_secs` pass; whether it held. For waits whose length depends on how
    /// loaded the machine is.
    fn run_until(
        &mut self,
        max_secs: f64,
        cmd: Option<WheelSpeeds>,
        done: impl Fn(&Rig) -> bool,
    ) -> bool {
        let t0 = self.clock.now();
        while self.clock.now() - t0 < max_secs {
            if done(self) {
                return true;
            }
            self.run(0.05, cmd);
        }
        done(self)
    }

    /// Commands a stop until the motors are at rest, then reads the last
    /// odometry.
    fn settle(&mut self) {
        let stop = Some(WheelSpeeds::STOP);
        self.run_until(5.0, stop, |r| r.emu.wheels() == WheelSpeeds::STOP);
        self.run(0.3, stop);
    }

    fn saw(&self, f: impl Fn(&SafetyEvent) -> bool) -> bool {
        self.events.iter().any(f)
    }
}

const FWD: WheelSpeeds = WheelSpeeds {
    left: 0.2,
    right: 0.2,
};

// Every wait below is "until this happens, at most N s": the machine these run
// on may be heavily loaded, so fixed durations would test the scheduler.

#[test]
fn commands_move_the_robot_and_odometry_follows() {
    for kind in KINDS {
        let mut r = rig(kind, None, pose(0.0, 0.0, 0.0), false);
        let moved = r.run_until(10.0, Some(FWD), |r| r.emu.truth().translation.x > 0.15);
        assert!(
            moved,
            "{kind:?}: robot did not move: {:?} {:?}",
            r.base.health(),
            r.events
        );
        let turn = Some(WheelSpeeds::from_body(0.0, 0.5, 0.235));
        let turned = r.run_until(10.0, turn, |r| heading(&r.emu.truth()) > 0.3);
        assert!(turned, "{kind:?}: robot did not turn");
        r.settle();
        let t = r.emu.truth();
        let e = (t.translation.vector - r.odom.translation.vector).norm();
        let eh = (heading(&t) - heading(&r.odom)).abs();
        assert!(
            e < 0.01 && eh < 0.02,
            "{kind:?}: odometry {} vs truth {t}",
            r.odom
        );
        // The emulated RoboClaw's 3-cell pack reads 9.9-12.6 V; the Create 2
        // its NiMH pack's voltage under load, 13-16.8 V.
        let plausible = |v: f64| match kind {
            BaseKind::Roboclaw => (9.9..=12.6).contains(&v),
            BaseKind::Create2 => (13.0..=16.8).contains(&v),
        };
        assert!(
            r.battery.is_some_and(plausible),
            "{kind:?}: {:?}",
            r.battery
        );
        let line = r.emu.status_line();
        assert!(
            line.contains("pose=(") && line.contains("packets ok="),
            "{line}"
        );
        let h = r.base.health();
        assert!(h.received > 10, "{kind:?}: {h:?}");
        assert_eq!(h.checksum_errors, 0, "{kind:?}: {h:?}");
        // The emulator is strict: every byte the driver sent was part of a
        // packet the manual allows.
        let d = r.emu.stats().device;
        assert_eq!(
            (d.packets_rejected, d.packets_cut, d.bytes_skipped),
            (0, 0, 0),
            "{kind:?}: the driver sent what the manual does not allow: {d:?}"
        );
    }
}

#[test]
fn deadman_stops_the_wheels_when_commands_stop() {
    for kind in KINDS {
        // The shipped dead-man time, 0.25 s.
        let clock: SharedClock = Arc::new(MonotonicClock::new());
        let mut r = rig_on(clock, kind, None, pose(0.0, 0.0, 0.0), false, |m| {
            tolerant(m);
            m.deadman = MotorParams::default().deadman;
        });
        assert!(
            r.run_until(10.0, Some(FWD), |r| r.emu.wheels().left > 0.1),
            "{kind:?}: not moving"
        );
        r.events.clear();
        // Polling goes on, commands do not.
        let stopped = r.run_until(5.0, None, |r| {
            r.saw(|e| matches!(e, SafetyEvent::DeadMan)) && r.emu.wheels() == WheelSpeeds::STOP
        });
        assert!(stopped, "{kind:?}: {:?} {:?}", r.events, r.emu.wheels());
        assert!(r.base.health().deadman_stops >= 1);
        // Still stopped a while later: nothing restarts the wheels by itself.
        r.run(0.5, None);
        assert_eq!(r.emu.wheels(), WheelSpeeds::STOP, "{kind:?}");
        // Fresh commands move it again.
        assert!(
            r.run_until(5.0, Some(FWD), |r| r.emu.wheels().left > 0.05),
            "{kind:?}"
        );
    }
}

fn check_silent_link(kind: BaseKind) {
    // The controller's own timeout (0.5 s) is shorter than the silence. The
    // silence is 2 s against a 0.6 s link timeout: the driver notices the
    // loss only while it is polling inside the silence, and a loaded
    // machine can keep this test's thread off the CPU for a few hundred ms
    // (CI once saw no loss in a 1 s silence).
    let clock: SharedClock = Arc::new(MonotonicClock::new());
    let mut r = rig_on(clock, kind, None, pose(0.0, 0.0, 0.0), false, |m| {
        tolerant(m);
        m.roboclaw.serial_timeout = 0.5;
    });
    let cmd = Some(WheelSpeeds {
        left: 0.1,
        right: 0.1,
    });
    assert!(
        r.run_until(10.0, cmd, |r| r.emu.wheels().left > 0.05),
        "{kind:?}"
    );
    r.emu.inject(Fault::Silence { secs: 2.0 });
    let lost = r.run_until(5.0, cmd, |r| r.saw(|e| matches!(e, SafetyEvent::LinkLost)));
    assert!(lost, "{kind:?}: {:?}", r.events);
    let restored = r.run_until(8.0, cmd, |r| {
        r.saw(|e| matches!(e, SafetyEvent::LinkRestored))
    });
    assert!(restored, "{kind:?}: {:?}", r.events);
    if kind == BaseKind::Roboclaw {
        // The controller's own serial timeout stopped the motors meanwhile.
        assert!(
            r.emu.stats().device.device_timeouts >= 1,
            "{:?}",
            r.emu.stats()
        );
    }
    let before = r.emu.truth().translation.x;
    let drives = r.run_until(5.0, cmd, |r| r.emu.truth().translation.x > before + 0.02);
    assert!(drives, "{kind:?}: not driving after recovery");
    let h = r.base.health();
    assert!(h.link_losses >= 1, "{kind:?}: {h:?}");
    assert!(
        h.timeouts > 0 || kind == BaseKind::Create2,
        "{kind:?}: {h:?}"
    );
}

#[test]
fn silent_link_for_two_seconds_is_detected_and_recovered_roboclaw() {
    check_silent_link(BaseKind::Roboclaw);
}

#[test]
fn silent_link_for_two_seconds_is_detected_and_recovered_create2() {
    check_silent_link(BaseKind::Create2);
}

fn check_corrupted_bytes(kind: BaseKind) {
    let mut r = rig(kind, None, pose(0.0, 0.0, 0.0), false);
    let cmd = Some(WheelSpeeds {
        left: 0.15,
        right: 0.12,
    });
    assert!(
        r.run_until(10.0, cmd, |r| r.emu.wheels().left > 0.05),
        "{kind:?}"
    );
    r.emu.inject(Fault::CorruptOut { bytes: 40 });
    r.emu.inject(Fault::CorruptIn { bytes: 40 });
    r.run_until(10.0, cmd, |r| r.emu.stats().corrupted_bytes >= 80);
    r.run(0.5, cmd);
    r.settle();
    let h = r.base.health();
    // A burst garbles whole replies/frames: they fail their CRC/checksum or,
    // with the header itself garbled, are skipped as noise.
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
    let world = World::parse("room 0 0 1.2 0 1.2 2 0 2\n").unwrap();
    let mut r = rig(kind, Some(world), pose(0.7, 1.0, 0.0), false);
    let hit = r.run_until(15.0, Some(FWD), |r| {
        r.saw(|e| matches!(e, SafetyEvent::Bumper(_)))
    });
    assert!(hit, "{kind:?}: {:?}", r.events);
    let stopped = r.run_until(3.0, Some(FWD), |r| {
        r.emu.motor_targets() == WheelSpeeds::STOP && r.emu.wheels() == WheelSpeeds::STOP
    });
    assert!(
        stopped,
        "{kind:?}: motors still driven: {:?}",
        r.emu.motor_targets()
    );
    let x = r.emu.truth().translation.x;
    assert!(
        x > 1.0 && x < 1.2 - 0.17 + 0.021,
        "{kind:?}: stopped at {x}"
    );
    // Forward commands are refused while the bumper is closed.
    r.run(0.5, Some(FWD));
    let x2 = r.emu.truth().translation.x;
    assert!(
        x2 <= x + 1e-9,
        "{kind:?}: pushed on from {x} to {x2}: {:?}",
        r.events
    );
    assert_eq!(r.emu.motor_targets(), WheelSpeeds::STOP, "{kind:?}");
    // Reversing is allowed and opens the bumper.
    let back = Some(WheelSpeeds {
        left: -0.1,
        right: -0.1,
    });
    let freed = r.run_until(8.0, back, |r| {
        r.emu.truth().translation.x < x - 0.03
            && r.saw(|e| matches!(e, SafetyEvent::BumperReleased))
    });
    assert!(freed, "{kind:?}: did not back off: {:?}", r.events);
    assert!(r.base.health().safety_stops >= 1);
    if kind == BaseKind::Create2 {
        // The strict emulator refused nothing the driver sent.
        assert_no_rejections(&r.emu);
    }
}

/// The Create 2 emulator (strict by default) refused nothing: the driver
/// sent only what the OI specification allows, in the modes it allows it.
fn assert_no_rejections(emu: &EmulatorHandle) {
    let d = emu.stats().device;
    assert_eq!(d.packets_rejected, 0, "{d:?}");
    assert_eq!(d.packets_cut, 0, "{d:?}");
    assert_eq!(d.bytes_skipped, 0, "{d:?}");
    assert!(d.packets_ok > 10, "{d:?}");
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
        assert!(
            r.run_until(10.0, Some(FWD), |r| r.emu.wheels().left > 0.1),
            "{kind:?}"
        );
        r.emu.inject(Fault::Bump { secs: 1.5 });
        let stopped = r.run_until(1.2, Some(FWD), |r| {
            r.saw(|e| matches!(e, SafetyEvent::Bumper(_)))
                && r.emu.motor_targets() == WheelSpeeds::STOP
        });
        assert!(
            stopped,
            "{kind:?}: {:?} {:?}",
            r.events,
            r.emu.motor_targets()
        );
        let resumed = r.run_until(8.0, Some(FWD), |r| {
            r.saw(|e| matches!(e, SafetyEvent::BumperReleased)) && r.emu.wheels().left > 0.1
        });
        assert!(resumed, "{kind:?}: did not resume: {:?}", r.events);
    }
}

#[test]
fn create2_wheel_drop_stops_and_safe_mode_is_re_entered() {
    let mut r = rig(BaseKind::Create2, None, pose(0.0, 0.0, 0.0), false);
    assert!(r.run_until(10.0, Some(FWD), |r| r.emu.wheels().left > 0.1));
    r.emu.inject(Fault::WheelDrop { secs: 1.5 });
    let stopped = r.run_until(1.2, Some(FWD), |r| {
        r.saw(|e| matches!(e, SafetyEvent::WheelDrop(_)))
            && r.emu.motor_targets() == WheelSpeeds::STOP
    });
    assert!(stopped, "{:?} {:?}", r.events, r.emu.motor_targets());
    let resumed = r.run_until(8.0, Some(FWD), |r| {
        r.saw(|e| matches!(e, SafetyEvent::WheelDropCleared)) && r.emu.motor_targets().left > 0.1
    });
    assert!(
        resumed,
        "Safe mode not re-entered: {:?} {:?}",
        r.events,
        r.emu.motor_targets()
    );
    // The robot left Safe mode on its own: a drive command already on the
    // wire (one control period) may meet Passive mode and be refused; the
    // driver sends none once a frame reports Passive.
    let d = r.emu.stats().device;
    assert_eq!(d.packets_rejected, d.refused_in_mode, "{d:?}");
    assert!(d.refused_in_mode <= 2, "{d:?}");
    assert_eq!(d.bytes_skipped, 0, "{d:?}");
}

fn check_unplugged_base(kind: BaseKind) {
    let mut r = rig(kind, None, pose(0.0, 0.0, 0.0), true);
    let cmd = Some(WheelSpeeds {
        left: 0.1,
        right: 0.1,
    });
    assert!(
        r.run_until(10.0, cmd, |r| r.emu.wheels().left > 0.05),
        "{kind:?}: never drove"
    );
    r.emu.inject(Fault::Unplug { secs: 0.5 });
    r.run_until(8.0, cmd, |r| {
        r.saw(|e| matches!(e, SafetyEvent::LinkRestored))
    });
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
        r.run_until(5.0, cmd, |r| r.emu.wheels().left > 0.05),
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
        let mut r = rig_on(clock, kind, None, pose(0.0, 0.0, 0.0), false, tolerant);
        let moved = r.run_until(40.0, Some(FWD), |r| r.emu.truth().translation.x > 0.3);
        assert!(moved, "{kind:?}: did not move 0.3 m");
        r.settle();
        let e = (r.emu.truth().translation.vector - r.odom.translation.vector).norm();
        assert!(e < 0.03, "{kind:?}: odometry off by {e}");
        let fired = r.run_until(10.0, None, |r| {
            r.saw(|e| matches!(e, SafetyEvent::DeadMan))
                && r.emu.motor_targets() == WheelSpeeds::STOP
        });
        assert!(fired, "{kind:?}: {:?}", r.events);
    }
}

#[test]
fn create2_stream_pause_is_not_a_lost_link_and_resume_restores_odometry() {
    let clock: SharedClock = Arc::new(MonotonicClock::new());
    let cfg = {
        let mut c = Config::default();
        c.motor.kind = BaseKind::Create2;
        tolerant(&mut c.motor);
        c
    };
    let emu = spawn_on_pty(
        EmulatorConfig::from_config(&cfg, BaseKind::Create2),
        None,
        clock.clone(),
    )
    .unwrap();
    let opener = Box::new(ConnectorOpener(Box::new(DeviceConnector::new(
        emu.path().unwrap(),
    ))));
    let mut d = Create2Driver::new(&cfg.motor, &cfg.robot, opener, clock.clone());
    let mut events = Vec::new();
    let step = |d: &mut Create2Driver, cmd: WheelSpeeds, ev: &mut Vec<SafetyEvent>| {
        let now = clock.now();
        d.set_wheels(cmd, now).unwrap();
        let fb = d.poll(now).unwrap();
        ev.extend(fb.events.iter().copied());
        clock.sleep(0.05);
        fb
    };
    let mut up = false;
    for _ in 0..100 {
        up = step(&mut d, FWD, &mut events).link_up;
        if up && emu.wheels().left > 0.1 {
            break;
        }
    }
    assert!(up && emu.wheels().left > 0.1, "never drove");
    assert!(d.pause_stream());
    let frames = emu.stats().device.frames_out;
    for _ in 0..20 {
        let fb = step(&mut d, FWD, &mut events);
        assert!(fb.odometry.is_none() || d.stream_paused());
    }
    assert_eq!(
        emu.motor_targets(),
        WheelSpeeds::STOP,
        "moving while paused"
    );
    assert!(
        emu.stats().device.frames_out <= frames + 2,
        "stream did not pause"
    );
    assert!(
        !events.iter().any(|e| matches!(e, SafetyEvent::LinkLost)),
        "{events:?}"
    );
    assert!(d.resume_stream(clock.now()));
    let mut odometry = 0;
    for _ in 0..100 {
        odometry += usize::from(step(&mut d, FWD, &mut events).odometry.is_some());
        if odometry > 3 && emu.wheels().left > 0.1 {
            break;
        }
    }
    assert!(
        odometry > 3 && emu.wheels().left > 0.1,
        "no odometry or motion after resume"
    );
    assert!(
        !events.iter().any(|e| matches!(e, SafetyEvent::LinkLost)),
        "{events:?}"
    );
    assert!(EmulatorConfig::from_config(&cfg, BaseKind::Create2).strict);
    assert_no_rejections(&emu);
}

#[test]
fn serve_reports_status_until_stopped() {
    use std::sync::atomic::{AtomicBool, Ordering};
    let clock: SharedClock = Arc::new(MonotonicClock::new());
    let world = Arc::new(World::parse("room 0 0 3 0 3 3 0 3\nstart 1 1 0.5\n").unwrap());
    let cfg = EmulatorConfig::from_config(&Config::default(), BaseKind::Roboclaw).in_world(world);
    let emu = spawn_on_pty(cfg, None, clock.clone()).unwrap();
    let stop = AtomicBool::new(false);
    let mut lines = Vec::new();
    sweepline::sim::base_emu::serve(&emu, &*clock, &stop, 0.05, |l| {
        lines.push(l.to_string());
        if lines.len() == 3 {
            stop.store(true, Ordering::SeqCst);
        }
    });
    assert_eq!(lines.len(), 3);
    assert!(
        lines[0].contains("pose=(1.000 m, 1.000 m, 28.6 deg)"),
        "{}",
        lines[0]
    );
}

#[test]
fn roboclaw_at_another_address_never_counts_as_up() {
    let clock: SharedClock = Arc::new(MonotonicClock::new());
    let cfg = Config::default();
    // The emulated controller answers at 0x80; the driver asks 0x81.
    let emu = spawn_on_pty(
        EmulatorConfig::from_config(&cfg, BaseKind::Roboclaw),
        None,
        clock.clone(),
    )
    .unwrap();
    let mut motor = cfg.motor.clone();
    motor.roboclaw.address = 0x81;
    let opener = Box::new(ConnectorOpener(Box::new(DeviceConnector::new(
        emu.path().unwrap(),
    ))));
    let mut d = RoboClawDriver::new(&motor, &cfg.robot, opener, clock.clone());
    for _ in 0..5 {
        let now = clock.now();
        d.set_wheels(FWD, now).unwrap();
        assert!(!d.poll(now).unwrap().link_up);
        clock.sleep(0.2);
    }
    assert!(d.health().timeouts > 0, "{:?}", d.health());
    assert_eq!(emu.motor_targets(), WheelSpeeds::STOP);
}
