//! `sweepline probe`: asks a scanner what it is (VV, PP, II), takes one scan and prints a summary and the health counters.

use super::CliResult;

/// Arguments of `sweepline probe`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial device of the scanner, e.g. /dev/ttyACM0 or a pty path.
    #[arg(long)]
    pub port: std::path::PathBuf,
}

/// Runs `sweepline probe`.
pub fn run(args: Args) -> CliResult {
    let _ = args;
    super::not_yet("probe")
}
