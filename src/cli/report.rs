//! `sweepline report`: writes the latency/CPU budget report from a run's metrics.

use super::CliResult;

/// Arguments of `sweepline report`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder of a run (holding its `metrics.toml`); the report is written there.
    pub run_dir: std::path::PathBuf,
}

/// Runs `sweepline report`.
pub fn run(args: Args) -> CliResult {
    let path = crate::report::report_run_dir(&args.run_dir)?;
    println!("{}", path.display());
    Ok(())
}
