//! `biasctl predict`: replay a model over a log causally and write per-row predictions.

use super::common::LogArgs;
use biasctl::log::{Log, fmt_fixed, fmt_trimmed};
use biasctl::model::{FittedModel, Prediction};
use biasctl::output::write_atomic;
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
    let (model, log, pred) = args.input.replay()?;
    let s = &log.schema;
    write_atomic(&args.out, |w| -> std::io::Result<()> {
        let mut w = biasctl::log::csv_writer(w);
        let names = [&s.map.time, &s.map.track, &s.map.bias]
            .into_iter()
            .chain(&s.covariates)
            .map(String::as_str)
            .chain(["predicted", "residual"])
            .chain(pred.term_names.iter().map(String::as_str));
        w.write_record(names)?;
        for (i, &r) in pred.rows.iter().enumerate() {
            let row = &log.rows[r];
            w.write_field(fmt_fixed(row.time_s, 6))?;
            w.write_field(fmt_trimmed(row.track, 6))?;
            w.write_field(fmt_fixed(pred.measured[i], 4))?;
            for c in &row.covariates {
                w.write_field(fmt_trimmed(*c, 6))?;
            }
            w.write_field(fmt_fixed(pred.predicted[i], 4))?;
            w.write_field(fmt_fixed(pred.residual[i], 4))?;
            for c in &pred.contributions {
                w.write_field(fmt_fixed(c[i], 4))?;
            }
            w.write_record(None::<&[u8]>)?;
        }
        w.flush()
    })?;
    println!(
        "{}: {} measured rows predicted with `{}` (bias in {}, position in {}), wrote {}",
        s.file,
        pred.rows.len(),
        model.spec,
        s.units.bias,
        s.units.position,
        args.out.display()
    );
    Ok(())
}
