//! The `sweepline` binary: command line parsing and dispatch only.

#![forbid(unsafe_code)]

use clap::{Parser, Subcommand};
use sweepline::cli;

/// sweepline: an online coverage daemon for a URG-04LX robot.
#[derive(Parser)]
#[command(name = "sweepline", version, about, long_about = None, after_help = AFTER_HELP)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Logging and exit codes, shown under `--help`.
const AFTER_HELP: &str = "\
Logging: RUST_LOG sets the level (error, warn, info, debug, trace; default info),
per module too: RUST_LOG=warn,sweepline::motor=debug. Logs go to stderr.

Exit codes: 0 done; 1 error (the message says what); 2 wrong command line;
3 a simulation reached its --time-cap before coverage finished (report written).";

#[derive(Subcommand)]
enum Command {
    /// Simulated robot covering a world, writing its report (the main job).
    #[command(allow_negative_numbers = true)]
    Sim(cli::sim::Args),
    /// Run the daemon on real devices.
    #[command(allow_negative_numbers = true)]
    Run(cli::run::Args),
    /// Ask a scanner what it is and show one scan and the health counters.
    #[command(allow_negative_numbers = true)]
    Probe(cli::probe::Args),
    /// Run an emulated device on a pty (urg, roboclaw, create2).
    #[command(allow_negative_numbers = true)]
    Emulate(cli::emulate::Args),
    /// Run the scan matcher over a CARMEN log.
    #[command(allow_negative_numbers = true)]
    Replay(cli::replay::Args),
    /// Score a trajectory against ground-truth relations.
    #[command(allow_negative_numbers = true)]
    Eval(cli::eval::Args),
    /// Lock-step coverage planning run on a world (ideal localisation).
    #[command(allow_negative_numbers = true)]
    Coverage(cli::coverage::Args),
    /// Write the latency/CPU budget report of a run.
    #[command(allow_negative_numbers = true)]
    Report(cli::report::Args),
}

fn main() {
    let cli = Cli::parse();
    // The simulator's progress lines are on stdout: its log stays at warn
    // unless RUST_LOG says otherwise. The daemon and the tools log at info.
    let level = match cli.command {
        Command::Sim(_) => "warn",
        _ => "info",
    };
    init_logging(level);
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
        let code = cli::exit_code(&*e);
        if code == cli::exit::TIME_CAP {
            eprintln!("sweepline: {e}");
        } else {
            eprintln!("sweepline: error: {e}");
        }
        std::process::exit(code);
    }
}

/// Logs to stderr at `default` (or as `RUST_LOG` says). Under systemd's
/// journal (`JOURNAL_STREAM` set) each line starts with its syslog priority
/// `<N>`, so `journalctl -p` filters it, and carries no timestamp of its
/// own (the journal stamps it).
fn init_logging(default: &str) {
    use std::io::Write;
    let mut b =
        env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(default));
    if std::env::var_os("JOURNAL_STREAM").is_some() {
        b.format(|buf, record| {
            let priority = match record.level() {
                log::Level::Error => 3,
                log::Level::Warn => 4,
                log::Level::Info => 6,
                log::Level::Debug | log::Level::Trace => 7,
            };
            writeln!(buf, "<{priority}>{}: {}", record.target(), record.args())
        });
    } else {
        b.format_timestamp_millis();
    }
    // The console as configured, and a copy of each line for the live view
    // and the recording (`/log`).
    let console = b.build();
    let level = console.filter();
    let _ = sweepline::live::logs::install(Box::new(console), level);
}
