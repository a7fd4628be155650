//! `biasctl fleet`: one model over many drives' logs on this machine (`fleet fit`), and the
//! drives whose parameters stand out (`fleet outliers`).

use super::common::{ColumnArgs, DirectionArgs, with_flags};
use crate::fleet::{self, DriveFit, ReadSettings};
use anyhow::Context;
use std::path::PathBuf;

/// Flags of `biasctl fleet`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    /// Fit one model to every drive's log and write the fleet table (one row per drive: its
    /// parameters, their standard errors, std, warnings, and the error of a drive that failed).
    Fit(FitArgs),
    /// The drives whose parameters deviate from the fleet (robust z over the fleet table).
    Outliers(OutlierArgs),
    /// Every drive fitted and its residual screened as `diagnose` does, then pooled: per
    /// feature one statistic summed over the drives and its family-wise p-value from the same
    /// seeded block permutations within each drive.
    Diagnose(DiagnoseArgs),
}

/// Flags of `biasctl fleet fit`.
#[derive(Debug, clap::Args)]
struct FitArgs {
    #[command(flatten)]
    drives: Drives,
    /// The fleet table to write (CSV): source, rows, terms, each parameter and `<name>.se`,
    /// std, warnings, error.
    #[arg(long, value_name = "FITS.csv")]
    out: PathBuf,
}

/// The drives' logs, how to read them and the model: what `fleet fit` and `fleet diagnose`
/// share.
#[derive(Debug, clap::Args)]
struct Drives {
    /// The drives' logs: paths, or patterns with `*` / `?` in the file name (`'logs/*.csv'`,
    /// quoted so that biasctl expands it); one drive per file.
    #[arg(long, value_name = "LOG.csv", num_args = 1.., required = true)]
    data: Vec<String>,
    #[command(flatten)]
    columns: ColumnArgs,
    #[command(flatten)]
    direction: DirectionArgs,
    /// The model: a preset (position-direction, calibration, dahl) or a term list
    /// (`poly2,direction,dahl:4`).
    #[arg(long, value_name = "PRESET|T1,T2,...")]
    model: String,
}

impl Drives {
    /// The model, the fit settings, the paths (patterns expanded) and the read settings.
    fn resolve(
        &self,
    ) -> anyhow::Result<(
        crate::ModelSpec,
        crate::CheckedFitOptions,
        Vec<PathBuf>,
        ReadSettings,
    )> {
        let spec = model_spec(&self.model)?;
        let opts = self.direction.fit_options()?;
        let mut paths = Vec::new();
        for p in &self.data {
            paths.extend(fleet::expand(p).context("--data")?);
        }
        let read = ReadSettings {
            columns: self.columns.map(),
            bias_unit: self.columns.bias_unit.clone(),
            track_unit: self.columns.track_unit.clone(),
        };
        Ok((spec, opts, paths, read))
    }
}

/// Flags of `biasctl fleet diagnose`.
#[derive(Debug, clap::Args)]
struct DiagnoseArgs {
    #[command(flatten)]
    drives: Drives,
    /// Print the pooled diagnosis as JSON (keys drives, failed, features {name, explained,
    /// p_value, p_value_raw, flagged, reason, drives_alone, drives, suggested_term}, summary,
    /// alpha, permutations, seed, best_edit, verification {feature, term, edit, terms, folds,
    /// drives, gain, z, z_bar, verified, reason, why, drives_verified_alone, per_drive,
    /// failed}).
    #[arg(long)]
    json: bool,
    /// Family-wise significance level of the pooled screen, in (0, 0.5].
    #[arg(allow_hyphen_values = true, long, default_value_t = 0.01)]
    alpha: f64,
    /// Permutations per drive (at least 1/alpha − 1).
    #[arg(allow_negative_numbers = true, long, default_value_t = 199)]
    permutations: usize,
    /// Seed of every drive's folds and permutations (as `diagnose --seed`).
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    seed: u64,
    /// Cross-validation folds, 2..=50.
    #[arg(allow_negative_numbers = true, long, default_value_t = 5)]
    folds: usize,
    /// Skip the verification refits (every drive refitted with the pooled suggestion on
    /// held-out folds of consecutive seeks, the fleet's gain and z).
    #[arg(long)]
    no_verify: bool,
    /// Folds of consecutive seeks of the verification refits, 2..=20 (as `diagnose`).
    #[arg(allow_negative_numbers = true, long, default_value_t = 3)]
    verify_folds: usize,
}

/// Flags of `biasctl fleet outliers`.
#[derive(Debug, clap::Args)]
struct OutlierArgs {
    /// The fleet table `fleet fit --out` wrote.
    #[arg(long, value_name = "FITS.csv")]
    fits: PathBuf,
    /// |z| above which a drive's parameter is an outlier (z: distance from the fleet's median
    /// over the larger of 1.4826·MAD and the drive's own standard error).
    #[arg(long, value_name = "Z", default_value_t = fleet::OUTLIER_THRESHOLD, allow_negative_numbers = true)]
    threshold: f64,
    /// Also write the outliers as CSV (source, parameter, value, median, sigma, z, rule).
    #[arg(long, value_name = "OUT.csv")]
    out: Option<PathBuf>,
}

/// Runs `fleet fit` or `fleet outliers`.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::Fit(a) => fit(a),
        Command::Outliers(a) => outliers(a),
        Command::Diagnose(a) => diagnose(a),
    }
}

/// The model of `--model`: a preset, else a term list.
fn model_spec(text: &str) -> anyhow::Result<crate::ModelSpec> {
    if let Ok(spec) = crate::ModelSpec::preset(text) {
        return Ok(spec);
    }
    crate::ModelSpec::parse(text).context("--model")
}

fn fit(a: FitArgs) -> anyhow::Result<()> {
    let (spec, opts, paths, read) = a.drives.resolve()?;
    let inputs: Vec<(&str, Option<&std::path::Path>)> = paths
        .iter()
        .map(|p| ("--data", Some(p.as_path())))
        .collect();
    super::common::refuse_clashes(&inputs, &[("--out", Some(a.out.as_path()))])?;
    super::common::refuse_missing_folders(&[("--out", Some(a.out.as_path()))])?;
    let rows = fleet::fit_paths(&paths, &read, &spec, &opts);
    crate::io::write_string_atomic(&a.out, &fleet::fits_csv(&rows))?;
    let failed: Vec<&DriveFit> = rows.iter().filter(|r| r.error.is_some()).collect();
    for r in &failed {
        eprintln!(
            "warning: {}: no fit: {}",
            r.source,
            with_flags(r.error.as_deref().unwrap_or(""))
        );
    }
    outln!(
        "model `{spec}`: {} drives, {} fitted, {} failed; wrote {}",
        rows.len(),
        rows.len() - failed.len(),
        failed.len(),
        a.out.display()
    )?;
    if !rows.is_empty() && failed.len() == rows.len() {
        anyhow::bail!(
            "no drive could be fitted (each row of {} names its error)",
            a.out.display()
        );
    }
    Ok(())
}

fn outliers(a: OutlierArgs) -> anyhow::Result<()> {
    super::common::refuse_clashes(
        &[("--fits", Some(a.fits.as_path()))],
        &[("--out", a.out.as_deref())],
    )?;
    let text = std::fs::read_to_string(&a.fits)
        .with_context(|| format!("--fits: cannot read {}", a.fits.display()))?;
    let rows = fleet::read_fits(&text, &a.fits.display().to_string())?;
    let found = fleet::outliers(&rows, a.threshold)?;
    if let Some(out) = &a.out {
        crate::io::write_string_atomic(out, &fleet::outliers_csv(&found))?;
    }
    let fitted = rows.iter().filter(|r| r.error.is_none()).count();
    outln!(
        "{} drives ({} fitted), threshold |z| > {}: {} outlying parameter{}",
        rows.len(),
        fitted,
        a.threshold,
        found.len(),
        if found.len() == 1 { "" } else { "s" }
    )?;
    for o in &found {
        outln!(
            "  {}  {}  {:.6e} (fleet median {:.6e}, sigma {:.3e}): z = {:+.1} [{}]",
            o.source,
            o.parameter,
            o.value,
            o.median,
            o.sigma,
            o.z,
            o.rule
        )?;
    }
    Ok(())
}

fn diagnose(a: DiagnoseArgs) -> anyhow::Result<()> {
    let config = crate::DiagnoseConfig {
        alpha: a.alpha,
        permutations: a.permutations,
        seed: a.seed,
        folds: a.folds,
        ..crate::DiagnoseConfig::default()
    }
    .check()?;
    let (spec, opts, paths, read) = a.drives.resolve()?;
    let verify = crate::VerifyConfig {
        folds: a.verify_folds,
        fit: opts.clone(),
        ..crate::VerifyConfig::default()
    }
    .check()?;
    let verify = (!a.no_verify).then_some(&verify);
    let d = fleet::diagnose_paths(&paths, &read, &spec, &opts, &config, verify)?;
    // The warnings name the settings as flags (the JSON keeps the library's text, as Python's).
    for (source, message) in &d.verification.failed {
        let message = with_flags(message);
        eprintln!("warning: {source}: not refitted with the pooled suggestion: {message}");
    }
    for (source, message) in &d.failed {
        eprintln!("warning: {source}: not screened: {}", with_flags(message));
    }
    if d.drives == 0 {
        anyhow::bail!("no drive could be screened (the warnings above name each one's error)");
    }
    if a.json {
        outln!("{}", crate::io::to_string_pretty(&d)?)?;
        return Ok(());
    }
    outln!("model `{spec}`: {}", d.summary)?;
    outln!(
        "  {:<28} {:>9} {:>9} {:>8} {:>7}  suggested",
        "feature",
        "explained",
        "p_value",
        "alone",
        "flagged"
    )?;
    for f in &d.features {
        outln!(
            "  {:<28} {:>8.3}% {:>9.4} {:>4}/{:<3} {:>7}  {}",
            f.name,
            100.0 * f.explained,
            f.p_value,
            f.drives_alone,
            f.drives,
            if f.flagged { "yes" } else { "no" },
            f.suggested_term.as_deref().unwrap_or("-")
        )?;
    }
    let v = &d.verification;
    match (v.verified, v.edit.as_deref(), v.gain, v.z) {
        (true, Some(edit), Some(gain), Some(z)) => outln!(
            "verified: {edit} across {} drives: gain {:.2} % of the held-out squared error, \
             z = {z:.2} (bar {}; {} drives verify it alone) [{}]",
            v.drives,
            100.0 * gain,
            v.z_bar,
            v.drives_verified_alone,
            v.reason
        )?,
        _ => {
            // `why` begins with the rule; printed after the words here.
            let prefix = format!("{}: ", v.reason);
            let why = v.why.strip_prefix(&prefix).unwrap_or(&v.why);
            outln!("not verified: {why} ({})", v.reason)?
        }
    }
    Ok(())
}
