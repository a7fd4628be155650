//! `biasctl simulate`: run the simulated drive through a sequence and write the log.

use crate::{Drive, SequenceOptions, SimConfig, sim::MeasureMode, sim::simulate_to_files};
use std::path::PathBuf;

/// Flags of `biasctl simulate`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Sequence: table1..table7, random, dwell, script, calibration (default `script` when
    /// --script is given).
    #[arg(long, value_name = "NAME", required_unless_present = "script")]
    sequence: Option<String>,
    /// Seed; the same seed gives a byte-identical log.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    seed: u64,
    /// Drive description (TOML); default the built-in `paper1997`.
    #[arg(long, value_name = "FILE.toml")]
    drive: Option<PathBuf>,
    /// Effects to switch off, comma separated: position, direction, overshoot, time, memory,
    /// drift, scatter, runout, temperature.
    #[arg(long, value_name = "EFFECT,...", value_delimiter = ',')]
    disable: Vec<String>,
    /// Number of random seeks (random, calibration); default 2000.
    #[arg(allow_negative_numbers = true, long)]
    n: Option<u64>,
    /// Width of the random range, tracks; default 250.
    #[arg(long, value_name = "TRACKS", allow_hyphen_values = true)]
    span: Option<f64>,
    /// Centre of the random range, tables and dwell run, track; default mid-stroke.
    #[arg(long, value_name = "TRACK", allow_hyphen_values = true)]
    center: Option<f64>,
    /// Shortest random dwell, s (default 0.05).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    dwell_min: Option<f64>,
    /// Longest random dwell, s (default 0.5).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    dwell_max: Option<f64>,
    /// Script for `--sequence script`: CSV `track,dwell_s[,measure]`.
    #[arg(long, value_name = "FILE.csv")]
    script: Option<PathBuf>,
    /// How each bias is measured through the servo.
    #[arg(long, value_enum, default_value_t = Measure::Fast)]
    measure: Measure,
    /// Output log.
    #[arg(long, value_name = "LOG.csv")]
    out: PathBuf,
    /// Also write each effect's true contribution per row here.
    #[arg(long, value_name = "TRUTH.csv")]
    truth: Option<PathBuf>,
}

/// `--measure`: the command-line face of [`MeasureMode`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Measure {
    /// Exact superposition of precomputed servo responses (the default).
    Fast,
    /// The sample-by-sample closed-loop reference simulation.
    Slow,
}

/// The sequence asked for: `--sequence`, or `script` when only `--script` is given. A script
/// beside another sequence would be silently unused: refused naming both flags.
fn sequence(a: &Args) -> anyhow::Result<String> {
    match (&a.sequence, &a.script) {
        (Some(s), Some(script)) if s != "script" => anyhow::bail!(
            "--script {} is read only by --sequence script, not --sequence {}: leave out one of them",
            crate::io::quote(&script.display().to_string()),
            crate::io::quote(s)
        ),
        (Some(s), _) => Ok(s.clone()),
        (None, _) => Ok("script".into()),
    }
}

/// Turns the flags into a validated [`SimConfig`].
fn config(a: &Args) -> anyhow::Result<SimConfig> {
    let drive = match &a.drive {
        Some(p) => Drive::from_toml_file(p)?,
        None => Drive::paper1997(),
    };
    let opts = SequenceOptions {
        n: a.n,
        span: a.span,
        center: a.center,
        script: a.script.clone(),
        dwell_min_s: a.dwell_min,
        dwell_max_s: a.dwell_max,
        measure: match a.measure {
            Measure::Fast => MeasureMode::Fast,
            Measure::Slow => MeasureMode::Slow,
        },
    };
    let disabled: Vec<&str> = a.disable.iter().map(String::as_str).collect();
    Ok(SimConfig::new(
        drive,
        &sequence(a)?,
        &opts,
        a.seed,
        &disabled,
    )?)
}

/// Validates, simulates, writes the files and prints a summary.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    super::common::refuse_clashes(
        &[
            ("--drive", args.drive.as_deref()),
            ("--script", args.script.as_deref()),
        ],
        &[
            ("--out", Some(args.out.as_path())),
            ("--truth", args.truth.as_deref()),
        ],
    )?;
    super::common::refuse_missing_folders(&[
        ("--out", Some(args.out.as_path())),
        ("--truth", args.truth.as_deref()),
    ])?;
    let cfg = config(&args)?;
    let s = simulate_to_files(&cfg, &args.out, args.truth.as_deref())?;
    outln!(
        "simulated {} on drive {} (seed {}): {} rows, {} measured, {:.1} s -> {}",
        cfg.sequence.name(),
        cfg.drive.name,
        cfg.seed,
        s.rows,
        s.measured,
        s.end_time_s,
        args.out.display()
    )?;
    if let Some(t) = &args.truth {
        outln!("truth -> {}", t.display())?;
    }
    Ok(())
}
