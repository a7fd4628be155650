//! `biasctl report`: the whole story as one self-contained `report.html` plus every CSV/JSON
//! behind it; on the built-in drive, or on a user's log (`--data`) and model (`--model`).

use super::common::ColumnArgs;
use super::progress::Bar;
use crate::FittedModel;
use crate::{StoryOptions, data_report, demo_report, report::StoryOutcome};
use anyhow::Context;
use std::path::PathBuf;

/// Flags of `biasctl report`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Output folder (created if missing): report.html and the files behind it.
    #[arg(long, default_value = "out/report", value_name = "DIR")]
    pub out: PathBuf,
    /// Your measurement log; without it the report runs on the built-in drive.
    #[arg(long, value_name = "LOG.csv")]
    pub data: Option<PathBuf>,
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Your fitted model (from `biasctl fit`), scored and diagnosed on --data.
    #[arg(long, value_name = "MODEL.json", requires = "data")]
    pub model: Option<PathBuf>,
    /// Seed of the simulations and the diagnosis (printed in the report).
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    pub seed: u64,
    /// Random seeks of the built-in drive's test and calibration runs.
    #[arg(allow_negative_numbers = true, long, default_value_t = crate::sim::DEFAULT_N, value_name = "N")]
    pub seeks: u64,
}

/// Runs the story with a progress bar; returns what was written.
pub(crate) fn story(args: &Args) -> anyhow::Result<StoryOutcome> {
    let opts = StoryOptions {
        seed: args.seed,
        random_seeks: args.seeks,
        ..StoryOptions::default()
    }
    .check()?;
    // The report's other files are named during the run (models, figures): the inputs this
    // registers are also refused when the staged folder is moved into place.
    let html = args.out.join("report.html");
    super::common::refuse_clashes(
        &[
            ("--data", args.data.as_deref()),
            ("--model", args.model.as_deref()),
        ],
        &[("--out report.html", Some(html.as_path()))],
    )?;
    let mut bar = Bar::new();
    let outcome = match &args.data {
        None => demo_report(&args.out, &opts, &mut |p| bar.update(p)),
        Some(path) => {
            let model = match &args.model {
                Some(m) => Some(FittedModel::load(m)?),
                None => None,
            };
            let log = match &model {
                Some(m) => args.columns.read_log_for(path, m)?,
                None => args.columns.read_log(path)?,
            };
            data_report(&args.out, &log, model.as_ref(), &opts, &mut |p| {
                bar.update(p)
            })
        }
    };
    bar.finish();
    outcome.with_context(|| format!("report into {}", args.out.display()))
}

/// Writes the report and prints its path and the headline numbers.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let outcome = story(&args)?;
    print_outcome(&outcome)
}

/// Prints the report's path and the five-line summary.
pub(crate) fn print_outcome(o: &StoryOutcome) -> anyhow::Result<()> {
    outln!("report: {}", o.report.display())?;
    for line in &o.summary {
        outln!("  {line}")?;
    }
    for w in &o.warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}
