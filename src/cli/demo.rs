//! `biasctl demo`: the whole story on the built-in drive in one command — the paper's tables,
//! a dwell run, a calibration and a random run, fitted models, diagnosis, ladder, settle — into
//! one folder with `report.html`.

use super::common::ColumnArgs;
use super::report::{print_outcome, story};
use std::path::PathBuf;

/// Flags of `biasctl demo`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Output folder (created if missing).
    #[arg(long, default_value = "out/demo", value_name = "DIR")]
    out: PathBuf,
    /// Seed for every run.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    seed: u64,
    /// Random seeks of the test and calibration runs.
    #[arg(allow_negative_numbers = true, long, default_value_t = crate::sim::DEFAULT_N, value_name = "N")]
    seeks: u64,
}

/// Runs the story and prints the report's path and five headline lines.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    outln!("demo: drive paper1997, seed {}", args.seed)?;
    let outcome = story(&super::report::Args {
        out: args.out,
        data: None,
        columns: ColumnArgs::default(),
        model: None,
        seed: args.seed,
        seeks: args.seeks,
    })?;
    let logs: Vec<String> = outcome
        .files
        .iter()
        .filter_map(|p| {
            p.file_name()?
                .to_str()?
                .strip_suffix(".csv")
                .map(String::from)
        })
        .filter(|n| !n.ends_with("_truth") && !n.starts_with("settle_"))
        .collect();
    outln!(
        "wrote {} files; simulated logs (each with a _truth.csv): {}",
        outcome.files.len() + 1,
        logs.join(", ")
    )?;
    print_outcome(&outcome)?;
    Ok(())
}
