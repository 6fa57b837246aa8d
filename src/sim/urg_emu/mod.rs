//! An emulated Hokuyo URG-04LX (or UTM-30LX) on a pseudo-terminal: the daemon,
//! `sweepline probe` or Hokuyo's own urg_library open its path exactly as a
//! real `/dev/ttyACM0` and cannot tell the difference.
//!
//! * [`sensor`]: the sans-IO sensor (commands in, replies and scans out);
//! * [`model`]: the real units' VV/PP/II texts and geometry;
//! * [`scene`]: what the laser sees ([`Scene`] trait, a rectangular room,
//!   replay of a recorded scan);
//! * [`faults`]: fault injection switches;
//! * [`link`]: the sensor behind an in-process port (lock-step, no pty);
//! * this file: the runner that moves bytes between the sensor and a
//!   [`PtyHost`], applies wire faults (CRLF, split writes) and performs
//!   stalls and unplug/replug.
//!
//! Time comes from an injected [`Clock`]: tests run the 10 Hz sensor faster
//! with a [`crate::urg::clock::ScaledClock`].

pub mod faults;
pub mod link;
pub mod model;
pub mod scene;
pub mod sensor;

use std::io::{self, Read};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub use faults::{FaultSpecError, Faults, ScanFault};
pub use link::SensorLink;
pub use model::{Model, ModelSpec};
pub use scene::{capture_stream, Echo, RectRoom, ReplayError, ReplayScan, Scene};
pub use sensor::{Action, EmuLog, Sensor, SentScan};

use crate::scip::{LineEvent, LineFramer};
use crate::serial::{Pty, PtyError, PtyHost};
use crate::urg::clock::Clock;

/// Settings of one emulated sensor.
#[derive(Clone, Debug)]
pub struct EmulatorConfig {
    /// Which sensor.
    pub model: Model,
    /// Boot in SCIP 1.1 (the driver must send `SCIP2.0`).
    pub scip1_boot: bool,
    /// Fault injection.
    pub faults: Faults,
    /// Symlink kept pointing at the current pty (survives replug).
    pub link: Option<PathBuf>,
    /// Seed of every random choice (noise, fault placement, write splits).
    pub seed: u64,
    /// Sensor clock rate error (ppm) relative to the emulator clock.
    pub drift_ppm: f64,
}

impl Default for EmulatorConfig {
    fn default() -> Self {
        Self {
            model: Model::Urg04lx,
            scip1_boot: false,
            faults: Faults::default(),
            link: None,
            seed: 1,
            drift_ppm: 0.0,
        }
    }
}

/// Why the emulator could not start or run.
#[derive(Debug, thiserror::Error)]
pub enum EmuError {
    /// The pty or its symlink.
    #[error(transparent)]
    Pty(#[from] PtyError),
    /// The emulator thread could not be started.
    #[error("cannot start the emulator thread: {0}")]
    Thread(io::Error),
}

struct Shared {
    log: Arc<Mutex<EmuLog>>,
    path: Mutex<Option<PathBuf>>,
    stop: AtomicBool,
}

/// A running emulator thread; stopped and joined on drop.
pub struct Emulator {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl Emulator {
    /// Creates the pty and starts the emulator on its own thread.
    pub fn spawn(
        cfg: EmulatorConfig,
        scene: Box<dyn Scene>,
        clock: Arc<dyn Clock>,
    ) -> Result<Emulator, EmuError> {
        let host = PtyHost::new(cfg.link.clone())?;
        let shared = Arc::new(Shared {
            log: Arc::new(Mutex::new(EmuLog::default())),
            path: Mutex::new(host.client_path()),
            stop: AtomicBool::new(false),
        });
        let sh = shared.clone();
        let link = cfg.link.clone();
        let thread = std::thread::Builder::new()
            .name("urg-emulator".into())
            .spawn(move || {
                let stop = |_: &Option<PathBuf>| !sh.stop.load(Ordering::Relaxed);
                let mut on_plug = |p: Option<PathBuf>| {
                    if let Ok(mut g) = sh.path.lock() {
                        *g = link.clone().or(p);
                    }
                };
                let r = run(cfg, scene, clock, host, sh.log.clone(), &mut on_plug, &stop);
                if let Err(e) = r {
                    log::error!("urg emulator stopped: {e}");
                }
            })
            .map_err(EmuError::Thread)?;
        Ok(Emulator {
            shared,
            thread: Some(thread),
        })
    }

    /// The path a client opens (the symlink if configured, else the current
    /// `/dev/pts/N`); `None` while unplugged without a symlink.
    pub fn path(&self) -> Option<PathBuf> {
        self.shared.path.lock().ok().and_then(|g| g.clone())
    }

    /// A copy of the emulator's log.
    pub fn log(&self) -> EmuLog {
        self.shared
            .log
            .lock()
            .map(|g| g.clone())
            .unwrap_or_default()
    }

    /// Stops the emulator (the pty goes away) and waits for its thread.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        self.halt();
    }
}

/// Sleeps `dt` seconds of `clock` time in small slices, returning early
/// when `keep_going` turns false.
fn sleep_while(clock: &dyn Clock, dt: f64, keep_going: &dyn Fn() -> bool) {
    let end = clock.now() + dt;
    while keep_going() {
        let left = end - clock.now();
        if left <= 0.0 {
            break;
        }
        clock.sleep(left.min(0.01 * clock.rate()));
    }
}

/// Runs the emulator on `host` until `keep_going` returns false. `on_plug`
/// is told the pty's slave path (`/dev/pts/N`) after every (re)plug, `None`
/// while unplugged.
pub fn run(
    cfg: EmulatorConfig,
    scene: Box<dyn Scene>,
    clock: Arc<dyn Clock>,
    mut host: PtyHost,
    log: Arc<Mutex<EmuLog>>,
    on_plug: &mut dyn FnMut(Option<PathBuf>),
    keep_going: &dyn Fn(&Option<PathBuf>) -> bool,
) -> Result<(), EmuError> {
    let spec = ModelSpec::of(cfg.model);
    let spec_period = spec.period();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x5eed);
    let mut sensor = Sensor::new(
        spec,
        cfg.faults.clone(),
        cfg.scip1_boot,
        scene,
        cfg.seed,
        log.clone(),
        clock.now(),
    );
    sensor.set_drift_ppm(cfg.drift_ppm);
    let mut framer = LineFramer::new();
    let mut out: Vec<u8> = Vec::with_capacity(16 * 1024);
    let mut line: Vec<u8> = Vec::with_capacity(256);
    let mut buf = [0u8; 1024];
    on_plug(host.slave_path());
    let path_now = host.client_path();
    let go = || keep_going(&path_now);
    while go() {
        match sensor.take_action() {
            Some(Action::Stall(d)) => {
                if let Ok(mut l) = log.lock() {
                    l.stalls += 1;
                }
                sleep_while(&*clock, d, &go);
                continue;
            }
            Some(Action::Unplug(d)) => {
                // Let the client read the last scan first: the fault is an
                // unplug between scans, so no scan is cut in half.
                sleep_while(&*clock, 0.3 * spec_period, &go);
                host.unplug();
                if let Ok(mut l) = log.lock() {
                    l.unplugs += 1;
                }
                on_plug(None);
                sleep_while(&*clock, d, &go);
                host.replug()?;
                framer.reset();
                sensor.power_on(clock.now(), true);
                on_plug(host.slave_path());
                continue;
            }
            None => {}
        }
        let Some(pty) = host.pty() else {
            host.replug()?;
            continue;
        };
        let now = clock.now();
        let wait = sensor
            .next_due()
            .map(|t| (t - now) / clock.rate())
            .unwrap_or(0.01)
            .clamp(0.0, 0.01);
        pty.set_read_timeout(Duration::from_secs_f64(wait));
        match pty.read(&mut buf) {
            Ok(n) => {
                for &b in &buf[..n] {
                    if let Some(LineEvent::Line(l)) = framer.push(b) {
                        line.clear();
                        line.extend_from_slice(l);
                        sensor.on_line(&line, clock.now(), &mut out);
                    }
                }
            }
            Err(e) if e.kind() == io::ErrorKind::TimedOut => {}
            Err(e) => {
                log::warn!("urg emulator: pty read: {e}");
                clock.sleep(0.01 * clock.rate());
            }
        }
        sensor.poll(clock.now(), &mut out);
        if !out.is_empty() {
            send(pty, &out, &cfg.faults, &mut rng);
            out.clear();
        }
    }
    Ok(())
}

/// Writes `data` to the pty, applying the wire faults (CRLF endings, writes
/// split at random points with short pauses). A client that does not read
/// loses the bytes, as with a real device.
fn send(pty: &mut Pty, data: &[u8], faults: &Faults, rng: &mut ChaCha8Rng) {
    let crlf;
    let bytes: &[u8] = if faults.crlf {
        let mut v = Vec::with_capacity(data.len() + data.len() / 32);
        for &b in data {
            if b == b'\n' {
                v.push(b'\r');
            }
            v.push(b);
        }
        crlf = v;
        &crlf
    } else {
        data
    };
    let mut rest = bytes;
    while !rest.is_empty() {
        let n = if faults.split_writes {
            rng.random_range(1..=rest.len().min(96))
        } else {
            rest.len()
        };
        if let Err(e) =
            crate::serial::write_chunked(pty, &rest[..n], crate::serial::pty::WRITE_CHUNK)
        {
            log::debug!(
                "urg emulator: client not reading ({e}); {} bytes lost",
                rest.len()
            );
            return;
        }
        rest = &rest[n..];
        if faults.split_writes && !rest.is_empty() {
            std::thread::sleep(Duration::from_micros(rng.random_range(0..400)));
        }
    }
}
