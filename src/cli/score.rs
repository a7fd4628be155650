//! `biasctl score`: error statistics of a model on a log.

use super::common::LogArgs;
use biasctl::log::Log;
use biasctl::model::FittedModel;
use biasctl::score::score;
use std::path::PathBuf;

/// Flags of `biasctl score`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file written by `biasctl fit`.
    #[arg(long, value_name = "MODEL.json")]
    model: PathBuf,
    #[command(flatten)]
    log: LogArgs,
    /// Print JSON (keys n, mean, std, rms, median_abs, percentiles, histogram, bimodality, bimodal, trend).
    #[arg(long)]
    json: bool,
}

/// Replays the model and prints the score.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = FittedModel::load(&args.model)?;
    let log = Log::read(&args.log.data, &args.log.columns.map())?;
    let pred = model.predict_log(&log)?;
    let s = score(&pred.residual, &pred.positions)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        println!("{}: model `{}`", log.schema.file, model.spec);
        print!("{}", s.to_text());
    }
    Ok(())
}
