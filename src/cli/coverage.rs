//! `sweepline coverage`: runs the online decomposition and coverage planner in a deterministic lock-step simulation (ideal localisation) and writes metrics and pictures.

use super::CliResult;

/// Arguments of `sweepline coverage`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// World file (hw/worlds/*.world) or floor-plan PNG.
    #[arg(long)]
    pub world: Option<std::path::PathBuf>,
}

/// Runs `sweepline coverage`.
pub fn run(args: Args) -> CliResult {
    let _ = args;
    super::not_yet("coverage")
}
