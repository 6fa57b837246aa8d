//! `sweepline report`: writes the latency/CPU budget report from a run's metrics.

use super::CliResult;

/// Arguments of `sweepline report`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder of a run (its metrics file).
    pub run_dir: std::path::PathBuf,
}

/// Runs `sweepline report`.
pub fn run(args: Args) -> CliResult {
    let _ = args;
    super::not_yet("report")
}
