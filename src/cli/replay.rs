//! `sweepline replay`: runs the scan matcher over a recorded CARMEN log and writes the trajectory and a picture.

use super::CliResult;

/// Arguments of `sweepline replay`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The CARMEN log (FLASER / ROBOTLASER1 / ODOM lines); .gz accepted.
    pub log: std::path::PathBuf,
}

/// Runs `sweepline replay`.
pub fn run(args: Args) -> CliResult {
    let _ = args;
    super::not_yet("replay")
}
