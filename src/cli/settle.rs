//! `biasctl settle`: the settle-optimal integrator start value at handoff (paper Section IV).

use super::common::{ColumnArgs, SettleArgs};
use crate::analyse;
use crate::io::write_string_atomic;
use crate::{FittedModel, model::NextPrediction, model::predict_next};
use crate::{Units, log::DEFAULT_BIAS_UNIT};
use anyhow::Context;
use std::path::PathBuf;

/// Flags of `biasctl settle`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    settle: SettleArgs,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// Write the bounds (Fig. 15) as CSV: k, time_s, upper, lower, upper_min, lower_max.
    #[arg(long, value_name = "FILE.csv")]
    bounds_out: Option<PathBuf>,
    /// Write the responses (Fig. 16) as CSV: k, time_s, one e column (µm) per start-value choice.
    #[arg(long, value_name = "FILE.csv")]
    response_out: Option<PathBuf>,
    /// A fitted bias model: the bias is the model's prediction for the log's last target and
    /// Δb its error std (the fit's residual std) unless --bias / --bias-uncertainty are given.
    #[arg(long, value_name = "MODEL.json", requires = "data")]
    model: Option<PathBuf>,
    /// The measurement log the model is replayed over (with --model).
    #[arg(long, value_name = "LOG.csv", requires = "model")]
    data: Option<PathBuf>,
    /// Predict for a seek to this track after the log's last row instead of the last row's own
    /// target (with --model).
    #[arg(
        long,
        value_name = "TRACK",
        requires = "model",
        allow_hyphen_values = true
    )]
    target: Option<f64>,
    #[command(flatten)]
    columns: ColumnArgs,
}

/// `prediction` of `settle --model --data --json`: the handoff bias the model predicts.
#[derive(serde::Serialize)]
struct PredictionJson<'a> {
    model: String,
    target: f64,
    bias: f64,
    delta_b: f64,
    rows_replayed: usize,
    units: &'a Units,
    robust_worst_settle_ms: Option<f64>,
    zero_ff_worst_settle_ms: Option<f64>,
}

/// The bias a model predicts at handoff, and the uncertainty used for it.
struct ModelLink {
    model: PathBuf,
    next: NextPrediction,
    delta_b: f64,
    units: Units,
}

/// Replays the log through the model and predicts the handoff bias; Δb is the model's error std.
fn predict_handoff(args: &Args) -> anyhow::Result<Option<ModelLink>> {
    let (Some(model_path), Some(data)) = (&args.model, &args.data) else {
        return Ok(None);
    };
    let model = FittedModel::load(model_path)?;
    let log = args.columns.read_log_for(data, &model)?;
    let units = log.schema.units.clone();
    // The settle plant is a disk drive's: its input is in DAC counts. A bias in another unit
    // (N, mA) cannot be fed to it without a conversion the tool does not know.
    if units.bias != DEFAULT_BIAS_UNIT {
        anyhow::bail!(
            "{} measures bias in `{}`; the plant ({}) is a disk drive driven in \
             `{DEFAULT_BIAS_UNIT}`: use --bias-unit {DEFAULT_BIAS_UNIT} if the bias is in DAC \
             counts, else --bias and --bias-uncertainty",
            log.schema.file,
            units.bias,
            args.settle.plant.as_ref().map_or_else(
                || args.settle.preset.clone().unwrap_or("paper1997".into()),
                |p| p.display().to_string()
            )
        );
    }
    // `predict_next` refuses a target that is no position (ModelError::BadTarget): named here.
    let next = predict_next(&model, &log, args.target).with_context(|| match args.target {
        Some(t) => format!(
            "predicting the handoff bias at --target {t} from {}",
            data.display()
        ),
        None => format!("predicting the handoff bias from {}", data.display()),
    })?;
    super::common::warn_outside_range(&model, &log.schema.file, &[next.target]);
    let delta_b = args
        .settle
        .bias_uncertainty
        .unwrap_or(model.fit.residual_std);
    Ok(Some(ModelLink {
        model: model_path.clone(),
        next,
        delta_b,
        units,
    }))
}

/// Validates, designs, analyses; writes the CSVs (atomically) and prints the report.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    super::common::refuse_clashes(
        &[
            ("--plant", args.settle.plant.as_deref()),
            ("--model", args.model.as_deref()),
            ("--data", args.data.as_deref()),
        ],
        &[
            ("--bounds-out", args.bounds_out.as_deref()),
            ("--response-out", args.response_out.as_deref()),
        ],
    )?;
    super::common::refuse_missing_folders(&[
        ("--bounds-out", args.bounds_out.as_deref()),
        ("--response-out", args.response_out.as_deref()),
    ])?;
    let mut spec = args.settle.spec()?;
    let link = predict_handoff(&args)?;
    if let Some(l) = &link {
        if args.settle.bias.is_none() {
            spec.bias = l.next.bias;
        }
        spec.bias_uncertainty = l.delta_b;
    }
    let cfg = spec.check()?;
    let report = analyse(&cfg)?;
    if let Some(path) = &args.bounds_out {
        write_string_atomic(path, &report.bounds_csv())?;
    }
    if let Some(path) = &args.response_out {
        write_string_atomic(path, &report.responses_csv())?;
    }
    if args.json {
        let prediction = link.as_ref().map(|l| PredictionJson {
            model: l.model.display().to_string(),
            target: l.next.target,
            bias: l.next.bias,
            delta_b: l.delta_b,
            rows_replayed: l.next.rows_replayed,
            units: &l.units,
            robust_worst_settle_ms: report.worst_case.robust_worst_settle_ms,
            zero_ff_worst_settle_ms: report.worst_case.zero_ff_worst_settle_ms,
        });
        outln!("{}", report.to_json_with(prediction.as_ref())?)?;
    } else {
        if let Some(l) = &link {
            outln!(
                "model {}: predicted bias {:.3} {b} at {} {} (after {} rows), Δb = {:.3} {b}",
                l.model.display(),
                l.next.bias,
                l.next.target,
                l.units.position,
                l.next.rows_replayed,
                l.delta_b,
                b = l.units.bias,
            )?;
            outln!(
                "  worst-case settle for ±Δb: robust choice {}, zero feedforward {}",
                ms(report.worst_case.robust_worst_settle_ms),
                ms(report.worst_case.zero_ff_worst_settle_ms)
            )?;
        }
        out!("{}", report.to_text())?;
    }
    Ok(())
}

fn ms(v: Option<f64>) -> String {
    v.map_or("not settled".to_string(), |m| format!("{m:.2} ms"))
}
