//! `biasctl check`: validate a log and summarise it.

use super::common::LogArgs;
use crate::log::LogReader;

/// Flags of `biasctl check`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    log: LogArgs,
}

/// Streams the log (in constant memory) and prints rows, measured rows, span, units, the sampling (rows/s, how the
/// direction of motion is read, reversals, the position-noise estimate) and covariates.
pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let map = args.log.columns.map();
    let mut reader = LogReader::open(&args.log.data, &map)?;
    let units = args.log.columns.units(reader.schema())?;
    // Constant memory: the exact medians take a few passes over the log (see
    // `summarise_sampling`).
    let (sum, sampling) = crate::history::summarise_sampling(&mut reader, &args.log.data, &map)?;
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
    for line in sampling.describe(&units.position) {
        outln!("  {line}")?;
    }
    if !s.covariates.is_empty() {
        outln!("  covariates: {}", s.covariates.join(", "))?;
    }
    for e in &s.empty_cells {
        outln!(
            "  note: {e}, read as missing values (a term that reads the column needs every cell)"
        )?;
    }
    for note in &s.notes {
        outln!("  note: {note}")?;
    }
    for m in &s.metadata {
        outln!("  # {m}")?;
    }
    Ok(())
}
