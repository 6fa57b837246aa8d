//! The `sweepline` command line: one module per subcommand, each with its
//! arguments (clap derive) and a `run` function. `main.rs` only dispatches.

pub mod coverage;
pub mod emulate;
pub mod eval;
pub mod probe;
pub mod replay;
pub mod replay_mcap;
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

/// The exit codes of the `sweepline` binary (also in `--help`).
pub mod exit {
    /// The command did what it was asked.
    pub const OK: i32 = 0;
    /// An error: the message on stderr says what and, where it can, how to fix it.
    pub const ERROR: i32 = 1;
    /// The command line was wrong (clap's own code).
    pub const USAGE: i32 = 2;
    /// A simulation reached its `--time-cap` before coverage finished; its
    /// report was written.
    pub const TIME_CAP: i32 = 3;
}

/// The error of a simulation stopped by its time cap: reported with exit
/// code [`exit::TIME_CAP`], not as a failure of the program.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct TimeCapReached(pub String);

/// The exit code for a subcommand's error.
pub fn exit_code(e: &(dyn std::error::Error + Send + Sync + 'static)) -> i32 {
    if e.downcast_ref::<TimeCapReached>().is_some() {
        exit::TIME_CAP
    } else {
        exit::ERROR
    }
}
