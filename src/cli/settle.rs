//! `biasctl settle`: the settle-optimal integrator start value at handoff (paper Section IV).

use super::common::{ColumnArgs, SettleArgs};
use anyhow::Context;
use biasctl::log::{DEFAULT_BIAS_UNIT, Units};
use biasctl::model::{FittedModel, NextPrediction, predict_next};
use biasctl::output::write_string_atomic;
use biasctl::settle::{SettleReport, analyse};
use std::path::PathBuf;

/// Flags of `biasctl settle`.
#[derive(Debug, clap::Args)]
pub struct Args {
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
        allow_negative_numbers = true
    )]
    target: Option<f64>,
    #[command(flatten)]
    columns: ColumnArgs,
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
    let log = args.columns.read_log(data)?;
    let units = log.schema.units.clone();
    // The settle plant is a disk drive's: its input is in DAC counts. A bias in another unit
    // (N, mA) cannot be fed to it without a conversion the tool does not know.
    if units.bias != DEFAULT_BIAS_UNIT {
        anyhow::bail!(
            "settle --model: {} measures bias in `{}`, but the settle plant ({}) is a disk drive \
             driven in `{DEFAULT_BIAS_UNIT}`; the predicted bias cannot be used as a start value. \
             Give --bias-unit {DEFAULT_BIAS_UNIT} if the log's bias is in DAC counts, or leave \
             out --model and give --bias and --bias-uncertainty in counts",
            log.schema.file,
            units.bias,
            args.settle.plant.as_ref().map_or_else(
                || args.settle.preset.clone().unwrap_or("paper1997".into()),
                |p| p.display().to_string()
            )
        );
    }
    let next = predict_next(&model, &log, args.target)
        .with_context(|| format!("predicting the handoff bias from {}", data.display()))?;
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
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut spec = args.settle.spec()?;
    let link = predict_handoff(&args)?;
    if let Some(l) = &link {
        if args.settle.bias.is_none() {
            spec.bias = l.next.bias;
        }
        spec.bias_uncertainty = l.delta_b;
    }
    let cfg = spec.validate()?;
    let report = analyse(&cfg)?;
    if let Some(path) = &args.bounds_out {
        write_string_atomic(path, &report.bounds_csv())?;
    }
    if let Some(path) = &args.response_out {
        write_string_atomic(path, &report.responses_csv())?;
    }
    if args.json {
        let mut value = serde_json::to_value(&report)?;
        if let Some(obj) = value.as_object_mut() {
            let abs = |v: Option<f64>| v.map(|v| report.absolute(v));
            obj.insert(
                "absolute".into(),
                serde_json::json!({
                    "zero_ff": report.absolute(0.0),
                    "ff_midpoint": abs(report.ff_midpoint),
                    "paper_robust": abs(report.paper_robust.as_ref().map(|p| p.ff)),
                    "robust": abs(report.robust.as_ref().map(|c| c.ff)),
                }),
            );
        }
        if let (Some(l), Some(obj)) = (&link, value.as_object_mut()) {
            obj.insert(
                "prediction".into(),
                serde_json::json!({
                    "model": l.model.display().to_string(),
                    "target": l.next.target,
                    "bias": l.next.bias,
                    "delta_b": l.delta_b,
                    "rows_replayed": l.next.rows_replayed,
                    "units": l.units,
                    "robust_worst_settle_ms": report.worst_case.robust_worst_settle_ms,
                    "zero_ff_worst_settle_ms": report.worst_case.zero_ff_worst_settle_ms,
                }),
            );
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        if let Some(l) = &link {
            println!(
                "model {}: predicted bias {:.3} {b} at {} {} (after {} rows), Δb = {:.3} {b}",
                l.model.display(),
                l.next.bias,
                l.next.target,
                l.units.position,
                l.next.rows_replayed,
                l.delta_b,
                b = l.units.bias,
            );
            println!(
                "  worst-case settle for ±Δb: robust choice {}, zero feedforward {}",
                ms(report.worst_case.robust_worst_settle_ms),
                ms(report.worst_case.zero_ff_worst_settle_ms)
            );
        }
        print_text(&report);
    }
    Ok(())
}

fn ms(v: Option<f64>) -> String {
    v.map_or("not settled".to_string(), |m| format!("{m:.2} ms"))
}

fn print_text(r: &SettleReport) {
    let gain: Vec<String> = r.gain.iter().map(|g| format!("{g:.6}")).collect();
    let poles: Vec<String> = r.poles_abs.iter().map(|p| format!("{p:.5}")).collect();
    println!("LQR gain K = [{}]", gain.join(", "));
    println!(
        "  DARE: {} doubling steps, residual {:.1e}",
        r.dare_iterations, r.dare_residual
    );
    println!("closed-loop |poles| = [{}]", poles.join(", "));
    println!("dz/dbias = {:.5} (µm·samples per count)", r.dz_dbias);
    println!(
        "step {} µm, window ±{} µm, horizon {} samples, hold {}; start values (µm·samples) relative to the converged value {:.4}, absolute in brackets",
        r.step_um, r.window_um, r.horizon, r.hold, r.z_converged
    );
    let abs = |v: f64| format!("{v:.4} [{:.4}]", r.absolute(v));
    println!(
        "zero feedforward: {} (overshoot {:.1} %), start value {}",
        r.zero_ff_settle_ms
            .map_or("does not settle within the horizon".to_string(), |m| {
                format!("settles in {m:.2} ms")
            }),
        r.zero_ff_overshoot_pct,
        abs(0.0)
    );
    match (r.k_star, r.ff_interval) {
        (Some(k), Some([lo, hi])) => println!(
            "optimal: k* = {k}, {} for start values in [{lo:.4}, {hi:.4}] (choice {})",
            ms(r.optimal_settle_ms),
            r.ff_midpoint.map_or("none".to_string(), abs)
        ),
        _ => println!("optimal: no start value settles within the horizon"),
    }
    match &r.paper_robust {
        Some(p) => println!(
            "paper's robust choice: {} (first local minimum of the upper bound at k = {}): {}",
            abs(p.ff),
            p.k_min,
            ms(p.settle_ms)
        ),
        None => println!("paper's robust choice: the upper bound has no local minimum"),
    }
    let w = &r.worst_case;
    match &r.robust {
        Some(c) => println!(
            "robust for ±{:.3} counts (shift ±{:.4}): {}, worst case {} (simulated {}); zero feedforward worst case {}",
            w.delta_b,
            w.shift,
            abs(c.ff),
            ms(Some(c.worst_settle_ms)),
            ms(c.simulated_worst_settle_ms),
            ms(w.zero_ff_worst_settle_ms)
        ),
        None => println!(
            "robust for ±{:.3} counts: no start value settles for every bias within the horizon",
            w.delta_b
        ),
    }
}
