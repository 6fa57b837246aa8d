//! `sweepline run`: the daemon on real devices (systemd service).
//!
//! This build loads and validates the configuration, installs the signal
//! handlers and the systemd notifier, opens the state folder and looks for a
//! checkpoint to resume, then checks both serial devices. The scanner,
//! localise, map, plan, control and motor stages are wired in here as they
//! land; until then a run with both devices present stops with a clear error.

use std::path::{Path, PathBuf};

use super::CliResult;
use crate::config::Config;
use crate::pipeline::checkpoint::{CheckpointStore, RunProgress};
use crate::pipeline::notify::Notifier;
use crate::pipeline::signals::SignalForwarder;
use crate::pipeline::supervisor::Supervisor;

/// Stable device name the udev rules give the URG-04LX (`hw/99-sweepline.rules`).
pub const DEFAULT_SCANNER: &str = "/dev/sweepline-urg";
/// Stable device name the udev rules give the wheel base.
pub const DEFAULT_BASE: &str = "/dev/sweepline-base";
/// State folder when neither `--state-dir` nor systemd's `STATE_DIRECTORY` is set.
pub const DEFAULT_STATE_DIR: &str = "/var/lib/sweepline";

/// Arguments of `sweepline run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Configuration file.
    #[arg(long, default_value = "hw/robot.toml")]
    pub config: PathBuf,
    /// Only load and validate the configuration, then exit (0 when valid).
    #[arg(long)]
    pub check_config: bool,
    /// Scanner serial device.
    #[arg(long, default_value = DEFAULT_SCANNER)]
    pub scanner: PathBuf,
    /// Wheel-base serial device.
    #[arg(long, default_value = DEFAULT_BASE)]
    pub base: PathBuf,
    /// Folder for checkpoints, metrics and reports (default: systemd's
    /// `$STATE_DIRECTORY`, else /var/lib/sweepline).
    #[arg(long)]
    pub state_dir: Option<PathBuf>,
}

/// The state folder: the flag, else the first entry of `$STATE_DIRECTORY`
/// (set by systemd's `StateDirectory=`), else [`DEFAULT_STATE_DIR`].
pub fn state_dir(flag: Option<&Path>) -> PathBuf {
    if let Some(p) = flag {
        return p.to_path_buf();
    }
    std::env::var("STATE_DIRECTORY")
        .ok()
        .and_then(|v| v.split(':').next().map(PathBuf::from))
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or_else(|| PathBuf::from(DEFAULT_STATE_DIR))
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
    let cfg = Config::load(&args.config)?;
    if args.check_config {
        println!("{}: configuration is valid", args.config.display());
        return Ok(());
    }
    let supervisor = Supervisor::new(&cfg.pipeline);
    let _signals = SignalForwarder::install(supervisor.control())
        .map_err(|e| format!("cannot install signal handlers: {e}"))?;
    let notifier = Notifier::new();
    notifier.status("starting: checking state folder and devices");

    let dir = state_dir(args.state_dir.as_deref());
    std::fs::create_dir_all(&dir)
        .map_err(|e| format!("cannot create state folder {}: {e}", dir.display()))?;
    let store = CheckpointStore::new(&dir);
    match store.load() {
        Ok(None) => log::info!("no checkpoint in {}: fresh start", dir.display()),
        Ok(Some(l)) => {
            if let Some(why) = &l.fell_back {
                log::warn!("latest checkpoint unusable ({why}); using the previous copy");
            }
            match l.checkpoint.get::<RunProgress>() {
                Ok(Some(p)) => log::info!(
                    "checkpoint #{} found: {:.1} % covered after {:.0} s; resuming",
                    p.sequence,
                    p.coverage * 100.0,
                    p.elapsed
                ),
                Ok(None) => log::info!("checkpoint found without progress section"),
                Err(e) => log::warn!("checkpoint progress unreadable: {e}"),
            }
        }
        Err(e) => log::warn!("no usable checkpoint, starting fresh: {e}"),
    }

    let devices = check_device("scanner", &args.scanner)
        .and_then(|()| check_device("wheel-base", &args.base));
    if let Err(msg) = devices {
        notifier.status(&format!("failed: {msg}"));
        return Err(msg.into());
    }
    let msg = "both devices are present, but the scanner and motor stages are not wired into \
               `sweepline run` in this build yet (use `sweepline sim`)";
    notifier.status(&format!("failed: {msg}"));
    Err(msg.into())
}
