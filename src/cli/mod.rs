//! Command-line flag structs, one file per command. Each command's `run` turns its flags into the
//! library's validated configuration and calls the library; no numerics live here.

mod check;
mod common;
mod settle;

use clap::{Parser, Subcommand};

/// biasctl: predict, diagnose and compensate disk-drive actuator bias.
#[derive(Debug, Parser)]
#[command(name = "biasctl", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Read a measurement log, validate every row and print a summary.
    Check(check::Args),
    /// Settle-optimal integrator start value at the seek → track-following handoff.
    Settle(settle::Args),
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Check(a) => check::run(a),
        Command::Settle(a) => settle::run(a),
    }
}
