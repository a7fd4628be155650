//! `biasctl score`: error statistics of a model on a log.

use super::predict::ModelLogArgs;
use crate::model::Feedback;
use crate::score_model;

/// Flags of `biasctl score`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    input: ModelLogArgs,
    /// Print JSON (keys n, mean, std, rms, median_abs, percentiles, histogram, bimodality, dip
    /// {statistic, p_value, modal_interval, n}, bimodal (the dip test's p < 0.05), trend, units
    /// {bias, position}: the one-step figure; plus figure, free_run (the same keys; left out
    /// without an adaptive term), free_run_feedback and warnings).
    #[arg(long)]
    json: bool,
    /// In the free-run figure of a model with an adaptive term (`drift`), show it the measured
    /// bias every N measured rows (0: never, the default).
    #[arg(
        allow_negative_numbers = true,
        long,
        value_name = "N",
        default_value_t = 0
    )]
    feedback_every: u64,
}

/// Replays the model and prints the score.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let (model, log) = args.input.replay()?;
    let s = score_model(&model, &log, Feedback::every(args.feedback_every))?;
    // The score's own warnings name the scored log; the model's fit warnings (which `score`
    // repeats in its JSON as `fit: …`) come from the training log: named as the model's, and
    // grouped (a `play:32` gives one per weight).
    let fit_warnings: Vec<String> = model.warnings.iter().map(|w| format!("fit: {w}")).collect();
    for w in s.warnings.iter().filter(|w| !fit_warnings.contains(w)) {
        eprintln!("warning: {}: {w}", log.schema.file);
    }
    for w in crate::score::grouped_warnings(&model.warnings) {
        eprintln!(
            "warning: model {} (from its fit on the training log): {w}",
            args.input.model.display()
        );
    }
    if args.json {
        outln!("{}", crate::io::to_string_pretty(&s)?)?;
    } else {
        outln!("{}: model `{}`", log.schema.file, model.spec)?;
        if let (Some(f), Some(label)) = (&s.free_run, &s.free_run_feedback) {
            let u = &f.units.bias;
            outln!(
                "{label} (from the positions; adaptive terms see no measured bias or only as stated): mean {:.4} {u}, std {:.4} {u}, rms {:.4} {u}",
                f.mean,
                f.std,
                f.rms
            )?;
            outln!(
                "one-step (adaptive terms see every earlier measured bias), the statistics below:"
            )?;
        }
        out!("{}", s.one_step.to_text())?;
    }
    Ok(())
}
