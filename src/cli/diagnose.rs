//! `biasctl diagnose`: compare a fitted model with a log and name the missing effect.

use super::predict::ModelLogArgs;
use crate::FitOptions;
use crate::write_atomic;
use crate::{
    DiagnoseConfig, VerifyConfig, diagnose_model, diagnose_verified, select::PathStep,
    select::suggestion_path_from,
};
use std::io::Write;
use std::path::PathBuf;

/// Flags of `biasctl diagnose`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    input: ModelLogArgs,
    /// Print the diagnosis as JSON (keys residual_std, features, whiteness, bimodality, dip,
    /// summary, units).
    #[arg(long)]
    json: bool,
    /// Also write `diagnosis.json` and one `residual_vs_<feature>.csv` per top feature here.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Family-wise significance level for flagging a feature, in (0, 0.5].
    #[arg(allow_hyphen_values = true, long, default_value_t = 0.01)]
    alpha: f64,
    /// Permutations of the significance test (at least 1/alpha − 1).
    #[arg(allow_negative_numbers = true, long, default_value_t = 199)]
    permutations: usize,
    /// Seed of the fold assignment and the permutations.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    seed: u64,
    /// Cross-validation folds, 2..=50.
    #[arg(allow_negative_numbers = true, long, default_value_t = 5)]
    folds: usize,
    /// Follow the advice N times: add the top feature's suggested term, refit on --data,
    /// diagnose again; prints the path (and adds a `path` key to the JSON).
    #[arg(
        allow_negative_numbers = true,
        long,
        value_name = "N",
        default_value_t = 0
    )]
    path: usize,
    /// Skip the verification refits (the leading suggestions applied, refitted on --data and
    /// scored on held-out folds of consecutive seeks).
    #[arg(long)]
    no_verify: bool,
    /// Folds of consecutive seeks of the verification refits, 2..=20.
    #[arg(allow_negative_numbers = true, long, default_value_t = 3)]
    verify_folds: usize,
}

/// Validates the settings, replays the model, diagnoses, prints and writes.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let config = DiagnoseConfig {
        alpha: args.alpha,
        permutations: args.permutations,
        seed: args.seed,
        folds: args.folds,
        ..DiagnoseConfig::default()
    }
    .check()?;
    let model = args.input.load_model()?;
    // Re-fits read direction the way the model does.
    let fit_opts = FitOptions {
        direction: model.direction.setting(),
        ..FitOptions::default()
    }
    .check()?;
    let verify = VerifyConfig {
        folds: args.verify_folds,
        fit: fit_opts.clone(),
        ..VerifyConfig::default()
    }
    .check()?;
    let json_out = args.out.as_ref().map(|d| d.join("diagnosis.json"));
    // The feature CSVs' names are known only after the run: the inputs registered here are
    // also refused when the staged folder is moved into place.
    super::common::refuse_clashes(
        &[
            ("--model", Some(&args.input.model)),
            ("--data", Some(&args.input.log.data)),
        ],
        &[("--out diagnosis.json", json_out.as_deref())],
    )?;
    // The output folder is staged before the work, so that a path that cannot be written
    // fails at once (it failed after the whole diagnosis, naming only the staging folder).
    let staged = match &args.out {
        Some(dir) => Some(super::common::stage_out(dir)?),
        None => None,
    };
    let log = args
        .input
        .log
        .columns
        .read_log_for(&args.input.log.data, &model)?;
    super::common::warn_outside_range(&model, &log.schema.file, &log.measured_positions());
    let d = if args.no_verify {
        diagnose_model(&model, &log, &config)?
    } else {
        diagnose_verified(&model, &log, &config, &verify)?
    };
    let path = if args.path > 0 {
        let first = d.clone();
        suggestion_path_from(&model, &log, first, &config, args.path, &fit_opts)?
    } else {
        Vec::new()
    };
    if let Some(staged) = staged {
        // Built in a staging folder beside `--out` and moved in whole: no partial output.
        let json = d.to_json()?;
        write_atomic(&staged.path("diagnosis.json"), |w| writeln!(w, "{json}"))?;
        d.write_feature_csvs(&staged.path(""))?;
        staged.commit()?;
    }
    if args.json {
        if args.path > 0 {
            /// The diagnosis with its `path` key, checked by the one JSON writer.
            #[derive(serde::Serialize)]
            struct WithPath<'a, D, P> {
                #[serde(flatten)]
                diagnosis: &'a D,
                path: &'a P,
            }
            let v = WithPath {
                diagnosis: &d,
                path: &path,
            };
            outln!("{}", crate::io::to_string_pretty(&v)?)?;
        } else {
            outln!("{}", d.to_json()?)?;
        }
    } else {
        outln!(
            "{}: model `{}`, {} measured rows",
            log.schema.file,
            model.spec,
            log.measured_count()
        )?;
        out!("{}", d.to_text())?;
        if args.path > 0 {
            print_path(&path, args.path, &log.schema.units.bias)?;
        }
        if let Some(dir) = &args.out {
            outln!("wrote {}", dir.display())?;
        }
    }
    Ok(())
}

fn print_path(path: &[PathStep], asked: usize, unit: &str) -> anyhow::Result<()> {
    outln!("\nFollowing the advice (refit on this log after each step):")?;
    for (i, p) in path.iter().enumerate() {
        outln!(
            "  {}. `{}` ({:.1} % explained) → add `{}`: residual std {:.4} → {:.4} {unit}",
            i + 1,
            p.feature,
            100.0 * p.explained,
            p.term,
            p.std_before,
            p.std_after
        )?;
    }
    if path.len() < asked {
        outln!(
            "  (stopped after {} step(s): nothing flagged with a term left to add)",
            path.len()
        )?;
    }
    Ok(())
}
