//! `sweepline run`: the daemon on real devices (systemd service).
//!
//! Loads and validates the configuration, opens the state folder and looks
//! for a checkpoint to resume (map, pose, progress), checks both serial
//! devices, then starts the daemon (`crate::daemon`: the same stages
//! `sweepline sim` runs over ptys) with the monotonic clock, the systemd
//! notifier and the signal handlers, and supervises it until coverage is
//! done or SIGTERM (wheels stopped, scanner QT, final checkpoint). Metrics
//! and the budget report go to `STATE/run/`.

use std::path::{Path, PathBuf};

use std::sync::Arc;

use super::CliResult;
use crate::clock::{MonotonicClock, ScaledClock, SharedClock};
use crate::config::Config;
use crate::daemon::{Daemon, DaemonSetup, MapFrame};
use crate::geom::Pose;
use crate::pipeline::checkpoint::CheckpointStore;
use crate::pipeline::notify::Notifier;
use crate::pipeline::signals::SignalForwarder;
use crate::report::run_folder::RunFolderHooks;

/// State folder when neither `--state-dir` nor systemd's `STATE_DIRECTORY` is set.
pub const DEFAULT_STATE_DIR: &str = "/var/lib/sweepline";
/// Configuration file when neither `--config` nor systemd's
/// `CONFIGURATION_DIRECTORY` is set.
pub const DEFAULT_CONFIG: &str = "/etc/sweepline/robot.toml";

/// Arguments of `sweepline run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Configuration file (default: `robot.toml` in systemd's
    /// `$CONFIGURATION_DIRECTORY`, else /etc/sweepline/robot.toml).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Run every check of the configuration that `run` makes before opening
    /// the devices, print the devices it would open, then exit (0 when valid).
    #[arg(long)]
    pub check_config: bool,
    /// The scanner: a serial device or HOST:PORT of an Ethernet model
    /// (default: the config's `[scanner] port`); the same flag as
    /// `sweepline probe --scanner`.
    #[arg(long)]
    pub scanner: Option<PathBuf>,
    /// Wheel-base serial device (default: the config's `[motor] device`).
    #[arg(long)]
    pub base: Option<PathBuf>,
    /// Folder for checkpoints, metrics and reports (default: systemd's
    /// `$STATE_DIRECTORY`, else /var/lib/sweepline).
    #[arg(long)]
    pub state_dir: Option<PathBuf>,
    /// Side of the square map around the start (m): the largest room the
    /// robot can cover from where it is switched on is half of it each way.
    #[arg(long, default_value_t = 16.0)]
    pub map_extent: f64,
    /// For a simulator that runs the daemon as a separate process: the
    /// daemon's clock runs SCALE times the wall clock and read 0 at UNIX
    /// time EPOCH (s), the simulator's own clock (see docs/simulator.md).
    #[arg(long, value_name = "SCALE,EPOCH", hide = true, value_parser = parse_sim_clock)]
    pub sim_clock: Option<(f64, f64)>,
    /// Start a new run even if the state folder holds the checkpoint of one
    /// that was stopped before it finished (the robot was carried to
    /// another room meanwhile). A finished run is never resumed.
    #[arg(long)]
    pub fresh: bool,
}

/// The configuration file: the flag, else `robot.toml` in the first entry of
/// `$CONFIGURATION_DIRECTORY` (set by systemd's `ConfigurationDirectory=`),
/// else [`DEFAULT_CONFIG`].
pub fn config_path(flag: Option<&Path>) -> PathBuf {
    if let Some(p) = flag {
        return p.to_path_buf();
    }
    systemd_dir("CONFIGURATION_DIRECTORY")
        .map(|d| d.join("robot.toml"))
        .unwrap_or_else(|| PathBuf::from(DEFAULT_CONFIG))
}

/// The first entry of the colon-separated folder list systemd puts in
/// `var` (`STATE_DIRECTORY`, `CONFIGURATION_DIRECTORY`), if set and not empty.
fn systemd_dir(var: &str) -> Option<PathBuf> {
    std::env::var(var)
        .ok()
        .and_then(|v| v.split(':').next().map(PathBuf::from))
        .filter(|p| !p.as_os_str().is_empty())
}

/// The state folder: the flag, else the first entry of `$STATE_DIRECTORY`
/// (set by systemd's `StateDirectory=`), else [`DEFAULT_STATE_DIR`].
pub fn state_dir(flag: Option<&Path>) -> PathBuf {
    if let Some(p) = flag {
        return p.to_path_buf();
    }
    systemd_dir("STATE_DIRECTORY").unwrap_or_else(|| PathBuf::from(DEFAULT_STATE_DIR))
}

/// The run folder in the state folder: metrics, the report, `mount.toml`,
/// `events.toml`, `resume.toml`.
pub const RUN_FOLDER: &str = "run";

/// At a new run, the last run's folder `run` is kept as `run.prev` (the
/// one before is removed): the next day's run does not wipe the report of
/// the last. A failure is logged; the run goes on.
pub fn keep_previous_run(run: &Path) {
    let non_empty = std::fs::read_dir(run).is_ok_and(|mut d| d.next().is_some());
    if !non_empty {
        return;
    }
    let prev = run.with_extension("prev");
    let r = match std::fs::remove_dir_all(&prev) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e),
        _ => std::fs::rename(run, &prev),
    };
    match r {
        Ok(()) => log::info!(
            "a new run: the last run's reports are kept in {}",
            prev.display()
        ),
        Err(e) => log::warn!(
            "a new run: cannot keep the last run's reports as {} ({e}); they are overwritten",
            prev.display()
        ),
    }
}

/// Checks that a serial device exists and is a character device.
fn check_device(what: &str, path: &Path) -> Result<(), String> {
    use std::os::unix::fs::FileTypeExt;
    match std::fs::metadata(path) {
        Ok(m) if m.file_type().is_char_device() => Ok(()),
        Ok(_) => Err(format!(
            "{what} device {} exists but is not a character device",
            path.display()
        )),
        Err(e) => Err(format!(
            "{what} device {} is not available ({e}): is it plugged in, and are the udev \
             rules hw/99-sweepline.rules installed (README, \"Running as a service\")?",
            path.display()
        )),
    }
}

/// Runs `sweepline run`.
pub fn run(args: Args) -> CliResult {
    let path = config_path(args.config.as_deref());
    let mut cfg = Config::load(&path)?;
    // The devices: the flags when given, else the configuration's keys.
    let scanner = args
        .scanner
        .clone()
        .unwrap_or_else(|| PathBuf::from(&cfg.scanner.port));
    let base_dev = args
        .base
        .clone()
        .unwrap_or_else(|| PathBuf::from(&cfg.motor.device));
    if args.check_config {
        println!(
            "{}: configuration is valid; scanner {}, wheel base ({}) {}",
            path.display(),
            scanner.display(),
            cfg.motor.kind.name(),
            base_dev.display()
        );
        return Ok(());
    }
    let notifier = Notifier::new();
    notifier.status("starting: checking state folder and devices");

    let dir = state_dir(args.state_dir.as_deref());
    std::fs::create_dir_all(&dir)
        .map_err(|e| format!("cannot create state folder {}: {e}", dir.display()))?;
    let store = CheckpointStore::new(&dir);
    let resume = if args.fresh {
        log::info!(
            "--fresh: a new run; any checkpoint in {} is not resumed",
            dir.display()
        );
        None
    } else {
        crate::daemon::resume::load(&store, &crate::daemon::resume::heartbeat_store(&dir))
    };
    if resume.is_none() {
        keep_previous_run(&dir.join(RUN_FOLDER));
    }

    let scanner_name = scanner.display().to_string();
    let devices = if crate::serial::is_network_address(&scanner_name) {
        Ok(())
    } else {
        check_device("scanner", &scanner)
    }
    .and_then(|()| check_device("wheel-base", &base_dev));
    if let Err(msg) = devices {
        notifier.status(&format!("failed: {msg}"));
        return Err(msg.into());
    }
    cfg.scanner.port = scanner.display().to_string();
    cfg.motor.device = base_dev.display().to_string();
    if let Some((scale, epoch)) = args.sim_clock {
        cfg.pipeline.time_scale = scale;
        cfg.pipeline.clock_epoch = epoch;
    }
    let p = &cfg.pipeline;
    let clock: SharedClock = if p.time_scale != 1.0 || p.clock_epoch > 0.0 {
        log::info!(
            "clock: {}x wall time since UNIX time {:.3}",
            p.time_scale,
            p.clock_epoch
        );
        Arc::new(ScaledClock::since_unix(p.time_scale, p.clock_epoch))
    } else {
        Arc::new(MonotonicClock::new())
    };
    let base = crate::motor::open_base(&cfg.motor, &cfg.robot, clock.clone());
    let start = resume
        .as_ref()
        .map(|r| r.run.pose)
        .unwrap_or_else(Pose::identity);
    let map = MapFrame::centred(
        start.translation.vector.into(),
        args.map_extent,
        cfg.decomp.resolution,
    );
    let telemetry_wanted = cfg.record.enabled || !cfg.live.bind.is_empty();
    let mut daemon = Daemon::start(DaemonSetup {
        config: cfg.clone(),
        clock: clock.clone(),
        scanner: crate::serial::scanner_connector(&scanner_name, cfg.scanner.baud),
        base,
        start,
        map,
        resume,
        state_dir: Some(dir.clone()),
        taps: telemetry_wanted,
    })?;
    let telemetry = start_telemetry(&cfg, &dir, (start, map), &mut daemon, clock);
    let _signals = SignalForwarder::install(daemon.control())
        .map_err(|e| format!("cannot install signal handlers: {e}"))?;
    let mut hooks = RunFolderHooks::new(daemon.hooks(), &dir.join(RUN_FOLDER), &cfg.pipeline)
        .with_resume(daemon.resume_entry());
    let outcome = daemon.run(&mut hooks);
    log::info!("stopped: {}", outcome.reason);
    if let Some(t) = telemetry {
        let stats = t.finish(Vec::new());
        log::info!(
            "recorded {} scans ({} bytes in the last file)",
            stats.scans,
            stats.recorded_bytes
        );
    }
    if outcome.reason.is_failure() {
        Err(format!("the daemon stopped: {}", outcome.reason).into())
    } else {
        Ok(())
    }
}

/// The recording (`recordings/` in the state folder, rotating under the
/// `[record]` size cap) and the live view (`[live] bind`), as configured.
fn start_telemetry(
    cfg: &Config,
    dir: &std::path::Path,
    (start, frame): (Pose, MapFrame),
    daemon: &mut Daemon,
    clock: SharedClock,
) -> Option<crate::live::Telemetry> {
    let taps = daemon.take_taps()?;
    const MIB: f64 = 1024.0 * 1024.0;
    let r = &cfg.record;
    let opts = crate::live::TelemetryOptions {
        record: r.enabled.then(|| crate::live::RecordTo::Rotating {
            dir: dir.join("recordings"),
            file_bytes: (r.file_mib * MIB) as u64,
            total_bytes: (r.max_mib * MIB) as u64,
        }),
        record_channels: r.channels.clone(),
        live: (!cfg.live.bind.is_empty()).then(|| cfg.live.bind.clone()),
        mount: cfg.robot.scanner_mount(),
        sim: false,
        setup: Some(crate::live::recording::Setup {
            config: cfg.clone(),
            start,
            frame,
        }),
        scanner: Some(daemon.urg_health()),
    };
    // A robot does not refuse to clean for want of a recording.
    match crate::live::Telemetry::start(taps, daemon.shared(), clock, opts) {
        Ok(t) => Some(t),
        Err(e) => {
            log::warn!("{e}; the run goes on without a recording or live view");
            None
        }
    }
}

/// `--sim-clock SCALE,EPOCH`: a time scale in (0, 1000] and a UNIX time >= 0.
fn parse_sim_clock(s: &str) -> Result<(f64, f64), String> {
    let bad = || {
        format!("expected SCALE,EPOCH (a speed in (0, 1000] and a UNIX time in seconds), got `{s}`")
    };
    let (a, b) = s.split_once(',').ok_or_else(bad)?;
    let scale: f64 = a.trim().parse().map_err(|_| bad())?;
    let epoch: f64 = b.trim().parse().map_err(|_| bad())?;
    if scale > 0.0 && scale <= 1000.0 && epoch.is_finite() && epoch >= 0.0 {
        Ok((scale, epoch))
    } else {
        Err(bad())
    }
}
