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
//! with a [`crate::clock::ScaledClock`].

pub mod faults;
mod intensity;
pub mod link;
pub mod model;
mod returns;
pub mod scene;
pub mod sensor;

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
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
pub use scene::{capture_stream, Echo, RectRoom, ReplayError, ReplayScan, Scene, WallPatch};
pub use sensor::{Action, EmuLog, Sensor, SentScan};

use crate::clock::Clock;
use crate::scip::{LineEvent, LineFramer};
use crate::serial::{Pty, PtyError, PtyHost};

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
    /// Answer commands with the real firmware's latency (about one scan
    /// period; see [`sensor`]); off answers every line at once.
    pub reply_latency: bool,
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
            reply_latency: true,
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
    /// The TCP listener failed.
    #[error("emulator network socket: {0}")]
    Io(io::Error),
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

    /// Starts the emulator as an Ethernet sensor listening on `addr` (port 0
    /// picks a free one); returns it and the address it listens on.
    pub fn spawn_tcp(
        cfg: EmulatorConfig,
        scene: Box<dyn Scene>,
        clock: Arc<dyn Clock>,
        addr: SocketAddr,
    ) -> Result<(Emulator, SocketAddr), EmuError> {
        let listener = TcpListener::bind(addr).map_err(EmuError::Io)?;
        let local = listener.local_addr().map_err(EmuError::Io)?;
        let shared = Arc::new(Shared {
            log: Arc::new(Mutex::new(EmuLog::default())),
            path: Mutex::new(None),
            stop: AtomicBool::new(false),
        });
        let sh = shared.clone();
        let thread = std::thread::Builder::new()
            .name("urg-emulator-tcp".into())
            .spawn(move || {
                let go = || !sh.stop.load(Ordering::Relaxed);
                if let Err(e) = serve_tcp(cfg, scene, clock, listener, sh.log.clone(), &go) {
                    log::error!("urg emulator stopped: {e}");
                }
            })
            .map_err(EmuError::Thread)?;
        Ok((
            Emulator {
                shared,
                thread: Some(thread),
            },
            local,
        ))
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
        clock.sleep(left.min(0.01 * clock.speed()));
    }
}

/// The byte side of an emulated sensor: a pty master or a TCP connection.
pub(crate) trait EmuIo: Read + Write {
    /// Sets how long one read waits for the first byte.
    fn set_read_timeout(&mut self, t: Duration) -> io::Result<()>;
}

impl EmuIo for Pty {
    fn set_read_timeout(&mut self, t: Duration) -> io::Result<()> {
        Pty::set_read_timeout(self, t);
        Ok(())
    }
}

impl EmuIo for TcpStream {
    fn set_read_timeout(&mut self, t: Duration) -> io::Result<()> {
        TcpStream::set_read_timeout(self, Some(t.max(Duration::from_millis(1))))
    }
}

/// The sensor plus its line framer and buffers: one turn reads what the
/// client sent (waiting at most until the next scan), answers it, and sends
/// the scans that are due.
struct Engine {
    sensor: Sensor,
    faults: Faults,
    framer: LineFramer,
    out: Vec<u8>,
    line: Vec<u8>,
    buf: [u8; 1024],
    rng: ChaCha8Rng,
}

impl Engine {
    fn new(cfg: &EmulatorConfig, scene: Box<dyn Scene>, log: Arc<Mutex<EmuLog>>, now: f64) -> Self {
        let mut sensor = Sensor::new(
            ModelSpec::of(cfg.model),
            cfg.faults.clone(),
            cfg.scip1_boot,
            scene,
            cfg.seed,
            log,
            now,
        );
        sensor.set_drift_ppm(cfg.drift_ppm);
        sensor.set_reply_latency(cfg.reply_latency);
        Engine {
            sensor,
            faults: cfg.faults.clone(),
            framer: LineFramer::new(),
            out: Vec::with_capacity(16 * 1024),
            line: Vec::with_capacity(256),
            buf: [0u8; 1024],
            rng: ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x5eed),
        }
    }

    /// One turn; an error means the link is unusable (for TCP: the client left).
    fn turn(&mut self, io: &mut dyn EmuIo, clock: &dyn Clock) -> io::Result<()> {
        let now = clock.now();
        let wait = self
            .sensor
            .next_due()
            .map(|t| (t - now) / clock.speed())
            .unwrap_or(0.01)
            .clamp(0.0, 0.01);
        io.set_read_timeout(Duration::from_secs_f64(wait))?;
        match io.read(&mut self.buf) {
            Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => {
                for &b in &self.buf[..n] {
                    if let Some(LineEvent::Line(l)) = self.framer.push(b) {
                        self.line.clear();
                        self.line.extend_from_slice(l);
                        self.sensor.on_line(&self.line, clock.now(), &mut self.out);
                    }
                }
            }
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut
                        | io::ErrorKind::WouldBlock
                        | io::ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e),
        }
        self.sensor.poll(clock.now(), &mut self.out);
        if !self.out.is_empty() {
            send(io, &self.out, &self.faults, &mut self.rng);
            self.out.clear();
        }
        Ok(())
    }
}

/// How many tenths of a scan period an unplug waits at most for the client
/// to read what was sent before the plug is pulled.
const UNPLUG_DRAIN_WAITS: u32 = 50;

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
    let period = ModelSpec::of(cfg.model).period();
    let mut eng = Engine::new(&cfg, scene, log.clone(), clock.now());
    on_plug(host.slave_path());
    let path_now = host.client_path();
    let go = || keep_going(&path_now);
    while go() {
        match eng.sensor.take_action() {
            Some(Action::Stall(d)) => {
                if let Ok(mut l) = log.lock() {
                    l.stalls += 1;
                }
                sleep_while(&*clock, d, &go);
                continue;
            }
            Some(Action::Unplug(d)) => {
                // Let the client read the last scan first: the fault is an
                // unplug between scans, so no scan is cut in half (on a
                // loaded host the client may take longer than the pause).
                sleep_while(&*clock, 0.3 * period, &go);
                let unread = |h: &mut PtyHost| h.pty().and_then(|p| p.unread_by_client().ok());
                for _ in 0..UNPLUG_DRAIN_WAITS {
                    if !go() || unread(&mut host).is_none_or(|n| n == 0) {
                        break;
                    }
                    sleep_while(&*clock, 0.1 * period, &go);
                }
                host.unplug();
                if let Ok(mut l) = log.lock() {
                    l.unplugs += 1;
                }
                on_plug(None);
                sleep_while(&*clock, d, &go);
                host.replug()?;
                eng.framer.reset();
                eng.sensor.power_on(clock.now(), true);
                on_plug(host.slave_path());
                continue;
            }
            None => {}
        }
        let Some(pty) = host.pty() else {
            host.replug()?;
            continue;
        };
        if let Err(e) = eng.turn(pty, &*clock) {
            log::warn!("urg emulator: pty: {e}");
            clock.sleep(0.01 * clock.speed());
        }
    }
    Ok(())
}

/// Runs the emulator as an Ethernet sensor (UTM-30LX-EW style) on
/// `listener`, one client at a time, until `keep_going` returns false. The
/// sensor keeps its state between connections; the `unplug` fault closes
/// the connection (a pulled cable) and reboots the sensor.
pub fn serve_tcp(
    cfg: EmulatorConfig,
    scene: Box<dyn Scene>,
    clock: Arc<dyn Clock>,
    listener: TcpListener,
    log: Arc<Mutex<EmuLog>>,
    keep_going: &dyn Fn() -> bool,
) -> Result<(), EmuError> {
    let period = ModelSpec::of(cfg.model).period();
    let mut eng = Engine::new(&cfg, scene, log.clone(), clock.now());
    listener.set_nonblocking(true).map_err(EmuError::Io)?;
    while keep_going() {
        let mut stream = match listener.accept() {
            Ok((s, _)) => s,
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(5));
                continue;
            }
            Err(e) => return Err(EmuError::Io(e)),
        };
        let setup = stream
            .set_nonblocking(false)
            .and_then(|_| stream.set_nodelay(true))
            .and_then(|_| stream.set_write_timeout(Some(Duration::from_secs(1))));
        if let Err(e) = setup {
            log::warn!("urg emulator: tcp client: {e}");
            continue;
        }
        eng.framer.reset();
        while keep_going() {
            match eng.sensor.take_action() {
                Some(Action::Stall(d)) => {
                    if let Ok(mut l) = log.lock() {
                        l.stalls += 1;
                    }
                    sleep_while(&*clock, d, keep_going);
                    continue;
                }
                Some(Action::Unplug(d)) => {
                    sleep_while(&*clock, 0.3 * period, keep_going);
                    let _ = stream.shutdown(std::net::Shutdown::Both);
                    if let Ok(mut l) = log.lock() {
                        l.unplugs += 1;
                    }
                    sleep_while(&*clock, d, keep_going);
                    eng.sensor.power_on(clock.now(), true);
                    break;
                }
                None => {}
            }
            if let Err(e) = eng.turn(&mut stream, &*clock) {
                log::info!("urg emulator: tcp client gone: {e}");
                break;
            }
        }
    }
    Ok(())
}

/// Writes `data` to the client, applying the wire faults (CRLF endings,
/// writes split at random points with short pauses). A client that does not
/// read loses the bytes, as with a real device.
fn send(io: &mut dyn EmuIo, data: &[u8], faults: &Faults, rng: &mut ChaCha8Rng) {
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
            crate::serial::write_chunked(io, &rest[..n], crate::serial::pty::WRITE_CHUNK)
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
