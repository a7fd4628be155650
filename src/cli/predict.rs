//! `biasctl predict`: replay a model over a log causally and write per-row predictions.

use super::common::LogArgs;
use biasctl::log::{Log, fmt_fixed, fmt_trimmed};
use biasctl::model::{FittedModel, Prediction};
use biasctl::output::write_atomic;
use std::io::Write;
use std::path::PathBuf;

/// A model file and a log to apply it to (shared by `predict` and `score`).
#[derive(Debug, clap::Args)]
pub struct ModelLogArgs {
    /// The model file written by `biasctl fit`.
    #[arg(long, value_name = "MODEL.json")]
    pub model: PathBuf,
    #[command(flatten)]
    pub log: LogArgs,
}

impl ModelLogArgs {
    /// Loads the model and the log and replays the model causally over the log.
    pub fn replay(&self) -> anyhow::Result<(FittedModel, Log, Prediction)> {
        let model = FittedModel::load(&self.model)?;
        let log = self.log.columns.read_log(&self.log.data)?;
        let pred = model.predict_log(&log)?;
        biasctl::render::check_prediction(&pred, &log)?;
        super::common::warn_outside_range(&model, &log.schema.file, &pred.positions);
        Ok((model, log, pred))
    }
}

/// Flags of `biasctl predict`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    input: ModelLogArgs,
    /// The CSV to write: input columns, `predicted`, `residual`, one column per term.
    #[arg(long, value_name = "PRED.csv")]
    out: PathBuf,
}

/// Loads the model and log, replays, writes the CSV atomically.
pub fn run(args: Args) -> anyhow::Result<()> {
    super::common::refuse_clashes(
        &[
            ("--model", Some(args.input.model.as_path())),
            ("--data", Some(args.input.log.data.as_path())),
        ],
        &[("--out", Some(args.out.as_path()))],
    )?;
    let (model, log, pred) = args.input.replay()?;
    let s = &log.schema;
    write_atomic(&args.out, |w| -> std::io::Result<()> {
        write!(w, "{},{},{}", s.map.time, s.map.track, s.map.bias)?;
        for c in &s.covariates {
            write!(w, ",{c}")?;
        }
        write!(w, ",predicted,residual")?;
        for t in &pred.term_names {
            write!(w, ",{t}")?;
        }
        writeln!(w)?;
        for (i, &r) in pred.rows.iter().enumerate() {
            let row = &log.rows[r];
            write!(
                w,
                "{},{},{}",
                fmt_fixed(row.time_s, 6),
                fmt_trimmed(row.track, 6),
                fmt_fixed(pred.measured[i], 4)
            )?;
            for c in &row.covariates {
                write!(w, ",{}", fmt_trimmed(*c, 6))?;
            }
            write!(
                w,
                ",{},{}",
                fmt_fixed(pred.predicted[i], 4),
                fmt_fixed(pred.residual[i], 4)
            )?;
            for c in &pred.contributions {
                write!(w, ",{}", fmt_fixed(c[i], 4))?;
            }
            writeln!(w)?;
        }
        Ok(())
    })?;
    outln!(
        "{}: {} measured rows predicted with `{}` (bias in {}, position in {}), wrote {}",
        s.file,
        pred.rows.len(),
        model.spec,
        s.units.bias,
        s.units.position,
        args.out.display()
    )?;
    Ok(())
}
