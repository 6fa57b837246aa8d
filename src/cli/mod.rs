//! The `sweepline` command line: one module per subcommand, each with its
//! arguments (clap derive) and a `run` function. `main.rs` only dispatches.

pub mod coverage;
pub mod emulate;
pub mod eval;
pub mod probe;
pub mod replay;
pub mod report;
pub mod run;
pub mod sim;
pub mod world_args;

/// What a subcommand returns: `main` prints the error on one line and exits non-zero.
pub type CliResult = Result<(), Box<dyn std::error::Error + Send + Sync + 'static>>;

/// The error of a subcommand that this build does not provide yet.
pub fn not_yet(what: &str) -> CliResult {
    Err(format!("`sweepline {what}` is not implemented in this build yet").into())
}
