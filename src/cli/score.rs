//! `biasctl score`: error statistics of a model on a log.

use super::predict::ModelLogArgs;
use biasctl::score::score_with_units;

/// Flags of `biasctl score`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    input: ModelLogArgs,
    /// Print JSON (keys n, mean, std, rms, median_abs, percentiles, histogram, bimodality, dip
    /// {statistic, p_value, modal_interval, n}, bimodal (the dip test's p < 0.05), trend, units
    /// {bias, position}).
    #[arg(long)]
    json: bool,
}

/// Replays the model and prints the score.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (model, log, pred) = args.input.replay()?;
    let s = score_with_units(&pred.residual, &pred.positions, &log.schema.units)?;
    if args.json {
        outln!("{}", biasctl::render::json::to_string_pretty(&s)?)?;
    } else {
        outln!("{}: model `{}`", log.schema.file, model.spec)?;
        out!("{}", s.to_text())?;
    }
    Ok(())
}
