//! `biasctl plot KIND`: one figure as an SVG file, from your own log (and model) or from a
//! settle analysis.

use super::common::{ColumnArgs, SettleArgs};
use crate::Log;
use crate::analyse;
use crate::io::write_string_atomic;
use crate::{
    DiagnoseConfig, diagnose::FeatureTable, diagnose::diagnose_residual, diagnose::replay_model,
    ladder_fit, ladder_terms,
};
use crate::{FitOptions, fit};
use crate::{FittedModel, ModelSpec};
use crate::{plot::from_log, plot::views};
use anyhow::{Context, bail};
use clap::ValueEnum;
use std::path::{Path, PathBuf};

/// Which figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Kind {
    /// Fig. 3: bias vs position, inbound and outbound; with --model the model's curves.
    Position,
    /// Fig. 4: bias vs time at one track (--track, default the most measured track).
    Time,
    /// Figs. 5–9/12 view: bias vs signed seek length, split by direction change at the source.
    Seek,
    /// Figs. 10/11: prediction error vs position and its histogram, --model M1,M2,... side by side.
    Errors,
    /// Figs. 13/14: measured bias vs position in seek order with the --model prediction as a loop.
    Loop,
    /// The --model residual vs each of the top candidate features (diagnose).
    Diagnose,
    /// Test error std after each added term: fit on --data, score on --test, terms from --terms.
    Ladder,
    /// Fig. 15: bounds on the integrator start value (settle flags, no log).
    Bounds,
    /// Fig. 16: position error after handoff for each start value (settle flags, no log).
    Responses,
}

/// Flags of `biasctl plot`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The figure to draw.
    #[arg(value_enum)]
    kind: Kind,
    /// The SVG file to write.
    #[arg(long, value_name = "FILE.svg")]
    out: PathBuf,
    /// The measurement log (every kind but bounds and responses).
    #[arg(long, value_name = "LOG.csv")]
    data: Option<PathBuf>,
    #[command(flatten)]
    columns: ColumnArgs,
    /// A model: a model file from `biasctl fit`, or a preset / term list fitted on --data.
    /// `errors` takes several, comma-separated (a term list then needs its own file).
    #[arg(long, value_name = "MODEL")]
    model: Option<String>,
    /// The track of the `time` plot.
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    track: Option<f64>,
    /// The test log of the `ladder` plot.
    #[arg(long, value_name = "TEST.csv")]
    test: Option<PathBuf>,
    /// The ladder's terms, added one at a time.
    #[arg(
        long,
        value_name = "T1,T2,...",
        default_value = crate::model::CALIBRATION
    )]
    terms: String,
    /// Top features of the `diagnose` plot.
    #[arg(allow_negative_numbers = true, long, default_value_t = crate::plot::views::DEFAULT_TOP, value_name = "N")]
    top: usize,
    #[command(flatten)]
    settle: SettleArgs,
}

fn is_settle(kind: Kind) -> bool {
    matches!(kind, Kind::Bounds | Kind::Responses)
}

/// Flags that only some kinds accept: a clear error instead of silently ignoring them.
fn check_flags(a: &Args) -> anyhow::Result<()> {
    let k = format!("{:?}", a.kind).to_lowercase();
    let settle_flag = a.settle.any();
    if is_settle(a.kind) {
        if a.data.is_some() || a.model.is_some() || a.test.is_some() {
            bail!(
                "plot {k} takes settle flags (--preset, --plant, --step-um, --window-um, --bias, --bias-uncertainty, --horizon, --hold), not --data/--model/--test"
            );
        }
        return Ok(());
    }
    if settle_flag {
        bail!(
            "plot {k}: the settle flags (--preset, --plant, --step-um, --window-um, --bias, --bias-uncertainty, --horizon, --hold) are for `plot bounds` and `plot responses`"
        );
    }
    if a.data.is_none() {
        bail!("plot {k} needs --data LOG.csv");
    }
    if a.track.is_some() && a.kind != Kind::Time {
        bail!("plot {k}: --track is for `plot time`");
    }
    match (a.kind == Kind::Ladder, a.test.is_some()) {
        (true, false) => bail!("plot ladder needs --test TEST.csv"),
        (false, true) => bail!("plot {k}: --test is for `plot ladder`"),
        _ => {}
    }
    match a.kind {
        Kind::Errors | Kind::Loop | Kind::Diagnose if a.model.is_none() => {
            bail!("plot {k} needs --model MODEL (a model file or a preset)")
        }
        Kind::Time | Kind::Seek | Kind::Ladder if a.model.is_some() => {
            bail!("plot {k} does not take --model")
        }
        _ => {}
    }
    if a.kind != Kind::Errors
        && a.model
            .as_deref()
            .is_some_and(|m| m.contains(',') && Path::new(m).extension().is_some())
    {
        bail!("plot {k} takes one --model");
    }
    Ok(())
}

/// A model file, or a preset / term list fitted on `log`.
fn model(name: &str, log: &Log) -> anyhow::Result<(String, FittedModel)> {
    let path = Path::new(name);
    if path.exists() || name.ends_with(".json") {
        let m = FittedModel::load(path)?;
        let label = path
            .file_stem()
            .map_or(name.to_string(), |s| s.to_string_lossy().into_owned());
        return Ok((label, m));
    }
    let spec = ModelSpec::preset(name)
        .or_else(|_| ModelSpec::parse(name))
        .with_context(|| format!("--model {name}: not a model file, a preset or a term list"))?;
    let m = fit(&spec, log, &FitOptions::default().check()?)
        .with_context(|| format!("fitting --model {name} on {}", log.schema.file))?;
    Ok((name.to_string(), m))
}

/// The SVG text of the figure.
fn draw(a: &Args) -> anyhow::Result<String> {
    let panel = views::PanelOptions { top: a.top }.check()?;
    if is_settle(a.kind) {
        let report = analyse(&a.settle.spec()?.check()?)?;
        return Ok(match a.kind {
            Kind::Bounds => views::settle_bounds(&report),
            _ => views::settle_responses(&report),
        });
    }
    let data = a.data.as_ref().context("--data")?;
    let mut log = a.columns.read_log(data)?;
    // Model files: the log in the units they were fitted in (a flag that names others is
    // refused).
    for name in a.model.iter().flat_map(|m| m.split(',')) {
        let path = Path::new(name.trim());
        if path.is_file() {
            let m = FittedModel::load(path)?;
            log.schema.units = a.columns.units_for_model(&log.schema, &m)?;
        }
    }
    let log = log;
    let units = &log.schema.units;
    let single = || -> anyhow::Result<FittedModel> {
        model(a.model.as_deref().unwrap_or_default(), &log).map(|m| m.1)
    };
    Ok(match a.kind {
        Kind::Position => match &a.model {
            Some(name) => views::position(&log, Some(&model(name, &log)?.1))?,
            None => from_log::bias_vs_position(&log),
        },
        Kind::Time => {
            if let Some(t) = a.track {
                from_log::check_track(&log, t).context("--track")?;
            }
            from_log::bias_vs_time(&log, a.track)
        }
        Kind::Seek => from_log::bias_vs_seek_length(&log),
        Kind::Errors => {
            let mut preds = Vec::new();
            for name in a.model.as_deref().unwrap_or_default().split(',') {
                let (label, m) = model(name.trim(), &log)?;
                preds.push((label, m.predict_log(&log)?));
            }
            let refs: Vec<(&str, _)> = preds.iter().map(|(l, p)| (l.as_str(), p)).collect();
            views::errors(&refs, units)
        }
        Kind::Loop => {
            let (label, m) = model(a.model.as_deref().unwrap_or_default(), &log)?;
            views::dahl_loop(&m.predict_log(&log)?, units, &label)
        }
        Kind::Diagnose => {
            let m = single()?;
            let residual = replay_model(&m, &log)?.residual;
            let table = FeatureTable::from_log(&log);
            let d = diagnose_residual(&m, &table, &residual, &DiagnoseConfig::default().check()?)?;
            views::diagnose_panel(&d, &table, &residual, &panel)
        }
        Kind::Ladder => {
            let test_path = a.test.as_ref().context("--test")?;
            let test = a.columns.read_log(test_path)?;
            let terms = ladder_terms(&a.terms)?;
            let l = ladder_fit(&log, &test, &terms, &FitOptions::default().check()?)?;
            views::ladder(&l, &test.schema.units)
        }
        Kind::Bounds | Kind::Responses => bail!("plot bounds/responses take no log"),
    })
}

/// Validates the flags, draws the figure, writes it atomically.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let model_file = args.model.as_deref().map(Path::new).filter(|p| p.is_file());
    super::common::refuse_clashes(
        &[
            ("--data", args.data.as_deref()),
            ("--test", args.test.as_deref()),
            ("--model", model_file),
            ("--plant", args.settle.plant.as_deref()),
        ],
        &[("--out", Some(args.out.as_path()))],
    )?;
    super::common::refuse_missing_folders(&[("--out", Some(args.out.as_path()))])?;
    check_flags(&args)?;
    let svg = draw(&args)?;
    // The last guard before the file: no `NaN`/`inf` coordinate leaves (exit 2, nothing written).
    crate::io::check_text(&svg, &args.out.display().to_string())?;
    write_string_atomic(&args.out, &svg)?;
    outln!("wrote {}", args.out.display())?;
    Ok(())
}
