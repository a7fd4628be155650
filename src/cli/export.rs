//! `biasctl export c`: a fitted model as C99 source for the drive's firmware.

use super::predict::handoff_plan;
use crate::FittedModel;
use crate::{COptions, c_source, export::C_FILES, export::CHandoff, export::CPrecision};
use anyhow::Context;
use std::path::PathBuf;

/// Flags of `biasctl export`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(subcommand)]
    target: Target,
}

#[derive(Debug, clap::Subcommand)]
enum Target {
    /// C99: DIR/bias_model.h, DIR/bias_model.c (state struct, init, step, peek; no allocation,
    /// no globals) and DIR/replay.c; build with `cc -std=c99 -O2 DIR/*.c -lm`.
    C(CArgs),
}

/// Flags of `biasctl export c`.
#[derive(Debug, clap::Args)]
struct CArgs {
    /// The model file written by `biasctl fit`.
    #[arg(long, value_name = "MODEL.json")]
    model: PathBuf,
    /// The folder to write the C files into (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Single precision (`float`) for targets without double precision.
    #[arg(long)]
    float32: bool,
    /// Also export the handoff table of this plant (a preset such as paper1997, or a plant
    /// TOML file) and `bias_model_integrator_start`.
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

/// Loads the model, generates the C files and writes them.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let Target::C(a) = args.target;
    let handoff_file = a.handoff.as_deref().map(std::path::Path::new);
    let outs: Vec<(String, PathBuf)> = C_FILES
        .iter()
        .map(|f| (format!("--out {f}"), a.out.join(f)))
        .collect();
    super::common::refuse_clashes(
        &[
            ("--model", Some(a.model.as_path())),
            ("--handoff", handoff_file.filter(|p| p.is_file())),
        ],
        &outs
            .iter()
            .map(|(f, p)| (f.as_str(), Some(p.as_path())))
            .collect::<Vec<_>>(),
    )?;
    let model = FittedModel::load(&a.model)?;
    let start = match &a.handoff {
        Some(h) => Some(handoff_plan(&model, h, a.bias_uncertainty)?),
        None => None,
    };
    let opts = COptions {
        precision: if a.float32 {
            CPrecision::Float32
        } else {
            CPrecision::Float64
        },
        handoff: start.as_ref().map(|s| CHandoff { start: s }),
    };
    let src = c_source(&model, &opts)?;
    src.write(&a.out)
        .with_context(|| format!("--out {}", crate::io::quote(&a.out.display().to_string())))?;
    outln!(
        "exported `{}` ({}) to {}: bias_model.h, bias_model.c, replay.c; build with cc -std=c99 -O2 {}/*.c -lm",
        model.spec,
        if a.float32 { "float" } else { "double" },
        a.out.display(),
        a.out.display()
    )?;
    Ok(())
}
