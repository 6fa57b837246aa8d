//! `sweepline emulate`: runs an emulated device (URG scanner, RoboClaw or Create 2 base) on a pseudo-terminal.

use super::CliResult;

/// Arguments of `sweepline emulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Which device to emulate: urg, roboclaw or create2.
    pub device: String,
}

/// Runs `sweepline emulate`.
pub fn run(args: Args) -> CliResult {
    let _ = args;
    super::not_yet("emulate")
}
