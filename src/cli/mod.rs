//! Command-line flag structs, one file per command. Each command's `run` turns its flags into the
//! library's validated configuration and calls the library; no numerics live here.

/// Prints a line to stdout through the one output path ([`crate::io::write_stdout`]):
/// evaluates to `Result<(), OutputError>` (a closed pipe is `OutputError::BrokenPipe`).
macro_rules! outln {
    () => {
        crate::io::write_stdout("\n")
    };
    ($($t:tt)*) => {
        crate::io::write_stdout(&format!("{}\n", format_args!($($t)*)))
    };
}

/// Prints to stdout without a newline, as [`outln!`].
macro_rules! out {
    ($($t:tt)*) => {
        crate::io::write_stdout(&format!($($t)*))
    };
}

mod check;
mod common;
mod demo;
mod diagnose;
mod discover;
mod export;
mod fit;
mod fleet;
mod ladder;
mod plot;
mod predict;
mod progress;
mod report;
mod score;
mod settle;
mod simulate;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

/// biasctl: predict, diagnose and compensate disk-drive actuator bias.
#[derive(Debug, Parser)]
#[command(name = "biasctl", version, about, long_about = None)]
pub(crate) struct Cli {
    /// Worker threads for parallel work (ladder steps, diagnose); default: one per core.
    /// Results are the same for any number.
    #[arg(allow_negative_numbers = true, long, global = true, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Read a measurement log, validate every row and print a summary.
    Check(check::Args),
    /// Simulate the drive through a seek sequence and write a measurement log.
    Simulate(simulate::Args),
    /// The whole story on the built-in drive: simulate, fit, diagnose, settle, and write report.html.
    Demo(demo::Args),
    /// Draw one figure (SVG) from a log, a model or a settle analysis.
    Plot(plot::Args),
    /// Write one self-contained report.html (and every file behind it) for the built-in drive or your log.
    Report(report::Args),
    /// Fit a bias model (a preset or a term list) to a log and write the model file.
    Fit(fit::Args),
    /// Replay a model over a log causally and write per-row predictions and contributions.
    Predict(predict::Args),
    /// Score a model on a log: error moments, percentiles, histogram, bimodality, dip test, trend.
    Score(score::Args),
    /// Compare a model with a log: which missing effect the residual follows, and the term to add.
    Diagnose(diagnose::Args),
    /// Add terms one at a time, refit on a training log, score on a test log.
    Ladder(ladder::Args),
    /// Run the loop: fit, diagnose, apply the best verified edit, repeat until nothing is left.
    Discover(discover::Args),
    /// Settle-optimal integrator start value at the seek → track-following handoff.
    Settle(settle::Args),
    /// Export a fitted model for firmware (`export c`: C99 state struct, init, step, peek).
    Export(export::Args),
    /// One model over many drives: `fleet fit` (the fleet table), `fleet outliers`.
    Fleet(fleet::Args),
}

/// Parses the command line (exiting on `--help`, `--version` and flag errors, as clap does)
/// and checks what clap cannot: that `--time-col`, `--track-col` and `--bias-col` name three
/// different columns.
pub(crate) fn parse() -> Result<Cli, clap::Error> {
    let mut cmd = Cli::command();
    let matches = cmd.get_matches_mut();
    if let Some((_, sub)) = matches.subcommand()
        && let Some(msg) = column_clash(sub)
    {
        return Err(cmd.error(clap::error::ErrorKind::ArgumentConflict, msg));
    }
    Cli::from_arg_matches(&matches).map_err(|e| e.format(&mut cmd))
}

/// A message when two of the column flags (or their defaults) name the same column.
fn column_clash(m: &clap::ArgMatches) -> Option<String> {
    let get = |id: &str| m.try_get_one::<String>(id).ok().flatten();
    let cols = [
        ("--time-col", get("time_col")?),
        ("--track-col", get("track_col")?),
        ("--bias-col", get("bias_col")?),
    ];
    for i in 0..cols.len() {
        for j in i + 1..cols.len() {
            if cols[i].1 == cols[j].1 {
                return Some(format!(
                    "{} and {} both name the column `{}`; time, position and bias each need their own column",
                    cols[i].0, cols[j].0, cols[i].1
                ));
            }
        }
    }
    None
}

/// The text printed after `error: ` ([`crate::io::message_with`]), every library setting
/// name rendered as its flag by the one table ([`common::FLAGS`]).
pub(crate) fn message(err: &(dyn std::error::Error + 'static)) -> String {
    crate::io::message_with(err, &common::with_flags)
}

/// Runs the parsed command.
pub(crate) fn run(cli: Cli) -> anyhow::Result<()> {
    if let Some(n) = cli.threads {
        crate::set_threads(n.into())?;
    }
    match cli.command {
        Command::Check(a) => check::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Plot(a) => plot::run(a),
        Command::Report(a) => report::run(a),
        Command::Fit(a) => fit::run(a),
        Command::Predict(a) => predict::run(a),
        Command::Score(a) => score::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Ladder(a) => ladder::run(a),
        Command::Discover(a) => discover::run(a),
        Command::Settle(a) => settle::run(a),
        Command::Export(a) => export::run(a),
        Command::Fleet(a) => fleet::run(a),
    }
}

/// The `biasctl` program: parses the flags, runs the command and turns the outcome into the
/// exit code. 0 success (also when the reader of stdout goes away, as with `biasctl … | head`),
/// 2 bad input or a failed write (one message on stderr).
pub fn main() -> std::process::ExitCode {
    let args = match parse() {
        Ok(args) => args,
        Err(e) => e.exit(),
    };
    let result = run(args).and_then(|()| Ok(crate::io::flush_stdout()?));
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) if crate::io::is_broken_pipe(err.as_ref()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            // stderr gone too: nothing left to tell, the exit code still says it.
            let _ = std::io::Write::write_all(
                &mut std::io::stderr(),
                format!("error: {}\n", message(err.as_ref())).as_bytes(),
            );
            std::process::ExitCode::from(2)
        }
    }
}
