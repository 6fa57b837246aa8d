//! `sweepline emulate`: runs an emulated device (URG scanner, RoboClaw or Create 2 base) on a pseudo-terminal.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use super::CliResult;
use crate::serial::PtyHost;
use crate::sim::base_emu::faults::FaultPlan;
use crate::sim::urg_emu::{
    self, EmuLog, EmulatorConfig, Faults, Model, RectRoom, ReplayScan, Scene,
};
use crate::urg::{Clock, MonotonicClock, ScaledClock};

/// Arguments of `sweepline emulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Which device to emulate.
    #[arg(value_parser = ["urg", "roboclaw", "create2"])]
    pub device: String,
    /// Also make this symlink to the pty (kept pointing at it over unplug/replug).
    #[arg(long)]
    pub link: Option<PathBuf>,
    /// Sensor model.
    #[arg(long, default_value = "urg-04lx", value_parser = ["urg-04lx", "utm-30lx"])]
    pub model: String,
    /// Boot in SCIP 1.1, as many URG-04LX units do (clients must send SCIP2.0).
    #[arg(long)]
    pub scip1: bool,
    /// Fault switches, comma separated. urg: checksum=N, drop=N, extra=N,
    /// status=N or status=N:CODE, stuck=N, noise=N, hang=N, crlf, split,
    /// stall=N:SECONDS, wrap, unplug=N:SECONDS (N = every N-th scan).
    /// roboclaw and create2: silence=N:SECONDS, corrupt-in=N:BYTES,
    /// corrupt-out=N:BYTES, bump=N:SECONDS, wheel-drop=N:SECONDS,
    /// unplug=N:SECONDS (N = every N seconds).
    #[arg(long, default_value = "")]
    pub faults: String,
    /// roboclaw and create2: answer what the manual leaves open as the device
    /// would, instead of refusing and counting it (strict is the default,
    /// so a client that drifts from the manual sees it).
    #[arg(long)]
    pub lenient: bool,
    /// roboclaw and create2: the room the base drives in (walls and
    /// obstacles close its bumpers); default open floor.
    #[command(flatten)]
    pub world: super::world_args::WorldArgs,
    /// Replay the first scan of a byte capture (hokuyoaist .logr format)
    /// instead of the built-in 4 x 3 m room.
    #[arg(long)]
    pub replay: Option<PathBuf>,
    /// Seed of the range noise and fault placement.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Run the sensor this many times faster than real time.
    #[arg(long, default_value_t = 1.0)]
    pub rate: f64,
    /// Serve SCIP over TCP at this address (an Ethernet sensor, e.g.
    /// 127.0.0.1:10940) instead of a pty.
    #[arg(long)]
    pub tcp: Option<std::net::SocketAddr>,
    /// Sensor clock rate error in parts per million (crystal drift).
    #[arg(long, default_value_t = 0.0)]
    pub drift_ppm: f64,
    /// Answer every command at once instead of with the real URG's
    /// latency (about one scan period; TM1 about 1 ms).
    #[arg(long)]
    pub no_latency: bool,
}

/// Runs `sweepline emulate`.
pub fn run(args: Args) -> CliResult {
    match args.device.as_str() {
        "urg" => run_urg(args),
        "roboclaw" | "create2" => run_base(args),
        other => Err(format!("unknown device `{other}`: expected urg, roboclaw or create2").into()),
    }
}

/// An emulated wheel base (the motor engineer's `sim::base_emu`) on a pty,
/// open floor, until SIGINT/SIGTERM.
fn run_base(args: Args) -> CliResult {
    let kind = super::sim::parse_base(&args.device)?;
    if !(args.rate.is_finite() && args.rate > 0.0) {
        return Err(format!("--rate must be a positive number, got {}", args.rate).into());
    }
    let mut plan: FaultPlan = args.faults.parse()?;
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, stop.clone())?;
    }
    let cfg = crate::config::Config::default();
    let mut ecfg = crate::sim::base_emu::EmulatorConfig::from_config(&cfg, kind);
    ecfg.seed = args.seed;
    ecfg.strict = !args.lenient;
    let room = if args.world.selected() {
        let world = args.world.load(None)?;
        let name = world.name.clone();
        ecfg = ecfg.in_world(Arc::new(world));
        format!(" in {name}")
    } else {
        String::new()
    };
    let clock: crate::clock::SharedClock = Arc::new(crate::clock::ScaledClock::new(args.rate));
    let emu = crate::sim::base_emu::spawn_on_pty(ecfg, args.link.clone(), clock.clone())?;
    let at = args.link.clone().or(emu.path()).unwrap_or_default();
    println!("{} base emulated at {}{room}", args.device, at.display());
    let t0 = clock.now();
    while !stop.load(Ordering::Relaxed) {
        plan.due(clock.now() - t0, |f| emu.inject(f));
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let s = emu.stats();
    let p = emu.truth();
    println!(
        "stopped: {} packets ok, {} rejected, {} cut short by a pause; robot at ({:.3}, {:.3}) m",
        s.device.packets_ok,
        s.device.packets_rejected,
        s.device.packets_cut,
        p.translation.x,
        p.translation.y
    );
    Ok(())
}

fn run_urg(args: Args) -> CliResult {
    if args.world.selected() || args.lenient {
        return Err("--world, --room, --map and --lenient apply to roboclaw and create2; the urg emulator scans its built-in room or --replay".into());
    }
    let model: Model = args.model.parse()?;
    let faults: Faults = args.faults.parse()?;
    if !(args.rate.is_finite() && args.rate > 0.0) {
        return Err(format!("--rate must be a positive number, got {}", args.rate).into());
    }
    let scene: Box<dyn Scene> = match &args.replay {
        Some(p) => Box::new(ReplayScan::from_capture_file(p)?),
        None => Box::new(RectRoom::bench(args.seed)),
    };
    let clock: Arc<dyn Clock> = if args.rate == 1.0 {
        Arc::new(MonotonicClock::new())
    } else {
        Arc::new(ScaledClock::new(args.rate))
    };
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, stop.clone())?;
    }
    let cfg = EmulatorConfig {
        model,
        scip1_boot: args.scip1,
        faults,
        link: args.link.clone(),
        seed: args.seed,
        drift_ppm: args.drift_ppm,
        reply_latency: !args.no_latency,
    };
    let log = Arc::new(Mutex::new(EmuLog::default()));
    let spec = urg_emu::ModelSpec::of(model);
    if let Some(addr) = args.tcp {
        let listener = std::net::TcpListener::bind(addr)
            .map_err(|e| format!("cannot listen on {addr}: {e}"))?;
        println!(
            "{} emulated ({} ms scans) on tcp {}",
            spec.vv[1].1,
            (spec.period() * 1e3).round(),
            listener.local_addr()?
        );
        let go = || !stop.load(Ordering::Relaxed);
        urg_emu::serve_tcp(cfg, scene, clock, listener, log.clone(), &go)?;
        summary(&log);
        return Ok(());
    }
    let host = PtyHost::new(args.link.clone())?;
    let link_note = match &args.link {
        Some(l) => format!(" (symlink {})", l.display()),
        None => String::new(),
    };
    let mut on_plug = |p: Option<PathBuf>| match p {
        Some(p) => println!(
            "{} emulated ({} ms scans) at {}{link_note}",
            spec.vv[1].1,
            (spec.period() * 1e3).round(),
            p.display()
        ),
        None => println!("unplugged"),
    };
    let keep_going = |_: &Option<PathBuf>| !stop.load(Ordering::Relaxed);
    urg_emu::run(
        cfg,
        scene,
        clock,
        host,
        log.clone(),
        &mut on_plug,
        &keep_going,
    )?;
    summary(&log);
    Ok(())
}

fn summary(log: &Mutex<EmuLog>) {
    if let Ok(l) = log.lock() {
        println!(
            "stopped: {} scans sent ({} corrupted on purpose, {:.1} % of steps error codes), {} commands, {} boots",
            l.sent.len(),
            l.corrupted(),
            100.0 * l.error_share(),
            l.commands.len(),
            l.boots
        );
    }
}
