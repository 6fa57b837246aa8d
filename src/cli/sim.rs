//! `sweepline sim`: the main job: starts the emulated scanner and wheel base on ptys and the daemon, covers the default world and writes a report folder.

use super::CliResult;

/// Arguments of `sweepline sim`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// World file to cover (default: hw/worlds/paper.world).
    #[arg(long)]
    pub world: Option<std::path::PathBuf>,
}

/// Runs `sweepline sim`.
pub fn run(args: Args) -> CliResult {
    let _ = args;
    super::not_yet("sim")
}
