//! `biasctl predict`: replay a model over a log or a plan causally and write per-row predictions
//! (and, with `--handoff`, the integrator start value of every seek).

use super::common::{DirectionArgs, LogArgs, SettleArgs};
use crate::SettleSpec;
use crate::write_atomic;
use crate::{FittedModel, StartValues, model::ReplaySummary, model::write_predictions_csv};
use crate::{Log, log::BiasColumn, log::LogReader, log::STDIN_PATH};
use anyhow::Context;
use std::io::Write;
use std::path::{Path, PathBuf};

/// A model file and a log to apply it to (shared by `predict` and `score`).
#[derive(Debug, clap::Args)]
pub(crate) struct ModelLogArgs {
    /// The model file written by `biasctl fit`.
    #[arg(long, value_name = "MODEL.json")]
    pub model: PathBuf,
    #[command(flatten)]
    pub log: LogArgs,
    /// Without these flags the model replays direction as it was fitted (its file records
    /// how); with them, as they say.
    #[command(flatten)]
    pub direction: DirectionArgs,
}

impl ModelLogArgs {
    /// Loads the model (its direction source replaced when `--deadband`/`--velocity-col` is
    /// given).
    pub(crate) fn load_model(&self) -> anyhow::Result<FittedModel> {
        let mut model = FittedModel::load(&self.model)?;
        if let Some(d) = self.direction.setting()?.explicit()? {
            model.direction = d;
        }
        Ok(model)
    }

    /// Loads the model and the log and replays the model causally over the log (streamed:
    /// nothing per row is kept), refusing a non-finite prediction and warning where the log
    /// goes beyond the fitted positions.
    pub(crate) fn replay(&self) -> anyhow::Result<(FittedModel, Log)> {
        let model = self.load_model()?;
        let log = self.log.columns.read_log_for(&self.log.data, &model)?;
        crate::score::check_replay(&model, &log)??;
        let positions = log.measured_positions();
        super::common::warn_outside_range(&model, &log.schema.file, &positions);
        Ok((model, log))
    }
}

/// Flags of `biasctl predict`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    input: ModelLogArgs,
    /// The CSV to write (`-`: standard output): the input columns, `predicted`, `residual`
    /// (empty where the row is not measured), `integrator_start` with --handoff, one column per
    /// term.
    #[arg(long, value_name = "PRED.csv")]
    out: PathBuf,
    /// Add `integrator_start`, the settle-optimal (robust) integrator start value of each seek
    /// for this plant (a preset such as paper1997, or a plant TOML file), from the row's
    /// predicted bias with Δb = the model's error std.
    #[arg(long, value_name = "PRESET|PLANT.toml")]
    handoff: Option<String>,
    /// Δb in counts for --handoff instead of the model's error std (the fit's residual_std).
    #[arg(
        allow_hyphen_values = true,
        long,
        value_name = "DB",
        requires = "handoff"
    )]
    bias_uncertainty: Option<f64>,
}

/// The settle description named by `--handoff`: a file when it ends in `.toml` or exists,
/// else a preset name.
pub(crate) fn handoff_plan(
    model: &FittedModel,
    handoff: &str,
    delta_b: Option<f64>,
) -> anyhow::Result<StartValues> {
    let is_file = handoff.ends_with(".toml") || Path::new(handoff).is_file();
    if !is_file {
        // Named as the flag it came from (`SettleArgs` would call it --preset).
        SettleSpec::preset(handoff).with_context(|| {
            format!(
                "--handoff {}: not a plant file (FILE.toml) and not a preset",
                crate::io::quote(handoff)
            )
        })?;
    }
    let settle = SettleArgs {
        preset: (!is_file).then(|| handoff.to_string()),
        plant: is_file.then(|| PathBuf::from(handoff)),
        ..SettleArgs::default()
    };
    let cfg = settle.spec()?.check()?;
    let delta_b = delta_b.unwrap_or(model.fit.residual_std);
    Ok(StartValues::new(&cfg, delta_b)?)
}

/// Loads the model, streams the log through it and writes the CSV (atomically to a file, or
/// to stdout flushed per row when the input is stdin).
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    super::common::refuse_clashes(
        &[
            ("--model", Some(args.input.model.as_path())),
            ("--data", Some(args.input.log.data.as_path())),
            (
                "--handoff",
                args.handoff
                    .as_deref()
                    .map(Path::new)
                    .filter(|p| p.is_file()),
            ),
        ],
        &[("--out", Some(args.out.as_path()))],
    )?;
    super::common::refuse_missing_folders(&[("--out", Some(args.out.as_path()))])?;
    let model = args.input.load_model()?;
    let start = match &args.handoff {
        Some(h) => Some(handoff_plan(&model, h, args.bias_uncertainty)?),
        None => None,
    };
    let columns = &args.input.log.columns;
    let data = &args.input.log.data;
    let mut reader = LogReader::open_with(data, &columns.map(), BiasColumn::Optional)?;
    let units = columns.units_for_model(reader.schema(), &model)?;
    let file = reader.schema().file.clone();
    let flush_each = data.as_os_str() == STDIN_PATH;
    let mut write = |w: &mut dyn Write| -> anyhow::Result<ReplaySummary> {
        Ok(write_predictions_csv(
            &model,
            &mut reader,
            start
                .as_ref()
                .map(|s| s as &dyn crate::model::IntegratorStart),
            w,
            flush_each,
        )?)
    };
    let summary = if args.out.as_os_str() == STDIN_PATH {
        let stdout = std::io::stdout();
        let mut lock = stdout.lock();
        let s = write(&mut lock)?;
        lock.flush()?;
        s
    } else {
        let mut summary = None;
        write_atomic(&args.out, |w| -> anyhow::Result<()> {
            summary = Some(write(w)?);
            Ok(())
        })?;
        summary.ok_or_else(|| anyhow::anyhow!("no rows written"))?
    };
    if let Some(w) = &summary.outside_range {
        eprintln!("warning: {file}: {w}");
    }
    let text = format!(
        "{file}: {} rows predicted with `{}` ({} scored against a measured bias, {} only predicted; bias in {}, position in {}), wrote {}",
        summary.rows,
        model.spec,
        summary.scored,
        summary.predicted_only,
        units.bias,
        units.position,
        if args.out.as_os_str() == STDIN_PATH {
            "stdout".to_string()
        } else {
            args.out.display().to_string()
        }
    );
    // The summary goes to stderr when the CSV goes to stdout.
    if args.out.as_os_str() == STDIN_PATH {
        eprintln!("{text}");
    } else {
        outln!("{text}")?;
    }
    Ok(())
}
