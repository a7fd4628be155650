//! `biasctl ladder`: add terms one at a time, refit on a training log, score on a test log.

use super::common::{ColumnArgs, DirectionArgs};
use crate::{ladder_fit, ladder_terms};
use anyhow::Context;
use std::path::PathBuf;

/// Flags of `biasctl ladder`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The training log (every step is fitted on it).
    #[arg(long, value_name = "TRAIN.csv")]
    data: PathBuf,
    /// The test log (every step is scored on it).
    #[arg(long, value_name = "TEST.csv")]
    test: PathBuf,
    /// The terms in the order they are added, e.g. `poly2,direction,seek,memory`.
    #[arg(long, value_name = "T1,T2,...")]
    terms: String,
    #[command(flatten)]
    columns: ColumnArgs,
    #[command(flatten)]
    direction: DirectionArgs,
    /// Print JSON: {"steps": [{"terms", "std", "reduction"}, ...]}.
    #[arg(long)]
    json: bool,
}

/// Reads both logs, fits every prefix of the term list and prints the table.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let terms = ladder_terms(&args.terms)?;
    let opts = args.direction.fit_options()?;
    let train = args.columns.read_log(&args.data).context("--data")?;
    let test = args.columns.read_log(&args.test).context("--test")?;
    let l = ladder_fit(&train, &test, &terms, &opts)?;
    if args.json {
        outln!("{}", l.to_json()?)?;
    } else {
        let units = &test.schema.units;
        outln!(
            "fitted on {}, error std on {} ({}):",
            train.schema.file,
            test.schema.file,
            units.bias
        )?;
        out!("{}", l.to_text(units))?;
    }
    Ok(())
}
