//! `biasctl check`: validate a log and summarise it.

use super::common::LogArgs;
use biasctl::log::LogReader;

/// Flags of `biasctl check`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    log: LogArgs,
}

/// Streams the log once and prints rows, measured rows, span, units and covariates.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut reader = LogReader::open(&args.log.data, &args.log.columns.map())?;
    let units = args.log.columns.units(reader.schema())?;
    let sum = reader.summarise()?;
    let s = reader.schema();
    outln!("{}: {} rows, {} measured", s.file, sum.rows, sum.measured)?;
    outln!(
        "  positions {} .. {} {} (column {})",
        sum.positions[0],
        sum.positions[1],
        units.position,
        s.map.track
    )?;
    outln!("  bias in {} (column {})", units.bias, s.map.bias)?;
    outln!(
        "  time {} .. {} s (column {})",
        sum.times_s[0],
        sum.times_s[1],
        s.map.time
    )?;
    if !s.covariates.is_empty() {
        outln!("  covariates: {}", s.covariates.join(", "))?;
    }
    for note in &s.notes {
        outln!("  note: {note}")?;
    }
    for m in &s.metadata {
        outln!("  # {m}")?;
    }
    Ok(())
}
