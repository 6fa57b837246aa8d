//! `sweepline eval`: scores a trajectory against Kümmerle et al. relations.

use super::CliResult;

/// Arguments of `sweepline eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The relations file (t1 t2 x y z roll pitch yaw per line).
    #[arg(long)]
    pub relations: std::path::PathBuf,
    /// The trajectory (timestamp x y theta per line).
    pub trajectory: std::path::PathBuf,
}

/// Runs `sweepline eval`.
pub fn run(args: Args) -> CliResult {
    let _ = args;
    super::not_yet("eval")
}
