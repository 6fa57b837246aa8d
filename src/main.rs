//! The `sweepline` binary: command line parsing and dispatch only.

use clap::{Parser, Subcommand};
use sweepline::cli;

/// sweepline: an online coverage daemon for a URG-04LX robot.
#[derive(Parser)]
#[command(name = "sweepline", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulated robot covering a world, writing its report (the main job).
    Sim(cli::sim::Args),
    /// Run the daemon on real devices.
    Run(cli::run::Args),
    /// Ask a scanner what it is and show one scan and the health counters.
    Probe(cli::probe::Args),
    /// Run an emulated device on a pty (urg, roboclaw, create2).
    Emulate(cli::emulate::Args),
    /// Run the scan matcher over a CARMEN log.
    Replay(cli::replay::Args),
    /// Score a trajectory against ground-truth relations.
    Eval(cli::eval::Args),
    /// Lock-step coverage planning run on a world (ideal localisation).
    Coverage(cli::coverage::Args),
    /// Write the latency/CPU budget report of a run.
    Report(cli::report::Args),
}

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("info"))
        .format_timestamp_millis()
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Sim(a) => cli::sim::run(a),
        Command::Run(a) => cli::run::run(a),
        Command::Probe(a) => cli::probe::run(a),
        Command::Emulate(a) => cli::emulate::run(a),
        Command::Replay(a) => cli::replay::run(a),
        Command::Eval(a) => cli::eval::run(a),
        Command::Coverage(a) => cli::coverage::run(a),
        Command::Report(a) => cli::report::run(a),
    };
    if let Err(e) = result {
        eprintln!("sweepline: error: {e}");
        std::process::exit(1);
    }
}
