//! `sweepline run`: the daemon on real devices (systemd service).

use super::CliResult;

/// Arguments of `sweepline run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Configuration file.
    #[arg(long, default_value = "hw/robot.toml")]
    pub config: std::path::PathBuf,
}

/// Runs `sweepline run`.
pub fn run(args: Args) -> CliResult {
    let _ = args;
    super::not_yet("run")
}
