//! `biasctl discover`: fit, diagnose, apply the best verified edit, repeat.

use super::common::ColumnArgs;
use crate::write_atomic;
use crate::{DiagnoseConfig, DiscoverConfig, VerifyConfig, diagnose::model_spec, discover};
use crate::{FittedModel, ModelSpec};
use anyhow::Context;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Flags of `biasctl discover`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The training log: every model is fitted, diagnosed and verified on it.
    #[arg(long, value_name = "TRAIN.csv")]
    data: PathBuf,
    /// A test log: every rung's error std is measured on it (else on held-out folds of --data).
    #[arg(long, value_name = "TEST.csv")]
    test: Option<PathBuf>,
    /// Where to start: a preset (position-direction, calibration, dahl), a model file (its
    /// terms), or a term list such as `poly2,direction`.
    #[arg(long, value_name = "MODEL|TERMS", default_value = crate::model::terms::poly::HEAD)]
    start: String,
    #[command(flatten)]
    columns: ColumnArgs,
    /// Print the ladder as JSON: {"steps": [{"edit", "feature", "reason", "std_before",
    /// "std_after", "terms"}, ...], "final_terms", "stopped_because", "reason", "basis", "unit",
    /// "start_std"}.
    #[arg(long)]
    json: bool,
    /// Write discover.json, discover.txt and the final model.json into this directory.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Most edits applied, 1..=30.
    #[arg(allow_negative_numbers = true, long, default_value_t = 8)]
    max_steps: usize,
    /// Family-wise significance level for flagging a feature, in (0, 0.5].
    #[arg(allow_hyphen_values = true, long, default_value_t = 0.01)]
    alpha: f64,
    /// Seed of the folds and permutations.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    seed: u64,
    /// Folds of consecutive seeks of the verification refits, 2..=20.
    #[arg(allow_negative_numbers = true, long, default_value_t = 3)]
    verify_folds: usize,
}

/// The files `discover --out DIR` writes into DIR.
const DISCOVER_FILES: [&str; 3] = ["discover.json", "discover.txt", "model.json"];

/// The starting spec: a preset, a model file's terms, or a term list.
fn start_spec(start: &str) -> anyhow::Result<ModelSpec> {
    if let Ok(s) = ModelSpec::preset(start) {
        return Ok(s);
    }
    if start.ends_with(".json") || Path::new(start).is_file() {
        let m = FittedModel::load(Path::new(start)).context("--start")?;
        return model_spec(&m).context("--start");
    }
    ModelSpec::parse(start).context("--start")
}

/// Validates the settings, reads the logs, runs the loop, prints and writes.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let config = DiscoverConfig {
        diagnose: DiagnoseConfig {
            alpha: args.alpha,
            seed: args.seed,
            ..DiagnoseConfig::default()
        }
        .check()
        .context("--alpha")?,
        verify: VerifyConfig {
            folds: args.verify_folds,
            ..VerifyConfig::default()
        }
        .check()?,
        max_steps: args.max_steps,
    }
    .check()?;
    if let Some(dir) = &args.out
        && dir.exists()
        && !dir.is_dir()
    {
        anyhow::bail!(
            "--out {}: is a file; --out takes a directory",
            dir.display()
        );
    }
    let start_file = Path::new(&args.start);
    let out_files: Vec<(String, PathBuf)> = args
        .out
        .iter()
        .flat_map(|d| DISCOVER_FILES.map(|f| (format!("--out {f}"), d.join(f))))
        .collect();
    super::common::refuse_clashes(
        &[
            ("--data", Some(&args.data)),
            ("--test", args.test.as_deref()),
            ("--start", start_file.is_file().then_some(start_file)),
        ],
        &out_files
            .iter()
            .map(|(f, p)| (f.as_str(), Some(p.as_path())))
            .collect::<Vec<_>>(),
    )?;
    let start = start_spec(&args.start)?;
    // Staged before the work: a folder that cannot be written fails at once.
    let staged = match &args.out {
        Some(dir) => Some(super::common::stage_out(dir)?),
        None => None,
    };
    let train = args.columns.read_log(&args.data).context("--data")?;
    let test = match &args.test {
        Some(p) => Some(args.columns.read_log(p).context("--test")?),
        None => None,
    };
    let (d, model) = discover(&start, &train, test.as_ref(), &config)?;
    if let Some(staged) = staged {
        // Built in a staging folder beside `--out` and moved in whole: all three files or none.
        let json = d.to_json()?;
        write_atomic(&staged.path("discover.json"), |w| writeln!(w, "{json}"))?;
        let text = d.to_string();
        write_atomic(&staged.path("discover.txt"), |w| write!(w, "{text}"))?;
        model.save(&staged.path("model.json"))?;
        staged.commit()?;
    }
    if args.json {
        outln!("{}", d.to_json()?)?;
    } else {
        out!("{d}")?;
        if let Some(dir) = &args.out {
            outln!("wrote {}", dir.display())?;
        }
    }
    Ok(())
}
