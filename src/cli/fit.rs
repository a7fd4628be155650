//! `biasctl fit`: fit a model (a preset or a term list) to a log and write the model file.

use super::common::{DirectionArgs, LogArgs};
use crate::ModelSpec;
use crate::fit;
use anyhow::Context;
use std::path::PathBuf;

/// Flags of `biasctl fit`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    log: LogArgs,
    #[command(flatten)]
    direction: DirectionArgs,
    /// A preset: position-direction, calibration or dahl.
    #[arg(long, value_name = "PRESET", conflicts_with = "terms")]
    model: Option<String>,
    /// A comma-separated term list, e.g. `poly2,dahl:4,col:temp_c` or
    /// `poly2,direction,seek,memory,drift,dbins:dwell_s` (`--help` lists every built-in term).
    #[arg(long, value_name = "T1,T2,...", long_help = terms_help())]
    terms: Option<String>,
    /// The model file to write (JSON).
    #[arg(long, value_name = "MODEL.json")]
    out: PathBuf,
}

/// `--terms`'s long help: the example and every built-in term's syntax, from the registry (so
/// a new term is listed without editing this text).
fn terms_help() -> String {
    format!(
        "A comma-separated term list, e.g. `poly2,dahl:4,col:temp_c` or \
         `poly2,direction,seek,memory,drift,dbins:dwell_s`. Terms: {}",
        crate::model::builtin_names()
    )
}

/// Validates the spec, reads the log, fits, prints the parameters and writes the model.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    super::common::refuse_clashes(
        &[("--data", Some(args.log.data.as_path()))],
        &[("--out", Some(args.out.as_path()))],
    )?;
    super::common::refuse_missing_folders(&[("--out", Some(args.out.as_path()))])?;
    let spec = match (&args.model, &args.terms) {
        (Some(p), None) => match ModelSpec::preset(p) {
            Ok(spec) => spec,
            // A term list given as a preset (as `plot --model` and `discover --start` take
            // one): say where it goes.
            Err(e) if p.contains(',') || ModelSpec::parse(p).is_ok() => {
                return Err(anyhow::anyhow!(e).context(format!(
                    "--model {}: `fit --model` takes a preset; a term list goes in --terms: \
                     `--terms {}`",
                    crate::io::quote(p),
                    crate::io::quote(p)
                )));
            }
            Err(e) => return Err(anyhow::anyhow!(e).context("--model")),
        },
        (None, Some(t)) => ModelSpec::parse(t).context("--terms")?,
        _ => anyhow::bail!("give a model: --model PRESET or --terms T1,T2,..."),
    };
    let opts = args.direction.fit_options()?;
    let log = args.log.columns.read_log(&args.log.data)?;
    let model = fit(&spec, &log, &opts)?;
    model.save(&args.out)?;
    let f = &model.fit;
    outln!(
        "{}: model `{}`, {} measured rows, {} parameters, residual std {:.4} {}, R² {:.4}",
        log.schema.file,
        model.spec,
        f.rows_used,
        f.parameters,
        f.residual_std,
        log.schema.units.bias,
        f.r2
    )?;
    for p in model.params() {
        match p.se {
            Some(se) => outln!("  {:<32} {:>14.6e} ± {:.3e}", p.name, p.value, se)?,
            None => outln!("  {:<32} {:>14.6e}", p.name, p.value)?,
        }
    }
    for w in &model.warnings {
        eprintln!("warning: {w}");
    }
    outln!("wrote {}", args.out.display())?;
    Ok(())
}
